//! P3P on unit bearing vectors: Lambda Twist.
//!
//! M. Persson and K. Nordberg, "Lambda Twist: An Accurate Fast Robust Perspective Three Point
//! (P3P) Solver", European Conference on Computer Vision (ECCV), 2018.
//!
//! With depths `lambda_i` along the bearings `y_i`, the three world distances give
//! `lambda^T M_ij lambda = a_ij` (`a_ij = |x_i - x_j|^2`, `b_ij = y_i . y_j`). Two homogeneous
//! combinations `D_1 = a_23 M_12 - a_12 M_23` and `D_2 = a_23 M_13 - a_13 M_23` vanish at the
//! solution; a real root `gamma` of the cubic `det(D_1 + gamma D_2) = 0` makes
//! `D_0 = D_1 + gamma D_2` a degenerate conic, a pair of lines through the solutions. Each line
//! meets `D_1` (or `D_2`) in at most two points; scaling them to the measured distances and a
//! few verified Gauss-Newton steps on the three equations (paper section 3.8) give the depths,
//! and the pose follows from the three camera-frame points.
//!
//! Departures from the paper's presentation, for robustness at no loss of exactness:
//! - the cubic is solved in `gamma` or in `1 / gamma`, whichever has the larger leading
//!   coefficient, and among several real roots the one giving the best-conditioned line pair
//!   is used (any real root with an indefinite `D_0` is valid);
//! - each line is parameterized by two vectors orthogonal to its normal, so no depth ratio is
//!   ever divided by;
//! - the rotation is built from orthonormal frames of the two triangles, so it is a proper
//!   rotation even when the depths are slightly inconsistent.

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};

use crate::error::{Degeneracy, PnpError};
use crate::geometry::isometry_from;
use crate::validate::{COINCIDENT_TOLERANCE, PARALLEL_TOLERANCE, check_correspondences};

/// The most solutions a P3P problem has.
pub const P3P_MAX_SOLUTIONS: usize = 4;

/// Verified Gauss-Newton steps on the depths (the paper uses a few).
const REFINE_ITERATIONS: usize = 5;

/// Relative tolerance under which a negative discriminant or eigenvalue ratio is round-off of
/// a double root (a tangency), and is treated as zero.
const ROUND_OFF: f64 = 1e-12;

/// All real solutions of a P3P problem, at most [`P3P_MAX_SOLUTIONS`], without allocation.
#[derive(Debug, Clone, Copy)]
pub struct P3pSolutions {
    poses: [Isometry3<f64>; P3P_MAX_SOLUTIONS],
    len: usize,
}

impl P3pSolutions {
    fn new() -> Self {
        Self {
            poses: [Isometry3::identity(); P3P_MAX_SOLUTIONS],
            len: 0,
        }
    }

    fn push(&mut self, pose: Isometry3<f64>) {
        if self.len < P3P_MAX_SOLUTIONS {
            self.poses[self.len] = pose;
            self.len += 1;
        }
    }

    /// Number of solutions.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True if there is no solution.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The solutions, each a `camera_from_world`.
    pub fn as_slice(&self) -> &[Isometry3<f64>] {
        &self.poses[..self.len]
    }

    /// Iterates over the solutions.
    pub fn iter(&self) -> core::slice::Iter<'_, Isometry3<f64>> {
        self.as_slice().iter()
    }
}

