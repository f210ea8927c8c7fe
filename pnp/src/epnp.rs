//! EPnP on unit bearing vectors.
//!
//! V. Lepetit, F. Moreno-Noguer and P. Fua, "EPnP: An Accurate O(n) Solution to the PnP
//! Problem", International Journal of Computer Vision 81(2), 2009.
//!
//! Every world point is an affine combination of control points,
//! `X_i = c_0 + sum_k alpha_ik (c_k - c_0)`; the same weights hold in the camera frame, so the
//! camera-frame control points are the only unknowns. Instead of the paper's two image-plane
//! rows per point (which divide by depth), each bearing `f_i` gives the three rows of
//! `f_i x (c_0 + sum_k alpha_ik d_k) = 0` with `d_k = c_k - c_0`, valid for rays at any
//! incidence, also beyond 90 degrees. Their normal matrix is `sum_i (a_i a_i^T) ⊗ (I - f_i f_i^T)`
//! with `a_i = (1, alpha_i1, ..)`, built in O(n) (module `epnp_sums`, with an AVX path).
//!
//! Specifics of this implementation:
//! - Control points sit at the centroid and one standard deviation along each principal axis,
//!   so `alpha` is a whitened coordinate and `d_k . d_l = s_k^2 delta_kl` are the quadratic
//!   constraints (equivalent to the paper's control-point distances).
//! - The centroid block `c_0` is eliminated in closed form (a Schur complement), leaving a
//!   9 x 9 (planar: 6 x 6) eigenproblem, solved by a fixed-size symmetric QL iteration that
//!   forms only the wanted eigenvectors.
//! - Betas for null-space dimensions 1, 2 and 3 by the paper's linearization, each refined by
//!   Gauss-Newton over four betas (paper section 3.4); the candidate with the smallest bearing
//!   error wins. Starts that converge to the same betas are scored once.
//! - The sign of the solution is fixed by `sum_i f_i . p_i > 0` (points along their rays), not
//!   by `z > 0`, so rays behind the image plane are fine.
//! - Planar point sets (rank-2 scatter) use three control points and the three constraints of
//!   the plane (paper section 3.5); thin sets try both and keep the better fit.
//! - Optionally (on by default, [`EpnpOptions::depth_reweighting`]) a second pass divides
//!   each point's rows by its depth from the first pass, so the algebraic error becomes the
//!   angular error.
//! - The rotation comes from the control points by Kabsch's method; the translation is then the
//!   linear least-squares solution of the cross-product equations for that rotation.
//! - With exactly four non-coplanar points the null space is four-dimensional (the paper's
//!   N = 4, which needs relinearization); the P3P solutions of the four triples are added as
//!   candidates instead, so the minimal case is solved exactly.

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};

use crate::NonExhaustive;
use crate::epnp_sums::{DepthWeighting, NormalSums, PRODUCTS, WhitenedFrame, total_chord_error};
use crate::error::{Degeneracy, PnpError, Result};
use crate::geometry::{isometry_from, rotation_from_correlation};
use crate::small_linear::{cholesky_solve_4, solve_linear};
use crate::symmetric_eigen::smallest_eigenpairs;
use crate::validate::{PointSpread, check_bearings_spread, check_correspondences, point_spread};

/// EPnP needs four correspondences (paper section 3).
pub const EPNP_MIN_POINTS: usize = 4;

/// Below this ratio of the third to the first principal standard deviation a world point set
/// is solved as planar only: the deviation from the plane is then round-off.
pub const PLANAR_FLATNESS: f64 = 1e-12;

/// Below this ratio (and above [`PLANAR_FLATNESS`]) both the planar and the general solver run
/// and the one with the smaller bearing error is kept. Sets with a relative thickness between
/// about 1e-12 and 1e-7 are exact for neither model (the planar one ignores the thickness, the
/// general one is ill-conditioned), so their closed-form pose is accurate to about the
/// relative thickness; [`crate::refine_pose`] removes the remainder.
pub const NEAR_PLANAR_FLATNESS: f64 = 0.05;

/// Gauss-Newton iterations on the betas (the paper and its reference code use a handful).
const BETA_GN_ITERATIONS: usize = 5;

