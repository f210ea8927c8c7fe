//! Corners that do not fit: an iteratively reweighted refinement with Cauchy weights, then the
//! outlier corners excluded and the inliers refined alone.
//!
//! A corner detector sometimes returns a wrong corner (a reflection, a mismatched index) or
//! a whole view of garbage (a board that was not found, a wrong ordering). In a plain least
//! squares refinement a few wrong corners move the focal length by several standard
//! deviations, and one garbage view drags every parameter. So:
//!
//! 1. The refinement runs on every corner. If every residual is within the outlier bound
//!    below, that is the result (clean data costs one solve, as before).
//! 2. Otherwise it is repeated [`IRLS_ITERATIONS`] times with each corner weighted by the
//!    Cauchy weight `1 / (1 + (|r| / (c sigma))^2)`, `c = `[`CAUCHY_TUNING`], `sigma` the
//!    robust spread `1.4826 median |r|` of the residual coordinates (iteratively reweighted
//!    least squares; Holland and Welsch, "Robust regression using iteratively reweighted
//!    least-squares", 1977).
//! 3. A corner is an outlier when its residual exceeds
//!    `max(`[`OUTLIER_SIGMAS`]` sigma, `[`MIN_OUTLIER_PX`]`)`; an image left with fewer than
//!    half its corners, or fewer than [`super::MIN_CORNERS_PER_IMAGE`], is excluded whole.
//! 4. The inliers are refined alone, unweighted, so that the covariance is the plain least
//!    squares one of the corners kept.

use ibc_bundle_adjust::SolverOptions;
use ibc_camera_models::Camera;
use nalgebra::{Isometry3, Vector2};

use super::board_pose::{ImageCorrespondences, board_pose};
use super::calibrate::{IntrinsicModel, MIN_CORNERS_PER_IMAGE};
use super::error::IntrinsicsError;
use super::refine::{Refined, refine};
use ibc_camera_models::CameraModel;

/// The Cauchy loss's tuning constant for 95% efficiency on Gaussian noise (Holland and
/// Welsch, 1977), in units of the robust spread.
pub const CAUCHY_TUNING: f64 = 2.385;

/// Reweighted refinements when some corner is an outlier.
pub const IRLS_ITERATIONS: usize = 3;

/// A corner whose residual exceeds this many robust spreads is an outlier: a Gaussian
/// residual (per coordinate `sigma`) exceeds `5 sigma` in length with probability
/// `exp(-12.5) = 4e-6`.
pub const OUTLIER_SIGMAS: f64 = 5.0;

/// ... and in any case only when it exceeds this many pixels (noise-free or very precise
/// corners have a tiny spread, against which rounding would make outliers).
pub const MIN_OUTLIER_PX: f64 = 0.5;

/// An image is excluded whole when fewer than this share of its corners are inliers.
pub const MIN_INLIER_SHARE: f64 = 0.5;

/// The outcome of [`robust_refine`].
pub(crate) struct RobustRefined {
    /// The final (unweighted) refinement on the inliers of the images kept.
    pub refined: Refined,
    /// Which images were kept (an excluded image has too few inliers).
    pub kept: Vec<bool>,
    /// Per image, per corner: an inlier of the final refinement (false for every corner of an
    /// excluded image).
    pub inliers: Vec<Vec<bool>>,
    /// The outlier bound, pixels.
    pub outlier_px: f64,
}

/// `1.4826 median |r|` over both coordinates of the finite residuals.
fn robust_spread(residuals: &[Vec<Vector2<f64>>]) -> f64 {
    let mut values: Vec<f64> = residuals
        .iter()
        .flatten()
        .filter(|r| r.x.is_finite() && r.y.is_finite())
        .flat_map(|r| [r.x.abs(), r.y.abs()])
        .collect();
    if values.is_empty() {
        return f64::NAN;
    }
    let mid = values.len() / 2;
    let (_, m, _) = values.select_nth_unstable_by(mid, f64::total_cmp);
    1.482_602_218_505_602 * *m
}

/// Every corner's residual (infinite where it does not project).
fn residuals(
    camera: &Camera,
    poses: &[Isometry3<f64>],
    data: &[ImageCorrespondences],
) -> Vec<Vec<Vector2<f64>>> {
    data.iter()
        .zip(poses)
        .map(|((points, pixels), pose)| {
            points
                .iter()
                .zip(pixels)
                .map(|(x, obs)| {
                    camera
                        .project(&(pose * x).coords)
                        .map_or(Vector2::repeat(f64::INFINITY), |p| p - obs)
                })
                .collect()
        })
        .collect()
}

