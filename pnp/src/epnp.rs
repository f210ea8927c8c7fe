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
//! with `a_i = (1, alpha_i1, ..)`, built in O(n).
//!
//! Specifics of this implementation:
//! - Control points sit at the centroid and one standard deviation along each principal axis,
//!   so `alpha` is a whitened coordinate and `d_k . d_l = s_k^2 delta_kl` are the quadratic
//!   constraints (equivalent to the paper's control-point distances).
//! - The centroid block `c_0` is eliminated in closed form (a Schur complement), leaving a
//!   9 x 9 (planar: 6 x 6) eigenproblem, solved by a fixed-size symmetric QR.
//! - Betas for null-space dimensions 1, 2 and 3 by the paper's linearization, each refined by
//!   Gauss-Newton over four betas (paper section 3.4); the candidate with the smallest bearing
//!   error wins.
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

use nalgebra::{
    Cholesky, Isometry3, Matrix3, Matrix4, Matrix6, Point3, U3, Vector3, Vector4, Vector6,
};

use crate::error::{Degeneracy, PnpError};
use crate::geometry::{isometry_from, rotation_from_correlation, total_chord_error};
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

/// Options of [`epnp_with`].
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct EpnpOptions {
    /// Run a second pass with the rows of each point divided by its depth from the first
    /// pass, and keep whichever pass has the smaller bearing error. The cross-product rows
    /// measure `|p_i| sin(angle_i)`, which weights far points by their depth; the second pass
    /// measures the angle itself, the quantity the noise is in. About twice the work; lowers
    /// the median rotation error by 5 to 7 percent on the paper's synthetic setup. Default
    /// true; false gives the paper's single pass.
    pub depth_reweighting: bool,
}

