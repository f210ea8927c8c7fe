//! Rig bundle adjustment with free points: the self-calibration of a multi-camera rig's
//! extrinsics (and optionally intrinsics) without a map (TrimBot2020 deliverable D3.1; the
//! generalized-camera bundle adjustment of Heng, Li, Pollefeys, "CamOdoCal: Automatic
//! Intrinsic and Extrinsic Calibration of a Rig with Multiple Generic Cameras and Odometry",
//! IROS 2013, section IV-E; Triggs et al., "Bundle Adjustment — A Modern Synthesis", 2000,
//! for the gauge and the covariance).
//!
//! Minimizes Σ ρ(|π_c(camera_from_rig_c · rig_from_world_i · X_j) − x_cij|²) over the points
//! X_j (eliminated by the Schur complement), the rig poses `world_from_rig_i`, the extrinsics
//! `rig_from_camera_c` and, if asked, the intrinsics of each camera (one set per camera,
//! shared by all its images; any [`ibc_camera_models`] model, in CamOdoCal order). The
//! extrinsics and rig poses are poses on SE(3) updated on the right, as in [`crate::rig`],
//! whose Jacobians this solver shares. The reduced system holds the rig poses, the
//! extrinsics and the intrinsics; it is solved densely, sparsely or by conjugate gradients
//! ([`crate::LinearSolverType`]).
//!
//! **Gauge.** A similarity of the world and a rigid motion of the rig frame leave every
//! prediction unchanged (13 degrees of freedom). They are fixed by
//! - holding the extrinsic of [`RigBundleAdjustmentOptions::reference_camera`] (the rig frame
//!   is that camera's mounting),
//! - holding the rig pose of [`RigBundleAdjustmentOptions::reference_frame`] (the world
//!   frame), and
//! - the scale ([`ScaleGauge`]): a known baseline between the reference camera and another
//!   camera, or a known distance travelled between the reference rig pose and another one
//!   (odometry), both **hard** constraints (the pose's translation lives on the sphere of
//!   that radius about the reference, a five-dimensional manifold; the start is moved
//!   radially onto it); or a known distance between two points, a **soft** constraint (a
//!   prior residual (|X_a − X_b| − d)/σ with the caller's σ, default 1e-6 m, i.e. weight
//!   10⁶ per metre against residuals in pixels).
//!
//! **Covariance and observability.** At the solution the Jacobian (robust loss folded in) is
//! evaluated, the points are eliminated, and the rig poses are marginalized out of the
//! reduced information: M = S_cc − S_cf S_ff⁻¹ S_fc over the free camera parameters c (the
//! extrinsics' tangent coordinates and the free intrinsics), f the free rig poses. M⁻¹ is the
//! covariance of the camera parameters for unit pixel noise (multiply by σ²), in the gauge
//! above. For each camera parameter i, with M̃ = D M D, D = diag(M)^(−1/2):
//!
//! - `std_dev` = √(M⁻¹)_ii (unit pixel noise; infinite when i has a component in the null space
//!   of M, that is when the data does not determine it);
//! - `observability` = 1 / (M_ii (M⁻¹)_ii) = 1 / (M̃⁻¹)_ii ∈ [0, 1]: the share of the
//!   information on parameter i that is left once every other parameter is free as well
//!   (the inverse of its variance-inflation factor). 1 means the data determines i
//!   independently of the others; near 0, only in combination with others (a direction the
//!   data hardly sees); exactly 0 for a parameter in the null space, or one the data does not
//!   touch at all. Null directions are the eigenvectors of M̃ whose eigenvalue is below
//!   [`NULL_EIGENVALUE`] times the largest; a parameter is in the null space when the squares
//!   of its components in them sum above 1e-6.
//!
//! Callers hold what the data does not determine: parameters with a low observability (for
//! instance below 0.01) or a `std_dev` above their tolerance, with
//! [`RigBundleAdjustmentOptions::held_intrinsics`] and
//! [`RigBundleAdjustmentOptions::held_extrinsics`], and solve again.
//!
//! **Bad starts.** An observation that cannot be evaluated at the initial estimate (behind
//! the camera, outside the model's domain, not finite) is left out and listed in
//! [`RigBundleAdjustmentResult::excluded_observations`]. A camera, rig pose or point left
//! without observations, or a point left with a single one (two are needed to determine
//! it), is a typed error naming it.

use std::sync::Arc;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{
    LltRegularization, cholesky_in_place, cholesky_in_place_scratch,
};
use faer::linalg::cholesky::llt::solve::{solve_in_place, solve_in_place_scratch};
use faer::{MatMut, Par};
use ibc_camera_models::{Camera, CameraModel, Rig};
use nalgebra::{DMatrix, Isometry3, Matrix6, SMatrix, Vector2, Vector3};

use crate::corrector::validate_loss;
use crate::cost::EvaluationProbe;
use crate::error::{BundleAdjustError, Result};
use crate::evaluator::{Accumulated, EvalError, Evaluator};
use crate::manifold::{Se3Manifold, se3_from_params, se3_to_params};
use crate::options::{LossCurvature, SolverOptions};
use crate::parallel::Executor;
use crate::problem::{ParameterBlockId, Problem};
use crate::program::{NONE, Program};
use crate::reduced::{ReducedLayout, TargetKind};
use crate::rig::{check_pose, check_rig_coverage};
use crate::rig_ba_cost::{
    Intrinsics, IntrinsicsBlock, PointDistancePrior, RigBaReprojection, SpherePoseManifold,
    add_intrinsics_blocks, free_intrinsics, full_intrinsic_covariance, refined_cameras,
    validate_held_intrinsics,
};
use crate::schur::SchurComplement;
use crate::summary::Summary;
use crate::{NonExhaustive, RobustLoss};

/// Eigenvalues of the scaled marginal information below this times the largest count as
/// null directions (the data does not determine them). 1e-10 is about the relative precision
/// of an information matrix assembled in double precision from ~10⁶ residuals.
pub const NULL_EIGENVALUE: f64 = 1e-10;

