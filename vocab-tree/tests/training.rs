//! Training: determinism per seed and thread count, termination on binary and float data,
//! more clusters than points, IDF weights, invalid input.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use approx::assert_relative_eq;
use common::{flip_bits, perturb, random_orb, random_surf, rng};
use ibc_vocab_tree::{
    Descriptor, OrbDescriptor, Surf64Descriptor, TrainingOptions, VocabError, Vocabulary,
};
use rand_chacha::ChaCha8Rng;

/// Images of noisy observations of `clusters` random prototypes.
fn noisy_images<D: Copy>(
    (images, per_image, clusters, seed): (usize, usize, usize, u64),
    random: impl Fn(&mut ChaCha8Rng) -> D,
    noise: impl Fn(&D, &mut ChaCha8Rng) -> D,
) -> Vec<Vec<D>> {
    let mut r = rng(seed);
    let protos: Vec<D> = (0..clusters).map(|_| random(&mut r)).collect();
    (0..images)
        .map(|i| {
            (0..per_image)
                .map(|j| noise(&protos[(i * 7 + j * 13) % clusters], &mut r))
                .collect()
        })
        .collect()
}

fn binary_images(
    images: usize,
    per_image: usize,
    clusters: usize,
    seed: u64,
) -> Vec<Vec<OrbDescriptor>> {
    noisy_images((images, per_image, clusters, seed), random_orb, |d, r| {
        flip_bits(d, 0.05, r)
    })
}

fn float_images(
    images: usize,
    per_image: usize,
    clusters: usize,
    seed: u64,
) -> Vec<Vec<Surf64Descriptor>> {
    noisy_images((images, per_image, clusters, seed), random_surf, |d, r| {
        perturb(d, 0.02, r)
    })
}

/// Trains on a rayon pool of `threads` threads.
fn train_on_threads<D: Descriptor>(
    threads: usize,
    images: &[Vec<D>],
    options: &TrainingOptions,
) -> Vocabulary<D> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| Vocabulary::train(images, options).unwrap())
}

#[test]
fn training_is_deterministic_per_seed_and_thread_count() {
    let images = binary_images(40, 100, 300, 1);
    let options = TrainingOptions::default().with_shape(6, 3).with_seed(42);
    let one = train_on_threads(1, &images, &options);
    let two = train_on_threads(2, &images, &options);
    let four = train_on_threads(4, &images, &options);
    assert_eq!(one.to_bytes(), two.to_bytes());
    assert_eq!(one.to_bytes(), four.to_bytes());
    // Same seed on the default pool: same vocabulary; another seed: another vocabulary.
    assert_eq!(Vocabulary::train(&images, &options).unwrap(), one);
    let other = Vocabulary::train(&images, &options.clone().with_seed(43)).unwrap();
    assert_ne!(other.to_bytes(), one.to_bytes());

    // Float sums are order-dependent: the fixed chunking must make them thread-independent.
    let images = float_images(30, 120, 200, 2);
    let options = TrainingOptions::default().with_shape(5, 3).with_seed(7);
    assert_eq!(
        train_on_threads(1, &images, &options).to_bytes(),
        train_on_threads(3, &images, &options).to_bytes()
    );
}

#[test]
fn training_terminates_on_binary_and_float_data() {
    // Binary: 12,000 descriptors, branching 10, depth 3.
    let images = binary_images(60, 200, 800, 3);
    let options = TrainingOptions::default().with_shape(10, 3).with_seed(1);
    let voc = Vocabulary::train(&images, &options).unwrap();
    assert!(voc.word_count() > 100 && voc.word_count() <= 1000);
    assert_eq!((voc.branching(), voc.depth()), (10, 3));

    // Float: tight clusters, near-duplicates and exact duplicates, which make unbounded
    // Lloyd loops oscillate; with `max_iterations` training always ends.
    let mut images = float_images(40, 150, 120, 4);
    let dup = images[0][0];
    images.push(vec![dup; 500]);
    let mut tiny = dup;
    tiny[0] += f32::EPSILON;
    images.push(vec![tiny; 10]);
    for iterations in [0, 1, 10] {
        let options = TrainingOptions::default()
            .with_shape(8, 3)
            .with_seed(5)
            .with_max_iterations(iterations);
        let voc = Vocabulary::train(&images, &options).unwrap();
        assert!(voc.word_count() >= 8 && voc.word_count() <= 512);
        // Every training descriptor reaches a word of non-negative weight.
        for w in voc.quantize(&images[0]) {
            assert!(voc.word_weight(w).unwrap() >= 0.0);
        }
    }
}

