//! COLMAP's database, an SQLite file, read and written after its documented schema
//! (<https://colmap.github.io/database.html>):
//!
//! - `cameras(camera_id, model, width, height, params, prior_focal_length)`: `params` a blob
//!   of the model's `f64` parameters (COLMAP's order and pixel convention);
//! - `images(image_id, name, camera_id)`;
//! - `keypoints(image_id, rows, cols, data)`: `rows x cols` `f32`, row-major; the first two
//!   columns are `x, y` (COLMAP's pixel centres at `+0.5`), the others the affine shape
//!   (`cols` is 2, 4 or 6);
//! - `descriptors(image_id, [type,] rows, cols, data)`: `rows x cols` `u8`, row-major; SIFT
//!   descriptors are 128 bytes; the `type` column (COLMAP 3.13+: 0 SIFT, -1 undefined) is
//!   absent from older databases;
//! - `rigs(rig_id, ref_sensor_id, ref_sensor_type)`, `rig_sensors(rig_id, sensor_id,
//!   sensor_type, sensor_from_rig)` (the non-reference sensors; the pose a blob of 7 `f64`,
//!   `qw qx qy qz tx ty tz`, or NULL), `frames(frame_id, rig_id)` and `frame_data(frame_id,
//!   data_id, sensor_id, sensor_type)`, since COLMAP 3.12 (absent from older databases).
//!
//! Integers and floats in blobs are little-endian (COLMAP writes the machine's order, which is
//! little-endian on every platform it supports). The database is opened read-only after
//! `ibc_camera_models::io` has confirmed it is a regular file within the size bound; a blob
//! whose length is not `rows x cols` of its type is [`ColmapError::BadFeatures`].

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use ibc_camera_models::io::IoError;
use ibc_vocab_tree::{Descriptor, DescriptorKind};
use nalgebra::Vector2;
use rusqlite::{Connection, OpenFlags, OptionalExtension, params};

use super::camera::{ColmapCamera, ColmapCameraModel, PIXEL_SHIFT};
use super::error::{ColmapError, Result};
use super::model::{ColmapRig, Sensor, SensorKind, pose, pose_values};
use crate::data::ImageFeatures;
use crate::data::io::{DescriptorLayout, MAX_BINARY_INPUT_BYTES};

/// COLMAP's descriptor type code of SIFT.
pub const SIFT_TYPE: i64 = 0;

/// COLMAP's descriptor type code of descriptors it does not know (how ibc writes binary
/// descriptors).
pub const UNDEFINED_TYPE: i64 = -1;

/// An ibc descriptor type that COLMAP's `descriptors` table holds: `COLS` bytes per row.
///
/// SIFT's 128 bytes are read into `[f32; 128]`, the vocabulary tree's float path (each byte
/// its value as a float, exactly); written back rounded and clamped to `0..=255`. Binary
/// descriptors `[u64; W]` are their `8 W` bytes (`ibc_vocab_tree::binary_to_bytes`), written
/// with COLMAP's type "undefined".
pub trait ColmapDescriptor: Descriptor {
    /// Bytes per descriptor in the table.
    const COLS: usize;
    /// The type code written.
    const TYPE: i64;
    /// What the type takes, for messages.
    const DESCRIPTION: &'static str;
    /// The descriptor of a row of `COLS` bytes.
    fn from_row(row: &[u8]) -> Self;
    /// Appends the descriptor's `COLS` bytes.
    fn to_row(&self, out: &mut Vec<u8>);
}

impl ColmapDescriptor for [f32; 128] {
    const COLS: usize = 128;
    const TYPE: i64 = SIFT_TYPE;
    const DESCRIPTION: &'static str = "128-byte SIFT descriptors (float path)";

    fn from_row(row: &[u8]) -> Self {
        let mut d = [0.0; 128];
        for (x, &b) in d.iter_mut().zip(row) {
            *x = f32::from(b);
        }
        d
    }

    fn to_row(&self, out: &mut Vec<u8>) {
        // Rounded and clamped into a byte, as the cast saturates.
        out.extend(self.iter().map(|&x| x.round().clamp(0.0, 255.0) as u8));
    }
}

