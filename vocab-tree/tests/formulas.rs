//! Weighting and scoring parity with hand-computed examples.
//!
//! A four-word vocabulary (one level, descriptors equal to the centroids, so the words of an
//! image are known exactly) with IDF weights `[1, 2, 0.5, 4]`, and two images:
//! `A` = words `{0, 0, 1, 3}` (4 features), `B` = words `{0, 1, 1, 2, 2, 2}` (6 features).
//! Every expected value below is derived by hand from the formulas of Galvez-Lopez and Tardos
//! (T-RO 2012) and Nister and Stewenius (CVPR 2006) with DBoW2's scaling, and cross-checked
//! against dense-vector implementations of the same definitions.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use approx::assert_relative_eq;
use common::SCORINGS;
use ibc_vocab_tree::{BowVector, LOG_EPS, Scoring, Vocabulary, VocabularyParts, Weighting};

type D1 = [u64; 1];

const CENTROIDS: [u64; 4] = [0, 0xFFFF, 0xFFFF_0000_0000, 0xFFFF << 48];
const IDF: [f32; 4] = [1.0, 2.0, 0.5, 4.0];

fn vocabulary(weighting: Weighting, scoring: Scoring) -> Vocabulary<D1> {
    let mut centroids = vec![[0u64]];
    centroids.extend(CENTROIDS.iter().map(|&c| [c]));
    Vocabulary::from_parts(VocabularyParts {
        branching: 4,
        depth: 1,
        weighting,
        scoring,
        child_start: vec![1, 5, 5, 5, 5, 5],
        centroids,
        word_node: vec![1, 2, 3, 4],
        word_weights: IDF.to_vec(),
    })
    .unwrap()
}

fn image(words: &[usize]) -> Vec<D1> {
    words.iter().map(|&w| [CENTROIDS[w]]).collect()
}

fn image_a() -> Vec<D1> {
    image(&[0, 0, 1, 3])
}

fn image_b() -> Vec<D1> {
    image(&[0, 1, 1, 2, 2, 2])
}

fn dense(bow: &BowVector) -> [f64; 4] {
    let mut out = [0.0; 4];
    for (w, x) in bow.iter() {
        out[w as usize] = f64::from(x);
    }
    out
}

#[test]
fn every_weighting_matches_its_formula() {
    // Raw weights of image A (n_d = 4, counts [2, 1, 0, 1]), then L1-normalized.
    // TF-IDF: (n_id / n_d) idf = [2/4 * 1, 1/4 * 2, 0, 1/4 * 4] = [0.5, 0.5, 0, 1] -> / 2.
    // TF: [2/4, 1/4, 0, 1/4] (already of L1 norm 1).
    // IDF: [1, 2, 0, 4] -> / 7.   Binary: [1, 1, 0, 1] -> / 3.
    let cases = [
        (Weighting::TfIdf, [0.25, 0.25, 0.0, 0.5]),
        (Weighting::Tf, [0.5, 0.25, 0.0, 0.25]),
        (Weighting::Idf, [1.0 / 7.0, 2.0 / 7.0, 0.0, 4.0 / 7.0]),
        (Weighting::Binary, [1.0 / 3.0, 1.0 / 3.0, 0.0, 1.0 / 3.0]),
    ];
    for (weighting, expected) in cases {
        let v = vocabulary(weighting, Scoring::L1).transform(&image_a());
        assert_eq!(v.len(), 3, "{weighting:?}: words 0, 1 and 3");
        let got = dense(&v);
        for i in 0..4 {
            assert_relative_eq!(got[i], expected[i], epsilon = 1e-7);
        }
    }
    // Without normalization (dot product) the raw TF-IDF weights come out.
    let v = vocabulary(Weighting::TfIdf, Scoring::DotProduct).transform(&image_a());
    assert_eq!(dense(&v), [0.5, 0.5, 0.0, 1.0]);
    // With L2 normalization the TF-IDF vector of A is [0.5, 0.5, 0, 1] / sqrt(1.5).
    let v = vocabulary(Weighting::TfIdf, Scoring::L2).transform(&image_a());
    let got = dense(&v);
    let norm = 1.5f64.sqrt();
    for (g, e) in got.iter().zip([0.5 / norm, 0.5 / norm, 0.0, 1.0 / norm]) {
        assert_relative_eq!(*g, e, epsilon = 1e-7);
    }
}

