//! The error type of relative pose (two-view geometry): every way a pair of bearing sets can
//! be unusable, and every numeric outcome that has no answer.

use nalgebra::UnitQuaternion;
use thiserror::Error;

/// Errors of the relative-pose solvers ([`crate::five_point`], [`crate::homography`],
/// [`crate::relative_pose`], [`crate::refine_relative_pose`]). Caller input never causes a
/// panic: every unusable input, and every computation without an answer, is one of these.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum RelativePoseError {
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
    /// The two bearing slices differ in length.
    #[error("{a} bearings in view a but {b} in view b: they must pair up one to one")]
    LengthMismatch {
        /// Number of bearings of view a.
        a: usize,
        /// Number of bearings of view b.
        b: usize,
    },
    /// A bearing has a NaN or infinite coordinate.
    #[error("bearing {index} of view {view} has a non-finite coordinate")]
    NonFiniteBearing {
        /// The view, `'a'` or `'b'`.
        view: char,
        /// Index of the offending bearing.
        index: usize,
    },
    /// A bearing is not a unit vector.
    #[error(
        "bearing {index} of view {view} has norm {norm}, but bearings must be unit vectors (|norm - 1| <= {tolerance})"
    )]
    NonUnitBearing {
        /// The view, `'a'` or `'b'`.
        view: char,
        /// Index of the offending bearing.
        index: usize,
        /// Its Euclidean norm.
        norm: f64,
        /// The accepted deviation from 1 ([`crate::UNIT_NORM_TOLERANCE`]).
        tolerance: f64,
    },
    /// The input geometry does not determine a relative pose (named in the message).
    #[error("degenerate input: {0}")]
    Degenerate(&'static str),
    /// No model explains the correspondences: a minimal solver found no real solution with
    /// positive depths, or RANSAC found fewer inliers than required.
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
    /// The inliers see the scene under too small an angle to determine the translation: the
    /// median triangulation angle of the inliers is below the `min_parallax` option. The
    /// rotation is still determined and is given.
    #[error(
        "too little parallax: the median triangulation angle of the inliers is {median_parallax_deg:.3} deg, below the {minimum_deg:.3} deg required; the rotation is determined, the translation is not"
    )]
    InsufficientParallax {
        /// Median triangulation angle of the inliers, degrees.
        median_parallax_deg: f64,
        /// The `min_parallax` option, degrees.
        minimum_deg: f64,
        /// The estimated rotation of `b_from_a`.
        rotation: UnitQuaternion<f64>,
        /// The inliers (indices into the caller's slices).
        inliers: Vec<usize>,
    },
    /// An option is outside its valid range.
    #[error("invalid option `{name}`: {reason}")]
    InvalidOption {
        /// The option's field name.
        name: &'static str,
        /// What was wrong with it.
        reason: String,
    },
    /// A computation produced a non-finite number or a singular system.
    #[error("numerical failure: {0}")]
    Numerical(&'static str),
}

/// `Result` with [`RelativePoseError`] as the error.
pub type RelativeResult<T> = Result<T, RelativePoseError>;

/// Checks counts, lengths, finiteness and unit norms of two bearing sets.
pub(crate) fn check_bearing_pairs(
    solver: &'static str,
    needed: usize,
    a: &[nalgebra::Vector3<f64>],
    b: &[nalgebra::Vector3<f64>],
) -> RelativeResult<()> {
    if a.len() != b.len() {
        return Err(RelativePoseError::LengthMismatch {
            a: a.len(),
            b: b.len(),
        });
    }
    if a.len() < needed {
        return Err(RelativePoseError::NotEnoughPoints {
            solver,
            needed,
            got: a.len(),
        });
    }
    for (index, (fa, fb)) in a.iter().zip(b).enumerate() {
        for (view, f) in [('a', fa), ('b', fb)] {
            if !f.iter().all(|v| v.is_finite()) {
                return Err(RelativePoseError::NonFiniteBearing { view, index });
            }
            let norm = f.norm();
            if (norm - 1.0).abs() > crate::UNIT_NORM_TOLERANCE {
                return Err(RelativePoseError::NonUnitBearing {
                    view,
                    index,
                    norm,
                    tolerance: crate::UNIT_NORM_TOLERANCE,
                });
            }
        }
    }
    Ok(())
}
