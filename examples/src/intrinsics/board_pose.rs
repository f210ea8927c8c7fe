//! Board poses from one image's corners for a given camera: PnP on bearing vectors, and the
//! reprojection errors of a pose.
//!
//! Bearings come from the camera's unprojection, so the same code serves a pinhole and a
//! fisheye beyond 90 degrees; the pose is EPnP (Lepetit et al., IJCV 2009, planar case)
//! refined by Levenberg-Marquardt on the bearing error (`ibc-pnp`).

use ibc_camera_models::{Camera, CameraModel};
use ibc_pnp::{PnpError, RefineOptions, epnp, refine_pose};
use nalgebra::{Isometry3, Point3, Vector2, Vector3};

use super::corners::{CornerSet, ImageCorners};
use super::target::PlanarTarget;

/// The board points and observed pixels of one image's corners, index for index.
pub(crate) type ImageCorrespondences = (Vec<Point3<f64>>, Vec<Vector2<f64>>);

/// The [`ImageCorrespondences`] of every image, in input order.
pub(crate) type Correspondences = Vec<ImageCorrespondences>;

/// The correspondences of every image of a corner set.
pub(crate) fn all_correspondences(target: &PlanarTarget, corners: &CornerSet) -> Correspondences {
    corners
        .images
        .iter()
        .map(|image| correspondences(target, image))
        .collect()
}

/// The board points and pixels of an image's corners, index for index.
pub(crate) fn correspondences(target: &PlanarTarget, image: &ImageCorners) -> ImageCorrespondences {
    image
        .corners
        .iter()
        .map(|c| (target.point(c.row, c.col), c.pixel()))
        .unzip()
}

/// The unit bearings of pixels.
pub(crate) fn bearings(
    camera: &Camera,
    pixels: &[Vector2<f64>],
) -> Result<Vec<Vector3<f64>>, PnpError> {
    pixels
        .iter()
        .map(|p| Ok(camera.unproject_fast(p)?.into_inner()))
        .collect()
}

/// `camera_from_board` from the corners of one image: EPnP on the bearings, then (if
/// `refine`) the bearing-error refinement.
///
/// # Errors
/// [`PnpError`] if a pixel cannot be unprojected or the points do not determine a pose.
pub(crate) fn board_pose(
    camera: &Camera,
    points: &[Point3<f64>],
    pixels: &[Vector2<f64>],
    refine: bool,
) -> Result<Isometry3<f64>, PnpError> {
    let rays = bearings(camera, pixels)?;
    let pose = epnp(&rays, points)?;
    if !refine {
        return Ok(pose);
    }
    Ok(refine_pose(&rays, points, &pose, &RefineOptions::default())?.camera_from_world)
}

/// Sum over the corners of `min(|pi(pose X) - x|^2, cap^2)`: the squared reprojection error
/// with each corner's share capped (a corner that does not project counts as `cap^2`).
pub(crate) fn capped_squared_error(
    camera: &Camera,
    camera_from_board: &Isometry3<f64>,
    points: &[Point3<f64>],
    pixels: &[Vector2<f64>],
    cap: f64,
) -> f64 {
    let cap2 = cap * cap;
    points
        .iter()
        .zip(pixels)
        .map(
            |(x, obs)| match camera.project(&(camera_from_board * x).coords) {
                Ok(p) => (p - obs).norm_squared().min(cap2),
                Err(_) => cap2,
            },
        )
        .sum()
}
