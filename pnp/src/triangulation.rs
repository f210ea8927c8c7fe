//! Triangulation of a point from unit bearings seen by cameras of known pose, two views or
//! many: a linear estimate refined on the angular error, with the parallax and cheirality
//! checks a structure-from-motion pipeline needs.
//!
//! Every bearing `f_i` of camera `i` (`camera_from_world = (R_i, t_i)`) is turned into a ray of
//! the world frame, from the camera centre `c_i = -R_i^T t_i` along `d_i = R_i^T f_i`.
//!
//! - **Linear** (the multi-view midpoint): the point nearest to the rays' lines in the
//!   least-squares sense, `sum_i w_i (I - d_i d_i^T) (X - c_i) = 0`, a 3 x 3 positive definite
//!   system. It is the inhomogeneous form of the cross-product DLT on bearings,
//!   `[f_i]x (R_i X + t_i) = 0` (R. Hartley and A. Zisserman, "Multiple View Geometry in
//!   Computer Vision", 2nd edition, Cambridge, 2004, section 12.2), because
//!   `[f]x^T [f]x = I - f f^T` for a unit `f`. With `w_i = 1` it minimizes the distances to the
//!   lines; a second solve with `w_i = 1 / |X - c_i|^2` turns each distance into the angle it
//!   subtends, to first order, so the point moves nearer the ray of the nearer camera, where an
//!   angular error displaces it less. For two views the point then divides the rays' common
//!   perpendicular in the ratio that minimizes the sum of squared angles to first order; the
//!   same idea as the midpoint weighted by inverse depth of S. H. Lee and J. Civera,
//!   "Triangulation: Why Optimize?", BMVC 2019, whose closed form on bearings competes with the
//!   methods that minimize the reprojection error (in 3D error it can do better: the tests
//!   find the linear estimate's median 3D error within 2 % of the refined point's).
//! - **Refined**: Levenberg-Marquardt (Gauss-Newton steps, damped only as far as the cost
//!   needs) on `sum_i theta_i^2`, `theta_i` the angle between the ray `d_i` and the direction
//!   `u_i` of `X - c_i`: to first order the maximum-likelihood cost for isotropic angular noise
//!   on the bearings, at any incidence. The residual of view `i` is the tangent-plane vector
//!   `r_i = theta_i / sin(theta_i) (I - d_i d_i^T) u_i`, whose length is the angle itself, and
//!   its Jacobian is
//!   `dr_i/dX = [theta/sin (I - d d^T) - (sin - theta cos)/sin^3 (I - d d^T) u d^T] (I - u u^T) / |X - c_i|`
//!   (series in `theta` near 0).
//! - **Checks**: the parallax is the triangulation angle of COLMAP (J. L. Schönberger and
//!   J.-M. Frahm, "Structure-from-Motion Revisited", CVPR 2016): the angle between two rays'
//!   lines, folded into `[0, 90]` degrees, the largest over all pairs of views; it must be at
//!   least [`TriangulationOptions::min_parallax`] both between the observed rays (before any
//!   solve) and between the rays from the camera centres to the final point. Cheirality is
//!   decided along the bearing, `f_i . (R_i X + t_i) > 0`, never by `z > 0`, so a fisheye's
//!   rays beyond 90 degrees from the optical axis are triangulated like any other.

use core::f64::consts::FRAC_PI_2;

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use thiserror::Error;

use crate::NonExhaustive;
use crate::geometry::bearing_angle;
use crate::validate::{PARALLEL_TOLERANCE, UNIT_NORM_TOLERANCE};

/// The fewest views [`triangulate`] accepts.
pub const TRIANGULATION_MIN_VIEWS: usize = 2;

/// Default [`TriangulationOptions::min_parallax`], radians: 1.5 degrees, the minimum
/// triangulation angle of COLMAP's incremental triangulator (`IncrementalTriangulator::Options::
/// min_angle`). Below it a pixel of noise moves a point at 5 m by more than 15 cm along its ray
/// on a camera of focal length 800 px.
pub const TRIANGULATION_MIN_PARALLAX: f64 = 1.5 * (core::f64::consts::PI / 180.0);

