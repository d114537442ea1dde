//! Tables of an ensemble: one row per member, written as the members finish, in member order
//! ([`Ensemble::write_table`](super::Ensemble::write_table)), a job killed at any moment
//! keeping the rows it finished; parts of a job array joined by [`merge_parts`].
//!
//! # The table (CSV)
//!
//! A first line `# ecr ensemble table of M members: DESCRIPTION`, the run's
//! [fingerprint](super::fingerprint) (`# NAME: VALUE` lines), a header row, then one row per
//! member in member order: `member`, the [input
//! columns](Table::inputs) (the member's parameters, as the table's function gives them),
//! `status` (`verified`, `ok` for a fixed method that completed, `unverified`, `failed`,
//! `panicked`), the output columns (the cells the output function gives; empty for a member
//! without a solution) and `message` (why the answer is not verified, or the failure); with
//! [`Table::cpu_seconds`], a last column `cpu_seconds` (the member's CPU time, which differs
//! from run to run: without it, every run of the same ensemble writes the same bytes, resumed
//! or not, on any number of threads, ranks or parts). Numbers are written as Rust's `{:?}`
//! writes them, the shortest text that reads back to the same f64 (every bit kept); a field
//! with a comma or a quote is quoted (RFC 4180) and line breaks become spaces.
//!
//! # Unfinished tables and resume
//!
//! The rows go to `.NAME.ecr-partial-<hash>` beside `NAME` (the hash names the table or the
//! part), written to the file at least every 0.1 s
//! ([`FLUSH_EVERY`]: what a killed process leaves), synced (`fsync`) at least once a second
//! and when the run stops, and locked (`flock`) while a run writes it. When every row is there
//! the file is synced and renamed to `NAME` in one step (the directory synced after): `NAME`
//! holds the previous file or the complete new one, never a part, never a mix of two runs. A
//! run with [`Control::resume`](super::Control::resume) reads the unfinished file at `NAME`:
//! if its fingerprint is another run's, it refuses in one line naming the first field that
//! differs and writes nothing; else it keeps the rows that read as the table writes them
//! (whole lines, the next member's index and input cells, as many fields as the header, a
//! known status, every number cell a number written as the table writes numbers), up to the
//! first that does not (cut short by the kill, or changed), and solves the members from
//! there on. A run without it starts over (removing the unfinished files of `NAME` that no
//! run holds).
//!
//! # Parts and merge
//!
//! A part (part k of n, [`Control::part`](super::Control::part)) starts with the line `#
//! ecr ensemble part K/N of M members: DESCRIPTION` (K = k + 1), then the fingerprint, the
//! header and its rows, and ends with `# end of part K/N: R rows, sha256 HEX`, the SHA-256
//! digest of its rows' bytes. [`merge_parts`] checks every part's first line, fingerprint,
//! header, row indices, count and digest while it copies the rows in member order, and
//! refuses parts that are missing, given twice, of another run (naming the field of the
//! fingerprint that differs), unfinished or changed, and an output that is one of its parts.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufRead, BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use sha2::{Digest, Sha256};

use super::fingerprint::{Fingerprint, hex};
use super::{MemberError, MemberResult, part_len};
use crate::error::{Error, Result};
use crate::solve::Stats;

/// How often an unfinished table is synced to disk at least.
pub const SYNC_EVERY: Duration = Duration::from_secs(1);

/// How often the rows written are handed to the system at least (`write`, without `fsync`):
/// what a killed process leaves (SIGKILL, a wall-time limit) is at most this old; only a
/// crash of the machine loses what was not synced ([`SYNC_EVERY`]).
pub const FLUSH_EVERY: Duration = Duration::from_millis(100);

/// A cell of a row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Cell {
    /// A number, written so that it reads back to the same bits.
    F64(f64),
    /// A count.
    U64(u64),
    /// Nothing (an empty field).
    Empty,
}

impl From<f64> for Cell {
    fn from(x: f64) -> Self {
        Cell::F64(x)
    }
}

impl From<Option<f64>> for Cell {
    fn from(x: Option<f64>) -> Self {
        x.map_or(Cell::Empty, Cell::F64)
    }
}

/// What a column holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Numbers (`f64`).
    F64,
    /// Counts (`u64`).
    U64,
}

/// A column of a table: its name and kind.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Column {
    /// The name in the header.
    pub name: String,
    /// What it holds.
    pub kind: Kind,
}

impl Column {
    /// A column of numbers.
    pub fn f64(name: impl Into<String>) -> Self {
        Column {
            name: name.into(),
            kind: Kind::F64,
        }
    }

    /// A column of counts.
    pub fn u64(name: impl Into<String>) -> Self {
        Column {
            name: name.into(),
            kind: Kind::U64,
        }
    }
}

type InputFn<'a> = Box<dyn Fn(usize, &mut Vec<Cell>) + Sync + 'a>;

/// The layout of an ensemble's table (see the module docs): a description that names the
/// ensemble, the input columns with the function that gives member i's cells, and the output
/// columns.
pub struct Table<'a> {
    description: String,
    key: String,
    inputs: Vec<Column>,
    input_cells: Option<InputFn<'a>>,
    outputs: Vec<Column>,
    part_file: bool,
    cpu: bool,
}

