//! Frame-set selection (the paper's section IV-B).
//!
//! A frame set is a synchronized frame of the log with the poses of its localized cameras.
//! Frames are visited in time order; a frame is kept when
//!
//! - at least [`min_cameras`](FrameSetOptions::min_cameras) of its images are localized, and
//! - every camera localized both in it and in the last kept set has moved more than
//!   [`min_motion_m`](FrameSetOptions::min_motion_m) (distance between its two camera
//!   centres in the map frame).
//!
//! The first frame with enough localized cameras is kept; a frame that shares no localized
//! camera with the last kept set is kept (the condition holds for every shared camera).

use nalgebra::Isometry3;

use super::localization::Localizations;
use super::options::FrameSetOptions;

/// A kept frame set.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameSet {
    /// Index of the frame in the log.
    pub frame: usize,
    /// Per camera, its `camera_from_world` from localization, `None` if not localized.
    pub camera_from_world: Vec<Option<Isometry3<f64>>>,
}

impl FrameSet {
    /// Number of localized cameras.
    pub fn localized(&self) -> usize {
        self.camera_from_world.iter().flatten().count()
    }

    /// True when every camera is localized.
    pub fn is_complete(&self) -> bool {
        self.camera_from_world.iter().all(Option::is_some)
    }
}

/// The camera centre (in the world frame) of a `camera_from_world` pose.
fn centre(camera_from_world: &Isometry3<f64>) -> nalgebra::Vector3<f64> {
    camera_from_world.inverse().translation.vector
}

/// Selects the frame sets (see the module docs), in time order.
pub fn select_frame_sets(
    localizations: &Localizations,
    options: &FrameSetOptions,
) -> Vec<FrameSet> {
    let mut kept: Vec<FrameSet> = Vec::new();
    for (frame, images) in localizations.images.iter().enumerate() {
        let poses: Vec<Option<Isometry3<f64>>> = images
            .iter()
            .map(|r| r.as_ref().ok().map(|l| l.camera_from_world))
            .collect();
        if poses.iter().flatten().count() < options.min_cameras {
            continue;
        }
        let moved = kept.last().is_none_or(|last| {
            poses
                .iter()
                .zip(&last.camera_from_world)
                .all(|(now, before)| match (now, before) {
                    (Some(a), Some(b)) => (centre(a) - centre(b)).norm() > options.min_motion_m,
                    _ => true,
                })
        });
        if moved {
            kept.push(FrameSet {
                frame,
                camera_from_world: poses,
            });
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::localization::{LocalizationFailure, LocalizedImage};

    fn image(x: f64) -> Result<LocalizedImage, LocalizationFailure> {
        Ok(LocalizedImage {
            camera_from_world: Isometry3::translation(-x, 0.0, 0.0),
            inliers: Vec::new(),
            matches: 0,
            correspondences: Vec::new(),
        })
    }

    fn lost() -> Result<LocalizedImage, LocalizationFailure> {
        Err(LocalizationFailure::NoCandidates)
    }

    #[test]
    fn keeps_frames_whose_shared_cameras_all_moved() {
        let l = Localizations {
            images: vec![
                vec![image(0.0), lost(), lost()],          // one camera: skipped
                vec![image(0.0), image(0.0), lost()],      // first kept
                vec![image(0.2), image(0.5), lost()],      // camera 0 moved 0.2: skipped
                vec![image(0.4), image(0.6), image(9.0)],  // both moved > 0.3: kept
                vec![lost(), lost(), image(9.1)],          // one camera
                vec![image(0.5), lost(), image(9.2)],      // 0.1 and 0.2: skipped
                vec![lost(), image(5.0), lost()],          // one camera
                vec![image(0.75), image(0.7), image(9.5)], // 0.35, 0.1, 0.5: camera 1 too close
                vec![image(0.8), image(1.0), image(9.8)],  // 0.4, 0.4, 0.8: kept
            ],
        };
        let sets = select_frame_sets(&l, &FrameSetOptions::default());
        let frames: Vec<usize> = sets.iter().map(|s| s.frame).collect();
        assert_eq!(frames, vec![1, 3, 8]);
        assert!(sets[1].is_complete() && !sets[0].is_complete());
        assert_eq!(sets[0].localized(), 2);
    }
}
