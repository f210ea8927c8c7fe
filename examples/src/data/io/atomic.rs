//! Atomic file writes: each file is written to a temporary file in its target folder, synced,
//! then renamed over the target, so a reader never sees a half-written file. [`StagedFiles`]
//! extends this to a set of files: all are written first and renamed only when every one was
//! written, so an error leaves none of them behind.

use std::io::Write;
use std::path::{Path, PathBuf};

use tempfile::NamedTempFile;

use super::error::DataFileError;

fn io_error(path: &Path) -> impl Fn(std::io::Error) -> DataFileError + '_ {
    move |source| DataFileError::Io {
        path: path.to_owned(),
        source,
    }
}

/// The folder a file is written in (`.` for a bare file name).
fn folder(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Writes `bytes` to a synced temporary file next to `path`.
fn stage_one(path: &Path, bytes: &[u8]) -> Result<NamedTempFile, DataFileError> {
    let mut tmp = NamedTempFile::new_in(folder(path)).map_err(io_error(path))?;
    tmp.write_all(bytes).map_err(io_error(path))?;
    tmp.as_file().sync_all().map_err(io_error(path))?;
    Ok(tmp)
}

/// Writes `bytes` to `path` atomically (temporary file in the same folder, synced, renamed).
///
/// # Errors
/// [`DataFileError::Io`] naming `path` if the folder is missing or not writable, or the write
/// or the rename fails; the temporary file is removed then.
pub fn write_atomically(path: impl AsRef<Path>, bytes: &[u8]) -> Result<(), DataFileError> {
    let path = path.as_ref();
    stage_one(path, bytes)?
        .persist(path)
        .map_err(|e| io_error(path)(e.error))?;
    Ok(())
}

/// A set of files written all or nothing: [`stage`](Self::stage) writes each to a temporary
/// file next to its target, [`commit`](Self::commit) renames them all. Dropping the set
/// without committing removes the temporary files, so an error before the commit leaves no
/// output.
///
/// ```
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// use ibc_pipeline::data::io::StagedFiles;
/// let dir = tempfile::tempdir()?;
/// let mut files = StagedFiles::new();
/// files.stage(dir.path().join("a.txt"), b"first")?;
/// files.stage(dir.path().join("b.txt"), b"second")?;
/// assert!(!dir.path().join("a.txt").exists()); // nothing is visible before the commit
/// let written = files.commit()?;
/// assert_eq!(written.len(), 2);
/// assert_eq!(std::fs::read(dir.path().join("b.txt"))?, b"second");
/// # Ok(())
/// # }
/// ```
#[derive(Debug, Default)]
pub struct StagedFiles {
    staged: Vec<(NamedTempFile, PathBuf)>,
}

impl StagedFiles {
    /// An empty set.
    pub fn new() -> Self {
        Self::default()
    }

    /// Writes `bytes` to a synced temporary file next to `path`, to be renamed to `path` by
    /// [`commit`](Self::commit).
    ///
    /// # Errors
    /// [`DataFileError::Io`] naming `path`.
    pub fn stage(&mut self, path: impl AsRef<Path>, bytes: &[u8]) -> Result<(), DataFileError> {
        let path = path.as_ref();
        let tmp = stage_one(path, bytes)?;
        self.staged.push((tmp, path.to_owned()));
        Ok(())
    }

    /// Renames every staged file to its target, in staging order, and returns the targets.
    ///
    /// # Errors
    /// [`DataFileError::Io`] naming the file whose rename failed. The files renamed before it
    /// are removed again (best effort), and the rest are deleted, so no partial set is left.
    pub fn commit(self) -> Result<Vec<PathBuf>, DataFileError> {
        let mut done: Vec<PathBuf> = Vec::with_capacity(self.staged.len());
        for (tmp, path) in self.staged {
            if let Err(e) = tmp.persist(&path) {
                for p in &done {
                    // Best effort: the error returned is the rename's.
                    let _ = std::fs::remove_file(p);
                }
                return Err(io_error(&path)(e.error));
            }
            done.push(path);
        }
        Ok(done)
    }
}
