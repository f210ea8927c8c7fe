//! Non-linear refinement of the extrinsics and the rig poses (the paper's section IV-D,
//! equation 4): `ibc_bundle_adjust::rig::RigRefinement`.
//!
//! Minimizes `sum rho(|pi_c(E_c^-1 P_s^-1 X_j) - u_scj|^2)` over the extrinsics
//! `E_c = rig_from_camera` and the rig poses `P_s = world_from_rig`, with the map points `X_j`
//! fixed, `pi_c` camera `c`'s model with its intrinsics fixed, and `rho` the Cauchy loss
//! `a^2 ln(1 + s / a^2)`. The rig poses are eliminated by the Schur complement. The gauge is
//! fixed as the paper fixes it: the rig frame is camera 0, `E_0 = I` is held constant.
//!
//! Observations that cannot be projected at the initial estimate are left out; a frame set
//! left without observations keeps its initial pose.
//!
//! The standard deviations of the extrinsics come from the covariance of the reduced system
//! at the solution (rig poses marginalized), scaled by the a-posteriori variance factor
//! `2 cost / (residuals - unknowns)`, and are expressed in the rig frame.

use ibc_bundle_adjust::rig::{
    RigObservation as BaObservation, RigRefinement, RigRefinementOptions,
};
use ibc_bundle_adjust::{RobustLoss, SolverOptions};
use ibc_camera_models::{Camera, CameraModel};
use nalgebra::{Isometry3, Matrix3, Matrix6, Point3, Vector2, Vector3};

use super::error::CalibrationError;
use super::options::RefinementOptions;

/// One observation of the refinement: map point `point` seen at `pixel` by camera `camera` in
/// frame set `set`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigObservation {
    /// Index of the frame set.
    pub set: u32,
    /// Index of the camera.
    pub camera: u32,
    /// The map point, world frame.
    pub point: Point3<f64>,
    /// The measured pixel.
    pub pixel: Vector2<f64>,
}

/// Standard deviations of a pose, in the frame the pose maps into (the rig frame for
/// `rig_from_camera`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseStd {
    /// Of the translation, per axis, metres.
    pub translation_m: Vector3<f64>,
    /// Of the rotation about each axis, radians.
    pub rotation_rad: Vector3<f64>,
}

impl PoseStd {
    /// Zero uncertainty (camera 0, which defines the rig frame).
    pub fn zero() -> Self {
        Self {
            translation_m: Vector3::zeros(),
            rotation_rad: Vector3::zeros(),
        }
    }
}

/// The refined estimate.
#[derive(Clone, Debug, PartialEq)]
pub struct Refinement {
    /// `rig_from_camera` per camera (camera 0 the identity).
    pub rig_from_camera: Vec<Isometry3<f64>>,
    /// `world_from_rig` per frame set.
    pub world_from_rig: Vec<Isometry3<f64>>,
    /// Standard deviations of each extrinsic (zero for camera 0), when the covariance could be
    /// computed.
    pub rig_from_camera_std: Option<Vec<PoseStd>>,
    /// Cost `1/2 sum rho` before and after.
    pub initial_cost: f64,
    /// See `initial_cost`.
    pub final_cost: f64,
    /// Levenberg-Marquardt iterations.
    pub iterations: usize,
    /// Why the solver stopped.
    pub termination: String,
    /// Whether it stopped on a convergence criterion (not on its iteration budget or a
    /// failure).
    pub converged: bool,
}

/// The reprojection residual (projected minus observed pixel) of an observation under the
/// given poses, `None` where the point cannot be projected.
pub fn reprojection_residual(
    camera: &Camera,
    rig_from_camera: &Isometry3<f64>,
    world_from_rig: &Isometry3<f64>,
    observation: &RigObservation,
) -> Option<Vector2<f64>> {
    let p_cam = (world_from_rig * rig_from_camera).inverse_transform_point(&observation.point);
    camera
        .project(&p_cam.coords)
        .ok()
        .map(|pixel| pixel - observation.pixel)
}

/// The reprojection residual of every observation under the given estimate, in parallel (NaN
/// where the point does not project).
pub fn reprojection_residuals(
    cameras: &[Camera],
    rig_from_camera: &[Isometry3<f64>],
    world_from_rig: &[Isometry3<f64>],
    observations: &[RigObservation],
) -> Vec<Vector2<f64>> {
    use rayon::prelude::*;
    observations
        .par_iter()
        .map(|o| {
            let c = o.camera as usize;
            reprojection_residual(
                &cameras[c],
                &rig_from_camera[c],
                &world_from_rig[o.set as usize],
                o,
            )
            .unwrap_or(Vector2::repeat(f64::NAN))
        })
        .collect()
}

