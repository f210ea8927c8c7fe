//! Progressive sampling and its stopping rule (PROSAC).
//!
//! O. Chum and J. Matas, "Matching with PROSAC — Progressive Sample Consensus", CVPR 2005.
//! When the correspondences come ordered best first (by descriptor distance, say), samples
//! are drawn from a growing prefix `U_n` of the `N` correspondences: the `n`-th one with
//! `m - 1` others from `U_{n-1}`, `n` growing on the schedule that makes the sampling
//! equivalent to RANSAC's after `T_N` samples (`T_N` = [`PROSAC_T_N`]):
//!
//! `T_m = T_N prod_{i<m} (m - i) / (N - i)`, `T_{n+1} = T_n (n + 1) / (n + 1 - m)`,
//! `T'_m = 1`, `T'_{n+1} = T'_n + ceil(T_{n+1} - T_n)`, and `n` grows when the sample count
//! `t` reaches `T'_n`; once `t > T'_n` the sample is drawn from all of `U_n` (section 2.2).
//!
//! The search may stop (section 2.3) once, for some prefix `U_n` whose inlier count `I_n`
//! (under the best model so far) is not explained by chance, the samples drawn would have
//! found an all-inlier sample of `U_n` at the stated confidence: `t >= k_n` with
//! `k_n = ln(1 - confidence) / ln(1 - (I_n / n)^m)`; the prefix `U_N` gives RANSAC's count.
//! Non-randomness: `I_n >= m + mu + z sigma`, the normal approximation (the paper's) of the
//! binomial tail of the support of a wrong model, `mu = (n - m) beta`,
//! `sigma^2 = (n - m) beta (1 - beta)`, `z = 1.645` (probability 0.05), with `beta` =
//! [`PROSAC_BETA`], the chance that a random correspondence supports a wrong model; and,
//! here, `I_n >= min_inliers`, the caller's smallest acceptable model. The guarantee is the
//! paper's: with the stated confidence no model with more inliers in
//! `U_n` was missed; with an order that says nothing of the inliers, PROSAC is RANSAC.

use rand_chacha::ChaCha8Rng;

use crate::ransac::adaptive_iterations;
use crate::relative_pose::sample_distinct;

/// `T_N`, the number of samples after which the progressive sampling is RANSAC's (the
/// paper's value).
pub(crate) const PROSAC_T_N: f64 = 200_000.0;

/// The probability that a random correspondence supports a wrong model, for the
/// non-randomness test: 0.05, conservative for the angular thresholds of a few pixels used
/// here (a wrong epipolar geometry is supported by a random correspondence within a band of
/// twice the threshold, about 1 % of the field of view).
pub(crate) const PROSAC_BETA: f64 = 0.05;

/// The progressive sampler over `N` correspondences ordered best first.
#[derive(Debug, Clone)]
pub(crate) struct ProsacSampler {
    total: usize,
    size: usize,
    /// The current prefix size `n`.
    n: usize,
    /// Samples drawn, `t`.
    t: usize,
    /// `T_n`.
    t_n: f64,
    /// `T'_n`.
    t_prime: usize,
}

impl ProsacSampler {
    /// A sampler of `size`-samples from `total >= size` correspondences.
    pub(crate) fn new(total: usize, size: usize) -> Self {
        let mut t_n = PROSAC_T_N;
        for i in 0..size {
            t_n *= (size - i) as f64 / (total - i) as f64;
        }
        Self {
            total,
            size,
            n: size,
            t: 0,
            t_n,
            t_prime: 1,
        }
    }

    /// Draws the next sample into `out` (`size` distinct indices below `total`).
    pub(crate) fn sample(&mut self, rng: &mut ChaCha8Rng, out: &mut [usize]) {
        self.t += 1;
        if self.t == self.t_prime && self.n < self.total {
            let next = self.t_n * (self.n + 1) as f64 / (self.n + 1 - self.size) as f64;
            self.t_prime += ((next - self.t_n).ceil() as usize).max(1);
            self.t_n = next;
            self.n += 1;
        }
        if self.t_prime < self.t || self.n == self.size {
            sample_distinct(rng, self.n, out);
        } else {
            let (last, rest) = (self.n - 1, self.size - 1);
            sample_distinct(rng, last, &mut out[..rest]);
            out[rest] = last;
        }
    }
}

