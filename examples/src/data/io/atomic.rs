//! Output files written all or nothing, leaving nothing behind when a run fails or is
//! interrupted.
//!
//! [`StagedFiles`] writes a set of files into one output folder: each is written and synced
//! inside a hidden staging folder of the output folder (`.ibc-staging-<pid>-<n>`), and only
//! when every file was written are they renamed into place (a rename within one file system,
//! atomic for each file). So:
//!
//! - an error before the commit removes the staging folder (and the output folder, if this
//!   set created it): no output at all;
//! - an interrupt (SIGINT, SIGTERM, SIGHUP) is handled by the `ibc` binary through
//!   [`remove_staged_outputs`], which removes every staging folder of the process; it waits
//!   for a file being written or a commit in progress to finish, so the outputs are either
//!   all there or none of them;
//! - a process killed outright (SIGKILL, power loss) can leave only its hidden staging folder,
//!   which the next [`StagedFiles::new`] in that output folder removes once no live process
//!   owns it (its process id is in its name; where the operating system cannot tell whether a
//!   process lives, a staging folder older than [`STALE_STAGING_SECONDS`] is removed).
//!
//! Files are created as any program creates them, with mode `0666` less the process's umask
//! (`0644` under the usual umask `022`), so other accounts (a ROS node) can read them;
//! temporary-file libraries use `0600`.
//!
//! One file alone is written by `ibc_camera_models::io::write_atomically`, the workspace's
//! atomic writer, on which this module's staging follows the same rules (umask modes, sync,
//! rename).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use ibc_camera_models::io::IoError;

use super::error::DataFileError;

/// The prefix of staging folders.
pub const STAGING_PREFIX: &str = ".ibc-staging-";

/// Where the process's liveness cannot be checked, a staging folder older than this (seconds)
/// is taken as left over: one day.
pub const STALE_STAGING_SECONDS: u64 = 24 * 60 * 60;

/// The staging folders of this process that are not yet committed or removed. Locked while a
/// file is written into one and during a commit, so that [`remove_staged_outputs`] never
/// races them.
static STAGING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Distinguishes the staging folders of one process.
static NEXT_STAGING: AtomicU64 = AtomicU64::new(0);

/// Set (under the registry's lock) by [`remove_staged_outputs`]: no staging folder is created
/// after it, so none can appear between the handler's sweep and the process's exit.
static CANCELLED: AtomicBool = AtomicBool::new(false);

fn io_error(path: &Path) -> impl Fn(std::io::Error) -> DataFileError + '_ {
    move |source| IoError::os(path, source).into()
}

/// The registry, whatever a panicking holder left in it (a list of paths is never
/// inconsistent).
fn registry() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    STAGING
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Removes every staging folder of this process, for a signal handler: after it returns, no
/// output of an unfinished [`StagedFiles`] exists and none will be written (a later
/// [`StagedFiles::new`], [`StagedFiles::stage`] or [`StagedFiles::commit`] fails). A commit
/// in progress finishes first, so a set is never left half renamed. Call it, then exit.
pub fn remove_staged_outputs() {
    let mut staging = registry();
    CANCELLED.store(true, Ordering::SeqCst);
    for dir in staging.drain(..) {
        // Best effort: the process is about to exit.
        let _ = std::fs::remove_dir_all(dir);
    }
    // The guard is dropped here; the caller exits right after.
}

/// Whether the process `pid` is alive, when the operating system says (Linux's `/proc`).
fn process_alive(pid: u32) -> Option<bool> {
    let proc = Path::new("/proc");
    proc.join("self")
        .exists()
        .then(|| proc.join(pid.to_string()).exists())
}

