//! Output directories that are replaced whole: a command writes into a fresh staging directory
//! beside its `--out` (same filesystem) and puts it in place only when every file is written,
//! so that `--out` always holds the files of exactly one complete run.
//!
//! # Before the work ([`OutputDir::stage`])
//!
//! - `--out` is followed if it is a symlink: the files go to the directory it points to (which
//!   is created if missing, in a directory that must exist), and the link stays.
//! - `--out`, if it exists, must be a directory that a rename can replace: not a mount point,
//!   not immutable or append-only (`chattr +i`, `+a`), not another user's in a sticky
//!   directory. If it holds anything, it must hold [`MARKER`], the file ecr writes into every
//!   output directory, unless the user passes `--force`: ecr does not replace a directory of
//!   someone else's files.
//! - The staging directory `.<name>.ecr-new-<pid>-<k>` is created beside `<name>` (which proves
//!   that the parent takes new entries) and locked (`flock` on the directory, held until the
//!   process ends); two probe directories are created, swapped and removed, which proves that
//!   renames work there and tells whether the atomic exchange is available.
//!
//! Each of these is a one-line error before any work.
//!
//! # The commit ([`OutputDir::commit`])
//!
//! [`MARKER`] is written last into the staging directory, which is then swapped with
//! `<name>` in one step (`renameat2(RENAME_EXCHANGE)`, Linux) or, where the system cannot swap
//! directories (other systems, some network filesystems), by two renames:
//!
//! | step | `<name>` | `.<name>.ecr-old-<id>` | `.<name>.ecr-new-<id>` |
//! |---|---|---|---|
//! | before | previous files | — | new files, complete |
//! | 1. rename `<name>` → `-old-` | missing | previous files | new files |
//! | 2. rename `-new-` → `<name>` | new files | previous files | — |
//! | 3. rename `-old-` → `-del-`, remove | new files | — | — |
//!
//! A process killed after step 1 and before step 2 leaves no `<name>`: the next run with the
//! same `--out` (any command that writes one), before anything else, renames the `-old-`
//! directory back to `<name>`; a failed step 2 does the same at once. Only whole directories
//! are renamed, so `-old-` always holds a complete previous output (a partly removed one is
//! first renamed to `-del-`, which is never restored).
//!
//! If the commit fails all the same (the parent turned read-only during the run, say), the
//! staged files are kept, renamed to `<name>.ecr-kept-<pid>-<k>` where possible, and the
//! one-line error names where they are.
//!
//! # Concurrent runs and leftovers
//!
//! Runs take a lock on the parent directory (`flock`, briefly: while they create their staging
//! directory, commit, or clean up) and one on their staging directory (for the whole run). A
//! staging directory that can be locked belongs to no live run, whatever its name says (a run
//! in another PID namespace has a process id that means nothing here): runs remove those, and
//! `-old-` and `-del-` directories left by killed runs, beside their `--out`. Where `flock`
//! does not work (some network filesystems), nothing is treated as stale: leftovers stay.
//!
//! # Single files ([`OutputFile`])
//!
//! A command whose `--out` is one file (`ecr ensemble`) writes it the same way: into
//! `.<name>.ecr-new-<pid>-<k>` beside it, created (and locked) before the work, which proves
//! that the directory takes new files; at the end the data is written there, synced, and the
//! file renamed over `<name>` in one step. `<name>` holds the previous file or the complete new
//! one, never a part; a run killed before the rename leaves only its hidden staging file,
//! which the next run with the same `--out` removes (it is stale when it can be locked). The
//! removal and the last step are the library's, shared with the ensemble tables
//! (`ecr_runtime::ensemble::table::{remove_stale, put_in_place}`).

use super::UsageError;
use ecr_runtime::ensemble::table::{PutError, put_in_place, remove_stale};
use std::fs::{self, File};
use std::io;
use std::path::{Path, PathBuf};

/// The file that marks a directory as an output of ecr (written into every output directory,
/// last): a non-empty `--out` without it is replaced only with `--force`.
pub const MARKER: &str = ".ecr-output";