impl<const W: usize> ColmapDescriptor for [u64; W] {
    const COLS: usize = 8 * W;
    const TYPE: i64 = UNDEFINED_TYPE;
    const DESCRIPTION: &'static str = "binary descriptors";

    fn from_row(row: &[u8]) -> Self {
        <Self as Descriptor>::read_le(row)
    }

    fn to_row(&self, out: &mut Vec<u8>) {
        self.write_le(out);
    }
}

/// An image of the database.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DatabaseImage {
    /// COLMAP's image id.
    pub image_id: u32,
    /// The image's name (its path relative to the image folder).
    pub name: String,
    /// Its camera.
    pub camera_id: u32,
}

/// A frame of the database (no pose: the database holds none).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DatabaseFrame {
    /// COLMAP's frame id.
    pub frame_id: u32,
    /// Its rig.
    pub rig_id: u32,
    /// Its data: the sensor and the data id (an image id for a camera).
    pub data: Vec<(Sensor, u64)>,
}

/// An open COLMAP database (read-only).
pub struct ColmapDatabase {
    path: PathBuf,
    connection: Connection,
}

impl std::fmt::Debug for ColmapDatabase {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ColmapDatabase")
            .field("path", &self.path)
            .finish_non_exhaustive()
    }
}

fn blob_len_error(
    path: &Path,
    image: &str,
    what: &str,
    rows: i64,
    cols: i64,
    len: usize,
) -> ColmapError {
    ColmapError::BadFeatures {
        path: path.to_owned(),
        image: image.to_owned(),
        what: format!(
            "its {what} blob has {len} bytes, not the {rows} x {cols} of its rows and columns"
        ),
    }
}

impl ColmapDatabase {
    /// Opens the database at `path` read-only.
    ///
    /// # Errors
    /// [`ColmapError::Io`] when it is not a regular file or is past the size bound,
    /// [`ColmapError::Database`] when SQLite cannot open it or it has no `images` table.
    pub fn open(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref().to_owned();
        let (_, len) = ibc_camera_models::io::open_regular(&path)?;
        if len > MAX_BINARY_INPUT_BYTES {
            return Err(IoError::TooLarge {
                path,
                size: len,
                limit: MAX_BINARY_INPUT_BYTES,
            }
            .into());
        }
        let connection = Connection::open_with_flags(
            &path,
            OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .map_err(|source| ColmapError::Database {
            path: path.clone(),
            source,
        })?;
        let db = Self { path, connection };
        // A file that is not SQLite, or SQLite without COLMAP's tables, fails here.
        db.connection
            .prepare("SELECT image_id, name, camera_id FROM images LIMIT 1")
            .map_err(|source| db.sql(source))?;
        Ok(db)
    }

    /// The database's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn sql(&self, source: rusqlite::Error) -> ColmapError {
        ColmapError::Database {
            path: self.path.clone(),
            source,
        }
    }

    fn invalid(&self, what: String) -> ColmapError {
        ColmapError::Invalid {
            path: self.path.clone(),
            what,
        }
    }

    fn has_table(&self, table: &str) -> Result<bool> {
        self.connection
            .query_row(
                "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = ?1",
                [table],
                |r| r.get::<_, i64>(0),
            )
            .map(|n| n > 0)
            .map_err(|e| self.sql(e))
    }

