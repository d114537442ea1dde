//! Bit for bit the same results: a fixed set of `ecr run` reports and the CSVs of
//! `ecr reproduce --quick`, compared byte for byte with the golden files in `tests/golden/`,
//! timing fields excluded (the `wall_seconds` line of a report, the `wall_seconds` column of a
//! CSV). The small CSVs (the error studies and `summary.csv`) are kept whole; the long energy
//! traces (over 16 KiB) as their number of lines and a 64-bit FNV-1a digest of their bytes, in
//! `tests/golden/reproduce/digests.txt`.
//!
//! A refactoring must leave every byte as it is. A change that is *meant* to alter results
//! (a faster evaluation order, a new default) regenerates the golden files and commits them
//! with the change, saying why the bits moved:
//!
//! ```text
//! ECR_BLESS=1 cargo test --test it bit_identity::
//! git diff --stat tests/golden
//! ```
//!
//! The runs cover the three problems of the paper and the FPU chain, ECrP, TCrP and RKNCrP,
//! several r, s and h, the paper's stage solver, the constant start, Newton and a tighter
//! tolerance; the serial stage path only (the concurrent path is bit for bit the serial one:
//! `tests/it/parallel.rs`), the run-time stepper only (the `ecr_method!` steppers are bit for bit
//! the run-time one: `tests/it/macro_stepper.rs`, `tc.rs`).

use crate::common;

use common::{TempDir, ecr};
use std::path::{Path, PathBuf};

/// The `ecr run` cases: a golden file name and the arguments after `run`.
const RUNS: &[(&str, &str)] = &[
    (
        "duffing-ec-r2",
        "--problem duffing --r 2 --h 0.1 --t-end 20",
    ),
    (
        "duffing-ec-r3-s4-newton",
        "--problem duffing --r 3 --s 4 --h 0.05 --t-end 5 --newton",
    ),
    (
        "duffing-ec-r4-paper",
        "--problem duffing --omega 20 --r 4 --h 0.0625 --t-end 10 --paper-solver",
    ),
    ("wind-ec-r3", "--problem wind --r 3 --h 0.1 --t-end 20"),
    (
        "wind-dissipative-ec-r2-constant",
        "--problem wind-dissipative --r 2 --h 0.05 --t-end 10 --constant-start",
    ),
    ("nls-ec-r2", "--problem nls --r 2 --h 0.01 --t-end 0.5"),
    (
        "nls-ec-r3-n64-paper",
        "--problem nls --n 64 --r 3 --h 0.02 --t-end 0.4 --paper-solver",
    ),
    (
        "nls-ec-r2-n32-newton",
        "--problem nls --n 32 --r 2 --h 0.02 --t-end 0.2 --newton",
    ),
    (
        "fpu-tc-r2",
        "--problem fpu --method tc --r 2 --h 0.01 --t-end 5",
    ),
    (
        "fpu-tc-r3-tol",
        "--problem fpu --method tc --r 3 --h 0.02 --t-end 5 --stage-tol 1e-14",
    ),
    (
        "fpu-rknc-r2",
        "--problem fpu --omega 0 --method rknc --r 2 --h 0.05 --t-end 5",
    ),
    ("fpu-ec-r2", "--problem fpu --r 2 --h 0.01 --t-end 2"),
];

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden")
}

fn blessing() -> bool {
    std::env::var_os("ECR_BLESS").is_some_and(|v| v != "0")
}

/// Compares `found` with the golden file `path`, or writes it there with `ECR_BLESS=1`.
/// Returns a description of the difference, if any.
fn check(path: &Path, found: &str) -> Option<String> {
    if blessing() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, found).unwrap();
        return None;
    }
    let expected = match std::fs::read_to_string(path) {
        Ok(text) => text,
        Err(e) => return Some(format!("{}: {e}", path.display())),
    };
    if expected == found {
        return None;
    }
    let line = expected
        .lines()
        .zip(found.lines())
        .position(|(a, b)| a != b)
        .unwrap_or_else(|| expected.lines().count().min(found.lines().count()));
    Some(format!(
        "{}: differs from line {}:\n  golden: {:?}\n  now:    {:?}",
        path.display(),
        line + 1,
        expected.lines().nth(line).unwrap_or("<end>"),
        found.lines().nth(line).unwrap_or("<end>"),
    ))
}

fn report(diffs: Vec<String>) {
    assert!(
        diffs.is_empty(),
        "{} file(s) differ from tests/golden (if the change is meant to alter results, \
         regenerate with ECR_BLESS=1 cargo test --test it bit_identity::):\n{}",
        diffs.len(),
        diffs.join("\n")
    );
}

/// The report of `ecr run` without its timing line.
fn without_timing(json: &str) -> String {
    json.lines()
        .filter(|l| !l.trim_start().starts_with("\"wall_seconds\""))
        .map(|l| format!("{l}\n"))
        .collect()
}

#[test]
fn run_reports_are_bit_identical() {
    let mut diffs = Vec::new();
    for (name, args) in RUNS {
        let mut full = vec!["run"];
        full.extend(args.split_whitespace());
        let (code, out, err) = ecr(&full);
        assert_eq!(code, 0, "ecr {full:?}: {err}");
        assert!(out.contains("\"wall_seconds\""), "{name}: no timing field");
        let path = golden_dir().join("run").join(format!("{name}.json"));
        diffs.extend(check(&path, &without_timing(&out)));
    }
    report(diffs);
}

/// A CSV without its timing columns (`wall_seconds`; every field is unquoted).
fn without_timing_columns(csv: &str) -> String {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap_or("").split(',').collect();
    let keep: Vec<bool> = header.iter().map(|h| *h != "wall_seconds").collect();
    let row = |line: &str| -> String {
        let cells: Vec<&str> = line
            .split(',')
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(c, _)| c)
            .collect();
        format!("{}\n", cells.join(","))
    };
    std::iter::once(header.join(","))
        .chain(lines.map(str::to_string))
        .map(|l| row(&l))
        .collect()
}

/// CSVs longer than this are kept as a digest.
const WHOLE_MAX: usize = 16 * 1024;

/// `lines fnv1a64` of a text.
fn digest(text: &str) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in text.bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{} {h:016x}", text.lines().count())
}

#[test]
fn reproduce_csvs_are_bit_identical() {
    let dir = TempDir::new("bit-identity");
    let out = dir.0.join("out");
    let (code, _, err) = ecr(&["reproduce", "--quick", "--out", out.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let mut names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.ends_with(".csv"))
        .collect();
    names.sort();
    assert!(names.len() >= 10, "too few CSVs: {names:?}");
    let golden = golden_dir().join("reproduce");
    let mut diffs = Vec::new();
    let mut digests = String::new();
    for name in &names {
        let text = without_timing_columns(&std::fs::read_to_string(out.join(name)).unwrap());
        if text.len() > WHOLE_MAX {
            digests.push_str(&format!("{name} {}\n", digest(&text)));
        } else {
            diffs.extend(check(&golden.join(name), &text));
        }
    }
    diffs.extend(check(&golden.join("digests.txt"), &digests));
    // Every CSV kept whole is still written.
    if !blessing() {
        for e in std::fs::read_dir(&golden).unwrap() {
            let name = e.unwrap().file_name().into_string().unwrap();
            if name.ends_with(".csv") && !names.contains(&name) {
                diffs.push(format!(
                    "{name}: in tests/golden/reproduce, no longer written"
                ));
            }
        }
    }
    report(diffs);
}