impl Default for EpnpOptions {
    fn default() -> Self {
        Self {
            depth_reweighting: true,
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
pub fn epnp(bearings: &[Vector3<f64>], points: &[Point3<f64>]) -> Result<Isometry3<f64>, PnpError> {
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
) -> Result<Isometry3<f64>, PnpError> {
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

/// EPnP on validated input with known principal axes.
pub(crate) fn solve(
    bearings: &[Vector3<f64>],
    points: &[Point3<f64>],
    spread: &PointSpread,
    options: &EpnpOptions,
) -> Result<Candidate, PnpError> {
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
            for skip in 0..EPNP_MIN_POINTS {
                let index: Vec<usize> = (0..EPNP_MIN_POINTS).filter(|&i| i != skip).collect();
                let y = [bearings[index[0]], bearings[index[1]], bearings[index[2]]];
                let x = [points[index[0]], points[index[1]], points[index[2]]];
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
        // out with the first pass's depths turns the algebraic error into the angular one.
        let depths: Vec<f64> = points
            .iter()
            .map(|x| (first.rotation * x.coords + first.translation).norm())
            .collect();
        let mean = depths.iter().sum::<f64>() / depths.len() as f64;
        if depths.iter().all(|d| *d > 0.0) && mean.is_finite() {
            let weights: Vec<f64> = depths.iter().map(|d| (mean / d).powi(2)).collect();
            let system = ControlSystem::new(bearings, points, Some(&weights), spread, first.dirs)?;
            // Only the linearization that won the first pass: the weights change the fit, not
            // which null-space dimension describes it.
            keep_better(&mut best, system.solve(bearings, points, Some(first.guess)));
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

/// The index pairs `(a, b)`, `a <= b`, of the products of the four control weights.
const PRODUCTS: [(usize, usize); 10] = [
    (0, 0),
    (0, 1),
    (0, 2),
    (0, 3),
    (1, 1),
    (1, 2),
    (1, 3),
    (2, 2),
    (2, 3),
    (3, 3),
];

/// The accumulated normal equations in control-point coordinates and what is needed to turn a
/// null vector into a pose.
struct ControlSystem<'a> {
    spread: &'a PointSpread,
    /// Number of control directions: 3 (general) or 2 (planar).
    dirs: usize,
    /// `blocks[a][b] = sum_i w_ia w_ib (I - f_i f_i^T)`, with `w_i = (1, alpha_i1, ..)`.
    blocks: [[Matrix3<f64>; 4]; 4],
    /// Cholesky factor of `blocks[0][0] = sum_i (I - f_i f_i^T)`.
    centre: Cholesky<f64, U3>,
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
        weights: Option<&[f64]>,
        spread: &'a PointSpread,
        dirs: usize,
    ) -> Result<Self, PnpError> {
        // Whitening: alpha_k = (axis_k / s_k) . (X - centroid); unused directions stay zero.
        let mut scaled_axes = [Vector3::zeros(); 3];
        for (k, axis) in scaled_axes.iter_mut().enumerate().take(dirs) {
            *axis = spread.axes.column(k) / spread.std_devs[k];
        }
        // Fixed-size accumulation (unrolled by the compiler): for every product w_a w_b
        // (a <= b) the six distinct entries of the weighted projector I - f f^T.
        let mut sums = [[0.0; 6]; 10];
        let mut bearing_sums = [Vector3::zeros(); 4];
        for (i, (f, x)) in bearings.iter().zip(points).enumerate() {
            let local = x - spread.centroid;
            let weight = weights.map_or(1.0, |w| w[i]);
            let w = [
                1.0,
                scaled_axes[0].dot(&local),
                scaled_axes[1].dot(&local),
                scaled_axes[2].dot(&local),
            ];
            let projector = [
                (1.0 - f.x * f.x) * weight,
                -f.x * f.y * weight,
                -f.x * f.z * weight,
                (1.0 - f.y * f.y) * weight,
                -f.y * f.z * weight,
                (1.0 - f.z * f.z) * weight,
            ];
            for (sum, &(a, b)) in sums.iter_mut().zip(&PRODUCTS) {
                let product = w[a] * w[b];
                for (s, p) in sum.iter_mut().zip(&projector) {
                    *s += product * p;
                }
            }
            for (sum, wa) in bearing_sums.iter_mut().zip(&w) {
                *sum += f * (wa * weight);
            }
        }
        let mut blocks = [[Matrix3::zeros(); 4]; 4];
        for (sum, &(a, b)) in sums.iter().zip(&PRODUCTS) {
            let block = Matrix3::new(
                sum[0], sum[1], sum[2], sum[1], sum[3], sum[4], sum[2], sum[4], sum[5],
            );
            blocks[a][b] = block;
            blocks[b][a] = block;
        }
        let centre = Cholesky::new(blocks[0][0])
            .ok_or(PnpError::Degenerate(Degeneracy::ParallelBearings))?;
        Ok(Self {
            spread,
            dirs,
            blocks,
            centre,
            bearing_sums,
        })
    }

    /// The centroid block that minimizes the algebraic error for given direction blocks.
    fn centre_for(&self, dirs: &[Vector3<f64>; 3]) -> Vector3<f64> {
        let mut rhs = Vector3::zeros();
        for (block, d) in self.blocks[0][1..].iter().zip(dirs).take(self.dirs) {
            rhs += block * d;
        }
        -self.centre.solve(&rhs)
    }

    /// The reduced (Schur complement) matrix over the direction blocks. In the planar case the
    /// unused third block is padded with a multiple of the identity above every eigenvalue of
    /// the used part, so the smallest eigenvectors are those of the 6 x 6 system.
    fn reduced(&self) -> [[f64; 9]; 9] {
        let mut s = [[0.0; 9]; 9];
        let inv_centre = self.centre.inverse();
        for k in 0..self.dirs {
            let left = self.blocks[k + 1][0] * inv_centre;
            for l in k..self.dirs {
                let block = self.blocks[k + 1][l + 1] - left * self.blocks[0][l + 1];
                for i in 0..3 {
                    for j in 0..3 {
                        s[3 * k + i][3 * l + j] = block[(i, j)];
                        s[3 * l + j][3 * k + i] = block[(i, j)];
                    }
                }
            }
        }
        if self.dirs == 2 {
            // The trace bounds every eigenvalue of a positive semi-definite matrix.
            let pad = 1.0 + 2.0 * (0..6).map(|i| s[i][i]).sum::<f64>();
            for (i, row) in s.iter_mut().enumerate().skip(6) {
                row[i] = pad;
            }
        }
        s
    }

    /// All candidates from the null space; the one with the smallest bearing error.
    /// `only`: restrict to one linearization (0, 1, 2 for N = 1, 2, 3).
    fn solve(
        &self,
        bearings: &[Vector3<f64>],
        points: &[Point3<f64>],
        only: Option<usize>,
    ) -> Option<Candidate> {
        let (_, vectors) = smallest_eigenpairs::<9, 4>(self.reduced())?;
        let kernel_dim = if self.dirs == 3 { 4 } else { 3 };
        let mut kernel = [ControlVector::zero(); 4];
        for (v, column) in kernel.iter_mut().zip(&vectors[..kernel_dim]) {
            for k in 0..self.dirs {
                v.dirs[k] = Vector3::new(column[3 * k], column[3 * k + 1], column[3 * k + 2]);
            }
            v.centre = self.centre_for(&v.dirs);
        }
        let betas = Betas::new(&kernel[..kernel_dim], self.dirs, &self.spread.std_devs);
        let mut best: Option<Candidate> = None;
        for (guess, start) in betas.initial_guesses().iter().enumerate() {
            let Some(start) = start else { continue };
            if only.is_some_and(|g| g != guess) {
                continue;
            }
            let refined = betas.gauss_newton(*start);
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
        let translation = -self.centre.solve(&rhs);
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

/// Most quadratic constraints (general case: the 6 pairs of 3 directions).
const MAX_PAIRS: usize = 6;

/// The quadratic constraints `d_k . d_l = s_k^2 delta_kl` over the null-space weights.
struct Betas<'a> {
    kernel: &'a [ControlVector],
    dirs: usize,
    /// Right-hand sides `s_k^2 delta_kl` of the constraint pairs `(k, l)`, `k <= l`; the
    /// first `count` are used.
    targets: [f64; MAX_PAIRS],
    count: usize,
    /// `table[a][b][row] = u_a,k . u_b,l + u_b,k . u_a,l` for the pair `(k, l)` of `row`:
    /// every constraint is `sum_ab beta_a beta_b table[a][b][row] / 2 = target`.
    table: [[[f64; MAX_PAIRS]; 4]; 4],
    std_devs: &'a Vector3<f64>,
}

/// Betas for up to four null vectors (unused ones zero).
type Beta = [f64; 4];

impl<'a> Betas<'a> {
    fn new(kernel: &'a [ControlVector], dirs: usize, std_devs: &'a Vector3<f64>) -> Self {
        let mut pairs = [(0, 0); MAX_PAIRS];
        let mut targets = [0.0; MAX_PAIRS];
        let mut count = 0;
        for k in 0..dirs {
            for l in k..dirs {
                pairs[count] = (k, l);
                targets[count] = if k == l {
                    std_devs[k] * std_devs[k]
                } else {
                    0.0
                };
                count += 1;
            }
        }
        let mut table = [[[0.0; MAX_PAIRS]; 4]; 4];
        for a in 0..kernel.len() {
            for b in a..kernel.len() {
                let (u, v) = (&kernel[a], &kernel[b]);
                for (row, &(k, l)) in pairs[..count].iter().enumerate() {
                    let value = u.dirs[k].dot(&v.dirs[l]) + v.dirs[k].dot(&u.dirs[l]);
                    table[a][b][row] = value;
                    table[b][a][row] = value;
                }
            }
        }
        Self {
            kernel,
            dirs,
            targets,
            count,
            table,
            std_devs,
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
    /// (3 only with six constraints).
    fn initial_guesses(&self) -> [Option<Beta>; 3] {
        let mut guesses = [None; 3];
        // N = 1: match the control-point distances (paper section 3.3).
        let first = &self.kernel[0];
        let (mut num, mut den) = (0.0, 0.0);
        for k in 0..self.dirs {
            let length = first.dirs[k].norm();
            num += length * self.std_devs[k];
            den += length * length;
        }
        if den > 0.0 {
            guesses[0] = Some([num / den, 0.0, 0.0, 0.0]);
        }
        if self.kernel.len() >= 2 {
            guesses[1] = self.linearized_two();
        }
        if self.kernel.len() >= 3 && self.count == MAX_PAIRS {
            guesses[2] = self.linearized_three();
        }
        guesses
    }

    /// N = 2: least squares for `(beta_00, beta_01, beta_11)` (paper section 3.3).
    fn linearized_two(&self) -> Option<Beta> {
        let products = [(0, 0), (0, 1), (1, 1)];
        let mut normal = Matrix3::zeros();
        let mut rhs = Vector3::zeros();
        for row in 0..self.count {
            let coefficients =
                Vector3::from_fn(|c, _| self.coefficient(products[c].0, products[c].1, row));
            normal += coefficients * coefficients.transpose();
            rhs += coefficients * self.targets[row];
        }
        let b = normal.lu().solve(&rhs)?;
        let (b00, b01, b11) = (b[0], b[1], b[2]);
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
        let products = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];
        let l = Matrix6::from_fn(|row, c| self.coefficient(products[c].0, products[c].1, row));
        let rho = Vector6::from_column_slice(&self.targets);
        let b = l.lu().solve(&rho)?;
        let product = |a: usize, c: usize| {
            let (a, c) = (a.min(c), a.max(c));
            products
                .iter()
                .position(|&p| p == (a, c))
                .map_or(0.0, |i| b[i])
        };
        let pivot = (0..3).max_by(|&a, &c| product(a, a).total_cmp(&product(c, c)))?;
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

    /// Residuals `d_k . d_l - target` and their Jacobian rows at `beta`, from the table.
    /// Unused rows and betas have zero table entries and targets, so the loops run over the
    /// full fixed sizes (which the compiler unrolls).
    fn residuals(&self, beta: &Beta) -> ([f64; MAX_PAIRS], [Vector4<f64>; MAX_PAIRS]) {
        let mut residuals = [0.0; MAX_PAIRS];
        let mut jacobian = [Vector4::zeros(); MAX_PAIRS];
        for (a, table_a) in self.table.iter().enumerate() {
            for (entries, beta_b) in table_a.iter().zip(beta) {
                for (j, entry) in jacobian.iter_mut().zip(entries) {
                    j[a] += entry * beta_b;
                }
            }
        }
        for row in 0..MAX_PAIRS {
            residuals[row] = 0.5 * jacobian[row].dot(&Vector4::from(*beta)) - self.targets[row];
        }
        (residuals, jacobian)
    }

    /// Gauss-Newton on all betas, minimizing the summed squared constraint residuals (paper
    /// section 3.4); a step that does not lower the residual ends it.
    fn gauss_newton(&self, mut beta: Beta) -> Beta {
        let dim = self.kernel.len();
        let (mut r, mut jacobian) = self.residuals(&beta);
        let mut cost: f64 = r.iter().map(|v| v * v).sum();
        for _ in 0..BETA_GN_ITERATIONS {
            let mut normal = Matrix4::zeros();
            let mut gradient = Vector4::zeros();
            for row in 0..MAX_PAIRS {
                normal += jacobian[row] * jacobian[row].transpose();
                gradient += jacobian[row] * r[row];
            }
            // Unused betas stay zero.
            for a in dim..4 {
                normal[(a, a)] = 1.0;
            }
            let Some(step) = normal.cholesky().map(|c| c.solve(&(-gradient))) else {
                break;
            };
            let mut trial = beta;
            for (t, s) in trial.iter_mut().zip(step.iter()) {
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
        beta
    }
}