/// Errors of triangulation: every unusable input and every configuration without a point in
/// front of the cameras. Caller input never causes a panic.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum TriangulationError {
    /// Fewer views than [`TRIANGULATION_MIN_VIEWS`].
    #[error("triangulation needs at least {needed} views, got {got}")]
    TooFewViews {
        /// The minimum number of views.
        needed: usize,
        /// The number given.
        got: usize,
    },
    /// The pose and bearing slices differ in length.
    #[error("{poses} camera poses but {bearings} bearings: they must pair up one to one")]
    LengthMismatch {
        /// Number of poses given.
        poses: usize,
        /// Number of bearings given.
        bearings: usize,
    },
    /// A bearing has a NaN or infinite coordinate (view 0 is `a` and view 1 is `b` for
    /// [`triangulate_two_view`]).
    #[error("the bearing of view {view} has a non-finite coordinate")]
    NonFiniteBearing {
        /// Index of the offending view.
        view: usize,
    },
    /// A bearing is not a unit vector.
    #[error(
        "the bearing of view {view} has norm {norm}, but bearings must be unit vectors (|norm - 1| <= {tolerance})"
    )]
    NonUnitBearing {
        /// Index of the offending view.
        view: usize,
        /// Its Euclidean norm.
        norm: f64,
        /// The accepted deviation from 1 ([`crate::UNIT_NORM_TOLERANCE`]).
        tolerance: f64,
    },
    /// A camera pose has a NaN or infinite entry (view 1 is `b_from_a` for
    /// [`triangulate_two_view`]).
    #[error("the pose of view {view} has a non-finite entry")]
    NonFinitePose {
        /// Index of the offending view.
        view: usize,
    },
    /// The rays are too close to parallel for a reliable depth: the point is too far for the
    /// baseline, or the cameras share a centre (a pure rotation).
    #[error(
        "the largest angle between two rays is {parallax_deg:.4} degrees, below the minimum parallax of {min_deg:.4} degrees",
        parallax_deg = .parallax.to_degrees(),
        min_deg = .min_parallax.to_degrees()
    )]
    TooLittleParallax {
        /// The largest angle between two rays' lines, radians in `[0, pi/2]`.
        parallax: f64,
        /// [`TriangulationOptions::min_parallax`].
        min_parallax: f64,
    },
    /// The point where the rays meet is behind a camera: its depth along that camera's bearing
    /// is not positive (the rays diverge, or a match is wrong).
    #[error(
        "the point is behind the camera of view {view}: its depth along the bearing is {depth} m"
    )]
    BehindCamera {
        /// Index of the first view with a depth that is not positive.
        view: usize,
        /// That depth, `f . (R X + t)`, metres.
        depth: f64,
    },
    /// An option (or the initial point of [`refine_point`]) is outside its valid range.
    #[error("invalid option `{name}`: {reason}")]
    InvalidOption {
        /// The option's name.
        name: &'static str,
        /// What was wrong with it.
        reason: String,
    },
    /// A computation produced a non-finite number.
    #[error("numerical failure: {0}")]
    Numerical(&'static str),
}

/// Options of [`triangulate`], [`triangulate_two_view`] and [`refine_point`]. Write them in one
/// expression, `TriangulationOptions { min_parallax: 0.05, ..Default::default() }`.
#[derive(Debug, Clone, PartialEq)]
pub struct TriangulationOptions {
    /// Smallest accepted parallax (see the module docs), radians in `[0, pi/2)`; 0 accepts any
    /// pair of rays that are not exactly parallel. Default [`TRIANGULATION_MIN_PARALLAX`] (1.5
    /// degrees).
    pub min_parallax: f64,
    /// Refine the linear estimate on the angular error. Default true; without it the result is
    /// the linear estimate, with `iterations = 0` and `converged = false`.
    pub refine: bool,
    /// Most Levenberg-Marquardt iterations. Default 20 (from the linear estimate, 2 to 5 are
    /// used).
    pub max_iterations: usize,
    /// The refinement has converged when a step moves the point by at most this angle, radians,
    /// as seen from the nearest camera (the step's length over the distance to that camera).
    /// Default `1e-10`: near the minimum each Gauss-Newton step shrinks by a factor of about
    /// the residual angles, so the point is then far closer than that to the minimum.
    pub step_tolerance: f64,
    /// Keeps the struct open to new fields: write it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for TriangulationOptions {
    fn default() -> Self {
        Self {
            min_parallax: TRIANGULATION_MIN_PARALLAX,
            refine: true,
            max_iterations: 20,
            step_tolerance: 1e-10,
            non_exhaustive: NonExhaustive::VALUE,
        }
    }
}

impl TriangulationOptions {
    /// Checks every option's range: `min_parallax` in `[0, pi/2)` and a finite, non-negative
    /// `step_tolerance`.
    ///
    /// # Errors
    /// [`TriangulationError::InvalidOption`] naming the option.
    pub fn validate(&self) -> Result<(), TriangulationError> {
        if !(self.min_parallax >= 0.0 && self.min_parallax < FRAC_PI_2) {
            return Err(TriangulationError::InvalidOption {
                name: "min_parallax",
                reason: format!(
                    "must be an angle in [0, pi/2) radians, got {}",
                    self.min_parallax
                ),
            });
        }
        if !(self.step_tolerance.is_finite() && self.step_tolerance >= 0.0) {
            return Err(TriangulationError::InvalidOption {
                name: "step_tolerance",
                reason: format!(
                    "must be finite and non-negative, got {}",
                    self.step_tolerance
                ),
            });
        }
        Ok(())
    }
}

