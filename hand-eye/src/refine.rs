//! Nonlinear least-squares refinement of `A_i X = X B_i`, and the uncertainty of an estimate.
//!
//! The residual of motion `i` is the discrepancy between `A_i X` and `X B_i`, in frame `a`:
//!
//! ```text
//! e_rot,i   = log(R_Ai R_X R_Biᵀ R_Xᵀ)                  (rotation vector, radians)
//! e_trans,i = R_Ai t_X + t_Ai - R_X t_Bi - t_X           (metres)
//! ```
//!
//! and the cost is `Σ |e_rot,i|² / σ_r² + |e_trans,i|² / σ_t²`. Unless the caller gives them,
//! `σ_r` and `σ_t` are the RMS residuals per component of the starting estimate, re-estimated
//! once after a first convergence (variance-component estimation), so the two kinds of residual
//! get weights in proportion to their noise and no unit choice biases the result.
//! Levenberg-Marquardt updates `R_X ← exp(δ) R_X`, `t_X ← t_X + Δt` with analytic Jacobians.
//!
//! The same machinery refines the planar problem of Guo et al. in its own form
//! `B_i Y = Y A_i` (with `Y = X⁻¹`, an unknown scale on the translations of `A_i` and the
//! out-of-plane translation held fixed).
//!
//! The predicted standard deviations are the square roots of the diagonal of
//! `s² (JᵀJ)⁻¹` at the estimate, `J` the weighted Jacobian and `s²` the residual variance
//! factor. They assume independent motions: motions formed from all pairs of `n` poses share
//! poses, and their spread is then underestimated by up to `sqrt(m / (n - 1))` for `m` motions.

use nalgebra::{Isometry3, Matrix3, SMatrix, SVector, Translation3, UnitQuaternion, Vector3};

use crate::NonExhaustive;
use crate::error::{HandEyeError, Result};
use crate::least_squares::{Model, assess, minimize, standard_deviations};
use crate::motion::{MotionPair, check_pairs};

/// Default iteration limit of the refinement (it converges in 3 to 6 from the linear solutions).
pub const DEFAULT_MAX_ITERATIONS: usize = 50;

/// Options of the nonlinear refinement.
///
/// Write them as `RefineOptions { field: value, ..Default::default() }`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefineOptions {
    /// Iteration limit of each Levenberg-Marquardt run. Default [`DEFAULT_MAX_ITERATIONS`].
    pub max_iterations: usize,
    /// Noise of the rotation residual per component, radians, if known. Default `None`:
    /// estimated from the residuals.
    pub rotation_sigma: Option<f64>,
    /// Noise of the translation residual per component, metres, if known. Default `None`:
    /// estimated from the residuals.
    pub translation_sigma: Option<f64>,
    /// Keeps the struct open to new fields; use `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for RefineOptions {
    fn default() -> Self {
        Self {
            max_iterations: DEFAULT_MAX_ITERATIONS,
            rotation_sigma: None,
            translation_sigma: None,
            non_exhaustive: NonExhaustive(()),
        }
    }
}

/// How well an estimate fits the motions and how well the motions determine it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Uncertainty {
    /// RMS over the motions of the rotation residual norm `|e_rot,i|`, radians.
    pub rotation_rms: f64,
    /// RMS over the motions of the translation residual norm `|e_trans,i|`, metres.
    pub translation_rms: f64,
    /// Predicted standard deviation of the rotation of the estimate about each axis, radians
    /// (axes of the frame the solver states). Infinite when the motions do not determine it.
    pub rotation_std: Vector3<f64>,
    /// Predicted standard deviation of each translation component, metres. Infinite for a
    /// component the motions do not determine.
    pub translation_std: Vector3<f64>,
    /// Predicted standard deviation of the scale, when it is estimated.
    pub scale_std: Option<f64>,
}

/// The result of [`refine`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refined {
    /// The refined `X = a_from_b`.
    pub a_from_b: Isometry3<f64>,
    /// Residuals and predicted standard deviations; rotations about the axes of frame `a`,
    /// translations in frame `a`.
    pub uncertainty: Uncertainty,
    /// Levenberg-Marquardt iterations taken (both runs).
    pub iterations: usize,
}

