#![doc = include_str!("../README.md")]

pub mod calib;
pub mod data;
pub mod intrinsics;
pub mod report;
pub mod sim;

/// The `nalgebra` the crate's API is written with (poses, points, pixels).
pub use nalgebra;

/// The crate's `Result`, with [`calib::CalibrationError`] by default (the other modules have
/// their own error types: [`data::io::DataFileError`], [`sim::SimError`],
/// [`intrinsics::IntrinsicsError`], [`report::OutputError`]).
pub type Result<T, E = calib::CalibrationError> = std::result::Result<T, E>;

/// Marks an options struct as open to new fields: outside this crate it can only be built
/// with `..Default::default()` (`CalibrationOptions { refinement, ..Default::default() }`), so
/// adding a field is not a breaking change (faer's pattern).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[doc(hidden)]
pub struct NonExhaustive(pub(crate) ());
