//! COLMAP's binary sparse model (`cameras.bin`, `images.bin`, `points3D.bin`, and
//! `rigs.bin`, `frames.bin` since COLMAP 3.12), read and written after the documented layout
//! (<https://colmap.github.io/format.html>, "Binary File Format": little-endian, the text
//! format's fields in binary):
//!
//! - `cameras.bin`: `u64` count; per camera `u32` id, `i32` model id, `u64` width, `u64`
//!   height, the model's `f64` parameters.
//! - `images.bin`: `u64` count; per image `u32` id, `f64` `qw qx qy qz tx ty tz`
//!   (`cam_from_world`), `u32` camera id, the name as NUL-terminated bytes, `u64` number of
//!   2D points, per 2D point `f64 x, f64 y, u64 point3D_id` (`u64::MAX`: none).
//! - `points3D.bin`: `u64` count; per point `u64` id, `f64 x y z`, `u8 r g b`, `f64` error,
//!   `u64` track length, per element `u32` image id, `u32` 2D point index.
//! - `rigs.bin`: `u64` count; per rig `u32` id, `u32` number of sensors, the reference sensor
//!   as `i32` type, `u32` id; per other sensor `i32` type, `u32` id, `u8` has-pose flag, and
//!   when set `f64` `qw qx qy qz tx ty tz` (`sensor_from_rig`).
//! - `frames.bin`: `u64` count; per frame `u32` id, `u32` rig id, `f64` `qw qx qy qz tx ty tz`
//!   (`rig_from_world`), `u32` number of data, per datum `i32` sensor type, `u32` sensor id,
//!   `u64` data id.
//!
//! Every count is checked against the bytes that remain before anything is allocated by it
//! ([`ColmapError::BadCount`]); a file that ends inside a record is
//! [`ColmapError::Truncated`]; bytes after the last record are [`ColmapError::TrailingBytes`].

use std::path::{Path, PathBuf};

use nalgebra::{Point3, Vector2};

use super::camera::{ColmapCamera, ColmapCameraModel};
use super::error::{ColmapError, Result};
use super::model::{
    ColmapFrame, ColmapImage, ColmapModel, ColmapPoint2D, ColmapPoint3D, ColmapRig, Sensor,
    SensorKind, pose,
};
use crate::data::io::MAX_BINARY_INPUT_BYTES;

/// A bounds-checked little-endian reader over one file's bytes.
struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
    path: &'a Path,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len());
        let Some(end) = end else {
            return Err(ColmapError::Truncated {
                path: self.path.to_owned(),
                what: what.to_owned(),
                offset: self.pos as u64,
                len: self.bytes.len() as u64,
            });
        };
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N]> {
        let mut a = [0; N];
        a.copy_from_slice(self.take(N, what)?);
        Ok(a)
    }

    fn u8(&mut self, what: &str) -> Result<u8> {
        Ok(self.array::<1>(what)?[0])
    }

    fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }

    fn i32(&mut self, what: &str) -> Result<i32> {
        Ok(i32::from_le_bytes(self.array(what)?))
    }

    fn u64(&mut self, what: &str) -> Result<u64> {
        Ok(u64::from_le_bytes(self.array(what)?))
    }

    fn f64(&mut self, what: &str) -> Result<f64> {
        Ok(f64::from_le_bytes(self.array(what)?))
    }

    fn f64s<const N: usize>(&mut self, what: &str) -> Result<[f64; N]> {
        let mut v = [0.0; N];
        for x in &mut v {
            *x = self.f64(what)?;
        }
        Ok(v)
    }

    /// A count of records of at least `min_size` bytes each, checked against what remains.
    fn count(&mut self, min_size: u64, what: &str) -> Result<usize> {
        let offset = self.pos as u64;
        let count = self.u64(what)?;
        self.check_count(count, offset, min_size, what)
    }

    fn count_u32(&mut self, min_size: u64, what: &str) -> Result<usize> {
        let offset = self.pos as u64;
        let count = u64::from(self.u32(what)?);
        self.check_count(count, offset, min_size, what)
    }

    fn check_count(&self, count: u64, offset: u64, min_size: u64, what: &str) -> Result<usize> {
        let remaining = (self.bytes.len() - self.pos) as u64;
        let needed = count.saturating_mul(min_size);
        if needed > remaining {
            return Err(ColmapError::BadCount {
                path: self.path.to_owned(),
                what: what.to_owned(),
                count,
                offset,
                needed,
                remaining,
            });
        }
        // needed <= remaining <= usize::MAX, so the count fits.
        Ok(count as usize)
    }

    fn invalid(&self, what: String) -> ColmapError {
        ColmapError::Invalid {
            path: self.path.to_owned(),
            what,
        }
    }

    fn pose(&mut self, what: &str) -> Result<nalgebra::Isometry3<f64>> {
        let at = self.pos;
        let v = self.f64s::<7>(what)?;
        pose(v).ok_or_else(|| {
            self.invalid(format!(
                "{what} at byte {at}: not a pose (a non-finite value or a quaternion that is \
                 not a unit)"
            ))
        })
    }

    fn sensor(&mut self, what: &str) -> Result<Sensor> {
        let code = self.i32(what)?;
        let id = self.u32(what)?;
        let kind = SensorKind::from_code(i64::from(code))
            .ok_or_else(|| self.invalid(format!("{what}: unknown sensor type {code}")))?;
        Ok(Sensor { kind, id })
    }

    fn finish(&self) -> Result<()> {
        let extra = (self.bytes.len() - self.pos) as u64;
        if extra > 0 {
            return Err(ColmapError::TrailingBytes {
                path: self.path.to_owned(),
                extra,
            });
        }
        Ok(())
    }
}

