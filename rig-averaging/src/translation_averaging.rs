//! Translation averaging from relative directions, robust to outlier edges, per view or in the
//! rig form.
//!
//! B. Zhuang, L.-F. Cheong and G. H. Lee, "Baseline Desensitizing in Translation Averaging"
//! (BATA), CVPR 2018. The positions `p_k` of the view centres minimize
//! `sum_e rho(|d_e (p_j - p_i) - v_e|)` over the positions and one auxiliary `d_e >= 0` per edge
//! (the inverse of the edge's length at the optimum), where `v_e` is the measured unit
//! direction. For the optimal `d_e` the residual is the sine of the angle between the measured
//! and estimated directions (1 beyond 90 degrees), whatever the baseline's length: long and
//! short edges count alike, unlike the least unsquared deviations of LUD (Ozyesil and Singer,
//! CVPR 2015) whose residuals are distances. This file solves it in three phases:
//!
//! 1. **Least squares by BATA's alternation** (the paper's scheme), from every `d_e = 1`:
//!    the `d`-step in closed form, `d_e = max(0, v_e . (p_j - p_i)) / |p_j - p_i|^2`, then the
//!    `p`-step, the sparse weighted least squares
//!    `min sum_e w_e d_e^2 |p_j - p_i - v_e / d_e|^2` (an edge with `d_e = 0`, pointing against
//!    its measurement, drops out), by conjugate gradients (see `viewing_graph.rs`),
//!    warm-started at the current positions.
//! 2. **Robust Gauss-Newton** on the baseline-free residual `r_e = u_e - v_e`, `u_e` the unit
//!    estimated direction (the chordal distance `2 sin(theta / 2)` between the directions,
//!    which unlike BATA's `sin(theta)` still pulls a view whose edge points backwards), first
//!    with L1 weights `1 / max(|r|, 1e-3)`, then with Cauchy weights `1 / (1 + |r|^2 / c^2)`,
//!    `c` given or [`DIRECTION_SCALE_FACTOR`] times the median residual after the L1 phase.
//!    Each step solves the linearized least squares (3x3 information `J^T J` per edge, rank
//!    2) and is halved until the cost decreases. Alternation converges linearly and slowly;
//!    Gauss-Newton finishes in a few steps.
//! 3. **Re-seeding** of views stuck in a wrong basin (a view with few edges and several
//!    outliers): for every time, the rig position minimizing the Cauchy cost of its edges among
//!    the current one and the closest points of every two of its edges' rays, the rest fixed
//!    (a block coordinate descent step, so the cost decreases); if any time moved, the Cauchy
//!    phase runs again.
//!
//! With `robust: false` phase 2 is plain least squares on the same residual and phase 3 is
//! skipped: a least-squares baseline.
//!
//! The **rig form** has one position per time (`world_from_rig` translation, `P_t`) and one
//! lever arm per camera (`rig_from_camera` translation, `l_c`), with the rig rotations `W_t`
//! known (from [`rig_rotation_averaging`](crate::rig_rotation_averaging)): view (t, c) is at
//! `P_t + W_t l_c`, linear in the unknowns, so the same `p`-step applies with 3x3 blocks.
//!
//! **Measured distances** ([`rig_translation_averaging_with_distances`]): directions leave the
//! spacing of collinear positions free (a straight drive: every edge along it has the same
//! direction whatever the spacing), which the averaging can then only guess and its solves
//! converge slowly along. A distance `L` between the rig positions of two times, with its
//! standard deviation `sigma` (for example the distance the wheel odometry travelled between
//! two frames of the same heading, where the rig's own origin moved as far), adds the residual
//! `(|P_b - P_a| - L) s / sigma` with `s` the direction noise (the median direction residual
//! over 1.1774, per phase) so that both are in the same unit and the same loss; in the
//! alternation of phase 1 it is `|P_b - P_a - L u|`, `u` the current direction (BATA's
//! `d`-step with the length known). The distances then fix the scale.
//!
//! **Gauge**: the first kept view (rig form: the anchor time's rig position) is at the origin,
//! the reference camera's lever arm is zero, and the **scale is the caller's**
//! ([`ScaleGauge`]): by default the mean length of the kept inlier edges is 1; or the distance
//! between two views is a given length (for example a known lever arm, or a distance travelled
//! by odometry). Per view, views with fewer than two edges are dropped first (repeatedly):
//! their distance along their one edge is not determined.

use nalgebra::{Matrix3, UnitQuaternion, Vector3};

use crate::NonExhaustive;
use crate::error::ViewingGraphError;
use crate::rotation_averaging::{MIN_GRAPH_SCALE, OUTLIER_SCALE_FACTOR};
use crate::viewing_graph::{
    AveragingReport, CG_STEP_TOLERANCE, CgScratch, DirectionEdge, Prepared, RigLayout,
    check_edge_weight, check_ends, is_unit, median,
};

