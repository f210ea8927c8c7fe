//! The five-point relative pose solver on unit bearings, and the decomposition of an essential
//! matrix with the cheirality decided along the bearings.
//!
//! D. Nister, "An efficient solution to the five-point relative pose problem", IEEE TPAMI
//! 26(6), 2004; H. Stewenius, C. Engels and D. Nister, "Recent developments on direct
//! relative orientation", ISPRS J. Photogrammetry and Remote Sensing 60(4), 2006.
//!
//! Convention: `b_from_a` maps a point `X_a` of frame a to `X_b = R X_a + t`, and the
//! essential matrix `E = [t]x R` satisfies `b^T E a = 0` for the bearings `a`, `b` of one
//! point in the two views. The translation is recovered up to scale (unit norm).
//!
//! The solver (Nister, section 3): the five epipolar constraints `kron(b, a)^T vec(E) = 0`
//! leave a four-dimensional null space, `E = x X + y Y + z Z + W`, found here by a Householder
//! QR of the 9 x 5 transposed constraint matrix (orthonormal basis). The determinant
//! `det E = 0` and the nine trace constraints `2 E E^T E - tr(E E^T) E = 0` are ten cubics in
//! `(x, y, z)`; Gauss-Jordan elimination of their 10 x 20 coefficient matrix (monomials in
//! Nister's order) gives three polynomials `[x y 1] B(z)` linear in `x`, `y`, whose
//! determinant is the tenth-degree polynomial in `z`. Its real roots are isolated by a Sturm
//! sequence and bisection and polished by Newton's method (safeguarded by the bracket), in
//! `[-1, 1]` for the polynomial and for its reversal (the reciprocals of the larger roots), so
//! the chain stays well scaled whatever the roots' magnitude; `x`, `y` follow from the null
//! vector of `B(z)`. Every real root gives one essential matrix, so up to ten are returned.
//! [`five_point`] then polishes each solution whose constraints are not met to round-off by
//! Gauss-Newton on the ten cubics in the homogeneous coordinates `(x, y, z, w)` (clustered
//! roots lose digits in the elimination), and drops a solution still off by more than 1e-9.
//!
//! The decomposition of `E` (normalized to `|E|_F^2 = 2`) uses the closed form
//! `R = cof(E) -+ [t]x E` with `t` the left null vector of `E` (B. K. P. Horn, "Recovering
//! baseline and orientation from essential matrix", J. Optical Society of America, 1990):
//! `cof([t]x R) = t t^T R` and `[t]x [t]x = t t^T - I` for a unit `t`. Of the four candidates
//! `(R, +-t)`, the one that puts the points in front of both cameras is chosen by the
//! depths `lambda_a`, `lambda_b` along the bearings of `lambda_b b = lambda_a R a + t` (least
//! squares), both positive: never by `z > 0`, so rays beyond 90 degrees work.

// `!(x > y)` is written on purpose where a NaN must fail the test; index loops mirror
// the formulas.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

use nalgebra::{Isometry3, Matrix3, Vector3};

use crate::geometry::{isometry_from, rotation_from_correlation};
use crate::relative_pose_error::{RelativePoseError, RelativeResult, check_bearing_pairs};

/// The most essential matrices a five-point problem has.
pub const FIVE_POINT_MAX_SOLUTIONS: usize = 10;

/// All real solutions of a five-point problem, at most [`FIVE_POINT_MAX_SOLUTIONS`], without
/// allocation. Each is an essential matrix `E` with `b^T E a = 0`, normalized to
/// `|E|_F = sqrt(2)` (singular values 1, 1, 0), of unknown sign.
#[derive(Debug, Clone, Copy)]
pub struct EssentialSolutions {
    matrices: [Matrix3<f64>; FIVE_POINT_MAX_SOLUTIONS],
    len: usize,
}

impl EssentialSolutions {
    fn new() -> Self {
        Self {
            matrices: [Matrix3::zeros(); FIVE_POINT_MAX_SOLUTIONS],
            len: 0,
        }
    }

