//! Errors of the COLMAP readers and writers.

use std::path::PathBuf;

use ibc_camera_models::ParameterError;
use ibc_camera_models::io::IoError;

use crate::data::io::DataFileError;

/// Why a COLMAP model or database cannot be read (or an ibc map or rig written as one). Every
/// variant names the culprit file, and the camera, image or record where there is one.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ColmapError {
    /// The file could not be read or written (or is not a regular file, or is too large).
    #[error(transparent)]
    Io(#[from] IoError),
    /// The folder holds neither `cameras.bin` nor `cameras.txt`.
    #[error(
        "{}: not a COLMAP sparse model (no cameras.bin nor cameras.txt; give the folder that \
         holds them, such as sparse/0)",
        dir.display()
    )]
    NotAModel {
        /// The folder.
        dir: PathBuf,
    },
    /// A binary file ends inside a record.
    #[error(
        "{}: the file ends inside {what} (byte {offset} of {len}): it is truncated",
        path.display()
    )]
    Truncated {
        /// The file.
        path: PathBuf,
        /// The record being read.
        what: String,
        /// Where the missing bytes start.
        offset: u64,
        /// The file's length.
        len: u64,
    },
    /// A count in a binary file asks for more bytes than remain: a corrupted count or a
    /// truncated file. Checked before anything is allocated by it.
    #[error(
        "{}: {count} {what} declared at byte {offset} need at least {needed} bytes but only \
         {remaining} remain: the count is corrupted or the file truncated",
        path.display()
    )]
    BadCount {
        /// The file.
        path: PathBuf,
        /// What is counted.
        what: String,
        /// The count read.
        count: u64,
        /// Where it was read.
        offset: u64,
        /// The least number of bytes it needs (saturated).
        needed: u64,
        /// The bytes left in the file.
        remaining: u64,
    },
    /// Bytes after the last record of a binary file.
    #[error("{}: {extra} bytes after the last record: the file is corrupted", path.display())]
    TrailingBytes {
        /// The file.
        path: PathBuf,
        /// How many.
        extra: u64,
    },
    /// A line of a text file cannot be parsed.
    #[error("{}:{line}: {what}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// The line, from 1.
        line: usize,
        /// What is wrong.
        what: String,
    },
    /// A camera model id or name that COLMAP's documentation does not define.
    #[error("{}: camera {camera_id} has an unknown camera model {model}", path.display())]
    UnknownCameraModel {
        /// The file.
        path: PathBuf,
        /// The camera.
        camera_id: u32,
        /// The id or name found.
        model: String,
    },
    /// A COLMAP camera model that no ibc model represents exactly.
    #[error(
        "camera {camera_id}: COLMAP model {model} has no exact ibc counterpart (ibc reads \
         SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV and OPENCV_FISHEYE)"
    )]
    UnsupportedCameraModel {
        /// The camera.
        camera_id: u32,
        /// The COLMAP model's name.
        model: &'static str,
    },
    /// A camera's image size is empty or past what ibc's models take (`u32`).
    #[error("camera {camera_id}: image size {width}x{height} is empty or too large")]
    CameraSize {
        /// The camera.
        camera_id: u32,
        /// Width, pixels.
        width: u64,
        /// Height, pixels.
        height: u64,
    },
    /// An ibc camera model that no COLMAP model represents.
    #[error(
        "camera {camera}: the ibc {model} model has no COLMAP counterpart (COLMAP takes \
         pinhole_radtan as OPENCV and kannala_brandt as OPENCV_FISHEYE)"
    )]
    UnsupportedIbcModel {
        /// The camera's name.
        camera: String,
        /// The ibc model's name.
        model: &'static str,
    },
    /// A camera's parameters are invalid for the ibc model (a focal length that is not
    /// positive, an image size past `u32`, a non-finite value).
    #[error("camera {camera_id}: {source}")]
    CameraParameters {
        /// The camera.
        camera_id: u32,
        /// Why.
        source: ParameterError,
    },
    /// A record refers to something that is not there, or a value is out of range (a
    /// duplicate id, a 2D point of a missing 3D point, a track of a missing image, a
    /// non-finite coordinate, a quaternion that is not a unit).
    #[error("{}: {what}", path.display())]
    Invalid {
        /// The file (or folder).
        path: PathBuf,
        /// What is wrong and where.
        what: String,
    },
    /// SQLite could not open or query the database.
    #[error("{}: not a readable COLMAP database: {source}", path.display())]
    Database {
        /// The database.
        path: PathBuf,
        /// SQLite's error.
        source: rusqlite::Error,
    },
    /// A model image is not in the database (by name).
    #[error(
        "{}: the model's image {image:?} is not in the database: is it the database the \
         model was built from?",
        path.display()
    )]
    ImageNotInDatabase {
        /// The database.
        path: PathBuf,
        /// The image's name.
        image: String,
    },
    /// An image has no keypoints or no descriptors in the database.
    #[error(
        "{}: image {image:?} has no {what} in the database (run COLMAP's feature extraction, \
         or keep the descriptors when exporting)",
        path.display()
    )]
    MissingFeatures {
        /// The database.
        path: PathBuf,
        /// The image's name.
        image: String,
        /// `"keypoints"` or `"descriptors"`.
        what: &'static str,
    },
    /// A feature table's blob has another size or shape than its rows and columns say, or
    /// the keypoints, descriptors and model disagree on an image's feature count.
    #[error("{}: image {image:?}: {what}", path.display())]
    BadFeatures {
        /// The database.
        path: PathBuf,
        /// The image's name.
        image: String,
        /// What is wrong.
        what: String,
    },
    /// The descriptors are of a kind that the descriptor type asked for cannot hold.
    #[error(
        "{}: image {image:?} has descriptors of type {kind} with {cols} bytes each, which \
         ibc reads as {expected}",
        path.display()
    )]
    DescriptorMismatch {
        /// The database.
        path: PathBuf,
        /// The image's name.
        image: String,
        /// COLMAP's descriptor type code (0 SIFT, -1 undefined).
        kind: i64,
        /// Bytes per descriptor.
        cols: i64,
        /// What the requested ibc descriptor type takes.
        expected: &'static str,
    },
    /// A set of output files could not be staged or committed.
    #[error(transparent)]
    Output(#[from] DataFileError),
}

/// The crate-wide `Result` of this module.
pub type Result<T, E = ColmapError> = std::result::Result<T, E>;
