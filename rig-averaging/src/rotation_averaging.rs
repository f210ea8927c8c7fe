//! Multiple rotation averaging over a viewing graph: a chordal initialization, then robust
//! refinement in the Lie algebra, per view or in the rig form.
//!
//! A. Chatterjee and V. M. Govindu, "Efficient and Robust Large-Scale Rotation Averaging",
//! ICCV 2013, and "Robust Relative Rotation Averaging", IEEE TPAMI 40(4):958-972, 2018
//! (the journal version, online 2017). Their method: an L1 averaging in the Lie algebra
//! (L1RA), then iteratively reweighted least squares with a redescending loss (IRLS), both on
//! the linearized relation `omega_ij = omega_j - omega_i` with the graph's incidence matrix.
//! This file implements:
//!
//! 1. **Chordal initialization**: the linear relaxation of `min sum_e w_e |R_j - R_ij R_i|_F^2`
//!    (Martinec and Pajdla, "Robust Rotation and Translation Estimation in Multiview
//!    Reconstruction", CVPR 2007; Hartley, Trumpf, Dai and Li, "Rotation Averaging", IJCV 2013,
//!    section 5.3): the 3x3 matrices `R_k` are unconstrained, the first kept view's is fixed to
//!    the identity, the sparse normal equations (the graph's connection Laplacian) are solved
//!    by conjugate gradients for the three columns at once, and each `R_k` is projected onto
//!    SO(3) by SVD. Uniformly random outlier rotations have a zero mean, so they shrink the
//!    relaxed matrices rather than turn them: the projection undoes most of their effect.
//! 2. **L1 phase**: with world-frame perturbations `world_from_camera_k <- Exp(omega_k)
//!    world_from_camera_k`, an edge's residual `e_ij = Log(world_from_camera_j * j_from_i *
//!    camera_i_from_world)` becomes `e_ij + omega_j - omega_i` to first order. Each iteration
//!    solves the weighted least squares with weights `w_e / max(|e_ij|, 1e-6)` (one IRLS step
//!    of `min sum_e w_e |e_ij + omega_j - omega_i|`, the L1 norm of the residual vectors) and
//!    updates the rotations. Chatterjee and Govindu solve each linearized L1 problem to
//!    convergence before relinearizing; here every IRLS step relinearizes, which reaches the
//!    same fixed point with fewer solves.
//! 3. **IRLS phase**: the same with the Cauchy weights `w_e / (1 + |e_ij|^2 / c^2)` (the paper
//!    uses Geman-McClure; the Cauchy loss is this crate's, see `robust.rs`), with `c` given or
//!    [`ADAPTIVE_SCALE_FACTOR`](crate::ADAPTIVE_SCALE_FACTOR) times the median residual after
//!    the L1 phase, until the largest update is below the tolerance.
//!
//! In the **rig form** the unknowns are `world_from_rig` per time (`W_t`) and `rig_from_camera`
//! per camera (`C_c`), with `world_from_camera = W_t C_c`. The perturbations
//! `W_t <- Exp(alpha_t) W_t` (world frame) and `C_c <- Exp(beta_c) C_c` (rig frame) move the
//! view (t, c) by `omega = alpha_t + W_t beta_c`, so the same sparse least squares applies with
//! 3x3 blocks. The initialization averages per view (step 1), then splits the view rotations
//! into rig and camera rotations by Markley means along the (time, camera) bipartite graph.
//! Gauge: the reference camera's `rig_from_camera` is the identity and so is the
//! `world_from_rig` of the anchor time (the first time at which the reference camera has a
//! kept view). Per view (no rig), the first kept view's `camera_from_world` is the identity.

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

use crate::NonExhaustive;
use crate::error::ViewingGraphError;
use crate::quaternion_mean::quaternion_mean;
use crate::robust::ADAPTIVE_SCALE_FACTOR;
use crate::viewing_graph::{
    AveragingReport, CG_STEP_TOLERANCE, CG_TOLERANCE, CgScratch, Prepared, RigLayout, RotationEdge,
    check_edge_weight, check_ends, is_unit, median,
};

/// Smallest residual, radians, in the L1 weights `1 / max(|e|, L1_RESIDUAL_FLOOR)`: keeps the
/// weights finite on exact edges; far below any measured rotation noise.
pub const L1_RESIDUAL_FLOOR: f64 = 1e-6;