/// Default σ of the point-distance prior ([`ScaleGauge::PointDistance`]), metres.
pub const DEFAULT_DISTANCE_SIGMA_M: f64 = 1e-6;

/// One observation of a free point by one camera in one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigBaObservation {
    /// Frame index (into [`RigBundleAdjustment::world_from_rig`]).
    pub frame: usize,
    /// Camera index (into [`RigBundleAdjustment::cameras`]).
    pub camera: usize,
    /// Point index (into [`RigBundleAdjustment::points`]).
    pub point: usize,
    /// The observed pixel (pixel centres at integer coordinates).
    pub pixel: Vector2<f64>,
}

/// A rig bundle adjustment: cameras, start extrinsics, rig poses and points, observations.
#[derive(Debug, Clone)]
pub struct RigBundleAdjustment {
    /// Intrinsics of each camera (start values when they are optimized).
    pub cameras: Vec<Camera>,
    /// Start extrinsic of each camera.
    pub rig_from_camera: Vec<Isometry3<f64>>,
    /// Start rig pose of each frame.
    pub world_from_rig: Vec<Isometry3<f64>>,
    /// Start points, in the world frame.
    pub points: Vec<Vector3<f64>>,
    /// Observations.
    pub observations: Vec<RigBaObservation>,
}

/// How the scale of a rig bundle adjustment is fixed (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum ScaleGauge {
    /// The start distance between the reference camera and the camera farthest from it is
    /// held (hard constraint). The default: a rig's baselines are usually known from its
    /// drawing or a previous calibration to far better than its rotations.
    InitialBaseline,
    /// The distance between the reference camera and `camera` is `distance_m` (hard
    /// constraint).
    Baseline {
        /// The camera (not the reference camera).
        camera: usize,
        /// The distance between the two camera centres, metres.
        distance_m: f64,
    },
    /// The distance between the rig origins of the reference frame and `frame` is
    /// `distance_m`, as odometry measured it (hard constraint).
    Odometry {
        /// The frame (not the reference frame).
        frame: usize,
        /// The distance travelled, metres (straight line between the two rig origins).
        distance_m: f64,
    },
    /// The distance between points `points[0]` and `points[1]` is `distance_m`, with
    /// standard deviation `sigma_m` (soft constraint, a prior residual; see
    /// [`DEFAULT_DISTANCE_SIGMA_M`]).
    PointDistance {
        /// The two points.
        points: [usize; 2],
        /// Their distance, metres.
        distance_m: f64,
        /// Standard deviation of the prior, metres.
        sigma_m: f64,
    },
    /// The scale is left free: Levenberg-Marquardt's damping keeps steps finite, but the
    /// covariance is undefined and the scale drifts with the noise.
    Free,
}

/// Options of [`RigBundleAdjustment::solve`].
///
/// ```
/// use ibc_bundle_adjust::{RigBundleAdjustmentOptions, RobustLoss, ScaleGauge};
///
/// let options = RigBundleAdjustmentOptions {
///     optimize_intrinsics: true,
///     scale: ScaleGauge::Baseline { camera: 2, distance_m: 4.6 },
///     loss: RobustLoss::Huber { scale: 2.0 },
///     ..Default::default()
/// };
/// assert_eq!(options.reference_camera, 0);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct RigBundleAdjustmentOptions {
    /// Robust loss on the squared pixel error (default `RobustLoss::Cauchy { scale: 1.0 }`,
    /// the rig refinement's).
    pub loss: RobustLoss,
    /// The camera whose extrinsic is held at its start value (default 0).
    pub reference_camera: usize,
    /// The frame whose rig pose is held at its start value (default 0).
    pub reference_frame: usize,
    /// How the scale is fixed (default [`ScaleGauge::InitialBaseline`]).
    pub scale: ScaleGauge,
    /// Optimize the intrinsics of every camera (default false).
    pub optimize_intrinsics: bool,
    /// Intrinsic parameters held at their start values when the intrinsics are optimized:
    /// `(camera, parameter index in CamOdoCal order)` (default none).
    pub held_intrinsics: Vec<(usize, usize)>,
    /// Cameras whose extrinsics are held at their start values besides the reference camera
    /// (default none).
    pub held_extrinsics: Vec<usize>,
    /// Compute the covariance and observability of the camera parameters at the solution
    /// (default false: it costs a dense factorization of the rig poses' reduced system,
    /// about as much as two iterations).
    pub covariance: bool,
    /// Solver options (default: Ceres's, [`SolverOptions::default`], except
    /// [`LossCurvature::InlierCurvature`]: the loss's curvature kept for the inliers, which
    /// saves about one iteration in six here; [`SolverOptions::reuse_factorization`]: a
    /// point seen in k images adds k² block products to the reduced matrix, so its forming
    /// dominates a step, and most steps are instead solved by a few conjugate-gradient
    /// iterations preconditioned by an earlier factor; and an initial trust-region radius of
    /// 1e5 instead of 1e4: the damping D/radius holds back the directions the data
    /// determines weakly (intrinsics against extrinsics) until the radius has grown: from
    /// 1e4 the full simulated garage with intrinsics free took six iterations, its last
    /// steps lowering the cost by 41, 11 and 1.6 while the radius tripled per step, against
    /// five from 1e5, ending at a lower cost; the first step is accepted from either).
    pub solver: SolverOptions,
    /// Keeps the struct open to new fields: write it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for RigBundleAdjustmentOptions {
    fn default() -> Self {
        Self {
            loss: RobustLoss::Cauchy { scale: 1.0 },
            reference_camera: 0,
            reference_frame: 0,
            scale: ScaleGauge::InitialBaseline,
            optimize_intrinsics: false,
            held_intrinsics: Vec::new(),
            held_extrinsics: Vec::new(),
            covariance: false,
            solver: SolverOptions {
                loss_curvature: LossCurvature::InlierCurvature,
                reuse_factorization: true,
                initial_trust_region_radius: 1e5,
                ..SolverOptions::default()
            },
            non_exhaustive: NonExhaustive(()),
        }
    }
}

