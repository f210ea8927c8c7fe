//! Viewing graphs: views (images) joined by edges that carry relative measurements, their
//! connectivity, the rig layout of views as (time, camera) images, and the sparse linear
//! least-squares problem that rotation and translation averaging solve over them.
//!
//! Conventions (all of this module's users):
//!
//! - A view `k` has a rotation `camera_k_from_world` (`R_k`) and a centre `p_k` in the world
//!   frame. A [`RotationEdge`] `(i, j)` carries `j_from_i = R_j R_i^T` (camera j from camera
//!   i), so that `R_j = j_from_i R_i`. A [`DirectionEdge`] `(i, j)` carries the unit vector
//!   `(p_j - p_i) / |p_j - p_i|` in the world frame.
//! - In the rig form ([`RigLayout`]) view `k` is the image of camera `c` at time `t`; the
//!   unknowns are one `world_from_rig` per time and one `rig_from_camera` per camera, and
//!   `world_from_camera_k = world_from_rig_t * rig_from_camera_c`.
//! - Connectivity: only the largest connected component of the views (ties: the one holding
//!   the lowest view index) is solved; the views, times and edges left out are reported.
//!
//! The linear problem: minimize `sum_e w_e |x_b - x_a - y_e|^2` over edges `e = (a, b)`, where
//! each view's 3-vector is `x_k = u_t + W_t v_c` from a time block `u_t`, a camera block `v_c`
//! and the time's rotation `W_t` (`world_from_rig`). The anchor time's `u` and the reference
//! camera's `v` are fixed at zero (the gauge). Its normal equations are solved by conjugate
//! gradients with a 3x3 block-Jacobi preconditioner (Hestenes and Stiefel 1952; Saad,
//! *Iterative Methods for Sparse Linear Systems*, 2003, algorithm 9.1), matrix-free: one
//! product costs one pass over the edges and views. On a well-connected graph (an expander such
//! as a random graph of mean degree 20) it converges in tens of iterations; on chain-like
//! graphs (a drive) the iteration count grows with the graph's diameter. Translation averaging
//! with measured distances, whose system is then well determined, first solves it directly by
//! sparse Cholesky factorization (see `sparse_cholesky.rs`: the pattern is analysed once per
//! graph); conjugate gradients from that solution check it and refine it where it falls short
//! of the tolerance, and remain the fallback where the factorization fails. Without distances
//! the direct solve is not used: exact steps follow the noise along the spacing that
//! directions leave undetermined (measured on a survey drive: a worse map), where conjugate
//! gradients stopped at their tolerance keep it near its start.

use nalgebra::{Matrix3, UnitQuaternion, Vector3};

use crate::error::ViewingGraphError;
use crate::quaternion_mean::UNIT_NORM_TOLERANCE;
use crate::sparse_cholesky::SparseCholesky;

/// A relative rotation between views `i` and `j`: `j_from_i = camera_j_from_world *
/// world_from_camera_i`, so that `camera_j_from_world = j_from_i * camera_i_from_world`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RotationEdge {
    /// The first view.
    pub i: usize,
    /// The second view.
    pub j: usize,
    /// Rotation from camera i's frame to camera j's frame (finite, unit norm).
    pub j_from_i: UnitQuaternion<f64>,
    /// Weight of the edge (finite, strictly positive; 1 by [`RotationEdge::new`]), for example
    /// the inlier count of the two-view estimate.
    pub weight: f64,
}

impl RotationEdge {
    /// An edge of weight 1.
    pub fn new(i: usize, j: usize, j_from_i: UnitQuaternion<f64>) -> Self {
        Self {
            i,
            j,
            j_from_i,
            weight: 1.0,
        }
    }

    /// The same edge with another weight.
    #[must_use]
    pub fn with_weight(mut self, weight: f64) -> Self {
        self.weight = weight;
        self
    }
}