/// Smallest adaptive Cauchy scale of graph averaging, radians (exact data has a zero median
/// residual).
pub const MIN_GRAPH_SCALE: f64 = 1e-9;

/// Default outlier threshold in units of the Cauchy scale: an edge whose final residual
/// exceeds `3 c` (robust weight below 1/10) is reported as an outlier. With the adaptive scale
/// and Gaussian noise of `sigma` per axis, `3 c = 7.2 sigma`.
pub const OUTLIER_SCALE_FACTOR: f64 = 3.0;

/// Options of [`rotation_averaging`] and [`rig_rotation_averaging`].
///
/// With `l1_iterations: 0` and `irls_iterations: 0` the result is the chordal initialization
/// alone (a least-squares baseline).
///
/// ```
/// use ibc_rig_averaging::RotationAveragingOptions;
///
/// let options = RotationAveragingOptions { robust_scale: Some(0.05), ..Default::default() };
/// assert_eq!(options.irls_iterations, 50);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RotationAveragingOptions {
    /// L1 iterations after the chordal initialization (default 10; Chatterjee and Govindu run
    /// L1RA to convergence, a handful of steps from a chordal start).
    pub l1_iterations: usize,
    /// Cauchy IRLS iterations at most (default 50; they stop when the largest update is below
    /// `tolerance`).
    pub irls_iterations: usize,
    /// Cauchy scale of the residual angle, radians; `None` (default) estimates it as
    /// [`ADAPTIVE_SCALE_FACTOR`](crate::ADAPTIVE_SCALE_FACTOR) times the median residual after
    /// the L1 phase, at least [`MIN_GRAPH_SCALE`].
    pub robust_scale: Option<f64>,
    /// Residual angle above which a kept edge is reported as an outlier, radians; `None`
    /// (default) is [`OUTLIER_SCALE_FACTOR`] times the Cauchy scale.
    pub outlier_threshold: Option<f64>,
    /// A phase (L1 or IRLS) stops when its largest rotation update is below this, radians
    /// (default 1e-10).
    pub tolerance: f64,
    /// Rig form: the camera whose `rig_from_camera` is the identity (default 0). Unused per
    /// view.
    pub reference_camera: usize,
    /// Keeps the struct open to new fields: write it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for RotationAveragingOptions {
    fn default() -> Self {
        Self {
            l1_iterations: 10,
            irls_iterations: 50,
            robust_scale: None,
            outlier_threshold: None,
            tolerance: 1e-10,
            reference_camera: 0,
            non_exhaustive: NonExhaustive(()),
        }
    }
}

impl RotationAveragingOptions {
    fn validate(&self) -> Result<(), ViewingGraphError> {
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
        Ok(())
    }
}

/// The result of [`rotation_averaging`].
#[derive(Clone, Debug, PartialEq)]
pub struct RotationAveraging {
    /// `camera_from_world` of every view; `None` for a dropped view. The first kept view's is
    /// the identity (the gauge).
    pub camera_from_world: Vec<Option<UnitQuaternion<f64>>>,
    /// What was kept, dropped and found.
    pub report: AveragingReport,
}

/// The result of [`rig_rotation_averaging`].
#[derive(Clone, Debug, PartialEq)]
pub struct RigRotationAveraging {
    /// `world_from_rig` rotation of every time; `None` for a time without a kept view. The
    /// anchor time's (the first with a kept view of the reference camera) is the identity.
    pub world_from_rig: Vec<Option<UnitQuaternion<f64>>>,
    /// `rig_from_camera` rotation of every camera; the reference camera's is the identity.
    pub rig_from_camera: Vec<UnitQuaternion<f64>>,
    /// `camera_from_world = (world_from_rig * rig_from_camera)^-1` of every view; `None` for a
    /// dropped view.
    pub camera_from_world: Vec<Option<UnitQuaternion<f64>>>,
    /// What was kept, dropped and found.
    pub report: AveragingReport,
}

/// Averages the relative rotations of a viewing graph of `views` views into one
/// `camera_from_world` per view (see the module documentation for the method and the gauge).
///
/// # Errors
///
/// [`ViewingGraphError`]: no views or edges, an edge naming a missing view or joining a view
/// to itself, a non-unit or non-finite rotation, a bad weight or option.
pub fn rotation_averaging(
    views: usize,
    edges: &[RotationEdge],
    options: &RotationAveragingOptions,
) -> Result<RotationAveraging, ViewingGraphError> {
    let layout = RigLayout::single_camera(views);
    let options = RotationAveragingOptions {
        reference_camera: 0,
        ..*options
    };
    let solved = solve(&layout, edges, &options)?;
    Ok(RotationAveraging {
        camera_from_world: solved.camera_from_world,
        report: solved.report,
    })
}

