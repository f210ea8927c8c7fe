//! The survey phase (Heng et al. §IV-A, "a standard structure-from-motion implementation can
//! be used to build a sparse feature map"): a calibrated rig drives through the area, and the
//! machinery of [`super::self_calibrate`] with the rig's extrinsics held (they also fix the
//! metric scale) reconstructs the points; the map holds every posed image with its keypoints,
//! descriptors and the points they observe, in the format `ibc calibrate` reads.
//!
//! The map's world frame is the rig frame (camera 0's) at the first frame the reconstruction
//! posed.

use ibc_camera_models::Rig;
use ibc_vocab_tree::Descriptor;
use nalgebra::Isometry3;

use super::error::SelfCalibrationError;
use super::selfcalib::{Round, SelfCalibrationOptions, TrackStats, reconstruct};
use crate::data::{Map, MapImage, PointId, RigLog};

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
}

/// Builds a map from the survey `log` of the calibrated `rig` (its cameras in the log's order;
/// intrinsics and extrinsics used as they are).
///
/// # Errors
/// As [`super::self_calibrate`].
pub fn build_map<D: Descriptor>(
    log: &RigLog<D>,
    rig: &Rig,
    options: &SelfCalibrationOptions,
) -> Result<BuiltMap<D>, SelfCalibrationError> {
    let cameras: Vec<_> = rig.cameras.iter().map(|c| c.camera.clone()).collect();
    let known: Vec<Isometry3<f64>> = rig.cameras.iter().map(|c| c.rig_from_camera).collect();
    let (result, observations) = reconstruct(log, &cameras, Some(&known), options)?;
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
    })
}
