//! Pose refinement: Levenberg-Marquardt on the bearing error, optionally robust.
//!
//! K. Levenberg, "A method for the solution of certain non-linear problems in least squares",
//! Quarterly of Applied Mathematics 2, 1944; D. Marquardt, "An algorithm for least-squares
//! estimation of nonlinear parameters", SIAM J. Applied Mathematics 11(2), 1963; damping
//! update of H. B. Nielsen, "Damping parameter in Marquardt's method", IMM-REP-1999-05, DTU.
//!
//! The residual of correspondence `i` is the chord `r_i = p_i / |p_i| - f_i` between the
//! observed unit bearing `f_i` and the direction of the camera-frame point
//! `p_i = R X_i + t`. Its length is `2 sin(angle / 2)`: to first order the angle itself, the
//! tangent-plane error of the bearing, and it is well defined and monotonic for every angle up
//! to 180 degrees, so rays beyond 90 degrees of incidence are refined like any other. Its
//! Jacobian is `(I - p^ p^^T) / |p| [-[p]x, I]` for the update `R <- exp(w) R`,
//! `t <- exp(w) t + v`. Robust losses ([`RobustLoss`]) are applied by iteratively reweighted
//! least squares, the robustified normal equations of Triggs et al. 2000 (section 6.8) for
//! losses with `rho'' <= 0` (see the `loss` module).

use nalgebra::{
    Isometry3, Matrix3, Matrix6, Point3, Translation3, UnitQuaternion, Vector3, Vector6,
};

use crate::NonExhaustive;
use crate::error::{PnpError, Result};
use crate::loss::RobustLoss;
use crate::validate::check_correspondences;

/// Options of [`refine_pose`] and [`refine_pose_weighted`]. Write them in one expression,
/// `RefineOptions { loss: RobustLoss::Cauchy { scale: 0.005 }, ..Default::default() }`.
#[derive(Debug, Clone, PartialEq)]
pub struct RefineOptions {
    /// Most Levenberg-Marquardt iterations. Default 50.
    pub max_iterations: usize,
    /// The loss, its scale in radians (the residual is the bearing error). Default
    /// [`RobustLoss::Trivial`] (plain least squares).
    pub loss: RobustLoss,
    /// Stop when the update is smaller than this (radians for the rotation, and relative to
    /// the translation's norm plus the scene's spread for the translation). Default `1e-12`.
    pub step_tolerance: f64,
    /// Stop when an accepted step lowers the cost by less than this fraction. Default `1e-14`.
    pub cost_tolerance: f64,
    /// Keeps the struct open to new fields: write it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for RefineOptions {
    fn default() -> Self {
        Self {
            max_iterations: 50,
            loss: RobustLoss::Trivial,
            step_tolerance: 1e-12,
            cost_tolerance: 1e-14,
            non_exhaustive: NonExhaustive::VALUE,
        }
    }
}

impl RefineOptions {
    pub(crate) fn validate(&self) -> Result<()> {
        self.loss.validate()?;
        for (name, value) in [
            ("step_tolerance", self.step_tolerance),
            ("cost_tolerance", self.cost_tolerance),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(PnpError::InvalidOption {
                    name,
                    reason: format!("must be finite and non-negative, got {value}"),
                });
            }
        }
        Ok(())
    }
}

/// The outcome of [`refine_pose`].
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct RefinedPose {
    /// The refined `camera_from_world`.
    pub camera_from_world: Isometry3<f64>,
    /// Iterations run.
    pub iterations: usize,
    /// Cost `sum rho(|r_i|^2)` at the initial pose.
    pub initial_cost: f64,
    /// Cost at the refined pose (never above `initial_cost`).
    pub final_cost: f64,
}

/// Initial Levenberg-Marquardt damping, relative to the diagonal of `J^T J`: small, as the
/// starting pose of a refinement is usually close.
const INITIAL_DAMPING: f64 = 1e-4;

/// The least number of correspondences for refinement: three bearings fix the six degrees of
/// freedom (up to the P3P ambiguity the initial pose resolves).
pub const REFINE_MIN_POINTS: usize = 3;

/// Refines `camera_from_world` by Levenberg-Marquardt on the chord bearing error (see the
/// module docs), starting from `initial`.
///
/// # Errors
/// The input errors of [`crate::epnp`] (with at least [`REFINE_MIN_POINTS`]),
/// [`PnpError::InvalidLossScale`] for a loss scale that is not finite and positive,
/// [`PnpError::InvalidOption`] for a negative tolerance or a non-finite `initial` pose, and
/// [`PnpError::Numerical`] if the cost at `initial` is not finite.
pub fn refine_pose(
    bearings: &[Vector3<f64>],
    points: &[Point3<f64>],
    initial: &Isometry3<f64>,
    options: &RefineOptions,
) -> Result<RefinedPose> {
    refine_checked(bearings, points, None, initial, options)
}

