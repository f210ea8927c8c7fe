#![doc = include_str!("../README.md")]

mod camera;
#[cfg(feature = "files")]
pub mod camodocal;
#[cfg(feature = "files")]
mod camodocal_rig;
mod error;
#[cfg(feature = "glam")]
pub mod glam;
pub mod io;
#[cfg(feature = "files")]
mod kalibr;
mod kannala_brandt;
mod model;
mod pinhole_radtan;
pub mod plausibility;
pub mod polynomial;
mod radtan;
mod rig;
#[cfg(feature = "serde")]
mod serde_support;
mod series;
mod unified;
mod validate;
#[cfg(feature = "files")]
mod yaml;

/// The `nalgebra` this crate's API is written with (points, poses, Jacobians), so callers
/// need not match its version by hand.
pub use nalgebra;

pub use camera::Camera;
#[cfg(feature = "files")]
pub use camodocal::NamedCamera;
pub use error::{
    CameraError, CameraFileError, ParameterError, PlausibilityError, ProjectionError,
    UnprojectionError,
};
pub use kannala_brandt::{KannalaBrandt, KbBackprojection, MAX_FAST_ITERATIONS};
pub use model::{
    CameraModel, MAX_PARAMS, ParamJacobian, ProjectionJacobians, UnprojectionJacobians,
};
pub use pinhole_radtan::PinholeRadtan;
pub use radtan::MAX_UNDISTORT_ITERATIONS;
pub use rig::{Rig, RigCamera};
pub use unified::Unified;
#[cfg(feature = "files")]
pub use yaml::{MAX_FILE_BYTES, MAX_YAML_DEPTH, check_yaml_input};

/// The crate's `Result`, with [`CameraError`] by default.
pub type Result<T, E = CameraError> = std::result::Result<T, E>;