/// Refines `X = a_from_b` from a starting estimate by minimizing the residual of
/// `A_i X = X B_i` over all `pairs` (see the module docs).
///
/// Every motion is used: this residual has no quaternion sign ambiguity, and small rotations
/// still tell the rotation of `X` through `t_Ai ≈ R_X t_Bi`.
///
/// # Errors
/// [`HandEyeError::TooFewMotions`] for fewer than two pairs; [`HandEyeError::NonFinite`],
/// [`HandEyeError::NotUnitQuaternion`] or [`HandEyeError::InvalidOptions`] for invalid input.
pub fn refine(
    pairs: &[MotionPair],
    a_from_b: &Isometry3<f64>,
    options: &RefineOptions,
) -> Result<Refined> {
    check_pairs(pairs)?;
    crate::motion::check_pose(a_from_b, 0, crate::error::Sensor::A)?;
    if pairs.len() < 2 {
        return Err(HandEyeError::too_few_motions(pairs.len()));
    }
    let problem = Problem::new(pairs.iter().map(|p| (p.a, p.b)).collect(), Free::ALL);
    let start = Unknowns {
        z: *a_from_b,
        scale: 1.0,
    };
    let (fit, iterations) = problem.refine(start, options)?;
    Ok(Refined {
        a_from_b: fit.unknowns.z,
        uncertainty: fit.uncertainty,
        iterations,
    })
}

/// Which unknowns the refinement may change.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Free {
    /// Translation components of `Z`.
    pub(crate) translation: [bool; 3],
    /// The scale of the translations of the right-hand motions.
    pub(crate) scale: bool,
}

impl Free {
    /// Rotation and translation free, no scale.
    pub(crate) const ALL: Free = Free {
        translation: [true; 3],
        scale: false,
    };
}

/// The unknowns of `L_i Z = Z R_i`, the translations of `R_i` multiplied by `scale`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Unknowns {
    pub(crate) z: Isometry3<f64>,
    pub(crate) scale: f64,
}

/// An estimate with its fit.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Fit {
    pub(crate) unknowns: Unknowns,
    pub(crate) uncertainty: Uncertainty,
}

/// The equations `L_i Z = Z R_i` (Daniilidis: `L = A`, `R = B`, `Z = X`; planar: `L = B`,
/// `R = A`, `Z = Y`), unknowns `(δ, Δt, Δscale)` with `R_Z ← exp(δ) R_Z`.
pub(crate) struct Problem {
    motions: Vec<Motion>,
    /// RMS translation of the motions, the length scale of the translation floors.
    length: f64,
    free: Free,
}

/// One motion pair of `L_i Z = Z R_i`, with its rotation matrices.
struct Motion {
    left: Isometry3<f64>,
    right: Isometry3<f64>,
    left_matrix: Matrix3<f64>,
    right_matrix: Matrix3<f64>,
}

impl Problem {
    pub(crate) fn new(motions: Vec<(Isometry3<f64>, Isometry3<f64>)>, free: Free) -> Self {
        let sum: f64 = motions
            .iter()
            .map(|(l, r)| l.translation.vector.norm_squared() + r.translation.vector.norm_squared())
            .sum();
        let length = (sum / (2 * motions.len().max(1)) as f64).sqrt();
        let motions = motions
            .into_iter()
            .map(|(left, right)| Motion {
                left,
                right,
                left_matrix: left.rotation.to_rotation_matrix().into_inner(),
                right_matrix: right.rotation.to_rotation_matrix().into_inner(),
            })
            .collect();
        Self {
            motions,
            length: if length > 0.0 { length } else { 1.0 },
            free,
        }
    }

    /// Refines `start`, then assesses the result.
    pub(crate) fn refine(&self, start: Unknowns, options: &RefineOptions) -> Result<(Fit, usize)> {
        let (state, iterations) = minimize(self, start, options)?;
        Ok((self.assess(state), iterations))
    }

    /// Residual RMS and predicted standard deviations of an estimate.
    pub(crate) fn assess(&self, unknowns: Unknowns) -> Fit {
        let assessment = assess(self, &unknowns);
        let covariance = &assessment.covariance;
        Fit {
            unknowns,
            uncertainty: Uncertainty {
                rotation_rms: assessment.rotation_rms,
                translation_rms: assessment.translation_rms,
                rotation_std: standard_deviations(covariance, 0),
                translation_std: standard_deviations(covariance, 3),
                scale_std: self.free.scale.then(|| match covariance {
                    Some(c) => c[(6, 6)].max(0.0).sqrt(),
                    None => f64::INFINITY,
                }),
            },
        }
    }
}

impl Model<7> for Problem {
    type State = Unknowns;

    fn blocks(&self) -> usize {
        self.motions.len()
    }

    fn residual(&self, u: &Unknowns, i: usize) -> (Vector3<f64>, Vector3<f64>) {
        let (l, r) = (&self.motions[i].left, &self.motions[i].right);
        let rz = u.z.rotation;
        let e_rot = (l.rotation * rz * r.rotation.inverse() * rz.inverse()).scaled_axis();
        let tz = u.z.translation.vector;
        let e_trans =
            l.rotation * tz + l.translation.vector - rz * (r.translation.vector * u.scale) - tz;
        (e_rot, e_trans)
    }