/// Like [`refine_pose`], with a per-correspondence information matrix `information[i]`
/// (symmetric positive semi-definite, in bearing space): the cost is
/// `sum rho(r_i^T information[i] r_i)`. With the information of the camera's pixel noise
/// (the pseudo-inverse of the bearing's covariance `J J^T sigma^2`, `J = d ray / d pixel`),
/// this is the maximum-likelihood pose under Gaussian pixel noise;
/// [`crate::bearing_information`] gives it for any camera model.
///
/// # Errors
/// Those of [`refine_pose`], and [`PnpError::InvalidOption`] (`information`) if there is not
/// one finite matrix per correspondence.
pub fn refine_pose_weighted(
    bearings: &[Vector3<f64>],
    points: &[Point3<f64>],
    information: &[Matrix3<f64>],
    initial: &Isometry3<f64>,
    options: &RefineOptions,
) -> Result<RefinedPose> {
    refine_checked(bearings, points, Some(information), initial, options)
}

/// Input and option checks shared by the public refinements, then the refinement.
fn refine_checked(
    bearings: &[Vector3<f64>],
    points: &[Point3<f64>],
    information: Option<&[Matrix3<f64>]>,
    initial: &Isometry3<f64>,
    options: &RefineOptions,
) -> Result<RefinedPose> {
    check_correspondences("pose refinement", REFINE_MIN_POINTS, bearings, points)?;
    if let Some(information) = information {
        let invalid = |reason: String| PnpError::InvalidOption {
            name: "information",
            reason,
        };
        if information.len() != bearings.len() {
            return Err(invalid(format!(
                "{} matrices for {} correspondences",
                information.len(),
                bearings.len()
            )));
        }
        if let Some(index) = information
            .iter()
            .position(|m| !m.iter().all(|v| v.is_finite()))
        {
            return Err(invalid(format!("matrix {index} has a non-finite entry")));
        }
    }
    options.validate()?;
    check_initial(initial)?;
    let all: Vec<usize> = (0..bearings.len()).collect();
    refine_subset(bearings, points, &all, information, initial, options)
}

fn check_initial(initial: &Isometry3<f64>) -> Result<()> {
    let finite = initial.translation.vector.iter().all(|v| v.is_finite())
        && initial.rotation.coords.iter().all(|v| v.is_finite());
    if finite {
        Ok(())
    } else {
        Err(PnpError::InvalidOption {
            name: "initial",
            reason: "the initial pose has a non-finite entry".into(),
        })
    }
}

/// Refinement over the correspondences listed in `subset`, on validated input.
pub(crate) fn refine_subset(
    bearings: &[Vector3<f64>],
    points: &[Point3<f64>],
    subset: &[usize],
    information: Option<&[Matrix3<f64>]>,
    initial: &Isometry3<f64>,
    options: &RefineOptions,
) -> Result<RefinedPose> {
    let problem = Problem {
        bearings,
        points,
        subset,
        information,
        loss: options.loss,
    };
    let mut rotation = initial.rotation;
    let mut translation = initial.translation.vector;
    let initial_cost = problem.cost(&rotation, &translation);
    if !initial_cost.is_finite() {
        return Err(PnpError::Numerical(
            "pose refinement: the cost at the initial pose is not finite",
        ));
    }
    let mut cost = initial_cost;
    // Marquardt's damping, relative to the diagonal of J^T J.
    let mut damping = INITIAL_DAMPING;
    let mut nu = 2.0;
    let mut iterations = 0;
    'iterations: while iterations < options.max_iterations && cost > 0.0 {
        iterations += 1;
        let (hessian, gradient) = problem.normal_equations(&rotation, &translation);
        loop {
            let mut damped = hessian;
            for i in 0..6 {
                damped[(i, i)] += damping * hessian[(i, i)].max(f64::MIN_POSITIVE);
            }
            let Some(step) = damped.cholesky().map(|c| c.solve(&(-gradient))) else {
                damping = damping * nu + f64::MIN_POSITIVE;
                nu *= 2.0;
                if !damping.is_finite() {
                    break 'iterations;
                }
                continue;
            };
            let (new_rotation, new_translation) = apply(&rotation, &translation, &step);
            let new_cost = problem.cost(&new_rotation, &new_translation);
            // Gain ratio: actual over predicted decrease (the model is of cost / 2).
            let mut scaled = step;
            for i in 0..6 {
                scaled[i] *= damping * hessian[(i, i)].max(f64::MIN_POSITIVE);
            }
            let predicted = step.dot(&(scaled - gradient));
            let gain = (cost - new_cost) / predicted;
            let small_step = step.fixed_rows::<3>(0).norm() <= options.step_tolerance
                && step.fixed_rows::<3>(3).norm()
                    <= options.step_tolerance * (1.0 + translation.norm());
            if new_cost.is_finite() && new_cost <= cost && gain > 0.0 {
                let decrease = cost - new_cost;
                rotation = new_rotation;
                translation = new_translation;
                cost = new_cost;
                damping *= (1.0 - (2.0 * gain - 1.0).powi(3)).max(1.0 / 3.0);
                nu = 2.0;
                if decrease <= options.cost_tolerance * cost || small_step {
                    break 'iterations;
                }
                break;
            }
            damping *= nu;
            nu *= 2.0;
            if small_step || !damping.is_finite() {
                break 'iterations;
            }
        }
    }
    Ok(finish(
        rotation,
        translation,
        iterations,
        initial_cost,
        cost,
    ))
}