/// Factor from the median direction residual to the Cauchy scale.
///
/// Direction noise of `sigma` per axis in the tangent plane gives residuals `sigma * chi_2`,
/// whose median is `1.1774 sigma` (`sqrt(2 ln 2)`); the Cauchy scale with 95 % asymptotic
/// efficiency under Gaussian noise is `2.3849 sigma` (Holland and Welsch, 1977).
pub const DIRECTION_SCALE_FACTOR: f64 = 2.3849 / 1.1774;

/// Smallest residual in the L1 weights of translation averaging, `1 / max(r, floor)`:
/// 1e-3 (0.06 degree) keeps the conjugate-gradient solves well conditioned; below it the loss is
/// quadratic, which changes nothing for direction noise of a tenth of a degree or more.
pub const DIRECTION_L1_FLOOR: f64 = 1e-3;

/// Relative residual of the conjugate-gradient solve of a least-squares alternation's position
/// step and of an L1 Gauss-Newton step (the final phase solves to 1e-6): an inexact step
/// (Dembo, Eisenstat and Steihaug, "Inexact Newton methods", SIAM J. Numer. Anal. 1982) is
/// still a descent direction, checked by the step halving, and costs far fewer iterations on
/// the poorly scaled direction systems (their weights go as 1 / length^2).
const GAUSS_NEWTON_CG_TOLERANCE: f64 = 1e-3;

/// How the scale of the positions is fixed (translation averaging sees directions only).
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum ScaleGauge {
    /// The mean length of the kept edges that are not outliers is 1 (default).
    MeanBaseline,
    /// The distance between the centres of views `from` and `to` is `distance`.
    ViewDistance {
        /// The first view.
        from: usize,
        /// The second view.
        to: usize,
        /// Their distance (finite, positive), in the caller's unit.
        distance: f64,
    },
}

/// A measured distance between the rig positions (`world_from_rig` translations) of two
/// times, for [`rig_translation_averaging_with_distances`].
///
/// The rig's origin is the reference camera's centre: a distance travelled by odometry is that
/// of the rig's origin only where the rig did not turn between the two times (else the lever
/// arm from the odometry's origin to the rig's adds to it); `sigma` should include that.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeDistance {
    /// The first time.
    pub from: usize,
    /// The second time.
    pub to: usize,
    /// The distance (finite, positive), in the unit the positions are to have.
    pub distance: f64,
    /// Its standard deviation (finite, positive), same unit.
    pub sigma: f64,
}

impl TimeDistance {
    /// A distance `distance` with standard deviation `sigma` between the rig positions of
    /// times `from` and `to`.
    pub fn new(from: usize, to: usize, distance: f64, sigma: f64) -> Self {
        Self {
            from,
            to,
            distance,
            sigma,
        }
    }
}

/// Options of [`translation_averaging`] and [`rig_translation_averaging`].
///
/// With `robust: false` the result is the least-squares BATA (a baseline without
/// robustness).
///
/// ```
/// use ibc_rig_averaging::{ScaleGauge, TranslationAveragingOptions};
///
/// let options = TranslationAveragingOptions {
///     scale: ScaleGauge::ViewDistance { from: 0, to: 1, distance: 0.5 },
///     ..Default::default()
/// };
/// assert_eq!(options.irls_iterations, 30);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TranslationAveragingOptions {
    /// Least-squares alternations at most, from `d_e = 1` (default 10).
    pub ls_iterations: usize,
    /// L1-weighted Gauss-Newton iterations at most (default 10; skipped when `robust` is
    /// false).
    pub l1_iterations: usize,
    /// Gauss-Newton iterations at most of the final phase (default 30; again as many after a
    /// re-seeding that moved a view), Cauchy-weighted when `robust`, least squares otherwise.
    pub irls_iterations: usize,
    /// Whether the solve is robust (default true): false skips the L1 phase and makes the
    /// final phase least squares, the baseline without robustness.
    pub robust: bool,
    /// Cauchy scale of the residual (the sine of the direction error), `None` (default):
    /// [`DIRECTION_SCALE_FACTOR`] times the median residual after the L1 phase, at least
    /// [`MIN_GRAPH_SCALE`](crate::MIN_GRAPH_SCALE).
    pub robust_scale: Option<f64>,
    /// Direction error above which a kept edge is reported as an outlier, radians; `None`
    /// (default): [`OUTLIER_SCALE_FACTOR`](crate::OUTLIER_SCALE_FACTOR) times the Cauchy
    /// scale.
    pub outlier_threshold: Option<f64>,
    /// A phase stops when the largest position change of an alternation is below this
    /// fraction of the mean edge length (default 1e-6).
    pub tolerance: f64,
    /// How the scale is fixed (default [`ScaleGauge::MeanBaseline`]).
    pub scale: ScaleGauge,
    /// Rig form: the camera whose lever arm is zero (default 0). Unused per view.
    pub reference_camera: usize,
    /// Keeps the struct open to new fields: write it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for TranslationAveragingOptions {
    fn default() -> Self {
        Self {
            ls_iterations: 10,
            l1_iterations: 10,
            irls_iterations: 30,
            robust: true,
            robust_scale: None,
            outlier_threshold: None,
            tolerance: 1e-6,
            scale: ScaleGauge::MeanBaseline,
            reference_camera: 0,
            non_exhaustive: NonExhaustive(()),
        }
    }
}