/// A relative direction between views `i` and `j`: the unit vector from view i's centre to
/// view j's centre, in the world frame.
///
/// From a two-view pose `j_from_i` (`x_j = R x_i + t`, `t` known up to scale) and the rotation
/// `world_from_camera_j` of view j, the direction is `-(world_from_camera_j * t) / |t|`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectionEdge {
    /// The first view.
    pub i: usize,
    /// The second view.
    pub j: usize,
    /// `(p_j - p_i) / |p_j - p_i|` in the world frame (finite, unit norm).
    pub direction: Vector3<f64>,
    /// Weight of the edge (finite, strictly positive; 1 by [`DirectionEdge::new`]).
    pub weight: f64,
}

impl DirectionEdge {
    /// An edge of weight 1.
    pub fn new(i: usize, j: usize, direction: Vector3<f64>) -> Self {
        Self {
            i,
            j,
            direction,
            weight: 1.0,
        }
    }

    /// The same edge with another weight.
    #[must_use]
    pub fn with_weight(mut self, weight: f64) -> Self {
        self.weight = weight;
        self
    }
}

/// A connected component of a viewing graph and what was left out of it.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub struct Component {
    /// The views of the component, increasing.
    pub views: Vec<usize>,
    /// The edges with both ends in the component, increasing.
    pub edges: Vec<usize>,
    /// The other views, increasing.
    pub dropped_views: Vec<usize>,
    /// The other edges, increasing.
    pub dropped_edges: Vec<usize>,
}

/// The largest connected component of the graph of `views` views and the edges `edges`
/// (pairs of view indices); ties go to the component holding the lowest view index.
///
/// # Errors
///
/// [`ViewingGraphError::ViewOutOfRange`] when an edge names a view `>= views`.
pub fn largest_connected_component(
    views: usize,
    edges: &[(usize, usize)],
) -> Result<Component, ViewingGraphError> {
    let pairs = edges
        .iter()
        .enumerate()
        .map(|(e, &(i, j))| {
            for view in [i, j] {
                if view >= views {
                    return Err(ViewingGraphError::ViewOutOfRange {
                        edge: e,
                        view,
                        views,
                    });
                }
            }
            Ok([i, j])
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(component(views, &pairs, &vec![true; views], 0))
}

/// Union-find with path halving.
struct UnionFind(Vec<usize>);

impl UnionFind {
    fn new(n: usize) -> Self {
        Self((0..n).collect())
    }

    fn find(&mut self, mut a: usize) -> usize {
        while self.0[a] != a {
            self.0[a] = self.0[self.0[a]];
            a = self.0[a];
        }
        a
    }

    fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        // The smaller root wins, so the result does not depend on the edge order.
        if ra < rb {
            self.0[rb] = ra;
        } else {
            self.0[ra] = rb;
        }
    }
}

/// Largest component among the `usable` views, after iteratively removing views with fewer
/// than `min_degree` edges (the k-core); edges with a self-loop never count.
pub(crate) fn component(
    views: usize,
    pairs: &[[usize; 2]],
    usable: &[bool],
    min_degree: usize,
) -> Component {
    let mut alive = usable.to_vec();
    if min_degree > 0 {
        loop {
            let mut degree = vec![0usize; views];
            for &[i, j] in pairs {
                if alive[i] && alive[j] && i != j {
                    degree[i] += 1;
                    degree[j] += 1;
                }
            }
            let mut changed = false;
            for (a, d) in alive.iter_mut().zip(&degree) {
                if *a && *d < min_degree {
                    *a = false;
                    changed = true;
                }
            }
            if !changed {
                break;
            }
        }
    }
    let mut uf = UnionFind::new(views);
    let mut has_edge = vec![false; views];
    for &[i, j] in pairs {
        if alive[i] && alive[j] && i != j {
            uf.union(i, j);
            has_edge[i] = true;
            has_edge[j] = true;
        }
    }
    let mut size = vec![0usize; views];
    for (v, _) in has_edge.iter().enumerate().filter(|(_, h)| **h) {
        let r = uf.find(v);
        size[r] += 1;
    }
    // Roots are the smallest index of their component, so the first maximum holds the lowest
    // view.
    let mut best: Option<usize> = None;
    for r in 0..views {
        if size[r] > 0 && best.is_none_or(|b| size[r] > size[b]) {
            best = Some(r);
        }
    }
    let mut out = Component::default();
    for (v, &h) in has_edge.iter().enumerate() {
        if best.is_some_and(|b| h && uf.find(v) == b) {
            out.views.push(v);
        } else {
            out.dropped_views.push(v);
        }
    }
    for (e, &[i, j]) in pairs.iter().enumerate() {
        if best.is_some_and(|b| alive[i] && alive[j] && i != j && uf.find(i) == b) {
            out.edges.push(e);
        } else {
            out.dropped_edges.push(e);
        }
    }
    out
}

/// One image of a rig: camera `camera` at time `time`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RigView {
    /// The time (frame set) index.
    pub time: usize,
    /// The camera index.
    pub camera: usize,
}

