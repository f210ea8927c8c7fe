//! A COLMAP sparse model as COLMAP stores it, and its reader (text or binary by what the
//! folder holds).
//!
//! The types hold COLMAP's values unchanged (ids, pixel coordinates with centres at `+0.5`),
//! so that a model reads and writes back the same; [`super::map`] converts to ibc's
//! conventions. Poses are `Isometry3` named as in ibc and in COLMAP (`cam_from_world`,
//! `rig_from_world`, `sensor_from_rig`); COLMAP's quaternions are `[w, x, y, z]`.

use std::path::Path;

use nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion, Vector2};

use super::camera::ColmapCamera;
use super::error::{ColmapError, Result};
use super::{binary, text};

/// COLMAP's marker of a 2D point without a 3D point (`-1` in text, `u64::MAX` in binary).
pub const NO_POINT3D: u64 = u64::MAX;

/// A quaternion whose norm differs from 1 by more than this is refused (COLMAP writes unit
/// quaternions to 17 digits; a user's hand-made file may round them to 6).
pub const UNIT_QUATERNION_TOLERANCE: f64 = 1e-4;

/// A sensor of a rig: COLMAP's `(SENSOR_TYPE, SENSOR_ID)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Sensor {
    /// The kind of sensor.
    pub kind: SensorKind,
    /// The sensor's id: a camera's is its camera id.
    pub id: u32,
}

/// COLMAP's sensor types.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum SensorKind {
    /// A camera (`CAMERA`, code 0).
    Camera,
    /// An IMU (`IMU`, code 1).
    Imu,
}

impl SensorKind {
    /// From COLMAP's code.
    pub fn from_code(code: i64) -> Option<Self> {
        match code {
            0 => Some(Self::Camera),
            1 => Some(Self::Imu),
            _ => None,
        }
    }

    /// From COLMAP's name in text files.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "CAMERA" => Some(Self::Camera),
            "IMU" => Some(Self::Imu),
            _ => None,
        }
    }

    /// COLMAP's code.
    pub fn code(self) -> i32 {
        match self {
            Self::Camera => 0,
            Self::Imu => 1,
        }
    }

    /// COLMAP's name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Camera => "CAMERA",
            Self::Imu => "IMU",
        }
    }
}

/// A rig: its reference sensor (whose frame is the rig's) and the other sensors, each with
/// its `sensor_from_rig` when known.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapRig {
    /// COLMAP's rig id.
    pub rig_id: u32,
    /// The reference sensor.
    pub ref_sensor: Sensor,
    /// The other sensors.
    pub sensors: Vec<(Sensor, Option<Isometry3<f64>>)>,
}

/// A frame: one exposure of a rig, its pose and the data (images) it holds.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapFrame {
    /// COLMAP's frame id.
    pub frame_id: u32,
    /// The rig.
    pub rig_id: u32,
    /// The rig's pose.
    pub rig_from_world: Isometry3<f64>,
    /// The data of the frame: the sensor and the data id (an image id for a camera).
    pub data: Vec<(Sensor, u64)>,
}

/// A 2D point of an image: a keypoint, index for index with the database's keypoints.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ColmapPoint2D {
    /// Pixel position, COLMAP's convention (centres at `+0.5`).
    pub xy: Vector2<f64>,
    /// The 3D point it observes, or [`NO_POINT3D`].
    pub point3d_id: u64,
}

/// A registered image.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapImage {
    /// COLMAP's image id.
    pub image_id: u32,
    /// The image's name (its path relative to the image folder).
    pub name: String,
    /// The camera that took it.
    pub camera_id: u32,
    /// Its pose.
    pub cam_from_world: Isometry3<f64>,
    /// Its 2D points.
    pub points2d: Vec<ColmapPoint2D>,
}

/// A 3D point and its track.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapPoint3D {
    /// COLMAP's point id.
    pub point3d_id: u64,
    /// Position in the world frame.
    pub xyz: Point3<f64>,
    /// Colour.
    pub color: [u8; 3],
    /// Mean reprojection error, pixels.
    pub error: f64,
    /// The observations: `(image id, index of the 2D point in the image)`.
    pub track: Vec<(u32, u32)>,
}