/// A point triangulated from many views by [`triangulate`] or [`refine_point`].
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct TriangulatedPoint {
    /// The point, world frame.
    pub point: Point3<f64>,
    /// Depth of the point along each view's bearing, `f_i . (R_i X + t_i)`, metres: positive,
    /// and the distance to the camera when the bearing is exact.
    pub depths: Vec<f64>,
    /// Angle between each view's bearing and the direction of the point from that camera,
    /// radians.
    pub residuals: Vec<f64>,
    /// The largest of `residuals`, radians.
    pub max_residual: f64,
    /// The largest angle between the lines from two camera centres to the point, folded into
    /// `[0, pi/2]`, radians.
    pub parallax: f64,
    /// Levenberg-Marquardt iterations run.
    pub iterations: usize,
    /// Whether the refinement met [`TriangulationOptions::step_tolerance`] (false when it ran
    /// out of iterations, or was not run).
    pub converged: bool,
    /// `sum_i theta_i^2` at the linear estimate (at the initial point for [`refine_point`]),
    /// radians squared.
    pub initial_cost: f64,
    /// `sum_i theta_i^2` at `point` (never above `initial_cost`).
    pub final_cost: f64,
}

/// A point triangulated from two views by [`triangulate_two_view`].
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct TwoViewPoint {
    /// The point, in frame `a`.
    pub point_a: Point3<f64>,
    /// Depth of the point along `bearing_a`, `bearing_a . X_a`, metres (positive).
    pub depth_a: f64,
    /// Depth of the point along `bearing_b`, `bearing_b . (b_from_a * X_a)`, metres (positive).
    pub depth_b: f64,
    /// Angle between `bearing_a` and the direction of the point in frame `a`, radians.
    pub residual_a: f64,
    /// Angle between `bearing_b` and the direction of the point in frame `b`, radians.
    pub residual_b: f64,
    /// The triangulation angle: the angle between the lines from the two camera centres to the
    /// point, folded into `[0, pi/2]`, radians.
    pub parallax: f64,
    /// Levenberg-Marquardt iterations run.
    pub iterations: usize,
    /// Whether the refinement met [`TriangulationOptions::step_tolerance`] (false when it ran
    /// out of iterations, or was not run).
    pub converged: bool,
    /// `theta_a^2 + theta_b^2` at the linear estimate, radians squared.
    pub initial_cost: f64,
    /// `theta_a^2 + theta_b^2` at `point_a` (never above `initial_cost`).
    pub final_cost: f64,
}

/// The depths `(lambda_a, lambda_b)` along two bearings of the points where their rays come
/// closest: the least-squares solution of `lambda_b * bearing_b = lambda_a * R bearing_a + t`
/// for `b_from_a = (R, t)`, a 2 x 2 system. Both are positive when the rays meet in front of
/// both cameras (cheirality), and for exact bearings they are the distances to the point. The
/// bearings need not be unit vectors (the depths are then in units of their lengths).
///
/// `None` when the rays are parallel (the sine of their angle at most
/// [`crate::PARALLEL_TOLERANCE`]) or an input is not finite. A pure rotation (`t = 0`) gives
/// zero depths.
#[inline]
pub fn depths_along_bearings(
    b_from_a: &Isometry3<f64>,
    bearing_a: &Vector3<f64>,
    bearing_b: &Vector3<f64>,
) -> Option<(f64, f64)> {
    let m = b_from_a.rotation * bearing_a;
    let t = &b_from_a.translation.vector;
    let (mm, bb, mb) = (m.norm_squared(), bearing_b.norm_squared(), m.dot(bearing_b));
    // The determinant `|m|^2 |b|^2 - (m . b)^2 = |m x b|^2`, from the cross product so that it
    // keeps its relative accuracy for nearly parallel rays.
    let det = m.cross(bearing_b).norm_squared();
    if det.is_nan() || det <= PARALLEL_TOLERANCE * PARALLEL_TOLERANCE * mm * bb {
        return None;
    }
    let (mt, bt) = (m.dot(t), bearing_b.dot(t));
    let lambda_a = (mb * bt - bb * mt) / det;
    let lambda_b = (mm * bt - mb * mt) / det;
    (lambda_a.is_finite() && lambda_b.is_finite()).then_some((lambda_a, lambda_b))
}

