//! Algebraic circle fit with Pratt's normalization.
//!
//! V. Pratt, "Direct least-squares fitting of algebraic surfaces", SIGGRAPH 1987; the
//! Cholesky route to its generalized eigenproblem follows N. Chernov, "Circular and Linear
//! Regression: Fitting Circles and Lines by Least Squares", CRC 2010, section 5.5.
//!
//! A circle (or a line, its limit) is the zero set of
//! `a (x^2 + y^2) + d x + e y + f = 0`. The fit minimizes the algebraic error
//! `sum_i (a z_i + d x_i + e y_i + f)^2` (with `z_i = x_i^2 + y_i^2`) subject to Pratt's
//! constraint `d^2 + e^2 - 4 a f = 1`, which is `4 a^2 R^2` for a circle of radius `R`: unlike
//! Kasa's `a = 1`, it stays well posed as the arc flattens into a line (`a -> 0`), which is
//! what the rows of a board far from the image centre look like. The constrained minimum is
//! the generalized eigenvector of `M c = eta B c` with the smallest non-negative `eta`
//! (`M` the scatter of `(z, x, y, 1)`, `B` the constraint's matrix).

use nalgebra::{Cholesky, Matrix4, SymmetricEigen, Vector2, Vector4};

/// A circle or line `a (x^2 + y^2) + d x + e y + f = 0`, normalized so that
/// `d^2 + e^2 - 4 a f = 1`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlgebraicCircle {
    /// `(a, d, e, f)`.
    pub coefficients: Vector4<f64>,
}

impl AlgebraicCircle {
    /// The algebraic distance of a point, `a (x^2 + y^2) + d x + e y + f`; about the
    /// Euclidean distance to the curve near it under Pratt's normalization.
    pub fn algebraic_distance(&self, p: &Vector2<f64>) -> f64 {
        let [a, d, e, f] = [
            self.coefficients[0],
            self.coefficients[1],
            self.coefficients[2],
            self.coefficients[3],
        ];
        a * p.norm_squared() + d * p.x + e * p.y + f
    }
}

/// Pratt's constraint matrix: `c^T B c = d^2 + e^2 - 4 a f` for `c = (a, d, e, f)`.
fn pratt_matrix() -> Matrix4<f64> {
    Matrix4::new(
        0.0, 0.0, 0.0, -2.0, //
        0.0, 1.0, 0.0, 0.0, //
        0.0, 0.0, 1.0, 0.0, //
        -2.0, 0.0, 0.0, 0.0,
    )
}

