//! Robust averaging of rotations and poses: a Cauchy M-estimator solved by iteratively
//! reweighted Markley means, started from a weighted medoid.
//!
//! The scheme is the iteratively reweighted least squares of robust statistics (P. J. Huber,
//! *Robust Statistics*, 1981, section 7.8) applied to rotation averaging as surveyed by
//! R. Hartley, J. Trumpf, Y. Dai and H. Li, "Rotation Averaging", *International Journal of
//! Computer Vision* 103(3):267-305, 2013 (section 6, robust averaging): each step solves a
//! weighted chordal L2 problem, here exactly by Markley's eigenvector method, with weights
//! `psi(r) / r` of the current residuals. The loss is Cauchy, `rho(r) = c^2/2 log(1 + r^2/c^2)`,
//! whose weight `1 / (1 + r^2 / c^2)` tends to zero for gross outliers (a redescending
//! estimator), so one wrong input among many ends with a negligible weight instead of pulling
//! the mean by `1/N` of its error.
//!
//! 1. Start: the weighted medoid of the rotations (the input minimizing
//!    `sum_j w_j sin(theta_ij / 2)`, a chordal L1 criterion with breakdown point 1/2), and for
//!    poses the coordinate-wise weighted median of the translations.
//! 2. Scale: `c = ADAPTIVE_SCALE_FACTOR * median residual` at the start, unless given; for
//!    poses one scale for the rotation angle and one for the translation distance.
//! 3. Iterate: `omega_i = w_i / (1 + (theta_i / c_r)^2 + (d_i / c_t)^2)`, new mean = Markley
//!    mean and weighted translation mean with weights `omega_i`, until the step is below
//!    `tolerance` in units of the scales.
//!
//! With fewer than three inputs there is no majority to trust: the result is the plain mean,
//! with infinite scales and all robust weights 1.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use crate::NonExhaustive;
use crate::error::RigAveragingError;
use crate::pose_mean::{PoseMean, check_translation, weighted_pose_mean};
use crate::quaternion_mean::{QuaternionMean, check_unit, max_weight, scaled_weight};

/// Factor from the median residual at the starting estimate to the Cauchy scale.
///
/// For isotropic Gaussian errors of standard deviation `sigma` per axis in 3-D, residual norms
/// follow `sigma * chi_3`, whose median is `1.5382 sigma` (the square root of the `chi^2_3`
/// median 2.3660); the Cauchy scale with 95 % asymptotic efficiency under Gaussian noise is
/// `2.3849 sigma` (Holland and Welsch, "Robust regression using iteratively reweighted
/// least-squares", 1977). Hence `2.3849 / 1.5382`.
pub const ADAPTIVE_SCALE_FACTOR: f64 = 2.3849 / 1.5382;

/// Smallest adaptive rotation scale, radians: with exact inliers the median residual is 0, and
/// the scale must stay positive. 1e-12 rad is far below any measured rotation noise.
pub const MIN_ROTATION_SCALE: f64 = 1e-12;

/// Smallest adaptive translation scale, metres (same reason as [`MIN_ROTATION_SCALE`]).
pub const MIN_TRANSLATION_SCALE: f64 = 1e-12;