impl TranslationAveragingOptions {
    fn validate(&self, views: usize) -> Result<(), ViewingGraphError> {
        let positive = |v: Option<f64>| v.is_none_or(|v| v.is_finite() && v > 0.0);
        if !positive(self.robust_scale) {
            return Err(ViewingGraphError::InvalidOption {
                option: "robust_scale",
                reason: "must be finite and positive",
            });
        }
        if !positive(self.outlier_threshold) {
            return Err(ViewingGraphError::InvalidOption {
                option: "outlier_threshold",
                reason: "must be finite and positive",
            });
        }
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            return Err(ViewingGraphError::InvalidOption {
                option: "tolerance",
                reason: "must be finite and positive",
            });
        }
        if self.ls_iterations + self.l1_iterations + self.irls_iterations == 0 {
            return Err(ViewingGraphError::InvalidOption {
                option: "ls_iterations",
                reason: "at least one iteration must run (in some phase)",
            });
        }
        if let ScaleGauge::ViewDistance { from, to, distance } = self.scale {
            if !(distance.is_finite() && distance > 0.0) {
                return Err(ViewingGraphError::InvalidOption {
                    option: "scale",
                    reason: "the distance must be finite and positive",
                });
            }
            for view in [from, to] {
                if view >= views {
                    return Err(ViewingGraphError::InvalidScaleGauge {
                        view,
                        reason: "no such view",
                    });
                }
            }
            if from == to {
                return Err(ViewingGraphError::InvalidScaleGauge {
                    view: from,
                    reason: "the two views are the same",
                });
            }
        }
        Ok(())
    }
}

/// The result of [`translation_averaging`].
#[derive(Clone, Debug, PartialEq)]
pub struct TranslationAveraging {
    /// World position of every view's centre; `None` for a dropped view. The first kept view
    /// is at the origin; the scale is the options' [`ScaleGauge`].
    pub positions: Vec<Option<Vector3<f64>>>,
    /// What was kept, dropped and found.
    pub report: AveragingReport,
}

/// The result of [`rig_translation_averaging`].
#[derive(Clone, Debug, PartialEq)]
pub struct RigTranslationAveraging {
    /// `world_from_rig` translation of every time; `None` for a time without a kept view. The
    /// anchor time's (the first with a kept view of the reference camera) is zero.
    pub rig_positions: Vec<Option<Vector3<f64>>>,
    /// `rig_from_camera` translation (lever arm) of every camera; the reference camera's is
    /// zero.
    pub lever_arms: Vec<Vector3<f64>>,
    /// World position of every view's centre, `P_t + W_t l_c`; `None` for a dropped view.
    pub positions: Vec<Option<Vector3<f64>>>,
    /// How many of the distances given were used (both times kept with a view of the
    /// reference camera); when any was, they fixed the scale.
    pub distances_used: usize,
    /// What was kept, dropped and found.
    pub report: AveragingReport,
}

/// Averages the relative directions of a viewing graph of `views` views into one position per
/// view (see the module documentation for the method, the gauge and the scale).
///
/// # Errors
///
/// [`ViewingGraphError`]: no views or edges, an edge naming a missing view or joining a view
/// to itself, a non-unit or non-finite direction, a bad weight or option, a scale gauge naming
/// a dropped view, or positions that collapse.
pub fn translation_averaging(
    views: usize,
    edges: &[DirectionEdge],
    options: &TranslationAveragingOptions,
) -> Result<TranslationAveraging, ViewingGraphError> {
    let layout = RigLayout::single_camera(views);
    let options = TranslationAveragingOptions {
        reference_camera: 0,
        ..*options
    };
    let rotations = vec![Some(UnitQuaternion::identity()); views];
    let solved = solve(&layout, &rotations, edges, &[], &options, 2)?;
    Ok(TranslationAveraging {
        positions: solved.positions,
        report: solved.report,
    })
}

/// Averages the relative directions between the views of a rig into one position per time and
/// one lever arm per camera, given the rig rotations `world_from_rig` (one per time of
/// `layout`; a view whose time has `None` is dropped).
///
/// # Errors
///
/// As [`translation_averaging`], and [`ViewingGraphError::RotationCountMismatch`],
/// [`ViewingGraphError::InvalidRotation`], [`ViewingGraphError::UndeterminedCamera`] (as in
/// [`rig_rotation_averaging`](crate::rig_rotation_averaging)).
pub fn rig_translation_averaging(
    layout: &RigLayout,
    world_from_rig: &[Option<UnitQuaternion<f64>>],
    edges: &[DirectionEdge],
    options: &TranslationAveragingOptions,
) -> Result<RigTranslationAveraging, ViewingGraphError> {
    rig_translation_averaging_with_distances(layout, world_from_rig, edges, &[], options)
}

