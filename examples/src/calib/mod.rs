//! The calibration pipeline of Heng, Bürki, Lee, Furgale, Siegwart and Pollefeys,
//! "Infrastructure-Based Calibration of a Multi-Camera Rig", ICRA 2014.
//!
//! [`calibrate`] runs every stage; each stage is also a function of its own:
//!
//! | stage | function | module |
//! |---|---|---|
//! | vocabulary tree and map database | [`MapIndex::train`], [`MapIndex::build`] | [`map_index`] |
//! | localization of every image | [`localize_log`], [`localize_image`] | [`localization`] |
//! | frame sets | [`select_frame_sets`] | [`frame_sets`] |
//! | initialization | [`initialize`] | [`initialization`] |
//! | refinement | [`refine`] | [`refinement`] |
//! | hand-eye calibration | [`calibrate_hand_eye`] | [`hand_eye`] |
//! | per-camera figures and quality gates | [`quality::assess`] | [`quality`] |
//! | errors against ground truth | [`Calibration::accuracy`] | [`accuracy`] |
//!
//! Every default in [`CalibrationOptions`] is the paper's (or, where the paper gives none,
//! its implementation CamOdoCal's), and each module's docs state its exact rule. The
//! estimated rig frame is camera 0's. The pipeline is deterministic: the same inputs and
//! options give the same calibration whatever the number of threads (only
//! [`Calibration::timing`] differs).

pub mod accuracy;
pub mod camera_matching;
mod error;
pub mod frame_sets;
pub mod hand_eye;
pub mod initialization;
pub mod localization;
pub mod map_index;
pub mod online;
mod options;
mod pipeline;
mod progress;
pub mod quality;
pub mod refinement;

pub use accuracy::{CameraAccuracy, HandEyeAccuracy, IntrinsicsAccuracy};
pub use camera_matching::{CameraMatching, match_cameras};
pub use error::CalibrationError;
pub use frame_sets::{FrameSet, select_frame_sets};
pub use hand_eye::{HandEye, HandEyeFailure, HandEyeSolver, calibrate_hand_eye};
pub use initialization::{InitialHypothesis, Initialization, initialize};
pub use localization::{
    Correspondence, ImageLocalization, LocalizationFailure, Localizations, LocalizedImage,
    localize_image, localize_log,
};
pub use map_index::{MapIndex, train_vocabulary};
pub use online::{OnlineStep, replay_online};
pub use options::{
    CalibrationOptions, FrameSetOptions, HandEyeMethod, HandEyeOptions, InitializationOptions,
    LocalizationOptions, RefinementOptions, VocabularyOptions, default_pose_options,
};
pub use pipeline::{Accuracy, Calibration, Timing, calibrate, calibrate_with, finite_mean};
pub use progress::{NoProgress, Progress, Stage};
pub use quality::{CalibrationWarning, CameraQuality, Quality, ResidualStats, Status};
pub use refinement::{
    CameraIntrinsics, HeldIntrinsic, IntrinsicParameter, PoseStd, Refinement, RigObservation,
    refine,
};