/// A staging directory for the files of one run, put in place by [`commit`](Self::commit);
/// removed if dropped before (an error on the way).
pub struct OutputDir {
    /// `--out` as given, for messages.
    shown: PathBuf,
    /// Where the files go: `--out` with symlinks followed.
    target: PathBuf,
    parent: PathBuf,
    /// The target's name as it appears in the names beside it ([`side_tag`]).
    tag: String,
    /// `<pid>-<k>`: the staging directory's suffix, shared by its `-old-`, `-del-` and
    /// `-kept-` names.
    id: String,
    stage: PathBuf,
    /// The staging directory, open and locked for the life of the run.
    _lock: Option<File>,
    /// Whether the atomic exchange worked on the probe directories.
    exchange: bool,
    force: bool,
    command: &'static str,
    done: bool,
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

/// The longest file name most filesystems take (`NAME_MAX` on Linux), in bytes.
const NAME_MAX: usize = 255;

/// The most that the names beside the target add to its name: `.` before it, then
/// `.ecr-kept-`, a process id (up to 10 digits), `-`, a counter (up to 4) and a probe's `-a`.
const SIDE_OVERHEAD: usize = 1 + ".ecr-kept-".len() + 10 + 1 + 4 + 2;

/// The target's name as the staging, `-old-`, `-del-` and `-kept-` names beside it carry it:
/// the name itself where these fit in [`NAME_MAX`] bytes, otherwise its first bytes, `~` and
/// 16 hex digits of a hash of the whole name (FNV-1a, 64 bits), so that any legal `--out`
/// name can be staged and the leftovers of one target are still told apart from another's.
fn side_tag(name: &str) -> String {
    let room = NAME_MAX - SIDE_OVERHEAD;
    if name.len() <= room {
        return name.to_string();
    }
    let hash = name.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    });
    let mut cut = room - 17;
    while !name.is_char_boundary(cut) {
        cut -= 1;
    }
    format!("{}~{hash:016x}", &name[..cut])
}

/// `--out` with its symlinks followed (the last component; at most 40 links; a trailing `/` or
/// `/.` dropped first), and whether it was a link.
fn follow(out: &Path) -> Result<(PathBuf, bool), UsageError> {
    // Without a trailing slash or "." (`link/` names the link's target, which a rename of
    // `link/` would not replace): the components, put back together.
    let out: PathBuf = out.components().collect();
    let out = out.as_path();
    let mut path = out.to_path_buf();
    for _ in 0..40 {
        match fs::symlink_metadata(&path) {
            Ok(m) if m.file_type().is_symlink() => {
                let link = fs::read_link(&path).map_err(|e| {
                    UsageError(format!("cannot read the symlink '{}': {e}", path.display()))
                })?;
                // A relative link is relative to the link's directory; join keeps an absolute one.
                path = path.parent().unwrap_or(Path::new("")).join(link);
            }
            _ => {
                let linked = path != out;
                return Ok((path, linked));
            }
        }
    }
    Err(UsageError(format!(
        "output directory '{}': too many levels of symlinks",
        out.display()
    )))
}

/// Locks the directory `dir` exclusively (`flock` on it): with `wait`, waits for another
/// process's lock, otherwise `Ok(None)` if another process holds it. `Err` where the directory
/// cannot be opened or `flock` does not work.
fn lock(dir: &Path, wait: bool) -> io::Result<Option<File>> {
    use std::os::unix::io::AsRawFd;
    let file = File::open(dir)?;
    let op = if wait {
        libc::LOCK_EX
    } else {
        libc::LOCK_EX | libc::LOCK_NB
    };
    // SAFETY: flock on a descriptor this function owns.
    if unsafe { libc::flock(file.as_raw_fd(), op) } == 0 {
        return Ok(Some(file));
    }
    let e = io::Error::last_os_error();
    if e.kind() == io::ErrorKind::WouldBlock {
        Ok(None)
    } else {
        Err(e)
    }
}