impl<'a> IntoIterator for &'a P3pSolutions {
    type Item = &'a Isometry3<f64>;
    type IntoIter = core::slice::Iter<'a, Isometry3<f64>>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

/// Every camera pose (`camera_from_world`) that maps the three world points onto their three
/// unit bearings with positive depths, by Lambda Twist.
///
/// Bearings may point anywhere, also beyond 90 degrees from the optical axis.
///
/// # Errors
/// [`PnpError::NonFiniteBearing`], [`PnpError::NonFinitePoint`],
/// [`PnpError::NonUnitBearing`]; [`PnpError::Degenerate`] for coincident or collinear world
/// points or parallel bearings; [`PnpError::NoSolution`] when no real solution with positive
/// depths exists.
pub fn p3p(
    bearings: &[Vector3<f64>; 3],
    points: &[Point3<f64>; 3],
) -> Result<P3pSolutions, PnpError> {
    check_correspondences("P3P", 3, bearings, points)?;
    for (first, second) in [(0, 1), (0, 2), (1, 2)] {
        if bearings[first].cross(&bearings[second]).norm() <= PARALLEL_TOLERANCE {
            return Err(PnpError::Degenerate(Degeneracy::ParallelPair {
                first,
                second,
            }));
        }
        let gap = (points[first] - points[second]).norm();
        let scale = points[first]
            .coords
            .norm()
            .max(points[second].coords.norm());
        if gap == 0.0 || gap <= COINCIDENT_TOLERANCE * scale {
            return Err(PnpError::Degenerate(Degeneracy::CoincidentPair {
                first,
                second,
            }));
        }
    }
    let u = points[1] - points[0];
    let v = points[2] - points[0];
    if u.cross(&v).norm() <= crate::validate::COLLINEAR_TOLERANCE * u.norm() * v.norm() {
        return Err(PnpError::Degenerate(Degeneracy::CollinearPoints));
    }
    let solutions = solve(bearings, points);
    if solutions.is_empty() {
        return Err(PnpError::NoSolution(
            "the three rays admit no placement of the triangle in front of the camera",
        ));
    }
    Ok(solutions)
}

/// Lambda Twist without input checks: degenerate input gives no (or fewer) solutions, never a
/// non-finite pose.
pub(crate) fn solve(y: &[Vector3<f64>; 3], x: &[Point3<f64>; 3]) -> P3pSolutions {
    let mut out = P3pSolutions::new();
    for (rotation, translation) in solve_raw(y, x).iter() {
        out.push(isometry_from(rotation, translation));
    }
    out
}

/// Up to four poses as rotation matrices and translations, without allocation.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RawSolutions {
    poses: [(Matrix3<f64>, Vector3<f64>); P3P_MAX_SOLUTIONS],
    len: usize,
}

impl RawSolutions {
    fn push(&mut self, pose: (Matrix3<f64>, Vector3<f64>)) {
        if self.len < P3P_MAX_SOLUTIONS {
            self.poses[self.len] = pose;
            self.len += 1;
        }
    }

    /// The solutions as `(rotation, translation)` of `camera_from_world`.
    pub(crate) fn iter(&self) -> core::slice::Iter<'_, (Matrix3<f64>, Vector3<f64>)> {
        self.poses[..self.len].iter()
    }
}

