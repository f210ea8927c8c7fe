//! A rig calibrated from target corners: every camera's intrinsics, then the extrinsics from
//! the views that cameras share (or from the rig's motion), then one joint refinement of
//! everything.
//!
//! References: K. Daniilidis, "Hand-eye calibration using dual quaternions", IJRR 1999 (the
//! link between cameras that never share a view); P. Lébraly, E. Royer, O. Ait-Aider, M.
//! Dhome, "Calibration of non-overlapping cameras — application to vision-based robotics",
//! BMVC 2010 (each camera sees its own target standing still while the rig moves; hand-eye,
//! then one bundle adjustment with the targets' poses unknown); P. Furgale, J. Rehder, R.
//! Siegwart, "Unified temporal and spatial calibration for multi-sensor systems" (Kalibr),
//! IROS 2013 (the AprilGrid and the camchain).
//!
//! # Method
//! 1. **Intrinsics**, camera by camera, from its own corners
//!    ([`crate::intrinsics::calibrate_intrinsics`]: Heng et al.'s vanishing-point start for
//!    Kannala-Brandt, Zhang's for pinhole-radtan, a robust refinement with every board pose).
//! 2. **Extrinsics from shared views**: where cameras `i` and `j` both see the board at the
//!    same time (images with the same name), `camera_i_from_camera_j =
//!    camera_i_from_board * (camera_j_from_board)^-1`; the views of a pair are averaged
//!    ([`ibc_rig_averaging::pose_mean`]: Markley's quaternion mean, the mean translation), and
//!    a spanning tree from the reference camera over the pairs with the most shared views
//!    chains them into `rig_from_camera` (the reference camera's frame is the rig's).
//!    A pair whose relative pose wanders over their shared times (by more than
//!    [`SAME_BOARD_DEG`] or [`SAME_BOARD_M`]) saw two boards while the rig moved: such cameras
//!    are linked by a **hand-eye calibration** between their motions (Daniilidis, refined) when
//!    no shared view links them, each camera's board standing still; cameras linked by shared
//!    views share a board.
//! 3. **Joint refinement** ([`ibc_bundle_adjust::RigRefinement`] with every intrinsic free):
//!    the reference camera's board is the world (its corners exact and fixed), the other
//!    boards targets of unknown pose ([`RigRefinement::refine_with_targets`]), one
//!    `world_from_rig` per time, one `rig_from_camera` per camera (the reference held), every
//!    camera's intrinsics;
//!    Cauchy loss of 1 px on the corners the intrinsic calibration kept as inliers. The
//!    covariances are scaled by the a-posteriori variance factor `sum r^2 / (m - n)`.
//!
//! A camera with no time in common with a camera linked to the reference is not determined:
//! [`TargetError::NotConnected`] names it. One board carried around a rig standing still
//! cannot link cameras that never see it at the same time (each time's board pose is a new
//! unknown); the rig must move in front of boards standing still instead. Rotations about at
//! least two axes are needed (a car driving on a plane leaves the cameras' heights free).

use std::collections::{BTreeMap, HashMap};

use ibc_bundle_adjust::{
    IntrinsicsSelection, RigObservation, RigRefinement, RigRefinementOptions, RobustLoss,
};
use ibc_camera_models::{Camera, CameraModel, Rig, RigCamera};
use ibc_hand_eye::{DaniilidisOptions, MotionPair, RefineOptions, daniilidis};
use ibc_rig_averaging::pose_mean;
use nalgebra::Isometry3;

use super::error::TargetError;
use crate::intrinsics::{
    CornerSet, IntrinsicCalibration, IntrinsicModel, IntrinsicsOptions, MAX_RMS_PX, PlanarTarget,
    calibrate_intrinsics,
};

/// One camera's corners, named.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraCorners {
    /// The camera's name (its image folder).
    pub name: String,
    /// The model to calibrate.
    pub model: IntrinsicModel,
    /// Its corners, image by image; images of different cameras with the same name were taken
    /// at the same time.
    pub corners: CornerSet,
}

/// Options of [`calibrate_rig_from_target`].
#[derive(Clone, Debug)]
pub struct TargetCalibrationOptions {
    /// Options of each camera's intrinsic calibration.
    pub intrinsics: IntrinsicsOptions,
    /// The camera whose frame is the rig's (default 0).
    pub reference_camera: usize,
    /// Robust loss of the joint refinement (default Cauchy, 1 px).
    pub loss: RobustLoss,
    /// Images with fewer corners are left out (default 24, six tags: a board mostly outside
    /// the image gives a poor start to the closed-form initializations).
    pub min_corners_per_image: usize,
}

