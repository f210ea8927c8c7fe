//! Small geometric helpers shared by the solvers: the bearing error measures and the
//! rotation closest to a correlation matrix (Kabsch / Umeyama).
//!
//! W. Kabsch, "A solution for the best rotation to relate two sets of vectors", Acta
//! Crystallographica A32, 1976; S. Umeyama, "Least-squares estimation of transformation
//! parameters between two point patterns", IEEE TPAMI 13(4), 1991.

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// Squared chord between the unit bearing `f` and the direction of the camera-frame point `p`:
/// `|p/|p| - f|^2 = 2 - 2 cos(angle) = 4 sin^2(angle / 2)`. Increases monotonically with the
/// angle over `[0, pi]`, so it ranks models at any incidence; 4 for a point at the centre.
#[inline]
pub(crate) fn chord_squared(f: &Vector3<f64>, p: &Vector3<f64>) -> f64 {
    let norm = p.norm();
    if norm == 0.0 {
        4.0
    } else {
        // NaN for a non-finite point, so a broken pose never scores well. One division, not
        // three: the reciprocal is within an ulp of the quotients.
        (p * (1.0 / norm) - f).norm_squared()
    }
}

/// Angle in radians between the unit bearing `f` and the direction of `p`, accurate at every
/// angle (`atan2(|f x p|, f . p)`); `pi` for a point at the centre.
#[inline]
pub(crate) fn bearing_angle(f: &Vector3<f64>, p: &Vector3<f64>) -> f64 {
    if p.norm_squared() > 0.0 {
        f.cross(p).norm().atan2(f.dot(p))
    } else {
        core::f64::consts::PI
    }
}

/// The rotation `R` maximizing `trace(R^T h)`, i.e. minimizing `sum |a_i - R b_i|^2` for
/// `h = sum a_i b_i^T` (Kabsch). When `det(h) > 0` and `h` is well conditioned this is the
/// orthogonal polar factor of `h`, found by Higham's scaled Newton iteration (N. J. Higham,
/// "Computing the polar decomposition, with applications", SIAM J. Sci. Stat. Comput. 7(4),
/// 1986); otherwise by SVD with the determinant correction, which also handles rank-2 `h`.
/// `None` if `h` has rank below 2 or is not finite.
pub(crate) fn rotation_from_correlation(h: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    if !h.iter().all(|v| v.is_finite()) {
        return None;
    }
    let scale = h.norm();
    if h.determinant() > POLAR_MIN_DETERMINANT * scale * scale * scale
        && let Some(r) = polar_rotation(h)
    {
        return Some(r);
    }
    kabsch_svd(h)
}

/// Below this `det(h) / |h|_F^3` the Newton polar iteration is skipped for the SVD (the
/// matrix is then within a condition number of about 1e2 of singular or reflecting).
const POLAR_MIN_DETERMINANT: f64 = 1e-6;

/// Scaled Newton iteration `X <- (g X + X^-T / g) / 2`, `g = sqrt(|X^-1|_F / |X|_F)`, with
/// the scaling dropped (`g = 1`) once the steps are small (Higham's recommendation: near
/// convergence the optimal scale is 1 to first order, and the unscaled step skips two square
/// roots and a division). `X^-T` is the cofactor matrix over the determinant; the cofactor
/// columns of a 3 x 3 matrix are the cross products of its columns.
fn polar_rotation(h: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let mut x = *h;
    let mut scaled = true;
    for _ in 0..POLAR_MAX_ITERATIONS {
        let (cof, det) = cofactors(&x)?;
        let next = if scaled {
            let x_norm = x.norm_squared().sqrt();
            let inverse_norm = cof.norm_squared().sqrt() / det.abs();
            let gamma = (inverse_norm / x_norm).sqrt();
            x * (0.5 * gamma) + cof * (0.5 / (gamma * det))
        } else {
            x * 0.5 + cof * (0.5 / det)
        };
        let change = (next - x).norm_squared();
        x = next;
        if change <= 1e-28 {
            // Quadratic convergence: one more step reaches round-off.
            let (cof, det) = cofactors(&x)?;
            return Some(x * 0.5 + cof * (0.5 / det));
        }
        scaled &= change > POLAR_UNSCALED;
    }
    None
}

/// Squared Frobenius step below which the polar iteration stops scaling (steps of 1e-2).
const POLAR_UNSCALED: f64 = 1e-4;

/// The cofactor matrix of `x` (so `x^-T = cofactors / det`) and the determinant; `None` for a
/// singular matrix.
#[inline]
fn cofactors(x: &Matrix3<f64>) -> Option<(Matrix3<f64>, f64)> {
    let (c0, c1, c2) = (x.column(0), x.column(1), x.column(2));
    let cofactors = Matrix3::from_columns(&[c1.cross(&c2), c2.cross(&c0), c0.cross(&c1)]);
    let det = c0.dot(&cofactors.column(0));
    (det != 0.0).then_some((cofactors, det))
}

/// Newton polar iterations allowed (quadratic convergence: about six are used).
const POLAR_MAX_ITERATIONS: usize = 30;

fn kabsch_svd(h: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut sorted = [
        svd.singular_values[0],
        svd.singular_values[1],
        svd.singular_values[2],
    ];
    sorted.sort_by(|a, b| b.total_cmp(a));
    if sorted[1].is_nan() || sorted[1] <= f64::EPSILON * sorted[0] {
        return None;
    }
    let mut r = u * v_t;
    if r.determinant() < 0.0 {
        // Flip the singular vector of the smallest singular value.
        let smallest = (0..3)
            .min_by(|&a, &b| svd.singular_values[a].total_cmp(&svd.singular_values[b]))
            .unwrap_or(2);
        let mut d = Matrix3::identity();
        d[(smallest, smallest)] = -1.0;
        r = u * d * v_t;
    }
    Some(r)
}

/// An isometry from a rotation matrix known to be orthonormal and a translation.
pub(crate) fn isometry_from(rotation: &Matrix3<f64>, translation: &Vector3<f64>) -> Isometry3<f64> {
    let rotation =
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*rotation));
    Isometry3::from_parts(Translation3::from(*translation), rotation)
}