    fn push(&mut self, e: Matrix3<f64>) {
        if self.len < FIVE_POINT_MAX_SOLUTIONS {
            self.matrices[self.len] = e;
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

    /// The essential matrices.
    pub fn as_slice(&self) -> &[Matrix3<f64>] {
        &self.matrices[..self.len]
    }

    /// Iterates over the essential matrices.
    pub fn iter(&self) -> core::slice::Iter<'_, Matrix3<f64>> {
        self.as_slice().iter()
    }
}

impl<'a> IntoIterator for &'a EssentialSolutions {
    type Item = &'a Matrix3<f64>;
    type IntoIter = core::slice::Iter<'a, Matrix3<f64>>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

/// Every real essential matrix `E` with `bearings_b[i]^T E bearings_a[i] = 0` for the five
/// correspondences (Nister's five-point solver, see the module docs). Bearings may point
/// anywhere, also beyond 90 degrees from the optical axis. The poses follow with
/// [`pose_from_essential`].
///
/// # Errors
/// [`RelativePoseError::NonFiniteBearing`] and [`RelativePoseError::NonUnitBearing`] for
/// unusable bearings, [`RelativePoseError::Degenerate`] if the constraints do not reduce to
/// finitely many solutions (for instance a pure rotation, or repeated correspondences).
pub fn five_point(
    bearings_a: &[Vector3<f64>; 5],
    bearings_b: &[Vector3<f64>; 5],
) -> RelativeResult<EssentialSolutions> {
    check_bearing_pairs("five-point", 5, bearings_a, bearings_b)?;
    let all = solve(bearings_a, bearings_b, true).ok_or(RelativePoseError::Degenerate(
        "the five epipolar constraints do not reduce to finitely many essential matrices",
    ))?;
    // A root the elimination left inaccurate (a near-double root the polish could not
    // separate) or spurious is dropped rather than returned as an essential matrix.
    let mut out = EssentialSolutions::new();
    for e in &all {
        if constraint_residual(e, bearings_a, bearings_b) <= SOLUTION_TOLERANCE {
            out.push(*e);
        }
    }
    Ok(out)
}

/// Largest residual of the constraints a returned solution (normalized to `|E|_F = sqrt(2)`)
/// may leave: the five epipolar constraints `b^T E a`, `det E` and the entries of
/// `2 E E^T E - tr(E E^T) E`.
const SOLUTION_TOLERANCE: f64 = 1e-9;

/// The largest residual of the constraints of [`SOLUTION_TOLERANCE`].
fn constraint_residual(e: &Matrix3<f64>, a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    let epipolar = a
        .iter()
        .zip(b)
        .map(|(a, b)| b.dot(&(e * a)).abs())
        .fold(0.0, f64::max);
    let eet = e * e.transpose();
    let trace = (eet * e * 2.0 - e * eet.trace()).abs().max();
    epipolar.max(e.determinant().abs()).max(trace)
}

/// The essential matrix `[t]x R` of a pose `b_from_a` (not normalized).
pub fn essential_from_pose(b_from_a: &Isometry3<f64>) -> Matrix3<f64> {
    let r = b_from_a.rotation.to_rotation_matrix().into_inner();
    b_from_a.translation.vector.cross_matrix() * r
}

/// The four poses `(R, +-t)` with unit `t` whose essential matrix is `E` up to scale and
/// sign: `E` is first projected on the essential manifold (singular values 1, 1, 0).
///
/// # Errors
/// [`RelativePoseError::Numerical`] if `E` is not finite or has rank below 2.
pub fn decompose_essential(essential: &Matrix3<f64>) -> RelativeResult<[Isometry3<f64>; 4]> {
    if !essential.iter().all(|v| v.is_finite()) {
        return Err(RelativePoseError::Numerical(
            "the essential matrix is not finite",
        ));
    }
    let svd = essential.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(RelativePoseError::Numerical("SVD of the essential matrix"));
    };
    let mut s = svd.singular_values;
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| s[j].total_cmp(&s[i]));
    if !(s[order[1]] > 1e-12 * s[order[0]]) {
        return Err(RelativePoseError::Numerical(
            "the essential matrix has rank below 2",
        ));
    }
    s[order[0]] = 1.0;
    s[order[1]] = 1.0;
    s[order[2]] = 0.0;
    let projected = u * Matrix3::from_diagonal(&s) * v_t;
    let Some((r1, r2, t)) = rotations_and_translation(&projected) else {
        return Err(RelativePoseError::Numerical(
            "the essential matrix has rank below 2",
        ));
    };
    Ok([
        isometry_from(&r1, &t),
        isometry_from(&r1, &-t),
        isometry_from(&r2, &t),
        isometry_from(&r2, &-t),
    ])
}

/// The pose `b_from_a` (unit translation) of the essential matrix `E` that puts the most
/// correspondences in front of both cameras, judged by the depths along the bearings (see the
/// module docs); `E` is first projected on the essential manifold.
///
/// # Errors
/// The input errors of [`five_point`] (with at least one correspondence),
/// [`RelativePoseError::Numerical`] for an `E` that is not finite or of rank below 2, and
/// [`RelativePoseError::TooFewInliers`] if no candidate puts any correspondence in front of
/// both cameras.
pub fn pose_from_essential(
    essential: &Matrix3<f64>,
    bearings_a: &[Vector3<f64>],
    bearings_b: &[Vector3<f64>],
) -> RelativeResult<Isometry3<f64>> {
    check_bearing_pairs("essential decomposition", 1, bearings_a, bearings_b)?;
    let candidates = decompose_essential(essential)?;
    let mut best = (0, candidates[0]);
    for pose in candidates {
        let r = pose.rotation.to_rotation_matrix().into_inner();
        let t = pose.translation.vector;
        let count = bearings_a
            .iter()
            .zip(bearings_b)
            .filter(|(a, b)| {
                let (la, lb) = depths(&r, &t, a, b);
                la > 0.0 && lb > 0.0
            })
            .count();
        if count > best.0 {
            best = (count, pose);
        }
    }
    if best.0 == 0 {
        return Err(RelativePoseError::TooFewInliers {
            found: 0,
            required: 1,
            total: bearings_a.len(),
        });
    }
    Ok(best.1)
}

