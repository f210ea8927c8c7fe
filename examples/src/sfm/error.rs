//! Why a self-calibration could not be computed.

use ibc_bundle_adjust::BundleAdjustError;
use ibc_hand_eye::HandEyeError;
use ibc_rig_averaging::ViewingGraphError;
use ibc_vocab_tree::VocabError;

/// Why [`super::self_calibrate`] failed. Each message names the problem and, where one is
/// likely, what to do about it.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SelfCalibrationError {
    /// The cameras and the rig log disagree on the number of cameras.
    #[error("{cameras} camera(s) given but the rig log has {log}")]
    CameraCount {
        /// Cameras given.
        cameras: usize,
        /// Cameras in the log.
        log: usize,
    },
    /// A frame of the log has another number of images than cameras.
    #[error("frame {frame} of the rig log has {images} image(s) for {cameras} camera(s)")]
    FrameImages {
        /// The frame.
        frame: usize,
        /// Its images.
        images: usize,
        /// Cameras of the rig.
        cameras: usize,
    },
    /// An option is outside its domain.
    #[error("invalid option `{option}`: {reason}")]
    InvalidOption {
        /// The option.
        option: &'static str,
        /// What is wrong with it.
        reason: String,
    },
    /// The log has no descriptor at all.
    #[error("the rig log has no features")]
    NoFeatures,
    /// The vocabulary could not be trained or applied.
    #[error("vocabulary: {0}")]
    Vocabulary(#[source] VocabError),
    /// No image pair passed the geometric verification.
    #[error(
        "no image pair of the log shares enough verified matches ({candidates} candidate pairs): \
         is the log's motion large enough between frames, and do the features repeat?"
    )]
    NoVerifiedPairs {
        /// Candidate pairs tried.
        candidates: usize,
    },
    /// A camera's extrinsic is not determined by the log.
    #[error(
        "`{camera}` is not connected to the others: no verified track links its images with \
         those of the reference camera ({reason}); drive a turn, or a loop, so that it sees \
         what the other cameras saw"
    )]
    UndeterminedCamera {
        /// The camera's name.
        camera: String,
        /// What the graph lacked.
        reason: String,
    },
    /// Rotation or translation averaging failed.
    #[error("averaging of the viewing graph: {0}")]
    Averaging(#[source] ViewingGraphError),
    /// Too few points could be triangulated from the averaged poses.
    #[error(
        "only {points} point(s) could be triangulated from the averaged poses: the viewing \
         graph's poses are inconsistent"
    )]
    TooFewPoints {
        /// Points triangulated.
        points: usize,
    },
    /// The rig bundle adjustment failed.
    #[error("rig bundle adjustment: {0}")]
    BundleAdjustment(#[source] BundleAdjustError),
    /// The odometry's motions do not determine the scale (no translation, or degenerate).
    #[error(
        "the odometry's motions do not determine the metric scale (does the rig translate, and \
         rotate about more than one axis?); give a known baseline instead"
    )]
    ScaleUndetermined,
    /// The metric scale could not be estimated from the odometry.
    #[error("metric scale from the odometry: {0}")]
    Scale(#[source] HandEyeError),
}
