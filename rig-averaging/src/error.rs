//! The crate's error type: every way an input can be unusable, named after what was wrong.

use crate::quaternion_mean::UNIT_NORM_TOLERANCE;

/// `Result` with [`RigAveragingError`] as the default error.
pub type Result<T, E = RigAveragingError> = std::result::Result<T, E>;

/// Everything that can go wrong when averaging rotations and poses or initializing a rig.
///
/// Each variant names the input that was wrong and why, so a caller can fix the data rather
/// than guess. Indices are zero-based positions in the slices the caller passed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum RigAveragingError {
    /// There was nothing to average.
    #[error("nothing to average: the input holds no rotations or poses")]
    EmptyInput,

    /// The weight slice does not have one weight per input.
    #[error("{inputs} inputs but {weights} weights: give exactly one weight per input")]
    WeightCountMismatch {
        /// Number of rotations or poses.
        inputs: usize,
        /// Number of weights.
        weights: usize,
    },

    /// A weight is zero, negative, NaN or infinite.
    #[error("weight {index} is {weight}: weights must be finite and strictly positive")]
    InvalidWeight {
        /// Position of the weight.
        index: usize,
        /// The offending value.
        weight: f64,
    },

    /// The weights are finite and positive but their sum overflows, or they are so small that
    /// the accumulated matrix underflows to zero (only the streaming
    /// [`MarkleyAccumulator`](crate::MarkleyAccumulator) can hit this; the slice functions
    /// rescale the weights first).
    #[error(
        "the weights sum to {weight_sum}: rescale them into a range where their sum is a \
         finite, normal f64"
    )]
    WeightsOutOfRange {
        /// The accumulated weight sum.
        weight_sum: f64,
    },

    /// A quaternion is not of unit norm or has a non-finite component.
    #[error(
        "quaternion {index} has norm {norm}: rotations must be finite unit quaternions \
         (|norm - 1| <= {UNIT_NORM_TOLERANCE})"
    )]
    NotUnitQuaternion {
        /// Position of the quaternion.
        index: usize,
        /// Its Euclidean norm (NaN when a component is NaN).
        norm: f64,
    },

    /// A translation has a NaN or infinite component.
    #[error("translation {index} has a non-finite component")]
    NonFiniteTranslation {
        /// Position of the pose.
        index: usize,
    },

    /// An option of the robust mean ([`RobustOptions`](crate::RobustOptions)) is out of its
    /// domain.
    #[error("invalid robust averaging option `{option}`: {reason}")]
    InvalidRobustOptions {
        /// The option's field name, for instance `rotation_scale`.
        option: &'static str,
        /// What is wrong with it.
        reason: &'static str,
    },

    /// Rig initialization received no frame sets.
    #[error("no frame sets: rig initialization needs at least one set of camera poses")]
    NoFrameSets,

    /// The rig has fewer than two cameras, so there is no extrinsic to estimate.
    #[error("the frame sets have {cameras} camera slot(s): a rig needs at least two cameras")]
    TooFewRigCameras {
        /// Number of camera slots in the first set.
        cameras: usize,
    },

    /// Frame sets disagree on the number of cameras.
    #[error(
        "frame set {set} has {found} camera slot(s) but set 0 has {expected}: every set must \
         list every camera of the rig (None for a camera that was not localized)"
    )]
    CameraCountMismatch {
        /// The first set whose count differs.
        set: usize,
        /// Number of camera slots in set 0.
        expected: usize,
        /// Number of camera slots in `set`.
        found: usize,
    },

    /// A frame set localizes fewer than two cameras.
    #[error(
        "frame set {set} localizes {localized} camera(s): every set must localize at least two \
         cameras (drop the set before initialization)"
    )]
    SetTooFewCameras {
        /// Position of the set.
        set: usize,
        /// Number of localized cameras in it.
        localized: usize,
    },

    /// A camera pose has a non-finite component or a non-unit rotation.
    #[error(
        "the camera_from_world of camera {camera} in frame set {set} is not a finite rigid \
         transform (non-finite translation or non-unit rotation)"
    )]
    InvalidCameraPose {
        /// Position of the set.
        set: usize,
        /// Camera index within the set.
        camera: usize,
    },

    /// The extrinsics given to [`rig_poses`](crate::rig_poses) do not have one entry per camera
    /// slot of the frame sets.
    #[error("{found} extrinsic(s) given for frame sets of {expected} camera slot(s)")]
    ExtrinsicCountMismatch {
        /// Number of camera slots in the frame sets.
        expected: usize,
        /// Number of extrinsics given.
        found: usize,
    },

    /// An extrinsic given to [`rig_poses`](crate::rig_poses) has a non-finite component or a
    /// non-unit rotation.
    #[error(
        "the rig_from_camera of camera {camera} is not a finite rigid transform (non-finite \
         translation or non-unit rotation)"
    )]
    InvalidExtrinsic {
        /// Camera index.
        camera: usize,
    },

    /// No frame set localizes every camera, so no hypothesis of the extrinsics can be formed.
    #[error(
        "none of the {sets} frame set(s) localizes every camera: at least one complete set is \
         needed to form a hypothesis of the extrinsics"
    )]
    NoCompleteSet {
        /// Number of frame sets given.
        sets: usize,
    },

    /// The scorer gave no hypothesis a finite mean reprojection error: either it reported no
    /// observations at all, or its error sums were NaN or infinite.
    #[error(
        "no hypothesis received a finite mean reprojection error: the scorer reported no \
         observations or non-finite error sums"
    )]
    NoFiniteScore,
}