/// Triangulates the point seen along `bearing_a` by camera `a` and along `bearing_b` by camera
/// `b`, `b_from_a` mapping points of frame `a` into frame `b`; the point is returned in frame
/// `a`. The linear estimate is the weighted midpoint of the module docs, refined on the angular
/// error unless [`TriangulationOptions::refine`] is false.
///
/// # Errors
/// [`TriangulationError::NonFiniteBearing`] and [`TriangulationError::NonUnitBearing`] (view 0
/// is `a`, view 1 is `b`), [`TriangulationError::NonFinitePose`] (view 1),
/// [`TriangulationError::InvalidOption`], [`TriangulationError::TooLittleParallax`] when the
/// rays meet at less than [`TriangulationOptions::min_parallax`] (a pure rotation included),
/// [`TriangulationError::BehindCamera`] when the rays meet behind a camera, and
/// [`TriangulationError::Numerical`] for a non-finite computation.
pub fn triangulate_two_view(
    b_from_a: &Isometry3<f64>,
    bearing_a: &Vector3<f64>,
    bearing_b: &Vector3<f64>,
    options: &TriangulationOptions,
) -> Result<TwoViewPoint, TriangulationError> {
    check_bearing(0, bearing_a)?;
    check_bearing(1, bearing_b)?;
    check_pose(1, b_from_a)?;
    options.validate()?;
    let rays = [
        Ray {
            centre: Vector3::zeros(),
            direction: *bearing_a,
        },
        Ray {
            centre: b_from_a.inverse_transform_point(&Point3::origin()).coords,
            direction: b_from_a.inverse_transform_vector(bearing_b),
        },
    ];
    let solution = solve(&rays, None, options)?;
    let (mut depths, mut residuals) = ([0.0; 2], [0.0; 2]);
    let mut units = [Vector3::zeros(); 2];
    let parallax = finish(
        &rays,
        &solution.point,
        options.min_parallax,
        &mut depths,
        &mut residuals,
        &mut units,
    )?;
    let (initial_cost, final_cost) = solution
        .costs
        .unwrap_or_else(|| unrefined_costs(&residuals));
    Ok(TwoViewPoint {
        point_a: Point3::from(solution.point),
        depth_a: depths[0],
        depth_b: depths[1],
        residual_a: residuals[0],
        residual_b: residuals[1],
        parallax,
        iterations: solution.iterations,
        converged: solution.converged,
        initial_cost,
        final_cost,
    })
}

/// Triangulates the point seen along `bearings[i]` by the camera at `cameras_from_world[i]`
/// (at least [`TRIANGULATION_MIN_VIEWS`] views), in the world frame: the linear estimate of the
/// module docs, refined on the angular error unless [`TriangulationOptions::refine`] is false.
///
/// The parallax checks compare every pair of views, `n (n - 1) / 2` dot products: negligible
/// next to the solve up to hundreds of views.
///
/// # Errors
/// [`TriangulationError::LengthMismatch`], [`TriangulationError::TooFewViews`],
/// [`TriangulationError::NonFiniteBearing`], [`TriangulationError::NonUnitBearing`],
/// [`TriangulationError::NonFinitePose`], [`TriangulationError::InvalidOption`],
/// [`TriangulationError::TooLittleParallax`] when no two rays meet at
/// [`TriangulationOptions::min_parallax`] or more, [`TriangulationError::BehindCamera`] when the
/// point is behind a camera, and [`TriangulationError::Numerical`] for a non-finite computation.
pub fn triangulate(
    cameras_from_world: &[Isometry3<f64>],
    bearings: &[Vector3<f64>],
    options: &TriangulationOptions,
) -> Result<TriangulatedPoint, TriangulationError> {
    let rays = checked_rays(cameras_from_world, bearings, options)?;
    let solution = solve(&rays, None, options)?;
    finish_many(&rays, solution, options)
}

/// Refines a point on the angular error of its views from `initial` (world frame), with the
/// same cost, iterations and checks as [`triangulate`]: for a point known from elsewhere (a map,
/// an earlier triangulation after the poses changed).
///
/// # Errors
/// Those of [`triangulate`]; [`TriangulationError::InvalidOption`] (`initial`) for a non-finite
/// initial point and [`TriangulationError::BehindCamera`] for one behind a camera.
pub fn refine_point(
    cameras_from_world: &[Isometry3<f64>],
    bearings: &[Vector3<f64>],
    initial: &Point3<f64>,
    options: &TriangulationOptions,
) -> Result<TriangulatedPoint, TriangulationError> {
    let rays = checked_rays(cameras_from_world, bearings, options)?;
    if !initial.coords.iter().all(|v| v.is_finite()) {
        return Err(TriangulationError::InvalidOption {
            name: "initial",
            reason: "the initial point has a non-finite coordinate".into(),
        });
    }
    check_observed_parallax(&rays, options.min_parallax)?;
    check_cheirality(&rays, &initial.coords)?;
    let solution = solve(&rays, Some(initial.coords), options)?;
    finish_many(&rays, solution, options)
}

