//! The homography between two views of a plane (or of any scene under a pure rotation), from
//! unit bearings, and its decomposition into rotation, translation over distance and plane
//! normal.
//!
//! Estimation: the direct linear transformation in the cross-product form `b x (H a) = 0`
//! (R. Hartley and A. Zisserman, "Multiple View Geometry in Computer Vision", 2nd edition,
//! 2003, algorithm 4.2), which holds whatever the signs of the bearings, so rays beyond 90
//! degrees work. Four correspondences give `H` exactly (two independent rows each: the row of
//! the largest coordinate of `b` is dropped, as the three rows satisfy `b^T [b]x = 0`); more
//! are solved in least squares after normalization (Hartley, "In defense of the eight-point
//! algorithm", TPAMI 19(6), 1997): each view's bearings are whitened by the inverse square
//! root of their second-moment matrix, the bearing counterpart of Hartley's isotropic scaling.
//!
//! Convention: for points `X_a` on the plane `n^T X_a = d` (`n` unit, `d > 0`, frame a) and
//! `b_from_a = (R, t)`, `X_b = (R + t n^T / d) X_a`, so `H = R + (t / d) n^T` up to scale,
//! and `lambda_b b = H lambda_a a`. [`homography`] scales `H` so its middle singular value
//! is 1 and signs it so that `b . H a > 0` for most correspondences; then `H = R + (t / d) n^T`
//! exactly.
//!
//! Decomposition: the method of O. Faugeras and F. Lustman, "Motion and structure from motion
//! in a piecewise planar environment", IJPRAI 2(3), 1988, in the form of Y. Ma, S. Soatto,
//! J. Kosecka and S. Sastry, "An Invitation to 3-D Vision", Springer 2004, section 5.3.3: four
//! solutions from the SVD of `H`, of which those putting the points in front of both cameras
//! (`n . a > 0` and positive depths along both bearings) are kept, best first. Two usually
//! remain, an ambiguity only a third view or a prior on the normal resolves. A homography that
//! is a rotation (singular values all 1) is a pure rotation: the translation is zero and the
//! normal undetermined.

// `!(x > y)` is written on purpose where a NaN must fail the test; index loops mirror
// the formulas.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

use nalgebra::{Isometry3, Matrix3, SymmetricEigen, Vector3};

use crate::five_point::{depths, null_space_9};
use crate::geometry::{isometry_from, rotation_from_correlation};
use crate::relative_pose_error::{RelativePoseError, RelativeResult, check_bearing_pairs};
use crate::symmetric_eigen::smallest_eigenpairs;

/// The fewest correspondences [`homography`] takes.
pub const HOMOGRAPHY_MIN_POINTS: usize = 4;

/// Relative spread of the singular values of a normalized homography below which it is a
/// rotation (`(s1^2 - s3^2) / s2^2`): 1e-9, far below the 1e-6 a translation over distance of
/// one part in a million would give.
pub const PURE_ROTATION_TOLERANCE: f64 = 1e-9;

/// One solution of the decomposition of a homography.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct PlanarPose {
    /// `b_from_a` with the translation divided by the plane's distance `d` from centre a
    /// (zero for a pure rotation).
    pub b_from_a: Isometry3<f64>,
    /// The plane's unit normal in frame a (`n^T X_a = d > 0`), pointing away from centre a;
    /// zero for a pure rotation.
    pub normal: Vector3<f64>,
    /// How many correspondences this solution puts in front of both cameras.
    pub in_front: usize,
}

/// The homography `H` with `b ~ H a` (see the module docs for the scale and sign) of four or
/// more correspondences: exact for four, normalized least squares for more.
///
/// # Errors
/// The input errors of [`crate::five_point`] (with at least [`HOMOGRAPHY_MIN_POINTS`]), and
/// [`RelativePoseError::Degenerate`] if the bearings do not determine a homography (three
/// of four on one great circle, all bearings of a view parallel).
pub fn homography(
    bearings_a: &[Vector3<f64>],
    bearings_b: &[Vector3<f64>],
) -> RelativeResult<Matrix3<f64>> {
    check_bearing_pairs("homography", HOMOGRAPHY_MIN_POINTS, bearings_a, bearings_b)?;
    let degenerate = RelativePoseError::Degenerate("the bearings do not determine a homography");
    let h = if bearings_a.len() == HOMOGRAPHY_MIN_POINTS {
        solve_minimal(bearings_a, bearings_b)
    } else {
        let all: Vec<usize> = (0..bearings_a.len()).collect();
        solve_least_squares(bearings_a, bearings_b, &all)
    }
    .ok_or(degenerate.clone())?;
    normalize(&h, bearings_a, bearings_b, None).ok_or(degenerate)
}

