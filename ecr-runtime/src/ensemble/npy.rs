//! A complete table (CSV, as [`Ensemble::write_table`](super::Ensemble::write_table) or
//! [`merge_parts`](super::merge_parts) write it) as NumPy's NPY file, every number's bits
//! kept: [`table_to_npy`].
//!
//! The array is one-dimensional, one record per row, with a field per CSV column but the
//! message: `member` (`<u8`), each input and output column (`<u8` for a column of counts,
//! `<f8` otherwise), `status` (`|u1`: 0 verified, 1 ok, 2 unverified, 3 failed, 4 panicked)
//! and, if the table has it, `cpu_seconds` (`<f8`). An empty cell (an output of a member
//! without a solution) is NaN in an `<f8` field and 0 in a `<u8` field: the status says which
//! rows have outputs. The messages are in the CSV only. In Python:
//! `numpy.load("table.npy")["q_end"]`.
//!
//! The file is written by [`npyz`] beside its target and renamed onto it when complete, as the
//! table is. The CSV is read twice (the kinds of the columns and the row count, then the
//! records), a row at a time: memory does not grow with the rows.

use std::fs::File;
use std::io::{self, BufRead, BufReader, Write};
use std::path::Path;

use npyz::{DType, Field, TypeStr, WriterBuilder};

use super::table::{Staged, Status};
use crate::error::{Error, Result};

/// A field of the record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    F64,
    U64,
    Status,
}

/// One record: its fields' values as little-endian bytes, in order.
struct Record(Vec<u8>);

/// Writes a [`Record`] whose bytes are already laid out as the dtype says.
struct RecordWriter {
    size: usize,
}

impl npyz::TypeWrite for RecordWriter {
    type Value = Record;

    fn write_one<W: Write>(&self, mut writer: W, value: &Record) -> io::Result<()> {
        if value.0.len() != self.size {
            return Err(io::Error::other(format!(
                "a record of {} bytes for a dtype of {}",
                value.0.len(),
                self.size
            )));
        }
        writer.write_all(&value.0)
    }
}

impl npyz::Serialize for Record {
    type TypeWriter = RecordWriter;

    fn writer(dtype: &DType) -> std::result::Result<RecordWriter, npyz::DTypeError> {
        Ok(RecordWriter {
            size: dtype.num_bytes().unwrap_or(0),
        })
    }
}

/// The fields of a CSV line (RFC 4180 quotes; the line without its line break).
pub(super) fn fields(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut field = String::new();
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                chars.next();
                field.push('"');
            }
            ('"', true) => quoted = false,
            ('"', false) if field.is_empty() => quoted = true,
            (',', false) => out.push(std::mem::take(&mut field)),
            _ => field.push(c),
        }
    }
    out.push(field);
    out
}

/// Whether a cell is a count (digits only: Rust's `{:?}` of an f64 always has a `.`, an `e`,
/// `NaN` or `inf`).
fn is_count(cell: &str) -> bool {
    !cell.is_empty() && cell.bytes().all(|b| b.is_ascii_digit())
}

