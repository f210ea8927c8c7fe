//! The database: query scores equal direct scores bit for bit, ranking, options, empty
//! images, invalid input; and the matching helpers.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::sync::Arc;

use common::{SCORINGS, flip_bits, random_orb, rng};
use ibc_vocab_tree::{
    BowVector, Database, FeatureVector, Match, MatchOptions, MatchScratch, OrbDescriptor,
    QueryOptions, Scoring, TrainingOptions, VocabError, Vocabulary, match_brute_force,
    match_by_nodes, match_sets,
};
use proptest::prelude::*;
use rand::RngExt;

/// 30 images of 80 descriptors drawn (with noise) from 400 prototypes, so images share
/// words in varying amounts.
fn images() -> Vec<Vec<OrbDescriptor>> {
    let mut r = rng(21);
    let protos: Vec<_> = (0..400).map(|_| random_orb(&mut r)).collect();
    (0..30)
        .map(|_| {
            (0..80)
                .map(|_| flip_bits(&protos[r.random_range(0..400)], 0.05, &mut r))
                .collect()
        })
        .collect()
}

fn vocabulary(images: &[Vec<OrbDescriptor>]) -> Vocabulary<OrbDescriptor> {
    Vocabulary::train(
        images,
        &TrainingOptions::default().with_shape(8, 3).with_seed(3),
    )
    .unwrap()
}

#[test]
fn query_scores_equal_direct_scores_and_are_ranked() {
    let images = images();
    let base = vocabulary(&images);
    for scoring in SCORINGS {
        let voc = Arc::new(base.clone().with_scoring(scoring));
        let mut db = Database::new(Arc::clone(&voc), None);
        let bows: Vec<BowVector> = images.iter().map(|i| voc.transform(i)).collect();
        for bow in &bows {
            db.add_bow(bow, None).unwrap();
        }
        for q in &bows {
            let all = db.query(q, &QueryOptions::default().with_max_results(usize::MAX));
            assert!(!all.is_empty());
            for r in &all {
                // Bit-identical to the direct score.
                assert_eq!(
                    r.score,
                    voc.score(q, &bows[r.image as usize]),
                    "{scoring:?}"
                );
            }
            for pair in all.windows(2) {
                let (a, b) = (pair[0], pair[1]);
                if scoring.higher_is_better() {
                    assert!(a.score > b.score || (a.score == b.score && a.image < b.image));
                } else {
                    assert!(a.score < b.score || (a.score == b.score && a.image < b.image));
                }
            }
            // Images sharing no word with the query are not candidates.
            for (id, bow) in bows.iter().enumerate() {
                let shares = q.iter().any(|(w, _)| bow.get(w).is_some());
                assert_eq!(shares, all.iter().any(|r| r.image as usize == id));
            }
            // The top 10 are the first 10 of the full ranking.
            let top = db.query(q, &QueryOptions::default());
            assert_eq!(&top[..], &all[..all.len().min(10)]);
        }
        // An image is its own best match, except under the dot product, which is not
        // normalized.
        if scoring != Scoring::DotProduct {
            for (i, q) in bows.iter().enumerate() {
                let best = db.query(q, &QueryOptions::default().with_max_results(1));
                assert_eq!(best[0].image as usize, i, "{scoring:?}");
            }
        }
    }
}