/// [`solve`] returning rotation matrices (no quaternion round trip), for RANSAC.
pub(crate) fn solve_raw(y: &[Vector3<f64>; 3], x: &[Point3<f64>; 3]) -> RawSolutions {
    let mut out = RawSolutions {
        poses: [(Matrix3::identity(), Vector3::zeros()); P3P_MAX_SOLUTIONS],
        len: 0,
    };
    let b12 = y[0].dot(&y[1]);
    let b13 = y[0].dot(&y[2]);
    let b23 = y[1].dot(&y[2]);
    let a12 = (x[0] - x[1]).norm_squared();
    let a13 = (x[0] - x[2]).norm_squared();
    let a23 = (x[1] - x[2]).norm_squared();
    let m12 = Matrix3::new(1.0, -b12, 0.0, -b12, 1.0, 0.0, 0.0, 0.0, 0.0);
    let m13 = Matrix3::new(1.0, 0.0, -b13, 0.0, 0.0, 0.0, -b13, 0.0, 1.0);
    let m23 = Matrix3::new(0.0, 0.0, 0.0, 0.0, 1.0, -b23, 0.0, -b23, 1.0);
    let d1 = m12 * a23 - m23 * a12;
    let d2 = m13 * a23 - m23 * a13;

    let Some(d0) = degenerate_member(&d1, &d2) else {
        return out;
    };
    let Some(lines) = line_pair(&d0) else {
        return out;
    };
    // Intersect each line with the better-conditioned of the two conics.
    let d1_scale = d1.norm();
    let d2_scale = d2.norm();
    let distances = [(a12, m12), (a13, m13), (a23, m23)];
    let (scale_a, scale_m) = distances
        .iter()
        .copied()
        .max_by(|p, q| p.0.total_cmp(&q.0))
        .unwrap_or((a12, m12));
    let mut depths_found: [Vector3<f64>; P3P_MAX_SOLUTIONS] = [Vector3::zeros(); 4];
    let mut found = 0;
    for normal in lines.iter().flatten() {
        let (p, q) = orthonormal_complement(normal);
        let restrict = |d: &Matrix3<f64>, scale: f64| {
            let a = p.dot(&(d * p)) / scale;
            let b = p.dot(&(d * q)) / scale;
            let c = q.dot(&(d * q)) / scale;
            (a, b, c)
        };
        let r1 = if d1_scale > 0.0 {
            restrict(&d1, d1_scale)
        } else {
            (0.0, 0.0, 0.0)
        };
        let r2 = if d2_scale > 0.0 {
            restrict(&d2, d2_scale)
        } else {
            (0.0, 0.0, 0.0)
        };
        let size = |r: (f64, f64, f64)| r.0.abs() + r.1.abs() + r.2.abs();
        let (a, b, c) = if size(r1) >= size(r2) { r1 } else { r2 };
        for (alpha, beta) in homogeneous_quadratic_roots(a, b, c).iter().flatten() {
            let mut lambda = p * *alpha + q * *beta;
            if lambda.iter().all(|v| *v < 0.0) {
                lambda = -lambda;
            }
            if !lambda.iter().all(|v| *v > 0.0) {
                continue;
            }
            let quad = lambda.dot(&(scale_m * lambda));
            if quad.is_nan() || quad <= 0.0 {
                continue;
            }
            let mut lambda = lambda * (scale_a / quad).sqrt();
            refine_depths(&mut lambda, y, [a12, a13, a23], [b12, b13, b23]);
            if !lambda.iter().all(|v| v.is_finite() && *v > 0.0) {
                continue;
            }
            if depths_found[..found]
                .iter()
                .any(|l| (l - lambda).norm() <= 1e-12 * lambda.norm())
            {
                continue;
            }
            if found < P3P_MAX_SOLUTIONS {
                depths_found[found] = lambda;
                found += 1;
            }
            if let Some(pose) = pose_from_depths(y, x, &lambda) {
                out.push(pose);
            }
        }
    }
    out
}

/// A real root of `det(D1 + gamma D2) = 0` giving an indefinite (or rank-one) `D0`, as that
/// matrix; `None` if there is none.
fn degenerate_member(d1: &Matrix3<f64>, d2: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    // det(A + g B) = det A + g tr(adj(A) B) + g^2 tr(adj(B) A) + g^3 det B.
    let det1 = d1.determinant();
    let det2 = d2.determinant();
    let mixed1 = (adjugate(d1) * d2).trace();
    let mixed2 = (adjugate(d2) * d1).trace();
    // Solve in gamma (D1 + gamma D2) or in mu = 1/gamma (mu D1 + D2), whichever is monic-safer.
    let (lead, c2, c1, c0, swapped) = if det2.abs() >= det1.abs() {
        (det2, mixed2, mixed1, det1, false)
    } else {
        (det1, mixed1, mixed2, det2, true)
    };
    let member = |root: f64| {
        if swapped {
            d1 * root + d2
        } else {
            d1 + d2 * root
        }
    };
    if lead == 0.0 {
        // Both D1 and D2 are singular: D1 itself (or D2) is a degenerate member.
        return Some(if det1 == 0.0 { *d1 } else { *d2 });
    }
    let roots = cubic_roots(c2 / lead, c1 / lead, c0 / lead);
    let mut best: Option<(f64, Matrix3<f64>)> = None;
    for root in roots.iter().flatten() {
        let d0 = member(*root);
        let Some((s1, s2)) = nonzero_eigenvalues(&d0) else {
            continue;
        };
        // Quality: indefinite and balanced; a rank-one member (double line) scores 0.
        let (big, small) = if s1.abs() >= s2.abs() {
            (s1, s2)
        } else {
            (s2, s1)
        };
        if big == 0.0 {
            continue;
        }
        let ratio = -small / big;
        if ratio < -ROUND_OFF {
            continue;
        }
        if best.as_ref().is_none_or(|(r, _)| ratio > *r) {
            best = Some((ratio, d0));
        }
    }
    best.map(|(_, d0)| d0)
}

