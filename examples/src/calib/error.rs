//! The pipeline's error type.

use ibc_rig_averaging::RigAveragingError;

use crate::data::TruthMismatch;
use ibc_vocab_tree::VocabError;

/// Why a calibration could not be computed. Each message names the problem and, where one is
/// likely, its cause.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CalibrationError {
    /// An option is out of its valid range.
    #[error("invalid option `{name}`: {reason}")]
    InvalidOption {
        /// The option, as `stage.field`.
        name: &'static str,
        /// What is wrong with its value.
        reason: String,
    },
    /// The localization's pose options are outside their domain.
    #[error("invalid option `localization.pose`: {0}")]
    InvalidPoseOptions(#[source] ibc_pnp::PnpError),
    /// The camera file and the rig log disagree on the number of cameras.
    #[error(
        "the camera file has {cameras} camera(s) but the rig log has {log_cameras}: were the \
         camera file and the log recorded with different rigs?"
    )]
    CameraCountMismatch {
        /// Cameras in the camera file.
        cameras: usize,
        /// Cameras in the rig log.
        log_cameras: usize,
    },
    /// The camera file and the rig log name different cameras.
    #[error(
        "the camera file names the cameras {} but the rig log {}: are they from the same \
         rig? (cameras are matched by name; a file without names, such as a Kalibr camchain, \
         by order)",
        file.join(", "),
        log.join(", ")
    )]
    CameraNamesMismatch {
        /// The camera file's names, in its order.
        file: Vec<String>,
        /// The log's names, in its order.
        log: Vec<String>,
    },
    /// The rig has fewer than two cameras: a rig calibration needs at least two.
    #[error("the rig has {cameras} camera(s): extrinsic calibration needs at least two")]
    TooFewCameras {
        /// Cameras in the rig.
        cameras: usize,
    },
    /// The map has no map point or no map image with features.
    #[error("the map is empty ({what}): was the map built from the survey?")]
    EmptyMap {
        /// What is missing.
        what: &'static str,
    },
    /// The rig log has no frame.
    #[error("the rig log has no frame")]
    EmptyLog,
    /// The log's or the map's data are inconsistent (a frame with a wrong number of images,
    /// keypoints and descriptors of different lengths, a point id past the points).
    #[error("inconsistent input: {0}")]
    InvalidInput(String),
    /// The vocabulary could not be trained, or does not fit the map's descriptors.
    #[error("vocabulary: {0}")]
    Vocabulary(#[from] VocabError),
    /// No image of the log could be localized against the map.
    #[error(
        "no image was localized against the map ({images} images tried): does the log come \
         from the mapped area, and do the map and the log use the same kind of descriptors \
         and the right camera intrinsics?"
    )]
    NothingLocalized {
        /// Images tried.
        images: usize,
    },
    /// One camera was localized in none of its images (the others were).
    #[error(
        "camera `{camera}` was localized in none of its {images} images (most often: \
         {reason}): do its intrinsics in the camera file match the camera, and does it see the \
         mapped area?"
    )]
    CameraNotLocalized {
        /// The camera's name.
        camera: String,
        /// Its images.
        images: usize,
        /// The most frequent reason its images failed.
        reason: String,
    },
    /// Localized images exist, but no frame set has enough localized cameras, or none has all
    /// cameras localized, which the initialization needs.
    #[error(
        "no complete frame set: {reason} ({localized} of {images} images localized); the rig \
         needs frames where every camera sees the mapped area"
    )]
    NoCompleteFrameSet {
        /// Which condition failed.
        reason: String,
        /// Images localized.
        localized: usize,
        /// Images tried.
        images: usize,
    },
    /// The rig initialization failed.
    #[error("initialization: {0}")]
    Initialization(#[from] RigAveragingError),
    /// The non-linear refinement failed.
    #[error("refinement: {0}")]
    Refinement(#[from] ibc_bundle_adjust::BundleAdjustError),
    /// A camera has no observation the refinement can use.
    #[error(
        "refinement: camera {camera} (in the log's order) has no usable observation: is it \
         localized in any frame set?"
    )]
    CameraWithoutObservations {
        /// Index of the camera.
        camera: usize,
    },
    /// The ground truth does not fit the calibration's log.
    #[error("ground truth: {0}")]
    Truth(#[from] TruthMismatch),
}