impl Default for TargetCalibrationOptions {
    fn default() -> Self {
        Self {
            intrinsics: IntrinsicsOptions::default(),
            reference_camera: 0,
            loss: RobustLoss::Cauchy { scale: 1.0 },
            min_corners_per_image: 24,
        }
    }
}

/// How one camera is linked to the rig.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraLink {
    /// The camera it was chained from (`None` for the reference camera).
    pub parent: Option<usize>,
    /// Times both cameras saw a board (the same board, or with `hand_eye` each its own).
    pub shared_views: usize,
    /// Whether the link is a hand-eye calibration between the two cameras' motions (they
    /// never saw the same board at the same time).
    pub hand_eye: bool,
}

/// The calibrated rig.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct TargetCalibration {
    /// Camera names, in input order.
    pub names: Vec<String>,
    /// Each camera's own intrinsic calibration (step 1).
    pub intrinsics: Vec<IntrinsicCalibration>,
    /// The corners each intrinsic calibration was given (the images with at least
    /// [`TargetCalibrationOptions::min_corners_per_image`] corners), in its image order.
    pub used_corners: Vec<CornerSet>,
    /// The cameras after the joint refinement.
    pub cameras: Vec<Camera>,
    /// `rig_from_camera` of each camera after the joint refinement (the reference camera's is
    /// the identity).
    pub rig_from_camera: Vec<Isometry3<f64>>,
    /// `rig_from_camera` from the shared views alone (step 2).
    pub initial_rig_from_camera: Vec<Isometry3<f64>>,
    /// Standard deviation of each extrinsic, `(rotation degrees, translation metres)`, the
    /// largest over the axes; `None` for the reference camera.
    pub extrinsic_std: Vec<Option<(f64, f64)>>,
    /// Standard deviation of each camera's parameters after the joint refinement (CamOdoCal
    /// order), `None` where the covariance is undefined.
    pub intrinsic_std: Vec<Option<Vec<f64>>>,
    /// How each camera was linked.
    pub links: Vec<CameraLink>,
    /// Views shared by each pair of cameras `(i, j, count)`, `i < j`, count > 0.
    pub overlaps: Vec<(usize, usize, usize)>,
    /// The joint refinement's RMS per coordinate, pixels, per camera.
    pub rms_px: Vec<f64>,
    /// Its a-posteriori noise estimate, pixels.
    pub noise_sigma_px: f64,
    /// Board poses (times) in the joint refinement.
    pub times: usize,
    /// Corners in the joint refinement.
    pub observations: usize,
    /// Whether the joint refinement converged.
    pub converged: bool,
}

