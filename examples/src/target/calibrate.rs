//! A rig calibrated from target corners: every camera's intrinsics, then the extrinsics from
//! the views that cameras share, then one joint refinement of everything.
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
//! 3. **Joint refinement** ([`ibc_bundle_adjust::RigRefinement`] with every intrinsic free):
//!    the board is the world (its corners exact and fixed), one `board_from_rig` per time,
//!    one `rig_from_camera` per camera (the reference held), every camera's intrinsics;
//!    Cauchy loss of 1 px on the corners the intrinsic calibration kept as inliers. The
//!    covariances are scaled by the a-posteriori variance factor `sum r^2 / (m - n)`.
//!
//! A camera that never sees the board at the same time as a camera already linked to the
//! reference is not determined by one board and one time: [`TargetError::NotConnected`]
//! names it. (A rig whose cameras never share a view needs the rig's own motion between the
//! views, from odometry or from several boards standing still; neither is built yet.)

use std::collections::{BTreeMap, HashMap};

use ibc_bundle_adjust::{
    IntrinsicsSelection, RigObservation, RigRefinement, RigRefinementOptions, RobustLoss,
};
use ibc_camera_models::{Camera, CameraModel, Rig, RigCamera};
use ibc_rig_averaging::pose_mean;
use nalgebra::Isometry3;

use super::error::TargetError;
use crate::intrinsics::{
    CornerSet, IntrinsicCalibration, IntrinsicModel, IntrinsicsOptions, PlanarTarget,
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
}

impl Default for TargetCalibrationOptions {
    fn default() -> Self {
        Self {
            intrinsics: IntrinsicsOptions::default(),
            reference_camera: 0,
            loss: RobustLoss::Cauchy { scale: 1.0 },
        }
    }
}

/// How one camera is linked to the rig.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraLink {
    /// The camera it was chained from (`None` for the reference camera).
    pub parent: Option<usize>,
    /// Views the two cameras share.
    pub shared_views: usize,
}

/// The calibrated rig.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct TargetCalibration {
    /// Camera names, in input order.
    pub names: Vec<String>,
    /// Each camera's own intrinsic calibration (step 1).
    pub intrinsics: Vec<IntrinsicCalibration>,
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
    let intrinsics: Vec<IntrinsicCalibration> = cameras
        .iter()
        .map(|c| {
            calibrate_intrinsics(&c.corners, target, c.model, &options.intrinsics).map_err(|e| {
                TargetError::Camera {
                    camera: c.name.clone(),
                    reason: e.to_string(),
                }
            })
        })
        .collect::<Result<_, _>>()?;

    // Board poses by time (image name) for each camera.
    let poses: Vec<HashMap<&str, Isometry3<f64>>> = cameras
        .iter()
        .zip(&intrinsics)
        .map(|(c, cal)| {
            c.corners
                .images
                .iter()
                .zip(&cal.camera_from_board)
                .filter_map(|(image, pose)| pose.map(|p| (image.name.as_str(), p)))
                .collect()
        })
        .collect();
    let mut pair_views: BTreeMap<(usize, usize), Vec<Isometry3<f64>>> = BTreeMap::new();
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
                pair_views.insert((i, j), shared.into_iter().map(|(_, p)| p).collect());
            }
        }
    }
    let overlaps: Vec<(usize, usize, usize)> = pair_views
        .iter()
        .filter(|((i, j), _)| i < j)
        .map(|(&(i, j), v)| (i, j, v.len()))
        .collect();

    // A spanning tree from the reference camera, widest links first (Prim's algorithm on the
    // number of shared views).
    let mut rig_from_camera: Vec<Option<Isometry3<f64>>> = vec![None; n];
    let mut links = vec![
        CameraLink {
            parent: None,
            shared_views: 0
        };
        n
    ];
    rig_from_camera[reference] = Some(Isometry3::identity());
    loop {
        let best = pair_views
            .iter()
            .filter(|((i, j), _)| rig_from_camera[*i].is_some() && rig_from_camera[*j].is_none())
            .max_by_key(|((i, j), v)| (v.len(), std::cmp::Reverse((*i, *j))));
        let Some((&(i, j), views)) = best else {
            break;
        };
        let mean = pose_mean(views, None).map_err(|e| TargetError::Camera {
            camera: names[j].clone(),
            reason: format!("averaging its pose relative to `{}`: {e}", names[i]),
        })?;
        rig_from_camera[j] = rig_from_camera[i].map(|p| p * mean.mean);
        links[j] = CameraLink {
            parent: Some(i),
            shared_views: views.len(),
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

    // The joint refinement: one frame per time any camera saw the board.
    let mut times: BTreeMap<&str, Isometry3<f64>> = BTreeMap::new();
    for (c, camera_poses) in poses.iter().enumerate() {
        for (time, camera_from_board) in camera_poses {
            times
                .entry(time)
                .or_insert_with(|| (initial_rig_from_camera[c] * camera_from_board).inverse());
        }
    }
    let frame_of: HashMap<&str, usize> = times.keys().enumerate().map(|(k, t)| (*t, k)).collect();
    let mut observations = Vec::new();
    for (c, (camera, cal)) in cameras.iter().zip(&intrinsics).enumerate() {
        for ((image, pose), inliers) in camera
            .corners
            .images
            .iter()
            .zip(&cal.camera_from_board)
            .zip(&cal.inliers)
        {
            if pose.is_none() {
                continue;
            }
            let frame = frame_of[image.name.as_str()];
            for (corner, inlier) in image.corners.iter().zip(inliers) {
                if *inlier {
                    observations.push(RigObservation {
                        frame,
                        camera: c,
                        world_point: target.point(corner.row, corner.col).coords,
                        pixel: corner.pixel(),
                    });
                }
            }
        }
    }
    let problem = RigRefinement {
        cameras: intrinsics.iter().map(|c| c.camera.clone()).collect(),
        rig_from_camera: initial_rig_from_camera.clone(),
        world_from_rig: times.values().copied().collect(),
        observations,
    };
    let result = problem
        .refine(&RigRefinementOptions {
            loss: options.loss,
            reference_camera: reference,
            covariance: true,
            intrinsics: IntrinsicsSelection::All,
            ..Default::default()
        })
        .map_err(|e| TargetError::Refinement(e.to_string()))?;

    let m = 2 * problem.observations.len();
    let params = 6 * problem.world_from_rig.len()
        + 6 * (n - 1)
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
    for o in &problem.observations {
        let camera = &result.cameras[o.camera];
        let camera_from_world =
            (result.world_from_rig[o.frame] * result.rig_from_camera[o.camera]).inverse();
        if let Ok(px) =
            camera.project(&(camera_from_world * nalgebra::Point3::from(o.world_point)).coords)
        {
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
