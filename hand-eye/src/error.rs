//! The crate's error type: every way the input can fail to determine the transform.

use std::fmt;

use nalgebra::Vector3;

/// Which of the two sensors a pose or a motion belongs to (see the crate docs for `a` and `b`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
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
        unobservable: Unobservable,
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
        step: NullSpaceStep,
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
    #[error("invalid option: {}", invalid_option(*.field, *.value))]
    InvalidOptions {
        /// The field.
        field: OptionField,
        /// Its value, in the field's unit (radians for angles).
        value: f64,
    },
    /// A [`crate::Pairing::Window`] of size zero, which pairs no poses.
    #[error("Pairing::Window {{ size: {size} }} pairs no poses: the size must be at least 1")]
    InvalidWindow {
        /// The size given.
        size: usize,
    },
    /// A numerical decomposition did not converge (this should not happen on finite input).
    #[error("the {what} did not converge")]
    NoConvergence {
        /// The decomposition.
        what: Decomposition,
    },
}

/// Shorthand for the crate's results: `Result<T>` is `Result<T, HandEyeError>`.
pub type Result<T, E = HandEyeError> = std::result::Result<T, E>;

/// What a degenerate motion set leaves undetermined ([`HandEyeError::Degenerate`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Unobservable {
    /// The rotation of `X` (Daniilidis: rotations too small for the noise).
    Rotation,
    /// The translation of `X` (Daniilidis: rotations too small for the noise).
    Translation,
    /// The roll and pitch of `X` (planar method: rotations too small for the noise).
    RollPitch,
    /// The in-plane translation of `X` (planar method: sensor `b` never rotates).
    InPlaneTranslation,
    /// The yaw of `X` (planar method: sensor `a` does not translate).
    Yaw,
}

impl fmt::Display for Unobservable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Unobservable::Rotation => "the rotation of X (rotations too small for the noise)",
            Unobservable::Translation => "the translation of X (rotations too small for the noise)",
            Unobservable::RollPitch => {
                "the roll and pitch of X (rotations too small for the noise)"
            }
            Unobservable::InPlaneTranslation => {
                "the in-plane translation of X (sensor b never rotates)"
            }
            Unobservable::Yaw => "the yaw of X (sensor a does not translate)",
        })
    }
}

/// The null-space step whose quadratic constraint failed ([`HandEyeError::NegativeDiscriminant`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum NullSpaceStep {
    /// Daniilidis: the unit dual quaternion in the null space (`q·q' = 0`).
    DualQuaternion,
    /// Planar method: the roll-pitch quaternion mapping an axis of `a` into the `xz` plane of `b`.
    RollPitch,
}

impl fmt::Display for NullSpaceStep {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            NullSpaceStep::DualQuaternion => "dual-quaternion null space (q·q' = 0)",
            NullSpaceStep::RollPitch => "roll-pitch null space (axis of a in the xz plane of b)",
        })
    }
}

/// A decomposition that did not converge ([`HandEyeError::NoConvergence`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Decomposition {
    /// The singular value decomposition of Daniilidis' system.
    DaniilidisSvd,
    /// The eigen-decomposition of the planar method's roll-pitch system.
    RollPitchEigen,
    /// The Cholesky factor of a pose's residual covariance ([`crate::NoiseModel`]).
    NoiseCovariance,
}

impl fmt::Display for Decomposition {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Decomposition::DaniilidisSvd => "singular value decomposition of the Daniilidis system",
            Decomposition::RollPitchEigen => "eigen-decomposition of the roll-pitch system",
            Decomposition::NoiseCovariance => "factorization of the residual covariance of a pose",
        })
    }
}

