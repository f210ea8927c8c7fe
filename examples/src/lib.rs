#![doc = include_str!("../README.md")]

pub mod calib;
pub mod colmap;
pub mod data;
pub mod intrinsics;
pub mod report;
pub mod sfm;
pub mod sim;
pub mod target;

/// The `nalgebra` the crate's API is written with (poses, points, pixels).
pub use nalgebra;

/// The ibc library crates whose types the pipeline's API uses (cameras, pose and RANSAC
/// options, hand-eye pairing, losses, descriptors), at the versions it was built with.
pub use {
    ibc_bundle_adjust, ibc_camera_models, ibc_hand_eye, ibc_pnp, ibc_rig_averaging, ibc_vocab_tree,
};

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
