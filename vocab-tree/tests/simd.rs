//! Every SIMD path gives exactly the scalar path's output: the same words for every
//! instruction set the CPU has, on random trees, trees with ties and every branching around
//! the kernels' block sizes; and bit-identical distances.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::rng;
use ibc_vocab_tree::{Descriptor, Isa, Scoring, Vocabulary, VocabularyParts, Weighting};
use proptest::prelude::*;
use rand::{Rng, RngExt};

fn random_binary<const W: usize>(r: &mut impl Rng) -> [u64; W] {
    std::array::from_fn(|_| r.next_u64())
}

fn random_float<const D: usize>(r: &mut impl Rng) -> [f32; D] {
    std::array::from_fn(|_| r.random::<f32>() * 2.0 - 1.0)
}

fn complete<D: Descriptor>(k: u32, l: u32, centroids: Vec<D>) -> Vocabulary<D> {
    let parts = VocabularyParts::complete(k, l, centroids, Weighting::TfIdf, Scoring::L1).unwrap();
    Vocabulary::from_parts(parts).unwrap()
}

fn nodes_below_root(k: u32, l: u32) -> usize {
    (1..=l).map(|i| (k as usize).pow(i)).sum()
}

/// Checks that every supported instruction set quantizes `queries` as the scalar path does.
fn same_words_on_every_isa<D: Descriptor>(voc: &Vocabulary<D>, queries: &[D]) {
    let scalar = voc.quantize_with_isa(Isa::Scalar, queries).unwrap();
    for isa in Isa::supported() {
        assert_eq!(
            voc.quantize_with_isa(isa, queries).unwrap(),
            scalar,
            "{isa:?}"
        );
    }
    assert_eq!(voc.quantize(queries), scalar);
    // The descent in groups must agree with one-at-a-time words.
    for (q, w) in queries.iter().zip(&scalar).take(20) {
        assert_eq!(voc.word(q), *w);
    }
}

fn check_binary<const W: usize>(k: u32, l: u32, seed: u64) {
    let mut r = rng(seed);
    let n = nodes_below_root(k, l);
    let centroids: Vec<[u64; W]> = (0..n).map(|_| random_binary(&mut r)).collect();
    // Queries: random, equal to centroids, and near centroids.
    let mut queries: Vec<[u64; W]> = (0..300).map(|_| random_binary(&mut r)).collect();
    queries.extend(centroids.iter().step_by(7).copied());
    let voc = complete(k, l, centroids);
    same_words_on_every_isa(&voc, &queries);
}

fn check_float<const D: usize>(k: u32, l: u32, seed: u64) {
    let mut r = rng(seed);
    let n = nodes_below_root(k, l);
    let centroids: Vec<[f32; D]> = (0..n).map(|_| random_float(&mut r)).collect();
    let mut queries: Vec<[f32; D]> = (0..300).map(|_| random_float(&mut r)).collect();
    queries.extend(centroids.iter().step_by(7).copied());
    let voc = complete(k, l, centroids);
    same_words_on_every_isa(&voc, &queries);
}

#[test]
fn binary_paths_agree_for_every_width_and_branching() {
    // Branchings around the AVX2 kernel's blocks of 4 and 8 candidates.
    for k in [2, 3, 4, 5, 7, 8, 9, 10, 12, 16, 17] {
        check_binary::<1>(k, 2, u64::from(k));
        check_binary::<2>(k, 2, u64::from(k) + 100);
        check_binary::<4>(k, 2, u64::from(k) + 200);
        check_binary::<8>(k, 2, u64::from(k) + 300);
        check_binary::<12>(k, 2, u64::from(k) + 400);
    }
    check_binary::<4>(10, 4, 7);
}

#[test]
fn float_paths_agree_for_every_width_and_branching() {
    for k in [2, 3, 8, 9, 10, 17] {
        check_float::<64>(k, 2, u64::from(k));
        check_float::<128>(k, 2, u64::from(k) + 100);
        check_float::<20>(k, 2, u64::from(k) + 200); // 2 full lanes of 8 and a tail of 4
        check_float::<3>(k, 2, u64::from(k) + 300); // tail only
    }
    check_float::<64>(10, 3, 9);
}

