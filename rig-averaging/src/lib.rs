#![doc = include_str!("../README.md")]

mod eigen4;
mod error;
mod pose_mean;
mod quaternion_mean;
mod rig_init;
mod robust;
mod scoring;

pub use error::RigAveragingError;
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
pub use scoring::{
    DEFAULT_FAILURE_PENALTY_PX, ImageScore, ImageScorer, Observation, ObservationScorer,
};