/// Averages the relative rotations between the views of a rig (`layout`: view k is camera c at
/// time t) into one `world_from_rig` per time and one `rig_from_camera` per camera.
///
/// # Errors
///
/// As [`rotation_averaging`], and [`ViewingGraphError::UndeterminedCamera`] naming a camera
/// with no view in the largest connected component, or whose views share no chain of times
/// with the reference camera's; [`ViewingGraphError::InvalidOption`] for a reference camera
/// beyond the layout.
pub fn rig_rotation_averaging(
    layout: &RigLayout,
    edges: &[RotationEdge],
    options: &RotationAveragingOptions,
) -> Result<RigRotationAveraging, ViewingGraphError> {
    if options.reference_camera >= layout.cameras() {
        return Err(ViewingGraphError::InvalidOption {
            option: "reference_camera",
            reason: "must be a camera of the layout",
        });
    }
    solve(layout, edges, options)
}

fn to_quaternion(m: &Matrix3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*m))
}

fn exp(v: &Vector3<f64>) -> Matrix3<f64> {
    Rotation3::new(*v).into_inner()
}

/// `Log` of a rotation matrix: from its skew part, `theta / (2 sin theta) (m - m^T)^v`, below
/// 3 radians; through the quaternion (accurate up to pi) above.
fn log(m: &Matrix3<f64>) -> Vector3<f64> {
    let cos = 0.5 * (m.trace() - 1.0);
    if cos < -0.98 {
        return to_quaternion(m).scaled_axis();
    }
    let v = Vector3::new(
        m[(2, 1)] - m[(1, 2)],
        m[(0, 2)] - m[(2, 0)],
        m[(1, 0)] - m[(0, 1)],
    );
    let sin = 0.5 * v.norm();
    let theta = sin.atan2(cos.clamp(-1.0, 1.0));
    // theta / sin -> 1 + theta^2 / 6 as theta -> 0.
    let factor = if sin > 1e-8 {
        theta / sin
    } else {
        1.0 + theta * theta / 6.0
    };
    0.5 * factor * v
}

/// The nearest rotation to `m` in the Frobenius norm, `U diag(1, 1, det(U V^T)) V^T`; the
/// identity when the SVD fails.
pub(crate) fn project_to_rotation(m: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = m.svd(true, true);
    match (svd.u, svd.v_t) {
        (Some(u), Some(v_t)) => {
            let d = (u * v_t).determinant().signum();
            u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t
        }
        _ => Matrix3::identity(),
    }
}