/// A ray of the world frame: a camera centre and a unit direction.
#[derive(Debug, Clone, Copy)]
struct Ray {
    centre: Vector3<f64>,
    direction: Vector3<f64>,
}

/// The point and the refinement's report.
struct Solution {
    point: Vector3<f64>,
    iterations: usize,
    converged: bool,
    /// The initial and final costs of the refinement; `None` without one.
    costs: Option<(f64, f64)>,
}

fn check_bearing(view: usize, f: &Vector3<f64>) -> Result<(), TriangulationError> {
    if !f.iter().all(|v| v.is_finite()) {
        return Err(TriangulationError::NonFiniteBearing { view });
    }
    let norm = f.norm();
    if (norm - 1.0).abs() > UNIT_NORM_TOLERANCE {
        return Err(TriangulationError::NonUnitBearing {
            view,
            norm,
            tolerance: UNIT_NORM_TOLERANCE,
        });
    }
    Ok(())
}

fn check_pose(view: usize, pose: &Isometry3<f64>) -> Result<(), TriangulationError> {
    let finite = pose.translation.vector.iter().all(|v| v.is_finite())
        && pose.rotation.coords.iter().all(|v| v.is_finite());
    if finite {
        Ok(())
    } else {
        Err(TriangulationError::NonFinitePose { view })
    }
}

/// Input checks of the multi-view functions, then the world-frame rays.
fn checked_rays(
    cameras_from_world: &[Isometry3<f64>],
    bearings: &[Vector3<f64>],
    options: &TriangulationOptions,
) -> Result<Vec<Ray>, TriangulationError> {
    if cameras_from_world.len() != bearings.len() {
        return Err(TriangulationError::LengthMismatch {
            poses: cameras_from_world.len(),
            bearings: bearings.len(),
        });
    }
    if bearings.len() < TRIANGULATION_MIN_VIEWS {
        return Err(TriangulationError::TooFewViews {
            needed: TRIANGULATION_MIN_VIEWS,
            got: bearings.len(),
        });
    }
    for (view, (pose, f)) in cameras_from_world.iter().zip(bearings).enumerate() {
        check_bearing(view, f)?;
        check_pose(view, pose)?;
    }
    options.validate()?;
    Ok(cameras_from_world
        .iter()
        .zip(bearings)
        .map(|(pose, f)| Ray {
            centre: pose.inverse_transform_point(&Point3::origin()).coords,
            direction: pose.inverse_transform_vector(f),
        })
        .collect())
}

/// The multi-view result from a solution: the checks and per-view figures of [`finish`].
fn finish_many(
    rays: &[Ray],
    solution: Solution,
    options: &TriangulationOptions,
) -> Result<TriangulatedPoint, TriangulationError> {
    let n = rays.len();
    let (mut depths, mut residuals) = (vec![0.0; n], vec![0.0; n]);
    let mut units = vec![Vector3::zeros(); n];
    let parallax = finish(
        rays,
        &solution.point,
        options.min_parallax,
        &mut depths,
        &mut residuals,
        &mut units,
    )?;
    let max_residual = residuals.iter().copied().fold(0.0, f64::max);
    let (initial_cost, final_cost) = solution
        .costs
        .unwrap_or_else(|| unrefined_costs(&residuals));
    Ok(TriangulatedPoint {
        point: Point3::from(solution.point),
        depths,
        residuals,
        max_residual,
        parallax,
        iterations: solution.iterations,
        converged: solution.converged,
        initial_cost,
        final_cost,
    })
}

/// The costs of a point that was not refined: both `sum_i theta_i^2`.
fn unrefined_costs(residuals: &[f64]) -> (f64, f64) {
    let cost = residuals.iter().map(|r| r * r).sum();
    (cost, cost)
}

/// The linear estimate (unless `initial` is given), then the refinement.
fn solve(
    rays: &[Ray],
    initial: Option<Vector3<f64>>,
    options: &TriangulationOptions,
) -> Result<Solution, TriangulationError> {
    let start = match initial {
        Some(x) => x,
        None => {
            check_observed_parallax(rays, options.min_parallax)?;
            let x = linear(rays, options.min_parallax)?;
            check_cheirality(rays, &x)?;
            x
        }
    };
    if !options.refine {
        return Ok(Solution {
            point: start,
            iterations: 0,
            converged: false,
            costs: None,
        });
    }
    refine(rays, start, options)
}

