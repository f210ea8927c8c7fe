//! Rig refinement: the non-linear refinement of infrastructure-based calibration (Heng,
//! Bürki, Lee, Furgale, Siegwart, Pollefeys, "Infrastructure-Based Calibration of a
//! Multi-Camera Rig", ICRA 2014, equation 4).
//!
//! Minimizes Σ ρ(|π_c(camera_from_rig_c · rig_from_world_i · X) − x|²) over the extrinsics
//! `rig_from_camera_c` (one per camera) and the rig poses `world_from_rig_i` (one per frame
//! set), with the map points X fixed and any [`ibc_camera_models`] camera with fixed
//! intrinsics. Poses live on [`Se3Manifold`]; the rig poses are eliminated by the Schur
//! complement, so the reduced system only holds the extrinsics.
//!
//! **Gauge.** Moving the rig frame by any rigid motion T (world_from_rig · T,
//! T⁻¹ · rig_from_camera) leaves every prediction unchanged. The gauge is fixed by holding the
//! extrinsic of [`RigRefinementOptions::reference_camera`] at its initial value: the rig frame
//! is defined by that camera (identity if the rig frame is that camera's frame).

use std::sync::Arc;

use ibc_camera_models::{Camera, CameraModel};
use nalgebra::{Isometry3, Matrix3, Matrix6, SMatrix, Vector2, Vector3};

use crate::cost::{CostFunction, Jacobians};
use crate::error::{BundleAdjustError, Result};
use crate::loss::Loss;
use crate::manifold::{Se3Manifold, se3_from_params, se3_from_unit_params, se3_to_params, skew};
use crate::options::SolverOptions;
use crate::problem::{ParameterBlockId, Problem};
use crate::summary::Summary;

/// One observation of a fixed map point by one camera in one frame set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigObservation {
    /// Frame-set index (into [`RigRefinement::world_from_rig`]).
    pub frame: usize,
    /// Camera index (into [`RigRefinement::cameras`]).
    pub camera: usize,
    /// The map point, in the world frame (held fixed).
    pub world_point: Vector3<f64>,
    /// The observed pixel (pixel centres at integer coordinates).
    pub pixel: Vector2<f64>,
}

/// A rig-refinement problem: initial extrinsics and rig poses, cameras and observations.
#[derive(Debug, Clone)]
pub struct RigRefinement {
    /// Intrinsics of each camera (held fixed).
    pub cameras: Vec<Camera>,
    /// Initial extrinsic of each camera.
    pub rig_from_camera: Vec<Isometry3<f64>>,
    /// Initial rig pose of each frame set.
    pub world_from_rig: Vec<Isometry3<f64>>,
    /// Observations.
    pub observations: Vec<RigObservation>,
}

/// Options of [`RigRefinement::refine`].
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct RigRefinementOptions {
    /// Robust loss on the squared pixel error (default: Cauchy with a = 1 pixel, the paper's
    /// Cauchy-robust reprojection error).
    pub loss: Loss,
    /// The camera whose extrinsic is held at its initial value to fix the gauge (default 0).
    pub reference_camera: usize,
    /// Compute the covariance of the extrinsics at the solution (default true).
    pub covariance: bool,
    /// Solver options (default: [`SolverOptions::default`]).
    pub solver: SolverOptions,
}

impl Default for RigRefinementOptions {
    fn default() -> Self {
        Self {
            loss: Loss::Cauchy(1.0),
            reference_camera: 0,
            covariance: true,
            solver: SolverOptions::default(),
        }
    }
}

/// The refined rig.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct RigRefinementResult {
    /// Refined extrinsics.
    pub rig_from_camera: Vec<Isometry3<f64>>,
    /// Refined rig poses.
    pub world_from_rig: Vec<Isometry3<f64>>,
    /// Covariance of each extrinsic in its right tangent `[ρ, φ]` (metres, radians) for unit
    /// pixel noise, `None` for the reference camera or when not requested or undefined.
    /// Multiply by σ² for a pixel noise σ.
    pub extrinsic_covariance: Vec<Option<Matrix6<f64>>>,
    /// Root-mean-square reprojection error (pixels) at the start, over all observations.
    pub initial_rms: f64,
    /// Root-mean-square reprojection error (pixels) at the solution.
    pub final_rms: f64,
    /// The solver's summary.
    pub summary: Summary,
}

