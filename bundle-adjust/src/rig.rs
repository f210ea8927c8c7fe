//! Rig refinement: the non-linear refinement of infrastructure-based calibration (Heng,
//! Bürki, Lee, Furgale, Siegwart, Pollefeys, "Infrastructure-Based Calibration of a
//! Multi-Camera Rig", ICRA 2014, equation 4).
//!
//! Minimizes Σ ρ(|π_c(camera_from_rig_c · rig_from_world_i · X) − x|²) over the extrinsics
//! `rig_from_camera_c` (one per camera) and the rig poses `world_from_rig_i` (one per frame
//! set), with the map points X fixed and any [`ibc_camera_models`] camera; optionally also over
//! a selection of each camera's intrinsics ([`IntrinsicsSelection`], shared by all its images:
//! InfrasCal's intrinsics against a prior map, TrimBot2020 D3.1 §3.3.2), minus the parameters
//! the caller holds ([`RigRefinementOptions::held_intrinsics`]). Poses live on
//! [`Se3Manifold`]; the rig poses are eliminated by the Schur complement, so the reduced system
//! only holds the extrinsics and the free intrinsics. With free intrinsics the covariance comes
//! with a per-parameter observability figure (as [`crate::RigBundleAdjustment`]'s), so a caller
//! can hold what the data does not determine and solve again.
//!
//! **Targets of unknown pose** ([`RigRefinement::refine_with_targets`]): points may instead lie
//! on targets standing still whose poses are unknown too (calibration boards in front of
//! cameras that never see one board at the same time): such a point is `X` in its target's
//! frame, predicted as π_c(camera_from_rig_c · rig_from_world_i · world_from_target_k · X), and
//! each `world_from_target_k` is one more SE(3) block (right perturbation, Jacobian
//! `R [I, −[X]×]` into the world frame). The rig's motion separates a target's pose from the
//! extrinsic of the camera that sees it, as in hand-eye calibration: rotations about at
//! least two axes are needed.
//!
//! **Gauge.** Moving the rig frame by any rigid motion T (world_from_rig · T,
//! T⁻¹ · rig_from_camera) leaves every prediction unchanged. The gauge is fixed by holding the
//! extrinsic of [`RigRefinementOptions::reference_camera`] at its initial value: the rig frame
//! is defined by that camera (identity if the rig frame is that camera's frame).
//!
//! **Bad starts.** An observation that cannot be evaluated at the initial estimate (its point
//! behind the camera, outside the camera model's domain, or a non-finite residual or
//! Jacobian) is left out of the refinement and reported in
//! [`RigRefinementResult::excluded_observations`]; its camera and rig pose stay in as long as
//! other observations determine them. A camera or frame set left without observations is a
//! [`BundleAdjustError::CameraWithoutObservations`] or
//! [`BundleAdjustError::FrameWithoutObservations`].

use std::sync::Arc;

use ibc_camera_models::{Camera, CameraModel, Rig};
use nalgebra::{DMatrix, Isometry3, Matrix2x3, Matrix3, Matrix6, SMatrix, Vector2, Vector3};

use crate::corrector::validate_loss;
use crate::cost::{CostFunction, EvaluationProbe, Jacobians};
use crate::error::{BundleAdjustError, Result};
use crate::manifold::{Se3Manifold, se3_from_params, se3_from_unit_params, se3_to_params, skew};
use crate::options::SolverOptions;
use crate::problem::{ParameterBlockId, Problem};
use crate::rig_ba_cost::{
    Intrinsics, add_intrinsics_blocks, free_intrinsics, full_intrinsic_covariance, refined_cameras,
    validate_held_intrinsics,
};
use crate::rig_bundle_adjustment::{
    EXTRINSIC_NAMES, ParameterObservability, analyse_camera_blocks, camera_blocks,
};
use crate::summary::Summary;
use crate::{NonExhaustive, RobustLoss};

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
///
/// Build it from an [`ibc_camera_models::Rig`] with [`RigRefinement::from_rig`], or fill the
/// fields.
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
///
/// ```
/// use ibc_bundle_adjust::{RigRefinementOptions, RobustLoss, SolverOptions};
///
/// let options = RigRefinementOptions {
///     loss: RobustLoss::Huber { scale: 2.0 },
///     solver: SolverOptions { num_threads: 2, ..Default::default() },
///     ..Default::default()
/// };
/// assert!(options.covariance);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct RigRefinementOptions {
    /// Robust loss on the squared pixel error (default `RobustLoss::Cauchy { scale: 1.0 }`,
    /// a = 1 pixel: the paper's Cauchy-robust reprojection error).
    pub loss: RobustLoss,
    /// The camera whose extrinsic is held at its initial value to fix the gauge (default 0).
    pub reference_camera: usize,
    /// Compute the covariance of the extrinsics at the solution (default true), and with free
    /// intrinsics the covariance and observability of every free camera parameter.
    pub covariance: bool,
    /// The intrinsics refined with the extrinsics, the same set for every camera (default
    /// [`IntrinsicsSelection::None`]: intrinsics held, the paper's refinement).
    pub intrinsics: IntrinsicsSelection,
    /// Intrinsic parameters held at their start values although
    /// [`intrinsics`](Self::intrinsics) selects them: `(camera, parameter index in CamOdoCal
    /// order)` (default none), for parameters the data does not determine.
    pub held_intrinsics: Vec<(usize, usize)>,
    /// Solver options (default [`SolverOptions::default`], Ceres's defaults).
    pub solver: SolverOptions,
    /// Keeps the struct open to new fields: write it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