/// The uncertainty and observability of one free camera parameter (see the module
/// documentation for the definitions).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct ParameterObservability {
    /// The camera.
    pub camera: usize,
    /// The parameter: `rho_x`, `rho_y`, `rho_z`, `phi_x`, `phi_y`, `phi_z` for an extrinsic
    /// (its right tangent, metres and radians), `baseline_a`, `baseline_b` for the two free
    /// translation directions of the baseline camera, or the model's parameter name
    /// (CamOdoCal order) for an intrinsic.
    pub name: &'static str,
    /// Whether it is an intrinsic (else an extrinsic coordinate).
    pub intrinsic: bool,
    /// Index of the parameter (in the extrinsic's tangent, or in CamOdoCal order).
    pub index: usize,
    /// Marginal standard deviation for unit pixel noise (multiply by σ); infinite when the
    /// data does not determine it.
    pub std_dev: f64,
    /// 1 / variance-inflation factor, in [0, 1].
    pub observability: f64,
}

/// The adjusted rig.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct RigBundleAdjustmentResult {
    /// Cameras with their (possibly refined) intrinsics.
    pub cameras: Vec<Camera>,
    /// Refined extrinsics.
    pub rig_from_camera: Vec<Isometry3<f64>>,
    /// Refined rig poses.
    pub world_from_rig: Vec<Isometry3<f64>>,
    /// Refined points.
    pub points: Vec<Vector3<f64>>,
    /// Covariance of each extrinsic in its right tangent `[ρ, φ]` for unit pixel noise
    /// (multiply by σ²); `None` for held extrinsics, without
    /// [`RigBundleAdjustmentOptions::covariance`] or when undefined (a null direction).
    pub extrinsic_covariance: Vec<Option<Matrix6<f64>>>,
    /// Covariance of each camera's intrinsics (all its parameters in CamOdoCal order, zero
    /// rows and columns for held ones) for unit pixel noise; `None` when not optimized, not
    /// requested or undefined.
    pub intrinsic_covariance: Vec<Option<DMatrix<f64>>>,
    /// Uncertainty and observability of every free camera parameter, camera by camera,
    /// extrinsic then intrinsics (empty without [`RigBundleAdjustmentOptions::covariance`]).
    pub observability: Vec<ParameterObservability>,
    /// Why the covariance asked for by [`RigBundleAdjustmentOptions::covariance`] could not
    /// be computed, when it could not: [`BundleAdjustError::SingularInformation`] when the
    /// parameters marginalized out (rig poses, points, held-back intrinsics) are not
    /// determined, so that no marginal covariance of the cameras exists. The adjusted values
    /// are still returned; [`Self::extrinsic_covariance`], [`Self::intrinsic_covariance`]
    /// and [`Self::observability`] are then empty.
    pub covariance_error: Option<BundleAdjustError>,
    /// Root-mean-square reprojection error (pixels) at the start of the solve (the start
    /// values, with the scale gauge's pose moved onto its sphere), over the observations used.
    pub initial_rms: f64,
    /// Root-mean-square reprojection error (pixels) at the solution.
    pub final_rms: f64,
    /// Indices (ascending) of the observations left out because they cannot be evaluated at
    /// the start.
    pub excluded_observations: Vec<usize>,
    /// The solver's summary.
    pub summary: Summary,
}

impl RigBundleAdjustmentResult {
    /// `rig` with its cameras' extrinsics and intrinsics replaced by the refined ones.
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
        for ((c, pose), camera) in refined
            .cameras
            .iter_mut()
            .zip(&self.rig_from_camera)
            .zip(&self.cameras)
        {
            c.rig_from_camera = *pose;
            c.camera = camera.clone();
        }
        Ok(refined)
    }
}

/// A pose block held on a sphere: its index (camera or frame) and the manifold.
type Sphere = Option<(usize, SpherePoseManifold)>;

/// The compiled problem and where its blocks are.
struct Compiled {
    problem: Problem,
    frames: Vec<ParameterBlockId>,
    extrinsics: Vec<ParameterBlockId>,
    points: Vec<ParameterBlockId>,
    /// Per camera, the block of its free intrinsics and their indices.
    intrinsics: Vec<Option<(ParameterBlockId, Vec<usize>)>>,
    /// The baseline camera and its manifold.
    camera_sphere: Option<(usize, SpherePoseManifold)>,
    held_camera: Vec<bool>,
    excluded: Vec<usize>,
    /// Root-mean-square reprojection error (pixels) at the start of the solve, over the
    /// observations used.
    initial_rms: f64,
}

fn invalid(name: &'static str, reason: String) -> BundleAdjustError {
    BundleAdjustError::InvalidOption { name, reason }
}

impl RigBundleAdjustment {
    /// The adjustment of `rig`: its cameras and extrinsics as the start, the start rig poses
    /// and points, and the observations (`camera` a position in `rig.cameras`).
    #[must_use]
    pub fn from_rig(
        rig: &Rig,
        world_from_rig: Vec<Isometry3<f64>>,
        points: Vec<Vector3<f64>>,
        observations: Vec<RigBaObservation>,
    ) -> Self {
        Self {
            cameras: rig.cameras.iter().map(|c| c.camera.clone()).collect(),
            rig_from_camera: rig.cameras.iter().map(|c| c.rig_from_camera).collect(),
            world_from_rig,
            points,
            observations,
        }
    }

