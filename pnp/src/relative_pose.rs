//! Robust relative pose from two sets of unit bearings: LO-RANSAC with the five-point kernel,
//! an angular error, refinement on the essential manifold, and model selection between a
//! general scene, a plane and a pure rotation.
//!
//! M. A. Fischler and R. C. Bolles, "Random Sample Consensus", Communications of the ACM
//! 24(6), 1981 (sampling and the adaptive iteration count); P. H. S. Torr and A. Zisserman,
//! "MLESAC", CVIU 78, 2000 (the truncated-quadratic MSAC score); O. Chum, J. Matas and
//! J. Kittler, "Locally Optimized RANSAC", DAGM 2003 (local optimization of every new best
//! model); P. H. S. Torr, "Geometric motion segmentation and model selection", Phil. Trans.
//! Royal Society A 356, 1998 (GRIC); D. Nister, TPAMI 2004 (the kernel, [`crate::five_point`]).
//!
//! **Error.** The error of a correspondence `(a, b)` under `E = [t]x R` is the tangent-plane
//! Sampson error of the epipolar constraint on the unit sphere,
//!
//! `d^2 = (b^T E a)^2 / (|P_a E^T b|^2 + |P_b E a|^2)`, `P_f = I - f f^T`,
//!
//! the first-order distance, in radians, from the pair of bearings to the nearest pair that
//! satisfies the constraint exactly, each bearing moving in its tangent plane (so it is the
//! same at every incidence, beyond 90 degrees too). Since `a`, `b` are unit,
//! `|P_b E a|^2 = |E a|^2 - (b^T E a)^2`. Under isotropic angular noise `sigma` per tangent
//! axis on both bearings, `d / sigma` is a standard normal: a pixel threshold `p` on a camera
//! of focal length `f` pixels is the angle [`crate::angle_from_pixels`]`(p, f)`.
//!
//! **Algorithm.** Samples of five correspondences give up to ten essential matrices; each
//! is decomposed ([`crate::decompose_essential`]) and kept only in the pose that puts all
//! five in front of both cameras (depths along the bearings). Poses are scored by MSAC
//! (`sum min(d^2, threshold^2)`, stopped once above the best), the iteration count adapts to
//! `ln(1 - confidence) / ln(1 - w^5)` (`w` the best inlier ratio, no lower than
//! `min_inliers / n`: a pair without a model of `min_inliers` is rejected after the samples
//! that would have found one), and each new best pose is refined on its inliers
//! (local optimization). With correspondences ordered best first
//! ([`RelativePoseOptions::progressive`]), samples are drawn progressively from the best and
//! the search stops by PROSAC's rule (O. Chum and J. Matas, "Matching with PROSAC", CVPR
//! 2005). The best pose is refined on all its inliers until they are stable
//! ([`refine_relative_pose`]: Levenberg-Marquardt on the Sampson error over the rotation
//! on SO(3) and the translation direction on S^2, five degrees of freedom).
//!
//! **Model selection.** On the inliers of the essential matrix, a homography (four-point
//! RANSAC, then normalized least squares, [`crate::homography`]) and a rotation (two-point
//! RANSAC, then least squares) are fitted too, and Torr's GRIC
//! `sum min(d_i^2 / sigma^2, 2 (4 - m)) + ln(4) m n + ln(4 n) k` (data dimension 4; model
//! dimension `m` and parameters `k`: 3 and 5 for the essential matrix, 2 and 8 for the
//! homography, 2 and 3 for the rotation) picks the model, with `sigma = threshold / 3`.
//! The homography's error is the symmetric transfer error `d^2 = (e_ab^2 + e_ba^2) / 4`
//! (`e_ab` the angle between `b` and `H a`), the rotation's `d^2 = e^2 / 2` (`e` the angle
//! between `b` and `R a`): both first-order distances in the same four-dimensional space as
//! the Sampson error. GRIC is computed on the essential matrix's inliers, not on all
//! correspondences: outliers would otherwise weigh against the models of lower dimension.
//!
//! **Outcomes.** A pure rotation is a result: [`TwoViewModel::PureRotation`], with the
//! rotation and a zero translation (the translation is not observable). A plane is a result
//! too ([`TwoViewModel::Homography`], the pose from the homography's decomposition refined on
//! the essential manifold, with the plane normal and the other decomposition). A general
//! model whose inliers see the scene under a median triangulation angle below
//! `min_parallax` is [`RelativePoseError::InsufficientParallax`], which carries the rotation:
//! the translation direction is then mostly noise.

// `!(x > y)` is written on purpose where a NaN must fail the test; index loops mirror
// the formulas.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

use nalgebra::{Isometry3, Matrix3, Matrix5, Rotation3, UnitQuaternion, Vector3, Vector5};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::NonExhaustive;
use crate::error::PnpError;
use crate::five_point::{depths, rotations_and_translation, solve};
use crate::geometry::{isometry_from, rotation_from_correlation};
use crate::homography::{self as homography_mod, PlanarPose};
use crate::prosac::{ProsacSampler, prosac_iterations};
use crate::ransac::{RansacOptions, adaptive_iterations};
use crate::refine::RefineOptions;
use crate::relative_pose_error::{RelativePoseError, RelativeResult, check_bearing_pairs};

/// The fewest correspondences [`relative_pose`] and [`refine_relative_pose`] take: the five
/// of a minimal sample.
pub const RELATIVE_POSE_MIN_POINTS: usize = 5;

/// Default smallest median triangulation angle of the inliers of a general (or planar)
/// model, radians: 1 degree, ORB-SLAM's requirement for a two-view initialization
/// (R. Mur-Artal, J. M. M. Montiel and J. D. Tardos, "ORB-SLAM", IEEE T-RO 31(5), 2015).
pub const RELATIVE_POSE_MIN_PARALLAX: f64 = 0.017_453_292_519_943_295;