/// The views of a viewing graph as images of a rig: view `k` is `views()[k]`, camera
/// `camera` at time `time`. Built by [`RigLayout::new`], which checks it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RigLayout {
    times: usize,
    cameras: usize,
    views: Vec<RigView>,
}

impl RigLayout {
    /// A layout of `times` times and `cameras` cameras; `views[k]` is view `k`.
    ///
    /// # Errors
    ///
    /// [`ViewingGraphError::NoCameras`], [`ViewingGraphError::NoViews`],
    /// [`ViewingGraphError::RigViewOutOfRange`], [`ViewingGraphError::DuplicateRigView`].
    pub fn new(
        times: usize,
        cameras: usize,
        views: Vec<RigView>,
    ) -> Result<Self, ViewingGraphError> {
        if cameras == 0 {
            return Err(ViewingGraphError::NoCameras);
        }
        if views.is_empty() {
            return Err(ViewingGraphError::NoViews);
        }
        for (k, v) in views.iter().enumerate() {
            if v.time >= times || v.camera >= cameras {
                return Err(ViewingGraphError::RigViewOutOfRange {
                    view: k,
                    time: v.time,
                    camera: v.camera,
                    times,
                    cameras,
                });
            }
        }
        // Duplicates by sorting (no table of times x cameras, which could be huge).
        let mut order: Vec<usize> = (0..views.len()).collect();
        order.sort_by_key(|&k| (views[k].time, views[k].camera, k));
        for pair in order.windows(2) {
            let (first, view) = (pair[0], pair[1]);
            if views[first] == views[view] {
                return Err(ViewingGraphError::DuplicateRigView {
                    first,
                    view,
                    time: views[view].time,
                    camera: views[view].camera,
                });
            }
        }
        Ok(Self {
            times,
            cameras,
            views,
        })
    }

    /// One camera, one view per time: view `k` is (time `k`, camera 0).
    pub(crate) fn single_camera(views: usize) -> Self {
        Self {
            times: views,
            cameras: 1,
            views: (0..views).map(|time| RigView { time, camera: 0 }).collect(),
        }
    }

    /// Number of times.
    pub fn times(&self) -> usize {
        self.times
    }

    /// Number of cameras.
    pub fn cameras(&self) -> usize {
        self.cameras
    }

    /// The views, in view order.
    pub fn views(&self) -> &[RigView] {
        &self.views
    }
}