/// Swaps two directories atomically; `Ok(false)` where the system cannot.
#[cfg(target_os = "linux")]
fn exchange(a: &Path, b: &Path) -> io::Result<bool> {
    use std::ffi::CString;
    use std::os::unix::ffi::OsStrExt;
    let c = |p: &Path| CString::new(p.as_os_str().as_bytes()).map_err(io::Error::other);
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
    let e = io::Error::last_os_error();
    match e.raw_os_error() {
        Some(libc::EINVAL | libc::ENOSYS | libc::EOPNOTSUPP) => Ok(false),
        _ => Err(e),
    }
}

#[cfg(not(target_os = "linux"))]
fn exchange(_: &Path, _: &Path) -> io::Result<bool> {
    Ok(false)
}

/// Whether `dir` is the root of a mounted filesystem (statx's `STATX_ATTR_MOUNT_ROOT`, which
/// also sees bind mounts of the same filesystem; else a device other than its parent's).
fn is_mount_point(dir: &Path, parent: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    #[cfg(all(target_os = "linux", any(target_env = "gnu", target_env = "musl")))]
    {
        use std::os::unix::ffi::OsStrExt;
        if let Ok(c) = std::ffi::CString::new(dir.as_os_str().as_bytes()) {
            // SAFETY: statx fills the zeroed plain-data struct; the path is NUL-terminated.
            let mut st: libc::statx = unsafe { std::mem::zeroed() };
            let rc = unsafe {
                libc::statx(
                    libc::AT_FDCWD,
                    c.as_ptr(),
                    libc::AT_SYMLINK_NOFOLLOW,
                    libc::STATX_BASIC_STATS,
                    &mut st,
                )
            };
            let bit = libc::STATX_ATTR_MOUNT_ROOT as u64;
            if rc == 0 && st.stx_attributes_mask & bit != 0 {
                return st.stx_attributes & bit != 0;
            }
        }
    }
    match (fs::metadata(dir), fs::metadata(parent)) {
        (Ok(d), Ok(p)) => d.dev() != p.dev(),
        _ => false,
    }
}

/// The inode flags of `dir` that forbid renaming it: "immutable" or "append-only", if set.
#[cfg(target_os = "linux")]
fn frozen(dir: &Path) -> Option<&'static str> {
    use std::os::unix::io::AsRawFd;
    const FS_IMMUTABLE_FL: libc::c_int = 0x10;
    const FS_APPEND_FL: libc::c_int = 0x20;
    let file = File::open(dir).ok()?;
    let mut flags: libc::c_int = 0;
    // SAFETY: FS_IOC_GETFLAGS writes an int through the pointer.
    let rc = unsafe {
        libc::ioctl(
            file.as_raw_fd(),
            libc::FS_IOC_GETFLAGS,
            &mut flags as *mut libc::c_int,
        )
    };
    if rc != 0 {
        return None; // the filesystem has no such flags
    }
    if flags & FS_IMMUTABLE_FL != 0 {
        Some("immutable (chattr +i)")
    } else if flags & FS_APPEND_FL != 0 {
        Some("append-only (chattr +a)")
    } else {
        None
    }
}

#[cfg(not(target_os = "linux"))]
fn frozen(_: &Path) -> Option<&'static str> {
    None
}

/// Another user's directory in a sticky directory (such as /tmp), which only its owner, the
/// directory's owner or root may rename.
fn sticky_foreign(dir: &Path, parent: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    // SAFETY: geteuid has no preconditions.
    let me = unsafe { libc::geteuid() };
    match (fs::symlink_metadata(dir), fs::metadata(parent)) {
        (Ok(d), Ok(p)) => me != 0 && p.mode() & 0o1000 != 0 && d.uid() != me && p.uid() != me,
        _ => false,
    }
}

/// The entries of `dir` other than [`MARKER`], and whether it holds [`MARKER`].
fn entries(dir: &Path) -> io::Result<(usize, bool)> {
    let mut count = 0;
    let mut marked = false;
    for entry in fs::read_dir(dir)? {
        if entry?.file_name() == MARKER {
            marked = true;
        } else {
            count += 1;
        }
    }
    Ok((count, marked))
}