impl std::fmt::Debug for Table<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Table")
            .field("description", &self.description)
            .field("key", &self.key)
            .field("inputs", &self.inputs)
            .field("outputs", &self.outputs)
            .finish()
    }
}

/// A member's status in its row.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// Verified to the tolerance.
    Verified,
    /// A fixed method that completed.
    Ok,
    /// Not verified (the row holds the best solution).
    Unverified,
    /// No solution.
    Failed,
    /// A user function panicked.
    Panicked,
}

impl Status {
    /// The status's code in an NPY table and between MPI ranks: 0 verified, 1 ok,
    /// 2 unverified, 3 failed, 4 panicked.
    pub fn code(self) -> u8 {
        match self {
            Status::Verified => 0,
            Status::Ok => 1,
            Status::Unverified => 2,
            Status::Failed => 3,
            Status::Panicked => 4,
        }
    }

    /// The status of a [code](Self::code).
    pub fn from_code(code: u8) -> Option<Status> {
        [
            Status::Verified,
            Status::Ok,
            Status::Unverified,
            Status::Failed,
            Status::Panicked,
        ]
        .into_iter()
        .find(|s| s.code() == code)
    }

    /// The word in the `status` column.
    pub fn word(self) -> &'static str {
        match self {
            Status::Verified => "verified",
            Status::Ok => "ok",
            Status::Unverified => "unverified",
            Status::Failed => "failed",
            Status::Panicked => "panicked",
        }
    }

    pub(crate) fn from_word(word: &str) -> Option<Status> {
        [
            Status::Verified,
            Status::Ok,
            Status::Unverified,
            Status::Failed,
            Status::Panicked,
        ]
        .into_iter()
        .find(|s| s.word() == word)
    }
}

/// What one member's output gives a table: the cells of its output columns, and whether its
/// solution was verified (rather than a fixed method's).
pub type RowOutput = (Vec<Cell>, bool);