/// The steps of the module docs, from an initial camera and board poses.
pub(crate) fn robust_refine(
    model: IntrinsicModel,
    (width, height): (u32, u32),
    initial: &[f64],
    initial_poses: &[Isometry3<f64>],
    data: &[ImageCorrespondences],
    options: &SolverOptions,
) -> Result<RobustRefined, IntrinsicsError> {
    let camera_of = |r: &Refined| model.camera(width, height, &r.params);
    let mut current = refine(
        model,
        (width, height),
        initial,
        initial_poses,
        data,
        None,
        options,
    )?;
    let mut r = residuals(&camera_of(&current)?, &current.camera_from_board, data);
    let mut sigma = robust_spread(&r);
    let bound = |sigma: f64| (OUTLIER_SIGMAS * sigma).max(MIN_OUTLIER_PX);
    let all_inside = r.iter().flatten().all(|e| e.norm() <= bound(sigma));
    if all_inside {
        return Ok(RobustRefined {
            refined: current,
            kept: vec![true; data.len()],
            inliers: data.iter().map(|(p, _)| vec![true; p.len()]).collect(),
            outlier_px: bound(sigma),
        });
    }
    for _ in 0..IRLS_ITERATIONS {
        let scale = CAUCHY_TUNING * sigma.max(MIN_OUTLIER_PX / OUTLIER_SIGMAS);
        let weights: Vec<Vec<f64>> = r
            .iter()
            .map(|image| {
                image
                    .iter()
                    .map(|e| {
                        let u = e.norm() / scale;
                        if u.is_finite() {
                            1.0 / (1.0 + u * u)
                        } else {
                            0.0
                        }
                    })
                    .collect()
            })
            .collect();
        current = refine(
            model,
            (width, height),
            &current.params,
            &current.camera_from_board,
            data,
            Some(&weights),
            options,
        )?;
        r = residuals(&camera_of(&current)?, &current.camera_from_board, data);
        // The spread of the corners the weights trust: the inliers at the last bound.
        let inside: Vec<Vec<Vector2<f64>>> = r
            .iter()
            .map(|image| {
                image
                    .iter()
                    .copied()
                    .filter(|e| e.norm() <= bound(sigma))
                    .collect()
            })
            .collect();
        sigma = robust_spread(&inside);
    }
    let outlier_px = bound(sigma);
    let mut inliers: Vec<Vec<bool>> = r
        .iter()
        .map(|image| image.iter().map(|e| e.norm() <= outlier_px).collect())
        .collect();
    let kept: Vec<bool> = inliers
        .iter()
        .map(|image| {
            let n = image.iter().filter(|&&i| i).count();
            n >= MIN_CORNERS_PER_IMAGE && n as f64 >= MIN_INLIER_SHARE * image.len() as f64
        })
        .collect();
    for (image, &k) in inliers.iter_mut().zip(&kept) {
        if !k {
            image.iter_mut().for_each(|i| *i = false);
        }
    }
    // The inliers of the images kept, refined alone and unweighted.
    let (kept_data, kept_poses): (Vec<ImageCorrespondences>, Vec<Isometry3<f64>>) = data
        .iter()
        .zip(&inliers)
        .zip(&current.camera_from_board)
        .filter(|((_, inl), _)| inl.iter().any(|&i| i))
        .map(|(((points, pixels), inl), pose)| {
            let (points, pixels) = points
                .iter()
                .zip(pixels)
                .zip(inl)
                .filter(|(_, i)| **i)
                .map(|((x, p), _)| (*x, *p))
                .unzip();
            ((points, pixels), *pose)
        })
        .unzip();
    if kept_data.len() < super::MIN_IMAGES {
        return Err(IntrinsicsError::TooFewImages {
            got: kept_data.len(),
            needed: super::MIN_IMAGES,
        });
    }
    let mut refined = refine(
        model,
        (width, height),
        &current.params,
        &kept_poses,
        &kept_data,
        None,
        options,
    )?;
    // Board poses of every input image again: the kept ones from the final refinement, an
    // excluded one re-estimated with the final camera (for its residuals in the report).
    let camera = camera_of(&refined)?;
    let mut final_poses = refined.camera_from_board.iter();
    let mut all_poses = Vec::with_capacity(data.len());
    for (((points, pixels), &k), old) in data.iter().zip(&kept).zip(&current.camera_from_board) {
        let pose = if k {
            final_poses.next().copied().unwrap_or(*old)
        } else {
            board_pose(&camera, points, pixels, true).unwrap_or(*old)
        };
        all_poses.push(pose);
    }
    refined.camera_from_board = all_poses;
    Ok(RobustRefined {
        refined,
        kept,
        inliers,
        outlier_px,
    })
}