/// The reprojection error (pixels) of an observation under the given poses, `None` where the
/// point cannot be projected.
pub fn reprojection_error(
    camera: &Camera,
    rig_from_camera: &Isometry3<f64>,
    world_from_rig: &Isometry3<f64>,
    observation: &RigObservation,
) -> Option<f64> {
    reprojection_residual(camera, rig_from_camera, world_from_rig, observation).map(|r| r.norm())
}

/// Worker threads of the solver. Fixed, so the result is the same on every machine (the
/// solver is deterministic for a fixed thread count).
pub const REFINEMENT_THREADS: usize = 2;

/// Refines the extrinsics and rig poses (see the module docs) from `rig_from_camera` and
/// `world_from_rig` (camera 0's extrinsic is taken as the identity).
///
/// # Errors
/// [`CalibrationError::InvalidInput`] when the extrinsics and cameras differ in number,
/// [`CalibrationError::CameraWithoutObservations`] for a camera without usable observations,
/// [`CalibrationError::Refinement`] if the problem cannot be built or solved.
pub fn refine(
    cameras: &[Camera],
    rig_from_camera: &[Isometry3<f64>],
    world_from_rig: &[Isometry3<f64>],
    observations: &[RigObservation],
    options: &RefinementOptions,
) -> Result<Refinement, CalibrationError> {
    let k = cameras.len();
    if rig_from_camera.len() != k || k == 0 {
        return Err(CalibrationError::InvalidInput(format!(
            "{} extrinsics for {k} cameras",
            rig_from_camera.len()
        )));
    }
    let mut start: Vec<Isometry3<f64>> = rig_from_camera.to_vec();
    start[0] = Isometry3::identity();
    // Frame sets with usable observations, renumbered.
    let mut index_of = vec![usize::MAX; world_from_rig.len()];
    let mut poses = Vec::new();
    let mut kept = Vec::with_capacity(observations.len());
    let mut used_cameras = vec![false; k];
    for o in observations {
        let (s, c) = (o.set as usize, o.camera as usize);
        let (Some(camera), Some(e), Some(p)) =
            (cameras.get(c), start.get(c), world_from_rig.get(s))
        else {
            continue;
        };
        if reprojection_error(camera, e, p, o).is_none_or(|err| !err.is_finite()) {
            continue;
        }
        if index_of[s] == usize::MAX {
            index_of[s] = poses.len();
            poses.push(*p);
        }
        used_cameras[c] = true;
        kept.push(BaObservation {
            frame: index_of[s],
            camera: c,
            world_point: o.point.coords,
            pixel: o.pixel,
        });
    }
    if let Some(camera) = used_cameras.iter().position(|u| !u) {
        return Err(CalibrationError::CameraWithoutObservations { camera });
    }
    let problem = RigRefinement {
        cameras: cameras.to_vec(),
        rig_from_camera: start,
        world_from_rig: poses,
        observations: kept,
    };
    let ba = RigRefinementOptions {
        loss: RobustLoss::Cauchy {
            scale: options.cauchy_scale_px,
        },
        reference_camera: 0,
        covariance: true,
        solver: SolverOptions {
            max_iterations: options.max_iterations,
            num_threads: REFINEMENT_THREADS,
            ..Default::default()
        },
        ..Default::default()
    };
    let result = problem.refine(&ba)?;
    let residuals = 2 * problem.observations.len();
    let unknowns = 6 * (k - 1) + 6 * problem.world_from_rig.len();
    let factor = (residuals > unknowns)
        .then(|| 2.0 * result.summary.final_cost / (residuals - unknowns) as f64);
    let rig_from_camera_std = factor.and_then(|factor| {
        (0..k)
            .map(|c| {
                if c == 0 {
                    return Some(PoseStd::zero());
                }
                let cov = result.extrinsic_covariance.get(c).copied().flatten()?;
                Some(rig_frame_std(&result.rig_from_camera[c], &cov, factor))
            })
            .collect::<Option<Vec<PoseStd>>>()
    });
    let refined_poses = world_from_rig
        .iter()
        .enumerate()
        .map(|(s, p)| {
            result
                .world_from_rig
                .get(index_of[s])
                .copied()
                .unwrap_or(*p)
        })
        .collect();
    Ok(Refinement {
        rig_from_camera: result.rig_from_camera,
        world_from_rig: refined_poses,
        rig_from_camera_std,
        initial_cost: result.summary.initial_cost,
        final_cost: result.summary.final_cost,
        iterations: result.summary.iterations,
        termination: result.summary.termination.name().to_owned(),
        converged: result.summary.termination.is_converged(),
    })
}