/// Default most RANSAC iterations of [`relative_pose`]: 100 000, PoseLib's. At 80 % outliers
/// a five-point sample is all inliers with probability 3.2e-4, so 99.9 % confidence needs
/// about 21 600 samples, beyond [`RansacOptions`]'s own default of 10 000.
pub const RELATIVE_POSE_MAX_ITERATIONS: usize = 100_000;

/// Rounds of local optimization per new best model.
const LO_ROUNDS: usize = 2;
/// Levenberg-Marquardt iterations per local optimization round.
const LO_ITERATIONS: usize = 5;
/// Rounds of the final refit (refine on the inliers, recollect them).
const FINAL_ROUNDS: usize = 4;
/// Rounds of the final refit after a progressive search: a model found after few samples
/// can need more rounds before its inlier set is stable (measured: with 4, 2 of 30 trials at
/// 50 % outliers ended 3e-3 rad from the optimum of their inliers; with 10, none).
const FINAL_ROUNDS_PROGRESSIVE: usize = 10;
/// Most samples of the homography and rotation fits of model selection (their inlier ratio
/// within the essential matrix's inliers is high when they are the right model).
const SELECTION_ITERATIONS: usize = 100;
/// Fewest essential inliers for model selection to run.
const SELECTION_MIN_POINTS: usize = 8;

/// Options of [`relative_pose`]. Write them in one expression,
/// `RelativePoseOptions { min_parallax: 0.0, ..Default::default() }`.
#[derive(Debug, Clone, PartialEq)]
pub struct RelativePoseOptions {
    /// RANSAC options: `threshold` is the inlier threshold on the angular error of the module
    /// docs (radians), `min_inliers` the fewest inliers accepted, `local_optimization` and
    /// `final_refinement` switch the refinements, whose options are `refine` (its `loss`
    /// makes the final refinement robust). Default [`RansacOptions::default`] with
    /// `max_iterations` [`RELATIVE_POSE_MAX_ITERATIONS`] (100 000): threshold 3.75e-3 rad
    /// (3 px at f = 800), confidence 0.999, 50 to 100 000 iterations, 25 inliers, seed 0.
    pub ransac: RansacOptions,
    /// Choose between the essential matrix, a homography and a pure rotation by GRIC (see
    /// the module docs). Without it the model is always the essential matrix. Default true.
    pub model_selection: bool,
    /// Smallest median triangulation angle (radians) of the inliers of an essential or
    /// homography model; below it the result is [`RelativePoseError::InsufficientParallax`].
    /// 0 disables the check. Default [`RELATIVE_POSE_MIN_PARALLAX`] (1 degree).
    pub min_parallax: f64,
    /// The correspondences come ordered best first (for example by descriptor distance, the
    /// most distinctive match first): sample progressively from the best and stop by
    /// PROSAC's rule (Chum and Matas, CVPR 2005; see `prosac.rs`), which ends the search as
    /// soon as a prefix of the order holds enough inliers (at least `min_inliers`, not by
    /// chance) for the samples drawn to have found its model at the stated confidence. With
    /// an order that says nothing of the inliers it is RANSAC. Default false (uniform
    /// sampling, RANSAC's count).
    pub progressive: bool,
    /// Keeps the struct open to new fields: write it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for RelativePoseOptions {
    fn default() -> Self {
        Self {
            ransac: RansacOptions {
                max_iterations: RELATIVE_POSE_MAX_ITERATIONS,
                ..RansacOptions::default()
            },
            model_selection: true,
            min_parallax: RELATIVE_POSE_MIN_PARALLAX,
            progressive: false,
            non_exhaustive: NonExhaustive::VALUE,
        }
    }
}

impl RelativePoseOptions {
    /// Checks every option's range (those of [`RansacOptions::validate`], at least five
    /// inliers, and a `min_parallax` in `[0, pi)`).
    ///
    /// # Errors
    /// [`RelativePoseError::InvalidOption`] naming the option.
    pub fn validate(&self) -> RelativeResult<()> {
        self.ransac.validate().map_err(|e| match e {
            PnpError::InvalidOption { name, reason } => {
                RelativePoseError::InvalidOption { name, reason }
            }
            other => RelativePoseError::InvalidOption {
                name: "ransac.refine",
                reason: other.to_string(),
            },
        })?;
        if self.ransac.min_inliers < RELATIVE_POSE_MIN_POINTS {
            return Err(RelativePoseError::InvalidOption {
                name: "min_inliers",
                reason: format!(
                    "must be at least {RELATIVE_POSE_MIN_POINTS}, got {}",
                    self.ransac.min_inliers
                ),
            });
        }
        if !(self.min_parallax >= 0.0 && self.min_parallax < core::f64::consts::PI) {
            return Err(RelativePoseError::InvalidOption {
                name: "min_parallax",
                reason: format!("must be in [0, pi) radians, got {}", self.min_parallax),
            });
        }
        Ok(())
    }
}

/// The model [`relative_pose`] selected.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum TwoViewModel {
    /// A general scene: the essential matrix `[t]x R` of the pose (unit `t`).
    Essential {
        /// `E = [t]x R`.
        essential: Matrix3<f64>,
    },
    /// A planar scene: the homography `H = R + (t / d) n^T` (normalized as
    /// [`crate::homography`] returns it); the pose is its decomposition, refined.
    Homography {
        /// The homography, `b ~ H a`.
        homography: Matrix3<f64>,
        /// The plane's unit normal in frame a (`n^T X_a = d > 0`).
        normal: Vector3<f64>,
        /// The other decomposition that puts points in front of both cameras, if any: a
        /// homography alone cannot tell them apart when both explain the points.
        alternative: Option<PlanarPose>,
    },
    /// A pure rotation (or a translation too small to observe): the translation of
    /// `b_from_a` is zero.
    PureRotation,
}

/// GRIC scores of the three models (lower is better; see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct GricScores {
    /// The essential matrix's.
    pub essential: f64,
    /// The homography's (infinite if none was found).
    pub homography: f64,
    /// The pure rotation's (infinite if none was found, or not fitted because the homography
    /// explains less than half of the essential matrix's inliers, when a rotation cannot win).
    pub rotation: f64,
}