/// The smallest inlier count of the prefix `U_n` that a wrong model does not reach by chance
/// (probability 0.05).
fn non_random_minimum(n: usize, size: usize) -> f64 {
    let trials = n.saturating_sub(size) as f64;
    size as f64 + trials * PROSAC_BETA + 1.645 * (trials * PROSAC_BETA * (1.0 - PROSAC_BETA)).sqrt()
}

/// The samples PROSAC needs for the best model so far, whose inliers are `inliers` (indices
/// in increasing order into the `total` correspondences, ordered best first): the least
/// `k_n` over the prefixes that pass the non-randomness test and hold at least
/// `min_inliers` inliers (a prefix counts only if its inliers alone would make an acceptable
/// model: the normal approximation says little about a handful of correspondences), and
/// RANSAC's count on all correspondences ([`adaptive_iterations`], with its `min_inliers`
/// floor) at most.
pub(crate) fn prosac_iterations(
    inliers: &[usize],
    total: usize,
    min_inliers: usize,
    size: usize,
    confidence: f64,
) -> usize {
    let mut needed =
        adaptive_iterations(inliers.len(), min_inliers, total, size as i32, confidence);
    let mut count = 0;
    let mut next = inliers.iter().peekable();
    for n in 1..total {
        while next.next_if(|&&i| i < n).is_some() {
            count += 1;
        }
        if n >= size && count >= min_inliers && count as f64 >= non_random_minimum(n, size) {
            needed = needed.min(adaptive_iterations(count, 0, n, size as i32, confidence));
        }
    }
    needed
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;

    use super::*;

    #[test]
    fn samples_grow_from_the_best_and_hold_the_newest() {
        let mut sampler = ProsacSampler::new(300, 5);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let mut out = [0; 5];
        let mut largest = 0;
        for t in 1..=200 {
            sampler.sample(&mut rng, &mut out);
            let mut sorted = out;
            sorted.sort_unstable();
            assert!(sorted.windows(2).all(|w| w[0] < w[1]), "{out:?}");
            let max = *sorted.last().unwrap();
            // The prefix grows by at most one correspondence per sample at first.
            assert!(max < 5 + t, "sample {t}: {out:?}");
            largest = largest.max(max);
        }
        // After 200 samples the prefix is still far from all 300 correspondences...
        assert!(largest < 220, "{largest}");
        // ... and after T_N samples it is all of them.
        let mut sampler = ProsacSampler::new(40, 5);
        let mut seen = [false; 40];
        for _ in 0..(PROSAC_T_N as usize + 1000) {
            sampler.sample(&mut rng, &mut out);
            out.iter().for_each(|&i| seen[i] = true);
        }
        assert!(seen.iter().all(|&s| s));
        assert_eq!(sampler.n, 40);
    }

    #[test]
    fn stops_early_when_the_best_correspondences_are_inliers() {
        // 500 correspondences, the first 100 inliers, then one in five: 180 inliers (36 %).
        let inliers: Vec<usize> = (0..500).filter(|&i| i < 100 || i % 5 == 0).collect();
        let ransac = adaptive_iterations(inliers.len(), 30, 500, 5, 0.999);
        let prosac = prosac_iterations(&inliers, 500, 30, 5, 0.999);
        assert!(ransac > 500, "{ransac}");
        assert_eq!(prosac, 0, "a prefix of all inliers needs no more samples");
        // An order that says nothing: inliers spread evenly, PROSAC is RANSAC (no prefix does
        // much better than the whole).
        let spread: Vec<usize> = (0..500).filter(|&i| i % 3 == 0).collect();
        let r = adaptive_iterations(spread.len(), 30, 500, 5, 0.999);
        let p = prosac_iterations(&spread, 500, 30, 5, 0.999);
        assert!(p as f64 >= 0.5 * r as f64 && p <= r, "{p} {r}");
        // A chance agreement of a few top correspondences is not enough to stop.
        let chance: Vec<usize> = vec![0, 1, 2, 3, 4, 5, 100, 200, 300, 400];
        assert!(prosac_iterations(&chance, 500, 30, 5, 0.999) > 1000);
    }
}
