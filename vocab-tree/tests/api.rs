//! The API as a user outside the crate writes it: every options struct in one expression with
//! `..Default::default()`, and descriptor bytes through the public `Descriptor` trait.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use ibc_vocab_tree::{
    Descriptor, DescriptorKind, MatchOptions, QueryOptions, TrainingOptions, Vocabulary,
};

#[test]
fn options_are_written_in_one_expression() {
    let training = TrainingOptions {
        branching: 4,
        depth: 2,
        seed: 7,
        ..Default::default()
    };
    let matching = MatchOptions {
        ratio: 0.8,
        mutual_check: false,
        ..Default::default()
    };
    let query = QueryOptions {
        max_results: 3,
        ..Default::default()
    };
    let images: Vec<Vec<[u64; 4]>> = (0..6u64)
        .map(|i| (0..20u64).map(|j| [i * 31 + j, j, i ^ j, i * j]).collect())
        .collect();
    let vocabulary = Vocabulary::train(&images, &training).unwrap();
    assert_eq!(vocabulary.branching(), 4);
    assert!(matching.validate().is_ok());
    assert_eq!(query.max_results, 3);
}

#[test]
fn descriptor_bytes_are_public_and_round_trip() {
    let d: [f32; 4] = [1.5, -2.0, 0.25, 8.0];
    let mut bytes = Vec::new();
    d.write_le(&mut bytes);
    assert_eq!(bytes.len(), <[f32; 4]>::BYTES);
    assert_eq!(<[f32; 4]>::read_le(&bytes), d);
    assert!(!<[f32; 4]>::read_le(&f32::NAN.to_le_bytes().repeat(4)).is_finite());
    let b: [u64; 2] = [0x0102_0304_0506_0708, u64::MAX];
    let mut bytes = Vec::new();
    b.write_le(&mut bytes);
    assert_eq!(bytes[0], 0x08);
    assert_eq!(<[u64; 2]>::read_le(&bytes), b);
    assert_eq!(
        DescriptorKind::from_code(DescriptorKind::Float.code()),
        Some(DescriptorKind::Float)
    );
    assert_eq!(DescriptorKind::from_code(3), None);
}
