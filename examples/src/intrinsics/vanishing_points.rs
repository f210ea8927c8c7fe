//! The focal length of an equidistant fisheye from the two vanishing points of a family of
//! parallel lines.
//!
//! C. Hughes, P. Denny, M. Glavin and E. Jones, "Equidistant fish-eye calibration and
//! rectification by vanishing point extraction", IEEE TPAMI 32(12), 2010, sections 3 and 4;
//! used for the Kannala-Brandt initialization by L. Heng et al., "Infrastructure-based
//! calibration of a multi-camera rig", ICRA 2014, section III.
//!
//! Under the equidistant model `r = f theta` a straight line images to a curve that a circle
//! fits closely. Parallel lines share their two points at infinity, directions `+l` and `-l`,
//! which image at angles `theta` and `pi - theta` on opposite sides of the principal point, so
//! the two vanishing points are `f theta + f (pi - theta) = f pi` apart whatever the lines'
//! direction: `f = |v1 - v2| / pi`.
//!
//! Every fitted circle `a_i s + d_i x + e_i y + f_i w = 0` (with `s w = x^2 + y^2`, `w = 1`
//! for a finite point) passes through both vanishing points, so they span (in least squares,
//! the two smallest eigenvectors of `C^T C` for the stacked coefficients `C`) the null space
//! of the circles; the two points of that pencil on the quadric `s w = x^2 + y^2` are
//! `v1` and `v2`. With two circles this is their exact intersection; more circles average the
//! noise, and lines (`a = 0`) take part like any circle.

use nalgebra::{Matrix4, SymmetricEigen, Vector2, Vector4};

use super::circle_fit::AlgebraicCircle;

/// The two vanishing points common to a family of circles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VanishingPoints {
    /// The first point, in the circles' coordinates.
    pub first: Vector2<f64>,
    /// The second point.
    pub second: Vector2<f64>,
}

impl VanishingPoints {
    /// `|v1 - v2| / pi`: the equidistant focal length, in the circles' units.
    pub fn equidistant_focal(&self) -> f64 {
        (self.first - self.second).norm() / std::f64::consts::PI
    }
}

/// The symmetric bilinear form of the quadric `s w - x^2 - y^2` on `(s, x, y, w)`.
fn quadric(p: &Vector4<f64>, q: &Vector4<f64>) -> f64 {
    0.5 * (p[0] * q[3] + p[3] * q[0]) - p[1] * q[1] - p[2] * q[2]
}

/// The two points where at least two circles (or lines) meet, in least squares.
///
/// Returns `None` for fewer than two circles, circles that do not meet in two real points
/// (nested or tangent circles), or a meeting point at infinity (parallel straight lines).
pub fn common_points(circles: &[AlgebraicCircle]) -> Option<VanishingPoints> {
    if circles.len() < 2 {
        return None;
    }
    let mut gram = Matrix4::zeros();
    for c in circles {
        // Each circle's coefficients act on (s, x, y, w) in this order: (a, d, e, f).
        gram += c.coefficients * c.coefficients.transpose();
    }
    let eig = SymmetricEigen::new(gram);
    let mut order = [0usize, 1, 2, 3];
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let n1: Vector4<f64> = eig.eigenvectors.column(order[0]).into_owned();
    let n2: Vector4<f64> = eig.eigenvectors.column(order[1]).into_owned();
    // X = alpha n1 + beta n2 on the quadric: q11 alpha^2 + 2 q12 alpha beta + q22 beta^2 = 0.
    let (q11, q12, q22) = (quadric(&n1, &n1), quadric(&n1, &n2), quadric(&n2, &n2));
    let disc = q12 * q12 - q11 * q22;
    if disc.is_nan() || disc <= 0.0 {
        return None;
    }
    let root = disc.sqrt();
    let pencil = |alpha: f64, beta: f64| -> Option<Vector2<f64>> {
        let x = n1 * alpha + n2 * beta;
        let w = x[3];
        let scale = x.amax();
        if w.is_nan() || w.abs() <= 1e-12 * scale {
            return None;
        }
        Some(Vector2::new(x[1] / w, x[2] / w))
    };
    let (first, second) = if q11.abs() >= q22.abs() {
        (
            pencil((-q12 + root) / q11, 1.0)?,
            pencil((-q12 - root) / q11, 1.0)?,
        )
    } else {
        (
            pencil(1.0, (-q12 + root) / q22)?,
            pencil(1.0, (-q12 - root) / q22)?,
        )
    };
    if !(first.iter().chain(second.iter()).all(|v| v.is_finite())) {
        return None;
    }
    Some(VanishingPoints { first, second })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::intrinsics::circle_fit::fit_circle;
    use approx::assert_relative_eq;

    /// A circle through two given points, with its centre on their bisector at offset `k`.
    fn arc_through(p: Vector2<f64>, q: Vector2<f64>, k: f64) -> Vec<Vector2<f64>> {
        let mid = 0.5 * (p + q);
        let dir = (q - p).normalize();
        let normal = Vector2::new(-dir.y, dir.x);
        let centre = mid + normal * k;
        let r = (p - centre).norm();
        let a0 = (p - centre).y.atan2((p - centre).x);
        (0..7)
            .map(|i| {
                let t = a0 + 0.2 + 0.1 * i as f64;
                centre + Vector2::new(t.cos(), t.sin()) * r
            })
            .collect()
    }

    #[test]
    fn circles_through_two_points_meet_there() {
        let v1 = Vector2::new(-300.0, 40.0);
        let v2 = Vector2::new(900.0, 120.0);
        let circles: Vec<_> = [-400.0, 150.0, 2000.0]
            .iter()
            .map(|&k| fit_circle(&arc_through(v1, v2, k)).unwrap())
            .collect();
        let vp = common_points(&circles).unwrap();
        let (a, b) = if (vp.first - v1).norm() < (vp.second - v1).norm() {
            (vp.first, vp.second)
        } else {
            (vp.second, vp.first)
        };
        assert_relative_eq!(a, v1, epsilon = 1e-6);
        assert_relative_eq!(b, v2, epsilon = 1e-6);
        // The points agree to 1e-6 px, so the focal length agrees to about 2e-6 / pi px; the
        // default `f64::EPSILON` relative bound asked for more than the points carry.
        assert_relative_eq!(
            vp.equidistant_focal(),
            (v1 - v2).norm() / std::f64::consts::PI,
            epsilon = 1e-6
        );
    }

    #[test]
    fn parallel_lines_meet_at_infinity() {
        let line =
            |c: f64| -> Vec<Vector2<f64>> { (0..5).map(|i| Vector2::new(i as f64, c)).collect() };
        let circles = [
            fit_circle(&line(0.0)).unwrap(),
            fit_circle(&line(3.0)).unwrap(),
        ];
        assert!(common_points(&circles).is_none());
        assert!(common_points(&circles[..1]).is_none());
    }
}