/// Options of [`epnp_with`]. Write them in one expression,
/// `EpnpOptions { depth_reweighting: false, ..Default::default() }`.
#[derive(Debug, Clone, PartialEq)]
pub struct EpnpOptions {
    /// Run a second pass with the rows of each point divided by its depth from the first
    /// pass, and keep whichever pass has the smaller bearing error. The cross-product rows
    /// measure `|p_i| sin(angle_i)`, which weights far points by their depth; the second pass
    /// measures the angle itself, the quantity the noise is in. About twice the work; lowers
    /// the median rotation error by 5 to 7 percent on the paper's synthetic setup. Default
    /// true; false gives the paper's single pass.
    pub depth_reweighting: bool,
    /// Keeps the struct open to new fields: write it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for EpnpOptions {
    fn default() -> Self {
        Self {
            depth_reweighting: true,
            non_exhaustive: NonExhaustive::VALUE,
        }
    }
}

/// Camera pose from four or more bearing / world point correspondences by EPnP, with the
/// default [`EpnpOptions`].
///
/// `bearings[i]` is the unit direction, in the camera frame, towards `points[i]` (world
/// frame); rays may point anywhere, including beyond 90 degrees from the optical axis.
/// Returns `camera_from_world`. Planar point sets are handled.
///
/// # Errors
/// [`PnpError::LengthMismatch`], [`PnpError::NotEnoughPoints`] (fewer than 4),
/// [`PnpError::NonFiniteBearing`], [`PnpError::NonFinitePoint`],
/// [`PnpError::NonUnitBearing`], [`PnpError::Degenerate`] (coincident or collinear world
/// points, parallel bearings), [`PnpError::Numerical`] if no candidate gives a rotation.
pub fn epnp(bearings: &[Vector3<f64>], points: &[Point3<f64>]) -> Result<Isometry3<f64>> {
    epnp_with(bearings, points, &EpnpOptions::default())
}

/// [`epnp`] with explicit options.
///
/// # Errors
/// As [`epnp`].
pub fn epnp_with(
    bearings: &[Vector3<f64>],
    points: &[Point3<f64>],
    options: &EpnpOptions,
) -> Result<Isometry3<f64>> {
    check_correspondences("EPnP", EPNP_MIN_POINTS, bearings, points)?;
    check_bearings_spread(bearings)?;
    let spread = point_spread(points)?;
    let best = solve(bearings, points, &spread, options)?;
    Ok(isometry_from(&best.rotation, &best.translation))
}

/// A candidate pose with its summed squared chord error.
#[derive(Debug, Clone)]
pub(crate) struct Candidate {
    pub rotation: Matrix3<f64>,
    pub translation: Vector3<f64>,
    pub error: f64,
    /// Control directions of the system that produced it (3, 2), or 0 for a P3P candidate.
    pub dirs: usize,
    /// The linearization (null-space dimension minus one) it started from.
    pub guess: usize,
}

/// The minimal case's four triples: the indices left when one of the four is skipped.
const TRIPLES: [[usize; 3]; EPNP_MIN_POINTS] = [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]];

/// EPnP on validated input with known principal axes.
pub(crate) fn solve(
    bearings: &[Vector3<f64>],
    points: &[Point3<f64>],
    spread: &PointSpread,
    options: &EpnpOptions,
) -> Result<Candidate> {
    let flatness = spread.flatness();
    let mut best: Option<Candidate> = None;
    if flatness < NEAR_PLANAR_FLATNESS {
        let system = ControlSystem::new(bearings, points, None, spread, 2)?;
        keep_better(&mut best, system.solve(bearings, points, None));
    }
    if flatness >= PLANAR_FLATNESS {
        let system = ControlSystem::new(bearings, points, None, spread, 3)?;
        keep_better(&mut best, system.solve(bearings, points, None));
        if bearings.len() == EPNP_MIN_POINTS {
            // Four non-coplanar points leave a four-dimensional null space, which the
            // linearizations for N <= 3 cannot reach: add the P3P solutions of every triple,
            // ranked by the error on all four points.
            for index in TRIPLES {
                let y = index.map(|i| bearings[i]);
                let x = index.map(|i| points[i]);
                for &(rotation, translation) in crate::p3p::solve_raw(&y, &x).iter() {
                    let error = total_chord_error(&rotation, &translation, bearings, points);
                    keep_better(
                        &mut best,
                        Some(Candidate {
                            rotation,
                            translation,
                            error,
                            dirs: 0,
                            guess: 0,
                        }),
                    );
                }
            }
        }
    }
    if options.depth_reweighting
        && let Some(first) = best.clone()
        && first.dirs > 0
    {
        // The rows of point i carry the factor |p_i| (|f x p| = |p| sin(angle)); dividing it
        // out with the first pass's depths turns the algebraic error into the angular one:
        // weight mean_squared / depth^2, the depths computed where the weights are summed.
        // The scale `mean_squared` (the mean squared depth, `|R c + t|^2` at the centroid `c`
        // plus the scatter `sum_k s_k^2`) only keeps the sums near unit size: a common factor
        // of all weights leaves the null space, the translation and the sign test unchanged.
        let centre = first.rotation * spread.centroid.coords + first.translation;
        let mean_squared = centre.norm_squared() + spread.std_devs.norm_squared();
        if mean_squared > 0.0 && mean_squared.is_finite() {
            let weighting = (&first.rotation, &first.translation, mean_squared);
            // A point at the camera centre has an infinite weight: the centroid block is then
            // not finite, has no Cholesky factor and the system is refused. The first pass
            // stands then, as it does for any failure of the second.
            if let Ok(system) =
                ControlSystem::new(bearings, points, Some(weighting), spread, first.dirs)
            {
                // Only the linearization that won the first pass: the weights change the fit,
                // not which null-space dimension describes it.
                keep_better(&mut best, system.solve(bearings, points, Some(first.guess)));
            }
        }
    }
    best.ok_or(PnpError::Numerical(
        "EPnP: no null-space candidate gave a proper rotation",
    ))
}

