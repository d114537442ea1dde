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

mod merge;
mod staged;
mod writer;

use std::io::{self, Write};
use std::time::Duration;

use sha2::{Digest, Sha256};

use super::fingerprint::hex;
use super::{MemberError, MemberResult};
use crate::error::{Error, Result};
use crate::solve::Stats;

pub use merge::{MergeReport, merge_parts};
pub(crate) use staged::Staged;
pub use staged::{PutError, put_in_place, remove_stale};
pub use writer::TableWriter;

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
    /// writes numbers (a count, or an f64 as `{:?}` writes it), and the CPU time a number.
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
        // A cell as `push_cell` writes it: empty, a count, or an f64 as `{:?}` writes it
        // (whatever the column's kind: an output function may give either).
        let written = |cell: &String| {
            cell.is_empty()
                || cell.parse::<u64>().is_ok_and(|n| n.to_string() == *cell)
                || cell.parse::<f64>().is_ok_and(|x| format!("{x:?}") == *cell)
        };
        let numbers_ok = outputs.iter().all(written);
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