/// The depths `(lambda_a, lambda_b)` of `lambda_b b = lambda_a R a + t` in the least-squares
/// sense (the midpoint triangulation), each multiplied by `1 - (R a . b)^2 >= 0`, which keeps
/// their signs and avoids a division: both positive means the point is in front of both
/// cameras. Zero for parallel rays.
#[inline]
pub(crate) fn depths(
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
) -> (f64, f64) {
    let u = r * a;
    let c = u.dot(b);
    let ut = u.dot(t);
    let bt = b.dot(t);
    (c * bt - ut, bt - c * ut)
}

/// The two rotations and the unit translation of an essential matrix with singular values
/// close to (s, s, 0): `t` is the left null vector (the largest cross product of two columns),
/// `R = cof(E) -+ [t]x E` after scaling `E` to `|E|_F^2 = 2`, each made exactly orthonormal
/// if round-off left it off. `None` for a rank below 2.
pub(crate) fn rotations_and_translation(
    e: &Matrix3<f64>,
) -> Option<(Matrix3<f64>, Matrix3<f64>, Vector3<f64>)> {
    let norm = e.norm();
    if !(norm > 0.0 && norm.is_finite()) {
        return None;
    }
    let e = e * (core::f64::consts::SQRT_2 / norm);
    let (c0, c1, c2) = (
        e.column(0).into_owned(),
        e.column(1).into_owned(),
        e.column(2).into_owned(),
    );
    let crosses = [c1.cross(&c2), c2.cross(&c0), c0.cross(&c1)];
    let mut t = crosses[0];
    for c in &crosses[1..] {
        if c.norm_squared() > t.norm_squared() {
            t = *c;
        }
    }
    let t_norm = t.norm();
    if !(t_norm > 1e-14) {
        return None;
    }
    let t = t / t_norm;
    let cof = Matrix3::from_columns(&crosses);
    let te = t.cross_matrix() * e;
    let r1 = orthonormal(cof - te)?;
    let r2 = orthonormal(cof + te)?;
    Some((r1, r2, t))
}

/// The matrix itself if it is a rotation to 1e-9, else its closest rotation.
fn orthonormal(r: Matrix3<f64>) -> Option<Matrix3<f64>> {
    let defect = (r.transpose() * r - Matrix3::identity()).norm();
    if defect <= 1e-9 && r.determinant() > 0.0 {
        Some(r)
    } else {
        rotation_from_correlation(&r)
    }
}

// ---------------------------------------------------------------------------------------
// Polynomials in (x, y, z) of degree at most 3, in fixed monomial orders.

/// Exponents `(x, y, z)` of the cubic monomials in Nister's column order: the ten
/// eliminated first, then the ten of the basis `[xz^2, xz, x, yz^2, yz, y, z^3, z^2, z, 1]`.
const CUBIC: [[u8; 3]; 20] = [
    [3, 0, 0],
    [0, 3, 0],
    [2, 1, 0],
    [1, 2, 0],
    [2, 0, 1],
    [2, 0, 0],
    [0, 2, 1],
    [0, 2, 0],
    [1, 1, 1],
    [1, 1, 0],
    [1, 0, 2],
    [1, 0, 1],
    [1, 0, 0],
    [0, 1, 2],
    [0, 1, 1],
    [0, 1, 0],
    [0, 0, 3],
    [0, 0, 2],
    [0, 0, 1],
    [0, 0, 0],
];

/// Exponents of the quadratic monomials `[x^2, y^2, z^2, xy, xz, yz, x, y, z, 1]`.
const QUADRATIC: [[u8; 3]; 10] = [
    [2, 0, 0],
    [0, 2, 0],
    [0, 0, 2],
    [1, 1, 0],
    [1, 0, 1],
    [0, 1, 1],
    [1, 0, 0],
    [0, 1, 0],
    [0, 0, 1],
    [0, 0, 0],
];

/// Exponents of the linear monomials `[x, y, z, 1]`.
const LINEAR: [[u8; 3]; 4] = [[1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 0]];