/// Replaces `best` by `candidate` if that has the smaller bearing error.
fn keep_better(best: &mut Option<Candidate>, candidate: Option<Candidate>) {
    if let Some(c) = candidate
        && best.as_ref().is_none_or(|b| c.error < b.error)
    {
        *best = Some(c);
    }
}

/// The accumulated normal equations in control-point coordinates and what is needed to turn a
/// null vector into a pose.
struct ControlSystem<'a> {
    spread: &'a PointSpread,
    /// Number of control directions: 3 (general) or 2 (planar).
    dirs: usize,
    /// `blocks[a][b] = sum_i w_ia w_ib (I - f_i f_i^T)`, with `w_i = (1, alpha_i1, ..)`; every
    /// block is symmetric, and `blocks[a][b] = blocks[b][a]`.
    blocks: [[Matrix3<f64>; 4]; 4],
    /// Inverse of `blocks[0][0] = sum_i (I - f_i f_i^T)`, by its Cholesky factor.
    centre_inverse: Matrix3<f64>,
    /// `sum_i w_ia f_i`, for the sign test.
    bearing_sums: [Vector3<f64>; 4],
}

/// A vector of the control-point unknowns: the centroid block and the direction blocks.
#[derive(Debug, Clone, Copy)]
struct ControlVector {
    centre: Vector3<f64>,
    dirs: [Vector3<f64>; 3],
}

impl ControlVector {
    fn zero() -> Self {
        Self {
            centre: Vector3::zeros(),
            dirs: [Vector3::zeros(); 3],
        }
    }

    fn add_scaled(&mut self, other: &Self, scale: f64) {
        self.centre += other.centre * scale;
        for (d, o) in self.dirs.iter_mut().zip(&other.dirs) {
            *d += o * scale;
        }
    }
}

impl<'a> ControlSystem<'a> {
    fn new(
        bearings: &[Vector3<f64>],
        points: &[Point3<f64>],
        weighting: Option<DepthWeighting<'_>>,
        spread: &'a PointSpread,
        dirs: usize,
    ) -> Result<Self> {
        // Whitening: alpha_k = (axis_k / s_k) . (X - centroid); unused directions stay zero.
        let mut scaled_axes = [Vector3::zeros(); 3];
        for (k, axis) in scaled_axes.iter_mut().enumerate().take(dirs) {
            *axis = spread.axes.column(k) / spread.std_devs[k];
        }
        let frame = WhitenedFrame {
            centroid: spread.centroid.coords,
            scaled_axes,
        };
        let sums = NormalSums::accumulate(bearings, points, &frame, weighting);
        let mut blocks = [[Matrix3::zeros(); 4]; 4];
        for (k, &(a, b)) in PRODUCTS.iter().enumerate() {
            let e = sums.projector_entries(k);
            let block = Matrix3::new(e[0], e[1], e[2], e[1], e[3], e[4], e[2], e[4], e[5]);
            blocks[a][b] = block;
            blocks[b][a] = block;
        }
        let bearing_sums = sums.bearing_sums();
        let centre_inverse = symmetric_inverse(&blocks[0][0])
            .ok_or(PnpError::Degenerate(Degeneracy::ParallelBearings))?;
        Ok(Self {
            spread,
            dirs,
            blocks,
            centre_inverse,
            bearing_sums,
        })
    }