/// The reprojection residual of one rig observation; arguments
/// `[world_from_rig (7, SE(3)), rig_from_camera (7, SE(3))]`.
struct RigReprojection {
    cameras: Arc<[Camera]>,
    camera: usize,
    world_point: Vector3<f64>,
    pixel: Vector2<f64>,
}

impl CostFunction for RigReprojection {
    fn num_residuals(&self) -> usize {
        2
    }

    fn parameter_block_sizes(&self) -> &[usize] {
        &[7, 7]
    }

    fn evaluate(
        &self,
        parameters: &[&[f64]],
        residuals: &mut [f64],
        jacobians: Option<&mut Jacobians<'_>>,
    ) -> bool {
        let world_from_rig = se3_from_unit_params(parameters[0]);
        let rig_from_camera = se3_from_unit_params(parameters[1]);
        let p_rig = world_from_rig
            .inverse_transform_point(&self.world_point.into())
            .coords;
        let p_cam = rig_from_camera
            .inverse_transform_point(&p_rig.into())
            .coords;
        let camera = &self.cameras[self.camera];
        let Some(jac) = jacobians else {
            let Ok(pixel) = camera.project(&p_cam) else {
                return false;
            };
            residuals[0] = pixel.x - self.pixel.x;
            residuals[1] = pixel.y - self.pixel.y;
            return true;
        };
        let Ok((pixel, d_pixel)) = camera.project_with_point_jacobian(&p_cam) else {
            return false;
        };
        residuals[0] = pixel.x - self.pixel.x;
        residuals[1] = pixel.y - self.pixel.y;
        // Right perturbations: ∂(T Exp(δ))⁻¹p/∂δ = [−I, [T⁻¹p]×] for δ = [ρ, φ].
        let camera_from_rig: Matrix3<f64> = rig_from_camera
            .rotation
            .to_rotation_matrix()
            .into_inner()
            .transpose();
        if jac.wants(0) {
            let a = d_pixel * camera_from_rig;
            let mut j = SMatrix::<f64, 2, 6>::zeros();
            j.fixed_view_mut::<2, 3>(0, 0).copy_from(&(-a));
            j.fixed_view_mut::<2, 3>(0, 3)
                .copy_from(&(a * skew(&p_rig)));
            jac.set(0, &j);
        }
        if jac.wants(1) {
            let mut j = SMatrix::<f64, 2, 6>::zeros();
            j.fixed_view_mut::<2, 3>(0, 0).copy_from(&(-d_pixel));
            j.fixed_view_mut::<2, 3>(0, 3)
                .copy_from(&(d_pixel * skew(&p_cam)));
            jac.set(1, &j);
        }
        true
    }
}

fn check_pose(pose: &Isometry3<f64>, what: &str) -> Result<()> {
    if se3_to_params(pose).iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(BundleAdjustError::InvalidProblem(format!(
            "{what} is not finite"
        )))
    }
}

impl RigRefinement {
    fn validate(&self, options: &RigRefinementOptions) -> Result<()> {
        let nc = self.cameras.len();
        if self.rig_from_camera.len() != nc {
            return Err(BundleAdjustError::InvalidProblem(format!(
                "{} cameras but {} extrinsics",
                nc,
                self.rig_from_camera.len()
            )));
        }
        if options.reference_camera >= nc {
            return Err(BundleAdjustError::InvalidProblem(format!(
                "reference camera {} does not exist ({nc} cameras)",
                options.reference_camera
            )));
        }
        for (i, p) in self.rig_from_camera.iter().enumerate() {
            check_pose(p, &format!("rig_from_camera[{i}]"))?;
        }
        for (i, p) in self.world_from_rig.iter().enumerate() {
            check_pose(p, &format!("world_from_rig[{i}]"))?;
        }
        for (i, o) in self.observations.iter().enumerate() {
            if o.camera >= nc || o.frame >= self.world_from_rig.len() {
                return Err(BundleAdjustError::InvalidProblem(format!(
                    "observation {i} refers to camera {} or frame set {} that does not exist",
                    o.camera, o.frame
                )));
            }
            if !(o.world_point.iter().all(|v| v.is_finite())
                && o.pixel.iter().all(|v| v.is_finite()))
            {
                return Err(BundleAdjustError::NonFiniteObservation { index: i });
            }
        }
        Ok(())
    }

