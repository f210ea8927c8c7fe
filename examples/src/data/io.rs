//! File formats of the map, the rig log and the ground truth, with validating readers and
//! atomic writers.
//!
//! A user with real features writes the same files: a map from their SLAM or SfM survey and a
//! rig log from their rig, with any binary (`[u64; W]`) or float (`[f32; D]`) descriptor.
//!
//! # Common rules
//!
//! - All integers and floats are **little-endian**; floats are IEEE-754 (`f64` unless said).
//! - Poses are 7 `f64`: the translation `tx, ty, tz` (metres), then a unit quaternion
//!   `qw, qx, qy, qz` (**`[w, x, y, z]`** order; norm within 1e-6 of 1, normalized on
//!   reading), named `a_from_b` as everywhere in ibc: `camera_from_world` maps world points
//!   into the camera frame.
//! - Keypoints are two `f64`, `u, v`, in pixels with **pixel centres at integer
//!   coordinates** (OpenCV, Kalibr, CamOdoCal; add `-0.5` to COLMAP's).
//! - Descriptors: kind `1` is binary, stored as `W` `u64` words (ORB / BRIEF-256: `W = 4`;
//!   pack OpenCV's 32 bytes with `ibc_vocab_tree::binary_from_bytes`); kind `2` is float,
//!   stored as `D` `f32` values (SURF-64: `D = 64`). `e` below is 8 bytes for binary, 4 for
//!   float. Reading a file with descriptors of another kind or width than asked for is an
//!   error; [`read_descriptor_layout`] tells which type to ask for.
//! - Reserved bytes are zero. The last 8 bytes are the **XXH64** (seed 0) of every byte before
//!   them (`head -c -8 FILE | xxhsum -H1` prints it).
//! - Files are written atomically: staged in a hidden folder next to them, synced, then
//!   renamed (see [`StagedFiles`]), with the umask's usual modes.
//!
//! # The common header (32 bytes)
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 8 | magic: `IBCMAP\0\0` (map) or `IBCLOG\0\0` (rig log) |
//! | 8 | 4 | format version, `u32` = [`FORMAT_VERSION`] (1) |
//! | 12 | 1 | descriptor kind: 1 binary, 2 float |
//! | 13 | 3 | reserved |
//! | 16 | 4 | descriptor width `W`: `u64` words (binary) or `f32` values (float), `u32` |
//! | 20 | 4 | reserved |
//! | 24 | 8 | length of the whole file in bytes, checksum included, `u64` |
//!
//! # The map file (`map.ibcmap`)
//!
//! After the common header, with `P` points, `I` images and `F` features in all:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 32 | 4 | point count `P`, `u32` (at most 2^32 − 2) |
//! | 36 | 4 | image count `I`, `u32` |
//! | 40 | 8 | feature count `F` (sum over images), `u64` |
//! | 48 | `24 P` | map points `x, y, z` (`f64`, metres, world frame = the map's frame) |
//! | … | `64 I` | image records, in survey order: feature count `u32`; pose flag `u8` (1 when the image's `camera_from_world` is known, else 0); 3 reserved bytes; `camera_from_world` pose (56 bytes; zero when the flag is 0) |
//! | … | `16 F` | keypoints `u, v`, image after image |
//! | … | `F W e` | descriptors, in the same order |
//! | … | `4 F` | the map point each feature observes, `u32` index into the points, or `0xFFFF_FFFF` for a feature that is not in the map |
//! | end − 8 | 8 | XXH64 checksum |
//!
//! # The rig-log file (`log.ibclog`)
//!
//! After the common header, with `C` cameras, `N` synchronized frames and `F` features:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 32 | 4 | camera count `C`, `u32` (at least 1) |
//! | 36 | 4 | frame count `N`, `u32` |
//! | 40 | 1 | odometry kind: 0 none, 1 planar (wheel odometry), 2 6-DoF (pose tracker) |
//! | 41 | 7 | reserved |
//! | 48 | 8 | feature count `F` (sum over all images), `u64` |
//! | 56 | … | `C` camera names, each a `u32` byte length then that many bytes of UTF-8 (non-empty, unique, at most [`MAX_CAMERA_NAME_BYTES`], no line break); they are matched to the camera file's cameras **by name** (by order when the file names none: `crate::calib::camera_matching`) |
//! | … | `72 N` | frame records, in time order: time stamp `f64` (seconds, non-decreasing); odometry flag `u8` (1 when the frame has an odometry pose; always 0 when the kind is none); 7 reserved bytes; `world_from_odometry` pose (56 bytes, zero when the flag is 0) in the odometry's own world frame |
//! | … | `4 N C` | feature count of every image, `u32`, frame-major (frame 0 camera 0, frame 0 camera 1, …) |
//! | … | `16 F` | keypoints `u, v`, image after image in the same order |
//! | … | `F W e` | descriptors, in the same order |
//! | end − 8 | 8 | XXH64 checksum |
//!
//! Planar odometry poses are rotations about z and translations in the x-y plane; the reader
//! does not enforce it.
//!
//! # What the readers check
//!
//! In this order, and never allocating by a count before the file's length has confirmed it:
//! the magic (a log given as the map is named as such), the version, the descriptor kind and
//! width against the type asked for, the length in the header against the file's length
//! (truncation), the checksum (corruption), the counts against the length (every section must
//! fit exactly), then every value: finite points, keypoints and float descriptors, unit
//! quaternions, flags that are 0 or 1, zero reserved bytes, point ids below `P`, per-image
//! counts that sum to `F`, camera names, time order, odometry poses only when the kind is not
//! none. Every failure is a [`DataFileError`] naming the file and a [`FormatError`] naming
//! the problem. The writers run the same checks first, so every file written reads back.
//!
//! # The ground truth (`truth.json`)
//!
//! ```json
//! {
//!   "format": "ibc-ground-truth",
//!   "version": 1,
//!   "scenario": "garage",
//!   "seed": 1,
//!   "pixel_noise_px": 0.5,
//!   "camera_names": ["front", "left", "rear", "right"],
//!   "rig_from_camera": [{"translation": [x, y, z], "rotation_wxyz": [w, x, y, z]}, ...],
//!   "rig_from_odometry": {"translation": [...], "rotation_wxyz": [...]} or null,
//!   "world_from_rig": [{"translation": [...], "rotation_wxyz": [...]}, ...]
//! }
//! ```
//!
//! `camera_names` (optional) are the log's camera names in its order; `ibc calibrate --truth`
//! refuses a truth whose names, camera count or number of `world_from_rig` poses differ from
//! the log's. `rig_from_camera` holds the true extrinsics of the calibrated rig, one per camera
//! in the log's order, in the simulator's vehicle frame (x forward, y left, z up); a calibration's
//! rig frame is its camera 0, so compare poses relative to camera 0. `world_from_rig` holds
//! the true rig pose at every frame of the log; `rig_from_odometry` the true transform from
//! the odometry frame into the vehicle frame (null without odometry). Unknown fields are an
//! error.
//!
//! # Example
//!
//! ```
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use ibc_pipeline::data::io::{map_from_bytes, map_to_bytes, read_map, write_map};
//! use ibc_pipeline::data::{BinaryDescriptor, FloatDescriptor, ImageFeatures, Map, MapImage};
//! use nalgebra::{Point3, Vector2};
//!
//! let map: Map<BinaryDescriptor> = Map {
//!     points: vec![Point3::new(1.0, 2.0, 3.0)],
//!     images: vec![MapImage {
//!         camera_from_world: None,
//!         features: ImageFeatures {
//!             keypoints: vec![Vector2::new(320.5, 240.25), Vector2::new(10.0, 20.0)],
//!             descriptors: vec![[1, 2, 3, 4], [5, 6, 7, 8]],
//!         },
//!         point_ids: vec![Some(0), None],
//!     }],
//! };
//! let dir = tempfile::tempdir()?;
//! let path = dir.path().join("map.ibcmap");
//! write_map(&path, &map)?;
//! assert_eq!(read_map::<BinaryDescriptor>(&path)?, map);
//!
//! // Asking for SURF-64 descriptors from a binary map is an error that says so.
//! let err = read_map::<FloatDescriptor>(&path).unwrap_err();
//! assert!(err.to_string().contains("binary 256-bit"));
//!
//! // A flipped bit is caught by the checksum.
//! let mut bytes = map_to_bytes(&map)?;
//! bytes[60] ^= 1;
//! assert!(map_from_bytes::<BinaryDescriptor>(&bytes).is_err());
//! # Ok(())
//! # }
//! ```

