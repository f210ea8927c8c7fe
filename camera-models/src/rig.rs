//! A multi-camera rig: named cameras with their extrinsics, read and written in CamOdoCal and
//! Kalibr formats.

use std::path::Path;

use nalgebra::Isometry3;

use crate::camera::Camera;
use crate::camodocal;
use crate::error::FileError;
use crate::yaml;

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
}

impl RigCamera {
    /// A camera with no Kalibr metadata.
    pub fn new(name: impl Into<String>, camera: Camera, rig_from_camera: Isometry3<f64>) -> Self {
        Self {
            name: name.into(),
            camera,
            rig_from_camera,
            topic: None,
            overlaps: Vec::new(),
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
    /// [`FileError::Rig`] naming the offending camera.
    pub fn check_names(&self) -> Result<(), FileError> {
        for (i, c) in self.cameras.iter().enumerate() {
            if c.name.trim().is_empty() || c.name.contains(['\n', '\r']) {
                return Err(FileError::Rig {
                    message: format!("camera {i} has an empty or multi-line name"),
                });
            }
            if self.cameras[..i].iter().any(|o| o.name == c.name) {
                return Err(FileError::Rig {
                    message: format!("camera name `{}` appears twice", c.name),
                });
            }
        }
        Ok(())
    }

    /// Read a CamOdoCal rig directory: `extrinsic.txt` and, for every camera named there,
    /// `<name>_camera_calib.yaml`.
    ///
    /// # Errors
    /// [`FileError`] for a missing or malformed file, or a camera YAML whose `camera_name`
    /// differs from its name in `extrinsic.txt`.
    pub fn read_camodocal_dir(dir: impl AsRef<Path>) -> Result<Self, FileError> {
        let dir = dir.as_ref();
        let poses = camodocal::parse_extrinsics(&yaml::read_text(&dir.join("extrinsic.txt"))?)?;
        let mut cameras = Vec::with_capacity(poses.len());
        for (name, rig_from_camera) in poses {
            let named = camodocal::read_camera(dir.join(format!("{name}_camera_calib.yaml")))?;
            if named.name != name {
                return Err(FileError::Rig {
                    message: format!(
                        "`{name}_camera_calib.yaml` names its camera `{}`",
                        named.name
                    ),
                });
            }
            cameras.push(RigCamera::new(name, named.camera, rig_from_camera));
        }
        let rig = Self { cameras };
        rig.check_names()?;
        Ok(rig)
    }

    /// Write a CamOdoCal rig directory (created if needed): `<name>_camera_calib.yaml` per
    /// camera, then `extrinsic.txt`, each atomically.
    ///
    /// # Errors
    /// [`FileError`] for duplicate names or an I/O failure.
    pub fn write_camodocal_dir(&self, dir: impl AsRef<Path>) -> Result<(), FileError> {
        self.check_names()?;
        let dir = dir.as_ref();
        std::fs::create_dir_all(dir).map_err(|source| FileError::Io {
            path: dir.to_owned(),
            source,
        })?;
        for c in &self.cameras {
            camodocal::write_camera(
                dir.join(format!("{}_camera_calib.yaml", c.name)),
                &c.name,
                &c.camera,
            )?;
        }
        let text = camodocal::format_extrinsics(
            self.cameras
                .iter()
                .map(|c| (c.name.as_str(), &c.rig_from_camera)),
        );
        yaml::write_atomic(&dir.join("extrinsic.txt"), &text)
    }
}

#[cfg(feature = "serde")]
mod pose_serde {
    use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    #[derive(Serialize, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Pose {
        rotation_wxyz: [f64; 4],
        translation: [f64; 3],
    }

    pub fn serialize<S: Serializer>(p: &Isometry3<f64>, s: S) -> Result<S::Ok, S::Error> {
        let q = p.rotation.quaternion();
        let t = p.translation.vector;
        Pose {
            rotation_wxyz: [q.w, q.i, q.j, q.k],
            translation: [t.x, t.y, t.z],
        }
        .serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Isometry3<f64>, D::Error> {
        let p = Pose::deserialize(d)?;
        let [w, x, y, z] = p.rotation_wxyz;
        let q = Quaternion::new(w, x, y, z);
        let n = q.norm();
        if !n.is_finite() || (n - 1.0).abs() > 1e-6 || !p.translation.iter().all(|v| v.is_finite())
        {
            return Err(serde::de::Error::custom(
                "rotation_wxyz must be a finite unit quaternion (norm within 1e-6 of 1) and the \
                 translation finite",
            ));
        }
        let [tx, ty, tz] = p.translation;
        Ok(Isometry3::from_parts(
            Translation3::new(tx, ty, tz),
            UnitQuaternion::from_quaternion(q),
        ))
    }
}
