//! The plane-to-image homography by the normalized direct linear transform.
//!
//! R. Hartley and A. Zisserman, "Multiple View Geometry in Computer Vision", 2nd ed., 2004,
//! algorithm 4.2: both point sets are translated to their centroid and scaled to a mean
//! distance of sqrt(2) before the DLT, which makes its least-squares solution well
//! conditioned; the homography is denormalized afterwards.

use nalgebra::{Matrix3, SMatrix, SymmetricEigen, Vector2, Vector3};

/// The similarity that moves a point set's centroid to the origin and its mean distance from
/// it to sqrt(2), or `None` when all points coincide.
fn normalizing_transform(points: &[Vector2<f64>]) -> Option<Matrix3<f64>> {
    let n = points.len() as f64;
    let centroid = points.iter().sum::<Vector2<f64>>() / n;
    let mean = points.iter().map(|p| (p - centroid).norm()).sum::<f64>() / n;
    if !(mean > 0.0 && mean.is_finite()) {
        return None;
    }
    let s = std::f64::consts::SQRT_2 / mean;
    Some(Matrix3::new(
        s,
        0.0,
        -s * centroid.x,
        0.0,
        s,
        -s * centroid.y,
        0.0,
        0.0,
        1.0,
    ))
}

/// The homography `H` with `image ~ H (plane, 1)` from four or more correspondences, scaled to
/// unit Frobenius norm with `H[(2, 2)] >= 0`.
///
/// Returns `None` for fewer than four pairs, mismatched lengths, coincident points or a
/// rank-deficient system (three or more plane points on a line is fine as long as four are in
/// general position).
pub fn homography(plane: &[Vector2<f64>], image: &[Vector2<f64>]) -> Option<Matrix3<f64>> {
    if plane.len() < 4 || plane.len() != image.len() {
        return None;
    }
    let tp = normalizing_transform(plane)?;
    let ti = normalizing_transform(image)?;
    let mut ata = SMatrix::<f64, 9, 9>::zeros();
    for (p, q) in plane.iter().zip(image) {
        let x = tp * Vector3::new(p.x, p.y, 1.0);
        let y = ti * Vector3::new(q.x, q.y, 1.0);
        // Rows of y x (H x) = 0: [0, -x^T, v x^T] and [x^T, 0, -u x^T].
        let r1 = SMatrix::<f64, 1, 9>::from_row_slice(&[
            0.0,
            0.0,
            0.0,
            -x.x,
            -x.y,
            -x.z,
            y.y * x.x,
            y.y * x.y,
            y.y * x.z,
        ]);
        let r2 = SMatrix::<f64, 1, 9>::from_row_slice(&[
            x.x,
            x.y,
            x.z,
            0.0,
            0.0,
            0.0,
            -y.x * x.x,
            -y.x * x.y,
            -y.x * x.z,
        ]);
        ata += r1.transpose() * r1 + r2.transpose() * r2;
    }
    let eig = SymmetricEigen::new(ata);
    let mut order: Vec<usize> = (0..9).collect();
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    // A unique solution needs a one-dimensional null space.
    let (second, largest) = (eig.eigenvalues[order[1]], eig.eigenvalues[order[8]]);
    if second.is_nan() || second <= 1e-12 * largest {
        return None;
    }
    let h = eig.eigenvectors.column(order[0]);
    let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
    let ti_inv = ti.try_inverse()?;
    let mut out = ti_inv * hn * tp;
    let norm = out.norm();
    if !(norm > 0.0 && norm.is_finite()) {
        return None;
    }
    out /= norm;
    if out[(2, 2)] < 0.0 {
        out = -out;
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn recovers_an_exact_homography() {
        let truth = Matrix3::new(400.0, 12.0, 300.0, -8.0, 390.0, 220.0, 0.05, -0.02, 1.0);
        let plane: Vec<_> = (0..12)
            .map(|i| Vector2::new(f64::from(i % 4) * 0.1, f64::from(i / 4) * 0.1))
            .collect();
        let image: Vec<_> = plane
            .iter()
            .map(|p| {
                let q = truth * Vector3::new(p.x, p.y, 1.0);
                Vector2::new(q.x / q.z, q.y / q.z)
            })
            .collect();
        let h = homography(&plane, &image).unwrap();
        assert_relative_eq!(h, truth / truth.norm(), epsilon = 1e-10);
    }

    #[test]
    fn refuses_collinear_points() {
        let plane: Vec<_> = (0..6).map(|i| Vector2::new(f64::from(i), 0.0)).collect();
        let image = plane.clone();
        assert!(homography(&plane, &image).is_none());
        assert!(homography(&plane[..3], &image[..3]).is_none());
    }
}
