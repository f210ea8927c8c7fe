//! The crate's error type: every way an input can be unusable, and every numeric outcome that
//! has no answer.

use thiserror::Error;

/// `Result` with [`PnpError`] as the default error.
pub type Result<T, E = PnpError> = std::result::Result<T, E>;

/// Why a set of 2D-3D correspondences has no unique answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Degeneracy {
    /// All world points are the same point (relative spread below
    /// [`crate::COINCIDENT_TOLERANCE`]).
    CoincidentPoints,
    /// Two of the three world points of a P3P sample coincide.
    CoincidentPair {
        /// Index of the first point of the pair.
        first: usize,
        /// Index of the second point of the pair.
        second: usize,
    },
    /// The world points lie on one line (second principal spread over the first below
    /// [`crate::COLLINEAR_TOLERANCE`]); the rotation about that line is unobservable.
    CollinearPoints,
    /// All bearings are parallel (or antiparallel): the rays are one line through the centre.
    ParallelBearings,
    /// Two bearings of a P3P sample are parallel or antiparallel.
    ParallelPair {
        /// Index of the first bearing of the pair.
        first: usize,
        /// Index of the second bearing of the pair.
        second: usize,
    },
}

impl core::fmt::Display for Degeneracy {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::CoincidentPoints => write!(f, "all world points coincide"),
            Self::CoincidentPair { first, second } => {
                write!(f, "world points {first} and {second} coincide")
            }
            Self::CollinearPoints => write!(
                f,
                "the world points are collinear, so the rotation about their line is unobservable"
            ),
            Self::ParallelBearings => write!(f, "all bearings are parallel (one ray)"),
            Self::ParallelPair { first, second } => {
                write!(f, "bearings {first} and {second} are parallel")
            }
        }
    }
}

/// Errors of `ibc-pnp`. Caller input never causes a panic: every unusable input, and every
/// computation without an answer, is one of these.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum PnpError {
    /// Fewer correspondences than the solver needs.
    #[error("{solver} needs at least {needed} correspondences, got {got}")]
    NotEnoughPoints {
        /// The solver that refused the input.
        solver: &'static str,
        /// The minimum number of correspondences.
        needed: usize,
        /// The number given.
        got: usize,
    },
    /// The bearing and world-point slices differ in length.
    #[error("{bearings} bearings but {points} world points: they must pair up one to one")]
    LengthMismatch {
        /// Number of bearings given.
        bearings: usize,
        /// Number of world points given.
        points: usize,
    },
    /// A bearing has a NaN or infinite coordinate.
    #[error("bearing {index} has a non-finite coordinate")]
    NonFiniteBearing {
        /// Index of the offending bearing.
        index: usize,
    },
    /// A world point has a NaN or infinite coordinate.
    #[error("world point {index} has a non-finite coordinate")]
    NonFinitePoint {
        /// Index of the offending point.
        index: usize,
    },
    /// A bearing is not a unit vector.
    #[error(
        "bearing {index} has norm {norm}, but bearings must be unit vectors (|norm - 1| <= {tolerance})"
    )]
    NonUnitBearing {
        /// Index of the offending bearing.
        index: usize,
        /// Its Euclidean norm.
        norm: f64,
        /// The accepted deviation from 1 ([`crate::UNIT_NORM_TOLERANCE`]).
        tolerance: f64,
    },
    /// The input geometry does not determine a pose.
    #[error("degenerate input: {0}")]
    Degenerate(Degeneracy),
    /// The equations of a minimal solver have no real solution with positive depths.
    #[error("no real solution: {0}")]
    NoSolution(&'static str),
    /// RANSAC found fewer inliers than required.
    #[error(
        "only {found} inliers among {total} correspondences, fewer than the {required} required"
    )]
    TooFewInliers {
        /// Inliers of the best model found (0 if no sample gave a model).
        found: usize,
        /// The `min_inliers` option.
        required: usize,
        /// Number of correspondences given.
        total: usize,
    },
    /// An option is outside its valid range.
    #[error("invalid option `{name}`: {reason}")]
    InvalidOption {
        /// The option's field name.
        name: &'static str,
        /// What was wrong with it.
        reason: String,
    },
    /// The camera cannot unproject a pixel, in a function of one pixel: the principal point
    /// for [`crate::angle_from_pixels_at`] and [`crate::absolute_pose`] (which counts the
    /// correspondences whose pixel cannot be unprojected as outliers instead), the pixel of
    /// [`crate::bearing_information`].
    #[error("the camera cannot unproject the pixel: {0}")]
    Unprojection(#[from] ibc_camera_models::UnprojectionError),
    /// A robust loss's scale is not finite and positive.
    #[error("the scale of the robust loss must be finite and positive, got {scale}")]
    InvalidLossScale {
        /// The scale given.
        scale: f64,
    },
    /// The pixel and world-point slices of [`crate::absolute_pose`] differ in length.
    #[error("{pixels} pixels but {points} world points: they must pair up one to one")]
    PixelLengthMismatch {
        /// Number of pixels given.
        pixels: usize,
        /// Number of world points given.
        points: usize,
    },
    /// A pixel has a NaN or infinite coordinate.
    #[error("pixel {index} has a non-finite coordinate")]
    NonFinitePixel {
        /// Index of the offending pixel.
        index: usize,
    },
    /// Too few pixels of [`crate::absolute_pose`] could be unprojected by the camera to
    /// determine a pose.
    #[error(
        "only {unprojected} of {total} pixels could be unprojected by the camera, fewer than the {needed} needed"
    )]
    TooFewUnprojected {
        /// Pixels the camera unprojected.
        unprojected: usize,
        /// The minimum number of correspondences.
        needed: usize,
        /// Number of pixels given.
        total: usize,
    },
    /// The information of a bearing is undefined: the camera's d ray / d pixel is singular
    /// or not finite at the pixel.
    #[error("d ray / d pixel of the camera is singular or not finite at pixel ({u}, {v})")]
    SingularUnprojectionJacobian {
        /// The pixel's first coordinate.
        u: f64,
        /// The pixel's second coordinate.
        v: f64,
    },
    /// A computation produced a non-finite number or a singular system.
    #[error("numerical failure: {0}")]
    Numerical(&'static str),
}
