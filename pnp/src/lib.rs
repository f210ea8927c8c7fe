#![doc = include_str!("../README.md")]

#[cfg(feature = "camera-models")]
mod camera_threshold;
mod epnp;
mod epnp_sums;
mod error;
mod geometry;
mod p3p;
mod ransac;
mod refine;
mod small_linear;
mod symmetric_eigen;
mod threshold;
mod validate;

#[cfg(feature = "camera-models")]
pub use camera_threshold::angle_from_pixels_at;
pub use epnp::{
    EPNP_MIN_POINTS, EpnpOptions, NEAR_PLANAR_FLATNESS, PLANAR_FLATNESS, epnp, epnp_with,
};
pub use error::{Degeneracy, PnpError};
pub use p3p::{P3P_MAX_SOLUTIONS, P3pSolutions, p3p};
pub use ransac::{
    CAMODOCAL_ITERATIONS, CAMODOCAL_THRESHOLD_PX, DEFAULT_MIN_INLIERS, DEFAULT_THRESHOLD,
    RansacOptions, RobustPose, robust_pose,
};
pub use refine::{
    REFINE_MIN_POINTS, RefineOptions, RefinedPose, RobustLoss, pinhole_information, refine_pose,
    refine_pose_weighted,
};
pub use threshold::angle_from_pixels;
pub use validate::{
    COINCIDENT_TOLERANCE, COLLINEAR_TOLERANCE, PARALLEL_TOLERANCE, UNIT_NORM_TOLERANCE,
};