impl<'a> Table<'a> {
    /// The table of an ensemble described by `description` (one line that names it, e.g.
    /// the model and its options: a part file carries it, and [`merge_parts`] and resume
    /// compare it), with `outputs` as output columns and no input columns.
    pub fn new(description: impl Into<String>, outputs: Vec<Column>) -> Table<'static> {
        Table {
            description: description.into().replace(['\r', '\n'], " "),
            key: String::new(),
            inputs: Vec::new(),
            input_cells: None,
            outputs,
            part_file: false,
            cpu: false,
        }
    }

    /// Input columns (after `member`): `cells(i, &mut row)` pushes member i's cells, one per
    /// column (its parameters, its y₀).
    pub fn inputs<'b>(
        self,
        columns: Vec<Column>,
        cells: impl Fn(usize, &mut Vec<Cell>) + Sync + 'b,
    ) -> Table<'b> {
        Table {
            description: self.description,
            key: self.key,
            inputs: columns,
            input_cells: Some(Box::new(cells)),
            outputs: self.outputs,
            part_file: self.part_file,
            cpu: self.cpu,
        }
    }

    /// A key of your own in the table's [fingerprint](super::fingerprint) (line breaks become
    /// spaces): for what decides the rows that the library cannot see, such as the version of
    /// the model's code or of a data file it reads. A resume or a merge refuses rows written
    /// with another key.
    #[must_use]
    pub fn key(mut self, key: impl Into<String>) -> Self {
        self.key = key.into().replace(['\r', '\n'], " ");
        self
    }

    /// The key ([`key`](Self::key); empty if none was given).
    pub fn key_text(&self) -> &str {
        &self.key
    }

    /// Writes a part file (first and end lines) even for the whole ensemble (part 1 of 1).
    #[must_use]
    pub fn as_part(mut self) -> Self {
        self.part_file = true;
        self
    }

    /// A last column `cpu_seconds`, the CPU time of each member: it differs from run to run,
    /// so that a table with it is no longer the same bytes on every run (resumed, on
    /// other threads, ranks or parts); off by default.
    #[must_use]
    pub fn cpu_seconds(mut self) -> Self {
        self.cpu = true;
        self
    }

    pub(crate) fn is_part(&self) -> bool {
        self.part_file
    }

    /// The description.
    pub fn description(&self) -> &str {
        &self.description
    }

    /// The header row, with its line break.
    pub fn header(&self) -> String {
        let mut h = vec!["member".to_string()];
        h.extend(self.inputs.iter().map(|c| csv_field(&c.name)));
        h.push("status".into());
        h.extend(self.outputs.iter().map(|c| csv_field(&c.name)));
        h.push("message".into());
        if self.cpu {
            h.push("cpu_seconds".into());
        }
        h.join(",") + "\n"
    }

    /// The number of fields of a row (and of the header).
    fn field_count(&self) -> usize {
        self.inputs.len() + self.outputs.len() + 3 + usize::from(self.cpu)
    }

    /// Appends the start of member `index`'s row, as every row of it starts: its index and its
    /// input cells, each after a comma.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] if the input function gives another number of cells than there
    /// are input columns.
    fn push_inputs(&self, index: usize, out: &mut Vec<u8>) -> Result<()> {
        let mut cells = Vec::with_capacity(self.inputs.len());
        if let Some(f) = &self.input_cells {
            f(index, &mut cells);
        }
        if cells.len() != self.inputs.len() {
            return Err(Error::InvalidInput(format!(
                "the table's input function gave {} cells for member {index}, for {} input \
                 columns",
                cells.len(),
                self.inputs.len()
            )));
        }
        write!(out, "{index}").map_err(io_err("a row"))?;
        for c in &cells {
            out.push(b',');
            push_cell(out, c);
        }
        Ok(())
    }

    /// The SHA-256 digest of the input cells of members `0..members` as their rows start
    /// ([`push_inputs`](Self::push_inputs), each with a line break), for the fingerprint.
    ///
    /// # Errors
    /// As [`push_inputs`](Self::push_inputs).
    pub(crate) fn inputs_digest(&self, members: usize) -> Result<String> {
        let mut h = Sha256::new();
        let mut row = Vec::new();
        for i in 0..members {
            row.clear();
            self.push_inputs(i, &mut row)?;
            row.push(b'\n');
            h.update(&row);
        }
        Ok(format!("sha256 {}", hex(&h.finalize())))
    }

    /// The status of member `index`'s row `line` (with its line break) if the row reads as
    /// the table writes it: its index and input cells those of the member, as many fields as
    /// the header, a known status, every output cell empty or a number written as the table
    /// writes numbers (a count of a column of counts), and the CPU time a number.
    fn check_row(&self, index: usize, line: &[u8], start: &mut Vec<u8>) -> Option<Status> {
        let text = std::str::from_utf8(line).ok()?.strip_suffix('\n')?;
        if text.contains(['\0', '\r']) {
            return None;
        }
        start.clear();
        self.push_inputs(index, start).ok()?;
        start.push(b',');
        let rest = text.as_bytes().strip_prefix(&start[..])?;
        let cells = super::npy::fields(std::str::from_utf8(rest).ok()?);
        let expect = self.field_count() - 1 - self.inputs.len();
        if cells.len() != expect {
            return None;
        }
        let status = Status::from_word(&cells[0])?;
        let outputs = &cells[1..1 + self.outputs.len()];
        let numbers_ok = self.outputs.iter().zip(outputs).all(|(c, cell)| {
            cell.is_empty()
                || match c.kind {
                    Kind::F64 => cell.parse::<f64>().is_ok_and(|x| format!("{x:?}") == *cell),
                    Kind::U64 => cell.parse::<u64>().is_ok_and(|n| n.to_string() == *cell),
                }
        });
        let cpu_ok = !self.cpu
            || cells
                .last()
                .is_some_and(|c| c.parse::<f64>().is_ok_and(|x| format!("{x:?}") == *c));
        (numbers_ok && cpu_ok).then_some(status)
    }

    /// A row's bytes at most, roughly: 24 per number, for the estimate of a table's size.
    pub fn estimated_row_bytes(&self) -> usize {
        let cells = self.inputs.len() + self.outputs.len() + 2;
        20 + 24 * cells + 12
    }

    /// The status of a member's row.
    pub fn status_of(m: &MemberResult<RowOutput>) -> Status {
        match &m.outcome {
            Ok((_, true)) => Status::Verified,
            Ok((_, false)) => Status::Ok,
            Err(MemberError::Unverified { .. }) => Status::Unverified,
            Err(MemberError::Panicked(_)) => Status::Panicked,
            Err(_) => Status::Failed,
        }
    }

    /// Appends member `m`'s row (with its line break) to `out`.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] if the input function or the output gives another number of
    /// cells than there are columns.
    pub fn format_row(&self, m: &MemberResult<RowOutput>, out: &mut Vec<u8>) -> Result<()> {
        self.push_inputs(m.index, out)?;
        let status = Self::status_of(m);
        out.push(b',');
        out.extend_from_slice(status.word().as_bytes());
        let (output, message) = match &m.outcome {
            Ok((cells, _)) => (Some(cells), String::new()),
            Err(MemberError::Unverified { reason, output }) => (Some(&output.0), reason.clone()),
            Err(MemberError::Failed(e)) => (None, e.to_string()),
            Err(MemberError::Panicked(msg)) => (None, msg.clone()),
            Err(e) => (None, e.to_string()),
        };
        match output {
            Some(cells) => {
                if cells.len() != self.outputs.len() {
                    return Err(Error::InvalidInput(format!(
                        "the output function gave {} cells for member {}, for {} output columns",
                        cells.len(),
                        m.index,
                        self.outputs.len()
                    )));
                }
                for c in cells {
                    out.push(b',');
                    push_cell(out, c);
                }
            }
            None => out.extend(std::iter::repeat_n(b',', self.outputs.len())),
        }
        out.push(b',');
        out.extend_from_slice(csv_field(&message).as_bytes());
        if self.cpu {
            write!(out, ",{:?}", m.cpu.as_secs_f64()).map_err(io_err("a row"))?;
        }
        out.push(b'\n');
        Ok(())
    }
}

fn push_cell(out: &mut Vec<u8>, c: &Cell) {
    let _ = match c {
        Cell::F64(x) => write!(out, "{x:?}"),
        Cell::U64(n) => write!(out, "{n}"),
        Cell::Empty => Ok(()),
    };
}

