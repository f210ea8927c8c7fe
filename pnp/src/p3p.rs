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
//! - the line pair is read from `D_0` less its large eigenpair, a rank-one remainder whose
//!   largest column is the second eigenvector;
//! - a depth step below 1e-12 of the depths is taken without evaluating the residuals again
//!   and ends the refinement (Gauss-Newton is then at round-off);
//! - the rotation is `C X^-1` of the two triangles' edge matrices, with `X^-1` in closed form
//!   once per call; it is orthonormal to the accuracy of the depths, and the quaternions
//!   [`p3p`] returns are normalized.

use nalgebra::{Isometry3, Matrix3, Point3, UnitQuaternion, Vector3};

use crate::error::{Degeneracy, PnpError, Result};
use crate::geometry::isometry_from;
use crate::validate::{
    COINCIDENT_TOLERANCE, COLLINEAR_TOLERANCE, PARALLEL_TOLERANCE, check_correspondences,
};

/// The most solutions a P3P problem has.
pub const P3P_MAX_SOLUTIONS: usize = 4;

/// Verified Gauss-Newton steps on the depths (the paper uses a few).
const REFINE_ITERATIONS: usize = 5;

/// Times a rejected depth step is halved before the refinement stops.
const REFINE_HALVINGS: usize = 4;

/// Residuals of the depth equations below this fraction of the squared sides are taken as
/// round-off, where a rejected step ends the refinement at once (about 500 ulps).
const HALVING_FLOOR: f64 = 1e-13;

/// Depth residuals below this fraction of the squared sides are round-off: the refinement
/// stops there. Half an ulp: over 4e5 random instances the truth is then found as accurately
/// as by refining until no step helps (the same tail above 1e-12 rad), at a third of the
/// refinement steps.
const CONVERGED: f64 = 0.5 * f64::EPSILON;

