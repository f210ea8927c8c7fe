//! Pixel thresholds as angles for an `ibc-camera-models` camera.
//!
//! A pixel spans different angles across a fisheye image and in different directions at one
//! pixel. The angle returned is the largest that `pixels` pixels span at the given pixel:
//! along the direction in which the unprojection stretches most (the top right singular
//! vector of d ray / d pixel), measured exactly between the unprojected rays, so a threshold
//! built from it never rejects a match that is within `pixels` pixels in any direction to
//! first order.

use ibc_camera_models::CameraModel;
use nalgebra::{Vector2, Vector3};

use crate::error::Result;
use crate::threshold::check_positive;

/// The angle, in radians, that `pixels` pixels span at `pixel` of `camera`, in the direction
/// where it is largest (see the module docs). At the principal point of a distortion-free
/// pinhole camera it equals [`crate::angle_from_pixels`]`(pixels, f)`.
///
/// Pass `camera.principal_point()` for one camera-wide value; for a fisheye, a pixel near the
/// image border gives the angle where the lens is most compressed.
///
/// # Errors
/// [`PnpError::InvalidOption`](crate::PnpError::InvalidOption) if `pixels` is not finite and
/// positive, [`PnpError::Unprojection`](crate::PnpError::Unprojection) if the camera cannot
/// unproject `pixel`.
pub fn angle_from_pixels_at<C: CameraModel + ?Sized>(
    camera: &C,
    pixel: &Vector2<f64>,
    pixels: f64,
) -> Result<f64> {
    check_positive("pixels", pixels)?;
    let (ray, jacobian) = camera.unproject_with_pixel_jacobian(pixel)?;
    let gram = jacobian.transpose() * jacobian;
    // Top eigenvector of the 2 x 2 Gram matrix: the pixel direction of largest stretch.
    let (a, b, d) = (gram[(0, 0)], gram[(0, 1)], gram[(1, 1)]);
    let angle = 0.5 * (2.0 * b).atan2(a - d);
    let direction = Vector2::new(angle.cos(), angle.sin());
    let top = (0.5 * (a + d) + (0.25 * (a - d) * (a - d) + b * b).sqrt())
        .max(0.0)
        .sqrt();
    let mut largest: Option<f64> = None;
    for sign in [-1.0, 1.0] {
        if let Ok(other) = camera.unproject(&(pixel + direction * (sign * pixels))) {
            let between = angle_between(&ray, &other);
            largest = Some(largest.map_or(between, |l| l.max(between)));
        }
    }
    // Both neighbours outside the model's domain (a pixel at the fold): first order.
    Ok(largest.unwrap_or(top * pixels))
}

fn angle_between(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    a.cross(b).norm().atan2(a.dot(b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PnpError;
    use ibc_camera_models::{KannalaBrandt, PinholeRadtan};

    #[test]
    fn pinhole_principal_point_matches_the_focal_length_helper() {
        let camera =
            PinholeRadtan::new(640, 480, [0.0, 0.0, 0.0, 0.0, 800.0, 800.0, 320.0, 240.0]).unwrap();
        let angle = angle_from_pixels_at(&camera, &Vector2::new(320.0, 240.0), 2.0).unwrap();
        let expected = crate::angle_from_pixels(2.0, 800.0).unwrap();
        assert!((angle - expected).abs() < 1e-15, "{angle} vs {expected}");
        // Off-axis a pixel spans less angle (radially by cos^2 of the incidence).
        let corner = angle_from_pixels_at(&camera, &Vector2::new(0.0, 0.0), 2.0).unwrap();
        assert!(corner < angle);
    }

    #[test]
    fn fisheye_angle_is_the_largest_over_directions() {
        // An equidistant fisheye, r = mu theta with small distortion: 190 degrees over 1280 px.
        let camera = KannalaBrandt::new(
            1280,
            1280,
            [-0.01, 0.002, 0.0, 0.0, 385.0, 385.0, 639.5, 639.5],
        )
        .unwrap();
        for pixel in [
            Vector2::new(639.5, 639.5),
            Vector2::new(1000.0, 700.0),
            Vector2::new(1200.0, 639.5),
        ] {
            let angle = angle_from_pixels_at(&camera, &pixel, 3.0).unwrap();
            let centre = camera.unproject(&pixel).unwrap();
            // No direction of a 3 px displacement spans more (to first order).
            for k in 0..36 {
                let phi = f64::from(k) * std::f64::consts::TAU / 36.0;
                let other = camera
                    .unproject(&(pixel + Vector2::new(phi.cos(), phi.sin()) * 3.0))
                    .unwrap();
                assert!(angle_between(&centre, &other) <= angle * (1.0 + 1e-3));
            }
            assert!(angle > 0.0 && angle < 3.0 / 300.0);
        }
    }

    #[test]
    fn bad_arguments_are_errors() {
        let camera =
            PinholeRadtan::new(640, 480, [0.0, 0.0, 0.0, 0.0, 800.0, 800.0, 320.0, 240.0]).unwrap();
        let centre = Vector2::new(320.0, 240.0);
        assert!(matches!(
            angle_from_pixels_at(&camera, &centre, 0.0),
            Err(PnpError::InvalidOption { name: "pixels", .. })
        ));
        assert!(matches!(
            angle_from_pixels_at(&camera, &Vector2::new(f64::NAN, 0.0), 1.0),
            Err(PnpError::Unprojection(_))
        ));
    }
}
