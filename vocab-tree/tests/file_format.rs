//! The vocabulary file: save, load and query give identical results; every kind of damaged
//! or mismatched file is a typed error, never a panic; atomic writes; the ORB-SLAM text
//! import.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::sync::Arc;

use common::{flip_bits, random_orb, random_surf, rng};
use ibc_vocab_tree::file_format::{FORMAT_VERSION, MAGIC, checksum};
use ibc_vocab_tree::{
    Database, DescriptorKind, OrbDescriptor, QueryOptions, Scoring, Surf64Descriptor,
    TrainingOptions, VocabError, VocabFileError, Vocabulary, Weighting, binary_from_bytes,
    binary_to_bytes,
};
use proptest::prelude::*;
use rand::RngExt;

fn images() -> Vec<Vec<OrbDescriptor>> {
    let mut r = rng(41);
    let protos: Vec<_> = (0..200).map(|_| random_orb(&mut r)).collect();
    (0..20)
        .map(|_| {
            (0..60)
                .map(|_| flip_bits(&protos[r.random_range(0..200)], 0.05, &mut r))
                .collect()
        })
        .collect()
}

fn vocabulary() -> Vocabulary<OrbDescriptor> {
    let options = TrainingOptions::default()
        .with_shape(5, 3)
        .with_scoring(Scoring::ChiSquare)
        .with_weighting(Weighting::TfIdf);
    Vocabulary::train(&images(), &options).unwrap()
}

fn file_error(bytes: &[u8]) -> VocabFileError {
    match Vocabulary::<OrbDescriptor>::from_bytes(bytes) {
        Err(VocabError::File(e)) => e,
        other => panic!("expected a file error, got {other:?}"),
    }
}

/// Rewrites the checksum after an edit, so that the checks behind it are reached.
fn reseal(bytes: &mut [u8]) {
    let body = bytes.len() - 8;
    let sum = checksum(&bytes[..body]);
    bytes[body..].copy_from_slice(&sum.to_le_bytes());
}

#[test]
fn save_load_and_query_give_identical_results() {
    let voc = vocabulary();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("voc.ibcvoc");
    voc.save(&path).unwrap();
    let loaded = Vocabulary::<OrbDescriptor>::load(&path).unwrap();
    assert_eq!(loaded, voc);
    assert_eq!(loaded.to_bytes(), voc.to_bytes());
    assert_eq!(
        Vocabulary::<OrbDescriptor>::from_bytes(&voc.to_bytes()).unwrap(),
        voc
    );
    // The file is written whole: length, magic, version, checksum of the body.
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(bytes, voc.to_bytes());
    assert_eq!(&bytes[..8], &MAGIC);
    assert_eq!(
        u32::from_le_bytes(bytes[8..12].try_into().unwrap()),
        FORMAT_VERSION
    );
    let body = bytes.len() - 8;
    assert_eq!(
        u64::from_le_bytes(bytes[body..].try_into().unwrap()),
        checksum(&bytes[..body])
    );

    let images = images();
    let (a, b) = (Arc::new(voc), Arc::new(loaded));
    let (mut da, mut db) = (
        Database::new(Arc::clone(&a), Some(2)),
        Database::new(Arc::clone(&b), Some(2)),
    );
    for image in &images {
        da.add(image).unwrap();
        db.add(image).unwrap();
    }
    for image in &images {
        assert_eq!(a.quantize(image), b.quantize(image));
        let (qa, fa) = a.transform_with_features(image, 2).unwrap();
        let (qb, fb) = b.transform_with_features(image, 2).unwrap();
        assert_eq!((&qa, &fa), (&qb, &fb));
        let o = QueryOptions::default().with_max_results(usize::MAX);
        assert_eq!(da.query(&qa, &o), db.query(&qb, &o));
    }
    for i in 0..images.len() as u32 {
        assert_eq!(da.features(i), db.features(i));
    }

    // Float vocabularies round-trip too.
    let mut r = rng(5);
    let floats: Vec<Vec<Surf64Descriptor>> = (0..6)
        .map(|_| (0..50).map(|_| random_surf(&mut r)).collect())
        .collect();
    let fv = Vocabulary::train(&floats, &TrainingOptions::default().with_shape(4, 2)).unwrap();
    let path = dir.path().join("surf.ibcvoc");
    fv.save(&path).unwrap();
    assert_eq!(Vocabulary::<Surf64Descriptor>::load(&path).unwrap(), fv);
}

