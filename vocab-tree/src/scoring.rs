//! Similarity scores between bag-of-words vectors (Galvez-Lopez and Tardos, T-RO 2012;
//! Nister and Stewenius, CVPR 2006), scaled as DBoW2 scales them: see [`Scoring`].

use crate::bow::BowVector;

/// `ln ε` with `ε = 2⁻⁵²` (`f64::EPSILON`): the log-weight KL gives a query word the other
/// vector lacks (DBoW2's `LOG_EPS`).
pub const LOG_EPS: f64 = -36.043_653_389_117_15;

/// The vector norm a scoring needs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Norm {
    /// Sum of absolute values.
    L1,
    /// Euclidean norm.
    L2,
}

/// How two bag-of-words vectors are compared. The default, `L1`, is DBoW2's default and
/// ORB-SLAM's scoring. Scores are scaled as DBoW2 scales them (Galvez-Lopez and Tardos,
/// T-RO 2012, eq. 2; Nister and Stewenius, CVPR 2006, section 4).
///
/// `v` is the query and `w` the other vector, both normalized as the table says (`v*`: L1
/// norm 1, `v°`: L2 norm 1). Every sum runs over the words present in both vectors, except
/// for KL.
///
/// | scoring | normalization | score | range |
/// |---|---|---|---|
/// | [`Scoring::L1`] | L1 | `1 − ½ ‖v* − w*‖₁ = −½ Σ (abs(v_i − w_i) − v_i − w_i)` | `[0, 1]` |
/// | [`Scoring::L2`] | L2 | `1 − ‖v° − w°‖₂ / √2 = 1 − √(1 − Σ v_i w_i)` (see below) | `[0, 1]` |
/// | [`Scoring::ChiSquare`] | L1 | `1 − ½ χ²(v*, w*) = 2 Σ v_i w_i / (v_i + w_i)` | `[0, 1]` |
/// | [`Scoring::KL`] | L1 | `Σ_{v_i > 0} v_i ln(v_i / w_i)`, `w_i = ε` when absent, `ln ε = ln(2⁻⁵²)` | `[0, ∞)`, lower is better |
/// | [`Scoring::Bhattacharyya`] | L1 | `Σ √(v_i w_i)` | `[0, 1]` |
/// | [`Scoring::DotProduct`] | none | `Σ v_i w_i` | `[0, ∞)` |
///
/// L2 is evaluated as `1 − √((‖v‖² + ‖w‖² − 2 v·w) / 2)` with the norms of the stored `f32`
/// weights: for unit vectors this is DBoW2's `1 − √(1 − v·w)`, but it keeps full precision for
/// near-identical vectors, where `1 − v·w` would be rounding noise amplified by the square root.
///
/// The L1 identity is Nister and Stewenius' eq. 5 for `p = 1` and unit-norm vectors:
/// `‖v − w‖₁ = 2 + Σ_{v_i w_i ≠ 0} (|v_i − w_i| − |v_i| − |w_i|)`. KL uses
/// `Σ_{v_i > 0} v_i (ln v_i − ln ε) + Σ_{common} v_i (ln ε − ln w_i)`, which lets a database
/// accumulate only the common words. Sums are accumulated in `f64` in increasing word order,
/// so [`Scoring::score`] and a database query give bit-identical scores.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Scoring {
    /// `1 − ½ ‖v − w‖₁` on L1-normalized vectors.
    #[default]
    L1,
    /// `1 − √(1 − v·w)` on L2-normalized vectors.
    L2,
    /// `2 Σ v_i w_i / (v_i + w_i)` on L1-normalized vectors.
    ChiSquare,
    /// Kullback-Leibler divergence of `v` from `w` on L1-normalized vectors (lower is better).
    KL,
    /// Bhattacharyya coefficient `Σ √(v_i w_i)` on L1-normalized vectors.
    Bhattacharyya,
    /// `v · w` on vectors that are not normalized.
    DotProduct,
}

