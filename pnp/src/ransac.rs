//! Robust absolute pose: RANSAC with the P3P kernel, MSAC scoring, local optimization and a
//! final refit.
//!
//! M. A. Fischler and R. C. Bolles, "Random Sample Consensus", Communications of the ACM
//! 24(6), 1981 (sampling and the adaptive iteration count); P. H. S. Torr and A. Zisserman,
//! "MLESAC: A new robust estimator with application to estimating image geometry", CVIU 78,
//! 2000 (the truncated-quadratic MSAC score); O. Chum, J. Matas and J. Kittler, "Locally
//! Optimized RANSAC", DAGM 2003 (the local optimization when a new best model appears).
//!
//! A correspondence is an inlier of a pose when the angle between its bearing and the
//! direction of its camera-frame point is at most `threshold` (and the point lies on the
//! bearing's side of the centre), so rays at any incidence are scored alike.

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::NonExhaustive;
use crate::epnp;
use crate::error::{PnpError, Result};
use crate::geometry::{bearing_angle, isometry_from};
use crate::p3p;
use crate::refine::{RefineOptions, refine_subset};
use crate::threshold::angle_from_pixels;
use crate::validate::{check_bearings_spread, check_correspondences, point_spread};

/// The inlier count below which a localization is refused: 25, the value of Heng et al.,
/// "Infrastructure-Based Calibration of a Multi-Camera Rig", ICRA 2014.
pub const DEFAULT_MIN_INLIERS: usize = 25;

/// Default inlier threshold, radians: 3.75e-3, which is 3 pixels at a focal length of 800
/// pixels: three standard deviations of one-pixel noise on the EPnP paper's camera, so 99 %
/// of true inliers pass. Set it for your camera and noise with [`angle_from_pixels`].
pub const DEFAULT_THRESHOLD: f64 = 3.75e-3;

/// Rounds of local optimization per new best model (refit on the inliers, rescore).
const LO_ROUNDS: usize = 4;

/// Levenberg-Marquardt iterations per local-optimization refit.
const LO_ITERATIONS: usize = 10;

/// Rounds of the final refit (refine on the inliers, recollect them) before giving up on a
/// stable inlier set.
const FINAL_ROUNDS: usize = 5;

/// Options of [`robust_pose`]. Write them in one expression,
/// `RansacOptions { threshold: 2e-3, seed: 7, ..Default::default() }`.
#[derive(Debug, Clone, PartialEq)]
pub struct RansacOptions {
    /// Inlier threshold on the angle between a bearing and its point's direction, radians, in
    /// `(0, pi/2)`. Default [`DEFAULT_THRESHOLD`].
    pub threshold: f64,
    /// Probability of drawing at least one all-inlier sample, for the adaptive iteration count
    /// `ln(1 - confidence) / ln(1 - w^3)` (`w` the best inlier ratio so far, and no lower than
    /// `min_inliers / n`: a model with fewer inliers is rejected anyway, so a search that has
    /// not found one stops once such a model, if there were one, would have been drawn at this
    /// confidence), in `(0, 1)`. Default 0.999.
    pub confidence: f64,
    /// Fewest iterations. Default 50.
    pub min_iterations: usize,
    /// Most iterations. Default 10 000.
    pub max_iterations: usize,
    /// Fewer inliers than this is [`PnpError::TooFewInliers`]. Default
    /// [`DEFAULT_MIN_INLIERS`] (25).
    pub min_inliers: usize,
    /// Refit every new best model on its inliers (LO-RANSAC). Default true.
    pub local_optimization: bool,
    /// Refit the best model on all its inliers (EPnP, then refinement with `refine`, until
    /// the inlier set is stable). Default true.
    pub final_refinement: bool,
    /// Options of the final refinement (its loss may be robust). Default
    /// [`RefineOptions::default`].
    pub refine: RefineOptions,
    /// Seed of the sampler: same seed, same result. Default 0.
    pub seed: u64,
    /// Keeps the struct open to new fields: write it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for RansacOptions {
    fn default() -> Self {
        Self {
            threshold: DEFAULT_THRESHOLD,
            confidence: 0.999,
            min_iterations: 50,
            max_iterations: 10_000,
            min_inliers: DEFAULT_MIN_INLIERS,
            local_optimization: true,
            final_refinement: true,
            refine: RefineOptions::default(),
            seed: 0,
            non_exhaustive: NonExhaustive::VALUE,
        }
    }
}

/// CamOdoCal's fixed number of P3P RANSAC iterations, reproduced by
/// [`RansacOptions::camodocal`].
pub const CAMODOCAL_ITERATIONS: usize = 70;