    /// The centroid block that minimizes the algebraic error for given direction blocks.
    fn centre_for(&self, dirs: &[Vector3<f64>; 3]) -> Vector3<f64> {
        let mut rhs = Vector3::zeros();
        for (block, d) in self.blocks[0][1..].iter().zip(dirs).take(self.dirs) {
            rhs += block * d;
        }
        -(self.centre_inverse * rhs)
    }

    /// The reduced (Schur complement) matrix over the direction blocks, `3 DIRS x 3 DIRS`.
    fn reduced<const M: usize>(&self) -> [[f64; M]; M] {
        let mut s = [[0.0; M]; M];
        let dirs = M / 3;
        for k in 0..dirs {
            let left = self.blocks[0][k + 1] * self.centre_inverse;
            for l in k..dirs {
                let block = self.blocks[k + 1][l + 1] - left * self.blocks[0][l + 1];
                for i in 0..3 {
                    for j in 0..3 {
                        s[3 * k + i][3 * l + j] = block[(i, j)];
                        s[3 * l + j][3 * k + i] = block[(i, j)];
                    }
                }
            }
        }
        s
    }

    /// The null-space candidates: the `KERNEL` eigenvectors of the smallest eigenvalues of the
    /// reduced matrix (`M = 3 dirs`), with their centroid blocks.
    fn kernel<const M: usize, const KERNEL: usize>(&self) -> Option<[ControlVector; KERNEL]> {
        let (_, vectors) = smallest_eigenpairs::<M, KERNEL>(self.reduced::<M>())?;
        let mut kernel = [ControlVector::zero(); KERNEL];
        for (v, column) in kernel.iter_mut().zip(&vectors) {
            for k in 0..self.dirs {
                v.dirs[k] = Vector3::new(column[3 * k], column[3 * k + 1], column[3 * k + 2]);
            }
            v.centre = self.centre_for(&v.dirs);
        }
        Some(kernel)
    }

    /// All candidates from the null space; the one with the smallest bearing error.
    /// `only`: restrict to one linearization (0, 1, 2 for N = 1, 2, 3).
    fn solve(
        &self,
        bearings: &[Vector3<f64>],
        points: &[Point3<f64>],
        only: Option<usize>,
    ) -> Option<Candidate> {
        let mut kernel = [ControlVector::zero(); 4];
        let kernel_dim = if self.dirs == 3 {
            kernel = self.kernel::<9, 4>()?;
            4
        } else {
            kernel[..3].copy_from_slice(&self.kernel::<6, 3>()?);
            3
        };
        let betas = Betas::new(&kernel, kernel_dim, self.dirs, &self.spread.std_devs);
        let mut best: Option<Candidate> = None;
        let mut tried: [Option<(Beta, f64)>; 3] = [None; 3];
        for (guess, start) in betas.initial_guesses(only).iter().enumerate() {
            let Some(start) = start else { continue };
            let (refined, cost) = betas.gauss_newton(*start);
            // Different starts mostly converge to the same betas: a pose already scored is
            // not computed again, unless this run met the constraints markedly better (on
            // exact data a run that converged further is the exact pose).
            if tried
                .iter()
                .flatten()
                .any(|(t, t_cost)| same_betas(t, &refined) && cost >= *t_cost * (1.0 - SAME_COST))
            {
                continue;
            }
            tried[guess] = Some((refined, cost));
            let mut x = ControlVector::zero();
            for (v, beta) in kernel[..kernel_dim].iter().zip(&refined) {
                x.add_scaled(v, *beta);
            }
            keep_better(&mut best, self.pose(&x, bearings, points, guess));
        }
        best
    }