/// The relaxed chordal averaging over the kept views: `camera_from_world` per local view, the
/// anchor's the identity, and the number of conjugate-gradient iterations.
fn chordal(
    prepared: &Prepared,
    relative: &[Matrix3<f64>],
    weights: &[f64],
) -> (Vec<Matrix3<f64>>, usize, bool) {
    let n = prepared.view_time.len();
    let anchor = prepared.anchor_view;
    let edges = &prepared.local_edges;
    // A(X): the normal operator with the anchor's block held at zero.
    let apply = |x: &[Matrix3<f64>], out: &mut [Matrix3<f64>]| {
        out.iter_mut().for_each(|o| *o = Matrix3::zeros());
        for ((&[a, b], r), &w) in edges.iter().zip(relative).zip(weights) {
            let d = w * (x[b] - r * x[a]);
            out[b] += d;
            out[a] -= r.tr_mul(&d);
        }
        out[anchor] = Matrix3::zeros();
    };
    let mut diag = vec![0.0; n];
    let mut rhs = vec![Matrix3::zeros(); n];
    for ((&[a, b], r), &w) in edges.iter().zip(relative).zip(weights) {
        diag[a] += w;
        diag[b] += w;
        // Minus the gradient at X = 0 except X_anchor = I.
        if a == anchor {
            rhs[b] += w * r;
        }
        if b == anchor {
            rhs[a] += w * r.transpose();
        }
    }
    rhs[anchor] = Matrix3::zeros();
    let fro = |a: &[Matrix3<f64>], b: &[Matrix3<f64>]| -> f64 {
        a.iter().zip(b).map(|(x, y)| x.dot(y)).sum()
    };
    let precond = |r: &[Matrix3<f64>], out: &mut [Matrix3<f64>]| {
        for (k, (o, r)) in out.iter_mut().zip(r).enumerate() {
            *o = if k == anchor || diag[k] <= 0.0 {
                Matrix3::zeros()
            } else {
                r / diag[k]
            };
        }
    };
    let mut x = vec![Matrix3::zeros(); n];
    let mut r = rhs.clone();
    let mut z = vec![Matrix3::zeros(); n];
    precond(&r, &mut z);
    let mut p = z.clone();
    let mut ap = vec![Matrix3::zeros(); n];
    let mut rz = fro(&r, &z);
    let threshold = CG_TOLERANCE * fro(&rhs, &rhs).sqrt();
    let max_iterations = 9 * n + 100;
    let (mut iterations, mut converged) = (0, false);
    while iterations < max_iterations {
        let r_norm = fro(&r, &r).sqrt();
        if r_norm <= threshold || r_norm == 0.0 {
            converged = true;
            break;
        }
        apply(&p, &mut ap);
        let pap = fro(&p, &ap);
        if !(pap > 0.0 && pap.is_finite()) {
            break;
        }
        let alpha = rz / pap;
        for ((xi, pi), (ri, ai)) in x.iter_mut().zip(&p).zip(r.iter_mut().zip(&ap)) {
            *xi += alpha * pi;
            *ri -= alpha * ai;
        }
        precond(&r, &mut z);
        let rz_new = fro(&r, &z);
        let beta = rz_new / rz;
        rz = rz_new;
        for (pi, zi) in p.iter_mut().zip(&z) {
            *pi = zi + beta * *pi;
        }
        iterations += 1;
    }
    x[anchor] = Matrix3::identity();
    let rotations = x.iter().map(project_to_rotation).collect();
    (rotations, iterations, converged)
}

/// Splits `world_from_camera` of the kept views into `world_from_rig` per time and
/// `rig_from_camera` per camera (Markley means along the time-camera graph, then two sweeps
/// of alternating means), in the gauge of the module documentation.
fn split_rig(
    prepared: &Prepared,
    layout: &RigLayout,
    world_from_camera: &[Matrix3<f64>],
) -> (Vec<Matrix3<f64>>, Vec<Matrix3<f64>>) {
    let (times, cameras) = (layout.times(), layout.cameras());
    let mut w: Vec<Option<Matrix3<f64>>> = vec![None; times];
    let mut c: Vec<Option<Matrix3<f64>>> = vec![None; cameras];
    c[prepared.reference_camera] = Some(Matrix3::identity());
    let views = || {
        prepared
            .view_time
            .iter()
            .zip(&prepared.view_camera)
            .zip(world_from_camera)
    };
    let mean = |acc: Vec<UnitQuaternion<f64>>| -> Option<Matrix3<f64>> {
        quaternion_mean(&acc, None)
            .ok()
            .map(|m| m.mean.to_rotation_matrix().into_inner())
    };
    // Breadth-first: times from known cameras, then cameras from known times.
    for sweep in 0..(times + cameras + 2) {
        let all = sweep > times + cameras;
        let mut estimates: Vec<Vec<UnitQuaternion<f64>>> = vec![Vec::new(); times];
        for ((&t, &cam), q) in views() {
            if let (None, Some(cc)) = (w[t], c[cam]) {
                estimates[t].push(to_quaternion(&(q * cc.transpose())));
            }
        }
        let mut changed = false;
        for (t, est) in estimates.into_iter().enumerate() {
            if !est.is_empty() {
                w[t] = mean(est);
                changed = true;
            }
        }
        let mut estimates: Vec<Vec<UnitQuaternion<f64>>> = vec![Vec::new(); cameras];
        for ((&t, &cam), q) in views() {
            if let (Some(wt), None) = (w[t], c[cam]) {
                estimates[cam].push(to_quaternion(&(wt.tr_mul(q))));
            }
        }
        for (cam, est) in estimates.into_iter().enumerate() {
            if !est.is_empty() {
                c[cam] = mean(est);
                changed = true;
            }
        }
        if !changed || all {
            break;
        }
    }
    // Two sweeps of alternating means over all views.
    for _ in 0..2 {
        let mut estimates: Vec<Vec<UnitQuaternion<f64>>> = vec![Vec::new(); times];
        for ((&t, &cam), q) in views() {
            if let Some(cc) = c[cam] {
                estimates[t].push(to_quaternion(&(q * cc.transpose())));
            }
        }
        for (t, est) in estimates.into_iter().enumerate() {
            if !est.is_empty() {
                w[t] = mean(est).or(w[t]);
            }
        }
        let mut estimates: Vec<Vec<UnitQuaternion<f64>>> = vec![Vec::new(); cameras];
        for ((&t, &cam), q) in views() {
            if let Some(wt) = w[t]
                && cam != prepared.reference_camera
            {
                estimates[cam].push(to_quaternion(&(wt.tr_mul(q))));
            }
        }
        for (cam, est) in estimates.into_iter().enumerate() {
            if !est.is_empty() {
                c[cam] = mean(est).or(c[cam]);
            }
        }
    }
    let gauge = w[prepared.anchor_time]
        .map(|m| m.transpose())
        .unwrap_or_else(Matrix3::identity);
    let w = w
        .into_iter()
        .map(|m| gauge * m.unwrap_or_else(Matrix3::identity))
        .collect();
    let c = c
        .into_iter()
        .map(|m| m.unwrap_or_else(Matrix3::identity))
        .collect();
    (w, c)
}