    fn jacobian(&self, u: &Unknowns, i: usize) -> SMatrix<f64, 6, 7> {
        let motion = &self.motions[i];
        let rz = u.z.rotation.to_rotation_matrix().into_inner();
        // R_E(δ) = R_L exp(δ) C exp(-δ), C = R_Z R_Rᵀ R_Zᵀ, is R_E exp((Cᵀ - I) δ) to first order.
        let conj = rz * motion.right_matrix * rz.transpose();
        let moved = rz * motion.right.translation.vector;
        let mut j = SMatrix::<f64, 6, 7>::zeros();
        j.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(conj - Matrix3::identity()));
        j.fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&(moved * u.scale).cross_matrix());
        j.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(motion.left_matrix - Matrix3::identity()));
        j.fixed_view_mut::<3, 1>(3, 6).copy_from(&(-moved));
        j
    }

    fn apply(&self, u: &Unknowns, step: &SVector<f64, 7>) -> Unknowns {
        let rotation = UnitQuaternion::from_scaled_axis(step.fixed_rows::<3>(0)) * u.z.rotation;
        let translation = u.z.translation.vector + step.fixed_rows::<3>(3);
        Unknowns {
            z: Isometry3::from_parts(Translation3::from(translation), rotation),
            scale: u.scale + step[6],
        }
    }

    fn free(&self) -> [bool; 7] {
        let t = self.free.translation;
        [true, true, true, t[0], t[1], t[2], self.free.scale]
    }

    fn length(&self) -> f64 {
        self.length
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::iso;
    use approx::assert_relative_eq;

    fn motions(x: &Isometry3<f64>) -> Vec<(Isometry3<f64>, Isometry3<f64>)> {
        [
            iso([0.3, -0.2, 0.5], [0.4, 0.1, -0.2]),
            iso([-0.1, 0.6, 0.2], [-0.1, 0.7, 0.3]),
            iso([0.5, 0.5, -0.4], [0.2, -0.3, 0.9]),
        ]
        .into_iter()
        .map(|a| (a, x.inverse() * a * x))
        .collect()
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let x = iso([0.1, 0.2, 0.3], [0.3, -0.5, 0.2]);
        let problem = Problem::new(motions(&x), Free::ALL);
        // Away from the solution, so that every block is exercised.
        let u = Unknowns {
            z: iso([0.15, 0.1, 0.35], [0.32, -0.45, 0.25]),
            scale: 1.1,
        };
        let h = 1e-7;
        for i in 0..problem.blocks() {
            let j = problem.jacobian(&u, i);
            for k in 0..7 {
                let mut step = SVector::<f64, 7>::zeros();
                step[k] = h;
                let (rp, tp) = problem.residual(&problem.apply(&u, &step), i);
                let (rm, tm) = problem.residual(&problem.apply(&u, &-step), i);
                let numeric_t = (tp - tm) / (2.0 * h);
                assert_relative_eq!(
                    j.fixed_view::<3, 1>(3, k).into_owned(),
                    numeric_t,
                    epsilon = 1e-6
                );
                if k < 3 {
                    // The analytic rotation block omits the inverse right Jacobian of the
                    // residual, which is the identity up to |e_rot| / 2.
                    let numeric_r = (rp - rm) / (2.0 * h);
                    let (er, _) = problem.residual(&u, i);
                    let tolerance = 1e-6 + er.norm();
                    assert_relative_eq!(
                        j.fixed_view::<3, 1>(0, k).into_owned(),
                        numeric_r,
                        epsilon = tolerance
                    );
                }
            }
        }
    }

    #[test]
    fn refine_recovers_exact_transform_from_a_perturbed_start() {
        let x = iso([0.1, 0.2, 0.3], [0.3, -0.5, 0.2]);
        let pairs: Vec<_> = motions(&x)
            .into_iter()
            .map(|(a, b)| MotionPair::new(a, b))
            .collect();
        let start = iso([0.2, 0.1, 0.25], [0.35, -0.45, 0.15]);
        let refined = refine(&pairs, &start, &RefineOptions::default()).unwrap();
        assert!(refined.a_from_b.rotation.angle_to(&x.rotation) < 1e-12);
        assert!((refined.a_from_b.translation.vector - x.translation.vector).norm() < 1e-12);
        assert!(refined.uncertainty.translation_rms < 1e-12);
    }

    #[test]
    fn refine_rejects_bad_options_and_too_few_pairs() {
        let x = iso([0.1, 0.2, 0.3], [0.3, -0.5, 0.2]);
        let pairs: Vec<_> = motions(&x)
            .into_iter()
            .map(|(a, b)| MotionPair::new(a, b))
            .collect();
        let options = RefineOptions {
            rotation_sigma: Some(-1.0),
            ..RefineOptions::default()
        };
        assert!(matches!(
            refine(&pairs, &x, &options),
            Err(HandEyeError::InvalidOptions { .. })
        ));
        assert!(matches!(
            refine(&pairs[..1], &x, &RefineOptions::default()),
            Err(HandEyeError::TooFewMotions { .. })
        ));
    }
}