/// As [`rig_translation_averaging`], with measured `distances` between the rig positions of
/// pairs of times (see the module documentation). A distance whose two times are not both kept
/// with a view of the reference camera is not used; when at least one is, the distances fix
/// the scale and `options.scale` must be [`ScaleGauge::MeanBaseline`] (the default), which
/// they replace.
///
/// # Errors
///
/// As [`rig_translation_averaging`], and [`ViewingGraphError::InvalidDistance`] for a distance
/// naming a missing time or one time twice, or with a distance or standard deviation that is
/// not finite and positive; [`ViewingGraphError::InvalidOption`] for distances with
/// [`ScaleGauge::ViewDistance`].
pub fn rig_translation_averaging_with_distances(
    layout: &RigLayout,
    world_from_rig: &[Option<UnitQuaternion<f64>>],
    edges: &[DirectionEdge],
    distances: &[TimeDistance],
    options: &TranslationAveragingOptions,
) -> Result<RigTranslationAveraging, ViewingGraphError> {
    if options.reference_camera >= layout.cameras() {
        return Err(ViewingGraphError::InvalidOption {
            option: "reference_camera",
            reason: "must be a camera of the layout",
        });
    }
    for (index, d) in distances.iter().enumerate() {
        let reason = if d.from >= layout.times() || d.to >= layout.times() {
            Some("no such time")
        } else if d.from == d.to {
            Some("the two times are the same")
        } else if !(d.distance.is_finite() && d.distance > 0.0) {
            Some("the distance must be finite and positive")
        } else if !(d.sigma.is_finite() && d.sigma > 0.0) {
            Some("the standard deviation must be finite and positive")
        } else {
            None
        };
        if let Some(reason) = reason {
            return Err(ViewingGraphError::InvalidDistance { index, reason });
        }
    }
    if !distances.is_empty() && options.scale != ScaleGauge::MeanBaseline {
        return Err(ViewingGraphError::InvalidOption {
            option: "scale",
            reason: "measured distances fix the scale: leave the gauge at MeanBaseline",
        });
    }
    solve(layout, world_from_rig, edges, distances, options, 0)
}