/// A COLMAP sparse model, each list sorted by id. Rigs and frames are empty for models
/// written before COLMAP 3.12.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ColmapModel {
    /// Cameras.
    pub cameras: Vec<ColmapCamera>,
    /// Registered images.
    pub images: Vec<ColmapImage>,
    /// 3D points.
    pub points3d: Vec<ColmapPoint3D>,
    /// Rigs (`rigs.bin` / `rigs.txt`, where present).
    pub rigs: Vec<ColmapRig>,
    /// Frames (`frames.bin` / `frames.txt`, where present).
    pub frames: Vec<ColmapFrame>,
}

impl ColmapModel {
    /// The camera with this id.
    pub fn camera(&self, camera_id: u32) -> Option<&ColmapCamera> {
        self.cameras
            .binary_search_by_key(&camera_id, |c| c.camera_id)
            .ok()
            .map(|i| &self.cameras[i])
    }

    /// The image with this id.
    pub fn image(&self, image_id: u32) -> Option<&ColmapImage> {
        self.images
            .binary_search_by_key(&image_id, |c| c.image_id)
            .ok()
            .map(|i| &self.images[i])
    }

    /// Sorts every list by id and checks the references between them: unique ids, the
    /// cameras of the images, the 3D points of the 2D points, the images and 2D points of
    /// the tracks, the rigs of the frames. `path` names the model in errors.
    ///
    /// # Errors
    /// [`ColmapError::Invalid`] naming the first broken reference.
    pub fn check(&mut self, path: &Path) -> Result<()> {
        let invalid = |what: String| ColmapError::Invalid {
            path: path.to_owned(),
            what,
        };
        self.cameras.sort_by_key(|c| c.camera_id);
        self.images.sort_by_key(|i| i.image_id);
        self.points3d.sort_by_key(|p| p.point3d_id);
        self.rigs.sort_by_key(|r| r.rig_id);
        self.frames.sort_by_key(|f| f.frame_id);
        let dup = |ids: &mut dyn Iterator<Item = u64>, what: &str| {
            let mut last = None;
            for id in ids {
                if last == Some(id) {
                    return Err(invalid(format!("two {what}s have the id {id}")));
                }
                last = Some(id);
            }
            Ok(())
        };
        dup(
            &mut self.cameras.iter().map(|c| u64::from(c.camera_id)),
            "camera",
        )?;
        dup(
            &mut self.images.iter().map(|c| u64::from(c.image_id)),
            "image",
        )?;
        dup(&mut self.points3d.iter().map(|c| c.point3d_id), "3D point")?;
        dup(&mut self.rigs.iter().map(|c| u64::from(c.rig_id)), "rig")?;
        dup(
            &mut self.frames.iter().map(|c| u64::from(c.frame_id)),
            "frame",
        )?;
        let point = |id: u64| {
            self.points3d
                .binary_search_by_key(&id, |p| p.point3d_id)
                .is_ok()
        };
        for image in &self.images {
            if self.camera(image.camera_id).is_none() {
                return Err(invalid(format!(
                    "image {} ({:?}) has camera {}, which the model does not hold",
                    image.image_id, image.name, image.camera_id
                )));
            }
            for (idx, p) in image.points2d.iter().enumerate() {
                if p.point3d_id != NO_POINT3D && !point(p.point3d_id) {
                    return Err(invalid(format!(
                        "2D point {idx} of image {} observes 3D point {}, which the model \
                         does not hold",
                        image.image_id, p.point3d_id
                    )));
                }
            }
        }
        for p in &self.points3d {
            for &(image_id, idx) in &p.track {
                let ok = self.image(image_id).is_some_and(|i| {
                    i.points2d
                        .get(idx as usize)
                        .is_some_and(|q| q.point3d_id == p.point3d_id)
                });
                if !ok {
                    return Err(invalid(format!(
                        "the track of 3D point {} has 2D point {idx} of image {image_id}, \
                         which does not observe it",
                        p.point3d_id
                    )));
                }
            }
        }
        for f in &self.frames {
            if self
                .rigs
                .binary_search_by_key(&f.rig_id, |r| r.rig_id)
                .is_err()
            {
                return Err(invalid(format!(
                    "frame {} has rig {}, which the model does not hold",
                    f.frame_id, f.rig_id
                )));
            }
        }
        Ok(())
    }
}