impl OutputDir {
    /// Checks that `out` can be replaced, and creates its staging directory: see the module
    /// docs. `force` replaces a non-empty directory without [`MARKER`]; `command` is named in
    /// the marker.
    ///
    /// # Errors
    /// One line naming the directory and what is wrong: not a directory, a dangling symlink
    /// into a missing directory, a mount point, immutable, a directory ecr did not write
    /// (without `force`), or a parent that takes no new entries or renames.
    pub fn stage(out: &Path, force: bool, command: &'static str) -> Result<Self, UsageError> {
        let shown = out.display();
        let (target, linked) = follow(out)?;
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
        if linked && !parent.is_dir() {
            return Err(UsageError(format!(
                "output directory '{shown}' is a symlink to '{}', in a directory that does \
                 not exist ('{}')",
                target.display(),
                parent.display()
            )));
        }
        if target.exists() && !target.is_dir() {
            return Err(UsageError(format!(
                "cannot create output directory '{shown}': it exists and is not a directory"
            )));
        }
        fs::create_dir_all(&parent)
            .map_err(|e| UsageError(format!("cannot create output directory '{shown}': {e}")))?;
        let mut dir = OutputDir {
            shown: out.to_path_buf(),
            target,
            parent,
            tag: side_tag(&name),
            id: String::new(),
            stage: PathBuf::new(),
            _lock: None,
            exchange: false,
            force,
            command,
            done: true, // nothing to remove yet
        };
        let guard = lock(&dir.parent, true).ok().flatten();
        dir.recover(guard.is_some());
        dir.check_replaceable()?;
        dir.create_stage()?;
        dir.exchange = dir.probe()?;
        drop(guard);
        Ok(dir)
    }

    /// Where the files go until [`commit`](Self::commit).
    pub fn path(&self) -> &Path {
        &self.stage
    }

    /// `.<name>.ecr-<kind>-<id>` beside the target.
    fn side(&self, kind: &str, id: &str) -> PathBuf {
        self.parent.join(format!(".{}.ecr-{kind}-{id}", self.tag))
    }

    /// Cleans up beside the target after killed runs (see the module docs): restores the
    /// newest `-old-` directory if the target is missing; removes staging directories that no
    /// run holds, `-del-` directories, and (with the parent's lock, `locked`) other `-old-`
    /// ones.
    fn recover(&self, locked: bool) {
        let Ok(list) = fs::read_dir(&self.parent) else {
            return;
        };
        let prefix = format!(".{}.ecr-", self.tag);
        let mut olds = Vec::new();
        for entry in list.flatten() {
            let file = entry.file_name();
            let Some(rest) = file.to_str().and_then(|f| f.strip_prefix(&prefix)) else {
                continue;
            };
            let path = entry.path();
            if !entry.file_type().is_ok_and(|t| t.is_dir()) {
                continue;
            }
            if rest.starts_with("new-") {
                // Stale if no run holds its lock; kept if it cannot be told.
                if let Ok(Some(_held)) = lock(&path, false) {
                    let _ = fs::remove_dir_all(&path);
                }
            } else if rest.starts_with("old-") {
                let modified = entry.metadata().and_then(|m| m.modified()).ok();
                olds.push((modified, path));
            } else if rest.starts_with("del-") {
                let _ = fs::remove_dir_all(&path);
            }
        }
        olds.sort();
        if fs::symlink_metadata(&self.target).is_err() {
            if let Some((_, newest)) = olds.pop() {
                let _ = fs::rename(&newest, &self.target);
            }
        }
        if locked {
            for (_, old) in olds {
                let _ = fs::remove_dir_all(old);
            }
        }
    }