/// What an averaging kept, dropped and found, for every kind of averaging in this crate.
#[derive(Clone, Debug, PartialEq)]
pub struct AveragingReport {
    /// The views solved (the largest connected component), increasing.
    pub kept_views: Vec<usize>,
    /// The views left out (outside the largest component, without edges, or, for
    /// translations, with fewer than two edges or without a rotation), increasing.
    pub dropped_views: Vec<usize>,
    /// The times without a kept view (rig form; empty otherwise), increasing.
    pub dropped_times: Vec<usize>,
    /// The edges left out with the dropped views, increasing.
    pub dropped_edges: Vec<usize>,
    /// Final residual of every edge, radians (`None` for a dropped edge): the angle of
    /// `j_from_i^T * R_j R_i^T` for rotations, the angle between the measured and estimated
    /// directions for translations.
    pub residuals: Vec<Option<f64>>,
    /// Final robust weight of every kept edge in `[0, 1]`, before the caller's weight (`None`
    /// for a dropped edge; 1 when no robust iteration ran).
    pub robust_weights: Vec<Option<f64>>,
    /// The kept edges whose residual exceeds `outlier_threshold`, increasing.
    pub outlier_edges: Vec<usize>,
    /// The Cauchy scale of the robust iterations (given or estimated), radians.
    pub robust_scale: f64,
    /// The residual above which an edge is reported as an outlier, radians.
    pub outlier_threshold: f64,
    /// Nonlinear iterations run (all phases).
    pub iterations: usize,
    /// Whether the last phase that ran stopped on its tolerance rather than its iteration
    /// count.
    pub converged: bool,
    /// Conjugate-gradient iterations summed over all linear solves (after a direct solve,
    /// where one is made, only its refinements).
    pub linear_iterations: usize,
    /// Whether every linear solve reached its tolerance.
    pub linear_converged: bool,
}

/// Relative residual at which a direct solve (the chordal initialization) stops:
/// `|A x - b| <= tol |b|`.
pub(crate) const CG_TOLERANCE: f64 = 1e-10;

/// Relative residual at which the solve of one iteration of a nonlinear loop stops: the next
/// iteration corrects what is left, so a loose tolerance costs accuracy only in the last
/// steps, which are small.
pub(crate) const CG_STEP_TOLERANCE: f64 = 1e-6;

/// Outcome of one conjugate-gradient solve.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CgOutcome {
    pub iterations: usize,
    pub converged: bool,
}

/// Checks an edge's ends.
pub(crate) fn check_ends(
    edge: usize,
    i: usize,
    j: usize,
    views: usize,
) -> Result<(), ViewingGraphError> {
    for view in [i, j] {
        if view >= views {
            return Err(ViewingGraphError::ViewOutOfRange { edge, view, views });
        }
    }
    if i == j {
        return Err(ViewingGraphError::SelfLoop { edge, view: i });
    }
    Ok(())
}

/// Checks an edge's weight.
pub(crate) fn check_edge_weight(edge: usize, weight: f64) -> Result<(), ViewingGraphError> {
    if weight.is_finite() && weight > 0.0 {
        Ok(())
    } else {
        Err(ViewingGraphError::InvalidWeight { edge, weight })
    }
}

/// Whether a norm is that of a finite unit vector or quaternion.
pub(crate) fn is_unit(norm: f64) -> bool {
    norm.is_finite() && (norm - 1.0).abs() <= UNIT_NORM_TOLERANCE
}

/// The kept part of a rig viewing graph, its gauge and the index of its unknown blocks.
pub(crate) struct Prepared {
    /// Connectivity: kept and dropped views and edges (global indices).
    pub component: Component,
    /// Kept edges as pairs of local view indices, in `component.edges` order.
    pub local_edges: Vec<[usize; 2]>,
    /// Time of every local view.
    pub view_time: Vec<usize>,
    /// Camera of every local view.
    pub view_camera: Vec<usize>,
    /// The times without a kept view.
    pub dropped_times: Vec<usize>,
    /// The anchor time (the first at which the reference camera has a kept view).
    pub anchor_time: usize,
    /// The local view of (anchor time, reference camera).
    pub anchor_view: usize,
    /// The reference camera.
    pub reference_camera: usize,
    /// Block of every time (`None` for the anchor and dropped times).
    pub time_block: Vec<Option<usize>>,
    /// Block of every camera (`None` for the reference camera).
    pub camera_block: Vec<Option<usize>>,
    /// Number of free blocks.
    pub blocks: usize,
}

