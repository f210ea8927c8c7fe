//! Radial-tangential (Brown-Conrady) distortion of a normalized point, shared by the pinhole
//! and unified models: its value, Jacobians, Newton inverse and injective radius.
//!
//! D. C. Brown, "Decentering distortion of lenses", Photogrammetric Engineering 32(3), 1966,
//! in the two-radial, two-tangential form of OpenCV, Kalibr (`radtan`) and CamOdoCal:
//!
//! ```text
//! r^2 = x^2 + y^2,   a = 1 + k1 r^2 + k2 r^4
//! D(x, y) = ( a x + 2 p1 x y + p2 (r^2 + 2 x^2),
//!             a y + p1 (r^2 + 2 y^2) + 2 p2 x y )
//! ```

use nalgebra::{Matrix2, Matrix2x4, Vector2};

use crate::error::UnprojectionError;
use crate::polynomial;

/// Newton iterations allowed when undistorting. From the starting point below, strong real
/// lenses (EuRoC, CamOdoCal's test cameras) need about 5, far-field points of a Mei camera
/// near its limit about 20.
pub const MAX_UNDISTORT_ITERATIONS: usize = 50;

/// Newton stops when the residual is below this many ulps of the distorted radius.
const UNDISTORT_TOLERANCE: f64 = 4.0 * f64::EPSILON;

/// The four distortion coefficients `[k1, k2, p1, p2]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Radtan {
    /// Radial coefficients.
    pub k1: f64,
    /// Radial coefficients.
    pub k2: f64,
    /// Tangential coefficients.
    pub p1: f64,
    /// Tangential coefficients.
    pub p2: f64,
}

impl Radtan {
    /// Build from `[k1, k2, p1, p2]`.
    pub fn from_slice(c: &[f64]) -> Self {
        Self {
            k1: c[0],
            k2: c[1],
            p1: c[2],
            p2: c[3],
        }
    }

    /// D(m).
    #[inline]
    pub fn distort(&self, m: &Vector2<f64>) -> Vector2<f64> {
        let (x, y) = (m.x, m.y);
        let r2 = x * x + y * y;
        let a = 1.0 + r2 * (self.k1 + r2 * self.k2);
        let xy = x * y;
        Vector2::new(
            a * x + 2.0 * self.p1 * xy + self.p2 * (r2 + 2.0 * x * x),
            a * y + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * xy,
        )
    }

    /// D(m) and dD/dm (2x2, symmetric).
    #[inline]
    pub fn distort_with_jacobian(&self, m: &Vector2<f64>) -> (Vector2<f64>, Matrix2<f64>) {
        let (x, y) = (m.x, m.y);
        let r2 = x * x + y * y;
        let a = 1.0 + r2 * (self.k1 + r2 * self.k2);
        // da/dr2
        let da = self.k1 + 2.0 * self.k2 * r2;
        let xy = x * y;
        let d = Vector2::new(
            a * x + 2.0 * self.p1 * xy + self.p2 * (r2 + 2.0 * x * x),
            a * y + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * xy,
        );
        let j00 = a + 2.0 * x * x * da + 2.0 * self.p1 * y + 6.0 * self.p2 * x;
        let j01 = 2.0 * xy * da + 2.0 * self.p1 * x + 2.0 * self.p2 * y;
        let j11 = a + 2.0 * y * y * da + 6.0 * self.p1 * y + 2.0 * self.p2 * x;
        (d, Matrix2::new(j00, j01, j01, j11))
    }

    /// dD / d[k1, k2, p1, p2] (2x4).
    #[inline]
    pub fn jacobian_coeffs(m: &Vector2<f64>) -> Matrix2x4<f64> {
        let (x, y) = (m.x, m.y);
        let r2 = x * x + y * y;
        let r4 = r2 * r2;
        let xy2 = 2.0 * x * y;
        Matrix2x4::new(
            x * r2,
            x * r4,
            xy2,
            r2 + 2.0 * x * x,
            y * r2,
            y * r4,
            r2 + 2.0 * y * y,
            xy2,
        )
    }

