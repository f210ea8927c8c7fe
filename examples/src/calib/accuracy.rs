//! Errors of a calibration against ground truth, with the paper's metrics (Heng et al.,
//! ICRA 2014, Table I).
//!
//! A calibration's rig frame is its camera 0, the truth's is the vehicle frame, so every
//! extrinsic is compared relative to camera 0: `T_c = rig_from_camera_0^-1 rig_from_camera_c`
//! for both. For camera `c > 0`:
//!
//! - rotation error: the angle of `R_est^T R_true`, degrees;
//! - translation direction error: the angle between `t_est` and `t_true`, degrees;
//! - translation error: `|t_est - t_true|`, metres.
//!
//! The hand-eye truth is expressed in the camera-0 rig frame too:
//! `rig_from_odometry_true = rig_from_camera_0_true^-1 rig_from_odometry_vehicle`. The errors
//! are taken on `odometry_from_rig` (the form the planar method solves), in the odometry frame:
//! the rotation angle, the yaw (rotation about the odometry's z-axis), the in-plane (x-y)
//! translation error, and the height error when the height is observable.

use ibc_camera_models::{Camera, CameraModel};
use nalgebra::{Isometry3, Vector3};

use super::error::CalibrationError;
use super::hand_eye::HandEye;
use crate::data::{GroundTruth, TruthMismatch};

/// The errors of one camera's extrinsic relative to camera 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraAccuracy {
    /// Rotation error, degrees.
    pub rotation_error_deg: f64,
    /// Angle between the estimated and true translation directions, degrees.
    pub translation_error_deg: f64,
    /// Norm of the translation error, metres.
    pub translation_error_m: f64,
}

/// The errors of a camera's intrinsics (estimate minus truth), pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IntrinsicsAccuracy {
    /// Of the two focal lengths (horizontal, vertical).
    pub focal_error_px: [f64; 2],
    /// Of the principal point.
    pub principal_point_error_px: [f64; 2],
}

impl IntrinsicsAccuracy {
    /// The errors of `estimate` against the true parameters `truth` (CamOdoCal order, same
    /// model), `None` when the parameter counts differ.
    pub fn of(estimate: &Camera, truth: &[f64]) -> Option<Self> {
        let params = estimate.params();
        if params.len() != truth.len() {
            return None;
        }
        let error = |i: usize| params[i] - truth[i];
        Some(Self {
            focal_error_px: estimate.focal_length_indices().map(error),
            principal_point_error_px: estimate.principal_point_indices().map(error),
        })
    }

    /// The largest focal-length error's size, pixels.
    pub fn max_focal_error_px(&self) -> f64 {
        self.focal_error_px[0]
            .abs()
            .max(self.focal_error_px[1].abs())
    }

    /// The largest principal-point coordinate error's size, pixels.
    pub fn max_principal_point_error_px(&self) -> f64 {
        let [u, v] = self.principal_point_error_px;
        u.abs().max(v.abs())
    }
}

/// The errors of a hand-eye result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HandEyeAccuracy {
    /// Rotation error of `odometry_from_rig`, degrees.
    pub rotation_error_deg: f64,
    /// Its component about the odometry's z-axis (yaw), degrees.
    pub yaw_error_deg: f64,
    /// Error of the x-y translation of `odometry_from_rig`, metres.
    pub in_plane_translation_error_m: f64,
    /// Error of its height (z), metres, when the height is observable.
    pub height_error_m: Option<f64>,
    /// Translation error over the observable components, metres (the in-plane error for the
    /// planar method).
    pub translation_error_m: f64,
}

/// Every extrinsic relative to the first: `rig_from_camera_0^-1 rig_from_camera_c`.
pub fn relative_to_first(rig_from_camera: &[Isometry3<f64>]) -> Vec<Isometry3<f64>> {
    let Some(first) = rig_from_camera.first() else {
        return Vec::new();
    };
    let inverse = first.inverse();
    rig_from_camera.iter().map(|p| inverse * p).collect()
}

/// The angle between two vectors, degrees (0 when either is zero).
fn angle_between_deg(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    if a.norm() == 0.0 || b.norm() == 0.0 {
        return 0.0;
    }
    a.cross(b).norm().atan2(a.dot(b)).to_degrees()
}

/// The errors of `estimate` against `truth`, one per camera relative to camera 0 (`None` for
/// camera 0, the reference).
///
/// # Errors
/// [`CalibrationError::Truth`] when the camera counts differ.
pub fn camera_accuracy(
    estimate: &[Isometry3<f64>],
    truth: &[Isometry3<f64>],
) -> Result<Vec<Option<CameraAccuracy>>, CalibrationError> {
    if estimate.len() != truth.len() {
        return Err(CalibrationError::Truth(TruthMismatch::CameraCount {
            truth: truth.len(),
            log: estimate.len(),
        }));
    }
    let (e, t) = (relative_to_first(estimate), relative_to_first(truth));
    Ok(e.iter()
        .zip(&t)
        .enumerate()
        .map(|(c, (e, t))| {
            (c > 0).then(|| CameraAccuracy {
                rotation_error_deg: e.rotation.angle_to(&t.rotation).to_degrees(),
                translation_error_deg: angle_between_deg(
                    &e.translation.vector,
                    &t.translation.vector,
                ),
                translation_error_m: (e.translation.vector - t.translation.vector).norm(),
            })
        })
        .collect())
}