    /// The checks on an existing target: see [`stage`](Self::stage).
    fn check_replaceable(&self) -> Result<(), UsageError> {
        let shown = self.shown.display();
        if !self.target.is_dir() {
            return Ok(());
        }
        if is_mount_point(&self.target, &self.parent) {
            return Err(UsageError(format!(
                "output directory '{shown}' is a mount point, which ecr cannot replace whole: \
                 use a directory inside it"
            )));
        }
        if let Some(what) = frozen(&self.target) {
            return Err(UsageError(format!(
                "output directory '{shown}' is {what}: ecr cannot replace it"
            )));
        }
        if sticky_foreign(&self.target, &self.parent) {
            return Err(UsageError(format!(
                "output directory '{shown}' belongs to another user in a sticky directory: \
                 ecr cannot replace it"
            )));
        }
        self.check_ours()
    }

    /// A non-empty target without [`MARKER`] is refused unless `force`.
    fn check_ours(&self) -> Result<(), UsageError> {
        let (count, marked) = entries(&self.target).map_err(|e| {
            UsageError(format!(
                "cannot read output directory '{}': {e}",
                self.shown.display()
            ))
        })?;
        if count > 0 && !marked && !self.force {
            return Err(UsageError(format!(
                "output directory '{}' holds {count} {} that ecr did not write (it has no \
                 {MARKER}); ecr replaces --out whole: pass --force to replace it, or choose \
                 another --out",
                self.shown.display(),
                if count == 1 { "entry" } else { "entries" }
            )));
        }
        Ok(())
    }

    /// Creates and locks `.<name>.ecr-new-<pid>-<k>`, the first k whose name is free.
    fn create_stage(&mut self) -> Result<(), UsageError> {
        let pid = std::process::id();
        let mut k = 0u32;
        loop {
            let id = format!("{pid}-{k}");
            let stage = self.side("new", &id);
            match fs::create_dir(&stage) {
                Ok(()) => {
                    self.id = id;
                    self.stage = stage;
                    self.done = false;
                    // Where flock does not work, the directory stays unlocked; other runs then
                    // cannot tell it stale and leave it.
                    self._lock = lock(&self.stage, true).ok().flatten();
                    return Ok(());
                }
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists && k < 1000 => k += 1,
                Err(e) => {
                    return Err(UsageError(format!(
                        "cannot write output directory '{}' (staging it as '{}'): {e}",
                        self.shown.display(),
                        stage.display()
                    )));
                }
            }
        }
    }

    /// Creates two directories beside the target, swaps and removes them: `Ok(true)` if the
    /// atomic exchange works, `Ok(false)` if only plain renames do.
    fn probe(&self) -> Result<bool, UsageError> {
        let a = self.side("del", &format!("{}-a", self.id));
        let b = self.side("del", &format!("{}-b", self.id));
        let result = fs::create_dir(&a)
            .and_then(|()| fs::create_dir(&b))
            .and_then(|()| match exchange(&a, &b) {
                Ok(true) => Ok(true),
                Ok(false) => fs::rename(&a, &b).map(|()| false),
                Err(e) => Err(e),
            });
        let _ = fs::remove_dir(&a);
        let _ = fs::remove_dir(&b);
        result.map_err(|e| {
            UsageError(format!(
                "cannot rename directories in '{}', where output directory '{}' is replaced: {e}",
                self.parent.display(),
                self.shown.display()
            ))
        })
    }

    /// Puts the staged directory in place of the target (see the module docs) and removes the
    /// previous one.
    ///
    /// # Errors
    /// One line if the marker cannot be written (the staged files are removed), or if the
    /// directory cannot be put in place: then the staged files are kept and the line names
    /// where they are.
    pub fn commit(mut self) -> Result<Replaced, UsageError> {
        let marker = format!(
            "Written by `ecr {}` (ecr {}). The next run with this --out replaces this directory \
             whole; ecr replaces a directory without this file only with --force.\n",
            self.command,
            env!("CARGO_PKG_VERSION")
        );
        let path = self.stage.join(MARKER);
        fs::write(&path, marker)
            .map_err(|e| UsageError(format!("cannot write '{}': {e}", path.display())))?;
        let guard = lock(&self.parent, true).ok().flatten();
        let result = self.put_in_place();
        drop(guard);
        match result {
            Ok((replaced, previous)) => {
                self.done = true;
                if let Some(previous) = previous {
                    let _ = fs::remove_dir_all(previous);
                }
                Ok(replaced)
            }
            Err(e) => Err(self.keep(&e)),
        }
    }