fn read(path: &Path) -> Result<Vec<u8>> {
    Ok(ibc_camera_models::io::read_bytes(
        path,
        MAX_BINARY_INPUT_BYTES,
    )?)
}

/// Reads `dir`'s binary model (not yet checked: [`super::read_model`] checks it).
pub(crate) fn read_model_binary(dir: &Path) -> Result<ColmapModel> {
    let file = |name: &str| -> PathBuf { dir.join(name) };
    let cameras = cameras_from_bytes(&read(&file("cameras.bin"))?, &file("cameras.bin"))?;
    let images = images_from_bytes(&read(&file("images.bin"))?, &file("images.bin"))?;
    let points3d = points_from_bytes(&read(&file("points3D.bin"))?, &file("points3D.bin"))?;
    let rigs = if file("rigs.bin").exists() {
        rigs_from_bytes(&read(&file("rigs.bin"))?, &file("rigs.bin"))?
    } else {
        Vec::new()
    };
    let frames = if file("frames.bin").exists() {
        frames_from_bytes(&read(&file("frames.bin"))?, &file("frames.bin"))?
    } else {
        Vec::new()
    };
    Ok(ColmapModel {
        cameras,
        images,
        points3d,
        rigs,
        frames,
    })
}

/// Parses `cameras.bin`; `path` names it in errors.
///
/// # Errors
/// See the module docs; [`ColmapError::UnknownCameraModel`] for a model id COLMAP does not
/// define.
pub fn cameras_from_bytes(bytes: &[u8], path: &Path) -> Result<Vec<ColmapCamera>> {
    let mut c = Cursor {
        bytes,
        pos: 0,
        path,
    };
    // id, model, width, height and at least 2 parameters.
    let n = c.count(4 + 4 + 8 + 8 + 16, "cameras")?;
    let mut cameras = Vec::with_capacity(n);
    for _ in 0..n {
        let camera_id = c.u32("a camera id")?;
        let code = c.i32("a camera model")?;
        let model = ColmapCameraModel::from_id(i64::from(code)).ok_or_else(|| {
            ColmapError::UnknownCameraModel {
                path: path.to_owned(),
                camera_id,
                model: format!("id {code}"),
            }
        })?;
        let width = c.u64("a camera's width")?;
        let height = c.u64("a camera's height")?;
        let mut params = Vec::with_capacity(model.num_params());
        for _ in 0..model.num_params() {
            params.push(c.f64("a camera's parameters")?);
        }
        cameras.push(ColmapCamera {
            camera_id,
            model,
            width,
            height,
            params,
        });
    }
    c.finish()?;
    Ok(cameras)
}