    /// The pose of a control vector: sign by `sum f . p > 0`, rotation by Kabsch, translation
    /// by linear least squares.
    fn pose(
        &self,
        x: &ControlVector,
        bearings: &[Vector3<f64>],
        points: &[Point3<f64>],
        guess: usize,
    ) -> Option<Candidate> {
        let mut along = self.bearing_sums[0].dot(&x.centre);
        for k in 0..self.dirs {
            along += self.bearing_sums[k + 1].dot(&x.dirs[k]);
        }
        let sign = if along < 0.0 { -1.0 } else { 1.0 };
        let mut h = Matrix3::zeros();
        for k in 0..self.dirs {
            let axis = self.spread.axes.column(k);
            h += (x.dirs[k] * (sign * self.spread.std_devs[k])) * axis.transpose();
        }
        if self.dirs == 2 {
            // Complete the rank-2 correlation of a planar set with the plane normals, so it is
            // R times a positive definite matrix for exact data and has a polar factor.
            let normal = self
                .spread
                .axes
                .column(0)
                .cross(&self.spread.axes.column(1));
            h += x.dirs[0].cross(&x.dirs[1]) * normal.transpose();
        }
        let rotation = rotation_from_correlation(&h)?;
        // t minimizes sum |f_i x (R X_i + t)|^2 for this R: blocks give it in O(1).
        let mut rhs = self.blocks[0][0] * (rotation * self.spread.centroid.coords);
        for k in 0..self.dirs {
            let axis = self.spread.axes.column(k);
            rhs += self.blocks[0][k + 1] * (rotation * axis * self.spread.std_devs[k]);
        }
        let translation = -(self.centre_inverse * rhs);
        let error = total_chord_error(&rotation, &translation, bearings, points);
        (error.is_finite() && translation.iter().all(|v| v.is_finite())).then_some(Candidate {
            rotation,
            translation,
            error,
            dirs: self.dirs,
            guess,
        })
    }
}

/// Betas that give the same pose to within [`SAME_BETAS`] relative: a candidate already
/// scored.
fn same_betas(a: &Beta, b: &Beta) -> bool {
    let scale = a.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    a.iter()
        .zip(b)
        .all(|(x, y)| (x - y).abs() <= SAME_BETAS * scale)
}

/// Relative difference under which two refined betas are one candidate: their poses differ
/// by about this much (1e-10 rad), far below any noise, and no more than the spread of the
/// five Gauss-Newton steps themselves (different starts typically agree to 1e-12..1e-10 on
/// noisy data, and to round-off on exact data).
const SAME_BETAS: f64 = 1e-10;

/// A refined beta within [`SAME_BETAS`] of one already scored is scored again only if its
/// constraint cost is lower by more than this fraction.
const SAME_COST: f64 = 1e-6;

/// Inverse of a symmetric positive definite 3 x 3 matrix by its Cholesky factor
/// `L` (`m = L L^T`, `m^-1 = L^-T L^-1`); `None` if `m` is not positive definite.
fn symmetric_inverse(m: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let l00 = m[(0, 0)];
    if l00.is_nan() || l00 <= 0.0 {
        return None;
    }
    let l00 = l00.sqrt();
    let l10 = m[(1, 0)] / l00;
    let l20 = m[(2, 0)] / l00;
    let d1 = m[(1, 1)] - l10 * l10;
    if d1.is_nan() || d1 <= 0.0 {
        return None;
    }
    let l11 = d1.sqrt();
    let l21 = (m[(2, 1)] - l20 * l10) / l11;
    let d2 = m[(2, 2)] - l20 * l20 - l21 * l21;
    if d2.is_nan() || d2 <= 0.0 {
        return None;
    }
    let l22 = d2.sqrt();
    // L^-1, lower triangular.
    let i00 = 1.0 / l00;
    let i11 = 1.0 / l11;
    let i22 = 1.0 / l22;
    let i10 = -l10 * i00 * i11;
    let i21 = -l21 * i11 * i22;
    let i20 = -(l20 * i00 + l21 * i10) * i22;
    let inverse_l = Matrix3::new(i00, 0.0, 0.0, i10, i11, 0.0, i20, i21, i22);
    Some(inverse_l.tr_mul(&inverse_l))
}

/// The constraint pairs `(k, l)`, `k <= l`, of the three directions, in row order. A planar
/// system uses the rows without direction 2 (their table entries and targets are zero).
const PAIRS: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];