    fn validate(&self, options: &RigBundleAdjustmentOptions) -> Result<()> {
        let nc = self.cameras.len();
        let nf = self.world_from_rig.len();
        let np = self.points.len();
        if self.rig_from_camera.len() != nc {
            return Err(BundleAdjustError::LengthMismatch {
                what: "rig_from_camera",
                expected: nc,
                got: self.rig_from_camera.len(),
            });
        }
        if options.reference_camera >= nc {
            return Err(invalid(
                "reference_camera",
                format!(
                    "camera {} does not exist ({nc} cameras)",
                    options.reference_camera
                ),
            ));
        }
        if options.reference_frame >= nf {
            return Err(invalid(
                "reference_frame",
                format!(
                    "frame {} does not exist ({nf} frames)",
                    options.reference_frame
                ),
            ));
        }
        validate_loss(&options.loss)?;
        options.solver.validate()?;
        for (i, p) in self.rig_from_camera.iter().enumerate() {
            check_pose(i, p, "rig_from_camera")?;
        }
        for (i, p) in self.world_from_rig.iter().enumerate() {
            check_pose(i, p, "world_from_rig")?;
        }
        for (index, x) in self.points.iter().enumerate() {
            if !x.iter().all(|v| v.is_finite()) {
                return Err(BundleAdjustError::NonFiniteInput {
                    what: "points",
                    index,
                });
            }
        }
        validate_held_intrinsics(&self.cameras, &options.held_intrinsics)?;
        if let Some(&c) = options.held_extrinsics.iter().find(|&&c| c >= nc) {
            return Err(invalid(
                "held_extrinsics",
                format!("camera {c} does not exist ({nc} cameras)"),
            ));
        }
        let positive = |v: f64| v.is_finite() && v > 0.0;
        match options.scale {
            ScaleGauge::Baseline { camera, distance_m } => {
                if camera >= nc || camera == options.reference_camera {
                    return Err(invalid(
                        "scale",
                        format!(
                            "the baseline camera {camera} must exist ({nc} cameras) and not be the reference camera"
                        ),
                    ));
                }
                if !positive(distance_m) {
                    return Err(invalid(
                        "scale",
                        format!("the baseline {distance_m} m is not a finite positive distance"),
                    ));
                }
            }
            ScaleGauge::Odometry { frame, distance_m } => {
                if frame >= nf || frame == options.reference_frame {
                    return Err(invalid(
                        "scale",
                        format!(
                            "the odometry frame {frame} must exist ({nf} frames) and not be the reference frame"
                        ),
                    ));
                }
                if !positive(distance_m) {
                    return Err(invalid(
                        "scale",
                        format!("the distance {distance_m} m is not a finite positive distance"),
                    ));
                }
            }
            ScaleGauge::PointDistance {
                points: [a, b],
                distance_m,
                sigma_m,
            } => {
                if a >= np || b >= np || a == b {
                    return Err(invalid(
                        "scale",
                        format!("points {a} and {b} must be two distinct points of {np}"),
                    ));
                }
                if !positive(distance_m) || !positive(sigma_m) {
                    return Err(invalid(
                        "scale",
                        format!(
                            "distance {distance_m} m and sigma {sigma_m} m must be finite and positive"
                        ),
                    ));
                }
            }
            ScaleGauge::InitialBaseline | ScaleGauge::Free => {}
        }
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
            if o.point >= np {
                return Err(out_of_range("point", o.point, np));
            }
            if !o.pixel.iter().all(|v| v.is_finite()) {
                return Err(BundleAdjustError::NonFiniteObservation { index: i });
            }
        }
        Ok(())
    }

    /// The sphere constraint of the scale gauge on a camera or a frame.
    fn spheres(&self, options: &RigBundleAdjustmentOptions) -> Result<(Sphere, Sphere)> {
        let ref_cam = self.rig_from_camera[options.reference_camera]
            .translation
            .vector;
        match options.scale {
            ScaleGauge::InitialBaseline | ScaleGauge::Baseline { .. } => {
                let (camera, radius) = match options.scale {
                    ScaleGauge::Baseline { camera, distance_m } => (camera, distance_m),
                    _ => {
                        let far = (0..self.cameras.len())
                            .filter(|&c| c != options.reference_camera)
                            .map(|c| {
                                let d =
                                    (self.rig_from_camera[c].translation.vector - ref_cam).norm();
                                (c, d)
                            })
                            .max_by(|a, b| a.1.total_cmp(&b.1));
                        match far {
                            Some((c, d)) if d > 0.0 => (c, d),
                            _ => {
                                return Err(invalid(
                                    "scale",
                                    "no camera is away from the reference camera, so no baseline fixes the scale: use ScaleGauge::Odometry or ScaleGauge::PointDistance".into(),
                                ));
                            }
                        }
                    }
                };
                let start = self.rig_from_camera[camera].translation.vector - ref_cam;
                if start.norm() <= 0.0 {
                    return Err(invalid(
                        "scale",
                        format!("camera {camera} starts at the reference camera's centre"),
                    ));
                }
                Ok((
                    Some((
                        camera,
                        SpherePoseManifold {
                            centre: ref_cam,
                            radius,
                        },
                    )),
                    None,
                ))
            }
            ScaleGauge::Odometry { frame, distance_m } => {
                let centre = self.world_from_rig[options.reference_frame]
                    .translation
                    .vector;
                if (self.world_from_rig[frame].translation.vector - centre).norm() <= 0.0 {
                    return Err(invalid(
                        "scale",
                        format!("frame {frame} starts at the reference frame's rig origin"),
                    ));
                }
                Ok((
                    None,
                    Some((
                        frame,
                        SpherePoseManifold {
                            centre,
                            radius: distance_m,
                        },
                    )),
                ))
            }
            ScaleGauge::PointDistance { .. } | ScaleGauge::Free => Ok((None, None)),
        }
    }

    fn compile(&self, options: &RigBundleAdjustmentOptions) -> Result<Compiled> {
        self.validate(options)?;
        let nc = self.cameras.len();
        let (camera_sphere, frame_sphere) = self.spheres(options)?;
        let mut held_camera = vec![false; nc];
        held_camera[options.reference_camera] = true;
        for &c in &options.held_extrinsics {
            held_camera[c] = true;
        }
        // A held baseline camera needs no sphere: holding it fixes the scale already.
        let camera_sphere = camera_sphere.filter(|(c, _)| !held_camera[*c]);
        let mut camera_poses = self.rig_from_camera.clone();
        if let Some((c, m)) = &camera_sphere {
            camera_poses[*c] = m.project(&camera_poses[*c]);
        }
        let mut frame_poses = self.world_from_rig.clone();
        if let Some((f, m)) = &frame_sphere {
            frame_poses[*f] = m.project(&frame_poses[*f]);
        }
        let frame_params: Vec<[f64; 7]> = frame_poses.iter().map(se3_to_params).collect();
        let camera_params: Vec<[f64; 7]> = camera_poses.iter().map(se3_to_params).collect();
        let fixed: Vec<Arc<Camera>> = self.cameras.iter().cloned().map(Arc::new).collect();
        // The manifolds shared by the residuals on the sphere poses (a pointer each).
        let shared_frame_sphere = frame_sphere.map(|(f, m)| (f, Arc::new(m)));
        let shared_camera_sphere = camera_sphere.map(|(c, m)| (c, Arc::new(m)));
        let free = free_intrinsics(&self.cameras, |c, cam| {
            if !options.optimize_intrinsics {
                return Vec::new();
            }
            (0..cam.num_params())
                .filter(|&p| !options.held_intrinsics.contains(&(c, p)))
                .collect()
        });

        let mut problem = Problem::new();
        let points = self
            .points
            .iter()
            .map(|p| problem.add_parameter_block(p.as_slice()))
            .collect::<Result<Vec<_>>>()?;
        let frames = frame_params
            .iter()
            .enumerate()
            .map(|(f, p)| match frame_sphere {
                Some((sf, m)) if sf == f => problem.add_manifold_block(p, m),
                _ => problem.add_manifold_block(p, Se3Manifold),
            })
            .collect::<Result<Vec<_>>>()?;
        let extrinsics = camera_params
            .iter()
            .enumerate()
            .map(|(c, p)| match camera_sphere {
                Some((sc, m)) if sc == c => problem.add_manifold_block(p, m),
                _ => problem.add_manifold_block(p, Se3Manifold),
            })
            .collect::<Result<Vec<_>>>()?;
        let intrinsics = add_intrinsics_blocks(&mut problem, &free)?;
        let soft_point = match options.scale {
            ScaleGauge::PointDistance { points: [_, b], .. } => Some(b),
            _ => None,
        };
        for (j, &p) in points.iter().enumerate() {
            problem.set_eliminated(p, soft_point != Some(j))?;
        }
        problem.set_constant(frames[options.reference_frame], true)?;
        for (c, &held) in held_camera.iter().enumerate() {
            if held {
                problem.set_constant(extrinsics[c], true)?;
            }
        }
        let mut probe = EvaluationProbe::default();
        problem.reserve_residual_blocks(self.observations.len() + 1);
        let mut excluded = Vec::new();
        let mut initial_sum_sq = 0.0;
        let mut by_camera = vec![0usize; nc];
        let mut by_frame = vec![0usize; self.world_from_rig.len()];
        let mut by_point = vec![0usize; self.points.len()];
        // Residual blocks in the observations' point order (a stable counting sort of their
        // indices), the order in which the solver visits them (grouped by eliminated point,
        // ascending within a point): its passes then read the residual blocks and their cost
        // functions in sequence instead of scattered over memory. Each observation is
        // evaluated at the start first; one that cannot be is excluded and counted.
        let mut slot = vec![0usize; self.points.len() + 1];
        for o in &self.observations {
            if let Some(n) = slot.get_mut(o.point + 1) {
                *n += 1;
            }
        }
        for j in 0..self.points.len() {
            slot[j + 1] += slot[j];
        }
        // Scattered writes of copies, then sequential reads: cheaper than gathering.
        let mut sorted = vec![(0usize, None::<RigBaObservation>); self.observations.len()];
        for (i, o) in self.observations.iter().enumerate() {
            sorted[slot[o.point]] = (i, Some(*o));
            slot[o.point] += 1;
        }
        for (i, o) in sorted {
            let Some(o) = o else { continue };
            let fs = shared_frame_sphere
                .as_ref()
                .filter(|(f, _)| *f == o.frame)
                .map(|(_, m)| Arc::clone(m));
            let cs = shared_camera_sphere
                .as_ref()
                .filter(|(c, _)| *c == o.camera)
                .map(|(_, m)| Arc::clone(m));
            let (model, n_free) = Intrinsics::of(&fixed, o.camera, free[o.camera].as_ref());
            let n_args = if n_free > 0 { 4 } else { 3 };
            let sizes = [7, 7, 3, n_free];
            let cost = RigBaReprojection {
                intrinsics: model,
                sizes,
                n_args,
                pixel: o.pixel,
                frame_sphere: fs,
                camera_sphere: cs,
            };
            let params: [&[f64]; 4] = [
                &frame_params[o.frame],
                &camera_params[o.camera],
                self.points[o.point].as_slice(),
                free[o.camera].as_ref().map_or(&[][..], |f| &f.values),
            ];
            // The residual alone: the models' Jacobians exist wherever their projections do.
            if let Some(s) = probe.residual_norm2(&cost, &params[..n_args]) {
                initial_sum_sq += s;
                by_camera[o.camera] += 1;
                by_frame[o.frame] += 1;
                by_point[o.point] += 1;
                let blocks = [
                    frames[o.frame],
                    extrinsics[o.camera],
                    points[o.point],
                    intrinsics[o.camera]
                        .as_ref()
                        .map_or(points[o.point], |(k, _)| *k),
                ];
                problem.add_residual_block(cost, options.loss, &blocks[..n_args])?;
            } else {
                excluded.push(i);
            }
        }
        excluded.sort_unstable();
        let count_excluded = |pick: &dyn Fn(&RigBaObservation) -> bool| {
            excluded
                .iter()
                .filter(|&&i| pick(&self.observations[i]))
                .count()
        };
        check_rig_coverage(&by_camera, &by_frame, &excluded, &self.observations, |o| {
            (o.camera, o.frame)
        })?;
        if let Some(point) = by_point.iter().position(|&n| n < 2) {
            let excluded = count_excluded(&|o| o.point == point);
            return Err(if by_point[point] == 0 {
                BundleAdjustError::PointWithoutObservations { point, excluded }
            } else {
                BundleAdjustError::PointSeenOnce { point, excluded }
            });
        }

        if let ScaleGauge::PointDistance {
            points: [a, b],
            distance_m,
            sigma_m,
        } = options.scale
        {
            problem.add_residual_block(
                PointDistancePrior {
                    distance: distance_m,
                    sigma: sigma_m,
                },
                RobustLoss::Trivial,
                &[points[a], points[b]],
            )?;
        }
        let used = self.observations.len() - excluded.len();
        Ok(Compiled {
            problem,
            frames,
            extrinsics,
            points,
            intrinsics,
            camera_sphere,
            held_camera,
            excluded,
            initial_rms: (initial_sum_sq / used.max(1) as f64).sqrt(),
        })
    }

    /// Root-mean-square reprojection error (pixels) of a solution over the observations not
    /// in `excluded` (ascending); observations that cannot be projected are skipped.
    #[must_use]
    pub fn rms_error(
        &self,
        cameras: &[Camera],
        rig_from_camera: &[Isometry3<f64>],
        world_from_rig: &[Isometry3<f64>],
        points: &[Vector3<f64>],
        excluded: &[usize],
    ) -> f64 {
        let mut sum = 0.0;
        let mut n = 0usize;
        for (i, o) in self.observations.iter().enumerate() {
            if excluded.binary_search(&i).is_ok() {
                continue;
            }
            let (Some(c), Some(w), Some(cam), Some(x)) = (
                rig_from_camera.get(o.camera),
                world_from_rig.get(o.frame),
                cameras.get(o.camera),
                points.get(o.point),
            ) else {
                continue;
            };
            let p = (w * c).inverse_transform_point(&(*x).into()).coords;
            if let Ok(px) = cam.project(&p) {
                sum += (px - o.pixel).norm_squared();
                n += 1;
            }
        }
        if n == 0 { 0.0 } else { (sum / n as f64).sqrt() }
    }

    /// Adjusts points, rig poses, extrinsics and (if asked) intrinsics.
    ///
    /// # Errors
    /// [`BundleAdjustError::LengthMismatch`], [`BundleAdjustError::IndexOutOfRange`],
    /// [`BundleAdjustError::NonFiniteInput`] or [`BundleAdjustError::NonFiniteObservation`]
    /// for an inconsistent description; [`BundleAdjustError::InvalidOption`] for a reference
    /// camera or frame, a held parameter or a scale gauge that does not exist or is
    /// degenerate; [`BundleAdjustError::InvalidLossScale`];
    /// [`BundleAdjustError::CameraWithoutObservations`],
    /// [`BundleAdjustError::FrameWithoutObservations`],
    /// [`BundleAdjustError::PointWithoutObservations`] or
    /// [`BundleAdjustError::PointSeenOnce`] naming what the observations do not determine;
    /// [`BundleAdjustError::RefinedIntrinsicsRejected`]; the errors of [`Problem::solve`];
    /// a covariance that cannot be computed is not an error: see
    /// [`RigBundleAdjustmentResult::covariance_error`].
    pub fn solve(&self, options: &RigBundleAdjustmentOptions) -> Result<RigBundleAdjustmentResult> {
        let Compiled {
            mut problem,
            frames,
            extrinsics,
            points: point_ids,
            intrinsics,
            camera_sphere,
            held_camera,
            excluded,
            initial_rms,
        } = self.compile(options)?;
        let summary = problem.solve(&options.solver)?;
        let read_poses = |ids: &[ParameterBlockId]| -> Result<Vec<Isometry3<f64>>> {
            ids.iter()
                .map(|&id| Ok(se3_from_params(problem.parameter_block(id)?)))
                .collect()
        };
        let rig_from_camera = read_poses(&extrinsics)?;
        let world_from_rig = read_poses(&frames)?;
        let points = point_ids
            .iter()
            .map(|&id| {
                problem
                    .parameter_block(id)
                    .map(|v| Vector3::new(v[0], v[1], v[2]))
            })
            .collect::<Result<Vec<_>>>()?;
        let cameras = refined_cameras(&self.cameras, &intrinsics, &problem)?;
        let mut result = RigBundleAdjustmentResult {
            initial_rms,
            final_rms: self.rms_error(
                &cameras,
                &rig_from_camera,
                &world_from_rig,
                &points,
                &excluded,
            ),
            extrinsic_covariance: vec![None; self.cameras.len()],
            intrinsic_covariance: vec![None; self.cameras.len()],
            observability: Vec::new(),
            covariance_error: None,
            cameras,
            rig_from_camera,
            world_from_rig,
            points,
            excluded_observations: excluded,
            summary,
        };
        if options.covariance {
            // The camera parameter blocks, in order: extrinsic then intrinsics per camera.
            let blocks = camera_blocks(&extrinsics, &intrinsics, |c| {
                if held_camera[c] {
                    None
                } else if camera_sphere.is_some_and(|(sc, _)| sc == c) {
                    Some(&SPHERE_EXTRINSIC_NAMES[..])
                } else {
                    Some(&EXTRINSIC_NAMES[..])
                }
            });
            // The adjustment stands without its covariance: a marginalization that fails
            // is reported with the result, not instead of it.
            let (observability, covariances) =
                match analyse_camera_blocks(&problem, &blocks, &result.cameras, &options.solver) {
                    Ok(analysis) => analysis,
                    Err(e @ BundleAdjustError::SingularInformation) => {
                        result.covariance_error = Some(e);
                        return Ok(result);
                    }
                    Err(e) => return Err(e),
                };
            result.observability = observability;
            for (block, cov) in blocks.iter().zip(covariances) {
                let (c, Some(cov)) = (block.camera, cov) else {
                    continue;
                };
                if let Some(free) = block.intrinsics {
                    result.intrinsic_covariance[c] = Some(full_intrinsic_covariance(
                        &cov,
                        free,
                        result.cameras[c].num_params(),
                    ));
                } else if let Some((_, m)) = camera_sphere.filter(|(sc, _)| *sc == c) {
                    // [ρ, φ] = L [a, b, φ] with ρ = Rᵀ B [a, b].
                    let pose = &result.rig_from_camera[c];
                    let r = pose.rotation.to_rotation_matrix().into_inner();
                    let lift3 = r.transpose() * m.basis(&pose.translation.vector);
                    let mut lift = SMatrix::<f64, 6, 5>::zeros();
                    lift.fixed_view_mut::<3, 2>(0, 0).copy_from(&lift3);
                    lift.fixed_view_mut::<3, 3>(3, 2)
                        .copy_from(&nalgebra::Matrix3::identity());
                    let c5 = SMatrix::<f64, 5, 5>::from_iterator(cov.iter().copied());
                    result.extrinsic_covariance[c] = Some(lift * c5 * lift.transpose());
                } else {
                    result.extrinsic_covariance[c] =
                        Some(Matrix6::from_iterator(cov.iter().copied()));
                }
            }
        }
        Ok(result)
    }
}