/// The two nonzero eigenvalues of a symmetric 3 x 3 matrix with a zero eigenvalue: roots of
/// `s^2 - trace s + (sum of principal 2 x 2 minors) = 0`.
fn nonzero_eigenvalues(m: &Matrix3<f64>) -> Option<(f64, f64)> {
    let trace = m.trace();
    let minors = m[(0, 0)] * m[(1, 1)] - m[(0, 1)] * m[(1, 0)] + m[(0, 0)] * m[(2, 2)]
        - m[(0, 2)] * m[(2, 0)]
        + m[(1, 1)] * m[(2, 2)]
        - m[(1, 2)] * m[(2, 1)];
    let disc = (trace * trace - 4.0 * minors).max(0.0);
    let root = disc.sqrt();
    let q = -0.5 * (trace + trace.signum() * root);
    if q == 0.0 {
        return (trace == 0.0 && minors == 0.0).then_some((0.0, 0.0));
    }
    // Roots of s^2 - trace s + minors: -q and -minors / q (stable form).
    Some((-q, -minors / q))
}

/// The normals `n` of the lines `n . lambda = 0` whose union is the degenerate conic `d0`
/// (symmetric, rank 2 indefinite, or rank 1). `None` if `d0` is definite on its range.
fn line_pair(d0: &Matrix3<f64>) -> Option<[Option<Vector3<f64>>; 2]> {
    let (s1, s2) = nonzero_eigenvalues(d0)?;
    let (big, small) = if s1.abs() >= s2.abs() {
        (s1, s2)
    } else {
        (s2, s1)
    };
    if big == 0.0 {
        return None;
    }
    let e1 = eigenvector(d0, big)?;
    // Within the plane orthogonal to e1, d0 is the 2 x 2 form [[small, 0], [0, 0]] in its
    // eigenbasis; solving that 2 x 2 problem directly stays accurate as small -> 0.
    let (p, q) = orthonormal_complement(&e1);
    let a = p.dot(&(d0 * p));
    let b = p.dot(&(d0 * q));
    let c = q.dot(&(d0 * q));
    // Eigenpair of the 2 x 2 form [[a, b], [b, c]] with the larger-magnitude eigenvalue (the
    // other is the known zero), in closed form without trigonometry.
    let mean = 0.5 * (a + c);
    let half_gap = 0.5 * (a - c);
    let radius = (half_gap * half_gap + b * b).sqrt();
    let sigma2 = if mean >= 0.0 {
        mean + radius
    } else {
        mean - radius
    };
    let first = Vector3::from(p * b + q * (sigma2 - a));
    let second = Vector3::from(p * (sigma2 - c) + q * b);
    let e2 = if first.norm_squared() >= second.norm_squared() {
        first
    } else {
        second
    };
    let e2 = e2
        .try_normalize(0.0)
        .unwrap_or(if a.abs() >= c.abs() { p } else { q });
    let ratio = -sigma2 / big;
    if ratio < -ROUND_OFF * (1.0 + small.abs() / big.abs()) {
        return None;
    }
    let s = ratio.max(0.0).sqrt();
    if s == 0.0 {
        return Some([Some(e1), None]);
    }
    // big (e1 . l)^2 + sigma2 (e2 . l)^2 = 0  <=>  e1 . l = +- s (e2 . l).
    Some([Some(e1 - e2 * s), Some(e1 + e2 * s)])
}