/// The outcome of [`relative_pose`].
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct RelativePose {
    /// The estimated `b_from_a`: `X_b = R X_a + t` with `|t| = 1` (the scale is not
    /// observable), or `t = 0` for [`TwoViewModel::PureRotation`].
    pub b_from_a: Isometry3<f64>,
    /// The selected model.
    pub model: TwoViewModel,
    /// Indices (increasing) into the caller's slices of the correspondences within the
    /// threshold of the selected model.
    pub inliers: Vec<usize>,
    /// RANSAC iterations (five-point samples) drawn.
    pub iterations: usize,
    /// Root mean square of the inliers' errors under the selected model, radians.
    pub inlier_rms: f64,
    /// Median over the inliers of the triangulation angle (between `R a` and `b`), radians.
    pub median_parallax: f64,
    /// The GRIC scores, when model selection ran.
    pub gric: Option<GricScores>,
}

/// The correspondences consistent with a known relative pose `b_from_a` (`X_b = R X_a + t`,
/// for example between two cameras of a calibrated rig at one time): indices (increasing) of
/// those within `threshold` (radians) of its epipolar constraint, by the angular error of the
/// module documentation, and in front of both cameras (or too far for the sign of their depths
/// to tell, as in [`relative_pose`]). With `t = 0` (the same centre) the epipolar constraint
/// says nothing: a correspondence is consistent when the rotation model's distance (the angle
/// between `R a` and `b` over `sqrt 2`, the module documentation's) is within `threshold`.
/// The norm of `t` does not matter.
///
/// # Errors
/// [`RelativePoseError::LengthMismatch`], [`RelativePoseError::NonFiniteBearing`] and
/// [`RelativePoseError::NonUnitBearing`] for the bearings (any number of them, zero included);
/// [`RelativePoseError::InvalidOption`] for a `threshold` that is not finite and positive or a
/// pose that is not finite.
pub fn relative_pose_inliers(
    bearings_a: &[Vector3<f64>],
    bearings_b: &[Vector3<f64>],
    b_from_a: &Isometry3<f64>,
    threshold: f64,
) -> RelativeResult<Vec<usize>> {
    check_bearing_pairs("relative pose inliers", 0, bearings_a, bearings_b)?;
    if !(threshold.is_finite() && threshold > 0.0) {
        return Err(RelativePoseError::InvalidOption {
            name: "threshold",
            reason: format!("must be finite and positive, got {threshold}"),
        });
    }
    let rotation = b_from_a.rotation.to_rotation_matrix().into_inner();
    let t = b_from_a.translation.vector;
    if !(rotation.iter().all(|v| v.is_finite()) && t.iter().all(|v| v.is_finite())) {
        return Err(RelativePoseError::InvalidOption {
            name: "b_from_a",
            reason: "the pose is not finite".into(),
        });
    }
    let thr2 = threshold * threshold;
    let mut inliers = Vec::new();
    let norm = t.norm();
    if norm > 0.0 {
        let scorer = Scorer {
            a: bearings_a,
            b: bearings_b,
            thr2,
        };
        scorer.inliers(&Model::new(rotation, t / norm), &mut inliers);
    } else {
        // The rotation model's squared first-order distance `e^2 / 2` (module documentation).
        for (i, (fa, fb)) in bearings_a.iter().zip(bearings_b).enumerate() {
            if rotation_error(&rotation, fa, fb) <= thr2 {
                inliers.push(i);
            }
        }
    }
    Ok(inliers)
}

/// The outcome of [`refine_relative_pose`].
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct RefinedRelativePose {
    /// The refined `b_from_a`, with a unit translation.
    pub b_from_a: Isometry3<f64>,
    /// Iterations run.
    pub iterations: usize,
    /// Cost `sum rho(d_i^2)` at the initial pose.
    pub initial_cost: f64,
    /// Cost at the refined pose (never above `initial_cost`).
    pub final_cost: f64,
}

/// The tangent-plane Sampson error squared (see the module docs) of `(a, b)` under `e`.
#[inline]
fn sampson_squared(e: &Matrix3<f64>, a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    let ea = e * a;
    let etb = e.tr_mul(b);
    let c = b.dot(&ea);
    let c2 = c * c;
    let d = ea.norm_squared() + etb.norm_squared() - 2.0 * c2;
    if d > 0.0 {
        c2 / d
    } else if c2 == 0.0 {
        0.0
    } else {
        f64::INFINITY
    }
}

/// Refines `b_from_a` by Levenberg-Marquardt on the tangent-plane Sampson error (see the
/// module docs), starting from `initial`, over the rotation on SO(3) (`R <- R Exp(w)`) and
/// the translation direction on S^2 (five degrees of freedom; the norm of `initial`'s
/// translation is dropped). `options.loss` makes it robust (iteratively reweighted, as
/// [`crate::refine_pose`]); the loss scale is in radians.
///
/// # Errors
/// The input errors of [`crate::five_point`] (with at least [`RELATIVE_POSE_MIN_POINTS`]),
/// [`RelativePoseError::InvalidOption`] for invalid options or an `initial` pose that is not
/// finite or has a zero translation, and [`RelativePoseError::Numerical`] if the cost at
/// `initial` is not finite.
pub fn refine_relative_pose(
    bearings_a: &[Vector3<f64>],
    bearings_b: &[Vector3<f64>],
    initial: &Isometry3<f64>,
    options: &RefineOptions,
) -> RelativeResult<RefinedRelativePose> {
    check_bearing_pairs(
        "relative pose refinement",
        RELATIVE_POSE_MIN_POINTS,
        bearings_a,
        bearings_b,
    )?;
    options
        .validate()
        .map_err(|e| RelativePoseError::InvalidOption {
            name: "loss",
            reason: e.to_string(),
        })?;
    let t = initial.translation.vector;
    let q = initial.rotation.coords;
    if !(t.iter().chain(q.iter()).all(|v| v.is_finite()) && t.norm() > 0.0) {
        return Err(RelativePoseError::InvalidOption {
            name: "initial",
            reason: "the initial pose must be finite with a non-zero translation".into(),
        });
    }
    let all: Vec<usize> = (0..bearings_a.len()).collect();
    let r = initial.rotation.to_rotation_matrix().into_inner();
    let refined = refine_on(
        bearings_a,
        bearings_b,
        &all,
        &r,
        &t.normalize(),
        options,
        options.max_iterations,
    );
    if !refined.initial_cost.is_finite() {
        return Err(RelativePoseError::Numerical(
            "the cost at the initial pose is not finite",
        ));
    }
    Ok(RefinedRelativePose {
        b_from_a: isometry_from(&refined.rotation, &refined.translation),
        iterations: refined.iterations,
        initial_cost: refined.initial_cost,
        final_cost: refined.final_cost,
    })
}