#[test]
fn query_options_limit_threshold_and_filter() {
    let images = images();
    let voc = Arc::new(vocabulary(&images));
    let mut db = Database::new(Arc::clone(&voc), None);
    for image in &images {
        db.add(image).unwrap();
    }
    let q = voc.transform(&images[4]);
    let all = db.query(&q, &QueryOptions::default().with_max_results(usize::MAX));
    // max_results
    for n in [0, 1, 3, 10] {
        let r = db.query(&q, &QueryOptions::default().with_max_results(n));
        assert_eq!(r.len(), n.min(all.len()));
    }
    // min_score keeps exactly the results at least that good.
    let threshold = all[all.len() / 2].score;
    let r = db.query(
        &q,
        &QueryOptions::default()
            .with_max_results(usize::MAX)
            .with_min_score(threshold),
    );
    assert_eq!(
        r,
        all.iter()
            .copied()
            .filter(|x| x.score >= threshold)
            .collect::<Vec<_>>()
    );
    // The filter leaves out the query itself and its temporal neighbours.
    let not_near = |id: u32| id.abs_diff(4) > 1;
    let r = db.query(
        &q,
        &QueryOptions::default()
            .with_max_results(usize::MAX)
            .with_filter(&not_near),
    );
    assert_eq!(
        r,
        all.iter()
            .copied()
            .filter(|x| not_near(x.image))
            .collect::<Vec<_>>()
    );
    // KL is a divergence: min_score is a ceiling.
    let kl = Arc::new(vocabulary(&images).with_scoring(Scoring::KL));
    let mut db = Database::new(Arc::clone(&kl), None);
    for image in &images {
        db.add(image).unwrap();
    }
    let q = kl.transform(&images[4]);
    let all = db.query(&q, &QueryOptions::default().with_max_results(usize::MAX));
    assert_eq!(all[0].image, 4);
    let ceiling = all[3].score;
    let r = db.query(
        &q,
        &QueryOptions::default()
            .with_max_results(usize::MAX)
            .with_min_score(ceiling),
    );
    assert_eq!(r, all[..4].to_vec());
}

#[test]
fn empty_images_and_invalid_input() {
    let images = images();
    let voc = Arc::new(vocabulary(&images));
    let mut db = Database::new(Arc::clone(&voc), Some(1));
    assert!(db.is_empty());
    let empty = db.add(&[]).unwrap();
    let full = db.add(&images[0]).unwrap();
    assert_eq!((empty, full, db.len()), (0, 1, 2));
    assert!(db.features(empty).unwrap().is_empty());
    assert!(!db.features(full).unwrap().is_empty());
    // An empty query matches nothing; the empty image matches no query.
    assert!(
        db.query(&BowVector::new(), &QueryOptions::default())
            .is_empty()
    );
    let r = db.query(&voc.transform(&images[0]), &QueryOptions::default());
    assert!(r.iter().all(|x| x.image != empty));
    // A word outside the vocabulary, a missing or out-of-range feature vector.
    let outside = BowVector::from_entries(vec![(voc.word_count(), 1.0)]).unwrap();
    assert!(matches!(
        db.add_bow(&outside, Some(FeatureVector::new())),
        Err(VocabError::WordOutOfRange { .. })
    ));
    assert!(matches!(
        db.add_bow(&BowVector::new(), None),
        Err(VocabError::MissingFeatureVector)
    ));
    let far = FeatureVector::from_nodes(&[voc.node_count()]).unwrap();
    assert!(matches!(
        db.add_bow(&BowVector::new(), Some(far)),
        Err(VocabError::InvalidFeatureVector(_))
    ));
    assert_eq!(db.len(), 2);
}

#[test]
fn feature_vectors_group_features_by_node() {
    let images = images();
    let voc = vocabulary(&images);
    for levels_up in 0..=4 {
        let (_, fv) = voc.transform_with_features(&images[2], levels_up).unwrap();
        assert_eq!(fv.feature_count(), images[2].len());
        let words = voc.quantize(&images[2]);
        for (node, features) in fv.iter() {
            assert!(features.windows(2).all(|w| w[0] < w[1]));
            for &f in features {
                // Walk down from the node: the feature's word must be below it.
                let leaf = (0..voc.node_count())
                    .find(|&n| voc.node_word(n) == Some(words[f as usize]))
                    .unwrap();
                assert!(is_ancestor(&voc, node, leaf), "levels_up {levels_up}");
            }
        }
        if levels_up >= voc.depth() {
            assert_eq!(fv.nodes(), &[0]);
        }
        if levels_up == 0 {
            assert!(fv.iter().all(|(n, _)| voc.node_word(n).is_some()));
        }
    }
}

fn is_ancestor(voc: &Vocabulary<OrbDescriptor>, a: u32, n: u32) -> bool {
    a == n || voc.children(a).any(|c| is_ancestor(voc, c, n))
}

/// One-word binary descriptors for hand-made matching examples.
fn d(bits: u64) -> [u64; 1] {
    [bits]
}