    /// Whether all four coefficients are zero (the identity map).
    pub fn is_identity(&self) -> bool {
        self.k1 == 0.0 && self.k2 == 0.0 && self.p1 == 0.0 && self.p2 == 0.0
    }

    /// The undistorted point m with D(m) = md inside the disc |m| < `max_radius` (the
    /// injective radius, where the preimage is unique), by Newton's method with the analytic 2x2
    /// Jacobian. It starts at md (pulled inside the disc, and towards the axis where a radial
    /// term dominates), and halves a step that would increase the residual or leave the disc,
    /// so it cannot converge to a second preimage outside. Returns m and dD/dm at m.
    ///
    /// # Errors
    /// [`UnprojectionError::NotConverged`] if the residual does not fall below
    /// 4 eps (1 + |md|) within [`MAX_UNDISTORT_ITERATIONS`] or the Jacobian becomes singular;
    /// [`UnprojectionError::BeyondInjectiveRadius`] if the iteration is stopped at the edge of
    /// the disc (md is not the image of a point inside it).
    pub fn undistort(
        &self,
        md: &Vector2<f64>,
        max_radius: f64,
    ) -> Result<(Vector2<f64>, Matrix2<f64>), UnprojectionError> {
        let rd2 = md.norm_squared();
        let tol = UNDISTORT_TOLERANCE * (1.0 + rd2.sqrt());
        let tol2 = tol * tol;
        let max2 = max_radius * max_radius;
        // Start at the distorted point, pulled in where a radial term dominates (far from the
        // axis D grows like k2 r^5): r0 = min(rd, (rd/k2)^(1/5), (rd/k1)^(1/3)) for positive k2,
        // k1, and inside 0.9 of the disc. Only points with k2 rd^4 > 1, k1 rd^2 > 1 or outside
        // the disc are moved; near the axis this is the distorted point itself.
        let mut m = *md;
        if (self.k2 > 0.0 && self.k2 * rd2 * rd2 > 1.0)
            || (self.k1 > 0.0 && self.k1 * rd2 > 1.0)
            || rd2 >= 0.81 * max2
        {
            let rd = rd2.sqrt();
            let mut r0 = rd.min(0.9 * max_radius);
            if self.k2 > 0.0 {
                r0 = r0.min((rd / self.k2).powf(0.2));
            }
            if self.k1 > 0.0 {
                r0 = r0.min((rd / self.k1).cbrt());
            }
            m = md * (r0 / rd);
        }
        let (d, mut j) = self.distort_with_jacobian(&m);
        let mut res = d - md;
        let mut res2 = res.norm_squared();
        for it in 0..MAX_UNDISTORT_ITERATIONS {
            if res2 <= tol2 {
                return Ok((m, j));
            }
            let det = j[(0, 0)] * j[(1, 1)] - j[(0, 1)] * j[(1, 0)];
            if det == 0.0 || !det.is_finite() {
                return Err(UnprojectionError::NotConverged {
                    iterations: it,
                    residual: res2.sqrt(),
                });
            }
            let step = Vector2::new(
                (j[(1, 1)] * res.x - j[(0, 1)] * res.y) / det,
                (j[(0, 0)] * res.y - j[(1, 0)] * res.x) / det,
            );
            // Accept the first step length that stays in the disc and does not increase the
            // residual.
            let mut scale = 1.0;
            let mut accepted = false;
            for _ in 0..40 {
                let cand = m - step * scale;
                if cand.norm_squared() < max2 {
                    let (dc, jc) = self.distort_with_jacobian(&cand);
                    let rc = dc - md;
                    let rn2 = rc.norm_squared();
                    if rn2 <= res2 || rn2 <= tol2 {
                        m = cand;
                        j = jc;
                        res = rc;
                        res2 = rn2;
                        accepted = true;
                        break;
                    }
                }
                scale *= 0.5;
            }
            if !accepted {
                return Err(self.stuck(&m, max_radius, it + 1, res2));
            }
        }
        if res2 <= tol2 {
            Ok((m, j))
        } else {
            Err(self.stuck(&m, max_radius, MAX_UNDISTORT_ITERATIONS, res2))
        }
    }