struct Refined {
    rotation: Matrix3<f64>,
    translation: Vector3<f64>,
    iterations: usize,
    initial_cost: f64,
    final_cost: f64,
}

/// Two unit vectors completing the unit `t` to an orthonormal basis.
fn tangent_basis(t: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let helper = if t.x.abs() < 0.6 {
        Vector3::x()
    } else if t.y.abs() < 0.6 {
        Vector3::y()
    } else {
        Vector3::z()
    };
    let t1 = t.cross(&helper).normalize();
    (t1, t.cross(&t1))
}

/// Cost, gradient `J^T W r` and Gauss-Newton matrix `J^T W J` of the Sampson residuals on
/// `subset` at `(r, t)`.
fn normal_equations(
    a: &[Vector3<f64>],
    b: &[Vector3<f64>],
    subset: &[usize],
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
    options: &RefineOptions,
    with_jacobian: bool,
) -> (f64, Vector5<f64>, Matrix5<f64>) {
    let e = t.cross_matrix() * r;
    let (t1, t2) = tangent_basis(t);
    let tx_r = e;
    // dE for the five directions: [t]x R [e_k]x, then [t_j]x R.
    let de: [Matrix3<f64>; 5] = [
        tx_r * Vector3::x().cross_matrix(),
        tx_r * Vector3::y().cross_matrix(),
        tx_r * Vector3::z().cross_matrix(),
        t1.cross_matrix() * r,
        t2.cross_matrix() * r,
    ];
    let trivial = options.loss.is_trivial();
    let mut cost = 0.0;
    let mut g = Vector5::zeros();
    let mut h = Matrix5::zeros();
    for &i in subset {
        let (fa, fb) = (&a[i], &b[i]);
        let ea = e * fa;
        let etb = e.tr_mul(fb);
        let c = fb.dot(&ea);
        let d = ea.norm_squared() + etb.norm_squared() - 2.0 * c * c;
        if !(d > 0.0) {
            continue;
        }
        let s = d.sqrt();
        let residual = c / s;
        let s2 = residual * residual;
        let [rho, rho1, _] = if trivial {
            [s2, 1.0, 0.0]
        } else {
            options.loss.evaluate(s2)
        };
        cost += rho;
        if !with_jacobian {
            continue;
        }
        let s3 = s * d;
        let c1 = 1.0 / s + 2.0 * c * c / s3;
        let c2 = c / s3;
        let mut j = Vector5::zeros();
        for (k, dek) in de.iter().enumerate() {
            let dea = dek * fa;
            let detb = dek.tr_mul(fb);
            j[k] = c1 * fb.dot(&dea) - c2 * (ea.dot(&dea) + detb.dot(&etb));
        }
        g += j * (rho1 * residual);
        h += j * j.transpose() * rho1;
    }
    (cost, g, h)
}

/// Levenberg-Marquardt on `subset` (see [`refine_relative_pose`]).
fn refine_on(
    a: &[Vector3<f64>],
    b: &[Vector3<f64>],
    subset: &[usize],
    r0: &Matrix3<f64>,
    t0: &Vector3<f64>,
    options: &RefineOptions,
    max_iterations: usize,
) -> Refined {
    let (mut r, mut t) = (*r0, *t0);
    let (mut cost, mut g, mut h) = normal_equations(a, b, subset, &r, &t, options, true);
    let initial_cost = cost;
    let mut lambda = 1e-4 * (0..5).map(|k| h[(k, k)]).fold(0.0, f64::max);
    let mut iterations = 0;
    if !cost.is_finite() {
        return Refined {
            rotation: r,
            translation: t,
            iterations,
            initial_cost,
            final_cost: cost,
        };
    }
    while iterations < max_iterations {
        iterations += 1;
        let mut accepted = false;
        for _ in 0..10 {
            let mut damped = h;
            for k in 0..5 {
                damped[(k, k)] += lambda.max(1e-300) * h[(k, k)].max(1e-30);
            }
            let Some(step) = damped.cholesky().map(|c| c.solve(&(-g))) else {
                lambda *= 10.0;
                continue;
            };
            let w = Vector3::new(step[0], step[1], step[2]);
            let (t1, t2) = tangent_basis(&t);
            let r_next = r * Rotation3::new(w).into_inner();
            let t_next = (t + t1 * step[3] + t2 * step[4]).normalize();
            let (c_next, _, _) = normal_equations(a, b, subset, &r_next, &t_next, options, false);
            if c_next.is_finite() && c_next <= cost {
                let small = step.norm() <= options.step_tolerance;
                let flat = cost - c_next <= options.cost_tolerance * cost;
                r = r_next;
                t = t_next;
                lambda = (lambda / 3.0).max(1e-12);
                accepted = true;
                let previous = cost;
                (cost, g, h) = normal_equations(a, b, subset, &r, &t, options, true);
                if small || flat || cost == 0.0 {
                    return Refined {
                        rotation: orthonormalized(&r),
                        translation: t,
                        iterations,
                        initial_cost,
                        final_cost: cost.min(previous),
                    };
                }
                break;
            }
            lambda *= 10.0;
        }
        if !accepted {
            break;
        }
    }
    Refined {
        rotation: orthonormalized(&r),
        translation: t,
        iterations,
        initial_cost,
        final_cost: cost,
    }
}