/// The largest angle between two lines of direction `directions` (unit vectors), folded into
/// `[0, pi/2]` (COLMAP's triangulation angle), over all pairs; 0 for fewer than two.
fn max_line_angle(directions: &[Vector3<f64>]) -> f64 {
    // The pair with the smallest |cos|, then its angle accurately.
    let mut best: Option<(f64, usize, usize)> = None;
    for (i, u) in directions.iter().enumerate() {
        for (j, v) in directions.iter().enumerate().skip(i + 1) {
            let cos = u.dot(v).abs();
            if best.is_none_or(|(c, _, _)| cos < c) {
                best = Some((cos, i, j));
            }
        }
    }
    best.map_or(0.0, |(_, i, j)| {
        let (u, v) = (&directions[i], &directions[j]);
        u.cross(v).norm().atan2(u.dot(v).abs())
    })
}

/// [`TriangulationError::TooLittleParallax`] with the largest angle between the rays' lines.
#[cold]
fn too_little_parallax(rays: &[Ray], min_parallax: f64) -> TriangulationError {
    let directions: Vec<Vector3<f64>> = rays.iter().map(|r| r.direction).collect();
    TriangulationError::TooLittleParallax {
        parallax: max_line_angle(&directions),
        min_parallax,
    }
}

/// Refuses rays whose lines all meet at less than `min_parallax`; returns early at the first
/// pair that passes, which is usually the first.
fn check_observed_parallax(rays: &[Ray], min_parallax: f64) -> Result<(), TriangulationError> {
    let max_cos = min_parallax.cos();
    for (i, a) in rays.iter().enumerate() {
        for b in &rays[i + 1..] {
            let dot = a.direction.dot(&b.direction).abs();
            if dot < max_cos && a.direction.cross(&b.direction).norm() > PARALLEL_TOLERANCE {
                return Ok(());
            }
        }
    }
    Err(too_little_parallax(rays, min_parallax))
}

/// Refuses a point whose depth along some ray is not positive.
fn check_cheirality(rays: &[Ray], x: &Vector3<f64>) -> Result<(), TriangulationError> {
    for (view, ray) in rays.iter().enumerate() {
        let depth = ray.direction.dot(&(x - ray.centre));
        if depth.is_nan() || depth <= 0.0 {
            return Err(TriangulationError::BehindCamera { view, depth });
        }
    }
    Ok(())
}

/// The weighted midpoint, twice: unweighted, then each ray weighted by the inverse squared
/// distance from its centre to the first estimate (see the module docs).
fn linear(rays: &[Ray], min_parallax: f64) -> Result<Vector3<f64>, TriangulationError> {
    // Centred on the mean camera centre, so the solve keeps its accuracy far from the origin.
    let origin = rays.iter().map(|r| r.centre).sum::<Vector3<f64>>() / rays.len() as f64;
    let first = weighted_midpoint(rays, &origin, |_| 1.0)
        .ok_or_else(|| too_little_parallax(rays, min_parallax))?;
    let x = origin + first;
    let reweighted = weighted_midpoint(rays, &origin, |ray| {
        let squared = (x - ray.centre).norm_squared();
        if squared > 0.0 { 1.0 / squared } else { 1.0 }
    });
    Ok(origin + reweighted.unwrap_or(first))
}

/// The solution `y` of `sum_i w_i (I - d_i d_i^T) (y - (c_i - origin)) = 0`; `None` if the
/// system is singular or the solution not finite.
fn weighted_midpoint(
    rays: &[Ray],
    origin: &Vector3<f64>,
    weight: impl Fn(&Ray) -> f64,
) -> Option<Vector3<f64>> {
    // `A = (sum w) I - sum w d d^T`, `b = sum w (c - d (d . c))`.
    let mut total = 0.0;
    let mut outer = Matrix3::zeros();
    let mut b = Vector3::zeros();
    for ray in rays {
        let w = weight(ray);
        let d = &ray.direction;
        let c = ray.centre - origin;
        let wd = d * w;
        total += w;
        outer += wd * d.transpose();
        b += c * w - wd * d.dot(&c);
    }
    let a = Matrix3::from_diagonal_element(total) - outer;
    let y = a.cholesky()?.solve(&b);
    y.iter().all(|v| v.is_finite()).then_some(y)
}

/// Below this sine of the residual angle, `theta / sin` and `(sin - theta cos) / sin^3` are
/// evaluated by their series (`1 + theta^2 / 6` and `1/3 + 2 theta^2 / 15`, truncation
/// `O(theta^4) < 1e-16`), where the closed forms lose digits to cancellation.
const SERIES_SINE: f64 = 1e-4;