/// An options field, named by [`HandEyeError::InvalidOptions`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum OptionField {
    /// [`crate::MotionScreening::min_rotation`].
    MinRotation,
    /// [`crate::MotionScreening::max_rotation`].
    MaxRotation,
    /// [`crate::DaniilidisOptions::min_signal_to_noise`].
    DaniilidisMinSignalToNoise,
    /// [`crate::PlanarOptions::min_signal_to_noise`].
    PlanarMinSignalToNoise,
    /// [`crate::PlanarOptions::max_out_of_plane`].
    PlanarMaxOutOfPlane,
    /// [`crate::PlanarOptions::height_prior`].
    HeightPrior,
    /// [`crate::TrajectoryOptions::max_out_of_plane`].
    TrajectoryMaxOutOfPlane,
    /// [`crate::TrajectoryOptions::initial_scale`].
    InitialScale,
    /// [`crate::RefineOptions::rotation_sigma`].
    RotationSigma,
    /// [`crate::RefineOptions::translation_sigma`].
    TranslationSigma,
    /// [`crate::PoseNoise::rotation`] of the given sensor in [`crate::NoiseModel::Both`].
    NoiseRotation(Sensor),
    /// [`crate::PoseNoise::translation`] of the given sensor in [`crate::NoiseModel::Both`].
    NoiseTranslation(Sensor),
}

/// `field = value, must be domain`, the value in degrees or metres.
fn invalid_option(field: OptionField, value: f64) -> String {
    format!(
        "{field} = {}, must be {}",
        field.format(value),
        field.domain()
    )
}

/// The unit a field's value is shown in.
enum Unit {
    Degrees,
    Metres,
    None,
}

impl OptionField {
    fn unit(self) -> Unit {
        match self {
            OptionField::MinRotation
            | OptionField::MaxRotation
            | OptionField::PlanarMaxOutOfPlane
            | OptionField::TrajectoryMaxOutOfPlane
            | OptionField::RotationSigma
            | OptionField::NoiseRotation(_) => Unit::Degrees,
            OptionField::HeightPrior
            | OptionField::TranslationSigma
            | OptionField::NoiseTranslation(_) => Unit::Metres,
            OptionField::DaniilidisMinSignalToNoise
            | OptionField::PlanarMinSignalToNoise
            | OptionField::InitialScale => Unit::None,
        }
    }

    /// A value of the field (radians for angles) in its display unit.
    fn format(self, value: f64) -> String {
        match self.unit() {
            Unit::Degrees => format!("{:.3} deg", value.to_degrees()),
            Unit::Metres => format!("{value:.4} m"),
            Unit::None => format!("{value}"),
        }
    }

    /// The valid domain of the field.
    fn domain(self) -> &'static str {
        match self {
            OptionField::MinRotation => "in [0, max_rotation)",
            OptionField::MaxRotation => "in (min_rotation, 180 deg]",
            OptionField::DaniilidisMinSignalToNoise | OptionField::PlanarMinSignalToNoise => {
                "non-negative"
            }
            OptionField::PlanarMaxOutOfPlane | OptionField::TrajectoryMaxOutOfPlane => {
                "finite and non-negative"
            }
            OptionField::HeightPrior => "finite",
            OptionField::InitialScale
            | OptionField::RotationSigma
            | OptionField::TranslationSigma
            | OptionField::NoiseRotation(_)
            | OptionField::NoiseTranslation(_) => "positive and finite",
        }
    }
}

impl fmt::Display for OptionField {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let sensor = |s: &Sensor| match s {
            Sensor::A => "a",
            Sensor::B => "b",
        };
        match self {
            OptionField::MinRotation => f.write_str("MotionScreening::min_rotation"),
            OptionField::MaxRotation => f.write_str("MotionScreening::max_rotation"),
            OptionField::DaniilidisMinSignalToNoise => {
                f.write_str("DaniilidisOptions::min_signal_to_noise")
            }
            OptionField::PlanarMinSignalToNoise => {
                f.write_str("PlanarOptions::min_signal_to_noise")
            }
            OptionField::PlanarMaxOutOfPlane => f.write_str("PlanarOptions::max_out_of_plane"),
            OptionField::HeightPrior => f.write_str("PlanarOptions::height_prior"),
            OptionField::TrajectoryMaxOutOfPlane => {
                f.write_str("TrajectoryOptions::max_out_of_plane")
            }
            OptionField::InitialScale => f.write_str("TrajectoryOptions::initial_scale"),
            OptionField::RotationSigma => f.write_str("RefineOptions::rotation_sigma"),
            OptionField::TranslationSigma => f.write_str("RefineOptions::translation_sigma"),
            OptionField::NoiseRotation(s) => {
                write!(f, "NoiseModel::Both {{ {}: rotation }}", sensor(s))
            }
            OptionField::NoiseTranslation(s) => {
                write!(f, "NoiseModel::Both {{ {}: translation }}", sensor(s))
            }
        }
    }
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
