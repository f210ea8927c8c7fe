//! Robust absolute pose from a camera, pixels and world points: the entry point at the level
//! of the caller's data, as PoseLib's `estimate_absolute_pose` (V. Larsson and contributors,
//! PoseLib, `AbsolutePoseOptions { ransac, bundle, max_error }`) and kornia's PnP take pixels
//! and a camera.
//!
//! It composes the crate's pieces: each pixel is unprojected to a unit bearing by the camera
//! (any `ibc-camera-models` model, rays beyond 90 degrees included), a pixel the camera cannot
//! unproject counts as an outlier, the pixel threshold becomes an angle at the principal
//! point ([`crate::angle_from_pixels_at`]), and [`crate::robust_pose`] (RANSAC over P3P with
//! MSAC scoring, local optimization and a final refit; Fischler-Bolles 1981,
//! Torr-Zisserman 2000, Chum-Matas-Kittler 2003) solves the rest. Inliers are reported as
//! indices into the caller's slices.

use ibc_camera_models::CameraModel;
use nalgebra::{Isometry3, Point3, Vector2, Vector3};

use crate::NonExhaustive;
use crate::camera_threshold::angle_from_pixels_at;
use crate::error::{PnpError, Result};
use crate::ransac::{RansacOptions, robust_pose};
use crate::threshold::check_positive;

/// Default inlier threshold of [`absolute_pose`], pixels: 2, the localization threshold of
/// the ibc pipeline (and CamOdoCal's, [`crate::CAMODOCAL_THRESHOLD_PX`]).
pub const DEFAULT_MAX_ERROR_PX: f64 = 2.0;

/// The fewest correspondences [`absolute_pose`] takes: the three of a P3P sample.
pub const ABSOLUTE_POSE_MIN_POINTS: usize = 3;

/// Options of [`absolute_pose`]: the RANSAC and refinement options nested, and the inlier
/// threshold in pixels. Write them in one expression,
/// `AbsolutePoseOptions { max_error_px: 1.5, ..Default::default() }`.
#[derive(Debug, Clone, PartialEq)]
pub struct AbsolutePoseOptions {
    /// RANSAC options (with the refinement of the final refit, [`RansacOptions::refine`]),
    /// except `threshold`, which [`absolute_pose`] sets from `max_error_px`. Default
    /// [`RansacOptions::default`].
    pub ransac: RansacOptions,
    /// Inlier threshold, pixels: the largest reprojection error of an inlier. Turned into the
    /// angle that many pixels span at the camera's principal point, in the direction where
    /// it spans the most ([`crate::angle_from_pixels_at`]), which becomes
    /// [`RansacOptions::threshold`]; it must span less than 90 degrees. Default
    /// [`DEFAULT_MAX_ERROR_PX`] (2 px).
    pub max_error_px: f64,
    /// Keeps the struct open to new fields: write it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl AbsolutePoseOptions {
    /// Checks every option's range (the RANSAC options' and `max_error_px > 0`); the angle
    /// `max_error_px` spans is checked per camera by [`absolute_pose`].
    ///
    /// # Errors
    /// [`PnpError::InvalidOption`] or [`PnpError::InvalidLossScale`] naming the option.
    pub fn validate(&self) -> Result<()> {
        check_positive("max_error_px", self.max_error_px)?;
        self.ransac.validate()
    }
}

impl Default for AbsolutePoseOptions {
    fn default() -> Self {
        Self {
            ransac: RansacOptions::default(),
            max_error_px: DEFAULT_MAX_ERROR_PX,
            non_exhaustive: NonExhaustive::VALUE,
        }
    }
}

/// The outcome of [`absolute_pose`].
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct AbsolutePose {
    /// The estimated `camera_from_world`.
    pub camera_from_world: Isometry3<f64>,
    /// Indices (increasing) into the caller's `pixels` and `world_points` of the
    /// correspondences within the threshold of the final pose.
    pub inliers: Vec<usize>,
    /// How many pixels the camera could not unproject (beyond a fisheye's fold, outside a
    /// model's domain); they are outliers, never in `inliers`.
    pub unprojection_failures: usize,
    /// RANSAC iterations (samples) drawn.
    pub iterations: usize,
    /// Root mean square of the inliers' angular errors, radians.
    pub inlier_rms: f64,
    /// The angular inlier threshold `max_error_px` became, radians.
    pub threshold: f64,
}