/// CamOdoCal's inlier threshold in pixels.
pub const CAMODOCAL_THRESHOLD_PX: f64 = 2.0;

impl RansacOptions {
    /// A preset that mimics CamOdoCal's localization, for comparisons: P3P on a fixed
    /// [`CAMODOCAL_ITERATIONS`] (70) samples, a [`CAMODOCAL_THRESHOLD_PX`] (2 px) threshold
    /// for a camera of focal length `focal_px`, 25 inliers, and neither local optimization nor
    /// a final refit (the pose is that of the best sample).
    ///
    /// # Errors
    /// [`PnpError::InvalidOption`] if `focal_px` is not finite and positive.
    pub fn camodocal(focal_px: f64) -> Result<Self> {
        Ok(Self {
            threshold: angle_from_pixels(CAMODOCAL_THRESHOLD_PX, focal_px)?,
            min_iterations: CAMODOCAL_ITERATIONS,
            max_iterations: CAMODOCAL_ITERATIONS,
            min_inliers: DEFAULT_MIN_INLIERS,
            local_optimization: false,
            final_refinement: false,
            ..Self::default()
        })
    }

    /// Checks every option's range: a threshold in `(0, pi/2)`, a confidence in `(0, 1)`,
    /// `min_iterations <= max_iterations`, at least 3 inliers, and the refinement's options.
    ///
    /// # Errors
    /// [`PnpError::InvalidOption`] or [`PnpError::InvalidLossScale`] naming the option.
    pub fn validate(&self) -> Result<()> {
        let invalid =
            |name: &'static str, reason: String| Err(PnpError::InvalidOption { name, reason });
        if !(self.threshold > 0.0 && self.threshold < core::f64::consts::FRAC_PI_2) {
            return invalid(
                "threshold",
                format!(
                    "must be an angle in (0, pi/2) radians, got {}",
                    self.threshold
                ),
            );
        }
        if !(self.confidence > 0.0 && self.confidence < 1.0) {
            return invalid(
                "confidence",
                format!("must be in (0, 1), got {}", self.confidence),
            );
        }
        if self.max_iterations == 0 {
            return invalid("max_iterations", "must be at least 1".into());
        }
        if self.min_iterations > self.max_iterations {
            return invalid(
                "min_iterations",
                format!(
                    "{} exceeds max_iterations {}",
                    self.min_iterations, self.max_iterations
                ),
            );
        }
        self.refine.validate()
    }
}

/// The outcome of [`robust_pose`].
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct RobustPose {
    /// The estimated `camera_from_world`.
    pub camera_from_world: Isometry3<f64>,
    /// Indices (increasing) of the correspondences within the threshold of the final pose.
    pub inliers: Vec<usize>,
    /// RANSAC iterations (samples) drawn.
    pub iterations: usize,
    /// Root mean square of the inliers' angular errors, radians.
    pub inlier_rms: f64,
}