fn orthonormalized(r: &Matrix3<f64>) -> Matrix3<f64> {
    UnitQuaternion::from_matrix(r)
        .to_rotation_matrix()
        .into_inner()
}

#[derive(Debug, Clone, Copy)]
struct Model {
    rotation: Matrix3<f64>,
    translation: Vector3<f64>,
    essential: Matrix3<f64>,
    cost: f64,
}

impl Model {
    fn new(rotation: Matrix3<f64>, translation: Vector3<f64>) -> Self {
        Self {
            rotation,
            translation,
            essential: translation.cross_matrix() * rotation,
            cost: f64::INFINITY,
        }
    }
}

/// Whether the point of `(a, b)` is in front of both cameras of `model` (both depths along
/// the bearings positive), or so far that the sign of its depths is noise: a triangulation
/// angle (between `R a` and `b`) with `sin^2` at most `thr2`. A random match near its
/// epipolar line passes the epipolar test, but in about half the cases lies behind a camera.
#[inline]
fn in_front(model: &Model, a: &Vector3<f64>, b: &Vector3<f64>, thr2: f64) -> bool {
    let (la, lb) = depths(&model.rotation, &model.translation, a, b);
    (la > 0.0 && lb > 0.0) || (model.rotation * a).cross(b).norm_squared() <= thr2
}

struct Scorer<'a> {
    a: &'a [Vector3<f64>],
    b: &'a [Vector3<f64>],
    /// `threshold^2`.
    thr2: f64,
}

impl Scorer<'_> {
    /// MSAC cost `sum min(d^2, threshold^2)`, stopped once it reaches `bound`.
    #[inline]
    fn cost(&self, e: &Matrix3<f64>, bound: f64) -> f64 {
        let mut cost = 0.0;
        for (fa, fb) in self.a.iter().zip(self.b) {
            cost += sampson_squared(e, fa, fb).min(self.thr2);
            if cost >= bound {
                return cost;
            }
        }
        cost
    }

    /// The inliers of a pose: within the threshold of the epipolar constraint, and not
    /// behind either camera (see [`in_front`]).
    fn inliers(&self, model: &Model, out: &mut Vec<usize>) {
        out.clear();
        for (i, (fa, fb)) in self.a.iter().zip(self.b).enumerate() {
            if sampson_squared(&model.essential, fa, fb) <= self.thr2
                && in_front(model, fa, fb, self.thr2)
            {
                out.push(i);
            }
        }
    }

    fn score(&self, mut model: Model) -> Model {
        model.cost = self.cost(&model.essential, f64::INFINITY);
        model
    }
}

/// `count` distinct indices below `n` into `out` (`n >= count`).
pub(crate) fn sample_distinct(rng: &mut ChaCha8Rng, n: usize, out: &mut [usize]) {
    for k in 0..out.len() {
        loop {
            let candidate = rng.random_range(0..n);
            if !out[..k].contains(&candidate) {
                out[k] = candidate;
                break;
            }
        }
    }
}