/// Which intrinsic parameters of each camera a refinement frees (the rest are held at the
/// camera's values). Indices follow [`CameraModel::focal_length_indices`] and
/// [`CameraModel::principal_point_indices`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum IntrinsicsSelection {
    /// Every intrinsic held.
    #[default]
    None,
    /// The two focal lengths.
    Focal,
    /// The focal lengths and the principal point.
    FocalAndCenter,
    /// Every parameter of the model (distortion included).
    All,
}

impl IntrinsicsSelection {
    /// The selected parameters' indices (CamOdoCal order, ascending) for `camera`'s model.
    #[must_use]
    pub fn indices(self, camera: &Camera) -> Vec<usize> {
        let mut indices = match self {
            Self::None => Vec::new(),
            Self::Focal => camera.focal_length_indices().to_vec(),
            Self::FocalAndCenter => {
                let mut v = camera.focal_length_indices().to_vec();
                v.extend(camera.principal_point_indices());
                v
            }
            Self::All => (0..camera.num_params()).collect(),
        };
        indices.sort_unstable();
        indices
    }
}

impl Default for RigRefinementOptions {
    fn default() -> Self {
        Self {
            loss: RobustLoss::Cauchy { scale: 1.0 },
            reference_camera: 0,
            covariance: true,
            intrinsics: IntrinsicsSelection::None,
            held_intrinsics: Vec::new(),
            solver: SolverOptions::default(),
            non_exhaustive: NonExhaustive(()),
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
    /// Refined target poses ([`RigRefinement::refine_with_targets`]; empty otherwise).
    pub world_from_target: Vec<Isometry3<f64>>,
    /// The cameras with their refined intrinsics (the start ones where held).
    pub cameras: Vec<Camera>,
    /// Covariance of each extrinsic in its right tangent `[ρ, φ]` (metres, radians) for unit
    /// pixel noise, `None` for the reference camera or when not requested or undefined.
    /// Multiply by σ² for a pixel noise σ.
    pub extrinsic_covariance: Vec<Option<Matrix6<f64>>>,
    /// Covariance of each camera's intrinsics (all its parameters in CamOdoCal order, zero
    /// rows and columns for held ones) for unit pixel noise; `None` when none is free, when
    /// not requested or when undefined (a direction the data does not determine).
    pub intrinsic_covariance: Vec<Option<DMatrix<f64>>>,
    /// With free intrinsics and [`RigRefinementOptions::covariance`]: the uncertainty and
    /// observability of every free camera parameter, camera by camera, extrinsic then
    /// intrinsics (defined as for [`crate::RigBundleAdjustment`]); otherwise empty.
    pub observability: Vec<ParameterObservability>,
    /// Root-mean-square reprojection error (pixels) at the start, over the observations used.
    pub initial_rms: f64,
    /// Root-mean-square reprojection error (pixels) at the solution, over the observations
    /// used.
    pub final_rms: f64,
    /// Indices (into [`RigRefinement::observations`], ascending) of the observations left out
    /// because they cannot be evaluated at the initial estimate: behind the camera, outside
    /// the camera model's domain, or not finite. Empty for a good start.
    pub excluded_observations: Vec<usize>,
    /// The solver's summary.
    pub summary: Summary,
}

impl RigRefinementResult {
    /// `rig` with its cameras' extrinsics and intrinsics replaced by the refined ones (names
    /// and the rest unchanged).
    ///
    /// # Errors
    /// [`BundleAdjustError::LengthMismatch`] when `rig` does not have one camera per refined
    /// extrinsic.
    pub fn to_rig(&self, rig: &Rig) -> Result<Rig> {
        if rig.cameras.len() != self.rig_from_camera.len() {
            return Err(BundleAdjustError::LengthMismatch {
                what: "rig.cameras",
                expected: self.rig_from_camera.len(),
                got: rig.cameras.len(),
            });
        }
        let mut refined = rig.clone();
        for ((camera, pose), model) in refined
            .cameras
            .iter_mut()
            .zip(&self.rig_from_camera)
            .zip(&self.cameras)
        {
            camera.rig_from_camera = *pose;
            camera.camera = model.clone();
        }
        Ok(refined)
    }
}

/// A rig refinement compiled into a [`Problem`] by [`RigRefinement::to_problem`].
#[derive(Debug)]
#[non_exhaustive]
pub struct RigProblem {
    /// The problem: one residual block per observation used, in observation order.
    pub problem: Problem,
    /// The SE(3) block ([`Se3Manifold`]) of each frame set's `world_from_rig` (eliminated).
    pub world_from_rig: Vec<ParameterBlockId>,
    /// The SE(3) block of each camera's `rig_from_camera` (the reference camera's constant).
    pub rig_from_camera: Vec<ParameterBlockId>,
    /// Per camera, the block of its free intrinsics and their indices (CamOdoCal order).
    pub intrinsics: Vec<Option<(ParameterBlockId, Vec<usize>)>>,
    /// The SE(3) block of each free target (empty without targets).
    pub world_from_target: Vec<ParameterBlockId>,
    /// Indices of the observations left out (see
    /// [`RigRefinementResult::excluded_observations`]).
    pub excluded_observations: Vec<usize>,
}

/// Free targets of [`RigRefinement::refine_with_targets`]: their start poses and, per
/// observation, the target its point is on (`None`: a world point).
#[derive(Default)]
struct Targets<'a> {
    poses: &'a [Isometry3<f64>],
    of_observation: &'a [Option<usize>],
}

impl Targets<'_> {
    /// The target of observation `i`, if any.
    fn of(&self, i: usize) -> Option<usize> {
        self.of_observation.get(i).copied().flatten()
    }