/// The tangent-plane residual `r = theta / sin(theta) (I - d d^T) u` of a ray at `x`, its
/// Jacobian `dr / dx` (module docs) and the distance `|x - c|`; `None` where it is undefined
/// (`x` at the centre, or opposite the ray: `theta` within round-off of `pi`).
#[inline]
fn residual_and_jacobian(ray: &Ray, x: &Vector3<f64>) -> Option<(Vector3<f64>, Matrix3<f64>, f64)> {
    let p = x - ray.centre;
    let distance = p.norm();
    if !(distance > 0.0 && distance.is_finite()) {
        return None;
    }
    let d = &ray.direction;
    let u = p / distance;
    let cos = d.dot(&u);
    let v = u - d * cos;
    let sin = v.norm();
    let theta = sin.atan2(cos);
    let (scale, curvature) = if sin < SERIES_SINE {
        if cos < 0.0 {
            return None;
        }
        let theta2 = theta * theta;
        (1.0 + theta2 / 6.0, 1.0 / 3.0 + 2.0 * theta2 / 15.0)
    } else {
        (theta / sin, (sin - theta * cos) / (sin * sin * sin))
    };
    // dr/du = scale (I - d d^T) - curvature v d^T = scale I - (scale d + curvature v) d^T;
    // du/dx = (I - u u^T) / |p|.
    let mixed = d * scale + v * curvature;
    let d_residual_d_u = Matrix3::from_diagonal_element(scale) - mixed * d.transpose();
    let projector = (Matrix3::identity() - u * u.transpose()) / distance;
    Some((v * scale, d_residual_d_u * projector, distance))
}

/// The refinement's view of a point: the cost `sum |r_i|^2 = sum theta_i^2`, the normal
/// equations `J^T J` and `J^T r`, and the distance to the nearest camera centre.
struct Evaluation {
    cost: f64,
    hessian: Matrix3<f64>,
    gradient: Vector3<f64>,
    nearest: f64,
}

/// The [`Evaluation`] at `x`; `None` where a residual is undefined or a sum is not finite.
fn evaluate(rays: &[Ray], x: &Vector3<f64>) -> Option<Evaluation> {
    let mut e = Evaluation {
        cost: 0.0,
        hessian: Matrix3::zeros(),
        gradient: Vector3::zeros(),
        nearest: f64::INFINITY,
    };
    for ray in rays {
        let (r, j, distance) = residual_and_jacobian(ray, x)?;
        let jt = j.transpose();
        e.cost += r.norm_squared();
        e.hessian += jt * j;
        e.gradient += jt * r;
        e.nearest = e.nearest.min(distance);
    }
    e.cost.is_finite().then_some(e)
}

/// Initial Levenberg-Marquardt damping, relative to the diagonal of `J^T J`: small, as the
/// linear estimate is close.
const INITIAL_DAMPING: f64 = 1e-6;

/// Levenberg-Marquardt from `start` with Nielsen's damping update (as in `refine.rs`); each
/// candidate is evaluated once, its normal equations reused when it is accepted.
fn refine(
    rays: &[Ray],
    start: Vector3<f64>,
    options: &TriangulationOptions,
) -> Result<Solution, TriangulationError> {
    let Some(mut current) = evaluate(rays, &start) else {
        return Err(TriangulationError::Numerical(
            "triangulation: the angular error at the initial point is not finite",
        ));
    };
    let initial_cost = current.cost;
    let mut x = start;
    let mut damping = INITIAL_DAMPING;
    let mut nu = 2.0;
    let mut iterations = 0;
    let mut converged = current.cost == 0.0;
    'iterations: while !converged && iterations < options.max_iterations {
        iterations += 1;
        let diagonal = current.hessian.diagonal().map(|h| h.max(f64::MIN_POSITIVE));
        loop {
            let damped = current.hessian + Matrix3::from_diagonal(&(diagonal * damping));
            let Some(step) = damped.cholesky().map(|c| c.solve(&(-current.gradient))) else {
                damping = damping * nu + f64::MIN_POSITIVE;
                nu *= 2.0;
                if !damping.is_finite() {
                    break 'iterations;
                }
                continue;
            };
            let small = step.norm() <= options.step_tolerance * current.nearest;
            let candidate = x + step;
            // Gain ratio: actual over predicted decrease (the model is of cost / 2).
            let predicted = step.dot(&(step.component_mul(&diagonal) * damping - current.gradient));
            if let Some(next) = evaluate(rays, &candidate) {
                let gain = (current.cost - next.cost) / predicted;
                if next.cost <= current.cost && gain > 0.0 {
                    x = candidate;
                    damping *= (1.0 - (2.0 * gain - 1.0).powi(3)).max(1.0 / 3.0);
                    nu = 2.0;
                    converged = small || next.cost == 0.0;
                    current = next;
                    break;
                }
            }
            if small {
                // The cost cannot be lowered by a step this small: a minimum to round-off.
                converged = true;
                break 'iterations;
            }
            damping *= nu;
            nu *= 2.0;
            if !damping.is_finite() {
                break 'iterations;
            }
        }
    }
    Ok(Solution {
        point: x,
        iterations,
        converged,
        costs: Some((initial_cost, current.cost)),
    })
}