fn solve(
    layout: &RigLayout,
    world_from_rig: &[Option<UnitQuaternion<f64>>],
    edges: &[DirectionEdge],
    distances: &[TimeDistance],
    options: &TranslationAveragingOptions,
    min_degree: usize,
) -> Result<RigTranslationAveraging, ViewingGraphError> {
    let n_views = layout.views().len();
    if n_views == 0 {
        return Err(ViewingGraphError::NoViews);
    }
    options.validate(n_views)?;
    if world_from_rig.len() != layout.times() {
        return Err(ViewingGraphError::RotationCountMismatch {
            expected: layout.times(),
            found: world_from_rig.len(),
        });
    }
    let mut w = vec![Matrix3::identity(); layout.times()];
    for (index, (m, q)) in w.iter_mut().zip(world_from_rig).enumerate() {
        if let Some(q) = q {
            let norm = q.coords.norm();
            if !is_unit(norm) {
                return Err(ViewingGraphError::InvalidRotation { index, norm });
            }
            *m = q.to_rotation_matrix().into_inner();
        }
    }
    if edges.is_empty() {
        return Err(ViewingGraphError::NoEdges);
    }
    let mut pairs = Vec::with_capacity(edges.len());
    for (e, edge) in edges.iter().enumerate() {
        check_ends(e, edge.i, edge.j, n_views)?;
        let norm = edge.direction.norm();
        if !is_unit(norm) {
            return Err(ViewingGraphError::NotUnitDirection { edge: e, norm });
        }
        check_edge_weight(e, edge.weight)?;
        pairs.push([edge.i, edge.j]);
    }
    let usable: Vec<bool> = layout
        .views()
        .iter()
        .map(|v| world_from_rig[v.time].is_some())
        .collect();
    let prepared = Prepared::new(
        layout,
        &pairs,
        &usable,
        min_degree,
        options.reference_camera,
    )?;
    if let ScaleGauge::ViewDistance { from, to, .. } = options.scale {
        for view in [from, to] {
            if prepared.component.views.binary_search(&view).is_err() {
                return Err(ViewingGraphError::InvalidScaleGauge {
                    view,
                    reason: "the view is not in the solved component",
                });
            }
        }
    }
    let kept = &prepared.component.edges;
    let directions: Vec<Vector3<f64>> = kept.iter().map(|&e| edges[e].direction).collect();
    let base_weights: Vec<f64> = kept.iter().map(|&e| edges[e].weight).collect();
    // The distances between kept times, as edges between their reference camera's views
    // (at the rig positions themselves), after the direction edges.
    let mut reference_view = vec![None; layout.times()];
    for (k, (&t, &c)) in prepared
        .view_time
        .iter()
        .zip(&prepared.view_camera)
        .enumerate()
    {
        if c == prepared.reference_camera {
            reference_view[t] = Some(k);
        }
    }
    let mut all_edges = prepared.local_edges.clone();
    let (mut lengths, mut sigmas) = (Vec::new(), Vec::new());
    for d in distances {
        if let (Some(a), Some(b)) = (reference_view[d.from], reference_view[d.to]) {
            all_edges.push([a, b]);
            lengths.push(d.distance);
            sigmas.push(d.sigma);
        }
    }
    let n_distances = lengths.len();
    let system = prepared.system_with_edges(&w, &all_edges);
    let w = &w;

    let mut blocks = vec![Vector3::zeros(); prepared.blocks];
    let mut positions = Vec::new();
    let mut new_positions = Vec::new();
    let n_edges = kept.len();
    let mut d = vec![1.0; n_edges];
    let mut rho = vec![0.0; n_edges];
    let mut info = vec![Matrix3::zeros(); n_edges + n_distances];
    let mut rhs = vec![Vector3::zeros(); n_edges + n_distances];
    // The distances' residuals `(|P_b - P_a| - L) s / sigma` in the direction residuals' unit
    // (`s` the direction noise, per phase).
    let distance_edges = &all_edges[n_edges..];
    let mut distance_rho = vec![0.0; n_distances];
    let mut trial_distance_rho = vec![0.0; n_distances];
    let distance_residuals = |p: &[Vector3<f64>], noise: f64, out: &mut [f64]| {
        for (((&[a, b], l), sigma), out) in distance_edges
            .iter()
            .zip(&lengths)
            .zip(&sigmas)
            .zip(out.iter_mut())
        {
            *out = ((p[b] - p[a]).norm() - l) * noise / sigma;
        }
    };
    let mut robust_weights = vec![1.0; n_edges];
    let mut scratch = CgScratch::default();
    // With distances the system is well determined: solve it directly (viewing_graph.rs).
    scratch.direct_solve = n_distances > 0;
    let (mut linear_iterations, mut linear_converged) = (0, true);
    let (mut iterations, mut converged) = (0, false);
    let mut scale = options.robust_scale.unwrap_or(f64::INFINITY);
    let local = &prepared.local_edges;
    let robust = options.robust;

    // The d-step and residuals at the positions `p`.
    let d_step = |p: &[Vector3<f64>], d: &mut [f64], rho: &mut [f64]| {
        for (((&[a, b], v), d), rho) in local.iter().zip(&directions).zip(d).zip(rho) {
            let delta = p[b] - p[a];
            let n2 = delta.norm_squared();
            *d = if n2 > 0.0 {
                (v.dot(&delta)).max(0.0) / n2
            } else {
                0.0
            };
            *rho = (*d * delta - v).norm();
        }
    };
    // The chordal residuals |u - v| of the final phase.
    let chordal_residuals = |p: &[Vector3<f64>], rho: &mut [f64]| {
        for ((&[a, b], v), rho) in local.iter().zip(&directions).zip(rho) {
            let delta = p[b] - p[a];
            let length = delta.norm();
            *rho = if length > 0.0 {
                (delta / length - v).norm()
            } else {
                std::f64::consts::SQRT_2
            };
        }
    };
    let mean_length = |p: &[Vector3<f64>]| {
        local
            .iter()
            .map(|&[a, b]| (p[b] - p[a]).norm())
            .sum::<f64>()
            / local.len().max(1) as f64
    };
    let largest_step = |a: &[Vector3<f64>], b: &[Vector3<f64>]| {
        a.iter()
            .zip(b)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max)
    };

    // Phase 1: BATA's alternation in least squares.
    let mut first = true;
    if options.ls_iterations > 0 {
        converged = false;
        for _ in 0..options.ls_iterations {
            system.view_values(&blocks, &mut positions);
            let started = !first;
            if started {
                d_step(&positions, &mut d, &mut rho);
            }
            first = false;
            // The distances, `|P_b - P_a - L u|` with `u` the current direction (none before
            // the first positions).
            let noise = direction_noise(&rho);
            for (m, &[a, b]) in distance_edges.iter().enumerate() {
                let k = n_edges + m;
                let delta = positions[b] - positions[a];
                let length = delta.norm();
                if !started || length == 0.0 {
                    info[k] = Matrix3::zeros();
                    rhs[k] = Vector3::zeros();
                    continue;
                }
                let w = (noise / sigmas[m]).powi(2);
                info[k] = Matrix3::from_diagonal_element(w);
                rhs[k] = delta * (lengths[m] * w / length);
            }
            for k in 0..n_edges {
                // w d^2 |p_j - p_i - v / d|^2.
                let w = base_weights[k] * d[k] * d[k];
                info[k] = Matrix3::from_diagonal_element(w);
                rhs[k] = if d[k] > 0.0 {
                    directions[k] * (w / d[k])
                } else {
                    Vector3::zeros()
                };
            }
            let outcome = system.solve(
                &info,
                &rhs,
                &mut blocks,
                &mut scratch,
                GAUSS_NEWTON_CG_TOLERANCE,
            );
            linear_iterations += outcome.iterations;
            linear_converged &= outcome.converged;
            iterations += 1;
            system.view_values(&blocks, &mut new_positions);
            if largest_step(&positions, &new_positions)
                <= options.tolerance * mean_length(&new_positions)
            {
                converged = true;
                break;
            }
        }
    }

    // Phases 2 and 3: Gauss-Newton on the residual with d eliminated, r = (u . v) u - v for
    // the edge's estimated unit direction u (r = -v, constant, when u . v <= 0), reweighted for
    // the L1 loss, then for the Cauchy loss (or least squares), with a step halved until the
    // cost decreases.
    let mut step = vec![Vector3::zeros(); prepared.blocks];
    let mut trial = vec![Vector3::zeros(); prepared.blocks];
    let mut trial_rho = vec![0.0; n_edges];
    for phase in 0..3 {
        let count = match phase {
            0 if robust => options.l1_iterations,
            0 => 0,
            1 => options.irls_iterations,
            _ => {
                // Re-seed the times stuck in a wrong basin, then polish again.
                if !robust || options.irls_iterations == 0 {
                    break;
                }
                let noise = direction_noise(&rho);
                let measured: Vec<MeasuredDistance> = distance_edges
                    .iter()
                    .zip(&lengths)
                    .zip(&sigmas)
                    .map(|((&ends, &length), sigma)| MeasuredDistance {
                        ends,
                        length,
                        factor: noise / sigma,
                    })
                    .collect();
                let moved = relocate(
                    &prepared,
                    w,
                    &mut blocks,
                    (&directions, &base_weights),
                    &measured,
                    scale,
                );
                if moved == 0 {
                    break;
                }
                options.irls_iterations
            }
        };
        if count == 0 {
            continue;
        }
        converged = false;
        system.view_values(&blocks, &mut positions);
        chordal_residuals(&positions, &mut rho);
        if phase == 1 && robust && options.robust_scale.is_none() {
            scale = (DIRECTION_SCALE_FACTOR * median(rho.clone())).max(MIN_GRAPH_SCALE);
        }
        // The loss and its IRLS weight psi(r) / r.
        let loss = |r: f64| match (phase, robust) {
            (0, _) => r,
            (_, true) => 0.5 * scale * scale * (r / scale).powi(2).ln_1p(),
            (_, false) => 0.5 * r * r,
        };
        let weight = |r: f64| match (phase, robust) {
            (0, _) => 1.0 / r.max(DIRECTION_L1_FLOOR),
            (_, true) => 1.0 / (1.0 + (r / scale).powi(2)),
            (_, false) => 1.0,
        };
        let noise = direction_noise(&rho);
        let cost = |rho: &[f64], distance_rho: &[f64]| -> f64 {
            rho.iter()
                .zip(&base_weights)
                .map(|(r, w)| w * loss(*r))
                .sum::<f64>()
                + distance_rho.iter().map(|r| loss(r.abs())).sum::<f64>()
        };
        distance_residuals(&positions, noise, &mut distance_rho);
        let mut current_cost = cost(&rho, &distance_rho);
        for _ in 0..count {
            for k in 0..n_edges {
                let [a, b] = local[k];
                let delta = positions[b] - positions[a];
                let length = delta.norm();
                let v = directions[k];
                if length == 0.0 {
                    info[k] = Matrix3::zeros();
                    rhs[k] = Vector3::zeros();
                    continue;
                }
                let u = delta / length;
                let r = u - v;
                let jacobian = (Matrix3::identity() - u * u.transpose()) / length;
                let w = base_weights[k] * weight(r.norm());
                info[k] = jacobian.tr_mul(&jacobian) * w;
                rhs[k] = -(jacobian.tr_mul(&r) * w);
            }
            // The distances: residual r = (|P_b - P_a| - L) s / sigma, Jacobian u^T s / sigma.
            distance_residuals(&positions, noise, &mut distance_rho);
            for (m, &[a, b]) in distance_edges.iter().enumerate() {
                let k = n_edges + m;
                let delta = positions[b] - positions[a];
                let length = delta.norm();
                if length == 0.0 {
                    info[k] = Matrix3::zeros();
                    rhs[k] = Vector3::zeros();
                    continue;
                }
                let jacobian = delta * (noise / (sigmas[m] * length));
                let r = distance_rho[m];
                let w = weight(r.abs());
                info[k] = jacobian * jacobian.transpose() * w;
                rhs[k] = -(jacobian * (r * w));
            }
            step.iter_mut().for_each(|s| *s = Vector3::zeros());
            let outcome = system.solve(
                &info,
                &rhs,
                &mut step,
                &mut scratch,
                if phase == 0 {
                    GAUSS_NEWTON_CG_TOLERANCE
                } else {
                    CG_STEP_TOLERANCE
                },
            );
            linear_iterations += outcome.iterations;
            linear_converged &= outcome.converged;
            iterations += 1;
            let mut factor = 1.0;
            let mut accepted = false;
            for _ in 0..10 {
                for ((t, b), s) in trial.iter_mut().zip(&blocks).zip(&step) {
                    *t = b + s * factor;
                }
                system.view_values(&trial, &mut new_positions);
                chordal_residuals(&new_positions, &mut trial_rho);
                distance_residuals(&new_positions, noise, &mut trial_distance_rho);
                let trial_cost = cost(&trial_rho, &trial_distance_rho);
                if trial_cost <= current_cost {
                    accepted = true;
                    current_cost = trial_cost;
                    break;
                }
                factor *= 0.5;
            }
            if !accepted {
                // No decrease along the Gauss-Newton direction: a minimum to working precision.
                converged = true;
                break;
            }
            blocks.copy_from_slice(&trial);
            let moved = largest_step(&positions, &new_positions);
            std::mem::swap(&mut positions, &mut new_positions);
            if moved <= options.tolerance * mean_length(&positions) {
                converged = true;
                break;
            }
        }
    }
    system.view_values(&blocks, &mut positions);
    chordal_residuals(&positions, &mut rho);
    if robust && options.irls_iterations > 0 {
        for (rw, r) in robust_weights.iter_mut().zip(&rho) {
            *rw = 1.0 / (1.0 + (r / scale).powi(2));
        }
    }

    // Final residuals, outliers and the scale gauge.
    if !(robust && options.irls_iterations > 0) && options.robust_scale.is_none() {
        scale = (DIRECTION_SCALE_FACTOR * median(rho.clone())).max(MIN_GRAPH_SCALE);
    }
    let threshold = options
        .outlier_threshold
        .unwrap_or(OUTLIER_SCALE_FACTOR * scale);
    let mut report_residuals = vec![None; edges.len()];
    let mut report_weights = vec![None; edges.len()];
    let mut outlier_edges = Vec::new();
    let (mut length_sum, mut length_count) = (0.0, 0usize);
    let (mut all_sum, mut all_count) = (0.0, 0usize);
    for (k, &e) in kept.iter().enumerate() {
        let [a, b] = local[k];
        let delta = positions[b] - positions[a];
        let norm = delta.norm();
        let angle = if norm > 0.0 {
            delta
                .cross(&directions[k])
                .norm()
                .atan2(delta.dot(&directions[k]))
        } else {
            std::f64::consts::PI
        };
        report_residuals[e] = Some(angle);
        report_weights[e] = Some(robust_weights[k]);
        all_sum += norm;
        all_count += 1;
        if angle > threshold {
            outlier_edges.push(e);
        } else {
            length_sum += norm;
            length_count += 1;
        }
    }
    let factor = match options.scale {
        // The measured distances fixed it.
        _ if n_distances > 0 => 1.0,
        ScaleGauge::MeanBaseline => {
            if length_count > 0 {
                length_count as f64 / length_sum
            } else {
                all_count as f64 / all_sum
            }
        }
        ScaleGauge::ViewDistance { from, to, distance } => {
            let (Ok(a), Ok(b)) = (
                prepared.component.views.binary_search(&from),
                prepared.component.views.binary_search(&to),
            ) else {
                return Err(ViewingGraphError::InvalidScaleGauge {
                    view: from,
                    reason: "the view is not in the solved component",
                });
            };
            distance / (positions[b] - positions[a]).norm()
        }
    };
    if !(factor.is_finite() && factor > 0.0) {
        return Err(ViewingGraphError::DegeneratePositions {
            reason: "the positions coincide, so their scale cannot be fixed",
        });
    }
    if positions.iter().any(|p| !p.iter().all(|x| x.is_finite())) {
        return Err(ViewingGraphError::DegeneratePositions {
            reason: "a position is not finite",
        });
    }
    let mut rig_positions = vec![None; layout.times()];
    for &t in &prepared.view_time {
        rig_positions[t] = Some(
            prepared.time_block[t]
                .map(|b| blocks[b] * factor)
                .unwrap_or_else(Vector3::zeros),
        );
    }
    let lever_arms = prepared
        .camera_block
        .iter()
        .map(|b| b.map(|b| blocks[b] * factor).unwrap_or_else(Vector3::zeros))
        .collect();
    let mut out_positions = vec![None; n_views];
    for (&v, p) in prepared.component.views.iter().zip(&positions) {
        out_positions[v] = Some(p * factor);
    }
    let component = prepared.component;
    Ok(RigTranslationAveraging {
        rig_positions,
        lever_arms,
        positions: out_positions,
        distances_used: n_distances,
        report: AveragingReport {
            kept_views: component.views,
            dropped_views: component.dropped_views,
            dropped_times: prepared.dropped_times,
            dropped_edges: component.dropped_edges,
            residuals: report_residuals,
            robust_weights: report_weights,
            outlier_edges,
            robust_scale: scale,
            outlier_threshold: threshold,
            iterations,
            converged,
            linear_iterations,
            linear_converged,
        },
    })
}