#[test]
fn saving_is_atomic_and_replaces_the_file() {
    let voc = vocabulary();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("voc.ibcvoc");
    std::fs::write(&path, b"an older file").unwrap();
    voc.save(&path).unwrap();
    assert_eq!(Vocabulary::<OrbDescriptor>::load(&path).unwrap(), voc);
    // No temporary file is left behind.
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, vec![std::ffi::OsString::from("voc.ibcvoc")]);
    // A folder that does not exist is an I/O error naming the path.
    let missing = dir.path().join("no/such/folder/voc.ibcvoc");
    assert!(matches!(voc.save(&missing), Err(VocabError::Io(_))));
    assert!(matches!(
        Vocabulary::<OrbDescriptor>::load(&missing),
        Err(VocabError::Io(_))
    ));
}

#[test]
fn every_kind_of_damaged_file_is_rejected() {
    let good = vocabulary().to_bytes();

    // Not our file.
    assert_eq!(file_error(b""), VocabFileError::BadMagic);
    assert_eq!(file_error(b"IBCVOC"), VocabFileError::BadMagic);
    let mut bad = good.clone();
    bad[0] = b'X';
    assert_eq!(file_error(&bad), VocabFileError::BadMagic);

    // Another version.
    let mut bad = good.clone();
    bad[8..12].copy_from_slice(&2u32.to_le_bytes());
    assert_eq!(
        file_error(&bad),
        VocabFileError::UnsupportedVersion {
            found: 2,
            supported: 1
        }
    );

    // Bad header codes.
    for (at, field) in [(12, "descriptor kind"), (13, "weighting"), (14, "scoring")] {
        let mut bad = good.clone();
        bad[at] = 9;
        assert!(
            matches!(file_error(&bad), VocabFileError::InvalidHeader { field: f, value: 9 } if f == field)
        );
    }

    // Mismatched descriptor type: a binary 4-word file read as 8 words or as floats.
    assert!(matches!(
        Vocabulary::<[u64; 8]>::from_bytes(&good),
        Err(VocabError::File(VocabFileError::DescriptorMismatch {
            expected_kind: DescriptorKind::Binary,
            expected_width: 8,
            found_kind: DescriptorKind::Binary,
            found_width: 4
        }))
    ));
    assert!(matches!(
        Vocabulary::<Surf64Descriptor>::from_bytes(&good),
        Err(VocabError::File(VocabFileError::DescriptorMismatch {
            found_kind: DescriptorKind::Binary,
            ..
        }))
    ));

    // Every truncation.
    for len in 8..good.len() {
        let e = file_error(&good[..len]);
        assert!(
            matches!(e, VocabFileError::Truncated { .. }),
            "length {len}: {e:?}"
        );
    }
    // Trailing bytes.
    let mut long = good.clone();
    long.extend_from_slice(&[0, 0, 0]);
    assert_eq!(
        file_error(&long),
        VocabFileError::TrailingBytes { extra: 3 }
    );
    // Counts that promise more than the file holds.
    let mut bad = good.clone();
    bad[28..32].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(matches!(file_error(&bad), VocabFileError::Truncated { .. }));

    // Every flipped bit of the body: a checksum mismatch.
    for at in (40..good.len()).step_by(3) {
        let mut bad = good.clone();
        bad[at] ^= 0x10;
        let e = file_error(&bad);
        assert!(
            matches!(e, VocabFileError::ChecksumMismatch { .. }),
            "byte {at}: {e:?}"
        );
    }

    // Checksum-valid files whose tree is broken: every child index is checked.
    let n = u32::from_le_bytes(good[28..32].try_into().unwrap()) as usize;
    let child_start = |i: usize| 40 + 4 * i;
    let node_word = |i: usize| 40 + 4 * (n + 1) + 4 * i;
    let edits: Vec<(usize, u32)> = vec![
        (child_start(0), 0),            // the root's children start at the root
        (child_start(1), n as u32 + 5), // a child index past the end
        (child_start(n), n as u32 - 1), // offsets do not end at the node count
        (child_start(2), 1),            // offsets decrease
        (node_word(n - 1), 0),          // the last leaf carries word 0, already carried
        (node_word(0), 0),              // the root (internal) carries a word
        (node_word(n - 1), u32::MAX),   // a leaf carries no word
    ];
    for (at, value) in edits {
        let mut bad = good.clone();
        bad[at..at + 4].copy_from_slice(&value.to_le_bytes());
        reseal(&mut bad);
        assert!(
            matches!(
                Vocabulary::<OrbDescriptor>::from_bytes(&bad),
                Err(VocabError::InvalidTree(_))
            ),
            "edit at {at}"
        );
    }
    // A NaN word weight.
    let words = u32::from_le_bytes(good[32..36].try_into().unwrap()) as usize;
    let weights = 40 + 4 * (n + 1) + 4 * n;
    let mut bad = good.clone();
    bad[weights..weights + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    reseal(&mut bad);
    assert!(matches!(
        Vocabulary::<OrbDescriptor>::from_bytes(&bad),
        Err(VocabError::InvalidTree(_))
    ));
    // A depth smaller than the tree's.
    let mut bad = good.clone();
    bad[24..28].copy_from_slice(&2u32.to_le_bytes());
    reseal(&mut bad);
    assert!(matches!(
        Vocabulary::<OrbDescriptor>::from_bytes(&bad),
        Err(VocabError::InvalidTree(_))
    ));
    // A branching smaller than the widest node.
    let mut bad = good.clone();
    bad[20..24].copy_from_slice(&2u32.to_le_bytes());
    reseal(&mut bad);
    assert!(matches!(
        Vocabulary::<OrbDescriptor>::from_bytes(&bad),
        Err(VocabError::InvalidTree(_))
    ));
    assert!(words > 0);

    // A float file with a NaN centroid.
    let mut r = rng(6);
    let floats: Vec<Vec<Surf64Descriptor>> = (0..4)
        .map(|_| (0..30).map(|_| random_surf(&mut r)).collect())
        .collect();
    let fv = Vocabulary::train(&floats, &TrainingOptions::default().with_shape(3, 2)).unwrap();
    let mut bad = fv.to_bytes();
    let at = bad.len() - 8 - 4;
    bad[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    reseal(&mut bad);
    assert!(matches!(
        Vocabulary::<Surf64Descriptor>::from_bytes(&bad),
        Err(VocabError::InvalidTree(_))
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Random damage never panics and never loads a different vocabulary.
    #[test]
    fn random_damage_is_an_error(edits in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..6), reseal_it in any::<bool>()) {
        let voc = vocabulary();
        let good = voc.to_bytes();
        let mut bad = good.clone();
        for (at, byte) in edits {
            let at = at % bad.len();
            bad[at] = byte;
        }
        if reseal_it {
            reseal(&mut bad);
        }
        let loaded = Vocabulary::<OrbDescriptor>::from_bytes(&bad);
        if !reseal_it && bad != good {
            prop_assert!(loaded.is_err());
        }
        if bad == good {
            prop_assert_eq!(loaded.unwrap(), voc);
        }
    }
}

#[test]
fn orb_slam_text_vocabularies_are_imported() {
    // k = 2, L = 2, L1 scoring (0), TF-IDF (0). Nodes in file order (DBoW2 builds depth
    // first): 1 under the root, its leaves 2 and 3, then 4 under the root, its leaf 5.
    let byte_line = |parent: u32, leaf: u8, b: u8, w: f64| {
        let bytes: Vec<String> = (0..32)
            .map(|i| ((b as usize + i) % 256).to_string())
            .collect();
        format!("{parent} {leaf} {} {w}\n", bytes.join(" "))
    };
    let mut text = String::from("2 2  0 0\n");
    text += &byte_line(0, 0, 10, 0.0);
    text += &byte_line(1, 1, 11, 0.5);
    text += &byte_line(1, 1, 12, 1.5);
    text += &byte_line(0, 0, 200, 0.0);
    text += &byte_line(4, 1, 201, 2.5);
    let voc = Vocabulary::<OrbDescriptor>::from_dbow2_text(text.as_bytes()).unwrap();
    assert_eq!(
        (
            voc.branching(),
            voc.depth(),
            voc.word_count(),
            voc.node_count()
        ),
        (2, 2, 3, 6)
    );
    assert_eq!(
        (voc.scoring(), voc.weighting()),
        (Scoring::L1, Weighting::TfIdf)
    );
    // Words in file order of their leaves, with their weights.
    assert_eq!(voc.word_weight(0), Some(0.5));
    assert_eq!(voc.word_weight(1), Some(1.5));
    assert_eq!(voc.word_weight(2), Some(2.5));
    // Breadth-first renumbering: root's children 1 (file 1) and 2 (file 4); then 3, 4 under
    // node 1 and 5 under node 2.
    assert_eq!(voc.children(0), 1..3);
    assert_eq!(voc.children(1), 3..5);
    assert_eq!(voc.children(2), 5..6);
    assert_eq!(voc.node_word(3), Some(0));
    assert_eq!(voc.node_word(5), Some(2));
    // Descriptors: bytes packed little-endian into words.
    let d = |b: u8| -> OrbDescriptor {
        let bytes: Vec<u8> = (0..32).map(|i| ((b as usize + i) % 256) as u8).collect();
        binary_from_bytes(&bytes).unwrap()
    };
    assert_eq!(voc.centroid(2), Some(&d(200)));
    assert_eq!(binary_to_bytes(&d(7))[..3], [7, 8, 9]);
    assert_eq!(voc.word(&d(12)), 1);
    assert_eq!(voc.word(&d(201)), 2);
    // And it saves and loads like any vocabulary.
    assert_eq!(
        Vocabulary::<OrbDescriptor>::from_bytes(&voc.to_bytes()).unwrap(),
        voc
    );

    // Errors name the line.
    let line_of = |text: &str| match Vocabulary::<OrbDescriptor>::from_dbow2_text(text.as_bytes()) {
        Err(VocabError::File(VocabFileError::Text { line, .. })) => line,
        other => panic!("expected a text error, got {other:?}"),
    };
    assert_eq!(line_of(""), 1);
    assert_eq!(line_of("2 2 0\n"), 1);
    assert_eq!(line_of("2 2 9 0\n"), 1);
    assert_eq!(line_of(&format!("2 2 0 0\n{}", byte_line(3, 1, 0, 1.0))), 2); // parent not earlier
    assert_eq!(line_of(&format!("2 2 0 0\n{}", byte_line(0, 2, 0, 1.0))), 2); // is_leaf not 0/1
    assert_eq!(
        line_of(&format!("2 2 0 0\n{}", byte_line(0, 1, 0, -1.0))),
        2
    ); // negative weight
    assert_eq!(line_of("2 2 0 0\n0 1 1 2 3 0.5\n"), 2); // too few bytes
    assert_eq!(line_of(&format!("2 2 0 0\n{}", byte_line(0, 0, 0, 0.0))), 2); // internal, no child
    let leaf_with_child = format!(
        "2 2 0 0\n{}{}",
        byte_line(0, 1, 0, 1.0),
        byte_line(1, 1, 5, 1.0)
    );
    assert_eq!(line_of(&leaf_with_child), 2);
    let mut too_wide = String::from("1 2 0 0\n");
    too_wide += &byte_line(0, 1, 1, 1.0);
    too_wide += &byte_line(0, 1, 2, 1.0);
    assert!(matches!(
        Vocabulary::<OrbDescriptor>::from_dbow2_text(too_wide.as_bytes()),
        Err(VocabError::InvalidTree(_))
    ));
}