/// Parses `images.bin`; `path` names it in errors.
///
/// # Errors
/// See the module docs.
pub fn images_from_bytes(bytes: &[u8], path: &Path) -> Result<Vec<ColmapImage>> {
    let mut c = Cursor {
        bytes,
        pos: 0,
        path,
    };
    // id, pose, camera id, an empty name's NUL, the 2D point count.
    let n = c.count(4 + 56 + 4 + 1 + 8, "images")?;
    let mut images = Vec::with_capacity(n);
    for _ in 0..n {
        let image_id = c.u32("an image id")?;
        let cam_from_world = c.pose("an image's pose")?;
        let camera_id = c.u32("an image's camera id")?;
        let rest = &c.bytes[c.pos..];
        let Some(len) = rest.iter().position(|&b| b == 0) else {
            return Err(ColmapError::Truncated {
                path: path.to_owned(),
                what: "an image's name".to_owned(),
                offset: bytes.len() as u64,
                len: bytes.len() as u64,
            });
        };
        let name = String::from_utf8(rest[..len].to_vec())
            .map_err(|_| c.invalid(format!("image {image_id}: its name is not UTF-8")))?;
        c.pos += len + 1;
        let m = c.count(24, "2D points")?;
        let mut points2d = Vec::with_capacity(m);
        for _ in 0..m {
            let x = c.f64("a 2D point")?;
            let y = c.f64("a 2D point")?;
            let point3d_id = c.u64("a 2D point")?;
            points2d.push(ColmapPoint2D {
                xy: Vector2::new(x, y),
                point3d_id,
            });
        }
        images.push(ColmapImage {
            image_id,
            name,
            camera_id,
            cam_from_world,
            points2d,
        });
    }
    c.finish()?;
    Ok(images)
}

/// Parses `points3D.bin`; `path` names it in errors.
///
/// # Errors
/// See the module docs.
pub fn points_from_bytes(bytes: &[u8], path: &Path) -> Result<Vec<ColmapPoint3D>> {
    let mut c = Cursor {
        bytes,
        pos: 0,
        path,
    };
    let n = c.count(8 + 24 + 3 + 8 + 8, "3D points")?;
    let mut points = Vec::with_capacity(n);
    for _ in 0..n {
        let point3d_id = c.u64("a 3D point id")?;
        let [x, y, z] = c.f64s::<3>("a 3D point")?;
        let color = c.array::<3>("a 3D point's colour")?;
        let error = c.f64("a 3D point's error")?;
        let m = c.count(8, "track elements")?;
        let mut track = Vec::with_capacity(m);
        for _ in 0..m {
            track.push((c.u32("a track element")?, c.u32("a track element")?));
        }
        if ![x, y, z].iter().all(|v| v.is_finite()) {
            return Err(c.invalid(format!("3D point {point3d_id} is not finite")));
        }
        points.push(ColmapPoint3D {
            point3d_id,
            xyz: Point3::new(x, y, z),
            color,
            error,
            track,
        });
    }
    c.finish()?;
    Ok(points)
}

/// Parses `rigs.bin`; `path` names it in errors.
///
/// # Errors
/// See the module docs.
pub fn rigs_from_bytes(bytes: &[u8], path: &Path) -> Result<Vec<ColmapRig>> {
    let mut c = Cursor {
        bytes,
        pos: 0,
        path,
    };
    let n = c.count(4 + 4 + 8, "rigs")?;
    let mut rigs = Vec::with_capacity(n);
    for _ in 0..n {
        let rig_id = c.u32("a rig id")?;
        // The reference sensor's 8 bytes, then at least 9 for each other one.
        let sensors = c.count_u32(8, "rig sensors")?;
        if sensors == 0 {
            return Err(c.invalid(format!("rig {rig_id} has no sensor")));
        }
        let ref_sensor = c.sensor("a rig's reference sensor")?;
        let mut others = Vec::with_capacity(sensors - 1);
        for _ in 1..sensors {
            let sensor = c.sensor("a rig's sensor")?;
            let pose = match c.u8("a rig sensor's pose flag")? {
                0 => None,
                1 => Some(c.pose("a rig's sensor_from_rig")?),
                f => return Err(c.invalid(format!("rig {rig_id}: pose flag {f} (not 0 or 1)"))),
            };
            others.push((sensor, pose));
        }
        rigs.push(ColmapRig {
            rig_id,
            ref_sensor,
            sensors: others,
        });
    }
    c.finish()?;
    Ok(rigs)
}

