//! A multi-camera rig: named cameras with their extrinsics, read and written in CamOdoCal and
//! Kalibr formats.
//!
//! A CamOdoCal rig folder holds [`EXTRINSIC_FILE_NAME`](camodocal::EXTRINSIC_FILE_NAME) and a
//! YAML per camera named there: `<name>_calib.yaml` (CamOdoCal's `CameraSystem`, which
//! [`Rig::write_camodocal_dir`] writes) or `<name>_camera_calib.yaml` (CamOdoCal's intrinsic
//! calibration tool); [`Rig::read_camodocal_dir`] reads either.

use nalgebra::Isometry3;

use crate::camera::Camera;
use crate::error::CameraFileError;

/// One camera of a rig.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct RigCamera {
    /// Its name (CamOdoCal `camera_name`; Kalibr's key is `camN`, so the name there is `camN`).
    pub name: String,
    /// Its intrinsics.
    pub camera: Camera,
    /// Its extrinsic: maps camera coordinates into the rig frame. Serialized as
    /// `{"rotation_wxyz": [w, x, y, z], "translation": [x, y, z]}`.
    #[cfg_attr(feature = "serde", serde(with = "pose_serde"))]
    pub rig_from_camera: Isometry3<f64>,
    /// Kalibr `rostopic`, kept for round trips.
    #[cfg_attr(feature = "serde", serde(default))]
    pub topic: Option<String>,
    /// Kalibr `cam_overlaps` (indices of the cameras that share a view), kept for round trips.
    #[cfg_attr(feature = "serde", serde(default))]
    pub overlaps: Vec<usize>,
    /// Kalibr `T_cam_imu` (`camchain-imucam.yaml`): maps IMU coordinates into this camera.
    /// Serialized like `rig_from_camera`, omitted when absent.
    #[cfg_attr(
        feature = "serde",
        serde(
            default,
            with = "pose_serde_opt",
            skip_serializing_if = "Option::is_none"
        )
    )]
    pub camera_from_imu: Option<Isometry3<f64>>,
    /// Kalibr `timeshift_cam_imu` in seconds (`camchain-imucam.yaml`): the IMU time of an image
    /// is its camera timestamp plus this shift, `t_imu = t_cam + shift`.
    #[cfg_attr(
        feature = "serde",
        serde(default, skip_serializing_if = "Option::is_none")
    )]
    pub timeshift_cam_imu_s: Option<f64>,
}

impl RigCamera {
    /// A camera with no Kalibr metadata (no topic, overlaps, IMU transform or time shift).
    pub fn new(name: impl Into<String>, camera: Camera, rig_from_camera: Isometry3<f64>) -> Self {
        Self {
            name: name.into(),
            camera,
            rig_from_camera,
            topic: None,
            overlaps: Vec::new(),
            camera_from_imu: None,
            timeshift_cam_imu_s: None,
        }
    }
}

/// A rig of cameras, in order. Names must be unique for the rig to be written (the writers
/// check).
#[derive(Clone, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Rig {
    /// The cameras, in file order.
    pub cameras: Vec<RigCamera>,
}

impl Rig {
    /// A rig of these cameras.
    pub fn new(cameras: Vec<RigCamera>) -> Self {
        Self { cameras }
    }

    /// The camera with this name.
    pub fn camera(&self, name: &str) -> Option<&RigCamera> {
        self.cameras.iter().find(|c| c.name == name)
    }

    /// `a_from_b`: maps coordinates of camera `b` into camera `a`.
    pub fn camera_from_camera(&self, a: &str, b: &str) -> Option<Isometry3<f64>> {
        let a = self.camera(a)?;
        let b = self.camera(b)?;
        Some(a.rig_from_camera.inverse() * b.rig_from_camera)
    }

    /// Check that names are unique and non-empty.
    ///
    /// # Errors
    /// [`CameraFileError::Rig`] naming the offending camera.
    pub fn check_names(&self) -> Result<(), CameraFileError> {
        for (i, c) in self.cameras.iter().enumerate() {
            if c.name.trim().is_empty() || c.name.contains(['\n', '\r']) {
                return Err(CameraFileError::Rig {
                    message: format!("camera {i} has an empty or multi-line name"),
                });
            }
            if self.cameras[..i].iter().any(|o| o.name == c.name) {
                return Err(CameraFileError::Rig {
                    message: format!("camera name `{}` appears twice", c.name),
                });
            }
        }
        Ok(())
    }
}

#[cfg(feature = "serde")]
mod pose_serde {
    use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    #[derive(Serialize, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub(super) struct Pose {
        rotation_wxyz: [f64; 4],
        translation: [f64; 3],
    }

    pub(super) fn to_pose(p: &Isometry3<f64>) -> Pose {
        let q = p.rotation.quaternion();
        let t = p.translation.vector;
        Pose {
            rotation_wxyz: [q.w, q.i, q.j, q.k],
            translation: [t.x, t.y, t.z],
        }
    }

    pub(super) fn from_pose(p: &Pose) -> Result<Isometry3<f64>, &'static str> {
        let [w, x, y, z] = p.rotation_wxyz;
        let q = Quaternion::new(w, x, y, z);
        let n = q.norm();
        if !n.is_finite() || (n - 1.0).abs() > 1e-6 || !p.translation.iter().all(|v| v.is_finite())
        {
            return Err(
                "rotation_wxyz must be a finite unit quaternion (norm within 1e-6 of 1) and the \
                 translation finite",
            );
        }
        let [tx, ty, tz] = p.translation;
        Ok(Isometry3::from_parts(
            Translation3::new(tx, ty, tz),
            UnitQuaternion::from_quaternion(q),
        ))
    }

    pub fn serialize<S: Serializer>(p: &Isometry3<f64>, s: S) -> Result<S::Ok, S::Error> {
        to_pose(p).serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Isometry3<f64>, D::Error> {
        from_pose(&Pose::deserialize(d)?).map_err(serde::de::Error::custom)
    }
}

/// [`pose_serde`] for an optional pose (`null` or absent is `None`).
#[cfg(feature = "serde")]
mod pose_serde_opt {
    use nalgebra::Isometry3;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    use super::pose_serde::{Pose, from_pose, to_pose};

    #[allow(clippy::ref_option)] // serde's `with` passes `&Option<T>`
    pub fn serialize<S: Serializer>(p: &Option<Isometry3<f64>>, s: S) -> Result<S::Ok, S::Error> {
        p.as_ref().map(to_pose).serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(
        d: D,
    ) -> Result<Option<Isometry3<f64>>, D::Error> {
        Option::<Pose>::deserialize(d)?
            .as_ref()
            .map(from_pose)
            .transpose()
            .map_err(serde::de::Error::custom)
    }
}
