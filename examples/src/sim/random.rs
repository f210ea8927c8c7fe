//! Seeded random streams and the random pieces of features (descriptors, bit-flip noise).
//!
//! Every random process of the simulator draws from its own ChaCha8 stream, keyed by the
//! scenario's seed, a purpose tag and up to two indices (frame, camera). Streams do not depend
//! on the order in which they are used, so a world is the same whatever the thread count.

use rand::{Rng, RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::data::BinaryDescriptor;

/// What a random stream is for; each purpose has its own streams.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Purpose {
    /// The static world: surfaces, landmarks, their descriptors.
    World = 1,
    /// Moving objects.
    Movers = 2,
    /// Features of one survey image.
    SurveyImage = 3,
    /// Features of one log image.
    LogImage = 4,
    /// Map-point error.
    MapError = 5,
    /// Odometry noise.
    Odometry = 6,
}

/// The stream for `purpose` and the indices `a`, `b`: the ChaCha8 key is the seed, the
/// purpose and the two indices, so distinct arguments give independent streams.
pub(crate) fn stream(seed: u64, purpose: Purpose, a: u64, b: u64) -> ChaCha8Rng {
    let mut key = [0u8; 32];
    key[..8].copy_from_slice(&seed.to_le_bytes());
    key[8..16].copy_from_slice(&(purpose as u64).to_le_bytes());
    key[16..24].copy_from_slice(&a.to_le_bytes());
    key[24..].copy_from_slice(&b.to_le_bytes());
    ChaCha8Rng::from_seed(key)
}

/// A uniformly random 256-bit descriptor.
pub(crate) fn random_descriptor(rng: &mut impl Rng) -> BinaryDescriptor {
    [
        rng.next_u64(),
        rng.next_u64(),
        rng.next_u64(),
        rng.next_u64(),
    ]
}

/// Flips every bit of a descriptor independently with probability `p`: the number of flips
/// is drawn from the binomial distribution B(256, p) by inverting its cumulative distribution
/// (tabulated once), then that many distinct bit positions uniformly at random. That is the
/// same distribution with one uniform draw plus about one draw per flip.
#[derive(Clone, Debug)]
pub(crate) struct BitFlips {
    /// `cdf[k]` = P(at most k flips) of B(256, min(p, 1 - p)); empty for no flips.
    cdf: Vec<f64>,
    /// `p > 0.5`: the mask is drawn for `1 - p` and inverted.
    invert: bool,
}

impl BitFlips {
    /// Flips with probability `p` (clamped to `[0, 1]`).
    pub(crate) fn new(p: f64) -> Self {
        let p = if p.is_nan() { 0.0 } else { p.clamp(0.0, 1.0) };
        let invert = p > 0.5;
        let q = if invert { 1.0 - p } else { p };
        let mut cdf = Vec::new();
        if q > 0.0 {
            // pmf(0) = (1 - q)^256 >= 2^-256: no underflow; pmf(k + 1) by the ratio.
            let mut pmf = (1.0 - q).powi(256);
            let mut total = 0.0;
            for k in 0..=256u32 {
                total += pmf;
                cdf.push(total);
                pmf *= f64::from(256 - k) / f64::from(k + 1) * q / (1.0 - q);
            }
        }
        Self { cdf, invert }
    }

    /// `d` with its bits flipped.
    pub(crate) fn apply(&self, d: &BinaryDescriptor, rng: &mut impl Rng) -> BinaryDescriptor {
        let mut mask = [0u64; 4];
        if let Some(total) = self.cdf.last() {
            let u = rng.random::<f64>() * total;
            let n = self.cdf.partition_point(|c| *c <= u).min(256);
            let mut placed = 0;
            while placed < n {
                let bit = (rng.next_u32() & 255) as usize;
                let (w, b) = (bit / 64, 1u64 << (bit % 64));
                if mask[w] & b == 0 {
                    mask[w] |= b;
                    placed += 1;
                }
            }
        }
        if self.invert {
            mask = mask.map(|m| !m);
        }
        [
            d[0] ^ mask[0],
            d[1] ^ mask[1],
            d[2] ^ mask[2],
            d[3] ^ mask[3],
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bit_flips_have_the_requested_rate() {
        let mut rng = stream(7, Purpose::LogImage, 0, 0);
        let d = random_descriptor(&mut rng);
        let p = 0.05;
        let flips = BitFlips::new(p);
        let n = 4000;
        let mut total = 0u64;
        let mut per_bit = [0u32; 256];
        for _ in 0..n {
            let f = flips.apply(&d, &mut rng);
            for (w, (a, b)) in f.iter().zip(&d).enumerate() {
                let x = a ^ b;
                total += u64::from(x.count_ones());
                for (k, c) in per_bit[64 * w..64 * (w + 1)].iter_mut().enumerate() {
                    *c += u32::from((x >> k) & 1 == 1);
                }
            }
        }
        // Mean flips per descriptor 256 p = 12.8; standard error sqrt(256 p (1 - p) / n).
        let mean = total as f64 / f64::from(n);
        let se = (256.0 * p * (1.0 - p) / f64::from(n)).sqrt();
        assert!((mean - 256.0 * p).abs() < 5.0 * se, "mean flips {mean}");
        // Every bit position is flipped about as often: 4000 p = 200 times, standard deviation
        // 13.8.
        assert!(
            per_bit.iter().all(|c| (140..260).contains(c)),
            "{per_bit:?}"
        );
        // No flips and all flips.
        assert_eq!(BitFlips::new(0.0).apply(&d, &mut rng), d);
        assert_eq!(BitFlips::new(1.0).apply(&d, &mut rng), d.map(|w| !w));
    }

    #[test]
    fn streams_differ_by_every_argument() {
        let base = stream(1, Purpose::World, 2, 3).next_u64();
        assert_ne!(base, stream(2, Purpose::World, 2, 3).next_u64());
        assert_ne!(base, stream(1, Purpose::Movers, 2, 3).next_u64());
        assert_ne!(base, stream(1, Purpose::World, 3, 3).next_u64());
        assert_ne!(base, stream(1, Purpose::World, 2, 4).next_u64());
        assert_eq!(base, stream(1, Purpose::World, 2, 3).next_u64());
    }
}