/// Unit eigenvector of a symmetric 3 x 3 matrix for an eigenvalue: the largest cross product
/// of two rows of `m - value I`.
fn eigenvector(m: &Matrix3<f64>, value: f64) -> Option<Vector3<f64>> {
    let shifted = m - Matrix3::identity() * value;
    let rows = [
        shifted.row(0).transpose(),
        shifted.row(1).transpose(),
        shifted.row(2).transpose(),
    ];
    let candidates = [
        rows[0].cross(&rows[1]),
        rows[0].cross(&rows[2]),
        rows[1].cross(&rows[2]),
    ];
    let best = candidates
        .iter()
        .max_by(|a, b| a.norm_squared().total_cmp(&b.norm_squared()))?;
    let norm = best.norm();
    (norm > 0.0).then(|| best / norm)
}

/// Two unit vectors completing `n` (any length) to an orthogonal frame.
fn orthonormal_complement(n: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let helper = if n.x.abs() <= n.y.abs() && n.x.abs() <= n.z.abs() {
        Vector3::x()
    } else if n.y.abs() <= n.z.abs() {
        Vector3::y()
    } else {
        Vector3::z()
    };
    let p = n.cross(&helper).normalize();
    let q = n.cross(&p).normalize();
    (p, q)
}

/// Nonzero solutions `(alpha, beta)` of `a alpha^2 + 2 b alpha beta + c beta^2 = 0`, up to
/// scale, without division.
fn homogeneous_quadratic_roots(a: f64, b: f64, c: f64) -> [Option<(f64, f64)>; 2] {
    let scale = a.abs().max(b.abs()).max(c.abs());
    if scale == 0.0 {
        return [None, None];
    }
    let (a, b, c) = (a / scale, b / scale, c / scale);
    let mut disc = b * b - a * c;
    if disc < 0.0 {
        if disc < -ROUND_OFF {
            return [None, None];
        }
        disc = 0.0;
    }
    let root = disc.sqrt();
    // q = -(b + sign(b) sqrt(disc)); roots alpha/beta = q/a and c/q.
    let q = -(b + if b >= 0.0 { root } else { -root });
    let first = (q, a);
    let second = (c, q);
    let valid = |r: (f64, f64)| (r.0 != 0.0 || r.1 != 0.0).then_some(r);
    if root == 0.0 {
        // Double root: report it once.
        return [valid(first).or_else(|| valid(second)), None];
    }
    [valid(first), valid(second)]
}

/// Real roots of the monic cubic `x^3 + a x^2 + b x + c`, each polished by Newton steps.
fn cubic_roots(a: f64, b: f64, c: f64) -> [Option<f64>; 3] {
    let shift = a / 3.0;
    let p = b - a * shift;
    let q = 2.0 * shift * shift * shift - b * shift + c;
    let half_q = 0.5 * q;
    let third_p = p / 3.0;
    let disc = half_q * half_q + third_p * third_p * third_p;
    let mut roots = [None; 3];
    if disc > 0.0 || third_p >= 0.0 {
        // One real root, by Cardano in its cancellation-free form.
        let w = -half_q - half_q.signum() * disc.max(0.0).sqrt();
        let u = w.cbrt();
        let t = if u == 0.0 { 0.0 } else { u - third_p / u };
        roots[0] = Some(t - shift);
    } else {
        // Three real roots, by the trigonometric method.
        let r = (-third_p).sqrt();
        let cos_arg = (-half_q / (r * r * r)).clamp(-1.0, 1.0);
        let phi = cos_arg.acos() / 3.0;
        for (k, root) in roots.iter_mut().enumerate() {
            let angle = phi - 2.0 * core::f64::consts::PI * k as f64 / 3.0;
            *root = Some(2.0 * r * angle.cos() - shift);
        }
    }
    for root in roots.iter_mut().flatten() {
        for _ in 0..2 {
            let value = ((*root + a) * *root + b) * *root + c;
            let slope = (3.0 * *root + 2.0 * a) * *root + b;
            if slope != 0.0 {
                let next = *root - value / slope;
                if next.is_finite() {
                    *root = next;
                }
            }
        }
    }
    roots
}

/// Adjugate of a 3 x 3 matrix (transposed cofactors).
fn adjugate(m: &Matrix3<f64>) -> Matrix3<f64> {
    let c0 = m.column(0);
    let c1 = m.column(1);
    let c2 = m.column(2);
    // Rows of the adjugate are cross products of the columns.
    let r0 = c1.cross(&c2);
    let r1 = c2.cross(&c0);
    let r2 = c0.cross(&c1);
    Matrix3::from_rows(&[r0.transpose(), r1.transpose(), r2.transpose()])
}