/// Options of [`robust_quaternion_mean`] and [`robust_pose_mean`].
///
/// The paper averages without robustness; these defaults are this crate's: scales estimated
/// from the data, at most 50 iterations, convergence when a step is below `1e-10` of the scale.
/// Write them as one expression:
///
/// ```
/// use ibc_rig_averaging::RobustOptions;
///
/// let options = RobustOptions { rotation_scale: Some(0.01), ..Default::default() };
/// assert_eq!(options.max_iterations, 50);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RobustOptions {
    /// Cauchy scale of the rotation residual angle, radians; `None` (default) estimates it as
    /// [`ADAPTIVE_SCALE_FACTOR`] times the median residual at the medoid, at least
    /// [`MIN_ROTATION_SCALE`]. A residual of `c` gets weight 1/2, of `10 c` about 1/100.
    pub rotation_scale: Option<f64>,
    /// Cauchy scale of the translation residual distance, metres; `None` (default) estimates it
    /// like the rotation scale (at least [`MIN_TRANSLATION_SCALE`]). Unused for rotations alone.
    pub translation_scale: Option<f64>,
    /// Maximum number of reweighted means computed (default 50; must be at least 1).
    pub max_iterations: usize,
    /// Convergence threshold on the step of the mean, in units of the scales (default 1e-10):
    /// stop when `angle step / c_r` and `translation step / c_t` are both below it.
    pub tolerance: f64,
    /// Keeps the struct open to new fields: write it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for RobustOptions {
    fn default() -> Self {
        Self {
            rotation_scale: None,
            translation_scale: None,
            max_iterations: 50,
            tolerance: 1e-10,
            non_exhaustive: NonExhaustive(()),
        }
    }
}

impl RobustOptions {
    /// Sets a fixed rotation scale in radians.
    #[must_use]
    pub fn with_rotation_scale(mut self, radians: f64) -> Self {
        self.rotation_scale = Some(radians);
        self
    }

    /// Sets a fixed translation scale in metres.
    #[must_use]
    pub fn with_translation_scale(mut self, metres: f64) -> Self {
        self.translation_scale = Some(metres);
        self
    }

    /// Sets the maximum number of iterations.
    #[must_use]
    pub fn with_max_iterations(mut self, iterations: usize) -> Self {
        self.max_iterations = iterations;
        self
    }

    /// Sets the convergence tolerance (in units of the scales).
    #[must_use]
    pub fn with_tolerance(mut self, tolerance: f64) -> Self {
        self.tolerance = tolerance;
        self
    }

    /// Checks every option against its domain.
    pub(crate) fn validate(&self) -> Result<(), RigAveragingError> {
        let bad_scale = |s: Option<f64>| s.is_some_and(|s| !(s.is_finite() && s > 0.0));
        if bad_scale(self.rotation_scale) {
            return Err(RigAveragingError::InvalidRobustOptions {
                option: "rotation_scale",
                reason: "must be finite and positive",
            });
        }
        if bad_scale(self.translation_scale) {
            return Err(RigAveragingError::InvalidRobustOptions {
                option: "translation_scale",
                reason: "must be finite and positive",
            });
        }
        if self.max_iterations == 0 {
            return Err(RigAveragingError::InvalidRobustOptions {
                option: "max_iterations",
                reason: "must be at least 1",
            });
        }
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return Err(RigAveragingError::InvalidRobustOptions {
                option: "tolerance",
                reason: "must be finite and non-negative",
            });
        }
        Ok(())
    }
}

/// How a robust mean was reached.
#[derive(Clone, Debug, PartialEq)]
pub struct RobustDiagnostics {
    /// Per input, the Cauchy factor `1 / (1 + (theta_i/c_r)^2 + (d_i/c_t)^2)` in `(0, 1]` of the
    /// last iteration (the caller's weights are multiplied by it). Near 0: an outlier.
    pub robust_weights: Vec<f64>,
    /// The rotation scale used, radians (infinite with fewer than three inputs).
    pub rotation_scale: f64,
    /// The translation scale used, metres (`None` for rotations alone; infinite with fewer
    /// than three inputs).
    pub translation_scale: Option<f64>,
    /// Number of reweighted means computed.
    pub iterations: usize,
    /// Whether the step fell below the tolerance within `max_iterations`. When false the mean
    /// is the last iterate: still a weighted mean of the inputs, but not a stationary point.
    pub converged: bool,
}