/// Closed forms of every score of `A` against `B` under TF-IDF, derived by hand.
///
/// L1-normalized: `a = [1/4, 1/4, 0, 1/2]`, `b = [2/13, 8/13, 3/13, 0]` (raw `B` is
/// `[1/6, 4/6, 1.5/6, 0]`, of L1 norm `6.5/6`).
#[test]
fn every_scoring_matches_its_hand_computed_value() {
    // L1: 1 - 1/2 (5/52 + 19/52 + 12/52 + 26/52) = 1 - 31/52 = 21/52.
    let l1 = 21.0 / 52.0;
    // L2: a° = [0.5, 0.5, 0, 1]/sqrt(1.5), b° = [1, 4, 1.5, 0]/sqrt(19.25);
    // a°.b° = 2.5 / sqrt(1.5 * 19.25); score = 1 - sqrt(1 - a°.b°).
    let l2 = 1.0 - (1.0 - 2.5 / (1.5f64 * 19.25).sqrt()).sqrt();
    // Chi-square: 2 (ab/(a+b))_0 + 2 (ab/(a+b))_1 = 2 (2/21 + 8/45) = 172/315.
    let chi = 172.0 / 315.0;
    // KL: 1/4 ln(13/8) + 1/4 ln(13/32) + 1/2 (ln(1/2) - ln eps), ln eps = ln 2^-52.
    let kl = 0.25 * (13.0f64 / 8.0).ln()
        + 0.25 * (13.0f64 / 32.0).ln()
        + 0.5 * (0.5f64.ln() + 52.0 * 2.0f64.ln());
    // Bhattacharyya: sqrt(1/4 * 2/13) + sqrt(1/4 * 8/13) = 3 sqrt(2/52).
    let bhattacharyya = 3.0 * (2.0f64 / 52.0).sqrt();
    // Dot product of the raw vectors: 0.5/6 + 0.5 * 4/6 = 2.5/6.
    let dot = 2.5 / 6.0;
    let cases = [
        (Scoring::L1, l1),
        (Scoring::L2, l2),
        (Scoring::ChiSquare, chi),
        (Scoring::KL, kl),
        (Scoring::Bhattacharyya, bhattacharyya),
        (Scoring::DotProduct, dot),
    ];
    for (scoring, expected) in cases {
        let voc = vocabulary(Weighting::TfIdf, scoring);
        let (a, b) = (voc.transform(&image_a()), voc.transform(&image_b()));
        // f32 weights: seven significant digits.
        assert_relative_eq!(voc.score(&a, &b), expected, max_relative = 1e-6);
    }
    // Numeric anchors of the closed forms.
    assert_relative_eq!(l1, 0.403_846_153_8, epsilon = 1e-9);
    assert_relative_eq!(chi, 0.546_031_746_0, epsilon = 1e-9);
    assert_relative_eq!(kl, 17.571_433_5, epsilon = 1e-6);
    assert_relative_eq!(LOG_EPS, f64::EPSILON.ln(), epsilon = 1e-12);
}

/// Dense-vector versions of the score definitions (not the sparse identities the crate
/// uses), for every weighting and scoring on several image pairs.
#[test]
fn sparse_scores_equal_dense_definitions() {
    let images = [
        image_a(),
        image_b(),
        image(&[3]),
        image(&[2, 2, 1]),
        image(&[0, 1, 2, 3, 3]),
    ];
    let weightings = [
        Weighting::TfIdf,
        Weighting::Tf,
        Weighting::Idf,
        Weighting::Binary,
    ];
    for weighting in weightings {
        for scoring in SCORINGS {
            let voc = vocabulary(weighting, scoring);
            for x in &images {
                for y in &images {
                    let (v, w) = (dense(&voc.transform(x)), dense(&voc.transform(y)));
                    let expected = match scoring {
                        Scoring::L1 => {
                            1.0 - 0.5 * v.iter().zip(&w).map(|(a, b)| (a - b).abs()).sum::<f64>()
                        }
                        Scoring::L2 => {
                            let d2: f64 = v.iter().zip(&w).map(|(a, b)| (a - b) * (a - b)).sum();
                            1.0 - d2.sqrt() / 2.0f64.sqrt()
                        }
                        Scoring::ChiSquare => {
                            let chi2: f64 = v
                                .iter()
                                .zip(&w)
                                .filter(|(a, b)| *a + *b > 0.0)
                                .map(|(a, b)| (a - b) * (a - b) / (a + b))
                                .sum();
                            1.0 - chi2 / 2.0
                        }
                        Scoring::KL => v
                            .iter()
                            .zip(&w)
                            .filter(|(a, _)| **a > 0.0)
                            .map(|(a, b)| a * (a / if *b > 0.0 { *b } else { f64::EPSILON }).ln())
                            .sum(),
                        Scoring::Bhattacharyya => {
                            v.iter().zip(&w).map(|(a, b)| (a * b).sqrt()).sum()
                        }
                        _ => v.iter().zip(&w).map(|(a, b)| a * b).sum(),
                    };
                    let got = voc.score(&voc.transform(x), &voc.transform(y));
                    assert!(
                        (got - expected).abs() <= 2e-6 * expected.abs().max(1.0),
                        "{weighting:?}/{scoring:?}: {got} vs {expected}"
                    );
                }
            }
        }
    }
}

#[test]
fn zero_weight_words_and_empty_images_give_empty_vectors() {
    let mut parts = vocabulary(Weighting::TfIdf, Scoring::L1).into_parts();
    parts.word_weights[3] = 0.0; // a word present in every training image: idf = ln(N/N) = 0
    let voc = Vocabulary::from_parts(parts).unwrap();
    assert!(voc.transform(&image(&[3, 3])).is_empty());
    // Under TF weighting the same word counts.
    let tf = voc.clone().with_weighting(Weighting::Tf);
    assert_eq!(tf.transform(&image(&[3, 3])).entries(), &[(3, 1.0)]);
    // An empty image: empty vector, empty feature vector, score 0 against anything.
    assert!(voc.transform(&[]).is_empty());
    let (bow, fv) = voc.transform_with_features(&[], 0).unwrap();
    assert!(bow.is_empty() && fv.is_empty());
    assert_eq!(voc.score(&bow, &voc.transform(&image_a())), 0.0);
    assert_eq!(voc.score(&voc.transform(&image_a()), &bow), 0.0);
}

#[test]
fn bow_vectors_reject_unsorted_or_invalid_entries() {
    assert!(BowVector::from_entries(vec![(1, 0.5), (3, 0.5)]).is_ok());
    assert!(BowVector::from_entries(vec![(3, 0.5), (1, 0.5)]).is_err());
    assert!(BowVector::from_entries(vec![(1, 0.5), (1, 0.5)]).is_err());
    assert!(BowVector::from_entries(vec![(1, f32::NAN)]).is_err());
    assert!(BowVector::from_entries(vec![(1, -1.0)]).is_err());
    assert!(BowVector::from_entries(vec![(1, 0.0)]).is_err());
}