    fn validate(&self, observations: usize) -> Result<()> {
        if self.poses.is_empty() && self.of_observation.is_empty() {
            return Ok(());
        }
        if self.of_observation.len() != observations {
            return Err(BundleAdjustError::LengthMismatch {
                what: "observation_targets",
                expected: observations,
                got: self.of_observation.len(),
            });
        }
        for (i, p) in self.poses.iter().enumerate() {
            check_pose(i, p, "world_from_target")?;
        }
        for (i, t) in self.of_observation.iter().enumerate() {
            if let Some(t) = *t
                && t >= self.poses.len()
            {
                return Err(BundleAdjustError::IndexOutOfRange {
                    what: "observation",
                    position: i,
                    target: "target",
                    index: t,
                    count: self.poses.len(),
                });
            }
        }
        Ok(())
    }

    /// The world point of observation `i` at the target poses `poses`.
    fn world_point(
        &self,
        i: usize,
        point: &Vector3<f64>,
        poses: &[Isometry3<f64>],
    ) -> Vector3<f64> {
        match self.of(i).and_then(|t| poses.get(t)) {
            Some(pose) => pose.transform_point(&(*point).into()).coords,
            None => *point,
        }
    }
}

/// The reprojection residual of one rig observation; arguments
/// `[world_from_rig (7, SE(3)), rig_from_camera (7, SE(3))]`, then with free intrinsics
/// `intrinsics (free count)`, then for a point on a free target `world_from_target (7, SE(3))`.
struct RigReprojection {
    intrinsics: Intrinsics,
    /// The argument sizes, in order.
    sizes: [usize; 4],
    n_args: usize,
    /// Whether the last argument is the pose of the target the point is on.
    on_target: bool,
    /// The point: in the world frame, or in its target's frame when `on_target`.
    world_point: Vector3<f64>,
    pixel: Vector2<f64>,
}

