//! Reduction of the poses or motions of a sensor that moves in the `xy` plane of its frame.

use nalgebra::{Isometry3, Vector3};

use crate::error::{HandEyeError, Result};

/// Checks that every pose rotates about `z` to within `tolerance` (tilt of the `z` axis) and
/// that the translations, taken relative to `origin`, rise out of the `xy` plane by at most
/// `tolerance` (RMS elevation), then keeps only their yaw and `xy` translation.
pub(crate) fn reduce_to_plane<'a>(
    poses: impl ExactSizeIterator<Item = &'a Isometry3<f64>>,
    origin: &Vector3<f64>,
    tolerance: f64,
) -> Result<Vec<Isometry3<f64>>> {
    let (mut sum_z, mut sum_xy) = (0.0, 0.0);
    let mut planar = Vec::with_capacity(poses.len());
    for (index, pose) in poses.enumerate() {
        let r = pose.rotation.to_rotation_matrix();
        let r = r.matrix();
        // Angle between the z axis and its image.
        let tilt = r[(0, 2)].hypot(r[(1, 2)]).atan2(r[(2, 2)]);
        if tilt > tolerance {
            return Err(HandEyeError::NotPlanar {
                index: Some(index),
                out_of_plane: tilt,
                tolerance,
            });
        }
        let t = pose.translation.vector;
        let d = t - origin;
        sum_z += d.z * d.z;
        sum_xy += d.x * d.x + d.y * d.y;
        let yaw = r[(1, 0)].atan2(r[(0, 0)]);
        planar.push(Isometry3::new(
            Vector3::new(t.x, t.y, 0.0),
            Vector3::new(0.0, 0.0, yaw),
        ));
    }
    let elevation = sum_z.sqrt().atan2(sum_xy.sqrt());
    if elevation > tolerance {
        return Err(HandEyeError::NotPlanar {
            index: None,
            out_of_plane: elevation,
            tolerance,
        });
    }
    Ok(planar)
}
