//! The survey phase (Heng et al. §IV-A, "a standard structure-from-motion implementation can
//! be used to build a sparse feature map"): a calibrated rig drives through the area, and the
//! machinery of [`super::self_calibrate`] with the rig's extrinsics held (they also fix the
//! metric scale), or refined from them ([`MapOptions::refine_extrinsics`]), reconstructs the
//! points; the map holds every posed image with its keypoints,
//! descriptors and the points they observe, in the format `ibc calibrate` reads.
//!
//! The map's world frame is the rig frame (camera 0's) at the first frame the reconstruction
//! posed.

use ibc_camera_models::Rig;
use ibc_vocab_tree::Descriptor;
use nalgebra::{Isometry3, Matrix6};

use super::error::SelfCalibrationError;
use super::selfcalib::{OdometryDistances, Round, SelfCalibrationOptions, TrackStats, reconstruct};
use crate::NonExhaustive;
use crate::data::{Map, MapImage, PointId, RigLog};

/// How [`build_map`] treats the survey rig.
#[derive(Clone, Debug, PartialEq)]
pub struct MapOptions {
    /// The reconstruction's options (tracks, averaging, triangulation, adjustment rounds);
    /// their `scale` is not used: the rig's extrinsics give it. Default
    /// [`SelfCalibrationOptions::default`] with the tracks' verification sampling the matches
    /// progressively, best first (PROSAC, [`ibc_pnp::RelativePoseOptions::progressive`]): on
    /// the default survey drive the quarter of each pair's matches with the smallest
    /// descriptor distances held 99 % inliers where all held 48 %, and RANSAC's count (362
    /// samples a pair on average) was most of the time the command took; the maps built
    /// either way agree (BENCHMARKS.md). The self-calibration keeps uniform sampling: on the
    /// ten pinholes of the pentagon it gained no time. Also with the odometry's distances in
    /// the translation averaging ([`SelfCalibrationOptions::odometry_distances`]): on the
    /// survey drive they took the averaged trajectory's median error from 5.1 m to 1 cm. The
    /// held extrinsics also verify the pairs of two cameras of one frame by themselves
    /// ([`super::build_tracks_with_rig`]).
    pub reconstruction: SelfCalibrationOptions,
    /// Refine the rig's extrinsics with the map instead of holding them (default false: a
    /// rig just calibrated is trusted). Refined, they start from the camera file's and the
    /// scale is held by the reference camera's longest baseline as the file gives it; the
    /// map then carries no error of a camera that moved a little since its calibration, and
    /// [`BuiltMap::rig_from_camera`] says where each camera was found.
    pub refine_extrinsics: bool,
    /// Keeps the struct open to new fields: build it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for MapOptions {
    fn default() -> Self {
        let mut reconstruction = SelfCalibrationOptions::default();
        reconstruction.tracks.relative_pose.progressive = true;
        reconstruction.odometry_distances = Some(OdometryDistances::default());
        // Not for the survey: on the default drive it took `ibc map` from 27 s to 47 s wall
        // (78k points of 22 observations instead of 177k of 5.7; BENCHMARKS.md).
        reconstruction.track_completion = None;
        Self {
            reconstruction,
            refine_extrinsics: false,
            non_exhaustive: NonExhaustive(()),
        }
    }
}

/// A map built from a survey log ([`build_map`]).
#[derive(Clone, Debug, PartialEq)]
pub struct BuiltMap<D> {
    /// The map.
    pub map: Map<D>,
    /// `world_from_rig` at every frame of the survey log; `None` for a frame left out.
    pub world_from_rig: Vec<Option<Isometry3<f64>>>,
    /// For each map image, the survey frame and camera it comes from.
    pub image_sources: Vec<(usize, usize)>,
    /// Observations per point (mean).
    pub mean_observations_per_point: f64,
    /// RMS reprojection error of the last adjustment, pixels.
    pub rms_px: f64,
    /// The rounds of triangulation and adjustment.
    pub rounds: Vec<Round>,
    /// The feature tracking's counts.
    pub tracks: TrackStats,
    /// The extrinsics the map was built with (the rig frame is camera 0's): the rig's, or
    /// refined ([`MapOptions::refine_extrinsics`]).
    pub rig_from_camera: Vec<Isometry3<f64>>,
    /// With refined extrinsics, the covariance of each (`[rho, phi]`, right perturbation,
    /// metres and radians, for the log's own pixel noise as
    /// [`super::SelfCalibration::extrinsic_covariance`]; `None` for camera 0, the gauge); else
    /// all `None`.
    pub extrinsic_covariance: Vec<Option<Matrix6<f64>>>,
    /// With refined extrinsics, why they have no covariance
    /// ([`super::SelfCalibration::covariance_error`]); else `None`.
    pub covariance_error: Option<String>,
    /// How many of the odometry's distances between consecutive frames the translation
    /// averaging used (0 without odometry or with
    /// [`SelfCalibrationOptions::odometry_distances`] off): with any, they fixed the
    /// averaged trajectory's spacing and scale.
    pub odometry_distances: usize,
}

/// Builds a map from the survey `log` of the calibrated `rig` (its cameras in the log's order;
/// intrinsics used as they are, extrinsics held or refined as `options` say).
///
/// # Errors
/// As [`super::self_calibrate`].
pub fn build_map<D: Descriptor>(
    log: &RigLog<D>,
    rig: &Rig,
    options: &MapOptions,
) -> Result<BuiltMap<D>, SelfCalibrationError> {
    let cameras: Vec<_> = rig.cameras.iter().map(|c| c.camera.clone()).collect();
    let known: Vec<Isometry3<f64>> = rig.cameras.iter().map(|c| c.rig_from_camera).collect();
    let (result, observations) = reconstruct(
        log,
        &cameras,
        Some(&known),
        options.refine_extrinsics,
        &options.reconstruction,
    )?;
    let points = result.points.clone();
    let point_count = points.len();
    let mut images = Vec::new();
    let mut image_sources = Vec::new();
    let mut image_of = vec![vec![None; cameras.len()]; log.frames.len()];
    for (frame, (pose, f)) in result.world_from_rig.iter().zip(&log.frames).enumerate() {
        let Some(pose) = pose else { continue };
        for (camera, features) in f.images.iter().enumerate() {
            image_of[frame][camera] = Some(images.len());
            image_sources.push((frame, camera));
            images.push(MapImage {
                camera_from_world: Some((pose * result.rig_from_camera[camera]).inverse()),
                features: features.clone(),
                point_ids: vec![None; features.len()],
            });
        }
    }
    for o in &observations {
        let Some(image) = image_of
            .get(o.frame)
            .and_then(|f| f.get(o.camera))
            .copied()
            .flatten()
        else {
            continue;
        };
        let Ok(id) = PointId::try_from(o.point) else {
            continue;
        };
        if let Some(slot) = images[image].point_ids.get_mut(o.keypoint as usize) {
            *slot = Some(id);
        }
    }
    let last = result.rounds.last();
    Ok(BuiltMap {
        map: Map { points, images },
        world_from_rig: result.world_from_rig,
        image_sources,
        mean_observations_per_point: if point_count == 0 {
            0.0
        } else {
            observations.len() as f64 / point_count as f64
        },
        rms_px: last.map_or(f64::NAN, |r| r.rms_px),
        rounds: result.rounds,
        tracks: result.tracks,
        rig_from_camera: result.rig_from_camera,
        extrinsic_covariance: result.extrinsic_covariance,
        covariance_error: result.covariance_error,
        odometry_distances: result.odometry_distances,
    })
}