const fn find<const N: usize>(list: &[[u8; 3]; N], e: [u8; 3]) -> usize {
    let mut i = 0;
    while i < N {
        if list[i][0] == e[0] && list[i][1] == e[1] && list[i][2] == e[2] {
            return i;
        }
        i += 1;
    }
    usize::MAX
}

const fn add(a: [u8; 3], b: [u8; 3]) -> [u8; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `LINEAR[i] * LINEAR[j]` as an index of `QUADRATIC`.
const LIN_LIN: [[usize; 4]; 4] = {
    let mut table = [[0; 4]; 4];
    let mut i = 0;
    while i < 4 {
        let mut j = 0;
        while j < 4 {
            table[i][j] = find(&QUADRATIC, add(LINEAR[i], LINEAR[j]));
            j += 1;
        }
        i += 1;
    }
    table
};

/// `QUADRATIC[i] * LINEAR[j]` as an index of `CUBIC`.
const QUAD_LIN: [[usize; 4]; 10] = {
    let mut table = [[0; 4]; 10];
    let mut i = 0;
    while i < 10 {
        let mut j = 0;
        while j < 4 {
            table[i][j] = find(&CUBIC, add(QUADRATIC[i], LINEAR[j]));
            j += 1;
        }
        i += 1;
    }
    table
};

type Lin = [f64; 4];
type Quad = [f64; 10];
type Cubic = [f64; 20];

#[inline]
fn lin_lin(a: &Lin, b: &Lin) -> Quad {
    let mut out = [0.0; 10];
    for i in 0..4 {
        for j in 0..4 {
            out[LIN_LIN[i][j]] += a[i] * b[j];
        }
    }
    out
}

#[inline]
fn quad_lin(a: &Quad, b: &Lin) -> Cubic {
    let mut out = [0.0; 20];
    for i in 0..10 {
        for j in 0..4 {
            out[QUAD_LIN[i][j]] += a[i] * b[j];
        }
    }
    out
}

// ---------------------------------------------------------------------------------------
// The solver.

/// Every real essential matrix of five correspondences (unchecked bearings); `None` when the
/// elimination meets a singular system (a degenerate configuration).
/// With `polish`, each solution is refined by Gauss-Newton on the ten cubic constraints in
/// the homogeneous null-space coordinates (the elimination and the resultant lose digits when
/// roots cluster; two steps restore them), as [`five_point`] does; RANSAC hypotheses skip it.
pub(crate) fn solve(
    a: &[Vector3<f64>],
    b: &[Vector3<f64>],
    polish: bool,
) -> Option<EssentialSolutions> {
    let basis = null_space(a, b)?;
    // E_ij = x X_ij + y Y_ij + z Z_ij + W_ij as linear polynomials, row-major index 3 i + j.
    let e: [[Lin; 3]; 3] = core::array::from_fn(|i| {
        core::array::from_fn(|j| core::array::from_fn(|k| basis[k][3 * i + j]))
    });
    let mut m = [[0.0; 20]; 10];
    // The determinant.
    let minor = |r0: usize, r1: usize, c0: usize, c1: usize| -> Quad {
        let p = lin_lin(&e[r0][c0], &e[r1][c1]);
        let q = lin_lin(&e[r0][c1], &e[r1][c0]);
        core::array::from_fn(|k| p[k] - q[k])
    };
    let d0 = quad_lin(&minor(1, 2, 1, 2), &e[0][0]);
    let d1 = quad_lin(&minor(1, 2, 0, 2), &e[0][1]);
    let d2 = quad_lin(&minor(1, 2, 0, 1), &e[0][2]);
    for k in 0..20 {
        m[0][k] = d0[k] - d1[k] + d2[k];
    }
    // E E^T and its trace.
    let mut eet = [[[0.0; 10]; 3]; 3];
    for i in 0..3 {
        for j in i..3 {
            let mut s = [0.0; 10];
            for k in 0..3 {
                let p = lin_lin(&e[i][k], &e[j][k]);
                for (s, p) in s.iter_mut().zip(p) {
                    *s += p;
                }
            }
            eet[i][j] = s;
            eet[j][i] = s;
        }
    }
    let trace: Quad = core::array::from_fn(|k| eet[0][0][k] + eet[1][1][k] + eet[2][2][k]);
    // 2 E E^T E - tr(E E^T) E.
    for i in 0..3 {
        for j in 0..3 {
            let row = &mut m[1 + 3 * i + j];
            for k in 0..3 {
                let p = quad_lin(&eet[i][k], &e[k][j]);
                for (r, p) in row.iter_mut().zip(p) {
                    *r += 2.0 * p;
                }
            }
            let p = quad_lin(&trace, &e[i][j]);
            for (r, p) in row.iter_mut().zip(p) {
                *r -= p;
            }
        }
    }
    let original = m;
    let reduced = gauss_jordan(&mut m)?;
    let polys = resultant_rows(&reduced);
    let det = determinant_polynomial(&polys);
    let mut out = EssentialSolutions::new();
    let mut roots = [0.0; 10];
    let count = real_roots(&det, &mut roots);
    for &z in &roots[..count] {
        let rows: [Vector3<f64>; 3] = core::array::from_fn(|r| {
            Vector3::new(
                horner(&polys[r][0], z),
                horner(&polys[r][1], z),
                horner(&polys[r][2], z),
            )
        });
        let crosses = [
            rows[0].cross(&rows[1]),
            rows[0].cross(&rows[2]),
            rows[1].cross(&rows[2]),
        ];
        let mut v = crosses[0];
        for c in &crosses[1..] {
            if c.norm_squared() > v.norm_squared() {
                v = *c;
            }
        }
        if !(v[2].abs() > 1e-300) {
            continue;
        }
        let mut c = [v[0] / v[2], v[1] / v[2], z, 1.0];
        let combine = |c: &[f64; 4]| {
            let mut essential = Matrix3::zeros();
            for i in 0..3 {
                for j in 0..3 {
                    let k = 3 * i + j;
                    essential[(i, j)] = c[0] * basis[0][k]
                        + c[1] * basis[1][k]
                        + c[2] * basis[2][k]
                        + c[3] * basis[3][k];
                }
            }
            essential
        };
        let mut essential = combine(&c);
        // Polish only the roots that need it: most are accurate to round-off already.
        if polish {
            let norm = essential.norm();
            let scaled = essential * (core::f64::consts::SQRT_2 / norm);
            if !(constraint_residual(&scaled, a, b) <= POLISH_ABOVE) {
                polish_coordinates(&original, &mut c);
                essential = combine(&c);
            }
        }
        let norm = essential.norm();
        if norm.is_finite() && norm > 0.0 {
            out.push(essential * (core::f64::consts::SQRT_2 / norm));
        }
    }
    Some(out)
}

/// Constraint residual (as [`SOLUTION_TOLERANCE`]) above which a root is polished.
const POLISH_ABOVE: f64 = 1e-13;

/// Gauss-Newton steps taken by the polish of [`solve`].
const POLISH_STEPS: usize = 4;

/// The ten constraints `m` (cubic, monomials `CUBIC` homogenized by `w`) and their Jacobian
/// at the homogeneous coordinates `c = (x, y, z, w)`.
fn constraints_at(m: &[[f64; 20]; 10], c: &[f64; 4]) -> ([f64; 10], [[f64; 4]; 10]) {
    let mut powers = [[1.0; 4]; 4];
    for (v, p) in powers.iter_mut().enumerate() {
        p[1] = c[v];
        p[2] = c[v] * c[v];
        p[3] = p[2] * c[v];
    }
    let mut values = [0.0; 20];
    let mut grads = [[0.0; 4]; 20];
    for (k, e) in CUBIC.iter().enumerate() {
        let exps = [
            e[0] as usize,
            e[1] as usize,
            e[2] as usize,
            3 - (e[0] + e[1] + e[2]) as usize,
        ];
        let term = |skip: usize| -> f64 {
            (0..4)
                .filter(|&v| v != skip)
                .map(|v| powers[v][exps[v]])
                .product()
        };
        values[k] = term(4);
        for v in 0..4 {
            if exps[v] > 0 {
                grads[k][v] = exps[v] as f64 * powers[v][exps[v] - 1] * term(v);
            }
        }
    }
    let mut f = [0.0; 10];
    let mut jac = [[0.0; 4]; 10];
    for i in 0..10 {
        for k in 0..20 {
            f[i] += m[i][k] * values[k];
            for v in 0..4 {
                jac[i][v] += m[i][k] * grads[k][v];
            }
        }
    }
    (f, jac)
}

/// Gauss-Newton on the ten constraints over the unit sphere of homogeneous coordinates; a
/// step is kept only if it lowers the residual.
fn polish_coordinates(m: &[[f64; 20]; 10], c: &mut [f64; 4]) {
    let norm = c.iter().map(|v| v * v).sum::<f64>().sqrt();
    if !(norm > 0.0 && norm.is_finite()) {
        return;
    }
    c.iter_mut().for_each(|v| *v /= norm);
    let (mut f, mut jac) = constraints_at(m, c);
    let mut cost: f64 = f.iter().map(|v| v * v).sum();
    for _ in 0..POLISH_STEPS {
        // Normal equations with the gauge term c c^T (the constraints are homogeneous, so
        // the radial direction is free).
        let mut a = [[0.0; 4]; 4];
        let mut g = [0.0; 4];
        for i in 0..10 {
            for u in 0..4 {
                g[u] -= jac[i][u] * f[i];
                for v in 0..4 {
                    a[u][v] += jac[i][u] * jac[i][v];
                }
            }
        }
        let scale = (0..4).map(|u| a[u][u]).sum::<f64>();
        for u in 0..4 {
            for v in 0..4 {
                a[u][v] += scale * c[u] * c[v];
            }
        }
        let Some(step) = crate::small_linear::solve_linear::<4>(a, g) else {
            return;
        };
        let mut next: [f64; 4] = core::array::from_fn(|u| c[u] + step[u]);
        let n = next.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !(n > 0.0 && n.is_finite()) {
            return;
        }
        next.iter_mut().for_each(|v| *v /= n);
        let (f_next, jac_next) = constraints_at(m, &next);
        let cost_next: f64 = f_next.iter().map(|v| v * v).sum();
        if !(cost_next < cost) {
            return;
        }
        (*c, f, jac, cost) = (next, f_next, jac_next, cost_next);
    }
}

/// An orthonormal basis of the null space of the five rows `kron(b_i, a_i)` (9 entries each).
fn null_space(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> Option<[[f64; 9]; 4]> {
    let rows: [[f64; 9]; 5] =
        core::array::from_fn(|c| core::array::from_fn(|k| b[c][k / 3] * a[c][k % 3]));
    null_space_9::<5, 4>(&rows)
}

/// An orthonormal basis of the null space of `M` rows of 9 entries (`K = 9 - M` vectors),
/// by Householder QR of the 9 x M matrix of the rows as columns: the last `K` columns of its
/// orthogonal factor. `None` for non-finite input or a rank below `M` (a diagonal entry of
/// the triangular factor below 1e-10 of the largest): the null space is then larger.
pub(crate) fn null_space_9<const M: usize, const K: usize>(
    rows: &[[f64; 9]; M],
) -> Option<[[f64; 9]; K]> {
    let mut q = *rows;
    let mut vs = [[0.0; 9]; M];
    let mut betas = [0.0; M];
    let (mut largest, mut smallest) = (0.0f64, f64::INFINITY);
    for k in 0..M {
        let norm2: f64 = q[k][k..].iter().map(|v| v * v).sum();
        let norm = norm2.sqrt();
        if !norm.is_finite() {
            return None;
        }
        largest = largest.max(norm);
        smallest = smallest.min(norm);
        if norm == 0.0 {
            return None;
        }
        let alpha = if q[k][k] > 0.0 { -norm } else { norm };
        let mut v = [0.0; 9];
        v[k..].copy_from_slice(&q[k][k..]);
        v[k] -= alpha;
        let vnorm2: f64 = v[k..].iter().map(|x| x * x).sum();
        if vnorm2 == 0.0 {
            continue;
        }
        let beta = 2.0 / vnorm2;
        for col in q.iter_mut().skip(k + 1) {
            let dot: f64 = (k..9).map(|i| v[i] * col[i]).sum();
            for i in k..9 {
                col[i] -= beta * dot * v[i];
            }
        }
        vs[k] = v;
        betas[k] = beta;
    }
    if !(smallest > 1e-10 * largest) {
        return None;
    }
    let mut basis = [[0.0; 9]; K];
    for (j, out) in basis.iter_mut().enumerate() {
        let mut x = [0.0; 9];
        x[M + j] = 1.0;
        for k in (0..M).rev() {
            let v = &vs[k];
            let dot: f64 = (k..9).map(|i| v[i] * x[i]).sum();
            for i in k..9 {
                x[i] -= betas[k] * dot * v[i];
            }
        }
        *out = x;
    }
    Some(basis)
}

/// Gauss-Jordan elimination with partial pivoting of the first ten columns; returns the
/// ten-by-ten block `B` of `[I | B]`. `None` if a pivot vanishes.
fn gauss_jordan(m: &mut [[f64; 20]; 10]) -> Option<[[f64; 10]; 10]> {
    let scale = m.iter().flatten().fold(0.0f64, |s, v| s.max(v.abs()));
    if !(scale > 0.0 && scale.is_finite()) {
        return None;
    }
    for k in 0..10 {
        let mut pivot = k;
        for i in k + 1..10 {
            if m[i][k].abs() > m[pivot][k].abs() {
                pivot = i;
            }
        }
        if !(m[pivot][k].abs() > 1e-14 * scale) {
            return None;
        }
        m.swap(k, pivot);
        let inv = 1.0 / m[k][k];
        for v in m[k][k..].iter_mut() {
            *v *= inv;
        }
        let row = m[k];
        for (i, r) in m.iter_mut().enumerate() {
            if i == k {
                continue;
            }
            let f = r[k];
            if f != 0.0 {
                for c in k..20 {
                    r[c] -= f * row[c];
                }
            }
        }
    }
    Some(core::array::from_fn(|i| {
        core::array::from_fn(|j| m[i][10 + j])
    }))
}

/// Nister's `<k> = <e> - z <f>`, `<l> = <g> - z <h>`, `<m> = <i> - z <j>` from the rows of
/// `x^2 z`, `x^2`, `y^2 z`, `y^2`, `x y z`, `x y`: each a polynomial `px(z) x + py(z) y +
/// p1(z)` with degrees 3, 3 and 4, coefficients in increasing powers of `z`.
fn resultant_rows(b: &[[f64; 10]; 10]) -> [[[f64; 5]; 3]; 3] {
    let mut out = [[[0.0; 5]; 3]; 3];
    for (r, (upper, lower)) in [(4, 5), (6, 7), (8, 9)].into_iter().enumerate() {
        let (e, f) = (&b[upper], &b[lower]);
        // Basis columns: 0 xz^2, 1 xz, 2 x, 3 yz^2, 4 yz, 5 y, 6 z^3, 7 z^2, 8 z, 9 1.
        out[r][0] = [e[2], e[1] - f[2], e[0] - f[1], -f[0], 0.0];
        out[r][1] = [e[5], e[4] - f[5], e[3] - f[4], -f[3], 0.0];
        out[r][2] = [e[9], e[8] - f[9], e[7] - f[8], e[6] - f[7], -f[6]];
    }
    out
}

fn poly_mul(a: &[f64], b: &[f64], out: &mut [f64; 11]) {
    *out = [0.0; 11];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            if i + j < 11 {
                out[i + j] += x * y;
            }
        }
    }
}