/// The names of an extrinsic's tangent coordinates.
pub(crate) const EXTRINSIC_NAMES: [&str; 6] =
    ["rho_x", "rho_y", "rho_z", "phi_x", "phi_y", "phi_z"];

/// The names of the baseline camera's tangent coordinates (its translation on the sphere).
const SPHERE_EXTRINSIC_NAMES: [&str; 5] = ["baseline_a", "baseline_b", "phi_x", "phi_y", "phi_z"];

/// What [`analyse_camera_blocks`] finds: every coordinate's figures, and each block's
/// covariance (`None` when the information has a null direction).
pub(crate) type CameraBlockAnalysis = (Vec<ParameterObservability>, Vec<Option<DMatrix<f64>>>);

/// The camera parameter blocks of an analysis, camera by camera: its extrinsic (when
/// `extrinsic(c)` names its coordinates; `None` for a held one), then its free intrinsics.
pub(crate) fn camera_blocks<'a>(
    extrinsics: &[ParameterBlockId],
    intrinsics: &'a [IntrinsicsBlock],
    extrinsic: impl Fn(usize) -> Option<&'static [&'static str]>,
) -> Vec<CameraBlock<'a>> {
    let mut blocks = Vec::new();
    for (c, (&id, free)) in extrinsics.iter().zip(intrinsics).enumerate() {
        if let Some(names) = extrinsic(c) {
            blocks.push(CameraBlock {
                camera: c,
                id,
                intrinsics: None,
                names,
            });
        }
        if let Some((id, free)) = free {
            blocks.push(CameraBlock {
                camera: c,
                id: *id,
                intrinsics: Some(free),
                names: &[],
            });
        }
    }
    blocks
}

