//! The information matrix of a bearing under pixel noise, for the maximum-likelihood
//! refinement [`crate::refine_pose_weighted`], for any `ibc-camera-models` camera.
//!
//! First-order propagation of covariance (R. Hartley and A. Zisserman, "Multiple View Geometry
//! in Computer Vision", 2nd ed., 2004, chapter 5, propagation of covariance): a pixel with isotropic Gaussian noise of
//! `sigma` pixels per axis gives its unit ray `f = unproject(x)` the covariance
//! `Sigma = J J^T sigma^2`, with `J = d f / d x` (3 x 2). `Sigma` has rank 2: the ray stays a
//! unit vector, so its noise lies in the tangent plane of the sphere at `f`, which is the
//! column space of `J`. The information is its Moore-Penrose pseudo-inverse, the inverse of
//! the covariance on its support (the tangent plane),
//!
//! `Omega = Sigma^+ = J (J^T J)^-2 J^T / sigma^2`,
//!
//! zero along `f` and the inverse of the covariance in the tangent plane, so that
//! `r^T Omega r` is the squared pixel error, in units of `sigma`, of a small bearing error `r`.
//! For a pinhole `J^+ = (J^T J)^-1 J^T` is the projection Jacobian `d pixel / d f`, and
//! `Omega` reduces to `(d pixel / d f)^T (d pixel / d f) / sigma^2`.

use ibc_camera_models::CameraModel;
use nalgebra::{Matrix3, Matrix3x2, Vector2, Vector3};

use crate::error::{PnpError, Result};
use crate::threshold::check_positive;

/// The information matrix (inverse covariance, 3 x 3, rank 2) of the unit bearing of `pixel`
/// of `camera` under isotropic Gaussian pixel noise of `sigma_px` pixels per axis:
/// `J (J^T J)^-2 J^T / sigma_px^2` with `J = d ray / d pixel` (see the module docs). One per
/// correspondence is the `information` argument of [`crate::refine_pose_weighted`], which
/// then minimizes the squared pixel error in units of `sigma_px` to first order, for every
/// camera model and at every incidence, also beyond 90 degrees.
///
/// The bearing itself is `camera.unproject(pixel)`.
///
/// # Errors
/// [`PnpError::InvalidOption`] (`sigma_px`) if `sigma_px` is not finite and positive,
/// [`PnpError::Unprojection`] if the camera cannot unproject `pixel`, and
/// [`PnpError::SingularUnprojectionJacobian`] if `d ray / d pixel` is singular or not finite
/// there.
pub fn bearing_information<C: CameraModel + ?Sized>(
    camera: &C,
    pixel: &Vector2<f64>,
    sigma_px: f64,
) -> Result<Matrix3<f64>> {
    check_positive("sigma_px", sigma_px)?;
    let (_, jacobian) = camera.unproject_with_pixel_jacobian(pixel)?;
    information_from_ray_jacobian(&jacobian, 1.0 / (sigma_px * sigma_px)).ok_or(
        PnpError::SingularUnprojectionJacobian {
            u: pixel.x,
            v: pixel.y,
        },
    )
}

/// The information matrix of `bearing` for a distortion-free pinhole camera of focal length
/// `focal_px` pixels in both axes under one pixel of isotropic noise:
/// [`bearing_information`] of such a camera at the bearing's pixel with `sigma_px = 1`,
/// without a camera value (it equals `J^T J` for the Jacobian `J` of
/// `focal_px * (x / z, y / z)` at the bearing). Zero for a bearing with `z <= 0`, which a
/// pinhole cannot see, and for a focal length or bearing that is not finite and positive.
#[must_use]
pub fn pinhole_information(bearing: &Vector3<f64>, focal_px: f64) -> Matrix3<f64> {
    let z = bearing.z;
    let norm = bearing.norm();
    if !(z > 0.0 && norm.is_finite() && focal_px.is_finite() && focal_px > 0.0) {
        return Matrix3::zeros();
    }
    // The ray of pixel f (m_x, m_y) + c is m / |m| with m = bearing / z:
    // d ray / d pixel = (I - r r^T) / |m| [e_x, e_y] / f.
    let ray = bearing / norm;
    let scale = z / (norm * focal_px);
    let projector = Matrix3::identity() - ray * ray.transpose();
    let jacobian =
        Matrix3x2::from_columns(&[projector.column(0) * scale, projector.column(1) * scale]);
    information_from_ray_jacobian(&jacobian, 1.0).unwrap_or_else(Matrix3::zeros)
}

/// `J (J^T J)^-2 J^T * inverse_variance`, or `None` when `J^T J` is singular or not finite.
fn information_from_ray_jacobian(
    jacobian: &Matrix3x2<f64>,
    inverse_variance: f64,
) -> Option<Matrix3<f64>> {
    let gram = jacobian.tr_mul(jacobian);
    let (a, b, d) = (gram[(0, 0)], gram[(0, 1)], gram[(1, 1)]);
    let det = a * d - b * b;
    // Relative to the Gram matrix's size, so a valid but tiny Jacobian (a long focal length)
    // is not mistaken for a singular one.
    if !(det.is_finite() && det > f64::EPSILON * (a * d).abs()) {
        return None;
    }
    // J^+ transposed: J (J^T J)^-1.
    let inverse_gram = nalgebra::Matrix2::new(d, -b, -b, a) / det;
    let pseudo = jacobian * inverse_gram;
    let information = pseudo * pseudo.transpose() * inverse_variance;
    information
        .iter()
        .all(|v| v.is_finite())
        .then_some(information)
}