/// `det B(z)`, degree 10, coefficients in increasing powers.
fn determinant_polynomial(p: &[[[f64; 5]; 3]; 3]) -> [f64; 11] {
    let mut t1 = [0.0; 11];
    let mut t2 = [0.0; 11];
    let mut det = [0.0; 11];
    // Cofactors of the first row.
    let cof = |r0: usize, c0: usize, c1: usize, t1: &mut [f64; 11], t2: &mut [f64; 11]| {
        poly_mul(&p[r0][c0], &p[r0 + 1][c1], t1);
        poly_mul(&p[r0][c1], &p[r0 + 1][c0], t2);
        let mut out = [0.0; 11];
        for k in 0..11 {
            out[k] = t1[k] - t2[k];
        }
        out
    };
    let m0 = cof(1, 1, 2, &mut t1, &mut t2);
    let m1 = cof(1, 0, 2, &mut t1, &mut t2);
    let m2 = cof(1, 0, 1, &mut t1, &mut t2);
    let mut acc = [0.0; 11];
    for (sign, (c, m)) in [(1.0, (0, m0)), (-1.0, (1, m1)), (1.0, (2, m2))] {
        poly_mul(&p[0][c], &m, &mut acc);
        for k in 0..11 {
            det[k] += sign * acc[k];
        }
    }
    det
}

