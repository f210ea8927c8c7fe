//! Word weighting of bag-of-words vectors (Galvez-Lopez and Tardos, T-RO 2012; Nister and
//! Stewenius, CVPR 2006): see [`Weighting`].

use crate::bow::{BowVector, WordId};
use crate::scoring::{Norm, Scoring};

/// How words are weighted in bag-of-words vectors. The default, `TfIdf`, is DBoW2's default
/// and the weighting of ORB-SLAM's vocabulary (Galvez-Lopez and Tardos, "Bags of binary words
/// for fast place recognition in image sequences", T-RO 2012, section IV; Nister and
/// Stewenius, CVPR 2006, section 4).
///
/// With `n_id` the number of features of image `d` quantized to word `i`, `n_d` the number of
/// features of `d`, `N` the number of training images and `N_i` the number of training images
/// in which word `i` occurs, the weight of word `i` in the vector of `d` is
///
/// | weighting | weight |
/// |---|---|
/// | [`Weighting::TfIdf`] | `(n_id / n_d) · ln(N / N_i)` |
/// | [`Weighting::Tf`] | `n_id / n_d` |
/// | [`Weighting::Idf`] | `ln(N / N_i)` |
/// | [`Weighting::Binary`] | `1` |
///
/// `ln(N / N_i)` is computed once at training and stored in the vocabulary as the word's
/// weight. Words of weight zero (a word seen in every training image, under IDF weighting) are
/// left out of the vector. The vector is then normalized as its [`Scoring`] requires.
/// The weighting can be changed after training ([`Vocabulary::with_weighting`]).
///
/// [`Vocabulary::with_weighting`]: crate::Vocabulary::with_weighting
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Weighting {
    /// Term frequency times inverse document frequency.
    #[default]
    TfIdf,
    /// Term frequency `n_id / n_d`.
    Tf,
    /// Inverse document frequency `ln(N / N_i)`, once per word present.
    Idf,
    /// `1` for every word present.
    Binary,
}

impl Weighting {
    /// The code used in files: DBoW2's numbering (0 TF-IDF, 1 TF, 2 IDF, 3 binary).
    pub fn code(self) -> u8 {
        match self {
            Self::TfIdf => 0,
            Self::Tf => 1,
            Self::Idf => 2,
            Self::Binary => 3,
        }
    }

    /// The weighting with the given code (see [`Weighting::code`]).
    pub fn from_code(code: u8) -> Option<Self> {
        Some(match code {
            0 => Self::TfIdf,
            1 => Self::Tf,
            2 => Self::Idf,
            3 => Self::Binary,
            _ => return None,
        })
    }

    /// The weight of a word that occurs `count` times among `total` features, with inverse
    /// document frequency `idf`.
    pub fn weight(self, count: u32, total: usize, idf: f32) -> f64 {
        let tf = f64::from(count) / total.max(1) as f64;
        match self {
            Self::TfIdf => tf * f64::from(idf),
            Self::Tf => tf,
            Self::Idf => f64::from(idf),
            Self::Binary => 1.0,
        }
    }
}

/// The bag-of-words vector of an image whose `total` features were quantized to `words`
/// (sorted, with repeats), weighted and then normalized as `scoring` requires.
pub(crate) fn bow_from_sorted_words(
    words: impl Iterator<Item = WordId>,
    total: usize,
    weighting: Weighting,
    idf: &[f32],
    scoring: Scoring,
) -> BowVector {
    let mut raw: Vec<(WordId, f64)> = Vec::new();
    let mut push = |word: WordId, count: u32| {
        let w = weighting.weight(count, total, idf.get(word as usize).copied().unwrap_or(0.0));
        if w > 0.0 && w.is_finite() {
            raw.push((word, w));
        }
    };
    let mut run: Option<(WordId, u32)> = None;
    for word in words {
        run = match run {
            Some((w, c)) if w == word => Some((w, c + 1)),
            Some((w, c)) => {
                push(w, c);
                Some((word, 1))
            }
            None => Some((word, 1)),
        };
    }
    if let Some((w, c)) = run {
        push(w, c);
    }
    normalize(raw, scoring.norm())
}

/// Divides by the L1 or L2 norm (if any) and rounds to `f32`; an all-zero vector is empty.
pub(crate) fn normalize(raw: Vec<(WordId, f64)>, norm: Option<Norm>) -> BowVector {
    let scale = match norm {
        None => 1.0,
        Some(Norm::L1) => raw.iter().map(|e| e.1.abs()).sum::<f64>(),
        Some(Norm::L2) => raw.iter().map(|e| e.1 * e.1).sum::<f64>().sqrt(),
    };
    if !(scale > 0.0 && scale.is_finite()) {
        return BowVector::new();
    }
    BowVector::from_sorted(
        raw.into_iter()
            .map(|(w, v)| (w, (v / scale) as f32))
            .filter(|e| e.1 > 0.0)
            .collect(),
    )
}
