//! Bounded reading of input files.
//!
//! A camera file is a few kilobytes of text. Whatever path a reader is given, it must neither
//! block nor exhaust memory:
//!
//! - the path must be a regular file, checked with its metadata before it is opened (a FIFO
//!   would block the open forever, `/dev/zero` would be read until memory runs out) and again
//!   on the open handle;
//! - at most [`MAX_FILE_BYTES`] are read: the metadata size is checked first, and the read
//!   itself is limited to one byte more than the limit ([`Read::take`]), so a file that grows
//!   while it is read cannot exceed it either.
//!
//! The YAML reader adds its own bounds (no aliases, bounded nesting; see
//! [`MAX_YAML_DEPTH`](crate::MAX_YAML_DEPTH)).

use std::fs::File;
use std::io::Read;
use std::path::Path;

use crate::error::FileError;

/// The largest camera file read, in bytes: 1 MiB. A Kalibr camchain of ten cameras with IMU
/// fields is about 8 kB and a CamOdoCal camera YAML about 600 bytes, so the limit is more than
/// a hundred times any real file and still small enough to hold in memory without thought.
pub const MAX_FILE_BYTES: u64 = 1 << 20;

/// Read a whole text file of at most [`MAX_FILE_BYTES`] bytes from a regular file.
///
/// # Errors
/// [`FileError::NotRegularFile`], [`FileError::TooLarge`], or [`FileError::Io`] (including
/// text that is not UTF-8), each naming the path.
pub fn read_text(path: &Path) -> Result<String, FileError> {
    let io = |source| FileError::Io {
        path: path.to_owned(),
        source,
    };
    let not_regular = || FileError::NotRegularFile {
        path: path.to_owned(),
    };
    let too_large = |size| FileError::TooLarge {
        path: path.to_owned(),
        size,
        limit: MAX_FILE_BYTES,
    };
    // Follows symbolic links: a link to a regular file is fine.
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.is_file() {
        return Err(not_regular());
    }
    if meta.len() > MAX_FILE_BYTES {
        return Err(too_large(meta.len()));
    }
    let file = File::open(path).map_err(io)?;
    // The path may have been replaced between the check and the open.
    if !file.metadata().map_err(io)?.is_file() {
        return Err(not_regular());
    }
    let mut bytes = Vec::new();
    file.take(MAX_FILE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    let read = u64::try_from(bytes.len()).unwrap_or(u64::MAX);
    if read > MAX_FILE_BYTES {
        return Err(too_large(read));
    }
    String::from_utf8(bytes)
        .map_err(|e| io(std::io::Error::new(std::io::ErrorKind::InvalidData, e)))
}