/// Robust camera pose from bearing / world point correspondences with outliers: RANSAC over
/// P3P samples with MSAC scoring, an adaptive iteration count, local optimization of every new
/// best model, and a final refit (EPnP and refinement) on all inliers. See the module docs.
///
/// # Errors
/// The input errors of [`crate::epnp`] (with at least 3 correspondences; coincident or
/// collinear world points and parallel bearings are refused up front),
/// [`PnpError::InvalidOption`], and [`PnpError::TooFewInliers`] (with the count found) when
/// the best pose has fewer than `min_inliers` inliers.
pub fn robust_pose(
    bearings: &[Vector3<f64>],
    points: &[Point3<f64>],
    options: &RansacOptions,
) -> Result<RobustPose> {
    check_correspondences("robust pose", 3, bearings, points)?;
    options.validate()?;
    check_bearings_spread(bearings)?;
    point_spread(points)?;
    let n = bearings.len();
    let scorer = Scorer {
        bearings,
        points,
        tan2: options.threshold.tan().powi(2),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let mut best: Option<Model> = None;
    let min_inliers = options.min_inliers;
    let mut needed = adaptive_iterations(0, min_inliers, n, 3, options.confidence);
    let mut iterations = 0;
    let mut inliers = Vec::with_capacity(n);
    while iterations < needed.clamp(options.min_iterations, options.max_iterations) {
        iterations += 1;
        let [i, j, k] = sample_three(&mut rng, n);
        let y = [bearings[i], bearings[j], bearings[k]];
        let x = [points[i], points[j], points[k]];
        for &(rotation, translation) in p3p::solve_raw(&y, &x).iter() {
            let bound = best.as_ref().map_or(f64::INFINITY, |b| b.cost);
            let cost = scorer.cost(&rotation, &translation, bound);
            if cost >= bound {
                continue;
            }
            let mut model = Model {
                rotation,
                translation,
                cost,
            };
            if options.local_optimization {
                model = local_optimization(&scorer, model, &mut inliers);
            }
            scorer.inliers(&model.rotation, &model.translation, &mut inliers);
            needed = adaptive_iterations(inliers.len(), min_inliers, n, 3, options.confidence);
            best = Some(model);
        }
    }
    let Some(mut model) = best else {
        return Err(PnpError::TooFewInliers {
            found: 0,
            required: options.min_inliers,
            total: n,
        });
    };
    scorer.inliers(&model.rotation, &model.translation, &mut inliers);
    if options.final_refinement {
        model = final_refit(&scorer, model, &options.refine, &mut inliers);
    }
    if inliers.len() < options.min_inliers {
        return Err(PnpError::TooFewInliers {
            found: inliers.len(),
            required: options.min_inliers,
            total: n,
        });
    }
    let sum_sq: f64 = inliers
        .iter()
        .map(|&i| {
            bearing_angle(
                &bearings[i],
                &(model.rotation * points[i].coords + model.translation),
            )
            .powi(2)
        })
        .sum();
    let inlier_rms = if inliers.is_empty() {
        0.0
    } else {
        (sum_sq / inliers.len() as f64).sqrt()
    };
    Ok(RobustPose {
        camera_from_world: isometry_from(&model.rotation, &model.translation),
        inliers,
        iterations,
        inlier_rms,
    })
}

/// Three distinct indices below `n` (`n >= 3`).
fn sample_three(rng: &mut ChaCha8Rng, n: usize) -> [usize; 3] {
    let i = rng.random_range(0..n);
    let mut j = rng.random_range(0..n - 1);
    if j >= i {
        j += 1;
    }
    let (lo, hi) = (i.min(j), i.max(j));
    let mut k = rng.random_range(0..n - 2);
    if k >= lo {
        k += 1;
    }
    if k >= hi {
        k += 1;
    }
    [i, j, k]
}

/// The iterations RANSAC needs (Fischler and Bolles): `ln(1 - confidence) / ln(1 - w^size)`,
/// saturating, for the inlier ratio `w = max(best, min_inliers) / n` of samples of `size`
/// correspondences. A model with fewer than `min_inliers` inliers is rejected anyway, so
/// while the best found has fewer, the count is the one that would have drawn an all-inlier
/// sample of any model with `min_inliers` at the given confidence: a search for a model that
/// is not there stops there instead of at `max_iterations`.
pub(crate) fn adaptive_iterations(
    best: usize,
    min_inliers: usize,
    n: usize,
    size: i32,
    confidence: f64,
) -> usize {
    let w = best.max(min_inliers) as f64 / n as f64;
    let all_inlier = w.powi(size);
    if all_inlier >= 1.0 {
        return 0;
    }
    let needed = (1.0 - confidence).ln() / (-all_inlier).ln_1p();
    if needed.is_finite() && needed < usize::MAX as f64 {
        needed.ceil() as usize
    } else {
        usize::MAX
    }
}

#[derive(Debug, Clone, Copy)]
struct Model {
    rotation: Matrix3<f64>,
    translation: Vector3<f64>,
    cost: f64,
}

struct Scorer<'a> {
    bearings: &'a [Vector3<f64>],
    points: &'a [Point3<f64>],
    /// `tan^2(threshold)`.
    tan2: f64,
}

impl Scorer<'_> {
    /// MSAC cost `sum min(tan^2(angle), tan^2(threshold))`, a point behind its ray counting as
    /// an outlier. Stops early once the sum reaches `bound`.
    #[inline]
    fn cost(&self, rotation: &Matrix3<f64>, translation: &Vector3<f64>, bound: f64) -> f64 {
        let mut cost = 0.0;
        for (f, x) in self.bearings.iter().zip(self.points) {
            let p = rotation * x.coords + translation;
            let along = f.dot(&p);
            let across = p.norm_squared() - along * along;
            cost += if along > 0.0 && across <= self.tan2 * along * along {
                across / (along * along)
            } else {
                self.tan2
            };
            if cost >= bound {
                return cost;
            }
        }
        cost
    }

    /// Indices of the inliers of a pose, into `out`.
    fn inliers(&self, rotation: &Matrix3<f64>, translation: &Vector3<f64>, out: &mut Vec<usize>) {
        out.clear();
        for (i, (f, x)) in self.bearings.iter().zip(self.points).enumerate() {
            let p = rotation * x.coords + translation;
            let along = f.dot(&p);
            if along > 0.0 && p.norm_squared() - along * along <= self.tan2 * along * along {
                out.push(i);
            }
        }
    }

    fn full_cost(&self, rotation: &Matrix3<f64>, translation: &Vector3<f64>) -> f64 {
        self.cost(rotation, translation, f64::INFINITY)
    }
}