/// Fits a circle (or line) to at least three points. The points are centred and scaled
/// internally, so pixels or normalized coordinates work equally well.
///
/// Returns `None` for fewer than three points, points that all coincide, or non-finite input.
pub fn fit_circle(points: &[Vector2<f64>]) -> Option<AlgebraicCircle> {
    if points.len() < 3 || points.iter().any(|p| !(p.x.is_finite() && p.y.is_finite())) {
        return None;
    }
    let n = points.len() as f64;
    let centroid = points.iter().sum::<Vector2<f64>>() / n;
    let scale = (points
        .iter()
        .map(|p| (p - centroid).norm_squared())
        .sum::<f64>()
        / n)
        .sqrt();
    if scale.is_nan() || scale <= 0.0 {
        return None;
    }
    let mut m = Matrix4::zeros();
    for p in points {
        let q = (p - centroid) / scale;
        let z = Vector4::new(q.norm_squared(), q.x, q.y, 1.0);
        m += z * z.transpose();
    }
    let b = pratt_matrix();
    let local = match Cholesky::new(m) {
        Some(chol) => {
            // M = L L^T, c = L^-T w: L^-1 B L^-T w = (1 / eta) w, a symmetric problem whose
            // largest positive eigenvalue is the smallest positive eta.
            let l = chol.l();
            let l_inv = l.try_inverse()?;
            let sym = l_inv * b * l_inv.transpose();
            let sym = 0.5 * (sym + sym.transpose());
            let eig = SymmetricEigen::new(sym);
            let (k, mu) = eig
                .eigenvalues
                .iter()
                .copied()
                .enumerate()
                .max_by(|x, y| x.1.total_cmp(&y.1))?;
            if mu.is_nan() || mu <= 0.0 {
                return None;
            }
            l_inv.transpose() * eig.eigenvectors.column(k)
        }
        None => {
            // The points fit a circle exactly: the null vector of M.
            let eig = SymmetricEigen::new(m);
            let k = eig.eigenvalues.imin();
            eig.eigenvectors.column(k).into_owned()
        }
    };
    // Back to the caller's coordinates: q = (p - c) / s.
    let (a1, d1, e1, f1) = (local[0], local[1], local[2], local[3]);
    let s2 = scale * scale;
    let a = a1 / s2;
    let d = d1 / scale - 2.0 * a * centroid.x;
    let e = e1 / scale - 2.0 * a * centroid.y;
    let f = a * centroid.norm_squared() - d1 * centroid.x / scale - e1 * centroid.y / scale + f1;
    let c = Vector4::new(a, d, e, f);
    let norm = c[1] * c[1] + c[2] * c[2] - 4.0 * c[0] * c[3];
    if !(norm > 0.0 && norm.is_finite()) {
        return None;
    }
    Some(AlgebraicCircle {
        coefficients: c / norm.sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn circle_points(cx: f64, cy: f64, r: f64, from: f64, to: f64, n: usize) -> Vec<Vector2<f64>> {
        (0..n)
            .map(|i| {
                let t = from + (to - from) * i as f64 / (n - 1) as f64;
                Vector2::new(cx + r * t.cos(), cy + r * t.sin())
            })
            .collect()
    }

    /// Centre and radius from the coefficients: (-d / 2a, -e / 2a), 1 / (2 |a|).
    fn centre_radius(c: &AlgebraicCircle) -> (f64, f64, f64) {
        let [a, d, e, _] = [
            c.coefficients[0],
            c.coefficients[1],
            c.coefficients[2],
            c.coefficients[3],
        ];
        (-d / (2.0 * a), -e / (2.0 * a), 1.0 / (2.0 * a.abs()))
    }

    #[test]
    fn exact_arc_is_recovered() {
        let pts = circle_points(700.0, -300.0, 850.0, 0.3, 0.9, 9);
        let c = fit_circle(&pts).unwrap();
        let (x, y, r) = centre_radius(&c);
        assert_relative_eq!(x, 700.0, epsilon = 1e-6);
        assert_relative_eq!(y, -300.0, epsilon = 1e-6);
        assert_relative_eq!(r, 850.0, epsilon = 1e-6);
        for p in &pts {
            assert!(c.algebraic_distance(p).abs() < 1e-9);
        }
    }

    #[test]
    fn straight_line_gives_a_zero_quadratic_term() {
        let pts: Vec<_> = (0..6)
            .map(|i| Vector2::new(i as f64, 2.0 * i as f64 + 1.0))
            .collect();
        let c = fit_circle(&pts).unwrap();
        assert!(c.coefficients[0].abs() < 1e-12);
        for p in &pts {
            assert!(c.algebraic_distance(p).abs() < 1e-9);
        }
        // Under Pratt's normalization the algebraic distance of a line is the Euclidean one.
        let off = Vector2::new(0.0, 0.0);
        assert_relative_eq!(
            c.algebraic_distance(&off).abs(),
            1.0 / 5f64.sqrt(),
            epsilon = 1e-9
        );
    }

    #[test]
    fn refuses_too_few_or_coincident_points() {
        assert!(fit_circle(&[Vector2::new(0.0, 0.0), Vector2::new(1.0, 0.0)]).is_none());
        assert!(fit_circle(&[Vector2::new(1.0, 1.0); 5]).is_none());
        assert!(fit_circle(&[Vector2::new(f64::NAN, 1.0); 5]).is_none());
    }
}