/// Smallest direction noise that weighs the measured distances (radians): exact directions
/// have a zero median residual.
const MIN_DIRECTION_NOISE: f64 = 1e-9;

/// The direction noise per axis from the direction residuals `rho` (their median over
/// `sqrt(2 ln 2)`, the median of a two-axis Gaussian's norm in its sigmas), at least
/// [`MIN_DIRECTION_NOISE`].
fn direction_noise(rho: &[f64]) -> f64 {
    (median(rho.to_vec()) / (2.0 * std::f64::consts::LN_2).sqrt()).max(MIN_DIRECTION_NOISE)
}

/// A measured distance of [`relocate`]: between local views `ends` (each at its time's rig
/// position), its residual `(|P_b - P_a| - length) factor` in the direction residuals' unit.
struct MeasuredDistance {
    ends: [usize; 2],
    length: f64,
    factor: f64,
}

/// Most edges of a time used to propose its positions in [`relocate`] (the first ones in edge
/// order): 24 edges give 276 candidate pairs.
const RELOCATION_EDGES: usize = 24;

/// Robust re-seeding: for every time (but the anchor), the rig position that minimizes the
/// Cauchy cost of its edges to other times, the others fixed, among the current one and the
/// closest points of every two of its edges' rays (the rays from the other ends along the
/// measured directions). A time whose best candidate lowers the cost moves there (a block
/// coordinate descent step on the same objective, so the total cost decreases). Returns the
/// number of times moved.
fn relocate(
    prepared: &Prepared,
    world_from_rig: &[Matrix3<f64>],
    blocks: &mut [Vector3<f64>],
    (directions, base_weights): (&[Vector3<f64>], &[f64]),
    distances: &[MeasuredDistance],
    scale: f64,
) -> usize {
    let system = prepared.system(world_from_rig);
    let mut positions = Vec::new();
    system.view_values(blocks, &mut positions);
    let views = prepared.view_time.len();
    // Each view's offset from its rig position, W_t l_c.
    let offsets: Vec<Vector3<f64>> = (0..views)
        .map(|k| {
            let (t, c) = (prepared.view_time[k], prepared.view_camera[k]);
            prepared.camera_block[c]
                .map(|b| world_from_rig[t] * blocks[b])
                .unwrap_or_else(Vector3::zeros)
        })
        .collect();
    // The edges of every time to other times: (edge, view at this time, other view, sign).
    let times = prepared.time_block.len();
    let mut by_time: Vec<Vec<(usize, usize, usize, f64)>> = vec![Vec::new(); times];
    for (k, &[a, b]) in prepared.local_edges.iter().enumerate() {
        let (ta, tb) = (prepared.view_time[a], prepared.view_time[b]);
        if ta != tb {
            // p_b - p_a = s v: p_a = p_b - s v, p_b = p_a + s v.
            by_time[ta].push((k, a, b, -1.0));
            by_time[tb].push((k, b, a, 1.0));
        }
    }
    // The distances of every time: (view at this time, other view, distance).
    let mut distances_by_time: Vec<Vec<(usize, usize, &MeasuredDistance)>> =
        vec![Vec::new(); times];
    for m in distances {
        let [a, b] = m.ends;
        distances_by_time[prepared.view_time[a]].push((a, b, m));
        distances_by_time[prepared.view_time[b]].push((b, a, m));
    }
    let cauchy = |r: f64| 0.5 * scale * scale * (r / scale).powi(2).ln_1p();
    let mut moved = 0;
    for (t, constraints) in by_time.iter().enumerate() {
        let Some(block) = prepared.time_block[t] else {
            continue;
        };
        if constraints.len() < 2 {
            continue;
        }
        // Cost of the rig position `rig` over this time's edges.
        let cost = |rig: &Vector3<f64>, positions: &[Vector3<f64>]| -> f64 {
            constraints
                .iter()
                .map(|&(k, view, other, sign)| {
                    let delta = (rig + offsets[view] - positions[other]) * sign;
                    let length = delta.norm();
                    let r = if length > 0.0 {
                        (delta / length - directions[k]).norm()
                    } else {
                        std::f64::consts::SQRT_2
                    };
                    base_weights[k] * cauchy(r)
                })
                .sum::<f64>()
                + distances_by_time[t]
                    .iter()
                    .map(|&(view, other, m)| {
                        let length = (rig + offsets[view] - positions[other]).norm();
                        cauchy((length - m.length) * m.factor)
                    })
                    .sum::<f64>()
        };
        let current = blocks[block];
        let mut best = (cost(&current, &positions), current);
        let start = best.0;
        // Rays of the rig position: origin (other end - offset), direction sign * v.
        let rays: Vec<(Vector3<f64>, Vector3<f64>)> = constraints
            .iter()
            .take(RELOCATION_EDGES)
            .map(|&(k, view, other, sign)| (positions[other] - offsets[view], directions[k] * sign))
            .collect();
        for (i, (o1, d1)) in rays.iter().enumerate() {
            for (o2, d2) in &rays[i + 1..] {
                let w0 = o1 - o2;
                let b = d1.dot(d2);
                let denom = 1.0 - b * b;
                if denom < 1e-6 {
                    continue;
                }
                let (d, e) = (d1.dot(&w0), d2.dot(&w0));
                let s1 = (b * e - d) / denom;
                let s2 = (e - b * d) / denom;
                if s1 <= 0.0 || s2 <= 0.0 {
                    continue;
                }
                let candidate = 0.5 * ((o1 + d1 * s1) + (o2 + d2 * s2));
                let c = cost(&candidate, &positions);
                if c < best.0 {
                    best = (c, candidate);
                }
            }
        }
        // Move only for a clear gain: not to trade the current minimum for a twin.
        if best.0 < start - 1e-9 * (1.0 + start) {
            blocks[block] = best.1;
            for k in 0..views {
                if prepared.view_time[k] == t {
                    positions[k] = best.1 + offsets[k];
                }
            }
            moved += 1;
        }
    }
    moved
}
