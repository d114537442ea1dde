//! [`merge_parts`]: the parts of a job array joined into the table of the whole ensemble
//! (see the [module docs](super)).

use std::fs::{self, File};
use std::io::{self, BufRead, BufReader, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use super::hex;
use super::staged::{Staged, follow};
use super::writer::{Preamble, part_end, read_preamble, table_head};
use crate::ensemble::fingerprint::Fingerprint;
use crate::ensemble::{part_len, part_of};
use crate::error::{Error, Result};

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
/// ensemble at `out`, written as [`Ensemble::write_table`](crate::ensemble::Ensemble::write_table)
/// writes one (atomically): byte for byte the table of one run.
///
/// # Errors
/// One line ([`Error::InvalidInput`]) for parts that are missing, given twice, of different
/// runs (naming the first field of their [fingerprints](crate::ensemble::fingerprint) that differs),
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
        let (k, j) = part_of(i, n);
        let p = &mut parts[k];
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