mod atomic;
mod bytes;
mod checksum;
mod descriptor;
mod error;
mod features;
mod log_format;
mod map_format;
mod truth_json;

use std::path::Path;

use ibc_camera_models::io::{IoError, write_atomically};
use ibc_vocab_tree::Descriptor;

pub use atomic::{STAGING_PREFIX, STALE_STAGING_SECONDS, StagedFiles, remove_staged_outputs};
pub(crate) use bytes::unit_quaternion;
pub use checksum::xxh64;
pub use descriptor::descriptor_layout;
pub use error::{DataFileError, DescriptorLayout, FormatError};

/// The largest text input (ground truth, corner file): 256 MiB. A ground truth holds about
/// 200 bytes per frame (a million frames in 200 MB); a corner file about 60 bytes per corner.
pub const MAX_TEXT_INPUT_BYTES: u64 = 256 << 20;

/// The largest scenario file: 1 MiB, a thousand times a real one.
pub const MAX_SCENARIO_BYTES: u64 = 1 << 20;

/// The largest map or rig log: 16 GiB, read whole into memory. The default scenario's map is
/// 65 MB and its log 104 MB.
pub const MAX_BINARY_INPUT_BYTES: u64 = 16 << 30;
pub use log_format::{MAX_CAMERA_NAME_BYTES, log_from_bytes, log_to_bytes};
pub use map_format::{NO_POINT, map_from_bytes, map_to_bytes};
pub use truth_json::{TRUTH_FORMAT, truth_from_json, truth_to_json};

