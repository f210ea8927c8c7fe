#![doc = include_str!("../README.md")]

mod daniilidis;
mod error;
mod guo_planar;
mod least_squares;
mod motion;
mod noise;
mod plane;
mod quadratic;
mod refine;
mod screening;
mod trajectory;

pub use daniilidis::{
    DEFAULT_MIN_SIGNAL_TO_NOISE, DaniilidisOptions, HandEyeSolution, PARALLEL_AXIS_SPREAD,
    daniilidis,
};
pub use error::{
    Decomposition, HandEyeError, NullSpaceStep, OptionField, Result, Sensor, Unobservable,
};
pub use guo_planar::{
    DEFAULT_MAX_OUT_OF_PLANE, DEFAULT_MIN_PLANAR_SIGNAL_TO_NOISE, Height, PlanarOptions,
    PlanarSolution, guo_planar,
};
pub use motion::{MotionPair, Pairing, UNIT_QUATERNION_TOLERANCE, relative_motions};
pub use noise::{NoiseModel, PoseFrame, PoseNoise};
pub use refine::{DEFAULT_MAX_ITERATIONS, RefineOptions, Refined, Uncertainty, refine};
pub use screening::{DEFAULT_MAX_ROTATION, DEFAULT_MIN_ROTATION, MotionScreening};
pub use trajectory::{TrajectoryFit, TrajectoryOptions, refine_trajectories};

/// The linear algebra crate of the API's types (`Isometry3`, `Vector3`), re-exported so that
/// callers use the same version.
pub use nalgebra;

/// The last field of every options struct of the crate: it cannot be written outside the
/// crate, so options are written `X { field: value, ..Default::default() }` and new fields can
/// be added without breaking callers.
///
/// ```compile_fail,E0063
/// // Every field but the hidden one: rejected (missing field `non_exhaustive`).
/// let options = ibc_hand_eye::RefineOptions {
///     max_iterations: 10,
///     rotation_sigma: None,
///     translation_sigma: None,
/// };
/// ```
#[doc(hidden)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct NonExhaustive(());

#[cfg(test)]
mod test_support {
    use nalgebra::{Isometry3, Vector3};

    /// A pose from a translation and a rotation vector.
    pub(crate) fn iso(t: [f64; 3], r: [f64; 3]) -> Isometry3<f64> {
        Isometry3::new(Vector3::from(t), Vector3::from(r))
    }
}