/// Standard deviations in the rig frame of a pose `E` whose right-tangent (`E Exp(delta)`,
/// `delta = [rho, phi]`) covariance is `factor * cov`: the translation moves by `R rho` and
/// the rotation by `R phi` about the rig axes.
fn rig_frame_std(pose: &Isometry3<f64>, cov: &Matrix6<f64>, factor: f64) -> PoseStd {
    let r = pose.rotation.to_rotation_matrix().into_inner();
    let sub = |o: usize| {
        let m: Matrix3<f64> = cov.fixed_view::<3, 3>(o, o).into_owned();
        let in_rig = r * m * r.transpose() * factor;
        Vector3::new(in_rig[(0, 0)], in_rig[(1, 1)], in_rig[(2, 2)]).map(|v| v.max(0.0).sqrt())
    };
    PoseStd {
        translation_m: sub(0),
        rotation_rad: sub(3),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ibc_camera_models::KannalaBrandt;

    fn fisheye() -> Camera {
        Camera::from(
            KannalaBrandt::new(
                1280,
                960,
                [-0.01, 0.002, 0.0, 0.0, 395.0, 395.0, 640.0, 480.0],
            )
            .unwrap(),
        )
    }

    #[test]
    fn recovers_extrinsics_from_exact_observations_and_a_perturbed_start() {
        let cameras = vec![fisheye(), fisheye(), fisheye()];
        let truth = [
            Isometry3::identity(),
            Isometry3::new(Vector3::new(0.1, -1.0, -0.5), Vector3::new(0.0, 1.5, 0.0)),
            Isometry3::new(Vector3::new(-0.2, 1.0, -0.4), Vector3::new(0.0, -1.6, 0.1)),
        ];
        let points: Vec<Point3<f64>> = (0..400)
            .map(|i| {
                let a = f64::from(i) * 0.37;
                Point3::new(8.0 * a.cos(), 2.0 * (a * 1.7).sin(), 8.0 * a.sin())
            })
            .collect();
        let poses: Vec<Isometry3<f64>> = (0..12)
            .map(|s| {
                let s = f64::from(s);
                Isometry3::new(
                    Vector3::new(0.3 * s, 0.05 * s, -0.2 * s),
                    Vector3::new(0.0, 0.1 * s, 0.02),
                )
            })
            .collect();
        let mut observations = Vec::new();
        for (s, pose) in poses.iter().enumerate() {
            for (c, e) in truth.iter().enumerate() {
                for p in &points {
                    let p_cam = (pose * e).inverse_transform_point(p);
                    if p_cam.z < 0.2 {
                        continue;
                    }
                    if let Ok(pixel) = cameras[c].project(&p_cam.coords) {
                        observations.push(RigObservation {
                            set: s as u32,
                            camera: c as u32,
                            point: *p,
                            pixel,
                        });
                    }
                }
            }
        }
        let nudge = Isometry3::new(
            Vector3::new(0.02, -0.01, 0.03),
            Vector3::new(0.01, -0.02, 0.01),
        );
        let start: Vec<Isometry3<f64>> = truth.iter().map(|e| e * nudge).collect();
        let start_poses: Vec<Isometry3<f64>> = poses.iter().map(|p| p * nudge).collect();
        let r = refine(
            &cameras,
            &start,
            &start_poses,
            &observations,
            &RefinementOptions::default(),
        )
        .unwrap();
        for (e, t) in r.rig_from_camera.iter().zip(&truth) {
            assert!(e.rotation.angle_to(&t.rotation) < 1e-8);
            assert!((e.translation.vector - t.translation.vector).norm() < 1e-8);
        }
        assert!(r.final_cost < 1e-12, "{}", r.final_cost);
        let std = r.rig_from_camera_std.unwrap();
        assert_eq!(std[0], PoseStd::zero());
    }
}