/// The solutions of `H = R + (t / d) n^T` (see the module docs) that put correspondences in
/// front of both cameras, most first; one with zero translation and normal if `H` is a
/// rotation. `H` is first normalized as [`homography`] returns it.
///
/// # Errors
/// The input errors of [`crate::five_point`] (with at least one correspondence),
/// [`RelativePoseError::Numerical`] for an `H` that is not finite or is singular, and
/// [`RelativePoseError::TooFewInliers`] if no solution puts any correspondence in front of
/// both cameras.
pub fn decompose_homography(
    homography: &Matrix3<f64>,
    bearings_a: &[Vector3<f64>],
    bearings_b: &[Vector3<f64>],
) -> RelativeResult<Vec<PlanarPose>> {
    check_bearing_pairs("homography decomposition", 1, bearings_a, bearings_b)?;
    let all: Vec<usize> = (0..bearings_a.len()).collect();
    let h = normalize(homography, bearings_a, bearings_b, None).ok_or(
        RelativePoseError::Numerical("the homography is not finite or is singular"),
    )?;
    let out = decompose(&h, bearings_a, bearings_b, &all);
    if out.is_empty() {
        return Err(RelativePoseError::TooFewInliers {
            found: 0,
            required: 1,
            total: bearings_a.len(),
        });
    }
    Ok(out)
}

/// The decomposition of a normalized `h`, counting on the correspondences `subset`.
pub(crate) fn decompose(
    h: &Matrix3<f64>,
    a: &[Vector3<f64>],
    b: &[Vector3<f64>],
    subset: &[usize],
) -> Vec<PlanarPose> {
    let Some((u, s, v)) = sorted_svd(h) else {
        return Vec::new();
    };
    let _ = u;
    let (s1, s3) = (s[0] * s[0], s[2] * s[2]);
    if s1 - s3 <= PURE_ROTATION_TOLERANCE {
        let Some(r) = rotation_from_correlation(h) else {
            return Vec::new();
        };
        let in_front = subset
            .iter()
            .filter(|&&i| b[i].dot(&(r * a[i])) > 0.0)
            .count();
        return vec![PlanarPose {
            b_from_a: isometry_from(&r, &Vector3::zeros()),
            normal: Vector3::zeros(),
            in_front,
        }];
    }
    let (v1, v2, v3) = (
        v.column(0).into_owned(),
        v.column(1).into_owned(),
        v.column(2).into_owned(),
    );
    let denominator = (s1 - s3).sqrt();
    let (p, q) = ((1.0 - s3).max(0.0).sqrt(), (s1 - 1.0).max(0.0).sqrt());
    let mut out = Vec::with_capacity(4);
    for sign in [1.0, -1.0] {
        let u1 = (v1 * p + v3 * (sign * q)) / denominator;
        let n = v2.cross(&u1);
        let big_u = Matrix3::from_columns(&[v2, u1, n]);
        let (hv2, hu1) = (h * v2, h * u1);
        let big_w = Matrix3::from_columns(&[hv2, hu1, hv2.cross(&hu1)]);
        let Some(r) = rotation_from_correlation(&(big_w * big_u.transpose())) else {
            continue;
        };
        let t = (h - r) * n;
        for (n, t) in [(n, t), (-n, -t)] {
            let in_front = subset
                .iter()
                .filter(|&&i| {
                    let (la, lb) = depths(&r, &t, &a[i], &b[i]);
                    n.dot(&a[i]) > 0.0 && la > 0.0 && lb > 0.0
                })
                .count();
            if in_front > 0 {
                out.push(PlanarPose {
                    b_from_a: isometry_from(&r, &t),
                    normal: n,
                    in_front,
                });
            }
        }
    }
    out.sort_by_key(|p| core::cmp::Reverse(p.in_front));
    out
}

/// The SVD of `h` with the singular values decreasing: `(U, s, V)`, `h = U diag(s) V^T`.
fn sorted_svd(h: &Matrix3<f64>) -> Option<(Matrix3<f64>, [f64; 3], Matrix3<f64>)> {
    if !h.iter().all(|x| x.is_finite()) {
        return None;
    }
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| svd.singular_values[j].total_cmp(&svd.singular_values[i]));
    let s = order.map(|i| svd.singular_values[i]);
    let u = Matrix3::from_columns(&order.map(|i| u.column(i).into_owned()));
    let v = Matrix3::from_columns(&order.map(|i| v_t.row(i).transpose()));
    Some((u, s, v))
}