/// The final checks (cheirality, then parallax at the point) and per-view figures: depths,
/// residual angles and the unit directions from the centres to the point written into the
/// slices; returns the parallax.
fn finish(
    rays: &[Ray],
    x: &Vector3<f64>,
    min_parallax: f64,
    depths: &mut [f64],
    residuals: &mut [f64],
    units: &mut [Vector3<f64>],
) -> Result<f64, TriangulationError> {
    if !x.iter().all(|v| v.is_finite()) {
        return Err(TriangulationError::Numerical(
            "triangulation: the point is not finite",
        ));
    }
    check_cheirality(rays, x)?;
    for (((ray, depth), residual), unit) in rays.iter().zip(depths).zip(residuals).zip(&mut *units)
    {
        let p = x - ray.centre;
        *depth = ray.direction.dot(&p);
        *residual = bearing_angle(&ray.direction, &p);
        *unit = p.normalize();
    }
    let parallax = max_line_angle(units);
    if parallax < min_parallax {
        return Err(TriangulationError::TooLittleParallax {
            parallax,
            min_parallax,
        });
    }
    Ok(parallax)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn unit(rng: &mut ChaCha8Rng) -> Vector3<f64> {
        Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0)).normalize()
    }

    /// The analytic Jacobian of the tangent-plane residual agrees with central differences, at
    /// angles from 1e-6 (the series) to 170 degrees, and the residual's length is the angle.
    #[test]
    fn residual_jacobian_matches_finite_differences() {
        let mut rng = ChaCha8Rng::seed_from_u64(160);
        for trial in 0..400 {
            let direction = unit(&mut rng);
            let centre = Vector3::from_fn(|_, _| rng.random_range(-3.0..3.0));
            let ray = Ray { centre, direction };
            let angle = [1e-6, 5e-5, 2e-4, 0.01, 0.5, 1.5, 2.5, 2.97][trial % 8];
            let axis = direction.cross(&unit(&mut rng)).normalize();
            let towards =
                nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle)
                    * direction;
            let x = centre + towards * rng.random_range(1.0..5.0);
            let (r, j, _) = residual_and_jacobian(&ray, &x).unwrap();
            assert!((r.norm() - angle).abs() <= 1e-12 * (1.0 + angle), "{trial}");
            let h = 1e-6 * (x - centre).norm() * angle.clamp(1e-3, 1.0);
            for k in 0..3 {
                let mut e = Vector3::zeros();
                e[k] = h;
                let (plus, _, _) = residual_and_jacobian(&ray, &(x + e)).unwrap();
                let (minus, _, _) = residual_and_jacobian(&ray, &(x - e)).unwrap();
                let numeric = (plus - minus) / (2.0 * h);
                let error = (numeric - j.column(k)).norm();
                assert!(
                    error <= 1e-6 * j.norm(),
                    "trial {trial}, angle {angle}: {error:e} vs {:e}",
                    j.norm()
                );
            }
        }
    }

    #[test]
    fn depths_of_exact_rays_are_the_distances() {
        let mut rng = ChaCha8Rng::seed_from_u64(161);
        for _ in 0..200 {
            let b_from_a = Isometry3::new(
                Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0)),
                Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0)),
            );
            let x_a = Point3::from(unit(&mut rng) * rng.random_range(1.0..10.0));
            let x_b = b_from_a * x_a;
            let (fa, fb) = (x_a.coords.normalize(), x_b.coords.normalize());
            let Some((la, lb)) = depths_along_bearings(&b_from_a, &fa, &fb) else {
                // Only for rays within round-off of parallel.
                assert!((b_from_a.rotation * fa).cross(&fb).norm() < 1e-9);
                continue;
            };
            let tolerance = 1e-9 * x_a.coords.norm().max(x_b.coords.norm())
                / (b_from_a.rotation * fa).cross(&fb).norm();
            assert!((la - x_a.coords.norm()).abs() <= tolerance);
            assert!((lb - x_b.coords.norm()).abs() <= tolerance);
        }
        let identity = Isometry3::identity();
        assert_eq!(
            depths_along_bearings(&identity, &Vector3::z(), &Vector3::z()),
            None
        );
        assert_eq!(
            depths_along_bearings(&identity, &Vector3::z(), &Vector3::new(f64::NAN, 0.0, 1.0)),
            None
        );
    }
}