/// A robust mean rotation.
#[derive(Clone, Debug, PartialEq)]
pub struct RobustQuaternionMean {
    /// The final weighted Markley mean (weights: the caller's times the robust weights), with
    /// its conditioning figure.
    pub mean: QuaternionMean,
    /// Scales, robust weights and convergence.
    pub diagnostics: RobustDiagnostics,
}

/// A robust mean pose.
#[derive(Clone, Debug, PartialEq)]
pub struct RobustPoseMean {
    /// The final weighted pose mean (weights: the caller's times the robust weights).
    pub mean: PoseMean,
    /// Scales, robust weights and convergence.
    pub diagnostics: RobustDiagnostics,
}

/// Robust weighted mean of rotations: a Cauchy M-estimator of the rotation angle residuals
/// (see the module documentation).
///
/// `weights`: `None` for equal weights or one finite positive weight per rotation.
/// Cost: `O(N^2)` for the medoid start plus `O(N)` per iteration.
///
/// # Errors
/// As [`quaternion_mean`](crate::quaternion_mean), plus
/// [`RigAveragingError::InvalidRobustOptions`].
///
/// ```
/// use ibc_rig_averaging::{RobustOptions, quaternion_mean, robust_quaternion_mean};
/// use nalgebra::{UnitQuaternion, Vector3};
///
/// // Nine rotations near 0.1 rad about z, one wrong by 90 degrees.
/// let mut rotations: Vec<_> = (0..9)
///     .map(|i| UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.1 + 1e-3 * (i as f64 - 4.0)))
///     .collect();
/// rotations.push(UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 1.6));
/// let plain = quaternion_mean(&rotations, None)?;
/// let robust = robust_quaternion_mean(&rotations, None, &RobustOptions::default())?;
/// let truth = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.1);
/// assert!(plain.mean.angle_to(&truth) > 0.1);
/// assert!(robust.mean.mean.angle_to(&truth) < 1e-4);
/// assert!(robust.diagnostics.robust_weights[9] < 1e-3);
/// # Ok::<(), ibc_rig_averaging::RigAveragingError>(())
/// ```
pub fn robust_quaternion_mean(
    rotations: &[UnitQuaternion<f64>],
    weights: Option<&[f64]>,
    options: &RobustOptions,
) -> Result<RobustQuaternionMean, RigAveragingError> {
    options.validate()?;
    let w_max = max_weight(rotations.len(), weights)?;
    for (i, q) in rotations.iter().enumerate() {
        check_unit(i, q.quaternion())?;
    }
    let base: Vec<f64> = (0..rotations.len())
        .map(|i| scaled_weight(weights, i, w_max))
        .collect();
    let (mean, _, diagnostics) = reweighted_mean(rotations, None, &base, options)?;
    Ok(RobustQuaternionMean { mean, diagnostics })
}

/// Robust weighted mean of poses: one Cauchy weight per pose from its rotation angle and
/// translation distance residuals (see the module documentation), so a pose wrong in either
/// part is down-weighted as a whole.
///
/// # Errors
/// As [`pose_mean`](crate::pose_mean), plus [`RigAveragingError::InvalidRobustOptions`].
pub fn robust_pose_mean(
    poses: &[Isometry3<f64>],
    weights: Option<&[f64]>,
    options: &RobustOptions,
) -> Result<RobustPoseMean, RigAveragingError> {
    options.validate()?;
    let w_max = max_weight(poses.len(), weights)?;
    for (i, pose) in poses.iter().enumerate() {
        check_unit(i, pose.rotation.quaternion())?;
        check_translation(i, &pose.translation.vector)?;
    }
    let base: Vec<f64> = (0..poses.len())
        .map(|i| scaled_weight(weights, i, w_max))
        .collect();
    let rotations: Vec<UnitQuaternion<f64>> = poses.iter().map(|p| p.rotation).collect();
    let translations: Vec<Vector3<f64>> = poses.iter().map(|p| p.translation.vector).collect();
    let (rotation, translation, diagnostics) =
        reweighted_mean(&rotations, Some(&translations), &base, options)?;
    let translation = translation.unwrap_or_else(Vector3::zeros);
    Ok(RobustPoseMean {
        mean: PoseMean {
            mean: Isometry3::from_parts(Translation3::from(translation), rotation.mean),
            rotation,
        },
        diagnostics,
    })
}