impl RigReprojection {
    fn new(
        intrinsics: Intrinsics,
        n_free: usize,
        on_target: bool,
        world_point: Vector3<f64>,
        pixel: Vector2<f64>,
    ) -> Self {
        let mut sizes = [7, 7, 0, 0];
        let mut n_args = 2;
        if n_free > 0 {
            sizes[n_args] = n_free;
            n_args += 1;
        }
        if on_target {
            sizes[n_args] = 7;
            n_args += 1;
        }
        Self {
            intrinsics,
            sizes,
            n_args,
            on_target,
            world_point,
            pixel,
        }
    }

    /// The tangent sizes of the arguments (6 for a pose).
    fn tangent_sizes(&self) -> [usize; 4] {
        let mut t = self.sizes;
        t[0] = 6;
        t[1] = 6;
        if self.on_target {
            t[self.n_args - 1] = 6;
        }
        t
    }
}

impl CostFunction for RigReprojection {
    fn num_residuals(&self) -> usize {
        2
    }

    fn parameter_block_sizes(&self) -> &[usize] {
        &self.sizes[..self.n_args]
    }

    fn evaluate(
        &self,
        parameters: &[&[f64]],
        residuals: &mut [f64],
        jacobians: Option<&mut Jacobians<'_>>,
    ) -> bool {
        let world_from_rig = se3_from_unit_params(parameters[0]);
        let rig_from_camera = se3_from_unit_params(parameters[1]);
        let has_free = self.n_args - usize::from(self.on_target) > 2;
        let target_arg = self.n_args - 1;
        let world_from_target = self
            .on_target
            .then(|| se3_from_unit_params(parameters[target_arg]));
        let p_world = match &world_from_target {
            Some(t) => t.transform_point(&self.world_point.into()),
            None => self.world_point.into(),
        };
        let p_rig = world_from_rig.inverse_transform_point(&p_world).coords;
        let p_cam = rig_from_camera
            .inverse_transform_point(&p_rig.into())
            .coords;
        let free = if has_free { Some(parameters[2]) } else { None };
        let Some(jac) = jacobians else {
            return self
                .intrinsics
                .reprojection_residual(&p_cam, free, &self.pixel, residuals);
        };
        self.intrinsics
            .with_jacobians(&p_cam, free, |pixel, d_pixel, d_params| {
                // Right perturbations: ∂(T Exp(δ))⁻¹p/∂δ = [−I, [T⁻¹p]×] for δ = [ρ, φ].
                let d_pixel_d_rig = residual_and_rig_jacobian(
                    residuals,
                    pixel,
                    &self.pixel,
                    d_pixel,
                    &rig_from_camera,
                );
                if jac.wants(0) {
                    jac.set(0, &world_from_rig_jacobian(&d_pixel_d_rig, &p_rig));
                }
                if jac.wants(1) {
                    jac.set(1, &rig_from_camera_jacobian(d_pixel, &p_cam));
                }
                if has_free {
                    self.intrinsics.set_jacobian(jac, 2, d_params);
                }
                if let Some(t) = world_from_target
                    && jac.wants(target_arg)
                {
                    // ∂(T Exp(δ) X)/∂δ = R [I, −[X]×], then into the rig and camera frames.
                    let rig_from_world: Matrix3<f64> = world_from_rig
                        .rotation
                        .to_rotation_matrix()
                        .into_inner()
                        .transpose();
                    let a = d_pixel_d_rig
                        * rig_from_world
                        * t.rotation.to_rotation_matrix().into_inner();
                    let mut j = SMatrix::<f64, 2, 6>::zeros();
                    j.fixed_view_mut::<2, 3>(0, 0).copy_from(&a);
                    j.fixed_view_mut::<2, 3>(0, 3)
                        .copy_from(&(-a * skew(&self.world_point)));
                    jac.set(target_arg, &j);
                }
            })
    }
}