/// Depth steps below this fraction of the depths are taken without evaluating the
/// residuals again, and end the refinement.
const UNVERIFIED_STEP: f64 = 1e-12;

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
pub fn p3p(bearings: &[Vector3<f64>; 3], points: &[Point3<f64>; 3]) -> Result<P3pSolutions> {
    check_correspondences("P3P", 3, bearings, points)?;
    // The tolerances compare norms; squared norms against squared bounds decide the same
    // (up to the rounding of the bound) without a square root.
    for (first, second) in [(0, 1), (0, 2), (1, 2)] {
        if bearings[first].cross(&bearings[second]).norm_squared()
            <= PARALLEL_TOLERANCE * PARALLEL_TOLERANCE
        {
            return Err(PnpError::Degenerate(Degeneracy::ParallelPair {
                first,
                second,
            }));
        }
        let gap = (points[first] - points[second]).norm_squared();
        let scale = points[first]
            .coords
            .norm_squared()
            .max(points[second].coords.norm_squared());
        if gap == 0.0 || gap <= COINCIDENT_TOLERANCE * COINCIDENT_TOLERANCE * scale {
            return Err(PnpError::Degenerate(Degeneracy::CoincidentPair {
                first,
                second,
            }));
        }
    }
    let u = points[1] - points[0];
    let v = points[2] - points[0];
    if u.cross(&v).norm_squared()
        <= COLLINEAR_TOLERANCE * COLLINEAR_TOLERANCE * u.norm_squared() * v.norm_squared()
    {
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
        let mut pose = isometry_from(rotation, translation);
        // The rotation matrix is orthonormal to the accuracy of the depths; the quaternion
        // read from it is made unit to round-off.
        pose.rotation = UnitQuaternion::new_normalize(pose.rotation.into_inner());
        out.push(pose);
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

/// A symmetric 3 x 3 matrix by its six distinct entries: the conics of Lambda Twist.
#[derive(Debug, Clone, Copy)]
struct Sym3 {
    xx: f64,
    xy: f64,
    xz: f64,
    yy: f64,
    yz: f64,
    zz: f64,
}

impl Sym3 {
    #[inline]
    fn mul(&self, v: &Vector3<f64>) -> Vector3<f64> {
        Vector3::new(
            self.xx * v.x + self.xy * v.y + self.xz * v.z,
            self.xy * v.x + self.yy * v.y + self.yz * v.z,
            self.xz * v.x + self.yz * v.y + self.zz * v.z,
        )
    }

    /// `self + other * scale`.
    #[inline]
    fn add_scaled(&self, other: &Self, scale: f64) -> Self {
        Self {
            xx: self.xx + other.xx * scale,
            xy: self.xy + other.xy * scale,
            xz: self.xz + other.xz * scale,
            yy: self.yy + other.yy * scale,
            yz: self.yz + other.yz * scale,
            zz: self.zz + other.zz * scale,
        }
    }

    /// `self * scale + other`.
    #[inline]
    fn scale_add(&self, scale: f64, other: &Self) -> Self {
        Self {
            xx: self.xx * scale + other.xx,
            xy: self.xy * scale + other.xy,
            xz: self.xz * scale + other.xz,
            yy: self.yy * scale + other.yy,
            yz: self.yz * scale + other.yz,
            zz: self.zz * scale + other.zz,
        }
    }

    /// The cofactor matrix (the adjugate, as the matrix is symmetric).
    #[inline]
    fn cofactors(&self) -> Self {
        Self {
            xx: self.yy * self.zz - self.yz * self.yz,
            xy: self.xz * self.yz - self.xy * self.zz,
            xz: self.xy * self.yz - self.xz * self.yy,
            yy: self.xx * self.zz - self.xz * self.xz,
            yz: self.xy * self.xz - self.xx * self.yz,
            zz: self.xx * self.yy - self.xy * self.xy,
        }
    }

    /// `sum_ij self_ij other_ij`, which is `trace(self other)` for symmetric matrices.
    #[inline]
    fn contract(&self, other: &Self) -> f64 {
        self.xx * other.xx
            + self.yy * other.yy
            + self.zz * other.zz
            + 2.0 * (self.xy * other.xy + self.xz * other.xz + self.yz * other.yz)
    }

    fn trace(&self) -> f64 {
        self.xx + self.yy + self.zz
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
    // D1 = a23 M12 - a12 M23 and D2 = a23 M13 - a13 M23, with M_ij the quadratic forms of
    // lambda_i^2 + lambda_j^2 - 2 b_ij lambda_i lambda_j.
    let d1 = Sym3 {
        xx: a23,
        xy: -a23 * b12,
        xz: 0.0,
        yy: a23 - a12,
        yz: a12 * b23,
        zz: -a12,
    };
    let d2 = Sym3 {
        xx: a23,
        xy: 0.0,
        xz: -a23 * b13,
        yy: -a13,
        yz: a13 * b23,
        zz: a23 - a13,
    };

    let Some(Member {
        d0,
        big,
        small,
        weights: (w1, w2),
    }) = degenerate_member(&d1, &d2)
    else {
        return out;
    };
    let Some(lines) = line_pair(&d0, big, small) else {
        return out;
    };
    // Intersect each line with the better-conditioned of the two conics. On a line of D0 =
    // w1 D1 + w2 D2 the two restricted forms are proportional, w1 D1 = -w2 D2, so the larger
    // one relative to its conic's (Frobenius) size is known in advance: D1 when
    // |w2| |D2| >= |w1| |D1|. The depths are then scaled to the longest side (the quadratic
    // form `quad` of its pair).
    let conic = if w2 * w2 * d2.contract(&d2) >= w1 * w1 * d1.contract(&d1) {
        d1
    } else {
        d2
    };
    let (scale_a, pair) = if a12 >= a13 && a12 >= a23 {
        (a12, (0, 1, b12))
    } else if a13 >= a23 {
        (a13, (0, 2, b13))
    } else {
        (a23, (1, 2, b23))
    };
    let quad = |l: &Vector3<f64>| {
        let (i, j, b) = pair;
        l[i] * l[i] + l[j] * l[j] - 2.0 * b * l[i] * l[j]
    };
    let world = WorldTriangle::new(x, [a23, a13, a12]);
    let mut depths_found: [Vector3<f64>; P3P_MAX_SOLUTIONS] = [Vector3::zeros(); 4];
    let mut found = 0;
    for normal in lines.iter().flatten() {
        // Any basis of the line will do: the depths are scaled to the measured side below.
        let (p, q) = plane_basis(normal);
        let dp = conic.mul(&p);
        let (a, b, c) = (p.dot(&dp), q.dot(&dp), q.dot(&conic.mul(&q)));
        for (alpha, beta) in homogeneous_quadratic_roots(a, b, c).iter().flatten() {
            let mut lambda = p * *alpha + q * *beta;
            if lambda.x < 0.0 && lambda.y < 0.0 && lambda.z < 0.0 {
                lambda = -lambda;
            }
            if !(lambda.x > 0.0 && lambda.y > 0.0 && lambda.z > 0.0) {
                continue;
            }
            let measured = quad(&lambda);
            if measured.is_nan() || measured <= 0.0 {
                continue;
            }
            let mut lambda = lambda * (scale_a / measured).sqrt();
            refine_depths(&mut lambda, y, [a12, a13, a23], [b12, b13, b23]);
            // Also false for NaN.
            if !(lambda.x > 0.0
                && lambda.y > 0.0
                && lambda.z > 0.0
                && lambda.x < f64::INFINITY
                && lambda.y < f64::INFINITY
                && lambda.z < f64::INFINITY)
            {
                continue;
            }
            let tolerance = 1e-24 * lambda.norm_squared();
            if depths_found[..found]
                .iter()
                .any(|l| (l - lambda).norm_squared() <= tolerance)
            {
                continue;
            }
            if found < P3P_MAX_SOLUTIONS {
                depths_found[found] = lambda;
                found += 1;
            }
            if let Some(pose) = world.pose(y, &lambda) {
                out.push(pose);
            }
        }
    }
    out
}

/// A degenerate member `d0 = w1 D1 + w2 D2` of the pencil of two conics.
struct Member {
    d0: Sym3,
    /// The nonzero eigenvalue of `d0` of larger magnitude, and the other one.
    big: f64,
    small: f64,
    /// `(w1, w2)`.
    weights: (f64, f64),
}

/// A real root of `det(D1 + gamma D2) = 0` giving an indefinite (or rank-one) `D0`, as that
/// member with its two nonzero eigenvalues; `None` if there is none.
fn degenerate_member(d1: &Sym3, d2: &Sym3) -> Option<Member> {
    // det(A + g B) = det A + g tr(adj(A) B) + g^2 tr(adj(B) A) + g^3 det B.
    let c1 = d1.cofactors();
    let c2 = d2.cofactors();
    let det1 = d1.xx * c1.xx + d1.xy * c1.xy + d1.xz * c1.xz;
    let det2 = d2.xx * c2.xx + d2.xy * c2.xy + d2.xz * c2.xz;
    let mixed1 = c1.contract(d2);
    let mixed2 = c2.contract(d1);
    // Solve in gamma (D1 + gamma D2) or in mu = 1/gamma (mu D1 + D2), whichever is monic-safer.
    let (lead, c2, c1, c0, swapped) = if det2.abs() >= det1.abs() {
        (det2, mixed2, mixed1, det1, false)
    } else {
        (det1, mixed1, mixed2, det2, true)
    };
    let member = |root: f64| {
        if swapped {
            (d1.scale_add(root, d2), (root, 1.0))
        } else {
            (d1.add_scaled(d2, root), (1.0, root))
        }
    };
    let ranked = |(d0, weights): (Sym3, (f64, f64))| {
        let (s1, s2) = nonzero_eigenvalues(&d0)?;
        let (big, small) = if s1.abs() >= s2.abs() {
            (s1, s2)
        } else {
            (s2, s1)
        };
        Some(Member {
            d0,
            big,
            small,
            weights,
        })
    };
    if lead == 0.0 {
        // Both D1 and D2 are singular: D1 itself (or D2) is a degenerate member.
        return ranked(if det1 == 0.0 {
            (*d1, (1.0, 0.0))
        } else {
            (*d2, (0.0, 1.0))
        });
    }
    let inverse_lead = 1.0 / lead;
    let roots = cubic_roots(c2 * inverse_lead, c1 * inverse_lead, c0 * inverse_lead);
    let mut best: Option<(f64, Member)> = None;
    for root in roots.iter().flatten() {
        let Some(candidate) = ranked(member(*root)) else {
            continue;
        };
        // Quality: indefinite and balanced; a rank-one member (double line) scores 0.
        if candidate.big == 0.0 {
            continue;
        }
        let ratio = -candidate.small / candidate.big;
        if ratio < -ROUND_OFF {
            continue;
        }
        if best.as_ref().is_none_or(|(r, _)| ratio > *r) {
            best = Some((ratio, candidate));
        }
    }
    best.map(|(_, member)| member)
}

/// The two nonzero eigenvalues of a symmetric 3 x 3 matrix with a zero eigenvalue: roots of
/// `s^2 - trace s + (sum of principal 2 x 2 minors) = 0`.
fn nonzero_eigenvalues(m: &Sym3) -> Option<(f64, f64)> {
    let trace = m.trace();
    let minors = m.xx * m.yy - m.xy * m.xy + m.xx * m.zz - m.xz * m.xz + m.yy * m.zz - m.yz * m.yz;
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
/// (symmetric, rank 2 indefinite, or rank 1) with nonzero eigenvalues `big` and `small`
/// (`|big| >= |small|`). `None` if `d0` is definite on its range.
fn line_pair(d0: &Sym3, big: f64, small: f64) -> Option<[Option<Vector3<f64>>; 2]> {
    if big == 0.0 {
        return None;
    }
    let e1 = eigenvector(d0, big)?;
    // What is left of d0 without its big eigenpair is the rank-one small e2 e2^T (plus the
    // round-off of the zero eigenvalue): e2 is its largest column, normalized.
    let scaled = e1 * big;
    let rest = Sym3 {
        xx: d0.xx - scaled.x * e1.x,
        xy: d0.xy - scaled.x * e1.y,
        xz: d0.xz - scaled.x * e1.z,
        yy: d0.yy - scaled.y * e1.y,
        yz: d0.yz - scaled.y * e1.z,
        zz: d0.zz - scaled.z * e1.z,
    };
    let sigma2 = rest.trace();
    let (x, y, z) = (rest.xx.abs(), rest.yy.abs(), rest.zz.abs());
    let column = if x >= y && x >= z {
        Vector3::new(rest.xx, rest.xy, rest.xz)
    } else if y >= z {
        Vector3::new(rest.xy, rest.yy, rest.yz)
    } else {
        Vector3::new(rest.xz, rest.yz, rest.zz)
    };
    let ratio = -sigma2 / big;
    if ratio < -ROUND_OFF * (1.0 + small.abs() / big.abs()) {
        return None;
    }
    let s = ratio.max(0.0).sqrt();
    // A nonzero trace has a nonzero diagonal entry, so the column is zero only by underflow.
    let Some(e2) = column.try_normalize(0.0).filter(|_| s > 0.0) else {
        return Some([Some(e1), None]);
    };
    // big (e1 . l)^2 + sigma2 (e2 . l)^2 = 0  <=>  e1 . l = +- s (e2 . l).
    Some([Some(e1 - e2 * s), Some(e1 + e2 * s)])
}

/// Unit eigenvector of a symmetric 3 x 3 matrix for an eigenvalue: the largest cross product
/// of two rows of `m - value I`.
fn eigenvector(m: &Sym3, value: f64) -> Option<Vector3<f64>> {
    let rows = [
        Vector3::new(m.xx - value, m.xy, m.xz),
        Vector3::new(m.xy, m.yy - value, m.yz),
        Vector3::new(m.xz, m.yz, m.zz - value),
    ];
    let candidates = [
        rows[0].cross(&rows[1]),
        rows[0].cross(&rows[2]),
        rows[1].cross(&rows[2]),
    ];
    let sizes = candidates.map(|c| c.norm_squared());
    let best = if sizes[0] >= sizes[1] && sizes[0] >= sizes[2] {
        0
    } else if sizes[1] >= sizes[2] {
        1
    } else {
        2
    };
    let norm = sizes[best].sqrt();
    (norm > 0.0).then(|| candidates[best] * (1.0 / norm))
}

/// Two vectors completing `n` (nonzero, any length) to an orthogonal frame, not normalized:
/// `p = n x e_k` with `e_k` the axis of the smallest component of `n`, and `q = n x p`. So
/// `|p|^2 = |n|^2 - n_k^2 >= 2 |n|^2 / 3` and `|q| = |n| |p|`.
#[inline]
fn plane_basis(n: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let (x, y, z) = (n.x.abs(), n.y.abs(), n.z.abs());
    // n x e_x = (0, z, -y), n x e_y = (-z, 0, x), n x e_z = (y, -x, 0).
    let p = if x <= y && x <= z {
        Vector3::new(0.0, n.z, -n.y)
    } else if y <= z {
        Vector3::new(-n.z, 0.0, n.x)
    } else {
        Vector3::new(n.y, -n.x, 0.0)
    };
    (p, n.cross(&p))
}

/// Nonzero solutions `(alpha, beta)` of `a alpha^2 + 2 b alpha beta + c beta^2 = 0`, up to
/// scale, without division.
fn homogeneous_quadratic_roots(a: f64, b: f64, c: f64) -> [Option<(f64, f64)>; 2] {
    let scale = a.abs().max(b.abs()).max(c.abs());
    if scale == 0.0 {
        return [None, None];
    }
    let inverse = 1.0 / scale;
    let (a, b, c) = (a * inverse, b * inverse, c * inverse);
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
    let shift = a * (1.0 / 3.0);
    let p = b - a * shift;
    let q = 2.0 * shift * shift * shift - b * shift + c;
    let half_q = 0.5 * q;
    let third_p = p * (1.0 / 3.0);
    let disc = half_q * half_q + third_p * third_p * third_p;
    let mut roots = [None; 3];
    if disc > 0.0 || third_p >= 0.0 {
        // One real root, by Cardano in its cancellation-free form.
        let w = -half_q - half_q.signum() * disc.max(0.0).sqrt();
        let u = cube_root(w);
        let t = if u == 0.0 { 0.0 } else { u - third_p / u };
        roots[0] = Some(t - shift);
    } else {
        // Three real roots of t^3 + p t + q. The largest, t0 = 2 r cos(phi / 3), by the
        // trigonometric method; the other two from the deflated quadratic
        // t^2 + t0 t - q / t0 (t0 >= r > 0), in its cancellation-free form. The Newton
        // polish below brings all three to round-off.
        let r = (-third_p).sqrt();
        let cos_arg = (-half_q / (r * r * r)).clamp(-1.0, 1.0);
        let t0 = 2.0 * r * (cos_arg.acos() / 3.0).cos();
        let product = -q / t0;
        let root = (t0 * t0 - 4.0 * product).max(0.0).sqrt();
        // Both remaining roots are at most t0; the one of larger magnitude is -(t0 + root) / 2.
        let t1 = -0.5 * (t0 + root);
        let t2 = if t1 == 0.0 { 0.0 } else { product / t1 };
        roots = [Some(t0 - shift), Some(t1 - shift), Some(t2 - shift)];
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

/// The real cube root, by Halley's iteration `u <- u (u^3 + 2w) / (2u^3 + w)` (cubic
/// convergence) from a guess that divides the bit pattern by three: relative errors 3.2e-2,
/// 2.1e-5 and at most 6.5e-15 after the guess and each step (the last figure is the worst over
/// 2e7 samples from 1e-300 to 1e300 and a sweep of `[1, 8)` in steps of 1e-6; tested below
/// 8e-15). Several times
/// cheaper than the library's `cbrt`, whose last-bit accuracy the Newton polish of the
/// cubic's roots makes moot. Zero, subnormal and non-finite input go to `f64::cbrt`.
#[inline]
fn cube_root(w: f64) -> f64 {
    let magnitude = w.abs();
    if !magnitude.is_normal() {
        return w.cbrt();
    }
    // The exponent bits over three, and the mantissa bits with them: a piecewise-linear
    // approximation of cbrt in the bit pattern (the classic `bits / 3 + bias` guess).
    let bits = magnitude.to_bits() / 3 + CBRT_BIAS;
    let mut u = f64::from_bits(bits);
    for _ in 0..CBRT_STEPS {
        let cube = u * u * u;
        u *= (cube + 2.0 * magnitude) / (2.0 * cube + magnitude);
    }
    u.copysign(w)
}

/// Halley steps of [`cube_root`]: two reach 6.5e-15 relative; the Newton polish of the cubic's
/// roots in [`cubic_roots`] takes that to round-off.
const CBRT_STEPS: usize = 2;

/// `2/3` of the bit pattern of `1.0`, less the offset that centres the relative error of the
/// guess in [`cube_root`]: `bits(x) / 3 + CBRT_BIAS` is about `bits(cbrt(x))`.
const CBRT_BIAS: u64 = 0x2A9F_7893_782D_A1CE;

/// Verified Gauss-Newton steps on `lambda_i^2 + lambda_j^2 - 2 b_ij lambda_i lambda_j = a_ij`
/// (paper section 3.8): a step is kept only if it lowers the residual. Away from round-off a
/// rejected step is halved up to [`REFINE_HALVINGS`] times before giving up: near a double
/// solution (two poses about to merge) the full step overshoots, and the halved steps still
/// converge to the nearest solution.
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
    let size = a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
    // Residuals a few hundred ulps of the squared sides are round-off: no halving there.
    let round_off = HALVING_FLOOR * HALVING_FLOOR * size;
    // Residuals within a couple of ulps of the squared sides are as small as they get.
    let converged = CONVERGED * CONVERGED * size;
    let mut r = residual(lambda);
    let mut cost = r.norm_squared();
    for _ in 0..REFINE_ITERATIONS {
        if cost <= converged {
            break;
        }
        let l = *lambda;
        // The Jacobian is 2 [[j00, j01, 0], [j10, 0, j12], [0, j21, j22]]; the step solves it
        // by cofactors (the factor 2 folded into the scale).
        let (j00, j01) = (l[0] - b[0] * l[1], l[1] - b[0] * l[0]);
        let (j10, j12) = (l[0] - b[1] * l[2], l[2] - b[1] * l[0]);
        let (j21, j22) = (l[1] - b[2] * l[2], l[2] - b[2] * l[1]);
        let det = -(j00 * j12 * j21 + j01 * j10 * j22);
        if det == 0.0 || !det.is_finite() {
            break;
        }
        let mut step = Vector3::new(
            -j12 * j21 * r[0] - j01 * j22 * r[1] + j01 * j12 * r[2],
            -j10 * j22 * r[0] + j00 * j22 * r[1] - j00 * j12 * r[2],
            j10 * j21 * r[0] - j00 * j21 * r[1] - j01 * j10 * r[2],
        ) * (0.5 / det);
        // A step this small is taken unverified and ends the refinement: at a simple solution
        // Gauss-Newton converges quadratically, leaving an error of the order of the step
        // squared, and at worst (a double solution, linear convergence) the step bounds it.
        if step.norm_squared() <= UNVERIFIED_STEP * UNVERIFIED_STEP * l.norm_squared() {
            *lambda = l - step;
            break;
        }
        let halvings = if cost > round_off { REFINE_HALVINGS } else { 0 };
        let mut improved = false;
        for _ in 0..=halvings {
            let trial = l - step;
            let trial_r = residual(&trial);
            let trial_cost = trial_r.norm_squared();
            if trial_cost.is_nan() {
                break;
            }
            if trial_cost < cost {
                *lambda = trial;
                r = trial_r;
                cost = trial_cost;
                improved = true;
                break;
            }
            step *= 0.5;
        }
        if !improved {
            break;
        }
    }
}

/// The world triangle's edge matrix, inverted once for all solutions.
struct WorldTriangle {
    /// Vertex the edges start at (opposite the shortest edge) and the other two, in order.
    order: [usize; 3],
    /// Inverse of the edge matrix `[u, v, u x v]` (`u`, `v` the two edges from the first
    /// vertex of `order`); `None` for a degenerate triangle.
    edges_inverse: Option<Matrix3<f64>>,
    /// The first vertex of `order`.
    origin: Vector3<f64>,
}

impl WorldTriangle {
    /// `gaps`: the squared sides opposite each vertex, `|x1 - x2|^2, |x0 - x2|^2, |x0 - x1|^2`.
    fn new(x: &[Point3<f64>; 3], gaps: [f64; 3]) -> Self {
        // Start the edges at the vertex opposite the shortest edge: the two longer edges
        // span the plane and give the normal.
        let order = if gaps[0] <= gaps[1] && gaps[0] <= gaps[2] {
            [0, 1, 2]
        } else if gaps[1] <= gaps[2] {
            [1, 2, 0]
        } else {
            [2, 0, 1]
        };
        let (p0, p1, p2) = (
            &x[order[0]].coords,
            &x[order[1]].coords,
            &x[order[2]].coords,
        );
        let u = p1 - p0;
        let v = p2 - p0;
        let n = u.cross(&v);
        // [u, v, n]^-1 has the rows v x n, n x u and n, over det = n . (u x v) = |n|^2.
        let det = n.norm_squared();
        let edges_inverse = (det > 0.0 && det < f64::INFINITY).then(|| {
            let inverse = 1.0 / det;
            Matrix3::from_rows(&[
                (v.cross(&n) * inverse).transpose(),
                (n.cross(&u) * inverse).transpose(),
                (n * inverse).transpose(),
            ])
        });
        Self {
            order,
            edges_inverse,
            origin: *p0,
        }
    }

    /// The pose mapping the world triangle onto the camera-frame points `lambda_i y_i`:
    /// `R = C X^-1` with `C` and `X` the edge matrices `[u, v, u x v]` of the camera-frame and
    /// world triangles. For depths that satisfy the three distance equations the two
    /// triangles are congruent and `R` is the rotation; the depths are refined to round-off,
    /// so `R` is orthonormal to the accuracy of the depths.
    fn pose(
        &self,
        y: &[Vector3<f64>; 3],
        lambda: &Vector3<f64>,
    ) -> Option<(Matrix3<f64>, Vector3<f64>)> {
        let c = [y[0] * lambda[0], y[1] * lambda[1], y[2] * lambda[2]];
        let [o, i, j] = self.order;
        let u = c[i] - c[o];
        let v = c[j] - c[o];
        let camera = Matrix3::from_columns(&[u, v, u.cross(&v)]);
        let rotation = camera * self.edges_inverse?;
        let translation = c[o] - rotation * self.origin;
        // Every entry of the rotation enters the translation times a coordinate of the origin
        // (`inf * 0` is NaN), so `sum * 0` is zero exactly when the whole pose is finite.
        let sum = translation.x + translation.y + translation.z;
        (sum * 0.0 == 0.0).then_some((rotation, translation))
    }
}

#[cfg(test)]
mod tests {
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use nalgebra::{Matrix3, Point3, Rotation3, Vector3};

    use super::{cube_root, cubic_roots, solve_raw};

    /// The rotations are `C X^-1` of the two triangles' edge matrices, orthonormal to the
    /// accuracy of the refined depths: over random triangles seen from random poses (rays up
    /// to 95 degrees off the axis), `R^T R - I` stays below 1e-10 (2.6e-12 seen), and for thin triangles
    /// (a vertex 1e-3 off the opposite side, where the depths themselves are ill-conditioned)
    /// it is of the order of the error of the recovered rotation.
    #[test]
    fn raw_rotations_are_orthonormal_to_the_accuracy_of_the_pose() {
        let mut rng = ChaCha8Rng::seed_from_u64(14);
        let mut worst_regular = 0.0f64;
        for trial in 0..8_000 {
            let axis = Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0));
            let rotation = Rotation3::new(axis * 3.0).into_inner();
            let translation = Vector3::from_fn(|_, _| rng.random_range(-5.0..5.0));
            let mut camera = [Vector3::zeros(); 3];
            for point in &mut camera {
                let theta: f64 = rng.random_range(0.0..95f64.to_radians());
                let phi: f64 = rng.random_range(0.0..std::f64::consts::TAU);
                let depth: f64 = rng.random_range(1.0..10.0);
                *point = Vector3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                ) * depth;
            }
            let thin = trial % 4 == 0;
            if thin {
                let t: f64 = rng.random_range(0.2..0.8);
                camera[2] = camera[0] * t + camera[1] * (1.0 - t) + axis * 1e-3;
            }
            let y = camera.map(|c| c.normalize());
            let x: [Point3<f64>; 3] =
                camera.map(|c| Point3::from(rotation.transpose() * (c - translation)));
            let gap = |r: &Matrix3<f64>| (r.transpose() * r - Matrix3::identity()).abs().max();
            let solutions = solve_raw(&y, &x);
            for (r, t) in solutions.iter() {
                assert!(r.determinant() > 0.0, "{trial}");
                for (f, p) in y.iter().zip(&x) {
                    let q = r * p.coords + t;
                    assert!(f.cross(&q).norm() <= 1e-8 * q.norm(), "{trial}");
                }
                if !thin {
                    worst_regular = worst_regular.max(gap(r));
                }
            }
            // The solution nearest the truth: its departure from orthonormality is of the
            // order of its error (up to three times the largest entry of R - R_true here).
            if let Some(best) = solutions.iter().map(|(r, _)| r).min_by(|a, b| {
                (*a - rotation)
                    .abs()
                    .max()
                    .total_cmp(&(*b - rotation).abs().max())
            }) {
                let error = (best - rotation).abs().max();
                assert!(
                    gap(best) <= 1e-12 + 10.0 * error,
                    "{trial}: {:e} vs {error:e}",
                    gap(best)
                );
            }
        }
        assert!(worst_regular <= 1e-10, "R^T R - I up to {worst_regular:e}");
    }

    /// The bit-trick Halley cube root (the speed path of Cardano's formula) against the
    /// library's `cbrt`, over 600 decades and at the special values it hands over.
    #[test]
    fn cube_root_matches_the_library_cbrt() {
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        for _ in 0..20_000 {
            let magnitude = 10f64.powf(rng.random_range(-300.0..300.0));
            let w = if rng.random::<bool>() {
                magnitude
            } else {
                -magnitude
            };
            let want = w.cbrt();
            // The documented worst case is 6.5e-15 relative (about 30 ulps).
            assert!(
                (cube_root(w) - want).abs() <= 8e-15 * want.abs(),
                "{w:e}: {} vs {want}",
                cube_root(w)
            );
        }
        for w in [0.0, -0.0, 5e-324, -1e-310, f64::INFINITY, f64::NEG_INFINITY] {
            assert_eq!(cube_root(w).to_bits(), w.cbrt().to_bits(), "{w:e}");
        }
        assert!(cube_root(f64::NAN).is_nan());
    }

    /// The three-real-root branch (largest root by the trigonometric method, the other two by
    /// deflation) and the one-real-root branch, against cubics built from known roots.
    #[test]
    fn cubic_roots_are_found_to_round_off() {
        let mut rng = ChaCha8Rng::seed_from_u64(13);
        for _ in 0..2_000 {
            let mut r = [0.0f64; 3];
            r[0] = rng.random_range(-10.0..10.0);
            r[1] = r[0] + rng.random_range(0.1..10.0);
            r[2] = r[1] + rng.random_range(0.1..10.0);
            let a = -(r[0] + r[1] + r[2]);
            let b = r[0] * r[1] + r[0] * r[2] + r[1] * r[2];
            let c = -r[0] * r[1] * r[2];
            let mut found: Vec<f64> = cubic_roots(a, b, c).iter().flatten().copied().collect();
            found.sort_by(f64::total_cmp);
            assert_eq!(found.len(), 3, "{r:?}");
            // The limit set by rounding: evaluating the cubic near a root x errs by about
            // eps (|x|^3 + |a| x^2 + |b x| + |c|), which moves the root by that over |p'(x)|.
            let limit = |x: f64, a: f64, b: f64, c: f64| {
                let terms = x.abs().powi(3) + a.abs() * x * x + (b * x).abs() + c.abs();
                let slope = (3.0 * x + 2.0 * a) * x + b;
                4.0 * f64::EPSILON * terms / slope.abs()
            };
            for (got, want) in found.iter().zip(&r) {
                assert!(
                    (got - want).abs() <= limit(*want, a, b, c),
                    "{r:?}: {found:?}"
                );
            }
            // (x - r0)(x^2 + s^2): one real root.
            let s = rng.random_range(0.1..10.0);
            let (a, b, c) = (-r[0], s * s, -r[0] * s * s);
            let found: Vec<f64> = cubic_roots(a, b, c).iter().flatten().copied().collect();
            assert_eq!(found.len(), 1);
            assert!(
                (found[0] - r[0]).abs() <= limit(r[0], a, b, c),
                "{r:?} {s}: {found:?}"
            );
        }
    }
}