/// A pose from COLMAP's `QW QX QY QZ TX TY TZ`, or `None` when a value is not finite or the
/// quaternion is not a unit (within [`UNIT_QUATERNION_TOLERANCE`]; beyond rounding it is
/// normalized).
pub(crate) fn pose(v: [f64; 7]) -> Option<Isometry3<f64>> {
    if v.iter().any(|x| !x.is_finite()) {
        return None;
    }
    let q = Quaternion::new(v[0], v[1], v[2], v[3]);
    if (q.norm() - 1.0).abs() > UNIT_QUATERNION_TOLERANCE {
        return None;
    }
    // A quaternion that is a unit to rounding is kept as written, so that a model reads and
    // writes back bit for bit; others are normalized.
    let rotation = if (q.norm() - 1.0).abs() <= 4.0 * f64::EPSILON {
        UnitQuaternion::new_unchecked(q)
    } else {
        UnitQuaternion::from_quaternion(q)
    };
    Some(Isometry3::from_parts(
        Translation3::new(v[4], v[5], v[6]),
        rotation,
    ))
}

/// COLMAP's `QW QX QY QZ TX TY TZ` of a pose.
pub(crate) fn pose_values(p: &Isometry3<f64>) -> [f64; 7] {
    let q = p.rotation.quaternion();
    let t = p.translation.vector;
    [q.w, q.i, q.j, q.k, t.x, t.y, t.z]
}

/// Reads the sparse model in `dir`: binary when it holds `cameras.bin`, else text
/// (`cameras.txt`); `rigs` and `frames` files are read where present. The model is checked
/// ([`ColmapModel::check`]).
///
/// # Errors
/// [`ColmapError::NotAModel`] when the folder holds neither, else the reader's errors:
/// [`ColmapError::Truncated`], [`ColmapError::BadCount`], [`ColmapError::Parse`],
/// [`ColmapError::UnknownCameraModel`], [`ColmapError::Invalid`], [`ColmapError::Io`].
pub fn read_model(dir: impl AsRef<Path>) -> Result<ColmapModel> {
    let dir = dir.as_ref();
    let mut model = if dir.join("cameras.bin").exists() {
        binary::read_model_binary(dir)?
    } else if dir.join("cameras.txt").exists() {
        text::read_model_text(dir)?
    } else {
        return Err(ColmapError::NotAModel {
            dir: dir.to_owned(),
        });
    };
    model.check(dir)?;
    Ok(model)
}

/// The two encodings of a sparse model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelFormat {
    /// `*.txt` ([`super::model_to_text`]).
    Text,
    /// `*.bin` ([`super::model_to_binary`]), COLMAP's default.
    Binary,
}

/// Writes `model` into `dir` (the five files of `format`), all or nothing
/// ([`crate::data::io::StagedFiles`]); returns the paths written.
///
/// # Errors
/// [`ColmapError::Output`] when a file cannot be written (nothing is then left).
pub fn write_model(
    dir: impl AsRef<Path>,
    model: &ColmapModel,
    format: ModelFormat,
) -> Result<Vec<std::path::PathBuf>> {
    let dir = dir.as_ref();
    let files: Vec<(&str, Vec<u8>)> = match format {
        ModelFormat::Text => text::model_to_text(model)
            .into_iter()
            .map(|(n, t)| (n, t.into_bytes()))
            .collect(),
        ModelFormat::Binary => binary::model_to_binary(model),
    };
    let mut staged = crate::data::io::StagedFiles::new(dir)?;
    for (name, bytes) in files {
        staged.stage(dir.join(name), &bytes)?;
    }
    Ok(staged.commit()?)
}
