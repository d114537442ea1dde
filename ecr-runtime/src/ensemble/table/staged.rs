//! The atomic write of a table, a part or an NPY file: written beside its target as
//! `.NAME.ecr-partial-<hash>`, locked while a run writes it, synced and renamed onto the
//! target when complete (see the [module docs](super)). Its two shared steps,
//! [`remove_stale`] and [`put_in_place`], also write the `ecr` command's output files.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use super::hex;
use crate::error::{Error, Result};

/// A file written beside its target and renamed onto it when complete.
pub(crate) struct Staged {
    pub(super) shown: String,
    target: PathBuf,
    pub(super) stage: PathBuf,
    pub(crate) file: BufWriter<File>,
    /// Remove the file when dropped unfinished (a merge's), rather than keep it for a resume.
    pub(crate) discard: bool,
}

impl Drop for Staged {
    fn drop(&mut self) {
        if self.discard {
            let _ = fs::remove_file(&self.stage);
        }
    }
}

/// The target of `path`: symlinks of its last component followed (at most 40).
pub(super) fn follow(path: &Path) -> Result<PathBuf> {
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        match fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let link = fs::read_link(&p).map_err(|e| {
                    Error::Io(format!("cannot read the symlink '{}': {e}", p.display()))
                })?;
                p = p.parent().unwrap_or(Path::new("")).join(link);
            }
            _ => return Ok(p),
        }
    }
    Err(Error::Io(format!(
        "'{}': too many levels of symlinks",
        path.display()
    )))
}

/// Locks `file` (`flock`, exclusive, without waiting): `Ok(false)` if another process holds
/// it; `Ok(true)` where locks do not work (nothing to tell then).
fn try_lock(file: &File) -> io::Result<bool> {
    #[cfg(unix)]
    {
        use std::os::unix::io::AsRawFd;
        // SAFETY: flock on a descriptor owned by `file`.
        if unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } != 0 {
            let e = io::Error::last_os_error();
            return match e.kind() {
                io::ErrorKind::WouldBlock => Ok(false),
                _ => Ok(true),
            };
        }
    }
    let _ = file;
    Ok(true)
}

/// Whether `file` can be locked (`flock`, exclusive, without waiting), that is no process
/// holds it: `false` where locks do not work (nothing can be told then).
fn lock_free(file: &File) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::io::AsRawFd;
        // SAFETY: flock on a descriptor owned by `file`.
        unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) == 0 }
    }
    #[cfg(not(unix))]
    {
        let _ = file;
        false
    }
}

/// Removes the files of `dir` whose names start with `prefix` that no process holds locked
/// (`flock`): the staging files that killed runs left. Where locks do not work (some network
/// filesystems) nothing is taken for stale, and nothing is removed.
pub fn remove_stale(dir: &Path, prefix: &str) {
    let Ok(list) = fs::read_dir(dir) else {
        return;
    };
    for entry in list.flatten() {
        let ours = entry
            .file_name()
            .to_str()
            .is_some_and(|f| f.starts_with(prefix));
        if ours && entry.file_type().is_ok_and(|t| t.is_file()) {
            if let Ok(f) = File::open(entry.path()) {
                if lock_free(&f) {
                    let _ = fs::remove_file(entry.path());
                }
            }
        }
    }
}

/// Why [`put_in_place`] failed.
#[derive(Debug)]
pub enum PutError {
    /// Writing or syncing the staged data failed: the target is as it was.
    Write(io::Error),
    /// The rename onto the target failed: the target is as it was, the staged file complete.
    Rename(io::Error),
}

