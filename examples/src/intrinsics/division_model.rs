//! A one-parameter division model of radial distortion, estimated from plane homographies, to
//! undistort corners before Zhang's closed form.
//!
//! A. W. Fitzgibbon, "Simultaneous linear estimation of multiple view geometry and lens
//! distortion", CVPR 2001: `x_u = x_d / (1 + lambda |x_d|^2)` (coordinates centred on the
//! distortion centre) captures strong barrel distortion with one parameter. Fitzgibbon solves
//! for `lambda` with the geometry by a quadratic eigenvalue problem; here, with one planar
//! target per image, `lambda` is found by a one-dimensional search: the corners of every image
//! are undistorted with a trial `lambda`, a homography is fitted to each image, and the
//! summed, scale-normalized transfer error is minimized (a grid over
//! `[-LAMBDA_LIMIT, LAMBDA_LIMIT]`, then golden-section search around the best grid point).
//!
//! Coordinates are centred on the image centre and divided by the half-diagonal, so `lambda`
//! is dimensionless and about Zhang's `k1` there; the distortion centre is the image centre.

use nalgebra::{Matrix3, Vector2, Vector3};

use super::homography::homography;

/// The search range of `lambda` (half-diagonal units): beyond -1 the image corners would
/// divide by zero; +-0.9 covers barrel and pincushion distortion of every lens a pinhole model
/// can describe.
pub const LAMBDA_LIMIT: f64 = 0.9;

/// Grid points of the coarse search.
const GRID: usize = 37;

/// Golden-section iterations (each shrinks the bracket by 0.618: 40 give 1e-8 of it).
const GOLDEN_ITERATIONS: usize = 40;

/// Centre and scale of the normalized coordinates of a `width x height` image.
pub fn normalization(width: u32, height: u32) -> (Vector2<f64>, f64) {
    let (w, h) = (f64::from(width), f64::from(height));
    (Vector2::new(0.5 * w, 0.5 * h), 0.5 * w.hypot(h))
}

/// `x_d / (1 + lambda |x_d|^2)` for a point in normalized coordinates, or `None` where the
/// denominator is not positive.
pub fn undistort(x: &Vector2<f64>, lambda: f64) -> Option<Vector2<f64>> {
    let d = 1.0 + lambda * x.norm_squared();
    (d > 0.0).then(|| x / d)
}

/// Summed transfer error of the homographies of every image after undistorting with
/// `lambda`, each image's share divided by the spread of its undistorted points (so shrinking
/// the points does not lower it).
fn cost(plane: &[Vec<Vector2<f64>>], image: &[Vec<Vector2<f64>>], lambda: f64) -> f64 {
    let mut total = 0.0;
    for (p, x) in plane.iter().zip(image) {
        let Some(u): Option<Vec<Vector2<f64>>> = x.iter().map(|q| undistort(q, lambda)).collect()
        else {
            return f64::INFINITY;
        };
        let Some(h) = homography(p, &u) else {
            return f64::INFINITY;
        };
        let n = u.len() as f64;
        let centroid = u.iter().sum::<Vector2<f64>>() / n;
        let spread = u.iter().map(|q| (q - centroid).norm_squared()).sum::<f64>() / n;
        total += transfer_error(&h, p, &u) / spread.max(f64::MIN_POSITIVE);
    }
    total
}

/// Mean squared distance between `H p` and `x`.
fn transfer_error(h: &Matrix3<f64>, plane: &[Vector2<f64>], image: &[Vector2<f64>]) -> f64 {
    let mut sum = 0.0;
    for (p, x) in plane.iter().zip(image) {
        let q = h * Vector3::new(p.x, p.y, 1.0);
        if q.z.abs() < f64::MIN_POSITIVE {
            return f64::INFINITY;
        }
        sum += (Vector2::new(q.x / q.z, q.y / q.z) - x).norm_squared();
    }
    sum / plane.len().max(1) as f64
}

/// The division-model `lambda` that best straightens the boards: `plane[i]` holds image
/// `i`'s board points (x, y on the board) and `image[i]` its corners in normalized
/// coordinates (see [`normalization`]). Returns `None` when no trial `lambda` gives every
/// image a homography.
pub fn estimate_lambda(plane: &[Vec<Vector2<f64>>], image: &[Vec<Vector2<f64>>]) -> Option<f64> {
    let step = 2.0 * LAMBDA_LIMIT / (GRID - 1) as f64;
    let mut best: Option<(usize, f64)> = None;
    for i in 0..GRID {
        let lambda = -LAMBDA_LIMIT + step * i as f64;
        let c = cost(plane, image, lambda);
        if c.is_finite() && best.is_none_or(|(_, b)| c < b) {
            best = Some((i, c));
        }
    }
    let (i, _) = best?;
    let centre = -LAMBDA_LIMIT + step * i as f64;
    let (mut a, mut b) = (centre - step, centre + step);
    let ratio = 0.5 * (5f64.sqrt() - 1.0);
    let mut c = b - ratio * (b - a);
    let mut d = a + ratio * (b - a);
    let (mut fc, mut fd) = (cost(plane, image, c), cost(plane, image, d));
    for _ in 0..GOLDEN_ITERATIONS {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - ratio * (b - a);
            fc = cost(plane, image, c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + ratio * (b - a);
            fd = cost(plane, image, d);
        }
    }
    let lambda = 0.5 * (a + b);
    cost(plane, image, lambda).is_finite().then_some(lambda)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// Boards imaged by a homography and then distorted by the exact inverse of a division
    /// model give back its lambda.
    #[test]
    fn recovers_the_lambda_of_division_distorted_boards() {
        let lambda = -0.2;
        // Inverse of x_u = x_d / (1 + l |x_d|^2) along the ray: solve r_u (1 + l r_d^2) = r_d.
        let distort = |u: Vector2<f64>| -> Vector2<f64> {
            let ru = u.norm();
            if ru == 0.0 {
                return u;
            }
            let mut rd = ru;
            for _ in 0..100 {
                let f = ru * (1.0 + lambda * rd * rd) - rd;
                let df = 2.0 * ru * lambda * rd - 1.0;
                rd -= f / df;
            }
            u * (rd / ru)
        };
        let homographies = [
            Matrix3::new(1.1, 0.2, -0.5, -0.1, 0.9, -0.4, 0.3, 0.1, 1.0),
            Matrix3::new(0.8, -0.3, -0.2, 0.25, 1.0, -0.5, -0.2, 0.3, 1.0),
            Matrix3::new(1.3, 0.0, -0.6, 0.1, 1.2, -0.3, 0.0, -0.4, 1.0),
        ];
        let board: Vec<Vector2<f64>> = (0..30)
            .map(|k| Vector2::new(f64::from(k % 6) * 0.2, f64::from(k / 6) * 0.2))
            .collect();
        let mut plane = Vec::new();
        let mut image = Vec::new();
        for h in &homographies {
            plane.push(board.clone());
            image.push(
                board
                    .iter()
                    .map(|p| {
                        let q = h * Vector3::new(p.x, p.y, 1.0);
                        distort(Vector2::new(q.x / q.z, q.y / q.z))
                    })
                    .collect(),
            );
        }
        let estimate = estimate_lambda(&plane, &image).unwrap();
        assert_relative_eq!(estimate, lambda, epsilon = 1e-6);
    }
}