#[test]
fn ties_go_to_the_lowest_child_on_every_path() {
    // Binary: eleven children at equal distance from every query of weight-1 bit patterns.
    let k = 11;
    let centroids: Vec<[u64; 4]> = (0..k * (k + 1))
        .map(|i| {
            let mut c = [0u64; 4];
            c[i % 4] = 1 << (i % 64);
            c
        })
        .collect();
    let voc = complete(k as u32, 2, centroids);
    let queries: Vec<[u64; 4]> = vec![[0; 4], [u64::MAX; 4], [1, 0, 0, 0], [0, 0, 0, 1 << 63]];
    same_words_on_every_isa(&voc, &queries);
    // Identical centroids everywhere: word 0.
    let voc = complete(9, 2, vec![[5u64, 6, 7, 8]; 90]);
    for isa in Isa::supported() {
        assert_eq!(
            voc.quantize_with_isa(isa, &[[1, 2, 3, 4]]).unwrap(),
            vec![0]
        );
    }
    let voc = complete(9, 2, vec![[0.25f32; 64]; 90]);
    for isa in Isa::supported() {
        assert_eq!(voc.quantize_with_isa(isa, &[[1.0; 64]]).unwrap(), vec![0]);
    }
}

/// The scalar definition of the float distance, written out: eight lanes, lane `i mod 8`,
/// reduced as `((l0 + l4) + (l2 + l6)) + ((l1 + l5) + (l3 + l7))`.
fn lanes_l2<const D: usize>(a: &[f32; D], b: &[f32; D]) -> f32 {
    let mut l = [0f32; 8];
    for i in 0..D {
        let d = a[i] - b[i];
        l[i % 8] += d * d;
    }
    ((l[0] + l[4]) + (l[2] + l[6])) + ((l[1] + l[5]) + (l[3] + l[7]))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Float distances are bit-identical to the scalar lane definition (this runs the AVX2
    /// kernel on CPUs that have it).
    #[test]
    fn float_distance_is_bit_identical(seed in any::<u64>(), scale in 1e-3f32..1e3) {
        let mut r = rng(seed);
        let a: [f32; 64] = random_float(&mut r).map(|x| x * scale);
        let b: [f32; 64] = random_float(&mut r).map(|x| x * scale);
        prop_assert_eq!(a.distance(&b).to_bits(), lanes_l2(&a, &b).to_bits());
        let a: [f32; 19] = random_float(&mut r);
        let b: [f32; 19] = random_float(&mut r);
        prop_assert_eq!(a.distance(&b).to_bits(), lanes_l2(&a, &b).to_bits());
        prop_assert_eq!(a.metric_distance(&b), f64::from(lanes_l2(&a, &b)).sqrt());
    }

    /// Hamming distances equal the bit count of the XOR.
    #[test]
    fn binary_distance_is_the_bit_count(a in any::<[u64; 4]>(), b in any::<[u64; 4]>()) {
        let expected: u32 = a.iter().zip(&b).map(|(x, y)| (x ^ y).count_ones()).sum();
        prop_assert_eq!(a.distance(&b), expected);
        prop_assert_eq!(a.metric_distance(&b), f64::from(expected));
    }

    /// Random small trees and queries: every path gives the same words.
    #[test]
    fn random_trees_agree(seed in any::<u64>(), k in 2u32..20) {
        let mut r = rng(seed);
        let n = nodes_below_root(k, 2);
        let centroids: Vec<[u64; 4]> = (0..n).map(|_| random_binary(&mut r)).collect();
        let queries: Vec<[u64; 4]> = (0..40).map(|_| random_binary(&mut r)).collect();
        let voc = complete(k, 2, centroids);
        let scalar = voc.quantize_with_isa(Isa::Scalar, &queries).unwrap();
        for isa in Isa::supported() {
            prop_assert_eq!(&voc.quantize_with_isa(isa, &queries).unwrap(), &scalar);
        }
    }
}

#[test]
fn isa_detection_is_consistent() {
    let best = Isa::detect();
    assert_eq!(Isa::detect(), best);
    assert!(Isa::Scalar.is_supported());
    assert_eq!(Isa::supported().last(), Some(&best));
    let voc = complete(2, 1, vec![[0u64; 4], [u64::MAX; 4]]);
    for isa in [Isa::Scalar, Isa::Popcnt, Isa::Avx2] {
        let r = voc.quantize_with_isa(isa, &[[0; 4]]);
        assert_eq!(r.is_ok(), isa.is_supported());
    }
}