/// Robust relative pose `b_from_a` from unit bearings `bearings_a[i]`, `bearings_b[i]` of the
/// same point in two views, with outliers (see the module docs): five-point LO-RANSAC on the
/// angular Sampson error, refinement on the essential manifold, and the choice between a
/// general scene, a plane and a pure rotation. Inliers are indices into the caller's slices.
///
/// # Errors
/// The input errors of [`crate::five_point`] (with at least [`RELATIVE_POSE_MIN_POINTS`]),
/// [`RelativePoseError::InvalidOption`], [`RelativePoseError::TooFewInliers`] when the best
/// model has fewer than `min_inliers` inliers, and
/// [`RelativePoseError::InsufficientParallax`] (with the rotation) when the inliers of an
/// essential or homography model have a median triangulation angle below `min_parallax`.
pub fn relative_pose(
    bearings_a: &[Vector3<f64>],
    bearings_b: &[Vector3<f64>],
    options: &RelativePoseOptions,
) -> RelativeResult<RelativePose> {
    check_bearing_pairs(
        "relative pose",
        RELATIVE_POSE_MIN_POINTS,
        bearings_a,
        bearings_b,
    )?;
    options.validate()?;
    let ransac = &options.ransac;
    let (a, b) = (bearings_a, bearings_b);
    let n = a.len();
    let scorer = Scorer {
        a,
        b,
        thr2: ransac.threshold * ransac.threshold,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(ransac.seed);
    let mut best: Option<Model> = None;
    let mut needed = adaptive_iterations(0, ransac.min_inliers, n, 5, ransac.confidence);
    let mut progressive = options.progressive.then(|| ProsacSampler::new(n, 5));
    let mut iterations = 0;
    let mut inliers: Vec<usize> = Vec::with_capacity(n);
    let mut sample = [0usize; 5];
    let lo_options = RefineOptions {
        max_iterations: LO_ITERATIONS,
        ..RefineOptions::default()
    };
    while iterations < needed.clamp(ransac.min_iterations, ransac.max_iterations) {
        iterations += 1;
        match progressive.as_mut() {
            Some(sampler) => sampler.sample(&mut rng, &mut sample),
            None => sample_distinct(&mut rng, n, &mut sample),
        }
        let sa = sample.map(|i| a[i]);
        let sb = sample.map(|i| b[i]);
        let Some(solutions) = solve(&sa, &sb, false) else {
            continue;
        };
        for e in &solutions {
            let Some(model) = cheiral_pose(e, &sa, &sb) else {
                continue;
            };
            let bound = best.as_ref().map_or(f64::INFINITY, |m| m.cost);
            let cost = scorer.cost(&model.essential, bound);
            if cost >= bound {
                continue;
            }
            let mut model = Model { cost, ..model };
            if ransac.local_optimization {
                model = local_optimization(&scorer, model, &lo_options, &mut inliers);
            }
            scorer.inliers(&model, &mut inliers);
            needed = if progressive.is_some() {
                prosac_iterations(&inliers, n, ransac.min_inliers, 5, ransac.confidence)
            } else {
                adaptive_iterations(inliers.len(), ransac.min_inliers, n, 5, ransac.confidence)
            };
            best = Some(model);
        }
    }
    let Some(mut model) = best else {
        return Err(RelativePoseError::TooFewInliers {
            found: 0,
            required: ransac.min_inliers,
            total: n,
        });
    };
    scorer.inliers(&model, &mut inliers);
    if ransac.final_refinement {
        let rounds = if progressive.is_some() {
            FINAL_ROUNDS_PROGRESSIVE
        } else {
            FINAL_ROUNDS
        };
        model = final_refit(&scorer, model, &ransac.refine, &mut inliers, rounds);
    }
    if inliers.len() < ransac.min_inliers {
        return Err(RelativePoseError::TooFewInliers {
            found: inliers.len(),
            required: ransac.min_inliers,
            total: n,
        });
    }
    let essential_inliers = inliers.clone();
    let mut gric = None;
    let mut outcome = Outcome::Essential(model);
    if options.model_selection && essential_inliers.len() >= SELECTION_MIN_POINTS {
        let sigma2 = (ransac.threshold / 3.0).powi(2);
        let m = essential_inliers.len();
        let base = |dimension: f64, parameters: f64| {
            4f64.ln() * dimension * m as f64 + (4.0 * m as f64).ln() * parameters
        };
        let gric_e = essential_inliers
            .iter()
            .map(|&i| (sampson_squared(&model.essential, &a[i], &b[i]) / sigma2).min(2.0))
            .sum::<f64>()
            + base(3.0, 5.0);
        let selection = Selection {
            a,
            b,
            subset: &essential_inliers,
            thr2: scorer.thr2,
        };
        let homography = selection.fit_homography(&mut rng);
        // A rotation is a homography, so its inliers are at most about the homography's;
        // with more than a fifth of the subset off a rotation, its GRIC exceeds the essential
        // matrix's (an outlier costs 4 + 2 ln 4 against 1 + 3 ln 4 for a typical inlier of E),
        // so the fit is skipped when the homography explains less than half.
        let homography_share = homography.as_ref().map_or(0.0, |h| {
            essential_inliers
                .iter()
                .filter(|&&i| homography_error(h, &a[i], &b[i]) <= scorer.thr2)
                .count() as f64
                / m as f64
        });
        let rotation = if homography_share >= 0.5 {
            selection.fit_rotation(&mut rng)
        } else {
            None
        };
        let gric_h = homography.as_ref().map_or(f64::INFINITY, |h| {
            essential_inliers
                .iter()
                .map(|&i| (homography_error(h, &a[i], &b[i]) / sigma2).min(4.0))
                .sum::<f64>()
                + base(2.0, 8.0)
        });
        let gric_r = rotation.as_ref().map_or(f64::INFINITY, |r| {
            essential_inliers
                .iter()
                .map(|&i| (rotation_error(r, &a[i], &b[i]) / sigma2).min(4.0))
                .sum::<f64>()
                + base(2.0, 3.0)
        });
        gric = Some(GricScores {
            essential: gric_e,
            homography: gric_h,
            rotation: gric_r,
        });
        if let Some(r) = rotation
            && gric_r < gric_e
            && gric_r <= gric_h
        {
            outcome = Outcome::Rotation(selection.finish_rotation(r, &mut inliers));
        } else if let Some(h) = homography
            && gric_h < gric_e
        {
            if let Some(planar) =
                finish_homography(&scorer, h, &ransac.refine, ransac, &mut inliers)
            {
                outcome = planar;
            } else {
                inliers.clone_from(&essential_inliers);
            }
        }
    }
    if inliers.len() < ransac.min_inliers {
        return Err(RelativePoseError::TooFewInliers {
            found: inliers.len(),
            required: ransac.min_inliers,
            total: n,
        });
    }
    let rotation = match &outcome {
        Outcome::Essential(m) | Outcome::Planar { model: m, .. } => m.rotation,
        Outcome::Rotation(r) => *r,
    };
    let mut parallaxes: Vec<f64> = inliers
        .iter()
        .map(|&i| {
            let u = rotation * a[i];
            u.cross(&b[i]).norm().atan2(u.dot(&b[i]))
        })
        .collect();
    parallaxes.sort_by(f64::total_cmp);
    let median_parallax = parallaxes.get(parallaxes.len() / 2).copied().unwrap_or(0.0);
    let (b_from_a, model, errors): (Isometry3<f64>, TwoViewModel, Vec<f64>) = match outcome {
        Outcome::Essential(m) => (
            isometry_from(&m.rotation, &m.translation),
            TwoViewModel::Essential {
                essential: m.essential,
            },
            inliers
                .iter()
                .map(|&i| sampson_squared(&m.essential, &a[i], &b[i]))
                .collect(),
        ),
        Outcome::Planar {
            model: m,
            homography,
            normal,
            alternative,
        } => {
            let pair = (
                homography,
                homography.try_inverse().unwrap_or_else(Matrix3::zeros),
            );
            (
                isometry_from(&m.rotation, &m.translation),
                TwoViewModel::Homography {
                    homography,
                    normal,
                    alternative,
                },
                inliers
                    .iter()
                    .map(|&i| homography_error(&pair, &a[i], &b[i]))
                    .collect(),
            )
        }
        Outcome::Rotation(r) => (
            isometry_from(&r, &Vector3::zeros()),
            TwoViewModel::PureRotation,
            inliers
                .iter()
                .map(|&i| rotation_error(&r, &a[i], &b[i]))
                .collect(),
        ),
    };
    if !matches!(model, TwoViewModel::PureRotation) && median_parallax < options.min_parallax {
        return Err(RelativePoseError::InsufficientParallax {
            median_parallax_deg: median_parallax.to_degrees(),
            minimum_deg: options.min_parallax.to_degrees(),
            rotation: b_from_a.rotation,
            inliers,
        });
    }
    let inlier_rms = if errors.is_empty() {
        0.0
    } else {
        (errors.iter().sum::<f64>() / errors.len() as f64).sqrt()
    };
    Ok(RelativePose {
        b_from_a,
        model,
        inliers,
        iterations,
        inlier_rms,
        median_parallax,
        gric,
    })
}

enum Outcome {
    Essential(Model),
    Planar {
        model: Model,
        homography: Matrix3<f64>,
        normal: Vector3<f64>,
        alternative: Option<PlanarPose>,
    },
    Rotation(Matrix3<f64>),
}

/// The pose of `e` that puts all five sample correspondences in front of both cameras.
fn cheiral_pose(e: &Matrix3<f64>, a: &[Vector3<f64>; 5], b: &[Vector3<f64>; 5]) -> Option<Model> {
    let (r1, r2, t) = rotations_and_translation(e)?;
    for r in [r1, r2] {
        // Both depths positive with +t, or both negative (positive with -t), for all five.
        let mut plus = 0;
        let mut minus = 0;
        for (fa, fb) in a.iter().zip(b) {
            let (la, lb) = depths(&r, &t, fa, fb);
            if la > 0.0 && lb > 0.0 {
                plus += 1;
            } else if la < 0.0 && lb < 0.0 {
                minus += 1;
            }
        }
        if plus == 5 {
            return Some(Model::new(r, t));
        }
        if minus == 5 {
            return Some(Model::new(r, -t));
        }
    }
    None
}

/// Refits a new best model on its inliers until its MSAC cost stops falling.
fn local_optimization(
    scorer: &Scorer<'_>,
    mut model: Model,
    options: &RefineOptions,
    inliers: &mut Vec<usize>,
) -> Model {
    for _ in 0..LO_ROUNDS {
        scorer.inliers(&model, inliers);
        if inliers.len() < RELATIVE_POSE_MIN_POINTS {
            break;
        }
        let refined = refine_on(
            scorer.a,
            scorer.b,
            inliers,
            &model.rotation,
            &model.translation,
            options,
            options.max_iterations,
        );
        let candidate = scorer.score(Model::new(refined.rotation, refined.translation));
        if !(candidate.cost < model.cost) {
            break;
        }
        model = candidate;
    }
    model
}

/// Refinement on the inliers until the inlier set is stable; leaves the final inliers in
/// `inliers`.
fn final_refit(
    scorer: &Scorer<'_>,
    mut model: Model,
    options: &RefineOptions,
    inliers: &mut Vec<usize>,
    rounds: usize,
) -> Model {
    let mut previous: Vec<usize> = Vec::new();
    for _ in 0..rounds {
        if inliers.len() < RELATIVE_POSE_MIN_POINTS || *inliers == previous {
            break;
        }
        let refined = refine_on(
            scorer.a,
            scorer.b,
            inliers,
            &model.rotation,
            &model.translation,
            options,
            options.max_iterations,
        );
        previous.clone_from(inliers);
        model = scorer.score(Model::new(refined.rotation, refined.translation));
        scorer.inliers(&model, inliers);
    }
    model
}

/// A homography and its inverse.
type HomographyPair = (Matrix3<f64>, Matrix3<f64>);

/// The squared angle-like transfer error of a homography: `(e_ab^2 + e_ba^2) / 4` with
/// `e_ab = |b x H a| / |H a|` (the sine of the angle between `b` and `H a`, infinite when
/// `H a` points away from `b`) and `e_ba` the same for `H^-1`; see the module docs.
#[inline]
fn homography_error(h: &HomographyPair, a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    let ha = h.0 * a;
    let hb = h.1 * b;
    if b.dot(&ha) <= 0.0 || a.dot(&hb) <= 0.0 {
        return f64::INFINITY;
    }
    let e1 = b.cross(&ha).norm_squared() / ha.norm_squared();
    let e2 = a.cross(&hb).norm_squared() / hb.norm_squared();
    0.25 * (e1 + e2)
}

/// The squared error of a rotation: `|b x R a|^2 / 2`, infinite when `R a` points away from
/// `b`; see the module docs.
#[inline]
fn rotation_error(r: &Matrix3<f64>, a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    let ra = r * a;
    if b.dot(&ra) <= 0.0 {
        return f64::INFINITY;
    }
    0.5 * b.cross(&ra).norm_squared()
}

/// Homography and rotation fits on the essential matrix's inliers, for model selection.
struct Selection<'a> {
    a: &'a [Vector3<f64>],
    b: &'a [Vector3<f64>],
    subset: &'a [usize],
    thr2: f64,
}