impl Scoring {
    /// The code used in files: DBoW2's numbering (0 L1, 1 L2, 2 chi-square, 3 KL,
    /// 4 Bhattacharyya, 5 dot product).
    pub fn code(self) -> u8 {
        match self {
            Self::L1 => 0,
            Self::L2 => 1,
            Self::ChiSquare => 2,
            Self::KL => 3,
            Self::Bhattacharyya => 4,
            Self::DotProduct => 5,
        }
    }

    /// The scoring with the given code (see [`Scoring::code`]).
    pub fn from_code(code: u8) -> Option<Self> {
        Some(match code {
            0 => Self::L1,
            1 => Self::L2,
            2 => Self::ChiSquare,
            3 => Self::KL,
            4 => Self::Bhattacharyya,
            5 => Self::DotProduct,
            _ => return None,
        })
    }

    /// The norm vectors must have before scoring (`None` for the dot product).
    pub fn norm(self) -> Option<Norm> {
        match self {
            Self::L2 => Some(Norm::L2),
            Self::DotProduct => None,
            _ => Some(Norm::L1),
        }
    }

    /// True when a higher score means more similar (every scoring but KL, a divergence).
    pub fn higher_is_better(self) -> bool {
        self != Self::KL
    }

    /// True when score `a` ranks before score `b`.
    pub(crate) fn better(self, a: f64, b: f64) -> bool {
        if self.higher_is_better() {
            a > b
        } else {
            a < b
        }
    }

    /// The contribution of a word present in both vectors, with weights `q` (query) and `w`.
    #[inline]
    pub(crate) fn common_term(self, q: f32, w: f32) -> f64 {
        let (q, w) = (f64::from(q), f64::from(w));
        match self {
            Self::L1 => (q - w).abs() - q.abs() - w.abs(),
            Self::L2 | Self::DotProduct => q * w,
            Self::ChiSquare => {
                let s = q + w;
                if s != 0.0 { q * w / s } else { 0.0 }
            }
            Self::KL => q * (LOG_EPS - w.ln()),
            Self::Bhattacharyya => (q * w).sqrt(),
        }
    }

    /// The part of the score that depends on one vector alone: `‖v‖²` for L2, KL's
    /// `Σ v_i (ln v_i − ln ε)` for the query; zero for the others.
    pub(crate) fn constant(self, v: &BowVector) -> f64 {
        match self {
            Self::L2 => v.iter().map(|(_, x)| f64::from(x) * f64::from(x)).sum(),
            Self::KL => v
                .iter()
                .map(|(_, x)| {
                    let x = f64::from(x);
                    x * (x.ln() - LOG_EPS)
                })
                .sum(),
            _ => 0.0,
        }
    }

    /// The score from the sum of common terms and the constants of the query and the other
    /// vector.
    #[inline]
    pub(crate) fn finish(self, acc: f64, query: f64, other: f64) -> f64 {
        match self {
            // `0.0 -` turns a -0.0 into +0.0.
            Self::L1 => 0.0 - acc / 2.0,
            Self::L2 => 1.0 - ((query + other - 2.0 * acc).max(0.0) / 2.0).sqrt(),
            Self::ChiSquare => 2.0 * acc,
            Self::KL => query + acc,
            Self::Bhattacharyya | Self::DotProduct => acc,
        }
    }

    /// The score of `v` (the query) against `w`; both must be normalized as
    /// [`Scoring::norm`] says, which vectors made by the vocabulary are.
    pub fn score(self, v: &BowVector, w: &BowVector) -> f64 {
        let (a, b) = (v.entries(), w.entries());
        let (mut i, mut j) = (0, 0);
        let mut acc = 0.0;
        while i < a.len() && j < b.len() {
            match a[i].0.cmp(&b[j].0) {
                std::cmp::Ordering::Equal => {
                    acc += self.common_term(a[i].1, b[j].1);
                    i += 1;
                    j += 1;
                }
                std::cmp::Ordering::Less => i += 1,
                std::cmp::Ordering::Greater => j += 1,
            }
        }
        self.finish(acc, self.constant(v), self.constant(w))
    }
}
