#![doc = include_str!("../README.md")]

mod daniilidis;
mod error;
mod guo_planar;
mod least_squares;
mod motion;
mod plane;
mod quadratic;
mod refine;
mod screening;
mod trajectory;

pub use daniilidis::{
    DEFAULT_MIN_SIGNAL_TO_NOISE, DaniilidisOptions, HandEyeSolution, PARALLEL_AXIS_SPREAD,
    daniilidis,
};
pub use error::{HandEyeError, Sensor};
pub use guo_planar::{
    DEFAULT_MAX_OUT_OF_PLANE, DEFAULT_MIN_PLANAR_SIGNAL_TO_NOISE, Height, PlanarOptions,
    PlanarSolution, guo_planar,
};
pub use motion::{MotionPair, Pairing, UNIT_QUATERNION_TOLERANCE, relative_motions};
pub use refine::{DEFAULT_MAX_ITERATIONS, RefineOptions, Refined, Uncertainty, refine};
pub use screening::{DEFAULT_MAX_ROTATION, DEFAULT_MIN_ROTATION, MotionScreening};
pub use trajectory::{TrajectoryFit, TrajectoryOptions, refine_trajectories};

#[cfg(test)]
mod test_support {
    use nalgebra::{Isometry3, Vector3};

    /// A pose from a translation and a rotation vector.
    pub(crate) fn iso(t: [f64; 3], r: [f64; 3]) -> Isometry3<f64> {
        Isometry3::new(Vector3::from(t), Vector3::from(r))
    }
}
