//! The joint refinement of the intrinsics and every board pose: Levenberg-Marquardt on the
//! reprojection error with `ibc-bundle-adjust`, poses eliminated by the Schur complement.
//!
//! The residual of corner `k` of image `i` is `pi(params, T_i X_k) - x_ik` (pixels), with `pi`
//! the camera model, `T_i = camera_from_board` on SE(3) (right perturbation
//! `T Exp(delta)`, `delta = [rho, phi]`, as [`ibc_bundle_adjust::Se3Manifold`]) and `X_k` the
//! board corner. Its Jacobians are analytic: `d pixel / d params` from the camera model, and
//! `d pixel / d point * R [I, -[X]x]` for the pose. One residual block per image holds all
//! its corners, so the camera is built once per image and evaluation.
//!
//! The covariance of the intrinsics is the solver's ([`Problem::covariance`]: the inverse of
//! the Schur complement of `J^T J` with the poses eliminated, Triggs et al. 2000), scaled by
//! the a-posteriori variance factor `sum r^2 / (m - n)` (`m` residual coordinates,
//! `n = params + 6 * images` unknowns): the estimated pixel noise variance.

use ibc_bundle_adjust::{
    CostFunction, Jacobians, Problem, RobustLoss, Se3Manifold, SolverOptions, Summary,
};
use ibc_camera_models::{Camera, CameraModel, ParamJacobian};
use nalgebra::{DMatrix, Isometry3, Matrix2x6, Matrix3x6, Point3, Vector2};

use ibc_bundle_adjust::BundleAdjustError;

use super::board_pose::ImageCorrespondences;
use super::calibrate::IntrinsicModel;
use super::error::IntrinsicsError;

/// d pixel / d intrinsics on the stack: the model's parameters in the first columns, zero
/// beyond them ([`ParamJacobian`]).
pub(crate) type IntrinsicJacobian = ParamJacobian<2>;

/// The residual and Jacobians of one corner.
pub(crate) struct CornerTerms {
    /// Predicted minus observed pixel.
    pub residual: Vector2<f64>,
    /// d residual / d intrinsics.
    pub d_intrinsics: IntrinsicJacobian,
    /// d residual / d pose tangent `[rho, phi]`.
    pub d_pose: Matrix2x6<f64>,
}

/// The residual and Jacobians of a corner, or `None` where the point does not project.
pub(crate) fn corner_terms(
    camera: &Camera,
    camera_from_board: &Isometry3<f64>,
    point: &Point3<f64>,
    observed: &Vector2<f64>,
) -> Option<CornerTerms> {
    let p = camera_from_board * point;
    let j = camera.project_with_jacobians(&p.coords).ok()?;
    let r = camera_from_board.rotation.to_rotation_matrix().into_inner();
    let mut d_point_d_delta = Matrix3x6::zeros();
    d_point_d_delta.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    d_point_d_delta
        .fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(-r * point.coords.cross_matrix()));
    Some(CornerTerms {
        residual: j.pixel - observed,
        d_intrinsics: j.d_pixel_d_params,
        d_pose: j.d_pixel_d_point * d_point_d_delta,
    })
}

/// The reprojection residuals of one image: blocks `[intrinsics (n), camera_from_board (7)]`,
/// each corner's residual scaled by the square root of its weight (iteratively reweighted
/// least squares; weight 1 is the plain reprojection error).
pub(crate) struct ImageReprojection {
    pub model: IntrinsicModel,
    pub width: u32,
    pub height: u32,
    pub points: Vec<Point3<f64>>,
    pub observed: Vec<Vector2<f64>>,
    /// `sqrt(weight)` of each corner.
    pub sqrt_weights: Vec<f64>,
    /// `[n, 7]`: the model's parameter count and the pose's.
    pub block_sizes: [usize; 2],
}

impl CostFunction for ImageReprojection {
    fn num_residuals(&self) -> usize {
        2 * self.points.len()
    }

    fn parameter_block_sizes(&self) -> &[usize] {
        &self.block_sizes
    }

    fn evaluate(
        &self,
        parameters: &[&[f64]],
        residuals: &mut [f64],
        jacobians: Option<&mut Jacobians<'_>>,
    ) -> bool {
        let (Some(params), Some(pose)) = (parameters.first(), parameters.get(1)) else {
            return false;
        };
        let Ok(camera) = self.model.camera(self.width, self.height, params) else {
            return false;
        };
        let Some(pose) = Se3Manifold::pose(pose) else {
            return false;
        };
        let Some(jacobians) = jacobians else {
            for (k, (x, obs)) in self.points.iter().zip(&self.observed).enumerate() {
                let Ok(pixel) = camera.project(&(pose * x).coords) else {
                    return false;
                };
                let w = self.sqrt_weights[k];
                residuals[2 * k] = w * (pixel.x - obs.x);
                residuals[2 * k + 1] = w * (pixel.y - obs.y);
            }
            return true;
        };
        let mut terms = Vec::with_capacity(self.points.len());
        for (k, (x, obs)) in self.points.iter().zip(&self.observed).enumerate() {
            let Some(mut t) = corner_terms(&camera, &pose, x, obs) else {
                return false;
            };
            let w = self.sqrt_weights[k];
            t.residual *= w;
            t.d_intrinsics *= w;
            t.d_pose *= w;
            residuals[2 * k] = t.residual.x;
            residuals[2 * k + 1] = t.residual.y;
            terms.push(t);
        }
        let n = self.block_sizes[0];
        if let Some(block) = jacobians.row_major_mut(0) {
            for (k, t) in terms.iter().enumerate() {
                for row in 0..2 {
                    let dst = &mut block[(2 * k + row) * n..(2 * k + row + 1) * n];
                    for (c, v) in dst.iter_mut().enumerate() {
                        *v = t.d_intrinsics[(row, c)];
                    }
                }
            }
        }
        if let Some(block) = jacobians.row_major_mut(1) {
            for (k, t) in terms.iter().enumerate() {
                for row in 0..2 {
                    let dst = &mut block[(2 * k + row) * 6..(2 * k + row + 1) * 6];
                    for (c, v) in dst.iter_mut().enumerate() {
                        *v = t.d_pose[(row, c)];
                    }
                }
            }
        }
        true
    }
}

