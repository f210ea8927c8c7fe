#![doc = include_str!("../README.md")]

mod camera;
pub mod camodocal;
mod error;
#[cfg(feature = "glam")]
pub mod glam;
mod input;
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
mod yaml;

pub use camera::Camera;
pub use camodocal::NamedCamera;
pub use error::{
    Error, FileError, ParameterError, PlausibilityError, ProjectionError, UnprojectionError,
};
pub use input::MAX_FILE_BYTES;
pub use kannala_brandt::{KannalaBrandt, KbBackprojection, MAX_FAST_ITERATIONS};
pub use model::{
    CameraModel, MAX_PARAMS, ParamJacobian, ProjectionJacobians, UnprojectionJacobians,
};
pub use pinhole_radtan::PinholeRadtan;
pub use radtan::MAX_UNDISTORT_ITERATIONS;
pub use rig::{Rig, RigCamera};
pub use unified::Unified;
pub use yaml::{MAX_YAML_DEPTH, check_yaml_input};