/// A field of a CSV row: as it is, or quoted (RFC 4180) where it holds a comma or a quote;
/// line breaks become spaces, so that every row is one line.
pub fn csv_field(text: &str) -> String {
    let text = text.replace(['\r', '\n'], " ");
    if text.contains([',', '"']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text
    }
}

fn io_err(what: &str) -> impl Fn(io::Error) -> Error + '_ {
    move |e| Error::Io(format!("{what}: {e}"))
}

/// What [`Ensemble::write_table`](super::Ensemble::write_table) did.
#[derive(Clone, Debug, Default)]
pub struct TableReport {
    /// Members of the table (of the part).
    pub members: usize,
    /// Rows kept from an unfinished earlier run (resume).
    pub kept: usize,
    /// Rows written by this run.
    pub written: usize,
    /// Rows (kept and written) of verified or completed members.
    pub verified: usize,
    /// Rows of members whose answer could not be verified.
    pub unverified: usize,
    /// Rows of members that failed or panicked.
    pub failed: usize,
    /// What the solves of this run cost.
    pub stats: Stats,
    /// Whether the table is complete and in place (`false`: the progress callback stopped
    /// the run, and the rows so far wait in the unfinished file for a resume).
    pub complete: bool,
}

/// A file written beside its target and renamed onto it when complete.
pub(crate) struct Staged {
    shown: String,
    target: PathBuf,
    stage: PathBuf,
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
fn follow(path: &Path) -> Result<PathBuf> {
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

/// Free bytes for an unprivileged writer on the filesystem of `dir`, where the system says.
fn free_bytes(dir: &Path) -> Option<u128> {
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
            if let Ok(list) = fs::read_dir(&parent) {
                for entry in list.flatten() {
                    let ours = entry
                        .file_name()
                        .to_str()
                        .is_some_and(|f| f.starts_with(&prefix));
                    if ours && entry.file_type().is_ok_and(|t| t.is_file()) {
                        if let Ok(f) = File::open(entry.path()) {
                            if try_lock(&f).unwrap_or(false) {
                                let _ = fs::remove_file(entry.path());
                            }
                        }
                    }
                }
            }
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

    fn io(&self) -> impl Fn(io::Error) -> Error + '_ {
        move |e| Error::Io(format!("cannot write '{}': {e}", self.stage.display()))
    }

    /// Flushes and syncs the data.
    fn sync(&mut self) -> Result<()> {
        self.file.flush().map_err(self.io())?;
        self.file.get_ref().sync_data().map_err(self.io())
    }

    /// Syncs, renames onto the target and syncs the directory.
    pub(crate) fn commit(mut self) -> Result<()> {
        self.discard = false;
        self.file.flush().map_err(self.io())?;
        self.file.get_ref().sync_all().map_err(self.io())?;
        fs::rename(&self.stage, &self.target).map_err(|e| {
            Error::Io(format!(
                "cannot put '{}' in place of '{}': {e} (the complete table stays in '{}')",
                self.stage.display(),
                self.shown,
                self.stage.display()
            ))
        })?;
        #[cfg(unix)]
        if let Some(parent) = self.target.parent() {
            let dir = if parent.as_os_str().is_empty() {
                Path::new(".")
            } else {
                parent
            };
            if let Ok(d) = File::open(dir) {
                let _ = d.sync_all();
            }
        }
        Ok(())
    }
}

/// The first line of part k of n (0-based k).
fn part_head(k: usize, n: usize, members: usize, description: &str) -> String {
    format!(
        "# ecr ensemble part {}/{n} of {members} members: {description}\n",
        k + 1
    )
}

/// The first line of the table of the whole ensemble.
fn table_head(members: usize, description: &str) -> String {
    format!("# ecr ensemble table of {members} members: {description}\n")
}

/// Part k of n (0-based k) of a file, `None` for the table of the whole ensemble.
type PartOf = Option<(usize, usize)>;

/// What a table's first line (without its line break) says: the part, the member count and
/// the description.
fn parse_head(line: &str) -> Option<(PartOf, usize, String)> {
    let rest = line.strip_prefix("# ecr ensemble ")?;
    let (part, rest) = match rest.strip_prefix("table of ") {
        Some(rest) => (None, rest),
        None => {
            let (kn, rest) = rest.strip_prefix("part ")?.split_once(" of ")?;
            let (k, n) = kn.split_once('/')?;
            let (k, n) = (k.parse::<usize>().ok()?, n.parse::<usize>().ok()?);
            if k == 0 || k > n {
                return None;
            }
            (Some((k - 1, n)), rest)
        }
    };
    let (members, description) = rest.split_once(" members: ")?;
    Some((part, members.parse().ok()?, description.to_string()))
}

/// The preamble of a table (first line, fingerprint lines, header row) as a file has it.
struct Preamble {
    /// Its bytes.
    bytes: Vec<u8>,
    /// The part its first line names.
    part: PartOf,
    /// The fingerprint: members and description from the first line, columns from the
    /// header row.
    fingerprint: Fingerprint,
}

/// The preamble of a table as read from `r`; `None` if the file ends before the header row is
/// complete or its first line is not a table's.
fn read_preamble(r: &mut impl BufRead) -> io::Result<Option<Preamble>> {
    let mut bytes = Vec::new();
    let mut line = Vec::new();
    if !next_line(r, &mut line)? {
        return Ok(None);
    }
    bytes.extend_from_slice(&line);
    let Some((part, members, description)) = std::str::from_utf8(&line)
        .ok()
        .and_then(|l| parse_head(l.strip_suffix('\n')?))
    else {
        return Ok(None);
    };
    let mut fields = vec![
        ("members".to_string(), members.to_string()),
        ("description".to_string(), description),
    ];
    loop {
        if !next_line(r, &mut line)? {
            return Ok(None);
        }
        bytes.extend_from_slice(&line);
        let Ok(text) = std::str::from_utf8(&line[..line.len() - 1]) else {
            return Ok(None);
        };
        if text.starts_with('#') {
            match Fingerprint::parse_line(text) {
                Some(field) => fields.push(field),
                None => return Ok(None),
            }
        } else {
            fields.push(("columns".to_string(), text.to_string()));
            break;
        }
    }
    Ok(Some(Preamble {
        bytes,
        part,
        fingerprint: Fingerprint::new(fields),
    }))
}

/// Reads a line of at most 1 MiB into `line` (cleared first): whether it is a whole line.
fn next_line(r: &mut impl BufRead, line: &mut Vec<u8>) -> io::Result<bool> {
    line.clear();
    let len = Read::take(&mut *r, 1 << 20).read_until(b'\n', line)?;
    Ok(len > 0 && line.ends_with(b"\n"))
}

/// What a part says it is, for messages: `table` or `part K/N`.
fn part_name(part: Option<(usize, usize)>) -> String {
    match part {
        None => "table".to_string(),
        Some((k, n)) => format!("part {}/{n}", k + 1),
    }
}

/// The last line of part k of n (0-based k).
fn part_end(k: usize, n: usize, rows: usize, digest: &str) -> String {
    format!(
        "# end of part {}/{n}: {rows} rows, sha256 {digest}\n",
        k + 1
    )
}

/// The streaming writer of a table: the unfinished file, its rows so far, their digest.
/// Public for engines that gather rows themselves (the MPI engine of the `ecr` crate).
pub struct TableWriter {
    staged: Staged,
    part: Option<(usize, usize)>,
    members: usize,
    expected: usize,
    rows: usize,
    kept: usize,
    digest: Sha256,
    counts: [usize; 3],
    last_sync: Instant,
    last_flush: Instant,
    complete: bool,
}

impl std::fmt::Debug for TableWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TableWriter")
            .field("stage", &self.staged.stage)
            .field("rows", &self.rows)
            .finish()
    }
}