    /// The renames of [`commit`](Self::commit), under the parent's lock: what was replaced,
    /// and where the previous directory is now (to be removed).
    fn put_in_place(&self) -> Result<(Replaced, Option<PathBuf>), String> {
        let io = |e: io::Error| e.to_string();
        match fs::symlink_metadata(&self.target) {
            Err(e) if e.kind() == io::ErrorKind::NotFound => {
                fs::rename(&self.stage, &self.target).map_err(io)?;
                return Ok((Replaced(None), None));
            }
            Err(e) => return Err(e.to_string()),
            Ok(m) if !m.is_dir() => return Err("it is no longer a directory".to_string()),
            Ok(_) => {}
        }
        self.check_ours().map_err(|e| e.0)?;
        let (count, _) = entries(&self.target).map_err(io)?;
        if self.exchange && exchange(&self.stage, &self.target).map_err(io)? {
            return Ok((Replaced(Some(count)), Some(self.stage.clone())));
        }
        let old = self.side("old", &self.id);
        fs::rename(&self.target, &old).map_err(io)?;
        if let Err(e) = fs::rename(&self.stage, &self.target) {
            let _ = fs::rename(&old, &self.target);
            return Err(e.to_string());
        }
        let del = self.side("del", &self.id);
        let previous = if fs::rename(&old, &del).is_ok() {
            del
        } else {
            old
        };
        Ok((Replaced(Some(count)), Some(previous)))
    }

    /// After a failed commit: keeps the staged files (renamed to `<name>.ecr-kept-<id>` if
    /// possible) and returns the error naming them.
    fn keep(&mut self, why: &str) -> UsageError {
        self.done = true;
        let kept = self
            .parent
            .join(format!("{}.ecr-kept-{}", self.tag, self.id));
        let place = if fs::rename(&self.stage, &kept).is_ok() {
            kept
        } else {
            self.stage.clone()
        };
        UsageError(format!(
            "cannot put the new files in place of '{}' ({why}); they are complete in '{}'",
            self.shown.display(),
            place.display()
        ))
    }
}

impl Drop for OutputDir {
    fn drop(&mut self) {
        if !self.done {
            let _ = fs::remove_dir_all(&self.stage);
        }
    }
}

/// A file replaced whole (see the module docs): staged before the work, put in place by
/// [`commit`](Self::commit); the staging file is removed if dropped before.
pub struct OutputFile {
    /// `--out` as given, for messages.
    shown: PathBuf,
    /// Where the file goes: `--out` with symlinks followed.
    target: PathBuf,
    stage: PathBuf,
    /// The staging file, open for writing.
    file: io::BufWriter<File>,
    /// The staging file open once more and locked (`flock`) for the life of the run, if
    /// `flock` works there.
    _lock: Option<File>,
    done: bool,
}

