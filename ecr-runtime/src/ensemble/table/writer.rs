//! The streaming writer of a table or a part, and its resume: the preamble (first line,
//! fingerprint, header row) written and read back, the kept rows checked (see the [module
//! docs](super)).

use std::fs::File;
use std::io::{self, BufRead, BufReader, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use sha2::{Digest, Sha256};

use super::staged::{Staged, follow, free_bytes};
use super::{FLUSH_EVERY, SYNC_EVERY, Status, Table, TableReport, hex};
use crate::ensemble::fingerprint::Fingerprint;
use crate::ensemble::{member_of, part_len};
use crate::error::{Error, Result};
use crate::solve::Stats;

/// The first line of part k of n (0-based k).
fn part_head(k: usize, n: usize, members: usize, description: &str) -> String {
    format!(
        "# ecr ensemble part {}/{n} of {members} members: {description}\n",
        k + 1
    )
}

/// The first line of the table of the whole ensemble.
pub(super) fn table_head(members: usize, description: &str) -> String {
    format!("# ecr ensemble table of {members} members: {description}\n")
}

/// Part k of n (0-based k) of a file, `None` for the table of the whole ensemble.
pub(super) type PartOf = Option<(usize, usize)>;

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
pub(super) struct Preamble {
    /// Its bytes.
    pub(super) bytes: Vec<u8>,
    /// The part its first line names.
    pub(super) part: PartOf,
    /// The fingerprint: members and description from the first line, columns from the
    /// header row.
    pub(super) fingerprint: Fingerprint,
}

/// The preamble of a table as read from `r`; `None` if the file ends before the header row is
/// complete or its first line is not a table's.
pub(super) fn read_preamble(r: &mut impl BufRead) -> io::Result<Option<Preamble>> {
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
pub(super) fn part_end(k: usize, n: usize, rows: usize, digest: &str) -> String {
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
    /// The writer of `table` at `path` for the run whose [fingerprint](crate::ensemble::fingerprint)
    /// is `fingerprint` ([`Ensemble::fingerprint`](crate::ensemble::Ensemble::fingerprint): its
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
    /// [fingerprint](crate::ensemble::fingerprint) is made (which formats every member's input cells).
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
            let index = member_of(k, n, self.rows);
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
        member_of(k, n, self.rows)
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