#[test]
fn ratio_test_and_mutual_check_by_hand() {
    // Train 1 has bits 0..=4. Query 0 = {0}: distances 1 (train 0) and 4 (train 1), ratio
    // 0.25: kept. Query 1 = {0, 1}: 2 and 3, ratio 0.67 < 0.7: kept. Query 2 = {0, 1, 10}:
    // 3 and 4, ratio 0.75: rejected. Trains 2 and 3 are 8 bits or more away from every query.
    let train = [d(0), d(0b1_1111), d(0xFF << 32), d(0xFF << 48)];
    let query = [d(0b1), d(0b11), d(0b11 | 1 << 10)];
    let no_mutual = MatchOptions::default().with_mutual_check(false);
    let m = match_brute_force(&query, &train, &no_mutual).unwrap();
    let pairs: Vec<(u32, u32)> = m.iter().map(|x| (x.query, x.train)).collect();
    assert_eq!(pairs, vec![(0, 0), (1, 0)]);
    assert_eq!(m[0].distance, 1.0);
    assert_eq!(m[1].distance, 2.0);
    // Mutual check: train 0's nearest query is query 0 (distance 1), so (1, 0) goes.
    let m = match_brute_force(&query, &train, &MatchOptions::default()).unwrap();
    assert_eq!(
        m,
        vec![Match {
            query: 0,
            train: 0,
            distance: 1.0
        }]
    );
    // A lone candidate has no second neighbour and passes; a stricter ratio rejects more;
    // max_distance bounds the distance.
    let m = match_brute_force(&query[..1], &train[..1], &MatchOptions::default()).unwrap();
    assert_eq!(m.len(), 1);
    let strict = no_mutual.with_ratio(0.5);
    assert_eq!(match_brute_force(&query, &train, &strict).unwrap().len(), 1);
    let near = no_mutual.with_max_distance(1.0);
    assert_eq!(match_brute_force(&query, &train, &near).unwrap().len(), 1);
    // Equal nearest and second distances are ambiguous: rejected.
    let m = match_brute_force(&[d(0)], &[d(1), d(2)], &MatchOptions::default()).unwrap();
    assert!(m.is_empty());
    // Invalid options and feature vectors.
    for ratio in [0.0, -1.0, 1.5, f64::NAN] {
        let o = MatchOptions::default().with_ratio(ratio);
        assert!(match_brute_force(&query, &train, &o).is_err());
    }
    let fv = FeatureVector::from_nodes(&[0, 0, 0, 0]).unwrap(); // 4 features, query has 3
    assert!(matches!(
        match_by_nodes(&query, &fv, &train, &fv, &MatchOptions::default()),
        Err(VocabError::InvalidFeatureVector(_))
    ));
}

#[test]
fn matching_by_nodes_finds_true_correspondences() {
    // Two overlapping views of the same 150 points (60 in common), 8 % bit noise.
    let mut r = rng(31);
    let points: Vec<OrbDescriptor> = (0..240).map(|_| random_orb(&mut r)).collect();
    let a: Vec<_> = points[..150]
        .iter()
        .map(|p| flip_bits(p, 0.08, &mut r))
        .collect();
    let b: Vec<_> = points[90..240]
        .iter()
        .map(|p| flip_bits(p, 0.08, &mut r))
        .collect();
    let training: Vec<Vec<OrbDescriptor>> = (0..20)
        .map(|i| {
            points
                .iter()
                .skip(i)
                .step_by(3)
                .map(|p| flip_bits(p, 0.08, &mut r))
                .collect()
        })
        .collect();
    let voc = Vocabulary::train(&training, &TrainingOptions::default().with_shape(6, 3)).unwrap();
    let (_, fa) = voc.transform_with_features(&a, 2).unwrap();
    let (_, fb) = voc.transform_with_features(&b, 2).unwrap();
    let m = match_by_nodes(&a, &fa, &b, &fb, &MatchOptions::default()).unwrap();
    // Query i sees point i; train j sees point 90 + j.
    let correct = m.iter().filter(|x| x.query == x.train + 90).count();
    assert!(m.len() >= 40, "{} matches", m.len());
    assert!(correct == m.len(), "{correct} of {} correct", m.len());
    // Every node match is a brute-force candidate pair.
    let brute = match_brute_force(&a, &b, &MatchOptions::default()).unwrap();
    assert!(brute.iter().filter(|x| x.query == x.train + 90).count() >= m.len());
}