impl OutputFile {
    /// Checks that `out` can be written: not a directory, in a directory that takes a new
    /// file (the staging file, created now). Removes staging files of killed runs beside it.
    ///
    /// # Errors
    /// One line naming the file and what is wrong.
    pub fn stage(out: &Path) -> Result<Self, UsageError> {
        let shown = out.display();
        let (target, _) = follow(out)?;
        let name = target
            .file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(|| {
                UsageError(format!(
                    "output file '{shown}' must end in a file name (UTF-8)"
                ))
            })?
            .to_string();
        let parent = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        if target.is_dir() {
            return Err(UsageError(format!("output file '{shown}' is a directory")));
        }
        if !parent.is_dir() {
            return Err(UsageError(format!(
                "cannot write output file '{shown}': directory '{}' does not exist",
                parent.display()
            )));
        }
        // Within NAME_MAX whatever the target's length (see `side_tag`).
        let prefix = format!(".{}.ecr-new-", side_tag(&name));
        remove_stale(&parent, &prefix);
        let pid = std::process::id();
        for k in 0..1000u32 {
            let stage = parent.join(format!("{prefix}{pid}-{k}"));
            match fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&stage)
            {
                Ok(file) => {
                    return Ok(OutputFile {
                        shown: out.to_path_buf(),
                        target,
                        _lock: lock(&stage, true).ok().flatten(),
                        stage,
                        file: io::BufWriter::new(file),
                        done: false,
                    });
                }
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {}
                Err(e) => {
                    return Err(UsageError(format!(
                        "cannot write output file '{shown}' (staging it as '{}'): {e}",
                        stage.display()
                    )));
                }
            }
        }
        Err(UsageError(format!(
            "cannot write output file '{shown}': 1000 staging files of this process beside it"
        )))
    }

    /// Syncs what was written (through [`io::Write`]) and renames the staging file over the
    /// target.
    ///
    /// # Errors
    /// One line if the data cannot be written (the staging file is removed) or the file cannot
    /// be put in place.
    pub fn commit(mut self) -> Result<(), UsageError> {
        let shown = self.shown.display().to_string();
        match put_in_place(&mut self.file, &self.stage, &self.target) {
            Ok(()) => {
                self.done = true;
                Ok(())
            }
            Err(PutError::Write(e)) => Err(UsageError(format!(
                "cannot write output file '{shown}': {e}"
            ))),
            Err(PutError::Rename(e)) => Err(UsageError(format!(
                "cannot put output file '{shown}' in place: {e}"
            ))),
        }
    }
}

/// Writes go to the staging file (buffered); [`OutputFile::commit`] puts them in place.
impl io::Write for OutputFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.file.write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.file.flush()
    }
}