fn finish(
    rotation: UnitQuaternion<f64>,
    translation: Vector3<f64>,
    iterations: usize,
    initial_cost: f64,
    final_cost: f64,
) -> RefinedPose {
    RefinedPose {
        camera_from_world: Isometry3::from_parts(Translation3::from(translation), rotation),
        iterations,
        initial_cost,
        final_cost,
    }
}

/// `R <- exp(w) R`, `t <- exp(w) t + v` for `step = (w, v)`.
fn apply(
    rotation: &UnitQuaternion<f64>,
    translation: &Vector3<f64>,
    step: &Vector6<f64>,
) -> (UnitQuaternion<f64>, Vector3<f64>) {
    let delta = UnitQuaternion::from_scaled_axis(step.fixed_rows::<3>(0).into_owned());
    (
        delta * rotation,
        delta * translation + step.fixed_rows::<3>(3).into_owned(),
    )
}

struct Problem<'a> {
    bearings: &'a [Vector3<f64>],
    points: &'a [Point3<f64>],
    subset: &'a [usize],
    information: Option<&'a [Matrix3<f64>]>,
    loss: RobustLoss,
}

impl Problem<'_> {
    fn cost(&self, rotation: &UnitQuaternion<f64>, translation: &Vector3<f64>) -> f64 {
        let r = rotation.to_rotation_matrix().into_inner();
        self.subset
            .iter()
            .map(|&i| {
                let p = r * self.points[i].coords + translation;
                self.loss.rho(self.squared_error(i, &p))
            })
            .sum()
    }

    /// `r^T Omega r` (or `|r|^2`) for correspondence `i` at camera-frame point `p`.
    fn squared_error(&self, i: usize, p: &Vector3<f64>) -> f64 {
        match self.information {
            None => crate::geometry::chord_squared(&self.bearings[i], p),
            Some(info) => {
                let norm = p.norm();
                if norm.is_nan() || norm <= 0.0 {
                    return f64::INFINITY;
                }
                let r = p / norm - self.bearings[i];
                r.dot(&(info[i] * r))
            }
        }
    }

    /// `J^T W J` and `J^T W r` (IRLS weights `W = rho'(|r|^2)`).
    fn normal_equations(
        &self,
        rotation: &UnitQuaternion<f64>,
        translation: &Vector3<f64>,
    ) -> (Matrix6<f64>, Vector6<f64>) {
        let r = rotation.to_rotation_matrix().into_inner();
        let mut hessian = Matrix6::zeros();
        let mut gradient = Vector6::zeros();
        for &i in self.subset {
            let p = r * self.points[i].coords + translation;
            let norm = p.norm();
            if norm.is_nan() || norm <= 0.0 {
                continue;
            }
            let unit = p / norm;
            let residual = unit - self.bearings[i];
            let info = self.information.map(|info| info[i]);
            let squared = match &info {
                Some(o) => residual.dot(&(o * residual)),
                None => residual.norm_squared(),
            };
            let weight = self.loss.weight(squared);
            // d unit / d p = (I - u u^T) / |p|; d p / d(w, v) = [-[p]x, I].
            let projector = (Matrix3::identity() - unit * unit.transpose()) / norm;
            let skew = p.cross_matrix();
            let mut jacobian = nalgebra::Matrix3x6::zeros();
            jacobian
                .fixed_view_mut::<3, 3>(0, 0)
                .copy_from(&(-(projector * skew)));
            jacobian.fixed_view_mut::<3, 3>(0, 3).copy_from(&projector);
            match &info {
                Some(o) => {
                    let weighted = (o * jacobian).transpose();
                    hessian += weighted * jacobian * weight;
                    gradient += weighted * residual * weight;
                }
                None => {
                    hessian += jacobian.transpose() * jacobian * weight;
                    gradient += jacobian.transpose() * residual * weight;
                }
            }
        }
        (hessian, gradient)
    }
}
