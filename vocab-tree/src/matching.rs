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
//! T-RO 2012, section IV-B). [`match_brute_force`] compares every pair. Both are built on
//! [`match_sets`], which matches two sets of descriptors given by reference (for a train set
//! gathered from several sources) with reusable buffers ([`MatchScratch`]).

use crate::bow::FeatureVector;
use crate::descriptor::{Descriptor, DescriptorKind};
use crate::error::{Result, VocabError};
use crate::simd::Isa;

/// Options of the matching functions. Defaults: CamOdoCal's ratio 0.7 with the mutual
/// check, no absolute distance bound.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatchOptions {
    /// The distance ratio `d₁ / d₂` must be below this, in `(0, 1]`.
    pub ratio: f64,
    /// Keep a match only when each feature is the other's nearest.
    pub mutual_check: bool,
    /// Keep a match only when its metric distance is at most this.
    pub max_distance: Option<f64>,
    /// Keeps the struct open to new fields: build it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: crate::NonExhaustive,
}

impl Default for MatchOptions {
    fn default() -> Self {
        Self {
            ratio: 0.7,
            mutual_check: true,
            max_distance: None,
            non_exhaustive: crate::NonExhaustive(()),
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

    /// Checks that the options are in their domains.
    ///
    /// # Errors
    /// [`VocabError::InvalidOption`] for a ratio outside `(0, 1]` or a negative or NaN
    /// `max_distance`.
    pub fn validate(&self) -> Result<()> {
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
    options.validate()?;
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
    let mut sets = GroupSets::new();
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
                sets.match_group(isa, query, fa, train, fb, options, &mut out);
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
    options.validate()?;
    let to_u32 = |n: usize| {
        u32::try_from(n).map_err(|_| {
            VocabError::InvalidFeatureVector(format!("{n} features: feature indices are u32"))
        })
    };
    let qi: Vec<u32> = (0..to_u32(query.len())?).collect();
    let ti: Vec<u32> = (0..to_u32(train.len())?).collect();
    let mut out = Vec::new();
    GroupSets::new().match_group(Isa::detect(), query, &qi, train, &ti, options, &mut out);
    Ok(out)
}

/// Reusable buffers of [`match_sets`]: matching many small sets (one per vocabulary node, say)
/// allocates only while the buffers grow.
#[derive(Debug, Clone, Default)]
pub struct MatchScratch {
    /// Nearest query of each train descriptor: (raw distance, query position).
    column: Vec<(f64, usize)>,
    /// Nearest and second-nearest train descriptor of each query: (train position, raw
    /// distances `d1`, `d2`).
    rows: Vec<(usize, f64, f64)>,
}

/// The ratio test and the optional mutual check (see the module docs) between the descriptors
/// `query` and `train`, given by reference so that either set may be gathered from several
/// places. Calls `found(query_position, train_position, distance)` for every match, in query
/// order, with the metric distance. Ties go to the lowest position. `scratch` holds the
/// buffers between calls.
///
/// # Errors
/// [`VocabError::InvalidOption`] for options outside their domain.
pub fn match_sets<D: Descriptor>(
    query: &[&D],
    train: &[&D],
    options: &MatchOptions,
    scratch: &mut MatchScratch,
    found: impl FnMut(usize, usize, f64),
) -> Result<()> {
    options.validate()?;
    match_sets_with(Isa::detect(), query, train, options, scratch, found);
    Ok(())
}

/// [`match_sets`] on checked options with the instruction set `isa`. Candidates are ranked by
/// the raw distance (Hamming, or squared Euclidean), which orders them as the metric distance
/// does; only the two nearest are turned into metric distances for the ratio test.
fn match_sets_with<D: Descriptor>(
    isa: Isa,
    query: &[&D],
    train: &[&D],
    options: &MatchOptions,
    scratch: &mut MatchScratch,
    mut found: impl FnMut(usize, usize, f64),
) {
    let MatchScratch { column, rows } = scratch;
    column.clear();
    column.resize(train.len(), (f64::INFINITY, usize::MAX));
    rows.clear();
    for (r, qd) in query.iter().enumerate() {
        let (mut best, mut d1, mut d2) = (usize::MAX, f64::INFINITY, f64::INFINITY);
        for (c, td) in train.iter().enumerate() {
            let d: f64 = D::distance_isa(isa, qd, td).into();
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
        if best == usize::MAX {
            continue;
        }
        let (m1, m2) = (metric::<D>(d1), metric::<D>(d2));
        if m1.partial_cmp(&(options.ratio * m2)) != Some(std::cmp::Ordering::Less)
            || options.max_distance.is_some_and(|m| m1 > m)
            || (options.mutual_check && column[best].1 != r)
        {
            continue;
        }
        found(r, best, m1);
    }
}

/// The metric distance (Hamming bits, or Euclidean distance) of a raw distance (Hamming, or
/// squared Euclidean) as `f64`; infinity stays infinity.
fn metric<D: Descriptor>(raw: f64) -> f64 {
    match D::KIND {
        DescriptorKind::Binary => raw,
        DescriptorKind::Float => raw.sqrt(),
    }
}

/// The buffers of one matching call: the descriptors of a node's features and the buffers
/// of [`match_sets_with`].
struct GroupSets<'a, D> {
    query: Vec<&'a D>,
    train: Vec<&'a D>,
    scratch: MatchScratch,
}

impl<'a, D: Descriptor> GroupSets<'a, D> {
    fn new() -> Self {
        Self {
            query: Vec::new(),
            train: Vec::new(),
            scratch: MatchScratch::default(),
        }
    }

    /// Ratio test and mutual check among the query features `qi` and train features `ti`
    /// (indices checked by the caller), appended to `out`.
    #[allow(clippy::too_many_arguments)]
    fn match_group(
        &mut self,
        isa: Isa,
        query: &'a [D],
        qi: &[u32],
        train: &'a [D],
        ti: &[u32],
        options: &MatchOptions,
        out: &mut Vec<Match>,
    ) {
        self.query.clear();
        self.query.extend(qi.iter().map(|&q| &query[q as usize]));
        self.train.clear();
        self.train.extend(ti.iter().map(|&t| &train[t as usize]));
        let found = |r: usize, c: usize, distance: f64| {
            out.push(Match {
                query: qi[r],
                train: ti[c],
                distance,
            });
        };
        match_sets_with(
            isa,
            &self.query,
            &self.train,
            options,
            &mut self.scratch,
            found,
        );
    }
}
