//! The crate's error type: every way the input can fail to determine the transform.

use nalgebra::Vector3;

/// Which of the two sensors a pose or a motion belongs to (see the crate docs for `a` and `b`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sensor {
    /// Sensor `a`, whose motions are the `A_i` of `A_i X = X B_i` (the rig, in the pipeline).
    A,
    /// Sensor `b`, whose motions are the `B_i` of `A_i X = X B_i` (the odometry, in the pipeline).
    B,
}

/// Why a hand-eye problem has no answer.
///
/// A numeric outcome without an answer (degenerate motion, no real root) is one of these
/// variants, never a silently wrong transform.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum HandEyeError {
    /// The two synchronized trajectories do not have the same number of poses.
    #[error("the trajectories differ in length: {a} poses of sensor a, {b} poses of sensor b")]
    MismatchedLengths {
        /// Number of poses of sensor `a`.
        a: usize,
        /// Number of poses of sensor `b`.
        b: usize,
    },
    /// A pose or motion contains a NaN or an infinity.
    #[error("pose or motion {index} of sensor {sensor:?} contains a non-finite value")]
    NonFinite {
        /// Index of the offending pose (trajectory helpers) or motion pair (solvers).
        index: usize,
        /// The sensor it belongs to.
        sensor: Sensor,
    },
    /// A rotation is stored as a quaternion whose norm is not 1 (built with `new_unchecked`).
    #[error(
        "pose or motion {index} of sensor {sensor:?} has a quaternion of norm {norm}, not a rotation"
    )]
    NotUnitQuaternion {
        /// Index of the offending pose or motion pair.
        index: usize,
        /// The sensor it belongs to.
        sensor: Sensor,
        /// The norm found.
        norm: f64,
    },
    /// No motion rotates enough to be used: the rotation (and, for the planar method, the
    /// translation) of `X` is not determined by pure translations.
    #[error(
        "no motion rotates by at least the minimum rotation of {:.3} deg (the largest rotates \
         {:.3} deg): X is not determined",
        .min_rotation.to_degrees(),
        .largest_rotation.to_degrees()
    )]
    NoRotation {
        /// The largest rotation angle among the motions, radians.
        largest_rotation: f64,
        /// The minimum rotation of the screening options, radians.
        min_rotation: f64,
    },
    /// Fewer usable motions than the method needs.
    #[error(
        "{usable} usable motions, {needed} needed ({rejected_small} rotate less than the minimum, {rejected_half_turn} are too close to a half turn)"
    )]
    TooFewMotions {
        /// Motions that passed the screening.
        usable: usize,
        /// Motions the method needs.
        needed: usize,
        /// Motions rejected for rotating too little.
        rejected_small: usize,
        /// Motions rejected for rotating too close to 180 degrees (sign of the quaternion
        /// ambiguous).
        rejected_half_turn: usize,
    },
    /// Every rotation axis is parallel (planar motion, or rotation about one axis only): the
    /// translation of `X` along that axis is unobservable. The planar solver
    /// ([`crate::guo_planar`]) handles this case and takes that component from a prior.
    #[error(
        "all rotation axes are parallel to [{:.3}, {:.3}, {:.3}] (frame a; spread {:.3} deg, \
         signal-to-noise {:.2e}): the translation of X along this axis is unobservable \
         (planar motion); use the planar solver with a height prior",
        .axis_a.x,
        .axis_a.y,
        .axis_a.z,
        .axis_spread.to_degrees(),
        .signal_to_noise
    )]
    ParallelRotationAxes {
        /// The common rotation axis of the `A_i`, a unit vector in frame `a`.
        axis_a: Vector3<f64>,
        /// RMS angular spread of the rotation axes about `axis_a`, radians.
        axis_spread: f64,
        /// The degeneracy figure: sixth over seventh singular value of the Daniilidis system.
        signal_to_noise: f64,
    },
    /// The motions leave a part of `X` undetermined (named in `unobservable`).
    #[error(
        "degenerate motion: {unobservable} is unobservable (signal-to-noise {signal_to_noise:.2e})"
    )]
    Degenerate {
        /// What the motions cannot determine.
        unobservable: &'static str,
        /// The figure that revealed it (signal over noise of the weakest direction).
        signal_to_noise: f64,
    },
    /// The quadratic constraint of the null-space step has no real root: the motions are not
    /// consistent with one rigid transform (wrong pairing, unsynchronized or non-rigid data).
    #[error(
        "negative discriminant {discriminant:.3e} in the {step}: the motions are not consistent \
         with one rigid transform"
    )]
    NegativeDiscriminant {
        /// The step whose quadratic failed.
        step: &'static str,
        /// The discriminant (its coefficients are of order one).
        discriminant: f64,
    },
    /// A motion of sensor `b` leaves the plane the planar method assumes (rotation axis not
    /// along `z` of frame `b`, or translation out of its `xy` plane).
    #[error(
        "{} of sensor b {} not planar: it leaves the xy plane of frame b by {:.3} deg \
         (tolerance {:.3} deg)",
        .index.map_or_else(|| "the translations taken together".to_owned(), |i| format!("motion {i}")),
        if .index.is_some() { "is" } else { "are" },
        .out_of_plane.to_degrees(),
        .tolerance.to_degrees()
    )]
    NotPlanar {
        /// Index of the motion pair whose rotation tilts, or `None` when the translations taken
        /// together (RMS) rise out of the plane.
        index: Option<usize>,
        /// Tilt of the rotation axis, or elevation of the translations, radians.
        out_of_plane: f64,
        /// The tolerance of the options, radians.
        tolerance: f64,
    },
    /// An options field is outside its valid domain.
    #[error("invalid option: {what}")]
    InvalidOptions {
        /// Which field, and what its domain is.
        what: &'static str,
    },
    /// A numerical decomposition did not converge (this should not happen on finite input).
    #[error("the {what} did not converge")]
    NoConvergence {
        /// The decomposition.
        what: &'static str,
    },
}

impl HandEyeError {
    /// [`HandEyeError::TooFewMotions`] for `usable` of the two motions a method needs, none
    /// rejected by a screening.
    pub(crate) fn too_few_motions(usable: usize) -> Self {
        HandEyeError::TooFewMotions {
            usable,
            needed: 2,
            rejected_small: 0,
            rejected_half_turn: 0,
        }
    }
}