/// The IRLS core on validated inputs; `base` holds the caller's weights scaled into `(0, 1]`.
fn reweighted_mean(
    rotations: &[UnitQuaternion<f64>],
    translations: Option<&[Vector3<f64>]>,
    base: &[f64],
    options: &RobustOptions,
) -> Result<(QuaternionMean, Option<Vector3<f64>>, RobustDiagnostics), RigAveragingError> {
    let n = rotations.len();
    if n < 3 {
        let (mean, translation) = weighted_step(rotations, translations, base)?;
        return Ok((
            mean,
            translation,
            RobustDiagnostics {
                robust_weights: vec![1.0; n],
                rotation_scale: f64::INFINITY,
                translation_scale: translations.map(|_| f64::INFINITY),
                iterations: 1,
                converged: true,
            },
        ));
    }

    let mut rotation = rotations[medoid(rotations, base)];
    let mut translation = translations.map(|t| coordinate_median(t, base));
    let mut theta: Vec<f64> = rotations.iter().map(|q| rotation.angle_to(q)).collect();
    let mut dist: Vec<f64> = match (translations, &translation) {
        (Some(ts), Some(t0)) => ts.iter().map(|t| (t - t0).norm()).collect(),
        _ => vec![0.0; n],
    };
    let c_r = options
        .rotation_scale
        .unwrap_or_else(|| (ADAPTIVE_SCALE_FACTOR * upper_median(&theta)).max(MIN_ROTATION_SCALE));
    let c_t = options.translation_scale.unwrap_or_else(|| {
        (ADAPTIVE_SCALE_FACTOR * upper_median(&dist)).max(MIN_TRANSLATION_SCALE)
    });

    let mut omega = vec![0.0; n];
    let mut iterations = 0;
    let mut converged = false;
    let mut mean = None;
    while iterations < options.max_iterations {
        iterations += 1;
        for i in 0..n {
            let r2 = (theta[i] / c_r).powi(2) + (dist[i] / c_t).powi(2);
            omega[i] = base[i] / (1.0 + r2);
        }
        let (step_mean, step_translation) = weighted_step(rotations, translations, &omega)?;
        let rotation_step = rotation.angle_to(&step_mean.mean) / c_r;
        let translation_step = match (&translation, &step_translation) {
            (Some(old), Some(new)) => (new - old).norm() / c_t,
            _ => 0.0,
        };
        rotation = step_mean.mean;
        translation = step_translation;
        mean = Some(step_mean);
        for (th, q) in theta.iter_mut().zip(rotations) {
            *th = rotation.angle_to(q);
        }
        if let (Some(ts), Some(t0)) = (translations, &translation) {
            for (d, t) in dist.iter_mut().zip(ts) {
                *d = (t - t0).norm();
            }
        }
        if rotation_step.max(translation_step) <= options.tolerance {
            converged = true;
            break;
        }
    }
    // `max_iterations >= 1` (validated), so the loop ran and `mean` is set; the fallback only
    // satisfies the type checker.
    let mean = match mean {
        Some(m) => m,
        None => weighted_step(rotations, translations, base)?.0,
    };
    let robust_weights = omega.iter().zip(base).map(|(o, b)| o / b).collect();
    Ok((
        mean,
        translation,
        RobustDiagnostics {
            robust_weights,
            rotation_scale: c_r,
            translation_scale: translations.map(|_| c_t),
            iterations,
            converged,
        },
    ))
}