impl TableWriter {
    /// The writer of `table` at `path` for the run whose [fingerprint](super::fingerprint)
    /// is `fingerprint` ([`Ensemble::fingerprint`](super::Ensemble::fingerprint): its
    /// member count is the table's), `part` k of n for a part file, continuing an unfinished
    /// file of the same run with `resume`.
    ///
    /// # Errors
    /// A path that cannot be written, a table that would not fit on its filesystem
    /// (estimated at [`Table::estimated_row_bytes`] a row), a file another run is writing;
    /// with `resume`, an unfinished file of another run (one line naming the first field of
    /// the fingerprint that differs; the file is left as it was).
    pub fn open(
        path: &Path,
        table: &Table<'_>,
        fingerprint: &Fingerprint,
        part: Option<(usize, usize)>,
        resume: bool,
    ) -> Result<TableWriter> {
        let members = fingerprint.members().ok_or_else(|| {
            Error::InvalidInput("a fingerprint without the member count".to_string())
        })?;
        let (k, n) = part.unwrap_or((0, 1));
        let expected = part_len(members, k, n);
        let head = match part {
            Some((k, n)) => part_head(k, n, members, &table.description),
            None => table_head(members, &table.description),
        };
        let preamble = head + &fingerprint.lines() + &table.header();
        Self::check_fits(path, table, members, part)?;
        // One unfinished file per table or part at `path`, whatever the run: a resume finds
        // it and refuses it if it is another run's.
        let (staged, existing) = Staged::open(path, &part_name(part), resume)?;
        let mut writer = TableWriter {
            staged,
            part,
            members,
            expected,
            rows: 0,
            kept: 0,
            digest: Sha256::new(),
            counts: [0; 3],
            last_sync: Instant::now(),
            last_flush: Instant::now(),
            complete: false,
        };
        let kept_bytes = if resume {
            writer.read_kept(existing, &preamble, table, fingerprint)?
        } else {
            0
        };
        let staged = &mut writer.staged;
        let io =
            |e: io::Error| Error::Io(format!("cannot write '{}': {e}", staged.stage.display()));
        let f = staged.file.get_mut();
        f.set_len(kept_bytes).map_err(io)?;
        f.seek(SeekFrom::Start(kept_bytes)).map_err(io)?;
        if kept_bytes == 0 {
            writer
                .staged
                .file
                .write_all(preamble.as_bytes())
                .map_err(writer.staged.io())?;
        }
        Ok(writer)
    }

