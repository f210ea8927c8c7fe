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

/// Everything that can go wrong when averaging rotations or translations over a viewing graph
/// ([`rotation_averaging`](crate::rotation_averaging),
/// [`rig_rotation_averaging`](crate::rig_rotation_averaging),
/// [`translation_averaging`](crate::translation_averaging),
/// [`rig_translation_averaging`](crate::rig_translation_averaging)).
///
/// Indices are zero-based positions: an `edge` in the caller's edge slice, a `view` among the
/// graph's views, a `camera` or `time` of a [`RigLayout`](crate::RigLayout).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ViewingGraphError {
    /// The graph has no views.
    #[error("the viewing graph has no views")]
    NoViews,

    /// The graph has no edges, so nothing relates any two views.
    #[error("the viewing graph has no edges: averaging needs relative measurements")]
    NoEdges,

    /// An edge names a view that does not exist.
    #[error("edge {edge} names view {view}, but the graph has {views} view(s)")]
    ViewOutOfRange {
        /// Position of the edge.
        edge: usize,
        /// The view it names.
        view: usize,
        /// Number of views.
        views: usize,
    },

    /// An edge joins a view to itself.
    #[error("edge {edge} joins view {view} to itself")]
    SelfLoop {
        /// Position of the edge.
        edge: usize,
        /// The view.
        view: usize,
    },

    /// An edge's relative rotation is not a finite unit quaternion.
    #[error(
        "the relative rotation of edge {edge} has norm {norm}: rotations must be finite unit \
         quaternions"
    )]
    NotUnitRotation {
        /// Position of the edge.
        edge: usize,
        /// Its norm (NaN when a component is NaN).
        norm: f64,
    },

    /// An edge's direction is not a finite unit vector.
    #[error("the direction of edge {edge} has norm {norm}: directions must be finite unit vectors")]
    NotUnitDirection {
        /// Position of the edge.
        edge: usize,
        /// Its norm (NaN when a component is NaN).
        norm: f64,
    },

    /// An edge's weight is zero, negative, NaN or infinite.
    #[error("edge {edge} has weight {weight}: weights must be finite and strictly positive")]
    InvalidWeight {
        /// Position of the edge.
        edge: usize,
        /// The offending value.
        weight: f64,
    },

    /// An option is out of its domain.
    #[error("invalid option `{option}`: {reason}")]
    InvalidOption {
        /// The option's field name.
        option: &'static str,
        /// What is wrong with it.
        reason: &'static str,
    },

    /// A rig layout's view names a time or camera beyond the layout's counts.
    #[error(
        "rig view {view} is (time {time}, camera {camera}) but the layout has {times} time(s) \
         and {cameras} camera(s)"
    )]
    RigViewOutOfRange {
        /// Position of the view.
        view: usize,
        /// Its time.
        time: usize,
        /// Its camera.
        camera: usize,
        /// Number of times of the layout.
        times: usize,
        /// Number of cameras of the layout.
        cameras: usize,
    },

    /// Two views of a rig layout are the same (time, camera) image.
    #[error("rig views {first} and {view} are both (time {time}, camera {camera})")]
    DuplicateRigView {
        /// The earlier view.
        first: usize,
        /// The later view.
        view: usize,
        /// Their time.
        time: usize,
        /// Their camera.
        camera: usize,
    },

    /// A rig layout has no camera.
    #[error("the rig layout has no camera")]
    NoCameras,

    /// No view is left to solve: translation averaging drops views with fewer than two edges
    /// (repeatedly), since their distance along their one edge is free, and in the rig form the
    /// views of a time without a rotation.
    #[error(
        "no view is left to solve: translation averaging drops views in fewer than two edges \
         (repeatedly) and views of times without a rotation"
    )]
    NoSolvableViews,

    /// The graph does not determine a camera's extrinsic: none of its views is in the largest
    /// connected component, or its views there are tied to the reference camera by no time.
    #[error(
        "camera {camera}'s extrinsic is not determined by the viewing graph: {reason} (add \
         edges between its views and views of the other cameras, or drop the camera)"
    )]
    UndeterminedCamera {
        /// The camera.
        camera: usize,
        /// Why.
        reason: &'static str,
    },

    /// The rotations given to translation averaging do not have one entry per time (or per
    /// view).
    #[error("{found} rotation(s) given for {expected} time(s) or view(s)")]
    RotationCountMismatch {
        /// Number of times (rig form) or views.
        expected: usize,
        /// Number of rotations given.
        found: usize,
    },

    /// A distance given to translation averaging ([`crate::TimeDistance`]) is not usable.
    #[error("distance {index}: {reason}")]
    InvalidDistance {
        /// Its position in the list given.
        index: usize,
        /// What is wrong.
        reason: &'static str,
    },

    /// A rotation given to translation averaging is not a finite unit quaternion.
    #[error("rotation {index} has norm {norm}: rotations must be finite unit quaternions")]
    InvalidRotation {
        /// Position of the rotation (a time in the rig form).
        index: usize,
        /// Its norm.
        norm: f64,
    },

    /// The scale gauge names a view that is not kept (out of range, or dropped as outside the
    /// largest component), or two equal views.
    #[error("scale gauge: {reason} (view {view})")]
    InvalidScaleGauge {
        /// The view at fault.
        view: usize,
        /// What is wrong.
        reason: &'static str,
    },

    /// The estimated positions collapse (all equal, or non-finite), so no scale can be fixed:
    /// the directions do not determine the positions (for example all edges parallel).
    #[error(
        "the estimated positions are degenerate ({reason}): the directions do not determine \
         the positions"
    )]
    DegeneratePositions {
        /// What was found.
        reason: &'static str,
    },
}