impl Drop for OutputFile {
    fn drop(&mut self) {
        if !self.done {
            let _ = fs::remove_file(&self.stage);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh directory under the temp dir, removed on drop.
    struct Scratch(PathBuf);

    impl Scratch {
        fn new(tag: &str) -> Self {
            let nanos = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_nanos());
            let dir = std::env::temp_dir()
                .join(format!("ecr-output-{tag}-{}-{nanos}", std::process::id()));
            fs::create_dir_all(&dir).unwrap();
            Scratch(dir)
        }
    }

    impl Drop for Scratch {
        fn drop(&mut self) {
            let _ = fs::remove_dir_all(&self.0);
        }
    }

    fn write(dir: &Path, files: &[&str], content: &str) {
        fs::create_dir_all(dir).unwrap();
        for f in files {
            fs::write(dir.join(f), content).unwrap();
        }
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        v.sort();
        v
    }

    /// Commits through the two-rename fallback, as where the exchange is not available.
    #[test]
    fn fallback_commit_replaces_the_directory() {
        let root = Scratch::new("fallback");
        let out = root.0.join("out");
        write(&out, &["a", MARKER], "old");
        let mut staged = OutputDir::stage(&out, false, "test").unwrap();
        staged.exchange = false;
        write(staged.path(), &["b"], "new");
        let replaced = staged.commit().unwrap();
        assert_eq!(replaced.0, Some(1));
        assert_eq!(names(&out), [MARKER, "b"]);
        assert_eq!(names(&root.0), ["out"]);
    }

    /// Every state of a fallback commit killed between its steps is recovered by the next
    /// run: the target holds the previous or the new files, and nothing is left beside it.
    #[test]
    fn every_state_of_a_killed_fallback_commit_is_recovered() {
        let root = Scratch::new("states");
        let out = root.0.join("out");
        let (new, old, del) = (
            root.0.join(".out.ecr-new-1-0"),
            root.0.join(".out.ecr-old-1-0"),
            root.0.join(".out.ecr-del-1-0"),
        );
        // (name, out, -new-, -old-, -del-): which exist; what out must hold after recovery.
        let states: [(&str, bool, bool, bool, bool, &str); 4] = [
            ("before step 1", true, true, false, false, "old"),
            ("after step 1", false, true, true, false, "old"),
            ("after step 2", true, false, true, false, "new"),
            ("during step 3", true, false, false, true, "new"),
        ];
        for (what, has_out, has_new, has_old, has_del, expect) in states {
            let _ = fs::remove_dir_all(&root.0);
            if has_out {
                write(&out, &["f", MARKER], expect);
            }
            if has_new {
                write(&new, &["f", MARKER], "new");
            }
            if has_old {
                write(&old, &["f", MARKER], "old");
            }
            if has_del {
                write(&del, &["f"], "old, partly removed");
            }
            let staged = OutputDir::stage(&out, false, "test").unwrap();
            assert_eq!(fs::read_to_string(out.join("f")).unwrap(), expect, "{what}");
            drop(staged);
            assert_eq!(names(&root.0), ["out"], "{what}");
        }
    }

    /// A legal name of up to `NAME_MAX` bytes (ASCII or not) is staged and committed twice,
    /// through the exchange and the fallback, every name beside it fitting `NAME_MAX`; a
    /// killed commit's `-old-` directory is still recovered. (Staging names used to carry the
    /// whole name: a 250-byte `--out` failed, "File name too long".)
    #[test]
    fn names_up_to_name_max_are_staged_and_recovered() {
        let root = Scratch::new("long");
        let ascii = "x".repeat(NAME_MAX - 5);
        let wide = format!("{}é", "y".repeat(NAME_MAX - 2 - 1));
        for name in [ascii.as_str(), wide.as_str(), &"z".repeat(NAME_MAX)] {
            assert!(name.len() <= NAME_MAX);
            let tag = side_tag(name);
            assert!(tag.len() + SIDE_OVERHEAD <= NAME_MAX, "{}", tag.len());
            // Two names that differ in their last byte only have different tags.
            let mut other = name.to_string();
            other.pop();
            other.push('!');
            assert_ne!(side_tag(&other), tag);
            let out = root.0.join(name);
            for exchange in [true, false] {
                let mut staged = OutputDir::stage(&out, false, "test").unwrap();
                staged.exchange &= exchange;
                write(staged.path(), &["f"], "new");
                staged.commit().unwrap();
                assert_eq!(names(&out), [MARKER, "f"]);
            }
            // A commit killed after its first rename: the next run restores the old files.
            fs::rename(&out, root.0.join(format!(".{tag}.ecr-old-1-0"))).unwrap();
            let staged = OutputDir::stage(&out, false, "test").unwrap();
            assert_eq!(names(&out), [MARKER, "f"]);
            drop(staged);
            assert_eq!(names(&root.0), [name]);
            fs::remove_dir_all(&out).unwrap();
        }
    }

    /// A staged file replaces the target whole at its commit; until then (and if dropped) the
    /// target is untouched and only the hidden staging file exists; a staging file that no run
    /// holds is removed by the next run.
    #[test]
    fn a_file_is_replaced_whole_or_not_at_all() {
        use std::io::Write;
        let root = Scratch::new("file");
        let out = root.0.join("table.csv");
        fs::write(&out, "old\n").unwrap();
        let mut staged = OutputFile::stage(&out).unwrap();
        staged.write_all(b"new, part").unwrap();
        assert_eq!(fs::read_to_string(&out).unwrap(), "old\n");
        drop(staged);
        assert_eq!(names(&root.0), ["table.csv"]);
        assert_eq!(fs::read_to_string(&out).unwrap(), "old\n");
        // What a killed run leaves: a staging file nobody holds.
        fs::write(root.0.join(".table.csv.ecr-new-1-0"), "killed").unwrap();
        let mut staged = OutputFile::stage(&out).unwrap();
        assert_eq!(
            names(&root.0).len(),
            2,
            "the stale one removed, a new one made"
        );
        staged.write_all(b"new\n").unwrap();
        staged.commit().unwrap();
        assert_eq!(fs::read_to_string(&out).unwrap(), "new\n");
        assert_eq!(names(&root.0), ["table.csv"]);
        assert!(
            OutputFile::stage(&root.0).is_err(),
            "a directory is not a file"
        );
    }
}
