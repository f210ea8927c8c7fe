#![doc = include_str!("../README.md")]

mod eigen4;
mod error;
mod parallel;
mod pose_mean;
mod quaternion_mean;
mod rig_init;
mod robust;
mod rotation_averaging;
mod scoring;
mod sparse_cholesky;
mod translation_averaging;
mod viewing_graph;

/// The linear-algebra crate of this crate's API (`Isometry3`, `UnitQuaternion`, ...), so
/// callers can use the very version it was built with.
pub use nalgebra;

pub use error::{Result, RigAveragingError, ViewingGraphError};
pub use pose_mean::{PoseMean, pose_mean};
pub use quaternion_mean::{
    MarkleyAccumulator, QuaternionMean, UNIT_NORM_TOLERANCE, quaternion_mean,
};
pub use rig_init::{
    Averaging, HypothesisScore, HypothesisSource, RigInitOptions, RigInitialization,
    initialize_rig, rig_poses,
};
pub use robust::{
    ADAPTIVE_SCALE_FACTOR, MIN_ROTATION_SCALE, MIN_TRANSLATION_SCALE, RobustDiagnostics,
    RobustOptions, RobustPoseMean, RobustQuaternionMean, robust_pose_mean, robust_quaternion_mean,
};
pub use rotation_averaging::{
    L1_RESIDUAL_FLOOR, MIN_GRAPH_SCALE, OUTLIER_SCALE_FACTOR, RigRotationAveraging,
    RotationAveraging, RotationAveragingOptions, rig_rotation_averaging, rotation_averaging,
};
pub use scoring::{
    DEFAULT_FAILURE_PENALTY_PX, ImageScore, ImageScorer, Observation, ObservationScorer,
};
pub use translation_averaging::{
    DIRECTION_SCALE_FACTOR, RigTranslationAveraging, ScaleGauge, TimeDistance,
    TranslationAveraging, TranslationAveragingOptions, rig_translation_averaging,
    rig_translation_averaging_with_distances, translation_averaging,
};
pub use viewing_graph::{
    AveragingReport, Component, DirectionEdge, RigLayout, RigView, RotationEdge,
    largest_connected_component,
};

/// The last field of every options struct of this crate (`non_exhaustive`), set by the
/// struct's `Default`.
///
/// Code outside the crate cannot make one, so it writes an options struct as
/// `RobustOptions { max_iterations: 20, ..Default::default() }`: fields can then be added
/// without breaking it, as `#[non_exhaustive]` would guarantee, while the one-expression form
/// stays possible (the pattern of faer's parameter structs).
#[doc(hidden)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct NonExhaustive(pub(crate) ());