#[inline]
fn horner(p: &[f64], x: f64) -> f64 {
    p.iter().rev().fold(0.0, |acc, &c| acc * x + c)
}

/// The real roots of a polynomial of degree at most 10 (increasing powers) into `roots`;
/// returns their count. The roots in `[-1, 1]` are those of `p`, the others the reciprocals
/// of the roots in `(-1, 1)` of the reversed polynomial `z^10 p(1 / z)`: both searches run
/// on a bounded interval where the Sturm chain is well scaled, whatever the magnitude of
/// the roots.
fn real_roots(p: &[f64; 11], roots: &mut [f64; 10]) -> usize {
    let mut found = roots_in_unit_interval(p, roots, 0, false);
    let mut reversed = *p;
    reversed.reverse();
    let mut inverse = [0.0; 10];
    let count = roots_in_unit_interval(&reversed, &mut inverse, 0, true);
    for &w in &inverse[..count] {
        if w != 0.0 && w.abs() < 1.0 && found < roots.len() {
            roots[found] = 1.0 / w;
            found += 1;
        }
    }
    found
}

/// The real roots in `[-1, 1]` of a polynomial of degree at most 10 (increasing powers),
/// written into `roots` from `start`; returns the new count. Sturm sequence, bisection to
/// isolate, safeguarded Newton to polish. With `open`, roots within round-off of the ends
/// are left out (they belong to the other search of [`real_roots`]).
fn roots_in_unit_interval(p: &[f64; 11], roots: &mut [f64; 10], start: usize, open: bool) -> usize {
    let scale = p.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    if !(scale > 0.0 && scale.is_finite()) {
        return start;
    }
    // Drop leading coefficients that are round-off (roots at infinity).
    let mut degree = 10;
    while degree > 0 && p[degree].abs() <= 1e-14 * scale {
        degree -= 1;
    }
    if degree == 0 {
        return start;
    }
    let lead = p[degree];
    let mut monic = [0.0; 11];
    for k in 0..=degree {
        monic[k] = p[k] / lead;
    }
    // Sturm chain.
    let mut chain = [[0.0; 11]; 11];
    let mut degrees = [0usize; 11];
    chain[0][..=degree].copy_from_slice(&monic[..=degree]);
    degrees[0] = degree;
    for k in 1..=degree {
        chain[1][k - 1] = k as f64 * monic[k];
    }
    degrees[1] = degree - 1;
    let mut len = 2;
    while degrees[len - 1] > 0 && len < 11 {
        let (num, den) = (chain[len - 2], chain[len - 1]);
        let (dn, dd) = (degrees[len - 2], degrees[len - 1]);
        let mut rem = num;
        for k in (dd..=dn).rev() {
            let f = rem[k] / den[dd];
            for j in 0..=dd {
                rem[k - dd + j] -= f * den[j];
            }
            rem[k] = 0.0;
        }
        let mut dr = dd - 1;
        let rscale = rem[..dd].iter().fold(0.0f64, |s, v| s.max(v.abs()));
        let nscale = num[..=dn].iter().fold(0.0f64, |s, v| s.max(v.abs()));
        if !(rscale > 1e-15 * nscale) || !rscale.is_finite() {
            // Exact division: a multiple root; the chain ends here.
            break;
        }
        while dr > 0 && rem[dr].abs() <= 1e-15 * rscale {
            dr -= 1;
        }
        for (c, r) in chain[len].iter_mut().zip(rem) {
            *c = -r;
        }
        degrees[len] = dr;
        len += 1;
    }
    let sign_changes = |x: f64| -> usize {
        let mut count = 0;
        let mut last = 0.0f64;
        for (c, &d) in chain[..len].iter().zip(&degrees[..len]) {
            let v = horner(&c[..=d], x);
            if v != 0.0 {
                if last != 0.0 && (v > 0.0) != (last > 0.0) {
                    count += 1;
                }
                last = v;
            }
        }
        count
    };
    let mut found = start;
    // Stack of intervals with their sign-change counts.
    let mut stack = [(0.0, 0.0, 0usize, 0usize, 0u32); 64];
    let mut top = 0;
    let (lo, hi) = if open {
        (-1.0 + 1e-15, 1.0 - 1e-15)
    } else {
        (-1.0, 1.0)
    };
    let (slo, shi) = (sign_changes(lo), sign_changes(hi));
    if slo <= shi {
        return found;
    }
    stack[0] = (lo, hi, slo, shi, 0);
    top += 1;
    while top > 0 {
        top -= 1;
        let (lo, hi, slo, shi, depth) = stack[top];
        let count = slo - shi;
        if count == 0 {
            continue;
        }
        if count == 1 || depth >= 60 {
            if found < roots.len() {
                roots[found] = polish(&monic[..=degree], lo, hi);
                found += 1;
            }
            continue;
        }
        let mid = 0.5 * (lo + hi);
        let smid = sign_changes(mid);
        if top + 2 <= stack.len() {
            stack[top] = (lo, mid, slo, smid, depth + 1);
            stack[top + 1] = (mid, hi, smid, shi, depth + 1);
            top += 2;
        }
    }
    found
}