/// One camera parameter block of [`analyse_camera_blocks`].
pub(crate) struct CameraBlock<'a> {
    pub camera: usize,
    pub id: ParameterBlockId,
    /// The free parameters' indices (CamOdoCal order) of an intrinsics block; `None` for an
    /// extrinsic.
    pub intrinsics: Option<&'a [usize]>,
    /// The tangent coordinates' names of an extrinsic.
    pub names: &'static [&'static str],
}

/// The uncertainty and observability of every coordinate of `blocks` (free, not
/// eliminated; the others marginalized out, see the module documentation), and each block's
/// covariance (unit pixel noise), `None` when the information has a null direction.
pub(crate) fn analyse_camera_blocks(
    problem: &Problem,
    blocks: &[CameraBlock<'_>],
    cameras: &[Camera],
    solver: &SolverOptions,
) -> Result<CameraBlockAnalysis> {
    if blocks.is_empty() {
        return Ok((Vec::new(), Vec::new()));
    }
    let ids: Vec<ParameterBlockId> = blocks.iter().map(|b| b.id).collect();
    let information = marginal_information(problem, &ids, solver)?;
    let analysis = analyse(&information);
    let mut entries = Vec::new();
    let mut covariances = Vec::with_capacity(blocks.len());
    let mut offset = 0;
    for block in blocks {
        let n = problem.tangent_size(block.id)?;
        for k in 0..n {
            let (name, index) = match block.intrinsics {
                Some(free) => {
                    let p = free.get(k).copied().unwrap_or(k);
                    let name = cameras
                        .get(block.camera)
                        .and_then(|c| c.param_names().get(p).copied())
                        .unwrap_or("?");
                    (name, p)
                }
                None => (block.names.get(k).copied().unwrap_or("?"), k),
            };
            entries.push(ParameterObservability {
                camera: block.camera,
                name,
                intrinsic: block.intrinsics.is_some(),
                index,
                std_dev: analysis.std_dev[offset + k],
                observability: analysis.observability[offset + k],
            });
        }
        covariances.push(
            analysis
                .covariance
                .as_ref()
                .map(|cov| cov.view((offset, offset), (n, n)).into_owned()),
        );
        offset += n;
    }
    Ok((entries, covariances))
}

/// Covariance and per-parameter figures from a marginal information matrix.
struct Analysis {
    /// M⁻¹ when M has no null direction.
    covariance: Option<DMatrix<f64>>,
    std_dev: Vec<f64>,
    observability: Vec<f64>,
}

/// The module documentation's definitions, from the eigen-decomposition of D M D.
fn analyse(m: &DMatrix<f64>) -> Analysis {
    let n = m.nrows();
    let d: Vec<f64> = (0..n)
        .map(|i| {
            let v = m[(i, i)];
            if v > 0.0 { 1.0 / v.sqrt() } else { 0.0 }
        })
        .collect();
    let scaled = DMatrix::from_fn(n, n, |i, j| d[i] * m[(i, j)] * d[j]);
    let eigen = nalgebra::SymmetricEigen::new(scaled);
    let max = eigen.eigenvalues.iter().copied().fold(0.0, f64::max);
    let null: Vec<bool> = eigen
        .eigenvalues
        .iter()
        .map(|&l| l.is_nan() || l <= NULL_EIGENVALUE * max)
        .collect();
    let any_null = null.iter().any(|&z| z);
    // Pseudo-inverse of the scaled matrix over its non-null eigenvectors.
    let mut pinv = DMatrix::zeros(n, n);
    for (k, &l) in eigen.eigenvalues.iter().enumerate() {
        if null[k] {
            continue;
        }
        let v = eigen.eigenvectors.column(k);
        pinv += v * v.transpose() / l;
    }
    let mut std_dev = vec![f64::INFINITY; n];
    let mut observability = vec![0.0; n];
    for i in 0..n {
        if d[i] == 0.0 {
            continue;
        }
        let in_null: f64 = (0..n)
            .filter(|&k| null[k])
            .map(|k| eigen.eigenvectors[(i, k)].powi(2))
            .sum();
        if in_null > 1e-6 {
            continue;
        }
        observability[i] = (1.0 / pinv[(i, i)]).clamp(0.0, 1.0);
        std_dev[i] = pinv[(i, i)].sqrt() * d[i];
    }
    let covariance = (!any_null).then(|| DMatrix::from_fn(n, n, |i, j| d[i] * pinv[(i, j)] * d[j]));
    Analysis {
        covariance,
        std_dev,
        observability,
    }
}

/// The marginal information of `blocks` (free, not eliminated) at the current parameters:
/// the eliminated group removed by the Schur complement, then every other reduced block
/// marginalized out of the reduced information, M = S_cc − S_cf S_ff⁻¹ S_fc (Triggs et al.
/// 2000, section 6.1), in the blocks' tangent coordinates stacked in order.
fn marginal_information(
    problem: &Problem,
    blocks: &[ParameterBlockId],
    options: &SolverOptions,
) -> Result<DMatrix<f64>> {
    let program = Program::new(problem, options.automatic_elimination)?;
    let nf = program.n_f;
    let mut wanted = Vec::new();
    for &id in blocks {
        let block = problem.block(id)?;
        let col = program.block_col[id.index()];
        if col == NONE || (col as usize) < program.n_e {
            return Err(BundleAdjustError::CovarianceUnavailable { block: id.index() });
        }
        let start = col as usize - program.n_e;
        wanted.extend(start..start + block.tangent);
    }
    let exec = Executor::new(options.num_threads)?;
    let evaluator = Evaluator::new(problem, &program);
    let n = program.n_tangent();
    let mut res = vec![0.0; program.n_res_values];
    let mut jac = vec![0.0; program.n_jac_values];
    let mut g = vec![0.0; n];
    let mut norms = vec![0.0; n];
    evaluator
        .jacobian(
            &problem.values,
            &mut res,
            &mut jac,
            None,
            Accumulated {
                gradient: &mut g,
                column_norms: &mut norms,
            },
            &exec,
        )
        .map_err(|e| match e {
            EvalError::Failed(residual) => BundleAdjustError::InitialEvaluationFailed { residual },
            EvalError::NonFinite(residual) => BundleAdjustError::NonFiniteResidual { residual },
            EvalError::Shape(residual, position) => {
                BundleAdjustError::JacobianShapeMismatch { residual, position }
            }
        })?;
    let layout = ReducedLayout::new(&program, TargetKind::Dense)?;
    let mut schur = SchurComplement::new(&program, &layout, exec.threads());
    let zeros = vec![0.0; n];
    if !schur.eliminate(&program, &layout, &jac, &zeros, &zeros, &exec) {
        return Err(BundleAdjustError::SingularInformation);
    }
    let s = schur.target();
    let sym = |i: usize, j: usize| {
        if i >= j { s[i + j * nf] } else { s[j + i * nf] }
    };
    let mut is_wanted = vec![false; nf];
    for &w in &wanted {
        is_wanted[w] = true;
    }
    let rest: Vec<usize> = (0..nf).filter(|&i| !is_wanted[i]).collect();
    let (k, r) = (wanted.len(), rest.len());
    let mut m = DMatrix::from_fn(k, k, |i, j| sym(wanted[i], wanted[j]));
    if r > 0 {
        let mut s_ff = vec![0.0; r * r];
        for (j, &cj) in rest.iter().enumerate() {
            for (i, &ci) in rest.iter().enumerate().skip(j) {
                s_ff[i + j * r] = sym(ci, cj);
            }
        }
        let mut y = vec![0.0; r * k];
        for (j, &cj) in wanted.iter().enumerate() {
            for (i, &ci) in rest.iter().enumerate() {
                y[i + j * r] = sym(ci, cj);
            }
        }
        let s_fc = y.clone();
        let req = cholesky_in_place_scratch::<f64>(r, Par::Seq, Default::default())
            .or(solve_in_place_scratch::<f64>(r, k, Par::Seq));
        let mut scratch = MemBuffer::new(req);
        let mut a = MatMut::from_column_major_slice_mut(&mut s_ff, r, r);
        cholesky_in_place(
            a.as_mut(),
            LltRegularization::default(),
            Par::Seq,
            MemStack::new(&mut scratch),
            Default::default(),
        )
        .map_err(|_| BundleAdjustError::SingularInformation)?;
        let b = MatMut::from_column_major_slice_mut(&mut y, r, k);
        solve_in_place(a.as_ref(), b, Par::Seq, MemStack::new(&mut scratch));
        for j in 0..k {
            for i in 0..k {
                let dot: f64 = (0..r).map(|t| s_fc[t + i * r] * y[t + j * r]).sum();
                m[(i, j)] -= dot;
            }
        }
    }
    // Symmetrize against rounding.
    let mt = m.transpose();
    m = (m + mt) * 0.5;
    if m.iter().all(|v| v.is_finite()) {
        Ok(m)
    } else {
        Err(BundleAdjustError::SingularInformation)
    }
}