    /// Every row of `query` (no parameters), each read by `row`; SQLite's errors name the
    /// database.
    fn rows<T>(
        &self,
        query: &str,
        row: impl FnMut(&rusqlite::Row<'_>) -> rusqlite::Result<T>,
    ) -> Result<Vec<T>> {
        let mut stmt = self.connection.prepare(query).map_err(|e| self.sql(e))?;
        let rows = stmt.query_map([], row).map_err(|e| self.sql(e))?;
        rows.collect::<rusqlite::Result<Vec<T>>>()
            .map_err(|e| self.sql(e))
    }

    fn has_column(&self, table: &str, column: &str) -> Result<bool> {
        let names = self.rows(&format!("PRAGMA table_info({table})"), |r| {
            r.get::<_, String>(1)
        })?;
        Ok(names.iter().any(|n| n == column))
    }

    fn id(&self, v: i64, what: &str) -> Result<u32> {
        u32::try_from(v).map_err(|_| self.invalid(format!("{what} {v} is not a valid id")))
    }

    /// The cameras, by id.
    ///
    /// # Errors
    /// [`ColmapError::Database`], [`ColmapError::UnknownCameraModel`], [`ColmapError::Invalid`]
    /// for a parameter blob of the wrong length.
    pub fn cameras(&self) -> Result<Vec<ColmapCamera>> {
        let rows = self.rows(
            "SELECT camera_id, model, width, height, params FROM cameras ORDER BY camera_id",
            |r| {
                Ok((
                    r.get::<_, i64>(0)?,
                    r.get::<_, i64>(1)?,
                    r.get::<_, i64>(2)?,
                    r.get::<_, i64>(3)?,
                    r.get::<_, Option<Vec<u8>>>(4)?,
                ))
            },
        )?;
        let mut cameras = Vec::new();
        for (id, code, width, height, blob) in rows {
            let camera_id = self.id(id, "camera id")?;
            let model = ColmapCameraModel::from_id(code).ok_or_else(|| {
                ColmapError::UnknownCameraModel {
                    path: self.path.clone(),
                    camera_id,
                    model: format!("id {code}"),
                }
            })?;
            let blob = blob.unwrap_or_default();
            if blob.len() != 8 * model.num_params() {
                return Err(self.invalid(format!(
                    "camera {camera_id}: {} bytes of parameters, not the {} of {}",
                    blob.len(),
                    8 * model.num_params(),
                    model.name()
                )));
            }
            let size = |v: i64| {
                u64::try_from(v).map_err(|_| self.invalid(format!("camera {camera_id}: size {v}")))
            };
            cameras.push(ColmapCamera {
                camera_id,
                model,
                width: size(width)?,
                height: size(height)?,
                params: blob.chunks_exact(8).map(f64_le).collect(),
            });
        }
        Ok(cameras)
    }

    /// The images, by id.
    ///
    /// # Errors
    /// [`ColmapError::Database`], [`ColmapError::Invalid`] for an id out of range.
    pub fn images(&self) -> Result<Vec<DatabaseImage>> {
        let rows = self.rows(
            "SELECT image_id, name, camera_id FROM images ORDER BY image_id",
            |r| {
                Ok((
                    r.get::<_, i64>(0)?,
                    r.get::<_, String>(1)?,
                    r.get::<_, i64>(2)?,
                ))
            },
        )?;
        let mut images = Vec::new();
        for (id, name, camera) in rows {
            images.push(DatabaseImage {
                image_id: self.id(id, "image id")?,
                name,
                camera_id: self.id(camera, "camera id")?,
            });
        }
        Ok(images)
    }

    /// The rigs (empty for a database older than COLMAP 3.12).
    ///
    /// # Errors
    /// [`ColmapError::Database`], [`ColmapError::Invalid`] for an unknown sensor type or a
    /// pose blob that is not 7 `f64` of a unit quaternion and a translation.
    pub fn rigs(&self) -> Result<Vec<ColmapRig>> {
        if !self.has_table("rigs")? || !self.has_table("rig_sensors")? {
            return Ok(Vec::new());
        }
        let mut rigs = Vec::new();
        let rows = self.rows(
            "SELECT rig_id, ref_sensor_id, ref_sensor_type FROM rigs ORDER BY rig_id",
            |r| {
                Ok((
                    r.get::<_, i64>(0)?,
                    r.get::<_, i64>(1)?,
                    r.get::<_, i64>(2)?,
                ))
            },
        )?;
        for (rig, id, kind) in rows {
            rigs.push(ColmapRig {
                rig_id: self.id(rig, "rig id")?,
                ref_sensor: self.sensor(kind, id)?,
                sensors: Vec::new(),
            });
        }
        let rows = self.rows(
            "SELECT rig_id, sensor_id, sensor_type, sensor_from_rig FROM rig_sensors \
             ORDER BY rig_id, sensor_type, sensor_id",
            |r| {
                Ok((
                    r.get::<_, i64>(0)?,
                    r.get::<_, i64>(1)?,
                    r.get::<_, i64>(2)?,
                    r.get::<_, Option<Vec<u8>>>(3)?,
                ))
            },
        )?;
        for (rig_id, id, kind, blob) in rows {
            let sensor = self.sensor(kind, id)?;
            let pose = match blob {
                None => None,
                Some(b) => {
                    let values: Vec<f64> = b.chunks_exact(8).map(f64_le).collect();
                    let v: Option<[f64; 7]> = (b.len() == 56).then(|| {
                        let mut a = [0.0; 7];
                        a.copy_from_slice(&values);
                        a
                    });
                    Some(v.and_then(pose).ok_or_else(|| {
                        self.invalid(format!(
                            "rig {rig_id}: the sensor_from_rig of sensor {id} is not a pose"
                        ))
                    })?)
                }
            };
            let rig = rigs
                .iter_mut()
                .find(|r| i64::from(r.rig_id) == rig_id)
                .ok_or_else(|| {
                    self.invalid(format!(
                        "rig_sensors names rig {rig_id}, which rigs does not hold"
                    ))
                })?;
            rig.sensors.push((sensor, pose));
        }
        Ok(rigs)
    }

    fn sensor(&self, kind: i64, id: i64) -> Result<Sensor> {
        let kind = SensorKind::from_code(kind)
            .ok_or_else(|| self.invalid(format!("unknown sensor type {kind}")))?;
        Ok(Sensor {
            kind,
            id: self.id(id, "sensor id")?,
        })
    }

    /// The frames, by id (empty for a database older than COLMAP 3.12).
    ///
    /// # Errors
    /// [`ColmapError::Database`], [`ColmapError::Invalid`].
    pub fn frames(&self) -> Result<Vec<DatabaseFrame>> {
        if !self.has_table("frames")? || !self.has_table("frame_data")? {
            return Ok(Vec::new());
        }
        let mut frames = Vec::new();
        let mut index = HashMap::new();
        let rows = self.rows(
            "SELECT frame_id, rig_id FROM frames ORDER BY frame_id",
            |r| Ok((r.get::<_, i64>(0)?, r.get::<_, i64>(1)?)),
        )?;
        for (frame, rig) in rows {
            index.insert(frame, frames.len());
            frames.push(DatabaseFrame {
                frame_id: self.id(frame, "frame id")?,
                rig_id: self.id(rig, "rig id")?,
                data: Vec::new(),
            });
        }
        let rows = self.rows(
            "SELECT frame_id, data_id, sensor_id, sensor_type FROM frame_data \
             ORDER BY frame_id, sensor_type, sensor_id",
            |r| {
                Ok((
                    r.get::<_, i64>(0)?,
                    r.get::<_, i64>(1)?,
                    r.get::<_, i64>(2)?,
                    r.get::<_, i64>(3)?,
                ))
            },
        )?;
        for (frame, data, id, kind) in rows {
            let sensor = self.sensor(kind, id)?;
            let data = u64::try_from(data).map_err(|_| self.invalid(format!("data id {data}")))?;
            let &i = index.get(&frame).ok_or_else(|| {
                self.invalid(format!(
                    "frame_data names frame {frame}, which frames does not hold"
                ))
            })?;
            frames[i].data.push((sensor, data));
        }
        Ok(frames)
    }

    /// The keypoints of `image`, in ibc's pixel convention (COLMAP's `x, y` less 0.5).
    ///
    /// # Errors
    /// [`ColmapError::MissingFeatures`] when the image has none in the table,
    /// [`ColmapError::BadFeatures`] for a blob of the wrong size or a non-finite keypoint.
    pub fn keypoints(&self, image: &DatabaseImage) -> Result<Vec<Vector2<f64>>> {
        let row = self
            .connection
            .query_row(
                "SELECT rows, cols, data FROM keypoints WHERE image_id = ?1",
                [image.image_id],
                |r| {
                    Ok((
                        r.get::<_, i64>(0)?,
                        r.get::<_, i64>(1)?,
                        r.get::<_, Option<Vec<u8>>>(2)?,
                    ))
                },
            )
            .optional()
            .map_err(|e| self.sql(e))?;
        let Some((rows, cols, data)) = row else {
            return Err(self.missing(image, "keypoints"));
        };
        let data = data.unwrap_or_default();
        let bad = || blob_len_error(&self.path, &image.name, "keypoints", rows, cols, data.len());
        let (r, c) = match (usize::try_from(rows), usize::try_from(cols)) {
            (Ok(r), Ok(c)) if c >= 2 => (r, c),
            _ => return Err(bad()),
        };
        if r.checked_mul(c).and_then(|n| n.checked_mul(4)) != Some(data.len()) {
            return Err(bad());
        }
        let mut keypoints = Vec::with_capacity(r);
        for row in data.chunks_exact(4 * c) {
            let x = f32::from_le_bytes([row[0], row[1], row[2], row[3]]);
            let y = f32::from_le_bytes([row[4], row[5], row[6], row[7]]);
            if !(x.is_finite() && y.is_finite()) {
                return Err(ColmapError::BadFeatures {
                    path: self.path.clone(),
                    image: image.name.clone(),
                    what: format!("keypoint {} is not finite", keypoints.len()),
                });
            }
            keypoints.push(Vector2::new(
                f64::from(x) - PIXEL_SHIFT,
                f64::from(y) - PIXEL_SHIFT,
            ));
        }
        Ok(keypoints)
    }

    fn missing(&self, image: &DatabaseImage, what: &'static str) -> ColmapError {
        ColmapError::MissingFeatures {
            path: self.path.clone(),
            image: image.name.clone(),
            what,
        }
    }

    /// The descriptors of `image` as `D`.
    ///
    /// # Errors
    /// [`ColmapError::MissingFeatures`] when the image has none in the table (or the
    /// database has no descriptor table), [`ColmapError::DescriptorMismatch`] when they are
    /// not of `D`'s kind and width, [`ColmapError::BadFeatures`] for a blob of the wrong size.
    pub fn descriptors<D: ColmapDescriptor>(&self, image: &DatabaseImage) -> Result<Vec<D>> {
        if !self.has_table("descriptors")? {
            return Err(self.missing(image, "descriptors"));
        }
        let typed = self.has_column("descriptors", "type")?;
        let sql = if typed {
            "SELECT type, rows, cols, data FROM descriptors WHERE image_id = ?1"
        } else {
            "SELECT 0, rows, cols, data FROM descriptors WHERE image_id = ?1"
        };
        let row = self
            .connection
            .query_row(sql, [image.image_id], |r| {
                Ok((
                    r.get::<_, i64>(0)?,
                    r.get::<_, i64>(1)?,
                    r.get::<_, i64>(2)?,
                    r.get::<_, Option<Vec<u8>>>(3)?,
                ))
            })
            .optional()
            .map_err(|e| self.sql(e))?;
        let Some((kind, rows, cols, data)) = row else {
            return Err(self.missing(image, "descriptors"));
        };
        let data = data.unwrap_or_default();
        // Without a type column, 128 bytes are SIFT and anything else is undefined.
        let kind = if typed || cols == 128 {
            kind
        } else {
            UNDEFINED_TYPE
        };
        if usize::try_from(cols).ok() != Some(D::COLS)
            || !(kind == D::TYPE || kind == UNDEFINED_TYPE)
        {
            return Err(ColmapError::DescriptorMismatch {
                path: self.path.clone(),
                image: image.name.clone(),
                kind,
                cols,
                expected: D::DESCRIPTION,
            });
        }
        let r = usize::try_from(rows).ok();
        if r.and_then(|r| r.checked_mul(D::COLS)) != Some(data.len()) {
            return Err(blob_len_error(
                &self.path,
                &image.name,
                "descriptors",
                rows,
                cols,
                data.len(),
            ));
        }
        let descriptors: Vec<D> = data.chunks_exact(D::COLS).map(D::from_row).collect();
        if D::KIND == DescriptorKind::Float && descriptors.iter().any(|d| !d.is_finite()) {
            return Err(self.invalid(format!(
                "image {:?}: a descriptor is not finite",
                image.name
            )));
        }
        Ok(descriptors)
    }

    /// The keypoints and descriptors of `image`, index for index.
    ///
    /// # Errors
    /// Those of [`keypoints`](Self::keypoints) and [`descriptors`](Self::descriptors), and
    /// [`ColmapError::BadFeatures`] when their counts differ.
    pub fn features<D: ColmapDescriptor>(&self, image: &DatabaseImage) -> Result<ImageFeatures<D>> {
        let keypoints = self.keypoints(image)?;
        let descriptors = self.descriptors::<D>(image)?;
        if keypoints.len() != descriptors.len() {
            return Err(ColmapError::BadFeatures {
                path: self.path.clone(),
                image: image.name.clone(),
                what: format!(
                    "{} keypoints but {} descriptors",
                    keypoints.len(),
                    descriptors.len()
                ),
            });
        }
        Ok(ImageFeatures {
            keypoints,
            descriptors,
        })
    }

    /// The layout of the database's descriptors (of its first row), so a caller can pick the
    /// descriptor type: 128 bytes are SIFT, read as `[f32; 128]`; `8 W` bytes of an undefined
    /// type are binary `[u64; W]`.
    ///
    /// # Errors
    /// [`ColmapError::Database`]; [`ColmapError::MissingFeatures`] naming no image when the
    /// database holds no descriptors; [`ColmapError::Invalid`] for other widths and for
    /// descriptor types other than SIFT and undefined (COLMAP 4's ALIKED, say).
    pub fn descriptor_layout(&self) -> Result<DescriptorLayout> {
        let none = || ColmapError::MissingFeatures {
            path: self.path.clone(),
            image: "(any)".to_owned(),
            what: "descriptors",
        };
        if !self.has_table("descriptors")? {
            return Err(none());
        }
        let sql = if self.has_column("descriptors", "type")? {
            "SELECT type, cols FROM descriptors WHERE rows > 0 LIMIT 1"
        } else {
            "SELECT -1, cols FROM descriptors WHERE rows > 0 LIMIT 1"
        };
        let row: Option<(i64, i64)> = self
            .connection
            .query_row(sql, [], |r| Ok((r.get(0)?, r.get(1)?)))
            .optional()
            .map_err(|e| self.sql(e))?;
        if let Some((kind, _)) = row
            && kind != SIFT_TYPE
            && kind != UNDEFINED_TYPE
        {
            return Err(self.invalid(format!(
                "descriptors of COLMAP type {kind}: ibc reads SIFT (type 0) and binary \
                 descriptors (type -1)"
            )));
        }
        let cols = row.map(|r| r.1);
        match cols {
            None => Err(none()),
            Some(128) => Ok(DescriptorLayout {
                kind: DescriptorKind::Float,
                width: 128,
            }),
            Some(c) if c > 0 && c % 8 == 0 && c <= 1024 => Ok(DescriptorLayout {
                kind: DescriptorKind::Binary,
                width: (c / 8) as u32,
            }),
            Some(c) => Err(self.invalid(format!(
                "descriptors of {c} bytes: ibc reads 128-byte SIFT and binary descriptors of a \
                 multiple of 8 bytes"
            ))),
        }
    }
}

fn f64_le(b: &[u8]) -> f64 {
    let mut a = [0; 8];
    a.copy_from_slice(b);
    f64::from_le_bytes(a)
}

/// COLMAP's schema (the tables of its documentation, with the columns COLMAP 3.13+ writes),
/// so that COLMAP opens and extends a database ibc wrote.
const SCHEMA: &str = "
CREATE TABLE IF NOT EXISTS rigs (rig_id INTEGER PRIMARY KEY AUTOINCREMENT NOT NULL,
    ref_sensor_id INTEGER NOT NULL, ref_sensor_type INTEGER NOT NULL);
CREATE UNIQUE INDEX IF NOT EXISTS rig_ref_sensor_assignment ON rigs(ref_sensor_id, ref_sensor_type);
CREATE TABLE IF NOT EXISTS rig_sensors (rig_id INTEGER NOT NULL, sensor_id INTEGER NOT NULL,
    sensor_type INTEGER NOT NULL, sensor_from_rig BLOB,
    FOREIGN KEY(rig_id) REFERENCES rigs(rig_id) ON DELETE CASCADE);
CREATE UNIQUE INDEX IF NOT EXISTS rig_sensor_assignment ON rig_sensors(sensor_id, sensor_type);
CREATE TABLE IF NOT EXISTS cameras (camera_id INTEGER PRIMARY KEY AUTOINCREMENT NOT NULL,
    model INTEGER NOT NULL, width INTEGER NOT NULL, height INTEGER NOT NULL, params BLOB,
    prior_focal_length INTEGER NOT NULL);
CREATE TABLE IF NOT EXISTS frames (frame_id INTEGER PRIMARY KEY AUTOINCREMENT NOT NULL,
    rig_id INTEGER NOT NULL, FOREIGN KEY(rig_id) REFERENCES rigs(rig_id) ON DELETE CASCADE);
CREATE TABLE IF NOT EXISTS frame_data (frame_id INTEGER NOT NULL, data_id INTEGER NOT NULL,
    sensor_id INTEGER NOT NULL, sensor_type INTEGER NOT NULL,
    FOREIGN KEY(frame_id) REFERENCES frames(frame_id) ON DELETE CASCADE);
CREATE UNIQUE INDEX IF NOT EXISTS frame_sensor_assignment ON frame_data(data_id, sensor_type);
CREATE TABLE IF NOT EXISTS images (image_id INTEGER PRIMARY KEY AUTOINCREMENT NOT NULL,
    name TEXT NOT NULL UNIQUE, camera_id INTEGER NOT NULL,
    CONSTRAINT image_id_check CHECK(image_id >= 0 and image_id < 2147483647),
    FOREIGN KEY(camera_id) REFERENCES cameras(camera_id));
CREATE UNIQUE INDEX IF NOT EXISTS index_name ON images(name);
CREATE TABLE IF NOT EXISTS pose_priors (pose_prior_id INTEGER PRIMARY KEY NOT NULL,
    corr_data_id INTEGER NOT NULL, corr_sensor_id INTEGER NOT NULL,
    corr_sensor_type INTEGER NOT NULL, position BLOB, position_covariance BLOB, gravity BLOB,
    coordinate_system INTEGER NOT NULL);
CREATE UNIQUE INDEX IF NOT EXISTS pose_prior_data_assignment ON
    pose_priors(corr_data_id, corr_sensor_id, corr_sensor_type);
CREATE TABLE IF NOT EXISTS keypoints (image_id INTEGER PRIMARY KEY NOT NULL,
    rows INTEGER NOT NULL, cols INTEGER NOT NULL, data BLOB,
    FOREIGN KEY(image_id) REFERENCES images(image_id) ON DELETE CASCADE);
CREATE TABLE IF NOT EXISTS descriptors (image_id INTEGER PRIMARY KEY NOT NULL,
    type INTEGER NOT NULL, rows INTEGER NOT NULL, cols INTEGER NOT NULL, data BLOB,
    FOREIGN KEY(image_id) REFERENCES images(image_id) ON DELETE CASCADE);
CREATE TABLE IF NOT EXISTS matches (pair_id INTEGER PRIMARY KEY NOT NULL,
    rows INTEGER NOT NULL, cols INTEGER NOT NULL, data BLOB);
CREATE TABLE IF NOT EXISTS two_view_geometries (pair_id INTEGER PRIMARY KEY NOT NULL,
    rows INTEGER NOT NULL, cols INTEGER NOT NULL, data BLOB, config INTEGER NOT NULL,
    F BLOB, E BLOB, H BLOB, qvec BLOB, tvec BLOB, camera1 BLOB, camera2 BLOB);
";

/// What [`database_to_bytes`] writes: cameras, rigs, frames and images with their features.
#[derive(Clone, Copy, Debug)]
pub struct DatabaseContent<'a, D> {
    /// Cameras.
    pub cameras: &'a [ColmapCamera],
    /// Rigs.
    pub rigs: &'a [ColmapRig],
    /// Frames.
    pub frames: &'a [DatabaseFrame],
    /// Images, each with its features (ibc's pixel convention; written with COLMAP's).
    pub images: &'a [(DatabaseImage, &'a ImageFeatures<D>)],
}