/// Writes the complete table `csv` as an NPY file at `npy` (see the module docs): the number
/// of records.
///
/// # Errors
/// [`Error::InvalidInput`] for a file that is not a complete table (a part file, a row with
/// another number of fields than the header, a cell that is not a number where one is
/// expected); [`Error::Io`] for a failed read, write or rename (`npy` is then left as it
/// was).
pub fn table_to_npy(csv: &Path, npy: &Path) -> Result<u64> {
    let shown = csv.display().to_string();
    let open = || {
        File::open(csv)
            .map(BufReader::new)
            .map_err(|e| Error::Io(format!("cannot read the table '{shown}': {e}")))
    };
    let bad = |line: u64, why: &str| {
        Error::InvalidInput(format!(
            "'{shown}' line {line}: {why} (not a complete table)"
        ))
    };
    // Pass 1: the header, the kinds of the columns, the rows.
    let mut reader = open()?;
    let mut line = String::new();
    let read = |r: &mut BufReader<File>, line: &mut String| -> Result<bool> {
        line.clear();
        let n = r
            .read_line(line)
            .map_err(|e| Error::Io(format!("cannot read the table '{shown}': {e}")))?;
        if line.ends_with('\n') {
            line.pop();
        }
        Ok(n > 0)
    };
    // The first line and the fingerprint (`# ` lines), then the header row.
    let mut skip = 0u64;
    loop {
        if !read(&mut reader, &mut line)? || line.starts_with("# ecr ensemble part ") {
            return Err(bad(
                skip + 1,
                "no header row, or a part file: merge the parts first",
            ));
        }
        if !line.starts_with('#') {
            break;
        }
        skip += 1;
    }
    let names = fields(&line);
    let status_at = names.iter().position(|n| n == "status");
    let message_at = names.iter().position(|n| n == "message");
    let (Some(status_at), Some(message_at), true) = (
        status_at,
        message_at,
        names.first().is_some_and(|n| n == "member"),
    ) else {
        return Err(bad(
            skip + 1,
            "the header has no member, status or message column",
        ));
    };
    let mut kinds: Vec<Option<Kind>> = names
        .iter()
        .enumerate()
        .map(|(c, _)| match c {
            0 => Some(Kind::U64),
            c if c == status_at => Some(Kind::Status),
            c if c == message_at => None,
            _ => Some(Kind::U64),
        })
        .collect();
    let mut rows = 0u64;
    let mut seen = vec![false; names.len()];
    while read(&mut reader, &mut line)? {
        let cells = fields(&line);
        if cells.len() != names.len() {
            return Err(bad(
                skip + rows + 2,
                "another number of fields than the header",
            ));
        }
        for (c, cell) in cells.iter().enumerate() {
            if kinds[c] == Some(Kind::U64) && c != 0 && !cell.is_empty() {
                seen[c] = true;
                if !is_count(cell) {
                    kinds[c] = Some(Kind::F64);
                }
            }
        }
        rows += 1;
    }
    for (c, kind) in kinds.iter_mut().enumerate() {
        // A column without a value (every member failed) is one of numbers.
        if c != 0 && *kind == Some(Kind::U64) && !seen[c] {
            *kind = Some(Kind::F64);
        }
    }
    let dtype = DType::Record(
        names
            .iter()
            .zip(&kinds)
            .filter_map(|(name, kind)| {
                let ty = match (*kind)? {
                    Kind::F64 => "<f8",
                    Kind::U64 => "<u8",
                    Kind::Status => "|u1",
                };
                Some(Field {
                    name: name.clone(),
                    dtype: DType::Plain(ty.parse::<TypeStr>().expect("a valid type string")),
                })
            })
            .collect(),
    );
    // Pass 2: the records.
    let (mut staged, _) = Staged::open(npy, &format!("npy of {shown}"), false)?;
    staged.discard = true;
    let io = |e: io::Error| Error::Io(format!("cannot write '{}': {e}", npy.display()));
    let mut writer = npyz::WriteOptions::new()
        .dtype(dtype)
        .shape(&[rows])
        .writer(&mut staged.file)
        .begin_nd()
        .map_err(io)?;
    let mut reader = open()?;
    for _ in 0..=skip {
        read(&mut reader, &mut line)?;
    }
    let mut record = Record(Vec::new());
    for row in 0..rows {
        if !read(&mut reader, &mut line)? {
            return Err(bad(skip + row + 2, "the table changed while it was read"));
        }
        record.0.clear();
        for (cell, kind) in fields(&line).iter().zip(&kinds) {
            match kind {
                None => {}
                Some(Kind::U64) => {
                    let n = if cell.is_empty() {
                        Some(0)
                    } else {
                        cell.parse::<u64>().ok()
                    };
                    let n =
                        n.ok_or_else(|| bad(skip + row + 2, "a count that is not a whole number"))?;
                    record.0.extend_from_slice(&n.to_le_bytes());
                }
                Some(Kind::F64) => {
                    let x = if cell.is_empty() {
                        Some(f64::NAN)
                    } else {
                        cell.parse::<f64>().ok()
                    };
                    let x = x.ok_or_else(|| bad(skip + row + 2, "a cell that is not a number"))?;
                    record.0.extend_from_slice(&x.to_le_bytes());
                }
                Some(Kind::Status) => {
                    let s = Status::from_word(cell)
                        .ok_or_else(|| bad(skip + row + 2, "an unknown status"))?;
                    record.0.push(s.code());
                }
            }
        }
        writer.push(&record).map_err(io)?;
    }
    writer.finish().map_err(io)?;
    staged.commit()?;
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    #[test]
    fn csv_fields_with_quotes() {
        assert_eq!(
            fields("1,a,\"b,c\",\"say \"\"x\"\"\","),
            ["1", "a", "b,c", "say \"x\"", ""]
        );
        assert!(is_count("12") && !is_count("1.0") && !is_count("") && !is_count("NaN"));
    }

    /// Every f64 read back with its bits (NaN, infinities, −0, subnormals, the shortest
    /// texts), counts as `<u8`, statuses as codes, empty cells as NaN, the message left out.
    #[test]
    fn a_table_as_npy_keeps_every_bit() {
        let values = [
            0.1,
            -0.0,
            f64::MIN_POSITIVE / 3.0,
            f64::MAX,
            1.0 / 3.0,
            f64::INFINITY,
            f64::NAN,
        ];
        let dir = std::env::temp_dir().join(format!("ecr-npy-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let csv = dir.join("t.csv");
        let mut text = String::from("member,a,status,x,g_evals,message\n");
        for (i, x) in values.iter().enumerate() {
            text += &format!("{i},{:?},verified,{x:?},{},\n", i as f64 * 0.5, 10 * i);
        }
        text += "7,3.5,failed,,,\"no, not this one\"\n";
        std::fs::write(&csv, &text).unwrap();
        let npy = dir.join("t.npy");
        assert_eq!(table_to_npy(&csv, &npy).unwrap(), 8);
        let mut bytes = Vec::new();
        File::open(&npy).unwrap().read_to_end(&mut bytes).unwrap();
        let file = npyz::NpyFile::new(&bytes[..]).unwrap();
        assert_eq!(file.shape(), [8]);
        let names: Vec<String> = match file.dtype() {
            DType::Record(f) => f.into_iter().map(|f| f.name + &f.dtype.descr()).collect(),
            d => panic!("{d:?}"),
        };
        assert_eq!(
            names,
            [
                "member'<u8'",
                "a'<f8'",
                "status'|u1'",
                "x'<f8'",
                "g_evals'<u8'"
            ]
        );
        // 8 + 8 + 1 + 8 + 8 bytes a record, after the header.
        let data = &bytes[bytes.len() - 8 * 33..];
        let f =
            |r: usize, at: usize| f64::from_le_bytes(data[r * 33 + at..][..8].try_into().unwrap());
        let u =
            |r: usize, at: usize| u64::from_le_bytes(data[r * 33 + at..][..8].try_into().unwrap());
        for (i, x) in values.iter().enumerate() {
            assert_eq!(u(i, 0), i as u64);
            assert_eq!(f(i, 8).to_bits(), (i as f64 * 0.5).to_bits());
            assert_eq!(data[i * 33 + 16], 0);
            assert_eq!(f(i, 17).to_bits(), x.to_bits(), "{x:?}");
            assert_eq!(u(i, 25), 10 * i as u64);
        }
        assert_eq!((u(7, 0), data[7 * 33 + 16], u(7, 25)), (7, 3, 0));
        assert!(f(7, 17).is_nan());
        // A part file is refused, and the target left alone.
        std::fs::write(&csv, "# ecr ensemble part 1/2 of 4 members: x\n").unwrap();
        let e = table_to_npy(&csv, &npy).unwrap_err().to_string();
        assert!(e.contains("merge the parts first"), "{e}");
        assert_eq!(std::fs::read(&npy).unwrap(), bytes);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