/// The quadratic constraints `d_k . d_l = s_k^2 delta_kl` over the null-space weights.
struct Betas {
    /// Null vectors used (3 or 4).
    dim: usize,
    dirs: usize,
    /// Right-hand sides `s_k^2 delta_kl` of the rows (zero for unused rows).
    targets: [f64; 6],
    /// `table[a][b][row] = u_a,k . u_b,l + u_b,k . u_a,l` for the pair `(k, l)` of `row`:
    /// every constraint is `sum_ab beta_a beta_b table[a][b][row] / 2 = target`. Unused rows
    /// and null vectors are zero, so every loop runs over the full fixed sizes, the rows
    /// innermost.
    table: [[[f64; 6]; 4]; 4],
    /// `|u_0,k|`: the lengths of the first null vector's directions.
    first_lengths: [f64; 3],
    std_devs: Vector3<f64>,
}

/// Betas for up to four null vectors (unused ones zero).
type Beta = [f64; 4];

impl Betas {
    /// `kernel`: the null vectors, unused ones (beyond `dim`) and unused directions zero.
    fn new(kernel: &[ControlVector; 4], dim: usize, dirs: usize, std_devs: &Vector3<f64>) -> Self {
        let mut targets = [0.0; 6];
        for (target, &(k, l)) in targets.iter_mut().zip(&PAIRS) {
            if k == l && k < dirs {
                *target = std_devs[k] * std_devs[k];
            }
        }
        // Gram matrix of all direction blocks: gram[3a + k][3b + l] = u_a,k . u_b,l.
        let mut gram = [[0.0; 12]; 12];
        for i in 0..12 {
            let u = &kernel[i / 3].dirs[i % 3];
            for j in i..12 {
                let value = u.dot(&kernel[j / 3].dirs[j % 3]);
                gram[i][j] = value;
                gram[j][i] = value;
            }
        }
        let mut table = [[[0.0; 6]; 4]; 4];
        for a in 0..4 {
            for b in 0..4 {
                for (row, &(k, l)) in PAIRS.iter().enumerate() {
                    table[a][b][row] = gram[3 * a + k][3 * b + l] + gram[3 * b + k][3 * a + l];
                }
            }
        }
        Self {
            dim,
            dirs,
            targets,
            table,
            first_lengths: kernel[0].dirs.map(|d| d.norm()),
            std_devs: *std_devs,
        }
    }

    /// The coefficient of the product `beta_a beta_b` (`a <= b`) in constraint `row`.
    fn coefficient(&self, a: usize, b: usize, row: usize) -> f64 {
        if a == b {
            0.5 * self.table[a][a][row]
        } else {
            self.table[a][b][row]
        }
    }

    /// Starting betas from the paper's linearization for null-space dimensions 1, 2 and 3
    /// (3 only with six constraints); only the one numbered `only` if given.
    fn initial_guesses(&self, only: Option<usize>) -> [Option<Beta>; 3] {
        let wanted = |guess: usize| only.is_none_or(|g| g == guess);
        let mut guesses = [None; 3];
        // N = 1: match the control-point distances (paper section 3.3).
        if wanted(0) {
            let (mut num, mut den) = (0.0, 0.0);
            for k in 0..self.dirs {
                let length = self.first_lengths[k];
                num += length * self.std_devs[k];
                den += length * length;
            }
            if den > 0.0 {
                guesses[0] = Some([num / den, 0.0, 0.0, 0.0]);
            }
        }
        if self.dim >= 2 && wanted(1) {
            guesses[1] = self.linearized_two();
        }
        if self.dim >= 3 && self.dirs == 3 && wanted(2) {
            guesses[2] = self.linearized_three();
        }
        guesses
    }

    /// N = 2: least squares for `(beta_00, beta_01, beta_11)` (paper section 3.3).
    fn linearized_two(&self) -> Option<Beta> {
        let products = [(0, 0), (0, 1), (1, 1)];
        let mut normal = [[0.0; 3]; 3];
        let mut rhs = [0.0; 3];
        for row in 0..6 {
            let c = products.map(|(a, b)| self.coefficient(a, b, row));
            for i in 0..3 {
                for j in 0..3 {
                    normal[i][j] += c[i] * c[j];
                }
                rhs[i] += c[i] * self.targets[row];
            }
        }
        let [b00, b01, b11] = solve_linear(normal, rhs)?;
        let (beta0, beta1) = if b00 >= b11 {
            if b00.is_nan() || b00 <= 0.0 {
                return None;
            }
            let root = b00.sqrt();
            (root, b01 / root)
        } else {
            if b11.is_nan() || b11 <= 0.0 {
                return None;
            }
            let root = b11.sqrt();
            (b01 / root, root)
        };
        Some([beta0, beta1, 0.0, 0.0])
    }

