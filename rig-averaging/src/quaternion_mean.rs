//! Weighted average of unit quaternions by the eigenvector method.
//!
//! F. L. Markley, Y. Cheng, J. L. Crassidis and Y. Oshman, "Averaging Quaternions",
//! *Journal of Guidance, Control, and Dynamics* 30(4):1193-1197, 2007.
//!
//! With weights `w_i > 0` and unit quaternions `q_i`, the average is the unit vector `q` that
//! maximizes `q^T M q` with `M = sum_i w_i q_i q_i^T`: the eigenvector of `M`'s largest
//! eigenvalue. Since `||R(q) - R(q_i)||_F^2 = 8 (1 - (q . q_i)^2)`, the same `q` minimizes
//! `sum_i w_i ||R(q) - R(q_i)||_F^2`: it is the chordal L2 mean, equal to the projection of
//! `sum_i w_i R_i` onto SO(3). `q_i q_i^T` does not change when `q_i` is negated, so the result
//! does not depend on the sign of any input (bit for bit), which the naive normalized sum of
//! quaternions cannot offer.
//!
//! The mean is unique when the largest eigenvalue is simple. This module reports
//! `conditioning = (lambda_1 - lambda_2) / sum_i w_i`, between 0 (no unique mean, for example
//! `{identity, 180 degrees about z}` with equal weights) and 1 (all inputs equal). By the
//! Davis-Kahan theorem a perturbation `E` of `M` moves the mean by at most about
//! `||E|| / (lambda_1 - lambda_2)`, so the angular error of the mean scales as
//! (relative perturbation of the inputs) / conditioning. For two rotations `theta` apart with
//! equal weights, `conditioning = cos(theta / 2)`.

use nalgebra::{Quaternion, UnitQuaternion};

use crate::eigen4::{Sym4, symmetric_eigen4};
use crate::error::RigAveragingError;

/// Largest accepted `| ||q|| - 1 |` for an input quaternion.
///
/// nalgebra keeps unit quaternions within a few ulps of norm 1; chaining thousands of products
/// drifts by about 1e-13. 1e-6 lets any rounding through and rejects quaternions that were
/// never normalized (or were built with `new_unchecked` from arbitrary numbers). Inputs are
/// used as given, not renormalized: a norm of `1 + d` acts as a weight of `(1 + d)^2`.
pub const UNIT_NORM_TOLERANCE: f64 = 1e-6;

/// The result of Markley averaging.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuaternionMean {
    /// The mean rotation, with the sign convention `w > 0`; when `w == 0` exactly, the first
    /// non-zero of `x, y, z` is positive.
    pub mean: UnitQuaternion<f64>,
    /// `(lambda_1 - lambda_2) / sum_i w_i`, in `[0, 1]`: the gap between the two largest
    /// eigenvalues of `M = sum_i w_i q_i q_i^T` over the weight sum. Near 0 the mean is not
    /// unique and `mean` is one arbitrary (but deterministic) member of a set of solutions.
    pub conditioning: f64,
    /// The eigenvalues of `M / sum_i w_i`, largest first; they sum to 1 for unit inputs.
    pub eigenvalues: [f64; 4],
}

impl QuaternionMean {
    /// Whether the mean is unique to within `min_conditioning` (see [`QuaternionMean::conditioning`]).
    ///
    /// Rounding alone perturbs the mean by about `1e-16 / conditioning` radians, and input
    /// noise `sigma` by about `sigma / conditioning`; pick the threshold from the error you can
    /// accept.
    pub fn is_well_conditioned(&self, min_conditioning: f64) -> bool {
        self.conditioning >= min_conditioning
    }
}

/// Streaming accumulator of `M = sum_i w_i q_i q_i^T` (10 distinct entries) and the weight sum.
///
/// Useful when the rotations are produced one by one and should not be collected in a slice.
/// Weights are used as given (no rescaling), so their sum must stay a normal, finite `f64`.
///
/// ```
/// use ibc_rig_averaging::MarkleyAccumulator;
/// use nalgebra::UnitQuaternion;
///
/// let mut acc = MarkleyAccumulator::new();
/// acc.add(&UnitQuaternion::from_euler_angles(0.0, 0.0, 0.1), 1.0)?;
/// acc.add(&UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3), 1.0)?;
/// let mean = acc.finish()?;
/// assert!((mean.mean.euler_angles().2 - 0.2).abs() < 1e-12);
/// # Ok::<(), ibc_rig_averaging::RigAveragingError>(())
/// ```
#[derive(Clone, Debug, Default)]
pub struct MarkleyAccumulator {
    /// Upper triangle of `M` in row order: (0,0) (0,1) (0,2) (0,3) (1,1) (1,2) (1,3) (2,2)
    /// (2,3) (3,3), components ordered `w, x, y, z`.
    upper: [f64; 10],
    weight_sum: f64,
    count: usize,
}