/// The last step of an atomic write: flushes and syncs (`fsync`) the staged `file`, renames
/// `stage` onto `target` in one step, then syncs the directory (where it can be opened), so
/// that `target` holds the previous file or the complete new one, never a part.
///
/// # Errors
/// [`PutError`]: which step failed.
pub fn put_in_place(
    file: &mut BufWriter<File>,
    stage: &Path,
    target: &Path,
) -> std::result::Result<(), PutError> {
    file.flush()
        .and_then(|()| file.get_ref().sync_all())
        .map_err(PutError::Write)?;
    fs::rename(stage, target).map_err(PutError::Rename)?;
    let dir = match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// Free bytes for an unprivileged writer on the filesystem of `dir`, where the system says.
pub(super) fn free_bytes(dir: &Path) -> Option<u128> {
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        let c = std::ffi::CString::new(dir.as_os_str().as_bytes()).ok()?;
        // SAFETY: statvfs fills the zeroed plain-data struct; the path is NUL-terminated.
        let mut st: libc::statvfs = unsafe { std::mem::zeroed() };
        if unsafe { libc::statvfs(c.as_ptr(), &mut st) } == 0 {
            return Some(st.f_bavail as u128 * st.f_frsize as u128);
        }
    }
    let _ = dir;
    None
}

impl Staged {
    /// The unfinished file for `path` named by `identity`: created (or, with `resume`,
    /// opened as it is) and locked. Without `resume`, the unfinished files of `path` that no
    /// run holds are removed first.
    pub(crate) fn open(path: &Path, identity: &str, resume: bool) -> Result<(Staged, File)> {
        let shown = path.display().to_string();
        let target = follow(path)?;
        let name = target
            .file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(|| {
                Error::Io(format!(
                    "output file '{shown}' must end in a file name (UTF-8)"
                ))
            })?
            .to_string();
        let parent = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        if target.is_dir() {
            return Err(Error::Io(format!("output file '{shown}' is a directory")));
        }
        if !parent.is_dir() {
            return Err(Error::Io(format!(
                "cannot write output file '{shown}': directory '{}' does not exist",
                parent.display()
            )));
        }
        let short: String = name.chars().take(180).collect();
        let prefix = format!(".{short}.ecr-partial-");
        let hash = hex(&Sha256::digest(identity.as_bytes()))[..16].to_string();
        let stage = parent.join(format!("{prefix}{hash}"));
        if !resume {
            remove_stale(&parent, &prefix);
        }
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&stage)
            .map_err(|e| {
                Error::Io(format!(
                    "cannot write output file '{shown}' (unfinished as '{}'): {e}",
                    stage.display()
                ))
            })?;
        if !try_lock(&file).unwrap_or(true) {
            return Err(Error::Io(format!(
                "another run is writing '{shown}' (its unfinished file '{}' is locked)",
                stage.display()
            )));
        }
        let reader = file
            .try_clone()
            .map_err(|e| Error::Io(format!("cannot write '{}': {e}", stage.display())))?;
        Ok((
            Staged {
                shown,
                target,
                stage,
                file: BufWriter::with_capacity(1 << 16, file),
                discard: false,
            },
            reader,
        ))
    }

    pub(super) fn io(&self) -> impl Fn(io::Error) -> Error + '_ {
        move |e| Error::Io(format!("cannot write '{}': {e}", self.stage.display()))
    }

    /// Flushes and syncs the data.
    pub(super) fn sync(&mut self) -> Result<()> {
        self.file.flush().map_err(self.io())?;
        self.file.get_ref().sync_data().map_err(self.io())
    }

    /// Syncs, renames onto the target and syncs the directory ([`put_in_place`]).
    pub(crate) fn commit(mut self) -> Result<()> {
        self.discard = false;
        match put_in_place(&mut self.file, &self.stage, &self.target) {
            Ok(()) => Ok(()),
            Err(PutError::Write(e)) => Err(self.io()(e)),
            Err(PutError::Rename(e)) => Err(Error::Io(format!(
                "cannot put '{}' in place of '{}': {e} (the complete table stays in '{}')",
                self.stage.display(),
                self.shown,
                self.stage.display()
            ))),
        }
    }
}
