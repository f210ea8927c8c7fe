//! Bounded reading of input files: whatever path a reader is given, it neither blocks nor
//! exhausts memory.
//!
//! - The path must be a regular file, checked with its metadata before it is opened (a FIFO
//!   would block the open forever, `/dev/zero` would be read until memory runs out) and again
//!   on the open handle.
//! - At most a limit of bytes is read: the size in the metadata is checked first, and the read
//!   itself stops one byte past the limit ([`Read::take`]), so a file that grows while it is
//!   read cannot exceed it either. Text inputs (ground truth, corner files) have
//!   [`MAX_TEXT_INPUT_BYTES`], scenario files [`MAX_SCENARIO_BYTES`], maps and rig logs
//!   [`MAX_BINARY_INPUT_BYTES`] (they are read whole into memory).
//!
//! Errors are [`std::io::Error`]s (kind `InvalidInput` for a file that is not regular,
//! `FileTooLarge` for one over the limit) that each reader wraps with the path.

use std::fs::File;
use std::io::{Error, ErrorKind, Read};
use std::path::Path;

/// The largest text input (ground truth, corner file): 256 MiB. A ground truth holds about
/// 200 bytes per frame (a million frames in 200 MB); a corner file about 60 bytes per corner.
pub const MAX_TEXT_INPUT_BYTES: u64 = 256 << 20;

/// The largest scenario file: 1 MiB, a thousand times a real one.
pub const MAX_SCENARIO_BYTES: u64 = 1 << 20;

/// The largest map or rig log: 16 GiB, read whole into memory. The default scenario's map is
/// 65 MB and its log 104 MB.
pub const MAX_BINARY_INPUT_BYTES: u64 = 16 << 30;

/// The error of a path that is not a regular file.
fn not_regular() -> Error {
    Error::new(
        ErrorKind::InvalidInput,
        "not a regular file (a FIFO, a device or a folder): refused, since reading it could \
         block or never end",
    )
}

/// Opens a regular file for reading (checked before the open, which would block on a FIFO,
/// and again on the open file), with its size.
///
/// # Errors
/// The operating system's error, or `InvalidInput` when the path is not a regular file.
pub fn open_regular(path: &Path) -> Result<(File, u64), Error> {
    if !std::fs::metadata(path)?.is_file() {
        return Err(not_regular());
    }
    let file = File::open(path)?;
    let meta = file.metadata()?;
    if !meta.is_file() {
        return Err(not_regular());
    }
    Ok((file, meta.len()))
}

/// Reads a whole regular file of at most `limit` bytes.
///
/// # Errors
/// The operating system's error, `InvalidInput` when the path is not a regular file,
/// `FileTooLarge` when it holds more than `limit` bytes.
pub fn read_input(path: &Path, limit: u64) -> Result<Vec<u8>, Error> {
    let too_large = |size: u64| {
        Error::new(
            ErrorKind::FileTooLarge,
            format!("the file has {size} bytes, more than the {limit} this input may have"),
        )
    };
    let (file, size) = open_regular(path)?;
    if size > limit {
        return Err(too_large(size));
    }
    let mut bytes = Vec::with_capacity(usize::try_from(size).unwrap_or(0));
    file.take(limit.saturating_add(1)).read_to_end(&mut bytes)?;
    let read = u64::try_from(bytes.len()).unwrap_or(u64::MAX);
    if read > limit {
        return Err(too_large(read));
    }
    Ok(bytes)
}

/// [`read_input`] of UTF-8 text.
///
/// # Errors
/// As [`read_input`], and `InvalidData` for text that is not UTF-8.
pub fn read_text_input(path: &Path, limit: u64) -> Result<String, Error> {
    String::from_utf8(read_input(path, limit)?).map_err(|_| {
        Error::new(
            ErrorKind::InvalidData,
            "the file is not UTF-8 text: was another file given?",
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folders_and_devices_are_refused_and_sizes_bounded() {
        let dir = tempfile::tempdir().unwrap();
        let e = read_input(dir.path(), 10).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::InvalidInput);
        if Path::new("/dev/zero").exists() {
            let e = read_input(Path::new("/dev/zero"), 10).unwrap_err();
            assert_eq!(e.kind(), ErrorKind::InvalidInput);
        }
        let file = dir.path().join("f");
        std::fs::write(&file, b"0123456789").unwrap();
        assert_eq!(read_input(&file, 10).unwrap().len(), 10);
        let e = read_input(&file, 9).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::FileTooLarge);
        assert!(e.to_string().contains("10 bytes"), "{e}");
        std::fs::write(&file, [0xff, 0xfe]).unwrap();
        assert_eq!(
            read_text_input(&file, 10).unwrap_err().kind(),
            ErrorKind::InvalidData
        );
    }
}