/// ∂pixel/∂δ of a right perturbation δ = `[ρ, φ]` of `world_from_rig`, for the projection of
/// `camera_from_rig · p_rig` with `d_pixel_d_rig` = ∂pixel/∂p_cam · R_camera_from_rig and
/// `p_rig` the point in the rig frame: `[−A, A [p_rig]×]` (shared with the rig bundle
/// adjustment).
#[inline]
pub(crate) fn world_from_rig_jacobian(
    d_pixel_d_rig: &Matrix2x3<f64>,
    p_rig: &Vector3<f64>,
) -> SMatrix<f64, 2, 6> {
    let mut j = SMatrix::<f64, 2, 6>::zeros();
    j.fixed_view_mut::<2, 3>(0, 0).copy_from(&(-d_pixel_d_rig));
    j.fixed_view_mut::<2, 3>(0, 3)
        .copy_from(&(d_pixel_d_rig * skew(p_rig)));
    j
}

/// Writes the reprojection residual `pixel − observed` and returns ∂pixel/∂p_rig =
/// `d_pixel` (∂pixel/∂p_cam) · R_camera_from_rig (shared with the rig bundle adjustment).
#[inline]
pub(crate) fn residual_and_rig_jacobian(
    residuals: &mut [f64],
    pixel: &Vector2<f64>,
    observed: &Vector2<f64>,
    d_pixel: &Matrix2x3<f64>,
    rig_from_camera: &Isometry3<f64>,
) -> Matrix2x3<f64> {
    residuals[0] = pixel.x - observed.x;
    residuals[1] = pixel.y - observed.y;
    let camera_from_rig: Matrix3<f64> = rig_from_camera
        .rotation
        .to_rotation_matrix()
        .into_inner()
        .transpose();
    d_pixel * camera_from_rig
}

/// ∂pixel/∂δ of a right perturbation δ = `[ρ, φ]` of `rig_from_camera`, with `d_pixel` =
/// ∂pixel/∂p_cam and `p_cam` the point in the camera frame: `[−D, D [p_cam]×]` (shared with
/// the rig bundle adjustment).
#[inline]
pub(crate) fn rig_from_camera_jacobian(
    d_pixel: &Matrix2x3<f64>,
    p_cam: &Vector3<f64>,
) -> SMatrix<f64, 2, 6> {
    let mut j = SMatrix::<f64, 2, 6>::zeros();
    j.fixed_view_mut::<2, 3>(0, 0).copy_from(&(-d_pixel));
    j.fixed_view_mut::<2, 3>(0, 3)
        .copy_from(&(d_pixel * skew(p_cam)));
    j
}

pub(crate) fn check_pose(index: usize, pose: &Isometry3<f64>, what: &'static str) -> Result<()> {
    if se3_to_params(pose).iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(BundleAdjustError::NonFiniteInput { what, index })
    }
}

impl RigRefinement {
    /// The refinement of `rig`'s extrinsics: its cameras (intrinsics held fixed) and their
    /// `rig_from_camera` as the start, the start `world_from_rig` of each frame set, and the
    /// observations (their `camera` is a position in `rig.cameras`, their `frame` one in
    /// `world_from_rig`).
    #[must_use]
    pub fn from_rig(
        rig: &Rig,
        world_from_rig: Vec<Isometry3<f64>>,
        observations: Vec<RigObservation>,
    ) -> Self {
        Self {
            cameras: rig.cameras.iter().map(|c| c.camera.clone()).collect(),
            rig_from_camera: rig.cameras.iter().map(|c| c.rig_from_camera).collect(),
            world_from_rig,
            observations,
        }
    }