impl TargetCalibration {
    /// Why the calibration should not be trusted, camera by camera: the quality gates of each
    /// camera's intrinsic calibration ([`crate::intrinsics::IntrinsicsWarning`]), a camera whose
    /// joint RMS exceeds [`MAX_RMS_PX`], an implausible calibrated camera
    /// ([`ibc_camera_models::Camera::check_plausible`]), an extrinsic whose standard deviation
    /// exceeds [`MAX_EXTRINSIC_STD_DEG`] or [`MAX_EXTRINSIC_STD_M`], or a joint refinement that
    /// did not converge. Empty for a calibration to use.
    pub fn warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        for (name, cal) in self.names.iter().zip(&self.intrinsics) {
            for w in &cal.warnings {
                out.push(format!("`{name}`: {w}"));
            }
        }
        for (name, rms) in self.names.iter().zip(&self.rms_px) {
            if !(rms.is_finite() && *rms <= MAX_RMS_PX) {
                out.push(format!(
                    "`{name}`: RMS {rms:.3} px after the joint refinement, above {MAX_RMS_PX} px"
                ));
            }
        }
        for (c, name) in self.names.iter().enumerate() {
            if let Err(e) = self.cameras[c].check_plausible() {
                out.push(format!(
                    "`{name}`: the calibrated camera is implausible: {e}"
                ));
            }
            if let Some((rotation_deg, translation_m)) = self.extrinsic_std[c]
                && !(rotation_deg <= MAX_EXTRINSIC_STD_DEG && translation_m <= MAX_EXTRINSIC_STD_M)
            {
                out.push(format!(
                    "`{name}`: the extrinsic is not determined (standard deviation \
                     {rotation_deg:.3} deg / {:.2} mm, above {MAX_EXTRINSIC_STD_DEG} deg / {} mm): \
                     more views shared with `{}`, or more rotation of the rig",
                    translation_m * 1e3,
                    MAX_EXTRINSIC_STD_M * 1e3,
                    self.links[c]
                        .parent
                        .map_or("the others", |p| self.names[p].as_str()),
                ));
            }
        }
        if !self.converged {
            out.push("the joint refinement did not converge".into());
        }
        out
    }

    /// The calibrated rig, with Kalibr's `rostopic` (`/NAME/image_raw`) and `cam_overlaps`
    /// (cameras that shared a view).
    pub fn to_rig(&self) -> Rig {
        let cameras = (0..self.names.len())
            .map(|i| {
                let mut c = RigCamera::new(
                    self.names[i].clone(),
                    self.cameras[i].clone(),
                    self.rig_from_camera[i],
                );
                c.topic = Some(format!("/{}/image_raw", self.names[i]));
                c.overlaps = self
                    .overlaps
                    .iter()
                    .filter_map(|&(a, b, _)| match (a == i, b == i) {
                        (true, _) => Some(b),
                        (_, true) => Some(a),
                        _ => None,
                    })
                    .collect();
                c
            })
            .collect();
        Rig::new(cameras)
    }
}

