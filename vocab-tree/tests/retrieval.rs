//! Retrieval on synthetic data: images along a path see overlapping windows of scene points
//! through noisy, incomplete observations; a query revisits a database viewpoint and must
//! find the image it truly overlaps most in its top 10.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::sync::Arc;

use common::{World, flip_bits, perturb, random_orb, random_surf, rng};
use ibc_vocab_tree::{Database, Descriptor, QueryOptions, TrainingOptions, Vocabulary};
use rand::{Rng, RngExt};

/// Database images.
const IMAGES: usize = 150;
/// Scene points between consecutive database images.
const STRIDE: usize = 40;
/// Scene points in view of one image.
const WIDTH: usize = 150;
/// Queries (at least 100, so that 99 % is a meaningful bar).
const QUERIES: usize = 300;

/// The image `start .. start + WIDTH` with 20 % of the points missed by the detector.
fn observe<D: Copy>(
    world: &World<D>,
    start: usize,
    rng: &mut impl Rng,
    noise: &mut impl FnMut(&D, &mut rand_chacha::ChaCha8Rng) -> D,
    noise_rng: &mut rand_chacha::ChaCha8Rng,
) -> Vec<D> {
    let keep: Vec<bool> = (0..WIDTH).map(|_| rng.random::<f64>() >= 0.2).collect();
    let mut k = keep.iter();
    world
        .image(start, WIDTH, &mut |d| noise(d, noise_rng))
        .into_iter()
        .filter(|_| *k.next().unwrap_or(&true))
        .collect()
}

/// Builds the world, trains on the database images, and returns the fraction of queries
/// whose truly overlapping image is in the top 10 (and the top-1 fraction).
fn retrieval_rate<D: Descriptor>(
    random: impl Fn(&mut rand_chacha::ChaCha8Rng) -> D,
    mut noise: impl FnMut(&D, &mut rand_chacha::ChaCha8Rng) -> D,
    seed: u64,
) -> (f64, f64) {
    let mut r = rng(seed);
    let mut noise_rng = rng(seed + 1);
    let world = World {
        points: (0..STRIDE * IMAGES + WIDTH)
            .map(|_| random(&mut r))
            .collect(),
    };
    let images: Vec<Vec<D>> = (0..IMAGES)
        .map(|i| observe(&world, i * STRIDE, &mut r, &mut noise, &mut noise_rng))
        .collect();
    let options = TrainingOptions::default().with_shape(10, 4).with_seed(seed);
    let vocabulary = Arc::new(Vocabulary::train(&images, &options).unwrap());
    let mut db = Database::new(Arc::clone(&vocabulary), None);
    for image in &images {
        db.add(image).unwrap();
    }
    let (mut top10, mut top1) = (0, 0);
    for q in 0..QUERIES {
        let truth = q % IMAGES;
        // A revisit up to half a stride away: `truth` overlaps it by >= 130 points, its
        // neighbours by <= 129.
        let offset = r.random_range(0..STRIDE / 2);
        let query = observe(
            &world,
            truth * STRIDE + offset,
            &mut r,
            &mut noise,
            &mut noise_rng,
        );
        let results = db.query(&vocabulary.transform(&query), &QueryOptions::default());
        assert!(results.len() <= 10);
        if results.iter().any(|x| x.image as usize == truth) {
            top10 += 1;
        }
        if results.first().is_some_and(|x| x.image as usize == truth) {
            top1 += 1;
        }
    }
    (
        f64::from(top10) / QUERIES as f64,
        f64::from(top1) / QUERIES as f64,
    )
}

#[test]
fn binary_retrieval_finds_the_overlapping_image_in_the_top_10() {
    // ORB-like: each of the 256 bits flips with probability 8 % (about 20 bits per
    // observation).
    let (top10, top1) = retrieval_rate(random_orb, |d, r| flip_bits(d, 0.08, r), 100);
    println!("binary: top-10 {top10}, top-1 {top1}");
    assert!(top10 >= 0.99, "top-10 rate {top10}");
}

#[test]
fn float_retrieval_finds_the_overlapping_image_in_the_top_10() {
    // SURF-like: elements uniform in [-0.5, 0.5), observed with Gaussian noise of 0.05.
    let (top10, top1) = retrieval_rate(random_surf, |d, r| perturb(d, 0.05, r), 200);
    println!("float: top-10 {top10}, top-1 {top1}");
    assert!(top10 >= 0.99, "top-10 rate {top10}");
}