/// `h` scaled to a middle singular value of 1 and signed so that `b . h a > 0` for most of
/// the correspondences (`subset`, or all). `None` if `h` is not finite or has rank below 2.
pub(crate) fn normalize(
    h: &Matrix3<f64>,
    a: &[Vector3<f64>],
    b: &[Vector3<f64>],
    subset: Option<&[usize]>,
) -> Option<Matrix3<f64>> {
    let (_, s, _) = sorted_svd(h)?;
    if !(s[1] > 1e-12 * s[0]) {
        return None;
    }
    let mut h = h / s[1];
    let votes: i64 = match subset {
        Some(subset) => subset
            .iter()
            .map(|&i| if b[i].dot(&(h * a[i])) > 0.0 { 1 } else { -1 })
            .sum(),
        None => a
            .iter()
            .zip(b)
            .map(|(a, b)| if b.dot(&(h * a)) > 0.0 { 1 } else { -1 })
            .sum(),
    };
    if votes < 0 {
        h = -h;
    }
    Some(h)
}

/// The homography of four correspondences (the first four), exact, unnormalized and of
/// unknown sign. `None` if they do not determine one.
pub(crate) fn solve_minimal(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> Option<Matrix3<f64>> {
    let mut rows = [[0.0; 9]; 8];
    for p in 0..4 {
        let (fa, fb) = (&a[p], &b[p]);
        let cross = fb.cross_matrix();
        // Drop the row of the largest |b_k|: the other two are independent.
        let drop = (0..3)
            .max_by(|&i, &j| fb[i].abs().total_cmp(&fb[j].abs()))
            .unwrap_or(2);
        for (slot, k) in (0..3).filter(|&k| k != drop).enumerate() {
            for i in 0..3 {
                for j in 0..3 {
                    rows[2 * p + slot][3 * i + j] = cross[(k, i)] * fa[j];
                }
            }
        }
    }
    let [h] = null_space_9::<8, 1>(&rows)?;
    let h = Matrix3::from_row_slice(&h);
    // A rank-deficient system leaves a null vector that is not a homography of the four.
    let worst = (0..4)
        .map(|p| b[p].cross(&(h * a[p])).norm() / (h * a[p]).norm().max(f64::MIN_POSITIVE))
        .fold(0.0, f64::max);
    let (_, s, _) = sorted_svd(&h)?;
    (worst <= 1e-6 && s[2] > 1e-10 * s[0]).then_some(h)
}

/// The inverse square root of the second-moment matrix of the bearings `subset` of `f`, the
/// whitening that normalizes them. `None` if they span less than the three dimensions.
fn whitening(f: &[Vector3<f64>], subset: &[usize]) -> Option<(Matrix3<f64>, Matrix3<f64>)> {
    let mut m = Matrix3::zeros();
    for &i in subset {
        m += f[i] * f[i].transpose();
    }
    m /= subset.len() as f64;
    let eigen = SymmetricEigen::new(m);
    let largest = eigen.eigenvalues.max();
    if !(eigen.eigenvalues.min() > 1e-14 * largest) {
        return None;
    }
    let q = eigen.eigenvectors;
    let inv_sqrt = Matrix3::from_diagonal(&eigen.eigenvalues.map(|l| 1.0 / l.sqrt()));
    let sqrt = Matrix3::from_diagonal(&eigen.eigenvalues.map(f64::sqrt));
    Some((q * inv_sqrt * q.transpose(), q * sqrt * q.transpose()))
}

/// Normalized least-squares homography of the correspondences `subset` (at least four),
/// unnormalized and of unknown sign. `None` if they do not determine one.
pub(crate) fn solve_least_squares(
    a: &[Vector3<f64>],
    b: &[Vector3<f64>],
    subset: &[usize],
) -> Option<Matrix3<f64>> {
    if subset.len() < HOMOGRAPHY_MIN_POINTS {
        return None;
    }
    let (ta, _) = whitening(a, subset)?;
    let (tb, tb_inverse) = whitening(b, subset)?;
    // sum over the correspondences of ([b']x^T [b']x) kron (a' a'^T).
    let mut ata = [[0.0; 9]; 9];
    for &i in subset {
        let (fa, fb) = (ta * a[i], tb * b[i]);
        let p = Matrix3::identity() * fb.norm_squared() - fb * fb.transpose();
        let q = fa * fa.transpose();
        for r in 0..9 {
            for c in r..9 {
                ata[r][c] += p[(r / 3, c / 3)] * q[(r % 3, c % 3)];
            }
        }
    }
    for r in 0..9 {
        for c in 0..r {
            ata[r][c] = ata[c][r];
        }
    }
    let (_, [h]) = smallest_eigenpairs::<9, 1>(ata)?;
    let h = Matrix3::from_row_slice(&h);
    Some(tb_inverse * h * ta)
}