/// The edges as view pairs and as rotation matrices.
type CheckedEdges = (Vec<[usize; 2]>, Vec<Matrix3<f64>>);

/// Validated input: the edges as view pairs and as rotation matrices.
fn check_edges(views: usize, edges: &[RotationEdge]) -> Result<CheckedEdges, ViewingGraphError> {
    if views == 0 {
        return Err(ViewingGraphError::NoViews);
    }
    if edges.is_empty() {
        return Err(ViewingGraphError::NoEdges);
    }
    let mut pairs = Vec::with_capacity(edges.len());
    let mut relative = Vec::with_capacity(edges.len());
    for (e, edge) in edges.iter().enumerate() {
        check_ends(e, edge.i, edge.j, views)?;
        let norm = edge.j_from_i.coords.norm();
        if !is_unit(norm) {
            return Err(ViewingGraphError::NotUnitRotation { edge: e, norm });
        }
        check_edge_weight(e, edge.weight)?;
        pairs.push([edge.i, edge.j]);
        relative.push(edge.j_from_i.to_rotation_matrix().into_inner());
    }
    Ok((pairs, relative))
}

fn solve(
    layout: &RigLayout,
    edges: &[RotationEdge],
    options: &RotationAveragingOptions,
) -> Result<RigRotationAveraging, ViewingGraphError> {
    options.validate()?;
    let n_views = layout.views().len();
    let (pairs, relative_all) = check_edges(n_views, edges)?;
    let prepared = Prepared::new(
        layout,
        &pairs,
        &vec![true; n_views],
        0,
        options.reference_camera,
    )?;
    let kept = &prepared.component.edges;
    let relative: Vec<Matrix3<f64>> = kept.iter().map(|&e| relative_all[e]).collect();
    let base_weights: Vec<f64> = kept.iter().map(|&e| edges[e].weight).collect();

    // 1. Chordal initialization per view, then the rig split.
    let (camera_from_world, mut linear_iterations, mut linear_converged) =
        chordal(&prepared, &relative, &base_weights);
    let world_from_camera: Vec<Matrix3<f64>> =
        camera_from_world.iter().map(|m| m.transpose()).collect();
    let (mut w, mut c) = if layout.cameras() == 1 {
        let mut w = vec![Matrix3::identity(); layout.times()];
        for (&t, q) in prepared.view_time.iter().zip(&world_from_camera) {
            w[t] = *q;
        }
        (w, vec![Matrix3::identity()])
    } else {
        split_rig(&prepared, layout, &world_from_camera)
    };

    // 2-3. L1 then Cauchy IRLS in the Lie algebra.
    let n_local = prepared.view_time.len();
    let mut view_rotations = vec![Matrix3::identity(); n_local];
    let mut residuals = vec![Vector3::zeros(); kept.len()];
    let compute_residuals = |w: &[Matrix3<f64>],
                             c: &[Matrix3<f64>],
                             q: &mut [Matrix3<f64>],
                             res: &mut [Vector3<f64>]| {
        for (qk, (&t, &cam)) in q
            .iter_mut()
            .zip(prepared.view_time.iter().zip(&prepared.view_camera))
        {
            *qk = w[t] * c[cam];
        }
        for ((r, &[a, b]), rel) in res.iter_mut().zip(&prepared.local_edges).zip(&relative) {
            *r = log(&(q[b] * rel * q[a].transpose()));
        }
    };
    let mut scratch = CgScratch::default();
    let mut blocks = vec![Vector3::zeros(); prepared.blocks];
    let mut info = vec![Matrix3::zeros(); kept.len()];
    let mut rhs = vec![Vector3::zeros(); kept.len()];
    let mut scale = options.robust_scale.unwrap_or(f64::INFINITY);
    let mut iterations = 0;
    let mut converged = options.l1_iterations == 0 && options.irls_iterations == 0;
    let mut robust_weights = vec![1.0; kept.len()];
    for phase in 0..2 {
        let count = if phase == 0 {
            options.l1_iterations
        } else {
            options.irls_iterations
        };
        if count == 0 {
            continue;
        }
        compute_residuals(&w, &c, &mut view_rotations, &mut residuals);
        if phase == 1 && options.robust_scale.is_none() {
            let norms = residuals.iter().map(|r| r.norm()).collect();
            scale = (ADAPTIVE_SCALE_FACTOR * median(norms)).max(MIN_GRAPH_SCALE);
        }
        converged = false;
        for _ in 0..count {
            for (k, r) in residuals.iter().enumerate() {
                let norm = r.norm();
                robust_weights[k] = if phase == 0 {
                    1.0 / norm.max(L1_RESIDUAL_FLOOR)
                } else {
                    1.0 / (1.0 + (norm / scale).powi(2))
                };
                let w = base_weights[k] * robust_weights[k];
                info[k] = Matrix3::from_diagonal_element(w);
                rhs[k] = -w * r;
            }
            blocks.iter_mut().for_each(|b| *b = Vector3::zeros());
            let system = prepared.system(&w);
            let outcome = system.solve(&info, &rhs, &mut blocks, &mut scratch, CG_STEP_TOLERANCE);
            linear_iterations += outcome.iterations;
            linear_converged &= outcome.converged;
            iterations += 1;
            for (t, block) in prepared.time_block.iter().enumerate() {
                if let Some(b) = block {
                    w[t] = exp(&blocks[*b]) * w[t];
                }
            }
            for (cam, block) in prepared.camera_block.iter().enumerate() {
                if let Some(b) = block {
                    c[cam] = project_to_rotation(&(exp(&blocks[*b]) * c[cam]));
                }
            }
            compute_residuals(&w, &c, &mut view_rotations, &mut residuals);
            let step = blocks.iter().map(|b| b.norm()).fold(0.0, f64::max);
            if step < options.tolerance {
                converged = true;
                break;
            }
        }
        if phase == 0 {
            robust_weights.iter_mut().for_each(|r| *r = 1.0);
        }
    }
    compute_residuals(&w, &c, &mut view_rotations, &mut residuals);
    if options.irls_iterations > 0 {
        for (rw, r) in robust_weights.iter_mut().zip(&residuals) {
            *rw = 1.0 / (1.0 + (r.norm() / scale).powi(2));
        }
    } else if options.robust_scale.is_none() {
        let norms = residuals.iter().map(|r| r.norm()).collect();
        scale = (ADAPTIVE_SCALE_FACTOR * median(norms)).max(MIN_GRAPH_SCALE);
    }
    let threshold = options
        .outlier_threshold
        .unwrap_or(OUTLIER_SCALE_FACTOR * scale);

    let mut report_residuals = vec![None; edges.len()];
    let mut report_weights = vec![None; edges.len()];
    let mut outlier_edges = Vec::new();
    for (k, &e) in kept.iter().enumerate() {
        let angle = residuals[k].norm();
        report_residuals[e] = Some(angle);
        report_weights[e] = Some(robust_weights[k]);
        if angle > threshold {
            outlier_edges.push(e);
        }
    }
    let mut world_from_rig = vec![None; layout.times()];
    for &t in &prepared.view_time {
        world_from_rig[t] = Some(to_quaternion(&w[t]));
    }
    let mut camera_from_world = vec![None; n_views];
    for (&v, q) in prepared.component.views.iter().zip(&view_rotations) {
        camera_from_world[v] = Some(to_quaternion(&q.transpose()));
    }
    let component = prepared.component;
    Ok(RigRotationAveraging {
        world_from_rig,
        rig_from_camera: c.iter().map(to_quaternion).collect(),
        camera_from_world,
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