impl Prepared {
    /// Kept and dropped parts of the graph: `pairs` are the validated edges, `usable` the
    /// views allowed in (the others are dropped), `min_degree` the k-core to keep.
    pub(crate) fn new(
        layout: &RigLayout,
        pairs: &[[usize; 2]],
        usable: &[bool],
        min_degree: usize,
        reference_camera: usize,
    ) -> Result<Self, ViewingGraphError> {
        let n = layout.views.len();
        let component = component(n, pairs, usable, min_degree);
        if component.views.is_empty() {
            return Err(ViewingGraphError::NoSolvableViews);
        }
        let mut local = vec![usize::MAX; n];
        for (l, &v) in component.views.iter().enumerate() {
            local[v] = l;
        }
        let local_edges: Vec<[usize; 2]> = component
            .edges
            .iter()
            .map(|&e| [local[pairs[e][0]], local[pairs[e][1]]])
            .collect();
        let view_time: Vec<usize> = component
            .views
            .iter()
            .map(|&v| layout.views[v].time)
            .collect();
        let view_camera: Vec<usize> = component
            .views
            .iter()
            .map(|&v| layout.views[v].camera)
            .collect();
        let (times, cameras) = (layout.times, layout.cameras);
        let mut time_kept = vec![false; times];
        let mut camera_kept = vec![false; cameras];
        for (&t, &c) in view_time.iter().zip(&view_camera) {
            time_kept[t] = true;
            camera_kept[c] = true;
        }
        for (camera, kept) in camera_kept.iter().enumerate() {
            if !kept {
                return Err(ViewingGraphError::UndeterminedCamera {
                    camera,
                    reason: "none of its views is in the largest connected component",
                });
            }
        }
        // The times and cameras joined by their kept views must form one connected
        // bipartite graph, or a group of cameras could turn freely against the reference.
        let mut uf = UnionFind::new(times + cameras);
        for (&t, &c) in view_time.iter().zip(&view_camera) {
            uf.union(t, times + c);
        }
        let reference_root = uf.find(times + reference_camera);
        for camera in 0..cameras {
            if uf.find(times + camera) != reference_root {
                return Err(ViewingGraphError::UndeterminedCamera {
                    camera,
                    reason: "no chain of shared times ties its views to the reference camera's",
                });
            }
        }
        let mut anchor: Option<(usize, usize)> = None;
        for (l, (&t, &c)) in view_time.iter().zip(&view_camera).enumerate() {
            if c == reference_camera && anchor.is_none_or(|(at, _)| t < at) {
                anchor = Some((t, l));
            }
        }
        let Some((anchor_time, anchor_view)) = anchor else {
            return Err(ViewingGraphError::UndeterminedCamera {
                camera: reference_camera,
                reason: "none of its views is in the largest connected component",
            });
        };
        let mut blocks = 0;
        let mut time_block = vec![None; times];
        for (t, kept) in time_kept.iter().enumerate() {
            if *kept && t != anchor_time {
                time_block[t] = Some(blocks);
                blocks += 1;
            }
        }
        let mut camera_block = vec![None; cameras];
        for (c, block) in camera_block.iter_mut().enumerate() {
            if c != reference_camera {
                *block = Some(blocks);
                blocks += 1;
            }
        }
        let dropped_times = (0..times).filter(|&t| !time_kept[t]).collect();
        Ok(Self {
            component,
            local_edges,
            view_time,
            view_camera,
            dropped_times,
            anchor_time,
            anchor_view,
            reference_camera,
            time_block,
            camera_block,
            blocks,
        })
    }

