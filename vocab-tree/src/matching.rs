//! Descriptor matching with the distance-ratio test (Lowe, "Distinctive image features from
//! scale-invariant keypoints", IJCV 2004, section 7.1) and an optional mutual check, as
//! CamOdoCal matches a query image to its candidate map images (ratio 0.7, cross-checked).
//!
//! For each query feature the two nearest candidates (`k = 2`) are found; the match to the
//! nearest is kept when `d₁ < ratio · d₂` with metric distances (Hamming bits, or Euclidean
//! distance for float descriptors). A feature with a single candidate has `d₂ = ∞` and passes.
//! With the mutual check, the match `(i, j)` is kept only when `i` is also the nearest query
//! feature of `j` (lowest index on ties) among the same candidates.
//!
//! [`match_by_nodes`] takes the candidates from the direct index: a query feature is compared
//! only with the train features under the same vocabulary node (Galvez-Lopez and Tardos,
//! T-RO 2012, section IV-B). [`match_brute_force`] compares every pair.

use crate::bow::FeatureVector;
use crate::descriptor::Descriptor;
use crate::error::{Result, VocabError};
use crate::simd::Isa;

/// Options of the matching functions. Defaults: CamOdoCal's ratio 0.7 with the mutual
/// check, no absolute distance bound.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct MatchOptions {
    /// The distance ratio `d₁ / d₂` must be below this, in `(0, 1]`.
    pub ratio: f64,
    /// Keep a match only when each feature is the other's nearest.
    pub mutual_check: bool,
    /// Keep a match only when its metric distance is at most this.
    pub max_distance: Option<f64>,
}

impl Default for MatchOptions {
    fn default() -> Self {
        Self {
            ratio: 0.7,
            mutual_check: true,
            max_distance: None,
        }
    }
}

impl MatchOptions {
    /// Sets the ratio.
    pub fn with_ratio(mut self, ratio: f64) -> Self {
        self.ratio = ratio;
        self
    }

    /// Turns the mutual check on or off.
    pub fn with_mutual_check(mut self, mutual_check: bool) -> Self {
        self.mutual_check = mutual_check;
        self
    }

    /// Sets the largest metric distance of a match.
    pub fn with_max_distance(mut self, max_distance: f64) -> Self {
        self.max_distance = Some(max_distance);
        self
    }

    fn check(&self) -> Result<()> {
        if !(self.ratio > 0.0 && self.ratio <= 1.0) {
            return Err(VocabError::InvalidOption {
                name: "ratio",
                reason: format!("{} is outside (0, 1]", self.ratio),
            });
        }
        if let Some(m) = self.max_distance.filter(|m| m.is_nan() || *m < 0.0) {
            return Err(VocabError::InvalidOption {
                name: "max_distance",
                reason: format!("{m} is not a distance >= 0"),
            });
        }
        Ok(())
    }
}

/// A match between query feature `query` and train feature `train`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Match {
    /// Index of the query feature.
    pub query: u32,
    /// Index of the train feature.
    pub train: u32,
    /// Their metric distance.
    pub distance: f64,
}

/// Matches the query features with the train features under the same node of two feature
/// vectors made with the same vocabulary and the same `levels_up`. Matches are sorted by
/// query index.
///
/// Fails when a feature vector names a feature past the end of its descriptors, or an option
/// is outside its domain.
pub fn match_by_nodes<D: Descriptor>(
    query: &[D],
    query_features: &FeatureVector,
    train: &[D],
    train_features: &FeatureVector,
    options: &MatchOptions,
) -> Result<Vec<Match>> {
    options.check()?;
    for (fv, descs, name) in [
        (query_features, query, "query"),
        (train_features, train, "train"),
    ] {
        if fv.feature_bound() > descs.len() {
            return Err(VocabError::InvalidFeatureVector(format!(
                "the {name} feature vector names feature {}, but there are {} {name} descriptors",
                fv.feature_bound() - 1,
                descs.len()
            )));
        }
    }
    let isa = Isa::detect();
    let mut out = Vec::new();
    let (mut a, mut b) = (
        query_features.iter().peekable(),
        train_features.iter().peekable(),
    );
    while let (Some(&(na, fa)), Some(&(nb, fb))) = (a.peek(), b.peek()) {
        match na.cmp(&nb) {
            std::cmp::Ordering::Less => {
                a.next();
            }
            std::cmp::Ordering::Greater => {
                b.next();
            }
            std::cmp::Ordering::Equal => {
                match_group(isa, query, fa, train, fb, options, &mut out);
                a.next();
                b.next();
            }
        }
    }
    out.sort_unstable_by_key(|m| (m.query, m.train));
    Ok(out)
}

/// Matches every query feature against every train feature. Matches are sorted by query
/// index.
pub fn match_brute_force<D: Descriptor>(
    query: &[D],
    train: &[D],
    options: &MatchOptions,
) -> Result<Vec<Match>> {
    options.check()?;
    let to_u32 = |n: usize| {
        u32::try_from(n).map_err(|_| {
            VocabError::InvalidFeatureVector(format!("{n} features: feature indices are u32"))
        })
    };
    let qi: Vec<u32> = (0..to_u32(query.len())?).collect();
    let ti: Vec<u32> = (0..to_u32(train.len())?).collect();
    let mut out = Vec::new();
    match_group(Isa::detect(), query, &qi, train, &ti, options, &mut out);
    Ok(out)
}

/// Ratio test and mutual check among the query features `qi` and train features `ti`.
fn match_group<D: Descriptor>(
    isa: Isa,
    query: &[D],
    qi: &[u32],
    train: &[D],
    ti: &[u32],
    options: &MatchOptions,
    out: &mut Vec<Match>,
) {
    // Nearest query feature of each train feature: (distance, position in qi).
    let mut column = vec![(f64::INFINITY, usize::MAX); ti.len()];
    // Nearest and second-nearest train feature of each query feature.
    let mut rows = Vec::with_capacity(qi.len());
    for (r, &q) in qi.iter().enumerate() {
        let qd = &query[q as usize];
        let (mut best, mut d1, mut d2) = (usize::MAX, f64::INFINITY, f64::INFINITY);
        for (c, &t) in ti.iter().enumerate() {
            let d = D::metric(D::distance_isa(isa, qd, &train[t as usize]));
            if d < d1 {
                d2 = d1;
                d1 = d;
                best = c;
            } else if d < d2 {
                d2 = d;
            }
            if d < column[c].0 {
                column[c] = (d, r);
            }
        }
        rows.push((best, d1, d2));
    }
    for (r, &(best, d1, d2)) in rows.iter().enumerate() {
        if best == usize::MAX
            || d1.partial_cmp(&(options.ratio * d2)) != Some(std::cmp::Ordering::Less)
        {
            continue;
        }
        if options.max_distance.is_some_and(|m| d1 > m) {
            continue;
        }
        if options.mutual_check && column[best].1 != r {
            continue;
        }
        out.push(Match {
            query: qi[r],
            train: ti[best],
            distance: d1,
        });
    }
}