/// Removes the staging folders that a killed process left in `dir` (see the module docs).
fn sweep_stale(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(rest) = name.to_str().and_then(|n| n.strip_prefix(STAGING_PREFIX)) else {
            continue;
        };
        let pid = rest.split('-').next().and_then(|p| p.parse::<u32>().ok());
        let stale = match pid.and_then(process_alive) {
            Some(alive) => !alive,
            None => entry
                .metadata()
                .and_then(|m| m.modified())
                .ok()
                .and_then(|t| t.elapsed().ok())
                .is_some_and(|age| age.as_secs() > STALE_STAGING_SECONDS),
        };
        if stale && pid != Some(std::process::id()) {
            // Best effort: another run may be sweeping it at the same time.
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

/// Creates `dir` and its missing parents; returns the topmost folder it created, if any.
fn create_folder(dir: &Path) -> Result<Option<PathBuf>, DataFileError> {
    let mut missing = None;
    let mut p = Some(dir);
    while let Some(d) = p {
        if d.as_os_str().is_empty() || d.exists() {
            break;
        }
        missing = Some(d.to_path_buf());
        p = d.parent();
    }
    std::fs::create_dir_all(dir).map_err(io_error(dir))?;
    Ok(missing)
}

/// Writes `bytes` to a new file at `path` (mode `0666` less the umask) and syncs it.
fn write_new(path: &Path, bytes: &[u8]) -> Result<(), DataFileError> {
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
        .map_err(io_error(path))?;
    file.write_all(bytes).map_err(io_error(path))?;
    file.sync_all().map_err(io_error(path))
}

/// A set of files written into one folder all or nothing (see the module docs).
///
/// ```
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// use ibc_pipeline::data::io::StagedFiles;
/// let dir = tempfile::tempdir()?;
/// let out = dir.path().join("result");
/// let mut files = StagedFiles::new(&out)?;
/// files.stage(out.join("a.txt"), b"first")?;
/// files.stage(out.join("sub/b.txt"), b"second")?;
/// assert!(!out.join("a.txt").exists()); // nothing is visible before the commit
/// let written = files.commit()?;
/// assert_eq!(written.len(), 2);
/// assert_eq!(std::fs::read(out.join("sub/b.txt"))?, b"second");
/// assert_eq!(std::fs::read_dir(&out)?.count(), 2); // a.txt and sub/: no staging folder
///
/// // Dropped without a commit: nothing, not even the folder it created.
/// let other = dir.path().join("other");
/// let mut files = StagedFiles::new(&other)?;
/// files.stage(other.join("a.txt"), b"lost")?;
/// drop(files);
/// assert!(!other.exists());
/// # Ok(())
/// # }
/// ```
#[derive(Debug)]
pub struct StagedFiles {
    /// The output folder.
    dir: PathBuf,
    /// The hidden staging folder inside it.
    staging: PathBuf,
    /// The topmost folder [`new`](Self::new) created, removed again if nothing is committed.
    created: Option<PathBuf>,
    /// (path relative to `dir`, target path), in staging order.
    staged: Vec<(PathBuf, PathBuf)>,
    /// Set once the files are in place.
    committed: bool,
}

impl StagedFiles {
    /// A set of files to be written into `dir`, which is created if missing. Stale staging
    /// folders of killed runs in `dir` are removed first.
    ///
    /// # Errors
    /// [`DataFileError::Io`] naming the folder that cannot be created, or the staging folder
    /// once [`remove_staged_outputs`] has cancelled the process's outputs.
    pub fn new(dir: impl AsRef<Path>) -> Result<Self, DataFileError> {
        let dir = dir.as_ref().to_path_buf();
        let created = create_folder(&dir)?;
        sweep_stale(&dir);
        let n = NEXT_STAGING.fetch_add(1, Ordering::Relaxed);
        let staging = dir.join(format!("{STAGING_PREFIX}{}-{n}", std::process::id()));
        let mut registry = registry();
        let made = if CANCELLED.load(Ordering::SeqCst) {
            Err(std::io::Error::new(
                std::io::ErrorKind::Interrupted,
                "the output was cancelled (interrupted)",
            ))
        } else {
            std::fs::create_dir(&staging)
        };
        if let Err(e) = made {
            drop(registry);
            if let Some(top) = &created {
                let _ = std::fs::remove_dir_all(top);
            }
            return Err(io_error(&staging)(e));
        }
        registry.push(staging.clone());
        Ok(Self {
            dir,
            staging,
            created,
            staged: Vec::new(),
            committed: false,
        })
    }

    /// Writes `bytes` into the staging folder, to be renamed to `path` (inside the output
    /// folder, subfolders allowed) by [`commit`](Self::commit).
    ///
    /// # Errors
    /// [`DataFileError::Io`] naming `path`: a path outside the output folder or staged twice,
    /// a write that fails, or a set whose staging folder was removed by
    /// [`remove_staged_outputs`].
    pub fn stage(&mut self, path: impl AsRef<Path>, bytes: &[u8]) -> Result<(), DataFileError> {
        let path = path.as_ref();
        let invalid = |message: &str| {
            io_error(path)(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                message.to_owned(),
            ))
        };
        let relative = path
            .strip_prefix(&self.dir)
            .ok()
            .filter(|r| {
                !r.as_os_str().is_empty()
                    && r.components()
                        .all(|c| matches!(c, std::path::Component::Normal(_)))
            })
            .ok_or_else(|| invalid("not a file inside the output folder"))?
            .to_path_buf();
        if self.staged.iter().any(|(r, _)| *r == relative) {
            return Err(invalid("staged twice"));
        }
        let registry = registry();
        if !registry.contains(&self.staging) {
            return Err(invalid("the output was cancelled (interrupted)"));
        }
        let staged = self.staging.join(&relative);
        if let Some(parent) = staged.parent() {
            std::fs::create_dir_all(parent).map_err(io_error(path))?;
        }
        write_new(&staged, bytes).map_err(|e| match e {
            DataFileError::Io(IoError::Os { source, .. }) => io_error(path)(source),
            other => other,
        })?;
        drop(registry);
        self.staged.push((relative, path.to_path_buf()));
        Ok(())
    }

    /// Renames every staged file to its target, in staging order, and returns the targets.
    ///
    /// # Errors
    /// [`DataFileError::Io`] naming the file whose rename failed. The files renamed before it
    /// are removed again (best effort) and the staging folder is removed, so no partial set
    /// is left.
    pub fn commit(mut self) -> Result<Vec<PathBuf>, DataFileError> {
        let mut registry = registry();
        let Some(position) = registry.iter().position(|s| *s == self.staging) else {
            return Err(io_error(&self.dir)(std::io::Error::new(
                std::io::ErrorKind::Interrupted,
                "the output was cancelled (interrupted)",
            )));
        };
        let mut done: Vec<PathBuf> = Vec::with_capacity(self.staged.len());
        let mut failure = None;
        for (relative, target) in &self.staged {
            let moved = target
                .parent()
                .map_or(Ok(()), std::fs::create_dir_all)
                .and_then(|()| std::fs::rename(self.staging.join(relative), target));
            if let Err(e) = moved {
                failure = Some(io_error(target)(e));
                break;
            }
            done.push(target.clone());
        }
        if let Some(e) = failure {
            for p in &done {
                // Best effort: the error returned is the rename's.
                let _ = std::fs::remove_file(p);
            }
            return Err(e);
        }
        let _ = std::fs::remove_dir_all(&self.staging);
        registry.swap_remove(position);
        self.committed = true;
        Ok(done)
    }
}

impl Drop for StagedFiles {
    fn drop(&mut self) {
        let mut registry = registry();
        registry.retain(|s| *s != self.staging);
        let _ = std::fs::remove_dir_all(&self.staging);
        if !self.committed
            && let Some(top) = &self.created
        {
            let _ = std::fs::remove_dir_all(top);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stale_staging_folder_of_a_dead_process_is_swept() {
        let dir = tempfile::tempdir().unwrap();
        // A process id that is not alive: the largest pid the kernel may hand out is lower.
        let dead = dir.path().join(format!("{STAGING_PREFIX}4294967295-0"));
        std::fs::create_dir(&dead).unwrap();
        std::fs::write(dead.join("report.json"), b"{").unwrap();
        let files = StagedFiles::new(dir.path()).unwrap();
        if process_alive(1).is_some() {
            assert!(!dead.exists());
        }
        drop(files);
        // The folder existed before: it stays, empty of staging.
        assert!(dir.path().exists());
    }

    #[test]
    fn files_take_the_umask_modes_and_paths_outside_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let mut files = StagedFiles::new(dir.path()).unwrap();
        assert!(files.stage(dir.path().join("../x"), b"").is_err());
        assert!(files.stage("/elsewhere/x", b"").is_err());
        files.stage(dir.path().join("a.txt"), b"a").unwrap();
        assert!(files.stage(dir.path().join("a.txt"), b"a").is_err());
        files.commit().unwrap();
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(dir.path().join("a.txt"))
                .unwrap()
                .permissions()
                .mode();
            // Readable by the group and others unless the umask forbids it; never 0600 by
            // construction.
            assert_ne!(mode & 0o777, 0o600, "{mode:o}");
        }
    }

    #[test]
    fn removing_staged_outputs_cancels_the_set() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        let mut files = StagedFiles::new(&out).unwrap();
        files.stage(out.join("a.txt"), b"a").unwrap();
        // What `remove_staged_outputs` does, for this set only (other tests of this process
        // have sets of their own).
        registry().retain(|s| *s != files.staging);
        std::fs::remove_dir_all(&files.staging).unwrap();
        assert!(files.stage(out.join("b.txt"), b"b").is_err());
        assert!(files.commit().is_err());
        assert!(!out.exists());
    }
}