    /// Whether the table of `members` members (`part`: k of n) fits on the filesystem of
    /// `path`, estimated at [`Table::estimated_row_bytes`] a row: checked before the run's
    /// [fingerprint](super::fingerprint) is made (which formats every member's input cells).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] for a table larger than the free space; a path whose symlinks
    /// cannot be followed.
    pub fn check_fits(
        path: &Path,
        table: &Table<'_>,
        members: usize,
        part: Option<(usize, usize)>,
    ) -> Result<()> {
        let (k, n) = part.unwrap_or((0, 1));
        let expected = part_len(members, k, n);
        let need = expected as u128 * table.estimated_row_bytes() as u128;
        let dir = follow(path)?
            .parent()
            .map(|p| {
                if p.as_os_str().is_empty() {
                    PathBuf::from(".")
                } else {
                    p.to_path_buf()
                }
            })
            .unwrap_or_else(|| PathBuf::from("."));
        if let Some(free) = free_bytes(&dir) {
            if need > free {
                return Err(Error::InvalidInput(format!(
                    "the table of {expected} members needs about {} (estimate, {} bytes a \
                     row), more than the {} free for '{}'",
                    gb(need),
                    table.estimated_row_bytes(),
                    gb(free),
                    path.display()
                )));
            }
        }
        Ok(())
    }

    /// Reads the rows of an unfinished file: the bytes to keep (0: start over). The rows kept
    /// are those before the first that does not read as the table writes it
    /// ([`Table::check_row`]: another member, another number of fields, a cell that is not
    /// a number, …); that one and those after it are solved again.
    ///
    /// # Errors
    /// A file of another run: [`Error::InvalidInput`] naming the first field of the
    /// fingerprint that differs.
    fn read_kept(
        &mut self,
        file: File,
        preamble: &str,
        table: &Table<'_>,
        fingerprint: &Fingerprint,
    ) -> Result<u64> {
        let (k, n) = self.part.unwrap_or((0, 1));
        let mut r = BufReader::new(file);
        let read_err = |e: io::Error| {
            Error::Io(format!(
                "cannot read the unfinished table '{}': {e}",
                self.staged.stage.display()
            ))
        };
        let Some(Preamble {
            bytes,
            part,
            fingerprint: theirs,
        }) = read_preamble(&mut r).map_err(read_err)?
        else {
            // Empty, or cut before its header row was complete: nothing to keep.
            return Ok(0);
        };
        let refuse = |field: &str, there: &str, here: &str| {
            Error::InvalidInput(format!(
                "cannot resume '{}': its unfinished table is of another run ({field}: {there} \
                 there, {here} in this run); run without resume to start over",
                self.staged.shown
            ))
        };
        if part != self.part {
            return Err(refuse("part", &part_name(part), &part_name(self.part)));
        }
        if let Some(d) = fingerprint.difference(&theirs) {
            return Err(refuse(&d.field, &d.second, &d.first));
        }
        if bytes != preamble.as_bytes() {
            // The same run written otherwise (by hand?): start over.
            return Ok(0);
        }
        let mut offset = bytes.len() as u64;
        let mut line = Vec::new();
        let mut start = Vec::new();
        while next_line(&mut r, &mut line).unwrap_or(false) {
            if self.rows == self.expected {
                let end = part_end(k, n, self.rows, &hex(&self.digest.clone().finalize()));
                if self.part.is_some() && line == end.as_bytes() {
                    offset += line.len() as u64;
                    self.complete = true;
                }
                break;
            }
            let index = k + self.rows * n;
            let Some(status) = table.check_row(index, &line, &mut start) else {
                break;
            };
            self.count(status);
            self.digest.update(&line);
            self.rows += 1;
            offset += line.len() as u64;
        }
        self.kept = self.rows;
        if self.part.is_none() && self.rows == self.expected {
            self.complete = true;
        }
        Ok(offset)
    }

    fn count(&mut self, status: Status) {
        let slot = match status {
            Status::Verified | Status::Ok => 0,
            Status::Unverified => 1,
            Status::Failed | Status::Panicked => 2,
        };
        self.counts[slot] += 1;
    }

    /// Rows already in the file (kept from an earlier run, and written since).
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// The index of the first member whose row is not in the file yet.
    pub fn first_missing_member(&self) -> usize {
        let (k, n) = self.part.unwrap_or((0, 1));
        if self.rows >= self.expected {
            return self.members;
        }
        k + self.rows * n
    }

    /// Appends a row (its bytes with the line break, as [`Table::format_row`] makes them) of
    /// the next member, with its status; flushes if [`FLUSH_EVERY`] and syncs if
    /// [`SYNC_EVERY`] has passed since the last flush or sync.
    ///
    /// # Errors
    /// A failed write or sync; a row beyond the table's members.
    pub fn write_row(&mut self, row: &[u8], status: Status) -> Result<()> {
        if self.rows >= self.expected {
            return Err(Error::InvalidInput(format!(
                "a row beyond the {} members of the table",
                self.expected
            )));
        }
        self.staged.file.write_all(row).map_err(self.staged.io())?;
        self.digest.update(row);
        self.rows += 1;
        self.count(status);
        if self.last_flush.elapsed() >= FLUSH_EVERY {
            if self.last_sync.elapsed() >= SYNC_EVERY {
                self.staged.sync()?;
                self.last_sync = Instant::now();
            } else {
                self.staged.file.flush().map_err(self.staged.io())?;
            }
            self.last_flush = Instant::now();
        }
        Ok(())
    }