    /// The linear problem over this graph with the times' rotations `world_from_rig` (indexed
    /// by time; only kept times are read).
    pub(crate) fn system<'a>(&'a self, world_from_rig: &'a [Matrix3<f64>]) -> BlockSystem<'a> {
        self.system_with_edges(world_from_rig, &self.local_edges)
    }

    /// The same over other edges between the local views (for example the local edges
    /// followed by distance constraints).
    pub(crate) fn system_with_edges<'a>(
        &'a self,
        world_from_rig: &'a [Matrix3<f64>],
        edges: &'a [[usize; 2]],
    ) -> BlockSystem<'a> {
        BlockSystem {
            prepared: self,
            world_from_rig,
            edges,
        }
    }
}

/// The least-squares problem `min sum_e w_e |x_b - x_a - y_e|^2` with `x_k = u_t + W_t v_c`.
pub(crate) struct BlockSystem<'a> {
    prepared: &'a Prepared,
    world_from_rig: &'a [Matrix3<f64>],
    /// The edges `[a, b]` between local views, index for index with the solves' `info`.
    edges: &'a [[usize; 2]],
}

/// Scratch vectors of [`BlockSystem::solve`].
#[derive(Default)]
pub(crate) struct CgScratch {
    views: Vec<Vector3<f64>>,
    grads: Vec<Vector3<f64>>,
    r: Vec<Vector3<f64>>,
    z: Vec<Vector3<f64>>,
    p: Vec<Vector3<f64>>,
    ap: Vec<Vector3<f64>>,
    precond: Vec<Matrix3<f64>>,
    /// The sparse Cholesky factorization of the graph's normal equations: its pattern is the
    /// graph's, the same for every solve of one [`Prepared`] (`None` until the first solve;
    /// `Some(None)` when faer could not analyse the pattern).
    direct: Option<Option<SparseCholesky>>,
    /// Whether the solves factor the system first (see the module documentation).
    pub(crate) direct_solve: bool,
}

fn dot(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x.dot(y)).sum()
}