impl Selection<'_> {
    /// MSAC cost over the subset, stopped once it reaches `bound`.
    fn msac<M>(
        &self,
        model: &M,
        error: impl Fn(&M, &Vector3<f64>, &Vector3<f64>) -> f64,
        bound: f64,
    ) -> f64 {
        let mut cost = 0.0;
        for &i in self.subset {
            cost += error(model, &self.a[i], &self.b[i]).min(self.thr2);
            if cost >= bound {
                break;
            }
        }
        cost
    }

    fn collect<M>(
        &self,
        model: &M,
        error: impl Fn(&M, &Vector3<f64>, &Vector3<f64>) -> f64,
        over: &[usize],
        out: &mut Vec<usize>,
    ) {
        out.clear();
        out.extend(
            over.iter()
                .copied()
                .filter(|&i| error(model, &self.a[i], &self.b[i]) <= self.thr2),
        );
    }

    /// MSAC within the subset with a `K`-point `minimal` solver (given the sample's
    /// correspondence indices) and adaptive iterations, then two refits of the best model by
    /// `refit` on its inliers, each kept only when it lowers the cost.
    fn select<M, const K: usize>(
        &self,
        rng: &mut ChaCha8Rng,
        minimal: impl Fn([usize; K]) -> Option<M>,
        refit: impl Fn(&[usize]) -> Option<M>,
        error: impl Fn(&M, &Vector3<f64>, &Vector3<f64>) -> f64 + Copy,
    ) -> Option<M> {
        let m = self.subset.len();
        let mut best: Option<(M, f64)> = None;
        let mut needed = SELECTION_ITERATIONS;
        let mut iterations = 0;
        let mut pick = [0usize; K];
        let mut inliers = Vec::new();
        while iterations < needed.min(SELECTION_ITERATIONS) {
            iterations += 1;
            sample_distinct(rng, m, &mut pick);
            let Some(model) = minimal(pick.map(|k| self.subset[k])) else {
                continue;
            };
            let bound = best.as_ref().map_or(f64::INFINITY, |(_, c)| *c);
            let cost = self.msac(&model, error, bound);
            if cost < bound {
                self.collect(&model, error, self.subset, &mut inliers);
                needed = adaptive_iterations(inliers.len(), 0, m, K as i32, 0.999);
                best = Some((model, cost));
            }
        }
        let (mut model, mut cost) = best?;
        for _ in 0..2 {
            self.collect(&model, error, self.subset, &mut inliers);
            let Some(candidate) = refit(&inliers) else {
                break;
            };
            let c = self.msac(&candidate, error, f64::INFINITY);
            if !(c < cost) {
                break;
            }
            (model, cost) = (candidate, c);
        }
        Some(model)
    }

    /// Four-point RANSAC within the subset, then least squares on the inliers. The
    /// homography and its inverse.
    fn fit_homography(&self, rng: &mut ChaCha8Rng) -> Option<HomographyPair> {
        let minimal = |pick: [usize; 4]| {
            let sa = pick.map(|i| self.a[i]);
            let sb = pick.map(|i| self.b[i]);
            let h = homography_mod::solve_minimal(&sa, &sb)?;
            let signs: i32 = (0..4)
                .map(|k| if sb[k].dot(&(h * sa[k])) > 0.0 { 1 } else { -1 })
                .sum();
            let h = match signs {
                4 => h,
                -4 => -h,
                _ => return None,
            };
            Some((h, h.try_inverse()?))
        };
        let refit = |inliers: &[usize]| {
            let h = homography_mod::solve_least_squares(self.a, self.b, inliers)
                .and_then(|h| homography_mod::normalize(&h, self.a, self.b, Some(inliers)))?;
            Some((h, h.try_inverse()?))
        };
        self.select(rng, minimal, refit, homography_error)
    }

    /// Two-point RANSAC within the subset, then least squares (Kabsch) on the inliers.
    fn fit_rotation(&self, rng: &mut ChaCha8Rng) -> Option<Matrix3<f64>> {
        let minimal = |[i, j]: [usize; 2]| {
            let h = self.b[i] * self.a[i].transpose()
                + self.b[j] * self.a[j].transpose()
                + self.b[i].cross(&self.b[j]) * self.a[i].cross(&self.a[j]).transpose();
            rotation_from_correlation(&h)
        };
        let refit = |inliers: &[usize]| kabsch(self.a, self.b, inliers);
        self.select(rng, minimal, refit, rotation_error)
    }

    /// The selected rotation refit on its inliers among all correspondences.
    fn finish_rotation(&self, mut r: Matrix3<f64>, inliers: &mut Vec<usize>) -> Matrix3<f64> {
        let all: Vec<usize> = (0..self.a.len()).collect();
        for _ in 0..3 {
            self.collect(&r, rotation_error, &all, inliers);
            match kabsch(self.a, self.b, inliers) {
                Some(candidate) => r = candidate,
                None => break,
            }
        }
        self.collect(&r, rotation_error, &all, inliers);
        r
    }
}