/// The true `rig_from_odometry` in the camera-0 rig frame, if the truth has one.
pub fn true_rig_from_odometry(truth: &GroundTruth) -> Option<Isometry3<f64>> {
    let first = truth.rig_from_camera.first()?;
    Some(first.inverse() * truth.rig_from_odometry?)
}

/// The errors of a hand-eye result against the true `rig_from_odometry` in the camera-0 rig
/// frame (see [`true_rig_from_odometry`]).
pub fn hand_eye_accuracy(estimate: &HandEye, truth: &Isometry3<f64>) -> HandEyeAccuracy {
    let (e, t) = (estimate.rig_from_odometry.inverse(), truth.inverse());
    let delta = e.rotation * t.rotation.inverse();
    let rotation_error_deg = delta.angle().to_degrees();
    // The yaw of the rotation difference (about the odometry z-axis).
    let m = delta.to_rotation_matrix();
    let yaw_error_deg = m[(1, 0)].atan2(m[(0, 0)]).abs().to_degrees();
    let d = e.translation.vector - t.translation.vector;
    let in_plane = d.xy().norm();
    let height = estimate.height_observable.then_some(d.z.abs());
    HandEyeAccuracy {
        rotation_error_deg,
        yaw_error_deg,
        in_plane_translation_error_m: in_plane,
        height_error_m: height,
        translation_error_m: height.map_or(in_plane, |_| d.norm()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn metrics_are_relative_to_camera_0() {
        let vehicle_from_cam0 =
            Isometry3::new(Vector3::new(2.0, 0.0, 0.6), Vector3::new(0.3, 1.0, -0.2));
        let cam0_from_cam1 =
            Isometry3::new(Vector3::new(1.0, 0.0, 0.0), Vector3::new(0.0, 0.5, 0.0));
        let truth = vec![vehicle_from_cam0, vehicle_from_cam0 * cam0_from_cam1];
        // The estimate: rig frame = camera 0, camera 1 off by 1 mm along y and 0.01 degrees.
        let nudge = Isometry3::new(
            Vector3::new(0.0, 0.001, 0.0),
            Vector3::new(0.0, 0.0, 0.01f64.to_radians()),
        );
        let estimate = vec![Isometry3::identity(), nudge * cam0_from_cam1];
        let a = camera_accuracy(&estimate, &truth).unwrap();
        assert!(a[0].is_none());
        let a = a[1].unwrap();
        assert_abs_diff_eq!(a.rotation_error_deg, 0.01, epsilon = 1e-9);
        // The nudge's rotation also moves the translation by 1 m x 0.01 degrees.
        let expected = (Vector3::new(0.0, 0.001 + 0.01f64.to_radians().sin(), 0.0)
            + Vector3::new(0.01f64.to_radians().cos() - 1.0, 0.0, 0.0))
        .norm();
        assert_abs_diff_eq!(a.translation_error_m, expected, epsilon = 1e-9);
        assert!(a.translation_error_deg > 0.0);
        assert!(camera_accuracy(&estimate, &truth[..1]).is_err());
    }

    #[test]
    fn hand_eye_errors_split_yaw_and_in_plane_translation() {
        use crate::calib::hand_eye::HandEyeSolver;
        use ibc_hand_eye::Uncertainty;
        let truth = Isometry3::new(Vector3::new(0.5, -0.2, 0.9), Vector3::new(1.2, 0.3, -0.4));
        let t = truth.inverse();
        let odometry_from_rig = Isometry3::from_parts(
            (t.translation.vector + Vector3::new(0.003, 0.004, 0.5)).into(),
            nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.02f64.to_radians())
                * t.rotation,
        );
        let estimate = HandEye {
            solver: HandEyeSolver::Planar,
            rig_from_odometry: odometry_from_rig.inverse(),
            height_observable: false,
            uncertainty: Uncertainty {
                rotation_rms: 0.0,
                translation_rms: 0.0,
                rotation_std: Vector3::zeros(),
                translation_std: Vector3::zeros(),
                scale_std: None,
            },
            poses: 3,
            motions: 3,
        };
        let a = hand_eye_accuracy(&estimate, &truth);
        assert_abs_diff_eq!(a.yaw_error_deg, 0.02, epsilon = 1e-9);
        assert_abs_diff_eq!(a.rotation_error_deg, 0.02, epsilon = 1e-9);
        assert_abs_diff_eq!(a.in_plane_translation_error_m, 0.005, epsilon = 1e-9);
        assert_eq!(a.height_error_m, None);
        assert_abs_diff_eq!(a.translation_error_m, 0.005, epsilon = 1e-9);
    }
}