/// The bytes of a COLMAP database holding `content` (built in memory, so the caller can stage
/// it with the other outputs). Keypoints are written as 2 columns `x, y` (`f32`, COLMAP's
/// pixel convention), descriptors as `D`'s bytes.
///
/// # Errors
/// [`ColmapError::Database`] (naming `path`) when SQLite fails.
pub fn database_to_bytes<D: ColmapDescriptor>(
    path: &Path,
    content: &DatabaseContent<'_, D>,
) -> Result<Vec<u8>> {
    let sql = |source| ColmapError::Database {
        path: path.to_owned(),
        source,
    };
    let mut db = Connection::open_in_memory().map_err(sql)?;
    let tx = db.transaction().map_err(sql)?;
    tx.execute_batch(SCHEMA).map_err(sql)?;
    for c in content.cameras {
        let params: Vec<u8> = c.params.iter().flat_map(|p| p.to_le_bytes()).collect();
        tx.execute(
            "INSERT INTO cameras VALUES (?1, ?2, ?3, ?4, ?5, 0)",
            params![
                c.camera_id,
                c.model.id(),
                c.width as i64,
                c.height as i64,
                params
            ],
        )
        .map_err(sql)?;
    }
    for r in content.rigs {
        tx.execute(
            "INSERT INTO rigs VALUES (?1, ?2, ?3)",
            params![r.rig_id, r.ref_sensor.id, r.ref_sensor.kind.code()],
        )
        .map_err(sql)?;
        for (s, pose) in &r.sensors {
            let blob: Option<Vec<u8>> = pose.map(|p| {
                pose_values(&p)
                    .iter()
                    .flat_map(|v| v.to_le_bytes())
                    .collect()
            });
            tx.execute(
                "INSERT INTO rig_sensors VALUES (?1, ?2, ?3, ?4)",
                params![r.rig_id, s.id, s.kind.code(), blob],
            )
            .map_err(sql)?;
        }
    }
    for f in content.frames {
        tx.execute(
            "INSERT INTO frames VALUES (?1, ?2)",
            params![f.frame_id, f.rig_id],
        )
        .map_err(sql)?;
        for (s, data) in &f.data {
            tx.execute(
                "INSERT INTO frame_data VALUES (?1, ?2, ?3, ?4)",
                params![f.frame_id, *data as i64, s.id, s.kind.code()],
            )
            .map_err(sql)?;
        }
    }
    for (image, features) in content.images {
        tx.execute(
            "INSERT INTO images VALUES (?1, ?2, ?3)",
            params![image.image_id, image.name, image.camera_id],
        )
        .map_err(sql)?;
        let mut kp = Vec::with_capacity(8 * features.keypoints.len());
        for k in &features.keypoints {
            kp.extend(((k.x + PIXEL_SHIFT) as f32).to_le_bytes());
            kp.extend(((k.y + PIXEL_SHIFT) as f32).to_le_bytes());
        }
        tx.execute(
            "INSERT INTO keypoints VALUES (?1, ?2, 2, ?3)",
            params![image.image_id, features.keypoints.len() as i64, kp],
        )
        .map_err(sql)?;
        let mut desc = Vec::with_capacity(D::COLS * features.descriptors.len());
        for d in &features.descriptors {
            d.to_row(&mut desc);
        }
        tx.execute(
            "INSERT INTO descriptors VALUES (?1, ?2, ?3, ?4, ?5)",
            params![
                image.image_id,
                D::TYPE,
                features.descriptors.len() as i64,
                D::COLS as i64,
                desc
            ],
        )
        .map_err(sql)?;
    }
    tx.commit().map_err(sql)?;
    let data = db.serialize(rusqlite::MAIN_DB).map_err(sql)?;
    Ok(data.to_vec())
}