/// Verified Gauss-Newton steps on `lambda_i^2 + lambda_j^2 - 2 b_ij lambda_i lambda_j = a_ij`
/// (paper section 3.8): a step is kept only if it lowers the residual.
fn refine_depths(lambda: &mut Vector3<f64>, y: &[Vector3<f64>; 3], a: [f64; 3], b: [f64; 3]) {
    // The residuals as differences of camera-frame points: no cancellation in
    // lambda_i^2 + lambda_j^2 - 2 b_ij lambda_i lambda_j for nearly parallel rays.
    let residual = |l: &Vector3<f64>| {
        let p = [y[0] * l[0], y[1] * l[1], y[2] * l[2]];
        Vector3::new(
            (p[0] - p[1]).norm_squared() - a[0],
            (p[0] - p[2]).norm_squared() - a[1],
            (p[1] - p[2]).norm_squared() - a[2],
        )
    };
    let mut r = residual(lambda);
    let mut cost = r.norm_squared();
    for _ in 0..REFINE_ITERATIONS {
        if cost == 0.0 {
            break;
        }
        let l = *lambda;
        let jacobian = Matrix3::new(
            2.0 * (l[0] - b[0] * l[1]),
            2.0 * (l[1] - b[0] * l[0]),
            0.0,
            2.0 * (l[0] - b[1] * l[2]),
            0.0,
            2.0 * (l[2] - b[1] * l[0]),
            0.0,
            2.0 * (l[1] - b[2] * l[2]),
            2.0 * (l[2] - b[2] * l[1]),
        );
        let Some(inverse) = jacobian.try_inverse() else {
            break;
        };
        let trial = l - inverse * r;
        let trial_r = residual(&trial);
        let trial_cost = trial_r.norm_squared();
        if trial_cost.is_nan() || trial_cost >= cost {
            break;
        }
        *lambda = trial;
        r = trial_r;
        cost = trial_cost;
    }
}

/// The pose mapping the world triangle onto the camera-frame points `lambda_i y_i`, from the
/// orthonormal frames of the two triangles.
fn pose_from_depths(
    y: &[Vector3<f64>; 3],
    x: &[Point3<f64>; 3],
    lambda: &Vector3<f64>,
) -> Option<(Matrix3<f64>, Vector3<f64>)> {
    let c = [y[0] * lambda[0], y[1] * lambda[1], y[2] * lambda[2]];
    let frame = |p0: &Vector3<f64>, p1: &Vector3<f64>, p2: &Vector3<f64>| {
        let e1 = (p1 - p0).try_normalize(0.0)?;
        let e3 = (p1 - p0).cross(&(p2 - p0)).try_normalize(0.0)?;
        let e2 = e3.cross(&e1);
        Some(Matrix3::from_columns(&[e1, e2, e3]))
    };
    // Start the frames at the vertex opposite the shortest edge, so the first axis runs along
    // a long edge and the normal comes from the two longer edges.
    let gaps = [
        (x[1] - x[2]).norm_squared(),
        (x[0] - x[2]).norm_squared(),
        (x[0] - x[1]).norm_squared(),
    ];
    let o = (0..3)
        .min_by(|&i, &j| gaps[i].total_cmp(&gaps[j]))
        .unwrap_or(0);
    let (i, j) = ((o + 1) % 3, (o + 2) % 3);
    let camera = frame(&c[o], &c[i], &c[j])?;
    let world = frame(&x[o].coords, &x[i].coords, &x[j].coords)?;
    let rotation = camera * world.transpose();
    let centroid_c = (c[0] + c[1] + c[2]) / 3.0;
    let centroid_w = (x[0].coords + x[1].coords + x[2].coords) / 3.0;
    let translation = centroid_c - rotation * centroid_w;
    (rotation.iter().all(|v| v.is_finite()) && translation.iter().all(|v| v.is_finite()))
        .then_some((rotation, translation))
}