    /// Builds the [`Problem`]: one SE(3) block per frame set (eliminated) and per camera (the
    /// reference camera's held constant), one residual per observation.
    ///
    /// # Errors
    /// [`BundleAdjustError::InvalidProblem`] for inconsistent sizes, indices or non-finite
    /// poses, [`BundleAdjustError::NonFiniteObservation`], or an invalid loss.
    pub fn to_problem(
        &self,
        options: &RigRefinementOptions,
    ) -> Result<(Problem, Vec<ParameterBlockId>, Vec<ParameterBlockId>)> {
        self.validate(options)?;
        let mut problem = Problem::new();
        let frames = self
            .world_from_rig
            .iter()
            .map(|p| problem.add_manifold_block(&se3_to_params(p), Se3Manifold))
            .collect::<Result<Vec<_>>>()?;
        let extrinsics = self
            .rig_from_camera
            .iter()
            .map(|p| problem.add_manifold_block(&se3_to_params(p), Se3Manifold))
            .collect::<Result<Vec<_>>>()?;
        for &f in &frames {
            problem.set_eliminated(f, true)?;
        }
        problem.set_constant(extrinsics[options.reference_camera], true)?;
        let cameras: Arc<[Camera]> = self.cameras.clone().into();
        for o in &self.observations {
            problem.add_residual_block(
                RigReprojection {
                    cameras: Arc::clone(&cameras),
                    camera: o.camera,
                    world_point: o.world_point,
                    pixel: o.pixel,
                },
                options.loss,
                &[frames[o.frame], extrinsics[o.camera]],
            )?;
        }
        Ok((problem, frames, extrinsics))
    }

    /// Root-mean-square reprojection error (pixels) of the given poses over all observations
    /// (observations that cannot be projected are skipped).
    #[must_use]
    pub fn rms_error(
        &self,
        rig_from_camera: &[Isometry3<f64>],
        world_from_rig: &[Isometry3<f64>],
    ) -> f64 {
        let mut sum = 0.0;
        let mut n = 0usize;
        for o in &self.observations {
            let (Some(c), Some(w), Some(cam)) = (
                rig_from_camera.get(o.camera),
                world_from_rig.get(o.frame),
                self.cameras.get(o.camera),
            ) else {
                continue;
            };
            let p = (w * c)
                .inverse_transform_point(&o.world_point.into())
                .coords;
            if let Ok(px) = cam.project(&p) {
                sum += (px - o.pixel).norm_squared();
                n += 1;
            }
        }
        if n == 0 { 0.0 } else { (sum / n as f64).sqrt() }
    }

    /// Refines the extrinsics and rig poses.
    ///
    /// # Errors
    /// As [`RigRefinement::to_problem`] and [`Problem::solve`] (for instance
    /// [`BundleAdjustError::InitialEvaluationFailed`] when a point is behind its camera at the
    /// start).
    pub fn refine(&self, options: &RigRefinementOptions) -> Result<RigRefinementResult> {
        let (mut problem, frames, extrinsics) = self.to_problem(options)?;
        let summary = problem.solve(&options.solver)?;
        let read = |ids: &[ParameterBlockId]| -> Result<Vec<Isometry3<f64>>> {
            ids.iter()
                .map(|&id| Ok(se3_from_params(problem.parameter_block(id)?)))
                .collect()
        };
        let rig_from_camera = read(&extrinsics)?;
        let world_from_rig = read(&frames)?;
        let mut extrinsic_covariance = vec![None; extrinsics.len()];
        if options.covariance {
            let free: Vec<ParameterBlockId> = extrinsics
                .iter()
                .enumerate()
                .filter(|&(i, _)| i != options.reference_camera)
                .map(|(_, &id)| id)
                .collect();
            if !free.is_empty()
                && let Ok(cov) = problem.covariance(&free, &options.solver)
            {
                for (i, &id) in extrinsics.iter().enumerate() {
                    extrinsic_covariance[i] = cov
                        .block(id, id)
                        .map(|m| Matrix6::from_iterator(m.iter().copied()));
                }
            }
        }
        Ok(RigRefinementResult {
            initial_rms: self.rms_error(&self.rig_from_camera, &self.world_from_rig),
            final_rms: self.rms_error(&rig_from_camera, &world_from_rig),
            rig_from_camera,
            world_from_rig,
            extrinsic_covariance,
            summary,
        })
    }
}
