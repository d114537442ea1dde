//! Output directories that are replaced whole: a command writes into a fresh staging directory
//! beside its `--out` (same filesystem) and puts it in place only when every file is written,
//! so that `--out` always holds the files of exactly one complete run.
//!
//! [`OutputDir::stage`] creates `.<name>.ecr-new-<pid>` beside `<name>`; [`OutputDir::commit`]
//! swaps it with the old directory in one atomic step (`renameat2(RENAME_EXCHANGE)` on Linux)
//! and removes the old one, now at the staging path. A kill at any moment leaves `<name>` as it
//! was or complete; at most a staging directory stays behind, which the next run beside it
//! removes once its process is gone. Where the exchange is not supported (other systems, some
//! network filesystems), `<name>` is first renamed to `.<name>.ecr-old-<pid>` and the new one
//! renamed in place: a kill between these two renames leaves no `<name>`, the previous run
//! complete in `.<name>.ecr-old-<pid>` and the new one complete in `.<name>.ecr-new-<pid>`.

use super::UsageError;
use std::fs;
use std::path::{Path, PathBuf};

/// A staging directory for the files of one run, put in place by [`commit`](Self::commit);
/// removed if dropped before (an error on the way).
pub struct OutputDir {
    target: PathBuf,
    stage: PathBuf,
    committed: bool,
}

/// What [`OutputDir::commit`] replaced: the number of entries of the previous directory, if
/// there was one.
pub struct Replaced(pub Option<usize>);

impl Replaced {
    /// " (replacing its previous N files)" or "".
    pub fn describe(&self) -> String {
        match self.0 {
            Some(n) => format!(" (replacing its previous {n} files)"),
            None => String::new(),
        }
    }
}

/// Staging and backup names of a directory named `name`: `.<name>.ecr-new-<pid>`, `-old-`.
fn side_name(name: &str, kind: &str, pid: u32) -> String {
    format!(".{name}.ecr-{kind}-{pid}")
}

/// Removes staging and backup directories beside `target` left by processes that are gone.
fn remove_stale(parent: &Path, name: &str) {
    let Ok(entries) = fs::read_dir(parent) else {
        return;
    };
    let prefix = format!(".{name}.ecr-");
    for entry in entries.flatten() {
        let file = entry.file_name();
        let Some(rest) = file.to_str().and_then(|f| f.strip_prefix(&prefix)) else {
            continue;
        };
        let pid = rest
            .strip_prefix("new-")
            .or_else(|| rest.strip_prefix("old-"))
            .and_then(|p| p.parse::<u32>().ok());
        if let Some(pid) = pid {
            let alive = pid == std::process::id() || Path::new(&format!("/proc/{pid}")).exists();
            if !alive {
                let _ = fs::remove_dir_all(entry.path());
            }
        }
    }
}

/// Swaps two directories atomically; `Ok(false)` where the system cannot.
#[cfg(target_os = "linux")]
fn exchange(a: &Path, b: &Path) -> std::io::Result<bool> {
    use std::ffi::CString;
    use std::os::unix::ffi::OsStrExt;
    let c = |p: &Path| CString::new(p.as_os_str().as_bytes()).map_err(std::io::Error::other);
    let (ca, cb) = (c(a)?, c(b)?);
    // SAFETY: two valid NUL-terminated paths, relative to the current directory.
    let rc = unsafe {
        libc::renameat2(
            libc::AT_FDCWD,
            ca.as_ptr(),
            libc::AT_FDCWD,
            cb.as_ptr(),
            libc::RENAME_EXCHANGE,
        )
    };
    if rc == 0 {
        return Ok(true);
    }
    let e = std::io::Error::last_os_error();
    match e.raw_os_error() {
        Some(libc::EINVAL | libc::ENOSYS | libc::EOPNOTSUPP) => Ok(false),
        _ => Err(e),
    }
}

#[cfg(not(target_os = "linux"))]
fn exchange(_: &Path, _: &Path) -> std::io::Result<bool> {
    Ok(false)
}

impl OutputDir {
    /// Creates the staging directory beside `target` (and `target`'s parent if missing).
    ///
    /// # Errors
    /// One line naming the directory if it cannot be created, or if `target` exists and is
    /// not a directory.
    pub fn stage(target: &Path) -> Result<Self, UsageError> {
        let shown = target.display();
        let name = target
            .file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(|| {
                UsageError(format!(
                    "output directory '{shown}' must end in a directory name (UTF-8)"
                ))
            })?
            .to_string();
        let parent = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        if target.exists() && !target.is_dir() {
            return Err(UsageError(format!(
                "cannot create output directory '{shown}': it exists and is not a directory"
            )));
        }
        fs::create_dir_all(&parent)
            .map_err(|e| UsageError(format!("cannot create output directory '{shown}': {e}")))?;
        remove_stale(&parent, &name);
        let stage = parent.join(side_name(&name, "new", std::process::id()));
        let _ = fs::remove_dir_all(&stage);
        fs::create_dir(&stage).map_err(|e| {
            UsageError(format!(
                "cannot write output directory '{shown}' (staging it as '{}'): {e}",
                stage.display()
            ))
        })?;
        Ok(OutputDir {
            target: target.to_path_buf(),
            stage,
            committed: false,
        })
    }

    /// Where the files go until [`commit`](Self::commit).
    pub fn path(&self) -> &Path {
        &self.stage
    }

    /// Puts the staged directory in place of the target, atomically where the system can swap
    /// directories (see the module docs), and removes the previous one.
    ///
    /// # Errors
    /// One line if a rename fails (the staged files stay at [`path`](Self::path)'s name).
    pub fn commit(mut self) -> Result<Replaced, UsageError> {
        let fail = |e: std::io::Error| {
            UsageError(format!(
                "cannot move the new files from '{}' to '{}': {e}",
                self.stage.display(),
                self.target.display()
            ))
        };
        let previous = if self.target.is_dir() {
            let count = fs::read_dir(&self.target).map_or(0, |d| d.count());
            if !exchange(&self.stage, &self.target).map_err(fail)? {
                let name = self
                    .target
                    .file_name()
                    .unwrap_or_default()
                    .to_string_lossy();
                let backup = self
                    .stage
                    .with_file_name(side_name(&name, "old", std::process::id()));
                fs::rename(&self.target, &backup).map_err(fail)?;
                fs::rename(&self.stage, &self.target).map_err(fail)?;
                fs::rename(&backup, &self.stage).map_err(fail)?;
            }
            Some(count)
        } else {
            fs::rename(&self.stage, &self.target).map_err(fail)?;
            None
        };
        // The stage path now holds the previous directory, if any.
        let _ = fs::remove_dir_all(&self.stage);
        self.committed = true;
        Ok(Replaced(previous))
    }
}

impl Drop for OutputDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = fs::remove_dir_all(&self.stage);
        }
    }
}