#[test]
fn more_clusters_than_points_gives_one_word_per_distinct_descriptor() {
    let mut r = rng(9);
    let distinct: Vec<OrbDescriptor> = (0..5).map(|_| random_orb(&mut r)).collect();
    // Two images, with repeats: 5 distinct descriptors for a 10 x 10 x 10 tree.
    let images = vec![
        vec![distinct[0], distinct[1], distinct[2], distinct[0]],
        vec![distinct[3], distinct[4], distinct[4]],
    ];
    let options = TrainingOptions::default().with_shape(10, 3);
    let voc = Vocabulary::train(&images, &options).unwrap();
    assert_eq!(voc.word_count(), 5);
    // k-means++ picks distinct seeds: each descriptor is a child of the root, a word at
    // depth 1 whose centroid is the descriptor itself.
    assert_eq!(voc.children(0).len(), 5);
    let mut words: Vec<u32> = voc.quantize(&distinct);
    for (d, &w) in distinct.iter().zip(&words) {
        let node = voc
            .children(0)
            .find(|&n| voc.node_word(n) == Some(w))
            .unwrap();
        assert_eq!(voc.centroid(node).unwrap(), d);
    }
    words.sort_unstable();
    words.dedup();
    assert_eq!(words.len(), 5);

    // A single distinct descriptor: one word.
    let voc = Vocabulary::train(&[vec![distinct[0]; 7]], &options).unwrap();
    assert_eq!(voc.word_count(), 1);
    // A single descriptor.
    let voc = Vocabulary::train(&[vec![distinct[1]]], &options).unwrap();
    assert_eq!(voc.word_count(), 1);
    assert_eq!(voc.word(&distinct[1]), 0);
    // One training image: idf = ln(1/1) = 0, so TF-IDF vectors are empty but TF ones are not.
    assert_eq!(voc.word_weight(0), Some(0.0));
    assert!(voc.transform(&[distinct[1]]).is_empty());
    let tf = voc.with_weighting(ibc_vocab_tree::Weighting::Tf);
    assert_eq!(tf.transform(&[distinct[1]]).entries(), &[(0, 1.0)]);
}

#[test]
fn idf_weights_are_ln_n_over_n_i() {
    // Four well-separated prototypes; word i is seen in the images listed for it.
    let mut r = rng(11);
    let protos: Vec<OrbDescriptor> = (0..4).map(|_| random_orb(&mut r)).collect();
    // Prototype 0 in all 5 images, 1 in 4, 2 in 2, 3 in 1; image 4 has one empty slot too.
    let images = vec![
        vec![protos[0], protos[1], protos[2], protos[3]],
        vec![protos[0], protos[1], protos[2]],
        vec![protos[0], protos[1]],
        vec![protos[0], protos[1], protos[1]],
        vec![protos[0]],
        vec![],
    ];
    let voc = Vocabulary::train(&images, &TrainingOptions::default().with_shape(4, 2)).unwrap();
    assert_eq!(voc.word_count(), 4);
    let n = images.len() as f64; // empty images count: N = 6
    for (proto, seen_in) in protos.iter().zip([5.0, 4.0, 2.0, 1.0]) {
        let w = voc.word(proto);
        assert_relative_eq!(
            f64::from(voc.word_weight(w).unwrap()),
            (n / seen_in).ln(),
            max_relative = 1e-6
        );
    }
}

#[test]
fn invalid_training_input_is_an_error() {
    let images = binary_images(3, 10, 5, 12);
    let bad_shape = |k, l| {
        Vocabulary::train(&images, &TrainingOptions::default().with_shape(k, l)).unwrap_err()
    };
    assert!(matches!(
        bad_shape(1, 3),
        VocabError::InvalidOption {
            name: "branching",
            ..
        }
    ));
    assert!(matches!(
        bad_shape(10, 0),
        VocabError::InvalidOption { name: "depth", .. }
    ));
    assert!(matches!(
        bad_shape(10, 33),
        VocabError::InvalidOption { name: "depth", .. }
    ));
    let empty: Vec<Vec<OrbDescriptor>> = vec![vec![], vec![]];
    assert!(matches!(
        Vocabulary::train(&empty, &TrainingOptions::default()),
        Err(VocabError::NoTrainingData)
    ));
    let mut floats = float_images(2, 5, 3, 13);
    floats[1][3][7] = f32::NAN;
    assert!(matches!(
        Vocabulary::train(&floats, &TrainingOptions::default()),
        Err(VocabError::NonFiniteDescriptor { image: 1, index: 3 })
    ));
}