impl MarkleyAccumulator {
    /// An empty accumulator.
    pub fn new() -> Self {
        Self::default()
    }

    /// Number of rotations added so far.
    pub fn len(&self) -> usize {
        self.count
    }

    /// Whether no rotation was added yet.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Sum of the weights added so far.
    pub fn weight_sum(&self) -> f64 {
        self.weight_sum
    }

    /// Adds `rotation` with `weight`.
    ///
    /// # Errors
    /// [`RigAveragingError::InvalidWeight`] for a weight that is not finite and positive,
    /// [`RigAveragingError::NotUnitQuaternion`] for a quaternion off the unit sphere by more
    /// than [`UNIT_NORM_TOLERANCE`]. The index in the error is the number of rotations added
    /// before this one. Nothing is added on error.
    pub fn add(
        &mut self,
        rotation: &UnitQuaternion<f64>,
        weight: f64,
    ) -> Result<(), RigAveragingError> {
        check_weight(self.count, weight)?;
        check_unit(self.count, rotation.quaternion())?;
        self.add_unchecked(rotation.quaternion(), weight);
        Ok(())
    }

    /// Adds a quaternion already known to be unit with a weight already known to be valid.
    #[inline]
    pub(crate) fn add_unchecked(&mut self, q: &Quaternion<f64>, weight: f64) {
        let c = [q.w, q.i, q.j, q.k];
        let wc = [weight * c[0], weight * c[1], weight * c[2], weight * c[3]];
        let u = &mut self.upper;
        u[0] += wc[0] * c[0];
        u[1] += wc[0] * c[1];
        u[2] += wc[0] * c[2];
        u[3] += wc[0] * c[3];
        u[4] += wc[1] * c[1];
        u[5] += wc[1] * c[2];
        u[6] += wc[1] * c[3];
        u[7] += wc[2] * c[2];
        u[8] += wc[2] * c[3];
        u[9] += wc[3] * c[3];
        self.weight_sum += weight;
        self.count += 1;
    }

    /// The Markley mean of everything added.
    ///
    /// # Errors
    /// [`RigAveragingError::EmptyInput`] if nothing was added;
    /// [`RigAveragingError::WeightsOutOfRange`] if the weight sum overflowed or is subnormal.
    pub fn finish(&self) -> Result<QuaternionMean, RigAveragingError> {
        if self.count == 0 {
            return Err(RigAveragingError::EmptyInput);
        }
        if !self.weight_sum.is_normal() {
            return Err(RigAveragingError::WeightsOutOfRange {
                weight_sum: self.weight_sum,
            });
        }
        let u = &self.upper;
        let m: Sym4 = [
            [u[0], u[1], u[2], u[3]],
            [u[1], u[4], u[5], u[6]],
            [u[2], u[5], u[7], u[8]],
            [u[3], u[6], u[8], u[9]],
        ];
        let eigen = symmetric_eigen4(m);
        let order = eigen.descending_order();
        let inv_w = 1.0 / self.weight_sum;
        let eigenvalues = order.map(|k| eigen.values[k] * inv_w);
        let top = order[0];
        let mut v = [
            eigen.vectors[0][top],
            eigen.vectors[1][top],
            eigen.vectors[2][top],
            eigen.vectors[3][top],
        ];
        if v[0] < 0.0 || (v[0] == 0.0 && first_nonzero_is_negative(&v[1..])) {
            v = v.map(|x| -x);
        }
        let mean = UnitQuaternion::new_normalize(Quaternion::new(v[0], v[1], v[2], v[3]));
        Ok(QuaternionMean {
            mean,
            conditioning: (eigenvalues[0] - eigenvalues[1]).clamp(0.0, 1.0),
            eigenvalues,
        })
    }
}

