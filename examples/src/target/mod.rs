//! Calibration from images of a Kalibr AprilGrid (issue 20): the target definition
//! ([`aprilgrid`]), detection in images ([`detect`], with the `aprilgrid` crate), image
//! folders ([`images`]), a renderer of target images through any camera model with truth
//! ([`render`], [`simulate`]), the rig calibration ([`calibrate`]: every camera's intrinsics,
//! the extrinsics from shared views or, for cameras that never share one, from the rig's
//! motion in front of boards standing still, then one joint refinement) and `ibc target`'s
//! files ([`command`]).
//!
//! ```
//! use ibc_pipeline::ibc_camera_models::{Rig, RigCamera};
//! use ibc_pipeline::intrinsics::IntrinsicModel;
//! use ibc_pipeline::intrinsics::simulate::preset_camera;
//! use ibc_pipeline::nalgebra::Isometry3;
//! use ibc_pipeline::target::{
//!     AprilGrid, TargetSimulationOptions, detect_april_grid, rendered_corners,
//!     simulate_target_images,
//! };
//!
//! // Kalibr's target file, and a pinhole that sees one board.
//! let grid = AprilGrid::from_kalibr_str(
//!     "target_type: 'aprilgrid'\ntagCols: 6\ntagRows: 6\ntagSize: 0.05\ntagSpacing: 0.3\n",
//! )?;
//! let camera = preset_camera(IntrinsicModel::PinholeRadtan)?;
//! let rig = Rig::new(vec![RigCamera::new("cam0", camera.clone(), Isometry3::identity())]);
//! let options = TargetSimulationOptions { views_per_camera: 1, ..Default::default() };
//! let sim = simulate_target_images(&rig, &grid, &options)?;
//! let (Some(image), Some(pose)) = (&sim.images[0][0], sim.camera_from_board[0][0]) else {
//!     unreachable!("the simulation places the board in view");
//! };
//! let found = detect_april_grid(image, &grid, "t0000")?;
//! let truth = rendered_corners(&camera, &pose, &grid.planar_target(), 2.0);
//! for corner in &found.corners {
//!     let t = truth.iter().find(|t| (t.row, t.col) == (corner.row, corner.col)).unwrap();
//!     assert!((t.pixel() - corner.pixel()).norm() < 0.3);
//! }
//! assert!(found.corners.len() > truth.len() / 2);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

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
