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
//!
//! **Intrinsics** ([`RefinementOptions::intrinsics`]; InfrasCal, ECCV 2020, calibrates them
//! against a prior map; TrimBot2020 D3.1 §3.3.2 refines them with the extrinsics): the
//! selected parameters of every camera (shared by all its images) are refined with the
//! extrinsics and rig poses, the map still fixed. The data may not determine all of them (a
//! distortion term on a lens whose correspondences stay near the centre): every selected
//! parameter whose observability (see [`ibc_bundle_adjust::rig_bundle_adjustment`]) is
//! below [`RefinementOptions::min_observability`], or whose standard deviation is not
//! finite, is held at the camera file's value and listed in [`CameraIntrinsics::held`], and
//! the refinement runs again without it.

use ibc_bundle_adjust::rig::{
    RigObservation as BaObservation, RigRefinement, RigRefinementOptions, RigRefinementResult,
};
use ibc_bundle_adjust::{IntrinsicsSelection, RobustLoss, SolverOptions};
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

/// One refined intrinsic parameter.
#[derive(Clone, Debug, PartialEq)]
pub struct IntrinsicParameter {
    /// Its name in the model (CamOdoCal order: `mu`, `fx`, `u0`, `k1`, ...).
    pub name: &'static str,
    /// Its index in CamOdoCal order.
    pub index: usize,
    /// The camera file's value.
    pub prior: f64,
    /// The refined value.
    pub value: f64,
    /// Its standard deviation (scaled by the a-posteriori variance factor), NaN when the
    /// covariance could not be computed.
    pub std: f64,
    /// Its observability in [0, 1] (1 / variance-inflation factor).
    pub observability: f64,
}

/// A selected intrinsic parameter the data did not determine, held at the camera file's
/// value.
#[derive(Clone, Debug, PartialEq)]
pub struct HeldIntrinsic {
    /// Its name in the model.
    pub name: &'static str,
    /// Its index in CamOdoCal order.
    pub index: usize,
    /// Its observability when it was free (below the threshold, or 0 for a null direction).
    pub observability: f64,
}

/// What the refinement did with one camera's intrinsics.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CameraIntrinsics {
    /// The refined parameters (empty when none was selected or all were held).
    pub refined: Vec<IntrinsicParameter>,
    /// The selected parameters held because the data does not determine them.
    pub held: Vec<HeldIntrinsic>,
}

/// The refined estimate.
#[derive(Clone, Debug, PartialEq)]
pub struct Refinement {
    /// `rig_from_camera` per camera (camera 0 the identity).
    pub rig_from_camera: Vec<Isometry3<f64>>,
    /// `world_from_rig` per frame set.
    pub world_from_rig: Vec<Isometry3<f64>>,
    /// The cameras with their refined intrinsics (the given ones where none was refined).
    pub cameras: Vec<Camera>,
    /// Per camera, its refined and held intrinsics (see the module docs).
    pub intrinsics: Vec<CameraIntrinsics>,
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
/// `world_from_rig` (camera 0's extrinsic is taken as the identity), and the selected
/// intrinsics from `cameras`.
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
    let start = IntrinsicsStart {
        prior: cameras,
        start: cameras,
        held: &[],
        final_pass: true,
    };
    refine_from(
        &start,
        rig_from_camera,
        world_from_rig,
        observations,
        options,
    )
}

/// Where [`refine_from`] starts the intrinsics.
#[derive(Clone, Copy, Debug)]
pub(crate) struct IntrinsicsStart<'a> {
    /// The camera file's cameras: the prior of every intrinsic, the value of the held ones.
    pub prior: &'a [Camera],
    /// The cameras to start from (the free intrinsics of an earlier pass).
    pub start: &'a [Camera],
    /// Parameters already found undetermined: (camera, index, observability).
    pub held: &'a [(usize, usize, f64)],
    /// Whether this is the final pass: it holds the parameters it finds undetermined and
    /// refines again without them. A pass whose estimate only serves a next one lists them
    /// (in [`CameraIntrinsics::held`]) for the next one to hold.
    pub final_pass: bool,
}