    /// The error for an undistortion that stopped without converging: beyond the injective
    /// radius if it was held at the disc's edge, not converged otherwise.
    fn stuck(
        &self,
        m: &Vector2<f64>,
        max_radius: f64,
        iterations: usize,
        res2: f64,
    ) -> UnprojectionError {
        let radius = m.norm();
        if radius > 0.9 * max_radius {
            UnprojectionError::BeyondInjectiveRadius {
                radius,
                injective_radius: max_radius,
            }
        } else {
            UnprojectionError::NotConverged {
                iterations,
                residual: res2.sqrt(),
            }
        }
    }

    /// The injective radius: the largest R such that det(dD/dm) > 0 on the whole open disc
    /// |m| < R. Inside it the distortion is a local diffeomorphism that keeps orientation, and
    /// the Newton inverse is unique; `f64::INFINITY` if the determinant never vanishes.
    ///
    /// Derivation. With m = r (cos phi, sin phi), a = 1 + k1 r^2 + k2 r^4 and
    /// A = 2 k1 r^2 + 4 k2 r^4, the determinant depends on the direction only through
    /// w = p1 sin phi + p2 cos phi, which ranges over [-|p|, |p|] (|p| = sqrt(p1^2 + p2^2)):
    ///
    /// ```text
    /// det(r, w) = a^2 + a A + r w (8 a + 2 A) + r^2 (16 w^2 - 4 |p|^2)
    /// ```
    ///
    /// It is convex in w, so its minimum over the directions is at
    /// w* = -(8 a + 2 A) / (32 r) clamped to [-|p|, |p|]. The first r where that minimum
    /// reaches zero is a root of one of three polynomials of degree 8 in r (w = +|p|, w = -|p|,
    /// or the interior minimum `a^2 + a A - 4 r^2 |p|^2 - (8 a + 2 A)^2 / 64`) at which the
    /// branch is the active one; their roots come from the companion matrix, the smallest is
    /// polished by bisection on the sign of the minimum, and reduced by 1e-9 relative so the
    /// bound is safe. When p = 0 this is the first root of (r (1 + k1 r^2 + k2 r^4))', as
    /// expected for a radial distortion.
    pub fn injective_radius(&self) -> f64 {
        if self.is_identity() {
            return f64::INFINITY;
        }
        let (k1, k2) = (self.k1, self.k2);
        let pn = self.p1.hypot(self.p2);
        // Polynomials in r (index = power).
        let a = [1.0, 0.0, k1, 0.0, k2];
        let big_a = [0.0, 0.0, 2.0 * k1, 0.0, 4.0 * k2];
        let mut base = [0.0; 9]; // a^2 + a A
        for i in 0..5 {
            for j in 0..5 {
                base[i + j] += a[i] * a[j] + a[i] * big_a[j];
            }
        }
        let b: [f64; 5] = std::array::from_fn(|i| 8.0 * a[i] + 2.0 * big_a[i]); // 8a + 2A
        let boundary = |w: f64| {
            let mut c = base;
            for i in 0..5 {
                c[i + 1] += w * b[i];
            }
            c[2] += 12.0 * w * w; // 16 w^2 - 4 |p|^2 with w^2 = |p|^2
            c
        };
        let mut interior = base;
        interior[2] -= 4.0 * pn * pn;
        for i in 0..5 {
            for j in 0..5 {
                interior[i + j] -= b[i] * b[j] / 64.0;
            }
        }
        let b_at = |r: f64| polynomial::eval(&b, r);
        let min_det = |r: f64| {
            let w = (-b_at(r) / (32.0 * r)).clamp(-pn, pn);
            polynomial::eval(&base, r) + r * w * b_at(r) + r * r * (16.0 * w * w - 4.0 * pn * pn)
        };
        let mut best = f64::INFINITY;
        let mut consider =
            |coeffs: &[f64; 9], active: &dyn Fn(f64) -> bool| match polynomial::roots(coeffs) {
                Ok(roots) => {
                    for i in 0..roots.len {
                        let (re, im) = (roots.re[i], roots.im[i]);
                        if re > 0.0 && im.abs() <= 1e-7 * (1.0 + re) && re < best && active(re) {
                            best = re;
                        }
                    }
                }
                Err(_) => {
                    // The bounded eigenvalue iteration gave up: scan a geometric grid instead.
                    let mut r = 1e-6;
                    while r < 1e8 && r < best {
                        if min_det(r) <= 0.0 {
                            best = r;
                        }
                        r *= 1.001;
                    }
                }
            };
        consider(&boundary(pn), &|r| {
            -b_at(r) / (32.0 * r) >= pn * (1.0 - 1e-9)
        });
        consider(&boundary(-pn), &|r| {
            -b_at(r) / (32.0 * r) <= -pn * (1.0 - 1e-9)
        });
        if pn > 0.0 {
            consider(&interior, &|r| {
                (b_at(r) / (32.0 * r)).abs() <= pn * (1.0 + 1e-9)
            });
        }
        if !best.is_finite() {
            return f64::INFINITY;
        }
        // Polish: the last r with a positive minimum, by bisection around the root.
        let (lo, hi) = (best * (1.0 - 1e-6), best * (1.0 + 1e-6));
        if min_det(lo) > 0.0 && min_det(hi) <= 0.0 {
            best = bisect_sign_change(&min_det, lo, hi);
        }
        best * (1.0 - 1e-9)
    }
}