/// Robust camera pose from the pixels of a camera and their world points: unprojects each
/// pixel, counts the ones the camera cannot unproject as outliers, and runs
/// [`crate::robust_pose`] on the rest with the threshold `options.max_error_px` (see the
/// module docs and [`AbsolutePoseOptions`]). `pixels[i]` is the image of `world_points[i]`;
/// the returned inliers index both.
///
/// # Errors
/// [`PnpError::PixelLengthMismatch`], [`PnpError::NotEnoughPoints`] (fewer than
/// [`ABSOLUTE_POSE_MIN_POINTS`]), [`PnpError::NonFinitePixel`] and
/// [`PnpError::NonFinitePoint`] (with the caller's index), [`PnpError::InvalidOption`] for
/// `max_error_px` and the other options, [`PnpError::InvalidLossScale`],
/// [`PnpError::Unprojection`] if the camera cannot unproject its principal point,
/// [`PnpError::TooFewUnprojected`] if fewer than three pixels can be unprojected, then the
/// errors of [`crate::robust_pose`]: [`PnpError::Degenerate`] and [`PnpError::TooFewInliers`]
/// (whose `total` is `pixels.len()`).
pub fn absolute_pose<C: CameraModel + ?Sized>(
    camera: &C,
    pixels: &[Vector2<f64>],
    world_points: &[Point3<f64>],
    options: &AbsolutePoseOptions,
) -> Result<AbsolutePose> {
    if pixels.len() != world_points.len() {
        return Err(PnpError::PixelLengthMismatch {
            pixels: pixels.len(),
            points: world_points.len(),
        });
    }
    let total = pixels.len();
    if total < ABSOLUTE_POSE_MIN_POINTS {
        return Err(PnpError::NotEnoughPoints {
            solver: "absolute pose",
            needed: ABSOLUTE_POSE_MIN_POINTS,
            got: total,
        });
    }
    for (index, (pixel, point)) in pixels.iter().zip(world_points).enumerate() {
        if !pixel.iter().all(|v| v.is_finite()) {
            return Err(PnpError::NonFinitePixel { index });
        }
        if !point.coords.iter().all(|v| v.is_finite()) {
            return Err(PnpError::NonFinitePoint { index });
        }
    }
    let threshold = pixel_threshold(camera, options.max_error_px)?;
    let ransac = RansacOptions {
        threshold,
        ..options.ransac.clone()
    };
    ransac.validate()?;

    let mut bearings: Vec<Vector3<f64>> = Vec::with_capacity(total);
    let mut points: Vec<Point3<f64>> = Vec::with_capacity(total);
    // `used[k]` is the caller's index of correspondence `k` handed to `robust_pose`.
    let mut used: Vec<usize> = Vec::with_capacity(total);
    for (index, (pixel, point)) in pixels.iter().zip(world_points).enumerate() {
        if let Ok(ray) = camera.unproject_fast(pixel) {
            bearings.push(ray.into_inner());
            points.push(*point);
            used.push(index);
        }
    }
    let unprojection_failures = total - used.len();
    if used.len() < ABSOLUTE_POSE_MIN_POINTS {
        return Err(PnpError::TooFewUnprojected {
            unprojected: used.len(),
            needed: ABSOLUTE_POSE_MIN_POINTS,
            total,
        });
    }
    let pose = robust_pose(&bearings, &points, &ransac).map_err(|e| to_caller(e, &used, total))?;
    Ok(AbsolutePose {
        camera_from_world: pose.camera_from_world,
        inliers: pose.inliers.iter().map(|&k| used[k]).collect(),
        unprojection_failures,
        iterations: pose.iterations,
        inlier_rms: pose.inlier_rms,
        threshold,
    })
}

/// The angle `max_error_px` pixels span at the principal point, refused unless in
/// `(0, pi/2)`.
fn pixel_threshold<C: CameraModel + ?Sized>(camera: &C, max_error_px: f64) -> Result<f64> {
    check_positive("max_error_px", max_error_px)?;
    let angle = angle_from_pixels_at(camera, &camera.principal_point(), max_error_px)?;
    if angle > 0.0 && angle < core::f64::consts::FRAC_PI_2 {
        Ok(angle)
    } else {
        Err(PnpError::InvalidOption {
            name: "max_error_px",
            reason: format!(
                "{max_error_px} px span {angle} rad at the principal point, which must be in (0, pi/2)"
            ),
        })
    }
}

/// An error of [`robust_pose`] on the unprojected subset, with indices and counts turned
/// into the caller's.
fn to_caller(error: PnpError, used: &[usize], total: usize) -> PnpError {
    let index_of = |k: usize| used.get(k).copied().unwrap_or(k);
    match error {
        PnpError::TooFewInliers {
            found, required, ..
        } => PnpError::TooFewInliers {
            found,
            required,
            total,
        },
        PnpError::NonFiniteBearing { index } => PnpError::NonFiniteBearing {
            index: index_of(index),
        },
        PnpError::NonFinitePoint { index } => PnpError::NonFinitePoint {
            index: index_of(index),
        },
        PnpError::NonUnitBearing {
            index,
            norm,
            tolerance,
        } => PnpError::NonUnitBearing {
            index: index_of(index),
            norm,
            tolerance,
        },
        other => other,
    }
}