/// One weighted Markley mean and weighted translation mean (weights may be tiny but not all
/// zero: the medoid start gives at least half the inputs a weight above a third of theirs).
fn weighted_step(
    rotations: &[UnitQuaternion<f64>],
    translations: Option<&[Vector3<f64>]>,
    weights: &[f64],
) -> Result<(QuaternionMean, Option<Vector3<f64>>), RigAveragingError> {
    let translation = |i: usize| translations.map_or_else(Vector3::zeros, |ts| ts[i]);
    let mean = weighted_pose_mean(
        rotations
            .iter()
            .zip(weights)
            .enumerate()
            .map(|(i, (q, &w))| (*q, translation(i), w)),
    )?;
    Ok((
        mean.rotation,
        translations.map(|_| mean.mean.translation.vector),
    ))
}

/// Index of the weighted chordal-L1 medoid: `argmin_i sum_j w_j sin(theta_ij / 2)`, where
/// `sin(theta/2) = sqrt(1 - (q_i . q_j)^2)`; ties go to the lowest index.
fn medoid(rotations: &[UnitQuaternion<f64>], weights: &[f64]) -> usize {
    let mut best = (0, f64::INFINITY);
    for (i, qi) in rotations.iter().enumerate() {
        let cost: f64 = rotations
            .iter()
            .zip(weights)
            .map(|(qj, w)| {
                let d = qi.coords.dot(&qj.coords);
                w * (1.0 - d * d).max(0.0).sqrt()
            })
            .sum();
        if cost < best.1 {
            best = (i, cost);
        }
    }
    best.0
}

/// Coordinate-wise weighted median: per axis, the smallest value at which the cumulative
/// weight reaches half the total.
fn coordinate_median(points: &[Vector3<f64>], weights: &[f64]) -> Vector3<f64> {
    let total: f64 = weights.iter().sum();
    let mut order: Vec<usize> = (0..points.len()).collect();
    let mut median = Vector3::zeros();
    for axis in 0..3 {
        order.sort_by(|&a, &b| points[a][axis].total_cmp(&points[b][axis]));
        let mut cumulative = 0.0;
        for &i in &order {
            cumulative += weights[i];
            median[axis] = points[i][axis];
            if cumulative >= 0.5 * total {
                break;
            }
        }
    }
    median
}

/// The upper median (element `n / 2` in sorted order) of non-negative finite values.
fn upper_median(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted.get(sorted.len() / 2).copied().unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn medians_and_medoid() {
        assert_eq!(upper_median(&[3.0, 1.0, 2.0, 10.0]), 3.0);
        assert_eq!(upper_median(&[5.0]), 5.0);
        let pts = [
            Vector3::new(0.0, 5.0, 1.0),
            Vector3::new(1.0, 4.0, 1.0),
            Vector3::new(100.0, -100.0, 1.0),
        ];
        assert_eq!(
            coordinate_median(&pts, &[1.0, 1.0, 1.0]),
            Vector3::new(1.0, 4.0, 1.0)
        );
        // A heavy weight moves the weighted median onto its point.
        assert_eq!(
            coordinate_median(&pts, &[1.0, 1.0, 5.0]),
            Vector3::new(100.0, -100.0, 1.0)
        );
        let z = |a: f64| UnitQuaternion::from_axis_angle(&Vector3::z_axis(), a);
        assert_eq!(medoid(&[z(0.0), z(0.1), z(0.15), z(3.0)], &[1.0; 4]), 1);
    }

    #[test]
    fn invalid_options_are_rejected() {
        let q = [UnitQuaternion::identity(); 3];
        for options in [
            RobustOptions::default().with_rotation_scale(0.0),
            RobustOptions::default().with_translation_scale(f64::NAN),
            RobustOptions::default().with_max_iterations(0),
            RobustOptions::default().with_tolerance(-1.0),
        ] {
            assert!(matches!(
                robust_quaternion_mean(&q, None, &options),
                Err(RigAveragingError::InvalidRobustOptions { .. })
            ));
        }
    }
}