/// Refits a new best model on its inliers until its MSAC cost stops falling.
fn local_optimization(scorer: &Scorer<'_>, mut model: Model, inliers: &mut Vec<usize>) -> Model {
    let options = RefineOptions {
        max_iterations: LO_ITERATIONS,
        ..RefineOptions::default()
    };
    for _ in 0..LO_ROUNDS {
        scorer.inliers(&model.rotation, &model.translation, inliers);
        if inliers.len() < 3 {
            break;
        }
        let Some(refined) = refit(scorer, &model, inliers, &options) else {
            break;
        };
        if refined.cost.is_nan() || refined.cost >= model.cost {
            break;
        }
        model = refined;
    }
    model
}

/// EPnP on all inliers (kept if it scores better), then refinement on the inliers until the
/// inlier set is stable. Leaves the final inliers in `inliers`.
fn final_refit(
    scorer: &Scorer<'_>,
    mut model: Model,
    options: &RefineOptions,
    inliers: &mut Vec<usize>,
) -> Model {
    // Refinement follows, so EPnP's second (depth-reweighted) pass would buy nothing here.
    let single_pass = epnp::EpnpOptions {
        depth_reweighting: false,
        ..epnp::EpnpOptions::default()
    };
    if inliers.len() >= epnp::EPNP_MIN_POINTS {
        let b: Vec<Vector3<f64>> = inliers.iter().map(|&i| scorer.bearings[i]).collect();
        let x: Vec<Point3<f64>> = inliers.iter().map(|&i| scorer.points[i]).collect();
        if let Ok(s) = point_spread(&x)
            && let Ok(candidate) = epnp::solve(&b, &x, &s, &single_pass)
        {
            let cost = scorer.full_cost(&candidate.rotation, &candidate.translation);
            if cost < model.cost {
                model = Model {
                    rotation: candidate.rotation,
                    translation: candidate.translation,
                    cost,
                };
                scorer.inliers(&model.rotation, &model.translation, inliers);
            }
        }
    }
    let mut previous: Vec<usize> = Vec::new();
    for _ in 0..FINAL_ROUNDS {
        if inliers.len() < 3 || *inliers == previous {
            break;
        }
        let Some(refined) = refit(scorer, &model, inliers, options) else {
            break;
        };
        previous.clone_from(inliers);
        model = refined;
        scorer.inliers(&model.rotation, &model.translation, inliers);
    }
    model
}

/// Refinement of `model` on the correspondences `inliers`, rescored on all of them.
fn refit(
    scorer: &Scorer<'_>,
    model: &Model,
    inliers: &[usize],
    options: &RefineOptions,
) -> Option<Model> {
    let start = isometry_from(&model.rotation, &model.translation);
    let refined = refine_subset(
        scorer.bearings,
        scorer.points,
        inliers,
        None,
        &start,
        options,
    )
    .ok()?;
    let pose = refined.camera_from_world;
    let rotation = pose.rotation.to_rotation_matrix().into_inner();
    let translation = pose.translation.vector;
    Some(Model {
        rotation,
        translation,
        cost: scorer.full_cost(&rotation, &translation),
    })
}

#[cfg(test)]
mod tests {
    use super::adaptive_iterations;

    /// ln(1 - 0.999) / ln(1 - w^5) for the larger of the best ratio and `min_inliers / n`.
    #[test]
    fn a_search_without_min_inliers_stops_where_such_a_model_would_have_been_drawn() {
        let expected = |w: f64| ((0.001f64).ln() / (1.0 - w.powi(5)).ln()).ceil() as usize;
        // Best 10 of 60, 30 required: the count of a ratio of one half (218), not of 1/6.
        assert_eq!(adaptive_iterations(10, 30, 60, 5, 0.999), expected(0.5));
        assert_eq!(expected(0.5), 218);
        // Once the best has more than `min_inliers`, its own ratio.
        assert_eq!(adaptive_iterations(45, 30, 60, 5, 0.999), expected(0.75));
        // Without a floor, the best ratio alone; none found, no bound.
        assert_eq!(
            adaptive_iterations(10, 0, 60, 5, 0.999),
            expected(1.0 / 6.0)
        );
        assert_eq!(adaptive_iterations(0, 0, 60, 5, 0.999), usize::MAX);
        // More required than there are correspondences: nothing to search.
        assert_eq!(adaptive_iterations(0, 70, 60, 3, 0.999), 0);
    }
}