fn first_nonzero_is_negative(xs: &[f64]) -> bool {
    xs.iter().find(|x| **x != 0.0).is_some_and(|x| *x < 0.0)
}

/// Weighted Markley average of unit quaternions.
///
/// `weights` is `None` for equal weights, or one finite positive weight per rotation. Weights
/// are divided by their maximum before accumulation, so any positive finite weights work and
/// only their ratios matter.
///
/// The result does not depend on the sign of any input quaternion. Cost: `O(N)` plus one
/// 4x4 symmetric eigen-decomposition (cyclic Jacobi, see the `eigen4` module).
///
/// # Errors
/// [`RigAveragingError::EmptyInput`], [`RigAveragingError::WeightCountMismatch`],
/// [`RigAveragingError::InvalidWeight`], [`RigAveragingError::NotUnitQuaternion`].
///
/// ```
/// use ibc_rig_averaging::quaternion_mean;
/// use nalgebra::{UnitQuaternion, Vector3};
///
/// let a = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.2);
/// let b = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.4);
/// // The sign of an input does not matter: -b is the same rotation as b.
/// let minus_b = UnitQuaternion::new_unchecked(-b.into_inner());
/// let mean = quaternion_mean(&[a, minus_b], Some(&[1.0, 3.0]))?;
/// // The chordal mean of two rotations about one axis lies between them, nearer the heavier.
/// assert!((mean.mean.angle() - 0.35).abs() < 2e-3);
/// assert!(mean.conditioning > 0.99);
/// # Ok::<(), ibc_rig_averaging::RigAveragingError>(())
/// ```
pub fn quaternion_mean(
    rotations: &[UnitQuaternion<f64>],
    weights: Option<&[f64]>,
) -> Result<QuaternionMean, RigAveragingError> {
    let w_max = max_weight(rotations.len(), weights)?;
    let mut acc = MarkleyAccumulator::new();
    for (i, q) in rotations.iter().enumerate() {
        check_unit(i, q.quaternion())?;
        acc.add_unchecked(q.quaternion(), scaled_weight(weights, i, w_max));
    }
    acc.finish()
}

/// Checks that `weight` is finite and strictly positive.
pub(crate) fn check_weight(index: usize, weight: f64) -> Result<(), RigAveragingError> {
    if weight.is_finite() && weight > 0.0 {
        Ok(())
    } else {
        Err(RigAveragingError::InvalidWeight { index, weight })
    }
}

/// Checks that `q` is finite and of unit norm within [`UNIT_NORM_TOLERANCE`].
pub(crate) fn check_unit(index: usize, q: &Quaternion<f64>) -> Result<(), RigAveragingError> {
    // Compare squared norms (no square root on the hot path); NaN fails both comparisons.
    const LOW: f64 = (1.0 - UNIT_NORM_TOLERANCE) * (1.0 - UNIT_NORM_TOLERANCE);
    const HIGH: f64 = (1.0 + UNIT_NORM_TOLERANCE) * (1.0 + UNIT_NORM_TOLERANCE);
    let norm_squared = q.coords.norm_squared();
    if (LOW..=HIGH).contains(&norm_squared) {
        Ok(())
    } else {
        Err(RigAveragingError::NotUnitQuaternion {
            index,
            norm: norm_squared.sqrt(),
        })
    }
}

/// Validates the input count and weights and returns `max(weights)` (1 without weights).
pub(crate) fn max_weight(n: usize, weights: Option<&[f64]>) -> Result<f64, RigAveragingError> {
    if n == 0 {
        return Err(RigAveragingError::EmptyInput);
    }
    let Some(weights) = weights else {
        return Ok(1.0);
    };
    if weights.len() != n {
        return Err(RigAveragingError::WeightCountMismatch {
            inputs: n,
            weights: weights.len(),
        });
    }
    let mut max = 0.0f64;
    for (i, &w) in weights.iter().enumerate() {
        check_weight(i, w)?;
        max = max.max(w);
    }
    Ok(max)
}

/// Weight `i` divided by `max` (in `(0, 1]`), or 1 without weights. Division rather than a
/// multiplication by `1 / max`, which would overflow for a subnormal `max`.
#[inline]
pub(crate) fn scaled_weight(weights: Option<&[f64]>, i: usize, max: f64) -> f64 {
    weights.map_or(1.0, |w| w[i] / max)
}