/// The outcome of [`refine`].
pub(crate) struct Refined {
    pub params: Vec<f64>,
    pub camera_from_board: Vec<Isometry3<f64>>,
    pub summary: Summary,
    /// Covariance of the intrinsics (n x n, parameter order), scaled by `noise_variance`;
    /// `None` for a weighted pass or when the information matrix is singular (an intrinsic
    /// the views do not determine).
    pub covariance: Option<DMatrix<f64>>,
    /// `sum r^2 / (m - n)`, pixels squared.
    pub noise_variance: f64,
}

/// Refines the intrinsics and all board poses together from an initial guess.
///
/// `data[i]` holds image `i`'s board points and observed pixels, `weights[i]` (when given)
/// the weight of each of its corners; the covariance is that of the weighted problem, so it
/// is meaningful for weights 1 (the final solve on the inliers).
pub(crate) fn refine(
    model: IntrinsicModel,
    (width, height): (u32, u32),
    initial: &[f64],
    initial_poses: &[Isometry3<f64>],
    data: &[ImageCorrespondences],
    weights: Option<&[Vec<f64>]>,
    options: &SolverOptions,
) -> Result<Refined, IntrinsicsError> {
    let n_params = model.num_params();
    if initial.len() != n_params {
        return Err(IntrinsicsError::InvalidInput(format!(
            "{} intrinsics given for the {} model's {n_params}",
            initial.len(),
            model.short_name()
        )));
    }
    let mut problem = Problem::new();
    let intrinsics = problem.add_parameter_block(initial)?;
    let mut poses = Vec::with_capacity(initial_poses.len());
    for (i, ((points, pixels), pose)) in data.iter().zip(initial_poses).enumerate() {
        let block = problem.add_manifold_block(&Se3Manifold::params(pose), Se3Manifold)?;
        problem.set_eliminated(block, true)?;
        let sqrt_weights = match weights.and_then(|w| w.get(i)) {
            Some(w) => w.iter().map(|w| w.max(0.0).sqrt()).collect(),
            None => vec![1.0; points.len()],
        };
        problem.add_residual_block(
            ImageReprojection {
                model,
                width,
                height,
                points: points.clone(),
                observed: pixels.clone(),
                sqrt_weights,
                block_sizes: [n_params, 7],
            },
            RobustLoss::Trivial,
            &[intrinsics, block],
        )?;
        poses.push(block);
    }
    let summary = problem.solve(options)?;
    use ibc_bundle_adjust::Termination as T;
    match summary.termination {
        T::EvaluationFailed | T::TooManyInvalidSteps | T::NoFreeParameters => {
            return Err(IntrinsicsError::Refinement(format!(
                "Levenberg-Marquardt stopped with `{}` after {} iterations (cost {:.3e} -> {:.3e})",
                summary.termination, summary.iterations, summary.initial_cost, summary.final_cost
            )));
        }
        _ => {}
    }
    let params = problem.parameter_block(intrinsics)?.to_vec();
    let camera_from_board = poses
        .iter()
        .map(|&b| {
            Se3Manifold::pose(problem.parameter_block(b)?).ok_or_else(|| {
                IntrinsicsError::Refinement("a board pose block is not 7 values".into())
            })
        })
        .collect::<Result<Vec<_>, IntrinsicsError>>()?;
    let m: usize = data.iter().map(|(points, _)| 2 * points.len()).sum();
    let n = n_params + 6 * data.len();
    if m <= n {
        return Err(IntrinsicsError::SingularInformation(format!(
            "{m} residual coordinates do not exceed the {n} unknowns"
        )));
    }
    let noise_variance = 2.0 * summary.final_cost / (m - n) as f64;
    // The covariance of a weighted pass would be that of the weighted problem: not computed.
    let covariance = if weights.is_some() {
        None
    } else {
        match problem.covariance(&[intrinsics], options) {
            Ok(unit) => {
                let matrix = unit.matrix();
                (matrix.nrows() == n_params && matrix.ncols() == n_params)
                    .then(|| matrix.map(|v| v * noise_variance))
            }
            Err(
                BundleAdjustError::SingularInformation
                | BundleAdjustError::CovarianceRankDeficient { .. },
            ) => None,
            Err(other) => return Err(IntrinsicsError::Solver(other)),
        }
    };
    Ok(Refined {
        params,
        camera_from_board,
        summary,
        covariance,
        noise_variance,
    })
}
