//! Calibration from images of a Kalibr AprilGrid (issue 20): the target definition
//! ([`aprilgrid`]), detection in images ([`detect`]) and a renderer of target images through
//! any camera model, with truth ([`render`]).

pub mod aprilgrid;
pub mod calibrate;
pub mod command;
pub mod detect;
pub mod error;
pub mod images;
pub mod render;
pub mod simulate;

pub use aprilgrid::AprilGrid;
pub use calibrate::{
    CameraCorners, CameraLink, TargetCalibration, TargetCalibrationOptions,
    calibrate_rig_from_target,
};
pub use detect::{Detection, detect_april_grid, read_gray_image};
pub use error::TargetError;
pub use images::{CameraDetections, CameraFolder, detect_camera_folder, list_camera_folders};
pub use render::{RenderOptions, render_april_grid, rendered_corners};
pub use simulate::{
    SimulatedTargetImages, StaticBoardOptions, TargetSimulationOptions, simulate_static_boards,
    simulate_target_images,
};