/// The root of `p` in `[lo, hi]` (one sign change of the Sturm chain there): Newton's method
/// kept inside a shrinking bracket, bisection when it leaves it.
fn polish(p: &[f64], mut lo: f64, mut hi: f64) -> f64 {
    let value = |x: f64| -> (f64, f64) {
        let mut v = 0.0;
        let mut d = 0.0;
        for &c in p.iter().rev() {
            d = d * x + v;
            v = v * x + c;
        }
        (v, d)
    };
    let (flo, _) = value(lo);
    let (fhi, _) = value(hi);
    if flo == 0.0 {
        return lo;
    }
    if fhi == 0.0 {
        return hi;
    }
    if (flo > 0.0) == (fhi > 0.0) {
        // A root of even multiplicity (or round-off): the middle of the bracket.
        return 0.5 * (lo + hi);
    }
    let lo_positive = flo > 0.0;
    let mut x = 0.5 * (lo + hi);
    for _ in 0..100 {
        let (f, d) = value(x);
        if f == 0.0 {
            return x;
        }
        if (f > 0.0) == lo_positive {
            lo = x;
        } else {
            hi = x;
        }
        let newton = x - f / d;
        let next = if newton > lo && newton < hi && d != 0.0 {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if (next - x).abs() <= 1e-15 * x.abs().max(1e-300) || hi - lo <= 1e-15 * x.abs() {
            return next;
        }
        x = next;
    }
    x
}