/// Calibrates every camera's intrinsics and the rig's extrinsics from target corners (see the
/// module docs).
///
/// # Errors
/// [`TargetError::InvalidInput`] for no cameras, a reference camera out of range or duplicate
/// names; [`TargetError::Camera`] with the camera's name for its intrinsic calibration's
/// errors; [`TargetError::NotConnected`] for a camera that shares no view with the others;
/// [`TargetError::Refinement`] if the joint refinement fails.
pub fn calibrate_rig_from_target(
    cameras: &[CameraCorners],
    target: &PlanarTarget,
    options: &TargetCalibrationOptions,
) -> Result<TargetCalibration, TargetError> {
    let n = cameras.len();
    if n == 0 {
        return Err(TargetError::InvalidInput("no cameras".into()));
    }
    let reference = options.reference_camera;
    if reference >= n {
        return Err(TargetError::InvalidInput(format!(
            "reference camera {reference} of {n}"
        )));
    }
    let names: Vec<String> = cameras.iter().map(|c| c.name.clone()).collect();
    for (i, name) in names.iter().enumerate() {
        if names[..i].contains(name) {
            return Err(TargetError::InvalidInput(format!(
                "two cameras are named `{name}`"
            )));
        }
    }
    // Images with a few corners (a board mostly out of view) make poor homographies for the
    // closed-form starts; they are left out of the whole calibration.
    let kept: Vec<CornerSet> = cameras
        .iter()
        .map(|c| {
            let mut corners = c.corners.clone();
            corners
                .images
                .retain(|i| i.corners.len() >= options.min_corners_per_image);
            corners
        })
        .collect();
    let intrinsics: Vec<IntrinsicCalibration> = cameras
        .iter()
        .zip(&kept)
        .map(|(c, corners)| {
            calibrate_intrinsics(corners, target, c.model, &options.intrinsics).map_err(|e| {
                TargetError::Camera {
                    camera: c.name.clone(),
                    reason: e.to_string(),
                }
            })
        })
        .collect::<Result<_, _>>()?;

    // Board poses by time (image name) for each camera.
    let poses: Vec<HashMap<&str, Isometry3<f64>>> = kept
        .iter()
        .zip(&intrinsics)
        .map(|(corners, cal)| {
            corners
                .images
                .iter()
                .zip(&cal.camera_from_board)
                .filter_map(|(image, pose)| pose.map(|p| (image.name.as_str(), p)))
                .collect()
        })
        .collect();
    // Relative poses of every pair of cameras at the times both saw a board.
    let mut pair_views: BTreeMap<(usize, usize), TimedPoses<'_>> = BTreeMap::new();
    for i in 0..n {
        for j in 0..n {
            if i == j {
                continue;
            }
            let mut shared: Vec<(&str, Isometry3<f64>)> = poses[i]
                .iter()
                .filter_map(|(time, pi)| poses[j].get(time).map(|pj| (*time, pi * pj.inverse())))
                .collect();
            shared.sort_by(|a, b| a.0.cmp(b.0));
            if !shared.is_empty() {
                pair_views.insert((i, j), shared);
            }
        }
    }
    // A pair whose relative pose stays put saw one board; one whose relative pose wanders saw
    // two boards while the rig moved.
    let same_board = |views: &[(&str, Isometry3<f64>)]| -> Option<Isometry3<f64>> {
        let relative: Vec<Isometry3<f64>> = views.iter().map(|v| v.1).collect();
        let mean = pose_mean(&relative, None).ok()?.mean;
        let steady = relative.iter().all(|r| {
            let d = mean.inverse() * r;
            d.rotation.angle().to_degrees() < SAME_BOARD_DEG
                && d.translation.vector.norm() < SAME_BOARD_M
        });
        steady.then_some(mean)
    };
    let shared_board: BTreeMap<(usize, usize), Isometry3<f64>> = pair_views
        .iter()
        .filter_map(|(&pair, views)| same_board(views).map(|mean| (pair, mean)))
        .collect();
    let overlaps: Vec<(usize, usize, usize)> = pair_views
        .iter()
        .filter(|((i, j), _)| i < j && shared_board.contains_key(&(*i, *j)))
        .map(|(&(i, j), v)| (i, j, v.len()))
        .collect();

    // A spanning tree from the reference camera (Prim's algorithm): shared views first, the
    // widest link first; a camera that shares no view is linked by hand-eye calibration
    // between the two cameras' motions (each seeing its own board standing still).
    let mut rig_from_camera: Vec<Option<Isometry3<f64>>> = vec![None; n];
    let mut links = vec![
        CameraLink {
            parent: None,
            shared_views: 0,
            hand_eye: false,
        };
        n
    ];
    // The board each camera sees: cameras linked by shared views share a board.
    let mut board_of: Vec<usize> = (0..n).collect();
    rig_from_camera[reference] = Some(Isometry3::identity());
    loop {
        let open = |(i, j): &(usize, usize)| {
            rig_from_camera[*i].is_some() && rig_from_camera[*j].is_none()
        };
        let shared = shared_board
            .iter()
            .filter(|(pair, _)| open(pair))
            .max_by_key(|&(&(i, j), _)| (pair_views[&(i, j)].len(), std::cmp::Reverse((i, j))));
        if let Some((&(i, j), mean)) = shared {
            rig_from_camera[j] = rig_from_camera[i].map(|p| p * mean);
            links[j] = CameraLink {
                parent: Some(i),
                shared_views: pair_views[&(i, j)].len(),
                hand_eye: false,
            };
            board_of[j] = board_of[i];
            continue;
        }
        let moving = pair_views
            .iter()
            .filter(|(pair, views)| open(pair) && views.len() >= MIN_HAND_EYE_TIMES)
            .max_by_key(|&(&(i, j), v)| (v.len(), std::cmp::Reverse((i, j))));
        let Some((&(i, j), views)) = moving else {
            break;
        };
        let x =
            hand_eye_link(views, &poses[i], &poses[j]).map_err(|reason| TargetError::Camera {
                camera: names[j].clone(),
                reason: format!(
                    "it shares no view with `{}`, and the hand-eye calibration between their \
                     motions failed: {reason}",
                    names[i]
                ),
            })?;
        rig_from_camera[j] = rig_from_camera[i].map(|p| p * x);
        links[j] = CameraLink {
            parent: Some(i),
            shared_views: views.len(),
            hand_eye: true,
        };
    }
    if let Some(missing) = rig_from_camera.iter().position(Option::is_none) {
        return Err(TargetError::NotConnected {
            camera: names[missing].clone(),
            reference: names[reference].clone(),
        });
    }
    let initial_rig_from_camera: Vec<Isometry3<f64>> = rig_from_camera
        .iter()
        .map(|p| p.unwrap_or_default())
        .collect();

    // Boards: the reference camera's is the world; the others are free targets standing
    // still, placed from the times when a camera on a placed board saw the rig.
    let mut boards: Vec<usize> = board_of.clone();
    boards.sort_unstable();
    boards.dedup();
    let world_board = board_of[reference];
    let mut world_from_board: BTreeMap<usize, Isometry3<f64>> =
        BTreeMap::from([(world_board, Isometry3::identity())]);
    let mut all_times: Vec<&str> = poses.iter().flat_map(|p| p.keys().copied()).collect();
    all_times.sort_unstable();
    all_times.dedup();
    // world_from_rig at a time, from any camera whose board is placed.
    let rig_pose = |time: &str, placed: &BTreeMap<usize, Isometry3<f64>>| {
        (0..n).find_map(|c| {
            let board = placed.get(&board_of[c])?;
            let camera_from_board = poses[c].get(time)?;
            Some(board * camera_from_board.inverse() * initial_rig_from_camera[c].inverse())
        })
    };
    while world_from_board.len() < boards.len() {
        let before = world_from_board.len();
        for &b in &boards {
            if world_from_board.contains_key(&b) {
                continue;
            }
            let estimates: Vec<Isometry3<f64>> = all_times
                .iter()
                .filter_map(|time| {
                    let world_from_rig = rig_pose(time, &world_from_board)?;
                    let c = (0..n).find(|&c| board_of[c] == b && poses[c].contains_key(time))?;
                    Some(world_from_rig * initial_rig_from_camera[c] * poses[c][time])
                })
                .collect();
            if let Ok(mean) = pose_mean(&estimates, None) {
                world_from_board.insert(b, mean.mean);
            }
        }
        if world_from_board.len() == before {
            break;
        }
    }
    let free_boards: Vec<usize> = boards
        .iter()
        .copied()
        .filter(|&b| b != world_board)
        .collect();
    let target_of_board: HashMap<usize, usize> = free_boards
        .iter()
        .enumerate()
        .map(|(k, &b)| (b, k))
        .collect();
    let world_from_target: Vec<Isometry3<f64>> = free_boards
        .iter()
        .map(|b| world_from_board.get(b).copied().unwrap_or_default())
        .collect();

    // The joint refinement: one frame per time any camera saw a board.
    let times: Vec<(&str, Isometry3<f64>)> = all_times
        .iter()
        .filter_map(|t| rig_pose(t, &world_from_board).map(|p| (*t, p)))
        .collect();
    let frame_of: HashMap<&str, usize> = times.iter().enumerate().map(|(k, t)| (t.0, k)).collect();
    let mut observations = Vec::new();
    let mut observation_targets = Vec::new();
    for (c, (corners, cal)) in kept.iter().zip(&intrinsics).enumerate() {
        for ((image, pose), inliers) in corners
            .images
            .iter()
            .zip(&cal.camera_from_board)
            .zip(&cal.inliers)
        {
            let (Some(_), Some(&frame)) = (pose, frame_of.get(image.name.as_str())) else {
                continue;
            };
            for (corner, inlier) in image.corners.iter().zip(inliers) {
                if *inlier {
                    observations.push(RigObservation {
                        frame,
                        camera: c,
                        world_point: target.point(corner.row, corner.col).coords,
                        pixel: corner.pixel(),
                    });
                    observation_targets.push(target_of_board.get(&board_of[c]).copied());
                }
            }
        }
    }
    let problem = RigRefinement {
        cameras: intrinsics.iter().map(|c| c.camera.clone()).collect(),
        rig_from_camera: initial_rig_from_camera.clone(),
        world_from_rig: times.iter().map(|t| t.1).collect(),
        observations,
    };
    let result = problem
        .refine_with_targets(
            &world_from_target,
            &observation_targets,
            &RigRefinementOptions {
                loss: options.loss,
                reference_camera: reference,
                covariance: true,
                intrinsics: IntrinsicsSelection::All,
                ..Default::default()
            },
        )
        .map_err(|e| TargetError::Refinement(e.to_string()))?;

    let m = 2 * problem.observations.len();
    let params = 6 * problem.world_from_rig.len()
        + 6 * (n - 1)
        + 6 * world_from_target.len()
        + problem
            .cameras
            .iter()
            .map(|c| c.params().len())
            .sum::<usize>();
    let variance = if m > params {
        result.final_rms.powi(2) * m as f64 / (m - params) as f64
    } else {
        f64::NAN
    };
    let extrinsic_std = result
        .extrinsic_covariance
        .iter()
        .map(|cov| {
            cov.map(|c| {
                let c = c * variance;
                let t = (0..3).map(|k| c[(k, k)]).fold(0.0, f64::max).sqrt();
                let r = (3..6).map(|k| c[(k, k)]).fold(0.0, f64::max).sqrt();
                (r.to_degrees(), t)
            })
        })
        .collect();
    let intrinsic_std = result
        .intrinsic_covariance
        .iter()
        .map(|cov| {
            cov.as_ref().map(|c| {
                (0..c.nrows())
                    .map(|k| (c[(k, k)] * variance).sqrt())
                    .collect()
            })
        })
        .collect();
    let mut sums = vec![(0.0, 0usize); n];
    for (o, target) in problem.observations.iter().zip(&observation_targets) {
        let camera = &result.cameras[o.camera];
        let camera_from_world =
            (result.world_from_rig[o.frame] * result.rig_from_camera[o.camera]).inverse();
        let on_board = nalgebra::Point3::from(o.world_point);
        let world_point = match target.and_then(|t| result.world_from_target.get(t)) {
            Some(world_from_target) => world_from_target * on_board,
            None => on_board,
        };
        if let Ok(px) = camera.project(&(camera_from_world * world_point).coords) {
            sums[o.camera].0 += (px - o.pixel).norm_squared();
            sums[o.camera].1 += 2;
        }
    }
    let rms_px = sums
        .iter()
        .map(|&(s, k)| {
            if k > 0 {
                (s / k as f64).sqrt()
            } else {
                f64::NAN
            }
        })
        .collect();
    Ok(TargetCalibration {
        names,
        intrinsics,
        used_corners: kept,
        cameras: result.cameras.clone(),
        rig_from_camera: result.rig_from_camera.clone(),
        initial_rig_from_camera,
        extrinsic_std,
        intrinsic_std,
        links,
        overlaps,
        rms_px,
        noise_sigma_px: variance.sqrt(),
        times: problem.world_from_rig.len(),
        observations: problem.observations.len(),
        converged: result.summary.termination.is_converged(),
    })
}