/// `match_sets` on a train set gathered by reference (every other descriptor, in reverse
/// order), with one scratch reused across calls of different sizes, gives brute-force
/// matching of copies of the same descriptors, position for position.
#[test]
fn match_sets_on_gathered_references_is_brute_force() {
    let mut r = rng(41);
    let protos: Vec<OrbDescriptor> = (0..40).map(|_| random_orb(&mut r)).collect();
    let mut scratch = MatchScratch::default();
    for (queries, trains) in [(50usize, 80usize), (7, 3), (60, 120), (1, 1)] {
        let q: Vec<_> = (0..queries)
            .map(|_| flip_bits(&protos[r.random_range(0..40)], 0.1, &mut r))
            .collect();
        let all: Vec<_> = (0..trains)
            .map(|_| flip_bits(&protos[r.random_range(0..40)], 0.1, &mut r))
            .collect();
        let train: Vec<&OrbDescriptor> = all.iter().step_by(2).rev().collect();
        let copies: Vec<OrbDescriptor> = train.iter().map(|t| **t).collect();
        let query: Vec<&OrbDescriptor> = q.iter().collect();
        for mutual in [false, true] {
            let o = MatchOptions::default().with_mutual_check(mutual);
            let mut found = Vec::new();
            match_sets(&query, &train, &o, &mut scratch, |a, b, distance| {
                found.push(Match {
                    query: a as u32,
                    train: b as u32,
                    distance,
                });
            })
            .unwrap();
            assert_eq!(found, match_brute_force(&q, &copies, &o).unwrap());
            if queries >= 50 {
                assert!(found.len() >= 5, "{} matches", found.len());
            }
        }
    }
    let bad = MatchOptions::default().with_ratio(1.5);
    let refused = match_sets(
        &[&protos[0]],
        &[&protos[1]],
        &bad,
        &mut scratch,
        |_, _, _| {},
    );
    assert!(matches!(refused, Err(VocabError::InvalidOption { .. })));
}

/// The ratio test compares metric (Euclidean) distances of float descriptors, not the squared
/// distances the tree uses: nearest 1.0 and second 1.3 give a ratio of 0.77 (rejected at 0.7),
/// though their squares would give 0.59.
#[test]
fn float_ratio_test_uses_euclidean_distances() {
    let query = [[0.0f32, 0.0]];
    let train = [[1.0f32, 0.0], [0.0, 1.3]];
    let o = MatchOptions::default();
    assert!(match_brute_force(&query, &train, &o).unwrap().is_empty());
    let m = match_brute_force(&query, &train, &o.with_ratio(0.8)).unwrap();
    assert_eq!(m.len(), 1);
    assert_eq!((m[0].train, m[0].distance), (0, 1.0));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// With the direct index at the root, node matching is brute-force matching.
    #[test]
    fn node_matching_at_the_root_is_brute_force(seed in 0u64..1000, mutual in any::<bool>()) {
        let mut r = rng(seed);
        let protos: Vec<OrbDescriptor> = (0..30).map(|_| random_orb(&mut r)).collect();
        let q: Vec<_> = (0..40).map(|_| flip_bits(&protos[r.random_range(0..30)], 0.1, &mut r)).collect();
        let t: Vec<_> = (0..35).map(|_| flip_bits(&protos[r.random_range(0..30)], 0.1, &mut r)).collect();
        let voc = Vocabulary::train(&[q.clone(), t.clone()], &TrainingOptions::default().with_shape(4, 2)).unwrap();
        let (_, fq) = voc.transform_with_features(&q, 2).unwrap();
        let (_, ft) = voc.transform_with_features(&t, 2).unwrap();
        let o = MatchOptions::default().with_mutual_check(mutual);
        prop_assert_eq!(match_by_nodes(&q, &fq, &t, &ft, &o).unwrap(), match_brute_force(&q, &t, &o).unwrap());
    }
}