    fn validate(&self, options: &RigRefinementOptions) -> Result<()> {
        let nc = self.cameras.len();
        if self.rig_from_camera.len() != nc {
            return Err(BundleAdjustError::LengthMismatch {
                what: "rig_from_camera",
                expected: nc,
                got: self.rig_from_camera.len(),
            });
        }
        if options.reference_camera >= nc {
            return Err(BundleAdjustError::InvalidOption {
                name: "reference_camera",
                reason: format!(
                    "camera {} does not exist ({nc} cameras)",
                    options.reference_camera
                ),
            });
        }
        validate_loss(&options.loss)?;
        validate_held_intrinsics(&self.cameras, &options.held_intrinsics)?;
        for (i, p) in self.rig_from_camera.iter().enumerate() {
            check_pose(i, p, "rig_from_camera")?;
        }
        for (i, p) in self.world_from_rig.iter().enumerate() {
            check_pose(i, p, "world_from_rig")?;
        }
        let nf = self.world_from_rig.len();
        for (i, o) in self.observations.iter().enumerate() {
            let out_of_range = |target, index, count| BundleAdjustError::IndexOutOfRange {
                what: "observation",
                position: i,
                target,
                index,
                count,
            };
            if o.camera >= nc {
                return Err(out_of_range("camera", o.camera, nc));
            }
            if o.frame >= nf {
                return Err(out_of_range("frame set", o.frame, nf));
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
    /// reference camera's held constant), one residual per observation that can be evaluated
    /// at the initial estimate (the others are listed in
    /// [`RigProblem::excluded_observations`]).
    ///
    /// # Errors
    /// [`BundleAdjustError::LengthMismatch`], [`BundleAdjustError::IndexOutOfRange`],
    /// [`BundleAdjustError::NonFiniteInput`] or [`BundleAdjustError::NonFiniteObservation`]
    /// for an inconsistent description, [`BundleAdjustError::InvalidOption`] for a reference
    /// camera that does not exist, [`BundleAdjustError::InvalidLossScale`], and
    /// [`BundleAdjustError::CameraWithoutObservations`] or
    /// [`BundleAdjustError::FrameWithoutObservations`] naming a camera or frame set without a
    /// usable observation.
    pub fn to_problem(&self, options: &RigRefinementOptions) -> Result<RigProblem> {
        self.to_problem_with_targets(&Targets::default(), options)
    }

    /// [`to_problem`](Self::to_problem) with free targets (see
    /// [`refine_with_targets`](Self::refine_with_targets)).
    fn to_problem_with_targets(
        &self,
        targets: &Targets<'_>,
        options: &RigRefinementOptions,
    ) -> Result<RigProblem> {
        self.validate(options)?;
        targets.validate(self.observations.len())?;
        let target_params: Vec<[f64; 7]> = targets.poses.iter().map(se3_to_params).collect();
        let fixed: Vec<Arc<Camera>> = self.cameras.iter().cloned().map(Arc::new).collect();
        let frame_params: Vec<[f64; 7]> = self.world_from_rig.iter().map(se3_to_params).collect();
        let camera_params: Vec<[f64; 7]> = self.rig_from_camera.iter().map(se3_to_params).collect();
        let free = free_intrinsics(&self.cameras, |c, camera| {
            options
                .intrinsics
                .indices(camera)
                .into_iter()
                .filter(|&p| !options.held_intrinsics.contains(&(c, p)))
                .collect()
        });
        // Observations that cannot be evaluated at the start are left out.
        let mut probe = EvaluationProbe::default();
        let mut costs = Vec::with_capacity(self.observations.len());
        let mut excluded_observations = Vec::new();
        let mut used_by_camera = vec![0usize; self.cameras.len()];
        let mut used_by_frame = vec![0usize; self.world_from_rig.len()];
        for (i, o) in self.observations.iter().enumerate() {
            let (intrinsics, n_free) = Intrinsics::of(&fixed, o.camera, free[o.camera].as_ref());
            let target = targets.of(i);
            let cost =
                RigReprojection::new(intrinsics, n_free, target.is_some(), o.world_point, o.pixel);
            let mut params: Vec<&[f64]> = vec![&frame_params[o.frame], &camera_params[o.camera]];
            if let Some(f) = free[o.camera].as_ref() {
                params.push(&f.values);
            }
            if let Some(t) = target {
                params.push(&target_params[t]);
            }
            if probe.evaluates(&cost, &params, &cost.tangent_sizes()[..cost.n_args]) {
                used_by_camera[o.camera] += 1;
                used_by_frame[o.frame] += 1;
                costs.push((i, (o, cost)));
            } else {
                excluded_observations.push(i);
            }
        }
        check_rig_coverage(
            &used_by_camera,
            &used_by_frame,
            &excluded_observations,
            &self.observations,
            |o| (o.camera, o.frame),
        )?;
        let mut problem = Problem::new();
        let world_from_rig = frame_params
            .iter()
            .map(|p| problem.add_manifold_block(p, Se3Manifold))
            .collect::<Result<Vec<_>>>()?;
        let rig_from_camera = camera_params
            .iter()
            .map(|p| problem.add_manifold_block(p, Se3Manifold))
            .collect::<Result<Vec<_>>>()?;
        let intrinsics = add_intrinsics_blocks(&mut problem, &free)?;
        let world_from_target = target_params
            .iter()
            .map(|p| problem.add_manifold_block(p, Se3Manifold))
            .collect::<Result<Vec<_>>>()?;
        for &f in &world_from_rig {
            problem.set_eliminated(f, true)?;
        }
        problem.set_constant(rig_from_camera[options.reference_camera], true)?;
        for (i, (o, cost)) in costs {
            let mut blocks = vec![world_from_rig[o.frame], rig_from_camera[o.camera]];
            if let Some((id, _)) = &intrinsics[o.camera] {
                blocks.push(*id);
            }
            if let Some(t) = targets.of(i) {
                blocks.push(world_from_target[t]);
            }
            problem.add_residual_block(cost, options.loss, &blocks)?;
        }
        Ok(RigProblem {
            problem,
            world_from_rig,
            rig_from_camera,
            intrinsics,
            world_from_target,
            excluded_observations,
        })
    }

    /// Root-mean-square reprojection error (pixels) of the given poses over all observations
    /// (observations that cannot be projected are skipped), with the problem's cameras.
    #[must_use]
    pub fn rms_error(
        &self,
        rig_from_camera: &[Isometry3<f64>],
        world_from_rig: &[Isometry3<f64>],
    ) -> f64 {
        self.rms_over(
            &[],
            &self.cameras,
            rig_from_camera,
            world_from_rig,
            (&Targets::default(), &[]),
        )
    }

    /// [`RigRefinement::rms_error`] with the given cameras, without the observations in
    /// `excluded` (ascending).
    fn rms_over(
        &self,
        excluded: &[usize],
        cameras: &[Camera],
        rig_from_camera: &[Isometry3<f64>],
        world_from_rig: &[Isometry3<f64>],
        (targets, target_poses): (&Targets<'_>, &[Isometry3<f64>]),
    ) -> f64 {
        let mut sum = 0.0;
        let mut n = 0usize;
        for (i, o) in self.observations.iter().enumerate() {
            if excluded.binary_search(&i).is_ok() {
                continue;
            }
            let (Some(c), Some(w), Some(cam)) = (
                rig_from_camera.get(o.camera),
                world_from_rig.get(o.frame),
                cameras.get(o.camera),
            ) else {
                continue;
            };
            let world_point = targets.world_point(i, &o.world_point, target_poses);
            let p = (w * c).inverse_transform_point(&world_point.into()).coords;
            if let Ok(px) = cam.project(&p) {
                sum += (px - o.pixel).norm_squared();
                n += 1;
            }
        }
        if n == 0 { 0.0 } else { (sum / n as f64).sqrt() }
    }

    /// Refines the extrinsics, rig poses and the selected intrinsics, leaving out the
    /// observations that cannot be evaluated at the initial estimate (see the module
    /// documentation).
    ///
    /// # Errors
    /// As [`RigRefinement::to_problem`] and [`Problem::solve`];
    /// [`BundleAdjustError::RefinedIntrinsicsRejected`] when a model refuses its refined
    /// intrinsics; with free intrinsics and [`RigRefinementOptions::covariance`],
    /// [`BundleAdjustError::SingularInformation`] when the rig poses are not determined.
    pub fn refine(&self, options: &RigRefinementOptions) -> Result<RigRefinementResult> {
        self.refine_over(&Targets::default(), options)
    }

    /// [`refine`](Self::refine) where some points lie on targets whose poses are unknown too:
    /// `observation_targets[i]` is `Some(k)` when observation `i`'s `world_point` is a point of
    /// target `k` in that target's frame (a calibration board standing still while the rig
    /// moves), `None` for a point in the world frame. Each target's `world_from_target`
    /// starts at `world_from_target[k]` and is refined with the rest; the result holds the
    /// refined poses in [`RigRefinementResult::world_from_target`]. Observations in the world
    /// frame (or a held reference) must fix the world: targets alone leave it free.
    ///
    /// # Errors
    /// As [`refine`](Self::refine), and [`BundleAdjustError::LengthMismatch`] when
    /// `observation_targets` does not have one entry per observation,
    /// [`BundleAdjustError::IndexOutOfRange`] for a target that does not exist,
    /// [`BundleAdjustError::NonFiniteInput`] for a non-finite target pose.
    pub fn refine_with_targets(
        &self,
        world_from_target: &[Isometry3<f64>],
        observation_targets: &[Option<usize>],
        options: &RigRefinementOptions,
    ) -> Result<RigRefinementResult> {
        self.refine_over(
            &Targets {
                poses: world_from_target,
                of_observation: observation_targets,
            },
            options,
        )
    }

    fn refine_over(
        &self,
        targets: &Targets<'_>,
        options: &RigRefinementOptions,
    ) -> Result<RigRefinementResult> {
        let RigProblem {
            mut problem,
            world_from_rig: frames,
            rig_from_camera: extrinsics,
            intrinsics,
            world_from_target: target_blocks,
            excluded_observations,
        } = self.to_problem_with_targets(targets, options)?;
        let summary = problem.solve(&options.solver)?;
        let read = |ids: &[ParameterBlockId]| -> Result<Vec<Isometry3<f64>>> {
            ids.iter()
                .map(|&id| Ok(se3_from_params(problem.parameter_block(id)?)))
                .collect()
        };
        let rig_from_camera = read(&extrinsics)?;
        let world_from_rig = read(&frames)?;
        let world_from_target = read(&target_blocks)?;
        let cameras = refined_cameras(&self.cameras, &intrinsics, &problem)?;
        let nc = extrinsics.len();
        let mut extrinsic_covariance = vec![None; nc];
        let mut intrinsic_covariance = vec![None; nc];
        let mut observability = Vec::new();
        let free_extrinsic = |c: usize| c != options.reference_camera;
        if options.covariance && intrinsics.iter().any(Option::is_some) {
            let blocks = camera_blocks(&extrinsics, &intrinsics, |c| {
                free_extrinsic(c).then_some(&EXTRINSIC_NAMES[..])
            });
            let (entries, covariances) =
                analyse_camera_blocks(&problem, &blocks, &cameras, &options.solver)?;
            observability = entries;
            for (block, cov) in blocks.iter().zip(covariances) {
                let (c, Some(cov)) = (block.camera, cov) else {
                    continue;
                };
                match block.intrinsics {
                    Some(free) => {
                        intrinsic_covariance[c] = Some(full_intrinsic_covariance(
                            &cov,
                            free,
                            cameras[c].num_params(),
                        ));
                    }
                    None => {
                        extrinsic_covariance[c] = Some(Matrix6::from_iterator(cov.iter().copied()));
                    }
                }
            }
        } else if options.covariance {
            let free: Vec<ParameterBlockId> = (0..nc)
                .filter(|&c| free_extrinsic(c))
                .map(|c| extrinsics[c])
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
            initial_rms: self.rms_over(
                &excluded_observations,
                &self.cameras,
                &self.rig_from_camera,
                &self.world_from_rig,
                (targets, targets.poses),
            ),
            final_rms: self.rms_over(
                &excluded_observations,
                &cameras,
                &rig_from_camera,
                &world_from_rig,
                (targets, &world_from_target),
            ),
            rig_from_camera,
            world_from_rig,
            world_from_target,
            cameras,
            extrinsic_covariance,
            intrinsic_covariance,
            observability,
            excluded_observations,
            summary,
        })
    }
}

/// The first camera, then the first frame set, that no observation reaches once those at
/// `excluded` (indices into `observations`) are left out, as the typed error naming it and
/// counting its excluded observations; `by_camera` and `by_frame` count the observations
/// kept. `camera_and_frame` reads an observation's camera and frame set.
pub(crate) fn check_rig_coverage<O>(
    by_camera: &[usize],
    by_frame: &[usize],
    excluded: &[usize],
    observations: &[O],
    camera_and_frame: impl Fn(&O) -> (usize, usize),
) -> Result<()> {
    let count = |pick: &dyn Fn((usize, usize)) -> bool| {
        excluded
            .iter()
            .filter(|&&i| {
                observations
                    .get(i)
                    .is_some_and(|o| pick(camera_and_frame(o)))
            })
            .count()
    };
    if let Some(camera) = by_camera.iter().position(|&n| n == 0) {
        return Err(BundleAdjustError::CameraWithoutObservations {
            camera,
            excluded: count(&|(c, _)| c == camera),
        });
    }
    if let Some(frame) = by_frame.iter().position(|&n| n == 0) {
        return Err(BundleAdjustError::FrameWithoutObservations {
            frame,
            excluded: count(&|(_, f)| f == frame),
        });
    }
    Ok(())
}
