//! Bounded reading and atomic writing of files: the one place the ibc crates touch the file
//! system.
//!
//! **Reading.** Whatever path a reader is given, it must neither block nor exhaust memory:
//!
//! - the path must be a regular file, checked with its metadata before it is opened (a FIFO
//!   would block the open forever, `/dev/zero` would be read until memory runs out) and again
//!   on the open handle ([`open_regular`]);
//! - at most a limit of bytes is read: the size in the metadata is checked first, and the read
//!   itself stops one byte past the limit ([`Read::take`]), so a file that grows while it is
//!   read cannot exceed it either ([`read_bytes`], [`read_text`]).
//!
//! **Writing.** [`write_atomically`] writes a hidden temporary file next to the target
//! (`.<name>.tmp-<pid>-<n>`), created as any program creates files (mode `0666` less the
//! umask, so other accounts can read the result; temporary-file libraries use `0600`), syncs
//! it, renames it over the target, and removes it again on error: a reader never sees a
//! half-written file.
//!
//! Every error is an [`IoError`] that names the path.

use std::fs::File;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Why a file could not be read or written. Every variant names the path.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IoError {
    /// The operating system refused to read or write the file.
    #[error("{}: {source}", path.display())]
    Os {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// The path is not a regular file (a folder, a FIFO, a device such as `/dev/zero`, a
    /// socket): inputs are read only from regular files, so that a reader neither blocks on a
    /// FIFO nor reads a device without end.
    #[error("{}: not a regular file (a FIFO, a device or a folder)", path.display())]
    NotRegularFile {
        /// The path.
        path: PathBuf,
    },
    /// The file is larger than the reader accepts.
    #[error("{}: at least {size} bytes, over the {limit}-byte limit for this input", path.display())]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size (from its metadata, or the bytes read when it grew while being read).
        size: u64,
        /// The limit.
        limit: u64,
    },
    /// The file was to be text but is not UTF-8.
    #[error("{}: not UTF-8 text (was another file given?)", path.display())]
    NotText {
        /// The file.
        path: PathBuf,
    },
}

impl IoError {
    /// The file the error is about.
    pub fn path(&self) -> &Path {
        match self {
            Self::Os { path, .. }
            | Self::NotRegularFile { path }
            | Self::TooLarge { path, .. }
            | Self::NotText { path } => path,
        }
    }

    /// The operating system's error `source` about `path`.
    pub fn os(path: &Path, source: std::io::Error) -> Self {
        Self::Os {
            path: path.to_owned(),
            source,
        }
    }
}

/// Opens a regular file for reading and returns it with its size in bytes.
///
/// # Errors
/// [`IoError::NotRegularFile`], or [`IoError::Os`] when it cannot be opened.
pub fn open_regular(path: &Path) -> Result<(File, u64), IoError> {
    let not_regular = || IoError::NotRegularFile {
        path: path.to_owned(),
    };
    // Follows symbolic links: a link to a regular file is fine.
    let meta = std::fs::metadata(path).map_err(|e| IoError::os(path, e))?;
    if !meta.is_file() {
        return Err(not_regular());
    }
    let file = File::open(path).map_err(|e| IoError::os(path, e))?;
    // The path may have been replaced between the check and the open.
    let meta = file.metadata().map_err(|e| IoError::os(path, e))?;
    if !meta.is_file() {
        return Err(not_regular());
    }
    Ok((file, meta.len()))
}

/// Reads a whole regular file of at most `limit` bytes.
///
/// # Errors
/// [`IoError::NotRegularFile`], [`IoError::TooLarge`] or [`IoError::Os`].
pub fn read_bytes(path: &Path, limit: u64) -> Result<Vec<u8>, IoError> {
    let too_large = |size| IoError::TooLarge {
        path: path.to_owned(),
        size,
        limit,
    };
    let (file, size) = open_regular(path)?;
    if size > limit {
        return Err(too_large(size));
    }
    let mut bytes = Vec::with_capacity(usize::try_from(size).unwrap_or(0));
    file.take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| IoError::os(path, e))?;
    let read = u64::try_from(bytes.len()).unwrap_or(u64::MAX);
    if read > limit {
        return Err(too_large(read));
    }
    Ok(bytes)
}

/// Reads a whole regular file of at most `limit` bytes of UTF-8 text.
///
/// # Errors
/// As [`read_bytes`], and [`IoError::NotText`].
pub fn read_text(path: &Path, limit: u64) -> Result<String, IoError> {
    String::from_utf8(read_bytes(path, limit)?).map_err(|_| IoError::NotText {
        path: path.to_owned(),
    })
}

/// Distinguishes the temporary files of one process.
static NEXT_TEMPORARY: AtomicU64 = AtomicU64::new(0);

/// Writes `bytes` to `path` atomically (see the module docs). The folder must exist.
///
/// # Errors
/// [`IoError::Os`] naming `path` if the temporary file cannot be created, written, synced or
/// renamed; nothing is left behind then.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), IoError> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let name = path
        .file_name()
        .map_or_else(|| "file".into(), |n| n.to_string_lossy());
    let n = NEXT_TEMPORARY.fetch_add(1, Ordering::Relaxed);
    let tmp = dir.join(format!(".{name}.tmp-{}-{n}", std::process::id()));
    let written = (|| {
        let mut file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)?;
        file.write_all(bytes)?;
        file.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    written.map_err(|e| {
        // Best effort: the error returned is the write's.
        let _ = std::fs::remove_file(&tmp);
        IoError::os(path, e)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folders_are_refused_and_sizes_bounded() {
        let dir = std::env::temp_dir().join(format!("ibc-io-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap_or_default();
        assert!(matches!(
            read_bytes(&dir, 10),
            Err(IoError::NotRegularFile { .. })
        ));
        let file = dir.join("f");
        write_atomically(&file, b"0123456789").unwrap_or_default();
        assert_eq!(read_bytes(&file, 10).map(|b| b.len()).unwrap_or(0), 10);
        assert!(matches!(
            read_bytes(&file, 9),
            Err(IoError::TooLarge { size: 10, .. })
        ));
        write_atomically(&file, &[0xff, 0xfe]).unwrap_or_default();
        assert!(matches!(read_text(&file, 10), Err(IoError::NotText { .. })));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
