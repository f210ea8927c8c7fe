//! Initial extrinsics and rig poses from the frame sets (the paper's section IV-C), by
//! `ibc_rig_averaging::initialize_rig`.
//!
//! Every complete frame set gives a hypothesis of the extrinsics (rig frame = camera 0); the
//! rig pose of every set is the Markley average of its cameras' estimates; the hypothesis
//! with the lowest mean reprojection error of the inlier 2D-3D correspondences, projected
//! through the camera models, wins. To bound the cost (hypotheses x observations), the
//! hypotheses and the scoring use at most [`max_sets`](InitializationOptions::max_sets)
//! frame sets evenly spaced in time, each image at most
//! [`max_observations_per_image`](InitializationOptions::max_observations_per_image) of its
//! inliers (evenly spaced); the rig poses of all sets are then averaged under the winner.

use ibc_camera_models::{Camera, CameraModel};
use ibc_rig_averaging::{
    HypothesisSource, Observation, ObservationScorer, initialize_rig, rig_poses,
};
use nalgebra::{Isometry3, Point2};

use super::error::CalibrationError;
use super::frame_sets::FrameSet;
use super::localization::Localizations;
use super::options::{InitializationOptions, evenly_spaced};
use crate::data::{Map, RigLog};

/// Where the chosen extrinsics came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InitialHypothesis {
    /// The complete frame set with this index (into the calibration's frame sets).
    FrameSet(usize),
    /// The extrinsics averaged over all scored complete sets.
    Averaged,
}

/// The initial estimate.
#[derive(Clone, Debug, PartialEq)]
pub struct Initialization {
    /// `rig_from_camera` per camera; camera 0 is the identity.
    pub rig_from_camera: Vec<Isometry3<f64>>,
    /// `world_from_rig` of every frame set.
    pub world_from_rig: Vec<Isometry3<f64>>,
    /// The chosen hypothesis.
    pub hypothesis: InitialHypothesis,
    /// Its mean reprojection error over the scoring observations, pixels.
    pub score_px: f64,
    /// Number of hypotheses scored.
    pub hypotheses: usize,
}

/// Initializes the extrinsics and the rig poses (see the module docs).
///
/// # Errors
/// [`CalibrationError::NoCompleteFrameSet`] if no set is complete,
/// [`CalibrationError::Initialization`] if the averaging fails.
pub fn initialize<D>(
    sets: &[FrameSet],
    localizations: &Localizations,
    map: &Map<D>,
    log: &RigLog<D>,
    cameras: &[Camera],
    options: &InitializationOptions,
) -> Result<Initialization, CalibrationError> {
    let Some(first_complete) = sets.iter().position(FrameSet::is_complete) else {
        return Err(CalibrationError::NoCompleteFrameSet {
            reason: format!(
                "none of the {} frame sets has every camera localized",
                sets.len()
            ),
            localized: localizations.localized_count(),
            images: localizations.image_count(),
        });
    };
    let mut chosen = evenly_spaced(sets.len(), options.max_sets);
    if !chosen.iter().any(|&s| sets[s].is_complete()) {
        chosen.push(first_complete);
        chosen.sort_unstable();
    }
    let poses: Vec<&[Option<Isometry3<f64>>]> = chosen
        .iter()
        .map(|&s| sets[s].camera_from_world.as_slice())
        .collect();
    let observations: Vec<Vec<Vec<Observation>>> = chosen
        .iter()
        .map(|&s| {
            let frame = sets[s].frame;
            (0..cameras.len())
                .map(|c| {
                    let Some(image) = localizations.get(frame, c) else {
                        return Vec::new();
                    };
                    let keypoints = &log.frames[frame].images[c].keypoints;
                    evenly_spaced(image.inliers.len(), options.max_observations_per_image)
                        .into_iter()
                        .filter_map(|i| {
                            let corr = image.inliers[i];
                            Some(Observation {
                                point_in_world: *map.points.get(corr.point as usize)?,
                                pixel: Point2::from(*keypoints.get(corr.feature as usize)?),
                            })
                        })
                        .collect()
                })
                .collect()
        })
        .collect();
    let project = |c: usize, p: &nalgebra::Point3<f64>| {
        cameras.get(c)?.project(&p.coords).ok().map(Point2::from)
    };
    let scorer = ObservationScorer::new(observations, project);
    let init = initialize_rig(&poses, &scorer, &options.rig)?;
    let all: Vec<&[Option<Isometry3<f64>>]> = sets
        .iter()
        .map(|s| s.camera_from_world.as_slice())
        .collect();
    let world_from_rig = rig_poses(&all, &init.rig_from_camera, &options.rig.rig_pose_averaging)?
        .into_iter()
        .map(|m| m.mean)
        .collect();
    let hypothesis = match init.source {
        HypothesisSource::CompleteSet(i) => InitialHypothesis::FrameSet(chosen[i]),
        HypothesisSource::AveragedExtrinsics => InitialHypothesis::Averaged,
    };
    Ok(Initialization {
        rig_from_camera: init.rig_from_camera,
        world_from_rig,
        hypothesis,
        score_px: init.score.mean_error,
        hypotheses: init.set_scores.len() + usize::from(init.averaged.is_some()),
    })
}
