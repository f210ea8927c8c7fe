#![doc = include_str!("../README.md")]

mod absolute_pose;
mod camera_threshold;
mod epnp;
mod epnp_sums;
mod error;
mod five_point;
mod geometry;
mod homography;
mod information;
mod loss;
mod p3p;
mod prosac;
mod ransac;
mod refine;
mod relative_pose;
mod relative_pose_error;
mod small_linear;
mod symmetric_eigen;
mod threshold;
mod triangulation;
mod validate;

/// The linear-algebra crate of this crate's API (`Isometry3`, `Point3`, `Vector3`, ...), so
/// callers can use the very version it was built with.
pub use nalgebra;

pub use absolute_pose::{
    ABSOLUTE_POSE_MIN_POINTS, AbsolutePose, AbsolutePoseOptions, DEFAULT_MAX_ERROR_PX,
    absolute_pose,
};
pub use camera_threshold::angle_from_pixels_at;
pub use epnp::{
    EPNP_MIN_POINTS, EpnpOptions, NEAR_PLANAR_FLATNESS, PLANAR_FLATNESS, epnp, epnp_with,
};
pub use error::{Degeneracy, PnpError, Result};
pub use five_point::{
    EssentialSolutions, FIVE_POINT_MAX_SOLUTIONS, decompose_essential, essential_from_pose,
    five_point, pose_from_essential,
};
pub use homography::{
    HOMOGRAPHY_MIN_POINTS, PURE_ROTATION_TOLERANCE, PlanarPose, decompose_homography, homography,
};
pub use information::{bearing_information, pinhole_information};
pub use loss::RobustLoss;
pub use p3p::{P3P_MAX_SOLUTIONS, P3pSolutions, p3p};
pub use ransac::{
    CAMODOCAL_ITERATIONS, CAMODOCAL_THRESHOLD_PX, DEFAULT_MIN_INLIERS, DEFAULT_THRESHOLD,
    RansacOptions, RobustPose, robust_pose,
};
pub use refine::{
    REFINE_MIN_POINTS, RefineOptions, RefinedPose, refine_pose, refine_pose_weighted,
};
pub use relative_pose::{
    GricScores, RELATIVE_POSE_MAX_ITERATIONS, RELATIVE_POSE_MIN_PARALLAX, RELATIVE_POSE_MIN_POINTS,
    RefinedRelativePose, RelativePose, RelativePoseOptions, TwoViewModel, refine_relative_pose,
    relative_pose, relative_pose_inliers,
};
pub use relative_pose_error::{RelativePoseError, RelativeResult};
pub use threshold::angle_from_pixels;
pub use triangulation::{
    TRIANGULATION_MIN_PARALLAX, TRIANGULATION_MIN_VIEWS, TriangulatedPoint, TriangulationError,
    TriangulationOptions, TwoViewPoint, depths_along_bearings, refine_point, triangulate,
    triangulate_two_view,
};
pub use validate::{
    COINCIDENT_TOLERANCE, COLLINEAR_TOLERANCE, PARALLEL_TOLERANCE, UNIT_NORM_TOLERANCE,
};

/// The last field of every options struct of this crate (`non_exhaustive`), set by the
/// struct's `Default`.
///
/// Code outside the crate cannot make one, so it writes an options struct as
/// `RansacOptions { seed: 7, ..Default::default() }`: fields can then be added without
/// breaking it, as `#[non_exhaustive]` would guarantee, while the one-expression form stays
/// possible (the pattern of faer's parameter structs).
#[doc(hidden)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct NonExhaustive(());

impl NonExhaustive {
    /// The marker, for this crate's `Default` impls.
    pub(crate) const VALUE: Self = Self(());
}