    /// The report of the table as it stands.
    pub fn report(&self, stats: Stats, stopped: bool) -> TableReport {
        TableReport {
            members: self.expected,
            kept: self.kept,
            written: self.rows - self.kept,
            verified: self.counts[0],
            unverified: self.counts[1],
            failed: self.counts[2],
            stats,
            complete: !stopped && self.rows == self.expected,
        }
    }

    /// Syncs the rows so far and leaves the file unfinished, for a resume.
    ///
    /// # Errors
    /// A failed write or sync.
    pub fn pause(mut self) -> Result<()> {
        self.staged.sync()
    }

    /// Closes the table (the end line of a part), syncs it and puts it in place.
    ///
    /// # Errors
    /// Rows missing; a failed write, sync or rename.
    pub fn commit(mut self) -> Result<()> {
        if self.rows != self.expected {
            self.staged.sync()?;
            return Err(Error::InvalidInput(format!(
                "the table has {} of its {} rows",
                self.rows, self.expected
            )));
        }
        if let (Some((k, n)), false) = (self.part, self.complete) {
            let end = part_end(k, n, self.rows, &hex(&self.digest.clone().finalize()));
            self.staged
                .file
                .write_all(end.as_bytes())
                .map_err(self.staged.io())?;
        }
        self.staged.commit()
    }
}

/// Bytes in GB, three significant digits.
fn gb(bytes: u128) -> String {
    format!("{:.3} GB", bytes as f64 / 1e9)
}

/// A part file being merged.
struct Part {
    shown: String,
    path: PathBuf,
    k: usize,
    n: usize,
    members: usize,
    /// The fingerprint lines and the header row, as the file has them.
    body: Vec<u8>,
    fingerprint: Fingerprint,
    rows: usize,
    digest: String,
    reader: BufReader<File>,
    hasher: Sha256,
}

fn open_part(path: &Path) -> Result<Part> {
    let shown = path.display().to_string();
    let read_err = |e: io::Error| Error::Io(format!("cannot read part '{shown}': {e}"));
    let file = File::open(path).map_err(read_err)?;
    let len = file.metadata().map_err(read_err)?.len();
    let mut reader = BufReader::new(file);
    let not_a_part = || {
        Error::InvalidInput(format!(
            "'{shown}' is not a part written by an ensemble's part (ecr ensemble --shard K/N)"
        ))
    };
    let Preamble {
        bytes,
        part,
        fingerprint,
    } = read_preamble(&mut reader)
        .ok()
        .flatten()
        .ok_or_else(not_a_part)?;
    let Some((k, n)) = part else {
        return Err(not_a_part());
    };
    let members = fingerprint.members().ok_or_else(not_a_part)?;
    let first = bytes.iter().position(|&b| b == b'\n').map_or(0, |p| p + 1);
    let body = bytes[first..].to_vec();
    // The end line, from the file's last bytes.
    let rows = part_len(members, k, n);
    let unfinished = || {
        Error::InvalidInput(format!(
            "part '{shown}' ({}/{n}) does not end with '# end of part {}/{n}: {rows} rows, \
             sha256 …': its shard was killed or has not finished; run it again",
            k + 1,
            k + 1
        ))
    };
    let mut tail = Vec::new();
    {
        let mut f = File::open(path).map_err(read_err)?;
        f.seek(SeekFrom::Start(len.saturating_sub(256)))
            .and_then(|_| f.read_to_end(&mut tail))
            .map_err(read_err)?;
    }
    let tail = String::from_utf8_lossy(&tail);
    let last = tail
        .strip_suffix('\n')
        .and_then(|t| t.rsplit('\n').next())
        .ok_or_else(unfinished)?;
    let prefix = format!("# end of part {}/{n}: {rows} rows, sha256 ", k + 1);
    let digest = last.strip_prefix(&prefix).ok_or_else(unfinished)?;
    if digest.len() != 64 || !digest.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(unfinished());
    }
    Ok(Part {
        shown,
        path: path.to_path_buf(),
        k,
        n,
        members,
        body,
        fingerprint,
        rows,
        digest: digest.to_string(),
        reader,
        hasher: Sha256::new(),
    })
}

/// Whether `a` and `b` name the same file: the same path once symlinks and `..` are resolved
/// (for `b`, which need not exist, its directory), or on Unix the same device and inode.
fn same_file(a: &Path, b: &Path) -> bool {
    let Ok(a) = fs::canonicalize(a) else {
        return false;
    };
    let b = match follow(b) {
        Ok(b) => b,
        Err(_) => return false,
    };
    let resolved = fs::canonicalize(&b).ok().or_else(|| {
        let parent = match b.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        Some(fs::canonicalize(parent).ok()?.join(b.file_name()?))
    });
    if resolved.as_deref() == Some(a.as_path()) {
        return true;
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let (Ok(ma), Ok(mb)) = (fs::metadata(&a), fs::metadata(&b)) {
            return ma.dev() == mb.dev() && ma.ino() == mb.ino();
        }
    }
    false
}