/// [`refine`] from `intrinsics`' start.
pub(crate) fn refine_from(
    intrinsics: &IntrinsicsStart<'_>,
    rig_from_camera: &[Isometry3<f64>],
    world_from_rig: &[Isometry3<f64>],
    observations: &[RigObservation],
    options: &RefinementOptions,
) -> Result<Refinement, CalibrationError> {
    let prior = intrinsics.prior;
    if intrinsics.start.len() != prior.len() {
        return Err(CalibrationError::InvalidInput(format!(
            "{} start cameras for {} cameras",
            intrinsics.start.len(),
            prior.len()
        )));
    }
    // The start: the free intrinsics from `start`, the held ones at the prior.
    let cameras = at_prior(intrinsics.start, prior, intrinsics.held)?;
    let cameras = cameras.as_slice();
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
    let mut ba = RigRefinementOptions {
        loss: RobustLoss::Cauchy {
            scale: options.cauchy_scale_px,
        },
        reference_camera: 0,
        // A first pass with intrinsics computes it too: it finds the undetermined ones.
        covariance: intrinsics.final_pass || options.intrinsics != IntrinsicsSelection::None,
        intrinsics: options.intrinsics,
        solver: SolverOptions {
            max_iterations: options.max_iterations,
            num_threads: REFINEMENT_THREADS,
            ..Default::default()
        },
        ..Default::default()
    };
    ba.held_intrinsics = intrinsics.held.iter().map(|&(c, p, _)| (c, p)).collect();
    let mut result = problem.refine(&ba)?;
    // Hold what the data does not determine, and refine again without it, from where the
    // first solve ended.
    let mut undetermined: Vec<(usize, usize, f64)> = intrinsics.held.to_vec();
    let found: Vec<(usize, usize, f64)> = result
        .observability
        .iter()
        .filter(|o| {
            o.intrinsic && (o.observability < options.min_observability || !o.std_dev.is_finite())
        })
        .map(|o| (o.camera, o.index, o.observability))
        .collect();
    undetermined.extend(&found);
    if !found.is_empty() && intrinsics.final_pass {
        ba.held_intrinsics = undetermined.iter().map(|&(c, p, _)| (c, p)).collect();
        let warm = RigRefinement {
            cameras: at_prior(&result.cameras, prior, &undetermined)?,
            rig_from_camera: result.rig_from_camera.clone(),
            world_from_rig: result.world_from_rig.clone(),
            observations: problem.observations.clone(),
        };
        result = warm.refine(&ba)?;
    }
    let n_intrinsics: usize = (0..k)
        .map(|c| {
            options
                .intrinsics
                .indices(&cameras[c])
                .iter()
                .filter(|&&p| !ba.held_intrinsics.contains(&(c, p)))
                .count()
        })
        .sum();
    let residuals = 2 * problem.observations.len();
    let unknowns = 6 * (k - 1) + 6 * problem.world_from_rig.len() + n_intrinsics;
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
    let intrinsics = camera_intrinsics(prior, &result, &undetermined, factor);
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
        cameras: result.cameras,
        intrinsics,
        rig_from_camera_std,
        initial_cost: result.summary.initial_cost,
        final_cost: result.summary.final_cost,
        iterations: result.summary.iterations,
        termination: result.summary.termination.name().to_owned(),
        converged: result.summary.termination.is_converged(),
    })
}

/// `cameras` with the parameters `held` (camera, index, observability) set to `prior`'s
/// values.
fn at_prior(
    cameras: &[Camera],
    prior: &[Camera],
    held: &[(usize, usize, f64)],
) -> Result<Vec<Camera>, CalibrationError> {
    let mut out = cameras.to_vec();
    for &(c, index, _) in held {
        let (Some(camera), Some(&value)) = (
            out.get_mut(c),
            prior.get(c).and_then(|p| p.params().get(index)),
        ) else {
            continue;
        };
        let mut params = camera.params().to_vec();
        if let Some(v) = params.get_mut(index) {
            *v = value;
        }
        camera
            .set_params(&params)
            .map_err(|e| CalibrationError::InvalidInput(format!("camera {c}: {e}")))?;
    }
    Ok(out)
}

/// Per camera, its refined intrinsics (from `result`, standard deviations scaled by
/// `factor`) and the held ones (`undetermined`: camera, index, observability).
fn camera_intrinsics(
    prior: &[Camera],
    result: &RigRefinementResult,
    undetermined: &[(usize, usize, f64)],
    factor: Option<f64>,
) -> Vec<CameraIntrinsics> {
    let mut out = vec![CameraIntrinsics::default(); prior.len()];
    for o in result.observability.iter().filter(|o| o.intrinsic) {
        let (Some(entry), Some(before), Some(after)) = (
            out.get_mut(o.camera),
            prior.get(o.camera),
            result.cameras.get(o.camera),
        ) else {
            continue;
        };
        entry.refined.push(IntrinsicParameter {
            name: o.name,
            index: o.index,
            prior: before.params()[o.index],
            value: after.params()[o.index],
            std: factor.map_or(f64::NAN, |f| o.std_dev * f.sqrt()),
            observability: o.observability,
        });
    }
    for &(c, index, observability) in undetermined {
        if let (Some(entry), Some(camera)) = (out.get_mut(c), prior.get(c)) {
            entry.held.push(HeldIntrinsic {
                name: camera.param_names()[index],
                index,
                observability,
            });
        }
    }
    out
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