/// The rotation minimizing `sum |b_i - R a_i|^2` over `subset`.
fn kabsch(a: &[Vector3<f64>], b: &[Vector3<f64>], subset: &[usize]) -> Option<Matrix3<f64>> {
    if subset.len() < 2 {
        return None;
    }
    let mut h = Matrix3::zeros();
    for &i in subset {
        h += b[i] * a[i].transpose();
    }
    rotation_from_correlation(&h)
}

/// The selected homography: refit on its inliers among all correspondences, decomposed, and
/// its best pose refined on the essential manifold. `None` if the decomposition gives no
/// pose with a translation (the caller then keeps the essential matrix).
fn finish_homography(
    scorer: &Scorer<'_>,
    h: HomographyPair,
    refine: &RefineOptions,
    ransac: &RansacOptions,
    inliers: &mut Vec<usize>,
) -> Option<Outcome> {
    let (a, b) = (scorer.a, scorer.b);
    let all: Vec<usize> = (0..a.len()).collect();
    let selection = Selection {
        a,
        b,
        subset: &all,
        thr2: scorer.thr2,
    };
    let mut model = h;
    for _ in 0..2 {
        selection.collect(&model, homography_error, &all, inliers);
        let Some(h) = homography_mod::solve_least_squares(a, b, inliers)
            .and_then(|h| homography_mod::normalize(&h, a, b, Some(inliers)))
        else {
            break;
        };
        let Some(inverse) = h.try_inverse() else {
            break;
        };
        model = (h, inverse);
    }
    selection.collect(&model, homography_error, &all, inliers);
    let mut poses = homography_mod::decompose(&model.0, a, b, inliers).into_iter();
    let first = poses.next()?;
    let t = first.b_from_a.translation.vector;
    if !(t.norm() > 0.0) {
        return None;
    }
    let mut pose = Model::new(
        first.b_from_a.rotation.to_rotation_matrix().into_inner(),
        t.normalize(),
    );
    if ransac.final_refinement && inliers.len() >= RELATIVE_POSE_MIN_POINTS {
        let refined = refine_on(
            a,
            b,
            inliers,
            &pose.rotation,
            &pose.translation,
            refine,
            refine.max_iterations,
        );
        pose = Model::new(refined.rotation, refined.translation);
    }
    Some(Outcome::Planar {
        model: scorer.score(pose),
        homography: model.0,
        normal: first.normal,
        alternative: poses.next(),
    })
}