/// What [`merge_parts`] wrote.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MergeReport {
    /// Members in the table.
    pub members: usize,
    /// Parts joined.
    pub parts: usize,
}

/// Joins the n part files of an ensemble (in any order) into the table of the whole
/// ensemble at `out`, written as [`Ensemble::write_table`](super::Ensemble::write_table)
/// writes one (atomically): byte for byte the table of one run.
///
/// # Errors
/// One line ([`Error::InvalidInput`]) for parts that are missing, given twice, of different
/// runs (naming the first field of their [fingerprints](super::fingerprint) that differs),
/// without their end line (killed or unfinished), whose rows are not their members in order
/// or do not match the digest of their end line (changed after they were written), and for
/// an `out` that is one of the parts (the merge never writes over its input); `out` is left
/// as it was then.
pub fn merge_parts<P: AsRef<Path>>(parts: &[P], out: &Path) -> Result<MergeReport> {
    if parts.is_empty() {
        return Err(Error::InvalidInput("no parts to merge".into()));
    }
    let mut parts = parts
        .iter()
        .map(|p| open_part(p.as_ref()))
        .collect::<Result<Vec<_>>>()?;
    if let Some(p) = parts.iter().find(|p| same_file(&p.path, out)) {
        return Err(Error::InvalidInput(format!(
            "the merged table '{}' would replace its part '{}': write it to another file",
            out.display(),
            p.shown
        )));
    }
    for p in &parts[1..] {
        let f = &parts[0];
        let differ = |field: &str, a: &str, b: &str| {
            Error::InvalidInput(format!(
                "'{}' and '{}' are parts of different runs ({field}: {a} in '{}', {b} in '{}')",
                f.shown, p.shown, f.shown, p.shown
            ))
        };
        if let Some(d) = f.fingerprint.difference(&p.fingerprint) {
            return Err(differ(&d.field, &d.first, &d.second));
        }
        if p.n != f.n {
            return Err(differ(
                "parts",
                &format!("{}/{}", f.k + 1, f.n),
                &format!("{}/{}", p.k + 1, p.n),
            ));
        }
        if p.body != f.body {
            return Err(differ(
                "fingerprint lines",
                "as written",
                "written otherwise",
            ));
        }
    }
    let n = parts[0].n;
    parts.sort_by_key(|p| p.k);
    for w in parts.windows(2) {
        if w[0].k == w[1].k {
            return Err(Error::InvalidInput(format!(
                "part {}/{n} is given twice ('{}', '{}')",
                w[0].k + 1,
                w[0].shown,
                w[1].shown
            )));
        }
    }
    let missing: Vec<String> = (0..n)
        .filter(|k| parts.iter().all(|p| p.k != *k))
        .map(|k| (k + 1).to_string())
        .collect();
    if !missing.is_empty() {
        return Err(Error::InvalidInput(format!(
            "{} of {n} parts missing: {} (each part is one run of part K/{n})",
            missing.len(),
            missing.join(", ")
        )));
    }
    let members = parts[0].members;
    let description = parts[0]
        .fingerprint
        .get("description")
        .unwrap_or_default()
        .to_string();
    let preamble = [table_head(members, &description).as_bytes(), &parts[0].body].concat();
    let identity = format!("merge of {n} parts of {members} members: {description}");
    let (mut staged, _) = Staged::open(out, &identity, false)?;
    staged.discard = true;
    staged.file.get_mut().set_len(0).map_err(staged.io())?;
    staged.file.write_all(&preamble).map_err(staged.io())?;
    let mut line = Vec::new();
    for i in 0..members {
        let p = &mut parts[i % n];
        let j = i / n;
        line.clear();
        let read = p.reader.read_until(b'\n', &mut line);
        let index = std::str::from_utf8(&line)
            .ok()
            .and_then(|l| l.split(',').next())
            .and_then(|f| f.parse::<usize>().ok());
        if read.is_err() || !line.ends_with(b"\n") || index != Some(i) {
            return Err(Error::InvalidInput(format!(
                "part '{}' ({}/{n}): row {} should be member {i}: the file was changed after \
                 its shard wrote it",
                p.shown,
                p.k + 1,
                j + 1
            )));
        }
        p.hasher.update(&line);
        staged.file.write_all(&line).map_err(staged.io())?;
    }
    for p in &mut parts {
        line.clear();
        let _ = p.reader.read_until(b'\n', &mut line);
        let mut rest = Vec::new();
        let _ = (&mut p.reader).take(1).read_to_end(&mut rest);
        let end = part_end(p.k, p.n, p.rows, &p.digest);
        if line != end.as_bytes() || !rest.is_empty() {
            return Err(Error::InvalidInput(format!(
                "part '{}' ({}/{n}) has other rows than its {} members: the file was changed \
                 after its shard wrote it",
                p.shown,
                p.k + 1,
                p.rows
            )));
        }
        if hex(&p.hasher.clone().finalize()) != p.digest {
            return Err(Error::InvalidInput(format!(
                "part '{}' ({}/{n}): its rows do not match the sha256 digest of its end line: \
                 the file was changed after its shard wrote it",
                p.shown,
                p.k + 1
            )));
        }
    }
    staged.commit()?;
    Ok(MergeReport { members, parts: n })
}