impl BlockSystem<'_> {
    /// Each local view's value `u_t + W_t v_c` from the blocks `z`.
    pub(crate) fn view_values(&self, z: &[Vector3<f64>], out: &mut Vec<Vector3<f64>>) {
        let p = self.prepared;
        out.clear();
        out.extend(p.view_time.iter().zip(&p.view_camera).map(|(&t, &c)| {
            let mut x = Vector3::zeros();
            if let Some(b) = p.time_block[t] {
                x += z[b];
            }
            if let Some(b) = p.camera_block[c] {
                x += self.world_from_rig[t] * z[b];
            }
            x
        }));
    }

    /// Adds the view gradients `grads` into the blocks: `out = J_view^T grads`.
    fn scatter(&self, grads: &[Vector3<f64>], out: &mut [Vector3<f64>]) {
        let p = self.prepared;
        out.iter_mut().for_each(|o| *o = Vector3::zeros());
        for ((&t, &c), g) in p.view_time.iter().zip(&p.view_camera).zip(grads) {
            if let Some(b) = p.time_block[t] {
                out[b] += g;
            }
            if let Some(b) = p.camera_block[c] {
                out[b] += self.world_from_rig[t].tr_mul(g);
            }
        }
    }

    /// `out = J^T Lambda J z`.
    fn apply(
        &self,
        info: &[Matrix3<f64>],
        z: &[Vector3<f64>],
        s: &mut CgScratch,
        out: &mut [Vector3<f64>],
    ) {
        let mut views = std::mem::take(&mut s.views);
        self.view_values(z, &mut views);
        s.grads.clear();
        s.grads.resize(views.len(), Vector3::zeros());
        for (&[a, b], l) in self.edges.iter().zip(info) {
            let r = l * (views[b] - views[a]);
            s.grads[b] += r;
            s.grads[a] -= r;
        }
        self.scatter(&s.grads, out);
        s.views = views;
    }

    /// An edge's Jacobian blocks `(block, matrix)`, duplicates merged (at most four): the
    /// view value `x_v = u_t + W_t v_c` enters `x_b - x_a` with sign -1 for `a`, +1 for `b`.
    fn edge_jacobian(&self, a: usize, b: usize) -> ([(usize, Matrix3<f64>); 4], usize) {
        let p = self.prepared;
        let mut jac: [(usize, Matrix3<f64>); 4] = [(usize::MAX, Matrix3::zeros()); 4];
        let mut n = 0;
        for (view, sign) in [(a, -1.0), (b, 1.0)] {
            let (t, c) = (p.view_time[view], p.view_camera[view]);
            let entries = [
                p.time_block[t].map(|k| (k, Matrix3::identity() * sign)),
                p.camera_block[c].map(|k| (k, self.world_from_rig[t] * sign)),
            ];
            for (k, m) in entries.into_iter().flatten() {
                if let Some(slot) = jac[..n].iter_mut().find(|(j, _)| *j == k) {
                    slot.1 += m;
                } else {
                    jac[n] = (k, m);
                    n += 1;
                }
            }
        }
        (jac, n)
    }

    /// Solves `J^T Lambda J z = b` by sparse Cholesky (the factorization's pattern analysed on
    /// the first call and kept in `direct`); false when it cannot (then `z` is unchanged).
    fn solve_direct(
        &self,
        info: &[Matrix3<f64>],
        b: &[Vector3<f64>],
        z: &mut [Vector3<f64>],
        direct: &mut Option<Option<SparseCholesky>>,
    ) -> bool {
        let p = self.prepared;
        let factor = direct.get_or_insert_with(|| {
            let pairs = self.edges.iter().flat_map(|&[a, b]| {
                let (jac, n) = self.edge_jacobian(a, b);
                (0..n).flat_map(move |i| (0..=i).map(move |j| (jac[i].0, jac[j].0)))
            });
            SparseCholesky::new(p.blocks, pairs)
        });
        let Some(factor) = factor.as_mut().filter(|f| f.blocks() == p.blocks) else {
            return false;
        };
        factor.clear();
        for (&[a, b], l) in self.edges.iter().zip(info) {
            let (jac, n) = self.edge_jacobian(a, b);
            for i in 0..n {
                let lm = l * jac[i].1;
                for j in 0..=i {
                    factor.add(jac[j].0, jac[i].0, &jac[j].1.tr_mul(&lm));
                }
            }
        }
        factor.solve(b, z)
    }

    /// The 3x3 diagonal blocks of `J^T Lambda J`, inverted (a multiple of the identity for a
    /// singular block, the identity for an empty one).
    fn preconditioner(&self, info: &[Matrix3<f64>], out: &mut Vec<Matrix3<f64>>) {
        let p = self.prepared;
        out.clear();
        out.resize(p.blocks, Matrix3::zeros());
        for (&[a, b], l) in self.edges.iter().zip(info) {
            let (jac, n) = self.edge_jacobian(a, b);
            for (k, m) in &jac[..n] {
                out[*k] += m.tr_mul(&(l * m));
            }
        }
        for m in out.iter_mut() {
            let t = m.trace() / 3.0;
            // A block much less than full rank (an edge's information is rank 2 for
            // directions) is regularized by a small multiple of its trace.
            let regularized = *m + Matrix3::identity() * (1e-9 * t);
            *m = regularized
                .try_inverse()
                .filter(|i| i.iter().all(|x| x.is_finite()))
                .unwrap_or_else(|| {
                    if t > 0.0 && t.is_finite() {
                        Matrix3::identity() / t
                    } else {
                        Matrix3::identity()
                    }
                });
        }
    }

    /// Solves the normal equations `sum_e D_e^T Lambda_e D_e z = sum_e D_e^T g_e` for the
    /// blocks `z` (warm start: `z` on entry), where `D_e z = x_b - x_a` and `info` holds the
    /// edges' symmetric information matrices `Lambda_e` and `rhs` their vectors `g_e` (for the
    /// scalar problem `min sum_e w_e |x_b - x_a - y_e|^2`: `Lambda_e = w_e I`, `g_e = w_e y_e`),
    /// by preconditioned conjugate gradients to the relative residual `tolerance`.
    pub(crate) fn solve(
        &self,
        info: &[Matrix3<f64>],
        rhs: &[Vector3<f64>],
        z: &mut [Vector3<f64>],
        s: &mut CgScratch,
        tolerance: f64,
    ) -> CgOutcome {
        let n = self.prepared.blocks;
        if n == 0 {
            return CgOutcome {
                iterations: 0,
                converged: true,
            };
        }
        // b = sum_e D_e^T g_e.
        let views = self.prepared.view_time.len();
        let mut grads = vec![Vector3::zeros(); views];
        for (&[a, c], g) in self.edges.iter().zip(rhs) {
            grads[c] += g;
            grads[a] -= g;
        }
        let mut b = vec![Vector3::zeros(); n];
        self.scatter(&grads, &mut b);
        let b_norm = dot(&b, &b).sqrt();
        // The direct solve first; conjugate gradients from its solution check it and refine
        // it where it falls short of the tolerance, or solve from the warm start alone.
        if s.direct_solve {
            let mut direct = s.direct.take();
            self.solve_direct(info, &b, z, &mut direct);
            s.direct = direct;
        }
        let mut precond = std::mem::take(&mut s.precond);
        self.preconditioner(info, &mut precond);
        let mut ap = std::mem::take(&mut s.ap);
        ap.resize(n, Vector3::zeros());
        self.apply(info, z, s, &mut ap);
        let mut r = std::mem::take(&mut s.r);
        r.clear();
        r.extend(b.iter().zip(&ap).map(|(b, a)| b - a));
        let mut zz = std::mem::take(&mut s.z);
        zz.clear();
        zz.extend(precond.iter().zip(&r).map(|(m, r)| m * r));
        let mut p = std::mem::take(&mut s.p);
        p.clear();
        p.extend_from_slice(&zz);
        let mut rz = dot(&r, &zz);
        let max_iterations = 3 * 3 * n + 100;
        let mut outcome = CgOutcome {
            iterations: 0,
            converged: false,
        };
        let threshold = tolerance * b_norm;
        while outcome.iterations < max_iterations {
            let r_norm = dot(&r, &r).sqrt();
            if r_norm <= threshold || r_norm == 0.0 {
                outcome.converged = true;
                break;
            }
            self.apply(info, &p, s, &mut ap);
            let pap = dot(&p, &ap);
            if !(pap > 0.0 && pap.is_finite()) {
                // The residual lies in the null space of a singular block (a block without
                // weighted edges): nothing more can be reduced.
                outcome.converged = r_norm <= 1e3 * threshold;
                break;
            }
            let alpha = rz / pap;
            for ((x, p), (r, a)) in z.iter_mut().zip(&p).zip(r.iter_mut().zip(&ap)) {
                *x += alpha * p;
                *r -= alpha * a;
            }
            for ((zi, m), ri) in zz.iter_mut().zip(&precond).zip(&r) {
                *zi = m * ri;
            }
            let rz_new = dot(&r, &zz);
            let beta = rz_new / rz;
            rz = rz_new;
            for (pi, zi) in p.iter_mut().zip(&zz) {
                *pi = zi + beta * *pi;
            }
            outcome.iterations += 1;
        }
        s.precond = precond;
        s.ap = ap;
        s.r = r;
        s.z = zz;
        s.p = p;
        outcome
    }
}

/// The median of a non-empty list (the lower middle for an even count); 0 when empty.
pub(crate) fn median(mut values: Vec<f64>) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mid = (values.len() - 1) / 2;
    let (_, m, _) = values.select_nth_unstable_by(mid, f64::total_cmp);
    *m
}