/// The last point with f > 0 of a bracket where f goes from positive (at `lo`) to non-positive
/// (at `hi`), to full precision.
fn bisect_sign_change(f: &impl Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if f(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// d pixel / d params shared by the pinhole and unified projections. The pixel is
/// `(f1 Dx(m) + c1, f2 Dy(m) + c2)` with the parameters laid out as `[.., k1, k2, p1, p2, ..,
/// f1, f2, c1, c2]` (coefficients from column `coeff_col`, `f1, f2, c1, c2` from `focal_col`);
/// the other columns are zero. Built column by column in one go (no zeroing, then writing).
#[inline]
pub fn projection_param_jacobian(
    coeffs_at: (usize, usize),
    f: (f64, f64),
    m: &Vector2<f64>,
    md: &Vector2<f64>,
) -> crate::model::ParamJacobian<2> {
    let (coeff_col, focal_col) = coeffs_at;
    let jc = Radtan::jacobian_coeffs(m);
    let mut columns = [[0.0; 2]; crate::model::MAX_PARAMS];
    for c in 0..4 {
        columns[coeff_col + c] = [f.0 * jc[(0, c)], f.1 * jc[(1, c)]];
    }
    columns[focal_col] = [md.x, 0.0];
    columns[focal_col + 1] = [0.0, md.y];
    columns[focal_col + 2] = [1.0, 0.0];
    columns[focal_col + 3] = [0.0, 1.0];
    columns.into()
}

/// `diag(f1, f2) a`: the rows of a 2x3 matrix scaled (d pixel / d point from d md / d point).
#[inline]
pub fn scale_rows(mut a: nalgebra::Matrix2x3<f64>, f: (f64, f64)) -> nalgebra::Matrix2x3<f64> {
    a.row_mut(0).scale_mut(f.0);
    a.row_mut(1).scale_mut(f.1);
    a
}

/// Chain rule shared by the pinhole and unified unprojections: the undistorted point m solves
/// `D(m) = md`, `md = ((u - c1) / f1, (v - c2) / f2)`, and the ray is a function of m with
/// d ray / d m = `l`. Fills the parameter columns of the coefficients and of `f1, f2, c1, c2`
/// (layout as in [`projection_param_jacobian`]) and returns d ray / d pixel.
#[inline]
pub fn chain_unprojection(
    coeffs_at: (usize, usize),
    f: (f64, f64),
    m: &Vector2<f64>,
    md: &Vector2<f64>,
    j_d: &Matrix2<f64>,
    l: &nalgebra::Matrix3x2<f64>,
    jp: &mut crate::model::ParamJacobian<3>,
) -> Result<nalgebra::Matrix3x2<f64>, UnprojectionError> {
    let (coeff_col, focal_col) = coeffs_at;
    let Some(j_inv) = j_d.try_inverse() else {
        return Err(UnprojectionError::BeyondInjectiveRadius {
            radius: m.norm(),
            injective_radius: m.norm(),
        });
    };
    // d ray / d md.
    let l_md = l * j_inv;
    let col_u = l_md.column(0) / f.0;
    let col_v = l_md.column(1) / f.1;
    let jc = Radtan::jacobian_coeffs(m);
    let d_ray_d_coeffs = -(l_md * jc);
    for c in 0..4 {
        jp.set_column(coeff_col + c, &d_ray_d_coeffs.column(c));
    }
    jp.set_column(focal_col, &(col_u * (-md.x)));
    jp.set_column(focal_col + 1, &(col_v * (-md.y)));
    jp.set_column(focal_col + 2, &(-col_u));
    jp.set_column(focal_col + 3, &(-col_v));
    Ok(nalgebra::Matrix3x2::from_columns(&[col_u, col_v]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// Brute force: the smallest r on a fine polar grid where det(dD/dm) <= 0.
    fn brute_force_radius(d: &Radtan, r_max: f64) -> f64 {
        let mut best = f64::INFINITY;
        for i in 0..720 {
            let phi = f64::from(i) * std::f64::consts::TAU / 720.0;
            let dir = Vector2::new(phi.cos(), phi.sin());
            let mut r = 0.0;
            while r < r_max.min(best) {
                let (_, j) = d.distort_with_jacobian(&(dir * r));
                if j.determinant() <= 0.0 {
                    best = r;
                    break;
                }
                r += 1e-4;
            }
        }
        best
    }

    #[test]
    fn injective_radius_of_a_radial_distortion_is_the_root_of_the_derivative() {
        // r (1 + k1 r^2)' = 1 + 3 k1 r^2 = 0 at r = sqrt(-1 / (3 k1)).
        let d = Radtan::from_slice(&[-0.5, 0.0, 0.0, 0.0]);
        assert_relative_eq!(
            d.injective_radius(),
            (1.0 / 1.5_f64).sqrt(),
            max_relative = 1e-8
        );
        // Real lenses (EuRoC cam0) never fold.
        let euroc = Radtan::from_slice(&[-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]);
        assert_eq!(euroc.injective_radius(), f64::INFINITY);
    }

    #[test]
    fn injective_radius_with_tangential_terms_matches_brute_force() {
        for c in [
            [-0.5, 0.05, 0.02, -0.03],
            [-0.3, 0.0, 0.1, 0.05],
            [0.0, 0.0, 0.05, 0.0],
            [0.2, -0.1, -0.01, 0.02],
        ] {
            let d = Radtan::from_slice(&c);
            let r = d.injective_radius();
            let brute = brute_force_radius(&d, 20.0);
            assert!(r.is_finite(), "{c:?}");
            // The grid step is 1e-4; the analytic radius is the exact infimum.
            assert!(
                r <= brute + 1e-12 && r >= brute - 2e-4,
                "{c:?}: {r} vs {brute}"
            );
        }
    }
}