/// Parses `frames.bin`; `path` names it in errors.
///
/// # Errors
/// See the module docs.
pub fn frames_from_bytes(bytes: &[u8], path: &Path) -> Result<Vec<ColmapFrame>> {
    let mut c = Cursor {
        bytes,
        pos: 0,
        path,
    };
    let n = c.count(4 + 4 + 56 + 4, "frames")?;
    let mut frames = Vec::with_capacity(n);
    for _ in 0..n {
        let frame_id = c.u32("a frame id")?;
        let rig_id = c.u32("a frame's rig id")?;
        let rig_from_world = c.pose("a frame's rig_from_world")?;
        let m = c.count_u32(16, "frame data")?;
        let mut data = Vec::with_capacity(m);
        for _ in 0..m {
            let sensor = c.sensor("a frame's datum")?;
            data.push((sensor, c.u64("a frame's datum")?));
        }
        frames.push(ColmapFrame {
            frame_id,
            rig_id,
            rig_from_world,
            data,
        });
    }
    c.finish()?;
    Ok(frames)
}

fn pose_bytes(out: &mut Vec<u8>, p: &nalgebra::Isometry3<f64>) {
    for v in super::model::pose_values(p) {
        out.extend(v.to_le_bytes());
    }
}

fn len_u32(n: usize) -> u32 {
    // Counts past u32 cannot come from a model COLMAP reads; saturate rather than wrap.
    u32::try_from(n).unwrap_or(u32::MAX)
}

/// The five binary files of a model, in the layout of the module docs: `(file name, bytes)`.
pub fn model_to_binary(model: &ColmapModel) -> Vec<(&'static str, Vec<u8>)> {
    let mut cameras = (model.cameras.len() as u64).to_le_bytes().to_vec();
    for c in &model.cameras {
        cameras.extend(c.camera_id.to_le_bytes());
        cameras.extend(c.model.id().to_le_bytes());
        cameras.extend(c.width.to_le_bytes());
        cameras.extend(c.height.to_le_bytes());
        for p in &c.params {
            cameras.extend(p.to_le_bytes());
        }
    }
    let mut images = (model.images.len() as u64).to_le_bytes().to_vec();
    for i in &model.images {
        images.extend(i.image_id.to_le_bytes());
        pose_bytes(&mut images, &i.cam_from_world);
        images.extend(i.camera_id.to_le_bytes());
        images.extend(i.name.as_bytes());
        images.push(0);
        images.extend((i.points2d.len() as u64).to_le_bytes());
        for p in &i.points2d {
            images.extend(p.xy.x.to_le_bytes());
            images.extend(p.xy.y.to_le_bytes());
            images.extend(p.point3d_id.to_le_bytes());
        }
    }
    let mut points = (model.points3d.len() as u64).to_le_bytes().to_vec();
    for p in &model.points3d {
        points.extend(p.point3d_id.to_le_bytes());
        for v in [p.xyz.x, p.xyz.y, p.xyz.z] {
            points.extend(v.to_le_bytes());
        }
        points.extend(p.color);
        points.extend(p.error.to_le_bytes());
        points.extend((p.track.len() as u64).to_le_bytes());
        for (image, idx) in &p.track {
            points.extend(image.to_le_bytes());
            points.extend(idx.to_le_bytes());
        }
    }
    let mut rigs = (model.rigs.len() as u64).to_le_bytes().to_vec();
    for r in &model.rigs {
        rigs.extend(r.rig_id.to_le_bytes());
        rigs.extend(len_u32(r.sensors.len() + 1).to_le_bytes());
        rigs.extend(r.ref_sensor.kind.code().to_le_bytes());
        rigs.extend(r.ref_sensor.id.to_le_bytes());
        for (s, pose) in &r.sensors {
            rigs.extend(s.kind.code().to_le_bytes());
            rigs.extend(s.id.to_le_bytes());
            match pose {
                Some(p) => {
                    rigs.push(1);
                    pose_bytes(&mut rigs, p);
                }
                None => rigs.push(0),
            }
        }
    }
    let mut frames = (model.frames.len() as u64).to_le_bytes().to_vec();
    for f in &model.frames {
        frames.extend(f.frame_id.to_le_bytes());
        frames.extend(f.rig_id.to_le_bytes());
        pose_bytes(&mut frames, &f.rig_from_world);
        frames.extend(len_u32(f.data.len()).to_le_bytes());
        for (s, data) in &f.data {
            frames.extend(s.kind.code().to_le_bytes());
            frames.extend(s.id.to_le_bytes());
            frames.extend(data.to_le_bytes());
        }
    }
    vec![
        ("cameras.bin", cameras),
        ("images.bin", images),
        ("points3D.bin", points),
        ("rigs.bin", rigs),
        ("frames.bin", frames),
    ]
}