    /// N = 3: the six products `beta_ab` (a <= b < 3) from the six constraints.
    fn linearized_three(&self) -> Option<Beta> {
        // The products (0,0), (0,1), (0,2), (1,1), (1,2), (2,2): the pairs of `PAIRS`.
        const INDEX: [[usize; 3]; 3] = [[0, 1, 2], [1, 3, 4], [2, 4, 5]];
        let l: [[f64; 6]; 6] =
            core::array::from_fn(|row| PAIRS.map(|(a, c)| self.coefficient(a, c, row)));
        let b = solve_linear(l, self.targets)?;
        let product = |a: usize, c: usize| b[INDEX[a][c]];
        // The largest diagonal product (the last of equals).
        let mut pivot = 0;
        for a in 1..3 {
            if product(a, a).total_cmp(&product(pivot, pivot)).is_ge() {
                pivot = a;
            }
        }
        let diagonal = product(pivot, pivot);
        if diagonal.is_nan() || diagonal <= 0.0 {
            return None;
        }
        let root = diagonal.sqrt();
        let mut beta = [0.0; 4];
        for (a, value) in beta.iter_mut().enumerate().take(3) {
            *value = if a == pivot {
                root
            } else {
                product(pivot, a) / root
            };
        }
        Some(beta)
    }

    /// Residuals `d_k . d_l - target` at `beta` and the transposed Jacobian,
    /// `jacobian[a][row] = sum_b table[a][b][row] beta_b`.
    #[inline]
    fn residuals(&self, beta: &Beta) -> ([f64; 6], [[f64; 6]; 4]) {
        let mut jacobian = [[0.0; 6]; 4];
        for (j, table_a) in jacobian.iter_mut().zip(&self.table) {
            for (entries, beta_b) in table_a.iter().zip(beta) {
                for (j, entry) in j.iter_mut().zip(entries) {
                    *j += entry * beta_b;
                }
            }
        }
        let mut residuals = [0.0; 6];
        for (j, beta_a) in jacobian.iter().zip(beta) {
            for (r, j) in residuals.iter_mut().zip(j) {
                *r += j * beta_a;
            }
        }
        for (r, target) in residuals.iter_mut().zip(&self.targets) {
            *r = 0.5 * *r - target;
        }
        (residuals, jacobian)
    }

    /// Gauss-Newton on all betas, minimizing the summed squared constraint residuals (paper
    /// section 3.4); a step that does not lower the residual ends it. Returns the betas and
    /// their summed squared residual.
    fn gauss_newton(&self, mut beta: Beta) -> (Beta, f64) {
        let (mut r, mut jacobian) = self.residuals(&beta);
        let mut cost: f64 = r.iter().map(|v| v * v).sum();
        for _ in 0..BETA_GN_ITERATIONS {
            // The normal equations J^T J step = -J^T r, the upper triangle packed by rows.
            let dot =
                |u: &[f64; 6], v: &[f64; 6]| -> f64 { u.iter().zip(v).map(|(x, y)| x * y).sum() };
            let [j0, j1, j2, j3] = &jacobian;
            let mut normal = [
                dot(j0, j0),
                dot(j0, j1),
                dot(j0, j2),
                dot(j0, j3),
                dot(j1, j1),
                dot(j1, j2),
                dot(j1, j3),
                dot(j2, j2),
                dot(j2, j3),
                dot(j3, j3),
            ];
            let gradient = [-dot(j0, &r), -dot(j1, &r), -dot(j2, &r), -dot(j3, &r)];
            // Unused betas stay zero.
            if self.dim < 4 {
                normal[9] = 1.0;
            }
            let Some(step) = cholesky_solve_4(&normal, &gradient) else {
                break;
            };
            let mut trial = beta;
            for (t, s) in trial.iter_mut().zip(&step) {
                *t += s;
            }
            let (trial_r, trial_jacobian) = self.residuals(&trial);
            let trial_cost: f64 = trial_r.iter().map(|v| v * v).sum();
            if trial_cost.is_nan() || trial_cost >= cost {
                break;
            }
            let converged = cost - trial_cost <= 1e-15 * cost;
            beta = trial;
            r = trial_r;
            jacobian = trial_jacobian;
            cost = trial_cost;
            if converged {
                break;
            }
        }
        (beta, cost)
    }
}
