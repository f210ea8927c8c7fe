//! A calibrated log replayed through the online calibrator (TrimBot2020 D3.1 §3.3.2;
//! [`ibc_bundle_adjust::OnlineCalibrator`]): the frame sets in time order, each with its start
//! rig pose from the initialization and its image's correspondences, so that the running
//! estimate of the intrinsics and extrinsics can be followed over the drive, as a robot would
//! see it while it runs.
//!
//! The calibrator starts from the camera file's intrinsics and the initialization's
//! extrinsics. Each frame set carries every 2D-3D correspondence its images' localization
//! tried, RANSAC inliers or not (evenly spaced, at most the refinement's 100 per image), and
//! the Cauchy loss weighs the wrong matches down. Not the inliers: chosen under the camera
//! file's intrinsics, they keep the noise that agrees with those and lean the estimate back
//! towards them as the lens drifts away (measured: 104 of 136 focal-length estimates within
//! three standard deviations of the truth, worst 10.9, against 136 of 136, worst 2.7, with
//! every correspondence; BENCHMARKS.md).

use ibc_bundle_adjust::{
    OnlineCalibrator, OnlineEvent, OnlineFrameSet, OnlineObservation, OnlineOptions,
};
use ibc_camera_models::{Rig, RigCamera};

use super::error::CalibrationError;
use super::options::{RefinementOptions, evenly_spaced};
use super::pipeline::Calibration;
use crate::data::{Map, RigLog};

/// One frame set of the replay: its log frame and what the calibrator did.
#[derive(Debug, Clone)]
pub struct OnlineStep {
    /// The frame set's index.
    pub set: usize,
    /// Its log frame.
    pub frame: usize,
    /// What the calibrator did with it.
    pub event: OnlineEvent,
}

/// Replays `calibration`'s frame sets (of `map` and `log`, the calibration's inputs) through
/// an [`OnlineCalibrator`] with `options`; only the frame sets at which an update was due are
/// returned (updated or skipped).
///
/// # Errors
/// [`CalibrationError::InvalidOption`] for options the calibrator refuses;
/// [`CalibrationError::Refinement`] for a frame set it refuses (an observation of a camera
/// the rig does not have, non-finite values).
pub fn replay_online<D>(
    calibration: &Calibration,
    map: &Map<D>,
    log: &RigLog<D>,
    options: &OnlineOptions,
) -> Result<Vec<OnlineStep>, CalibrationError> {
    let rig = Rig::new(
        calibration
            .prior_rig
            .cameras
            .iter()
            .zip(&calibration.initialization.rig_from_camera)
            .map(|(c, pose)| RigCamera::new(c.name.clone(), c.camera.clone(), *pose))
            .collect(),
    );
    let mut calibrator = OnlineCalibrator::new(&rig, options.clone()).map_err(|e| {
        CalibrationError::InvalidOption {
            name: "online",
            reason: e.to_string(),
        }
    })?;
    let per_image = RefinementOptions::default().max_observations_per_image;
    let mut sets = Vec::with_capacity(calibration.frame_sets.len());
    for (set, world_from_rig) in calibration
        .frame_sets
        .iter()
        .zip(&calibration.initialization.world_from_rig)
    {
        let mut observations = Vec::new();
        for c in 0..calibration.cameras.len() {
            let (Some(image), Some(features)) = (
                calibration.localizations.get(set.frame, c),
                log.frames.get(set.frame).and_then(|f| f.images.get(c)),
            ) else {
                continue;
            };
            let all = &image.correspondences;
            for i in evenly_spaced(all.len(), per_image) {
                let corr = all[i];
                if let (Some(point), Some(pixel)) = (
                    map.points.get(corr.point as usize),
                    features.keypoints.get(corr.feature as usize),
                ) {
                    observations.push(OnlineObservation {
                        camera: c,
                        world_point: point.coords,
                        pixel: *pixel,
                    });
                }
            }
        }
        sets.push(OnlineFrameSet {
            world_from_rig: *world_from_rig,
            observations,
        });
    }
    let mut steps = Vec::new();
    for (set, (frame_set, info)) in sets.into_iter().zip(&calibration.frame_sets).enumerate() {
        let event = calibrator.push(frame_set)?;
        if !matches!(event, OnlineEvent::Kept) {
            steps.push(OnlineStep {
                set,
                frame: info.frame,
                event,
            });
        }
    }
    Ok(steps)
}
