//! Synthetic data shared by the integration tests.

#![allow(dead_code)]

use ibc_vocab_tree::{OrbDescriptor, Scoring, Surf64Descriptor};
use rand::{Rng, RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Every scoring, in DBoW2's order.
pub const SCORINGS: [Scoring; 6] = [
    Scoring::L1,
    Scoring::L2,
    Scoring::ChiSquare,
    Scoring::KL,
    Scoring::Bhattacharyya,
    Scoring::DotProduct,
];

pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

pub fn random_orb(rng: &mut impl Rng) -> OrbDescriptor {
    [
        rng.next_u64(),
        rng.next_u64(),
        rng.next_u64(),
        rng.next_u64(),
    ]
}

pub fn random_surf(rng: &mut impl Rng) -> Surf64Descriptor {
    let mut d = [0f32; 64];
    for x in &mut d {
        *x = rng.random::<f32>() - 0.5;
    }
    d
}

/// `d` with each of its 256 bits flipped with probability `p`.
pub fn flip_bits(d: &OrbDescriptor, p: f64, rng: &mut impl Rng) -> OrbDescriptor {
    let mut out = *d;
    for word in &mut out {
        for bit in 0..64 {
            if rng.random::<f64>() < p {
                *word ^= 1 << bit;
            }
        }
    }
    out
}

/// `d` plus Gaussian noise of standard deviation `sigma` on every element.
pub fn perturb(d: &Surf64Descriptor, sigma: f32, rng: &mut impl Rng) -> Surf64Descriptor {
    let normal = Normal::new(0.0f32, sigma).unwrap();
    let mut out = *d;
    for x in &mut out {
        *x += normal.sample(rng);
    }
    out
}

/// A "world" of scene points seen along a path: image `i` sees the points
/// `start .. start + width` of the world, each through a fresh noisy observation.
pub struct World<D> {
    pub points: Vec<D>,
}

impl<D: Copy> World<D> {
    pub fn image(&self, start: usize, width: usize, observe: &mut impl FnMut(&D) -> D) -> Vec<D> {
        self.points[start..start + width]
            .iter()
            .map(observe)
            .collect()
    }
}