/// Relative poses of two cameras at the times (image names) both saw a board.
type TimedPoses<'a> = Vec<(&'a str, Isometry3<f64>)>;

/// Two cameras saw the same board when their relative pose stays within this angle of its
/// mean over their shared times, degrees (single-image poses scatter by hundredths of a
/// degree; a rig turning in front of two boards changes it by tens).
pub const SAME_BOARD_DEG: f64 = 1.0;
/// ... and within this distance, metres.
pub const SAME_BOARD_M: f64 = 0.02;
/// An extrinsic whose rotation standard deviation exceeds this (degrees) is reported as not
/// determined by the views (a good target calibration reaches a few thousandths).
pub const MAX_EXTRINSIC_STD_DEG: f64 = 0.1;
/// ... or whose translation standard deviation exceeds this, metres.
pub const MAX_EXTRINSIC_STD_M: f64 = 0.002;
/// Fewest common times for a hand-eye link.
pub const MIN_HAND_EYE_TIMES: usize = 3;

/// `camera_i_from_camera_j` from the two cameras' motions at their common times `views`
/// (Daniilidis' hand-eye calibration on every pair of times, then refined): camera `i` moves
/// by `A = P_i(a) P_i(b)^-1` while camera `j` moves by `B = P_j(a) P_j(b)^-1`, with `P` the
/// `camera_from_board` of each camera's own board, and `A X = X B`.
fn hand_eye_link(
    views: &[(&str, Isometry3<f64>)],
    poses_i: &HashMap<&str, Isometry3<f64>>,
    poses_j: &HashMap<&str, Isometry3<f64>>,
) -> Result<Isometry3<f64>, String> {
    let times: Vec<&str> = views.iter().map(|v| v.0).collect();
    let mut pairs = Vec::new();
    for (k, a) in times.iter().enumerate() {
        for b in &times[k + 1..] {
            let (ia, ib, ja, jb) = (poses_i[a], poses_i[b], poses_j[a], poses_j[b]);
            let (motion_i, motion_j) = (ia * ib.inverse(), ja * jb.inverse());
            pairs.push(MotionPair::new(motion_i, motion_j));
        }
    }
    let options = DaniilidisOptions {
        refine: Some(RefineOptions::default()),
        ..Default::default()
    };
    daniilidis(&pairs, &options)
        .map(|s| s.a_from_b)
        .map_err(|e| e.to_string())
}