use crate::data::{GroundTruth, Map, RigLog};

/// The format version this build writes and reads (map, rig log and ground truth).
pub const FORMAT_VERSION: u32 = 1;

/// The conventional file names in a simulated world's folder.
pub mod file_names {
    /// The map.
    pub const MAP: &str = "map.ibcmap";
    /// The rig log.
    pub const LOG: &str = "log.ibclog";
    /// The cameras (Kalibr camchain).
    pub const CAMERAS: &str = "camchain.yaml";
    /// The ground truth.
    pub const TRUTH: &str = "truth.json";
}

fn read_bytes(path: &Path) -> Result<Vec<u8>, DataFileError> {
    Ok(ibc_camera_models::io::read_bytes(
        path,
        MAX_BINARY_INPUT_BYTES,
    )?)
}

fn format_error(path: &Path) -> impl Fn(FormatError) -> DataFileError + '_ {
    move |source| DataFileError::Format {
        path: path.to_owned(),
        source,
    }
}

/// Reads and validates a map file.
///
/// # Errors
/// [`DataFileError::Io`] if the file cannot be read, [`DataFileError::Format`] naming the
/// problem if it is not a valid map with descriptors of type `D`.
pub fn read_map<D: Descriptor>(path: impl AsRef<Path>) -> Result<Map<D>, DataFileError> {
    let path = path.as_ref();
    map_from_bytes(&read_bytes(path)?).map_err(format_error(path))
}

/// Writes a map file atomically.
///
/// # Errors
/// [`DataFileError::Format`] if the map is invalid (see [`map_to_bytes`]),
/// [`DataFileError::Io`] if the file cannot be written.
pub fn write_map<D: Descriptor>(path: impl AsRef<Path>, map: &Map<D>) -> Result<(), DataFileError> {
    let path = path.as_ref();
    Ok(write_atomically(
        path,
        &map_to_bytes(map).map_err(format_error(path))?,
    )?)
}

/// Reads and validates a rig-log file.
///
/// # Errors
/// [`DataFileError::Io`] if the file cannot be read, [`DataFileError::Format`] naming the
/// problem if it is not a valid rig log with descriptors of type `D`.
pub fn read_log<D: Descriptor>(path: impl AsRef<Path>) -> Result<RigLog<D>, DataFileError> {
    let path = path.as_ref();
    log_from_bytes(&read_bytes(path)?).map_err(format_error(path))
}

/// Writes a rig-log file atomically.
///
/// # Errors
/// [`DataFileError::Format`] if the log is invalid (see [`log_to_bytes`]),
/// [`DataFileError::Io`] if the file cannot be written.
pub fn write_log<D: Descriptor>(
    path: impl AsRef<Path>,
    log: &RigLog<D>,
) -> Result<(), DataFileError> {
    let path = path.as_ref();
    Ok(write_atomically(
        path,
        &log_to_bytes(log).map_err(format_error(path))?,
    )?)
}

/// Reads and validates a ground-truth JSON file.
///
/// # Errors
/// [`DataFileError::Io`] if the file cannot be read, [`DataFileError::Json`] if it is not
/// valid ground truth.
pub fn read_truth(path: impl AsRef<Path>) -> Result<GroundTruth, DataFileError> {
    let path = path.as_ref();
    let text = ibc_camera_models::io::read_text(path, MAX_TEXT_INPUT_BYTES)?;
    truth_from_json(&text).map_err(|source| DataFileError::Json {
        path: path.to_owned(),
        source,
    })
}

/// Writes a ground-truth JSON file atomically.
///
/// # Errors
/// [`DataFileError::Json`] if a number is not finite, [`DataFileError::Io`] if the file
/// cannot be written.
pub fn write_truth(path: impl AsRef<Path>, truth: &GroundTruth) -> Result<(), DataFileError> {
    let path = path.as_ref();
    let text = truth_to_json(truth).map_err(|source| DataFileError::Json {
        path: path.to_owned(),
        source,
    })?;
    Ok(write_atomically(path, text.as_bytes())?)
}

/// The descriptor layout of a map or rig-log file, read from its header only, so a caller
/// can pick the descriptor type before reading the whole file.
///
/// # Errors
/// [`DataFileError::Io`] if the file cannot be read, [`DataFileError::Format`] if it does not
/// start with an ibc header of a version this build reads.
pub fn read_descriptor_layout(path: impl AsRef<Path>) -> Result<DescriptorLayout, DataFileError> {
    use std::io::Read;
    let path = path.as_ref();
    let mut header = Vec::with_capacity(bytes::COMMON_HEADER_LEN);
    ibc_camera_models::io::open_regular(path)?
        .0
        .take(bytes::COMMON_HEADER_LEN as u64)
        .read_to_end(&mut header)
        .map_err(|e| IoError::os(path, e))?;
    bytes::peek_layout(&header).map_err(format_error(path))
}
