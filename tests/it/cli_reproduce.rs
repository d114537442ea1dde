//! `ecr reproduce --quick`: every figure (PNG, SVG), CSV and the report are written, the CSVs
//! parse with finite numbers, the report covers the three problems; an unusable --out is a
//! one-line error with exit status 2.

use crate::common;

use common::{TempDir, ecr};

use std::path::Path;

const FIGURES: [&str; 5] = ["p1-1", "p1-2", "p2-1", "p2-2", "p3"];
const ERROR_CSVS: [&str; 6] = ["p1-1a", "p1-1b", "p1-1c", "p2-1a", "p2-2a", "p3a"];
const ENERGY_CSVS: [&str; 5] = ["p1-2a", "p1-2b", "p1-2c", "p2-1b", "p3b"];

fn non_empty(path: &Path) -> Vec<u8> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert!(!bytes.is_empty(), "{} is empty", path.display());
    bytes
}

/// Parses a CSV (no quoting is used): checks the header, a constant number of columns, at
/// least one row, and that every numeric cell is finite. Returns (header, rows).
fn check_csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = String::from_utf8(non_empty(path)).expect("UTF-8 CSV");
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .expect("header")
        .split(',')
        .map(str::to_string)
        .collect();
    let rows: Vec<Vec<String>> = lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    assert!(!rows.is_empty(), "{}: no rows", path.display());
    let mut numbers = 0;
    for row in &rows {
        assert_eq!(row.len(), header.len(), "{}: row {row:?}", path.display());
        for (cell, col) in row.iter().zip(&header) {
            if col == "method" || col == "panel" || col == "quantity" {
                assert!(!cell.is_empty());
                continue;
            }
            let x: f64 = cell
                .parse()
                .unwrap_or_else(|e| panic!("{}: {col} = {cell:?}: {e}", path.display()));
            assert!(x.is_finite(), "{}: {col} = {cell}", path.display());
            numbers += 1;
        }
    }
    assert!(numbers > 0);
    (header, rows)
}

fn column(header: &[String], name: &str) -> usize {
    header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name} in {header:?}"))
}

#[test]
fn quick_reproduction_writes_everything() {
    let dir = TempDir::new("reproduce-quick");
    let out = dir.0.join("nested").join("out");
    let (code, stdout, stderr) = ecr(&["reproduce", "--quick", "--out", out.to_str().unwrap()]);
    assert_eq!(code, 0, "stderr: {stderr}");
    // With stderr not a terminal, progress comes as plain lines: one at the start, one at
    // the end (at most one every 15 s between them), nothing else.
    let lines: Vec<&str> = stderr.lines().collect();
    assert!(lines.len() >= 2, "no progress lines: {stderr}");
    assert!(
        lines.iter().all(|l| l.starts_with("progress: ")),
        "{stderr}"
    );
    assert!(
        lines[0].contains("0% after 0s") && lines[0].ends_with("starting"),
        "{stderr}"
    );
    assert!(
        lines[lines.len() - 1].starts_with("progress: done in "),
        "{stderr}"
    );
    assert!(stdout.contains("report.md"), "{stdout}");

    for fig in FIGURES {
        let png = non_empty(&out.join(format!("{fig}.png")));
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "{fig}.png is not a PNG");
        let svg = String::from_utf8(non_empty(&out.join(format!("{fig}.svg")))).unwrap();
        assert!(svg.contains("<svg") && svg.contains("</svg>"), "{fig}.svg");
        assert!(
            svg.contains("<polyline") || svg.contains("<path"),
            "{fig}.svg has no curve"
        );
    }

    for id in ERROR_CSVS {
        let (header, rows) = check_csv(&out.join(format!("{id}.csv")));
        let err = column(&header, "global_error");
        let method = column(&header, "method");
        assert!(
            rows.iter().any(|r| r[method] == "EC2P"),
            "{id}: no EC2P rows"
        );
        for r in &rows {
            let e: f64 = r[err].parse().unwrap();
            // EC2P is accurate at every step size of the study; a baseline may legitimately
            // lose the phase at the coarsest h (RKEPC2 at hω = 1: error O(1)).
            if r[method] == "EC2P" {
                assert!((0.0..1.0).contains(&e), "{id}: EC2P global error {e}");
            } else {
                assert!(
                    e.is_finite() && e >= 0.0,
                    "{id}: {} global error {e}",
                    r[method]
                );
            }
        }
        // Four step sizes per method.
        let ec2p = rows.iter().filter(|r| r[method] == "EC2P").count();
        assert_eq!(ec2p, 4, "{id}");
    }
    for id in ENERGY_CSVS {
        let (header, rows) = check_csv(&out.join(format!("{id}.csv")));
        let err = column(&header, "energy_error");
        for r in &rows {
            let e: f64 = r[err].parse().unwrap();
            assert!((0.0..1e-2).contains(&e), "{id}: energy error {e}");
        }
    }
    let (header, rows) = check_csv(&out.join("p2-2b.csv"));
    let method = column(&header, "method");
    assert!(rows.iter().any(|r| r[method] == "EC2P-reference"));
    assert!(rows.iter().any(|r| r[method] == "EC2P"));
    check_csv(&out.join("summary.csv"));

    let report = String::from_utf8(non_empty(&out.join("report.md"))).unwrap();
    for needle in [
        "Problem 1",
        "Duffing",
        "Problem 2",
        "wind",
        "Problem 3",
        "NLS",
        "observed order",
        "Lyapunov",
        "EC2P",
        "QUICK",
    ] {
        assert!(report.contains(needle), "report.md lacks {needle:?}");
    }
    for fig in FIGURES.iter().chain(&ERROR_CSVS).chain(&ENERGY_CSVS) {
        assert!(report.contains(fig), "report.md does not mention {fig}");
    }
    check_verdict_first(&report);
    check_no_repeated_sentence(&report);
    check_significant_digits(&report, 6);
    check_omitted_methods_explained(&out, &report);
    // The error studies against a computed reference draw its estimated error.
    for fig in ["p2-1", "p2-2", "p3"] {
        let svg = std::fs::read_to_string(out.join(format!("{fig}.svg"))).unwrap();
        assert!(
            svg.contains("reference error (est.)"),
            "{fig}.svg: no floor line"
        );
    }
}

/// The report opens with its verdict: after the title and the line that says how it was made,
/// the first section is "## Verdict", a table with one row per error study (every problem:
/// Duffing, wind, NLS) saying who wins at equal h, at equal error and in energy, each cell
/// naming a method; the details (methods, setup, problems) come after it.
fn check_verdict_first(report: &str) {
    // The first paragraph after the title answers the paper's claim in one sentence.
    let first = report
        .split("\n\n")
        .map(str::trim)
        .find(|p| !p.is_empty() && !p.starts_with('#'))
        .unwrap_or("");
    assert!(first.starts_with("**Answer.** In this run EC2P"), "{first}");
    assert!(first.contains("invariant-preserving property"), "{first}");
    assert_eq!(
        first.matches(". ").count() + 1,
        2,
        "one sentence and a pointer: {first}"
    );
    let sections: Vec<&str> = report.lines().filter(|l| l.starts_with("## ")).collect();
    assert_eq!(sections.first(), Some(&"## Verdict"), "{sections:?}");
    let start = report.find("## Verdict").unwrap();
    let end = report.find("## Methods").expect("a Methods section");
    assert!(start < end);
    let verdict = &report[start..end];
    assert!(
        verdict.contains(
            "| problem | at equal h: smallest error | at equal error: least time | energy: smallest error |"
        ),
        "{verdict}"
    );
    for id in ERROR_CSVS {
        let row = verdict
            .lines()
            .find(|l| l.starts_with("| ") && l.contains(&format!("(`{id}`)")))
            .unwrap_or_else(|| panic!("no verdict row for {id}: {verdict}"));
        let cells: Vec<&str> = row.trim_matches('|').split(" | ").map(str::trim).collect();
        assert_eq!(cells.len(), 4, "{row}");
        for cell in &cells[1..] {
            assert!(
                ["EC2P", "RKEPC2", "EEI3s4", "DOP853"]
                    .iter()
                    .any(|m| cell.contains(m)),
                "{id}: a verdict cell names no method: {row}"
            );
        }
    }
    for problem in ["Duffing", "wind", "NLS"] {
        assert!(verdict.contains(problem), "the verdict lacks {problem}");
    }
}

/// The prose of the report (not table rows, headings or the code spans of file lists) split
/// into sentences: none may appear twice.
fn check_no_repeated_sentence(report: &str) {
    let mut seen = std::collections::HashSet::new();
    for line in report.lines() {
        let line = line.trim();
        if line.starts_with('|') || line.starts_with('#') || line.is_empty() {
            continue;
        }
        for sentence in line.split(". ").map(str::trim) {
            // Short fragments ("e.g", "i = 0..3") are not sentences.
            if sentence.chars().count() < 30 {
                continue;
            }
            assert!(
                seen.insert(sentence.to_string()),
                "sentence repeated in report.md: {sentence:?}"
            );
        }
    }
}

/// No number in the report has more than `max` significant digits (spurious digits such as
/// "factor 5374938.536"); integers count without trailing zeros.
fn check_significant_digits(report: &str, max: usize) {
    let bytes = report.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        let starts = bytes[i].is_ascii_digit()
            && (i == 0 || !(bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'_'));
        if !starts {
            i += 1;
            continue;
        }
        let start = i;
        while i < bytes.len() && (bytes[i].is_ascii_digit() || bytes[i] == b'.') {
            i += 1;
        }
        let mantissa = report[start..i].trim_end_matches('.');
        let digits: String = mantissa.chars().filter(char::is_ascii_digit).collect();
        let digits = digits.trim_start_matches('0');
        let digits = if mantissa.contains('.') {
            digits
        } else {
            digits.trim_end_matches('0')
        };
        assert!(
            digits.len() <= max,
            "report.md: {mantissa} has {} significant digits (> {max}): …{}…",
            digits.len(),
            &report[start.saturating_sub(60)..(i + 20).min(report.len())]
        );
    }
}

/// A method that has rows in some error study but none in another is missing from that
/// study's panel: the figure (SVG text) and the report's figure notes say why.
fn check_omitted_methods_explained(out: &Path, report: &str) {
    let methods_of = |id: &str| -> Vec<String> {
        let (header, rows) = check_csv(&out.join(format!("{id}.csv")));
        let m = column(&header, "method");
        let mut v: Vec<String> = rows.iter().map(|r| r[m].clone()).collect();
        v.dedup();
        v
    };
    let all: Vec<String> = ERROR_CSVS.iter().flat_map(|id| methods_of(id)).collect();
    let mut omitted = 0;
    for (id, fig) in ERROR_CSVS
        .iter()
        .zip(["p1-1", "p1-1", "p1-1", "p2-1", "p2-2", "p3"])
    {
        let present = methods_of(id);
        let svg = std::fs::read_to_string(out.join(format!("{fig}.svg"))).unwrap();
        for m in all.iter().filter(|m| !present.contains(m)) {
            omitted += 1;
            let note = format!("{m} not shown: ");
            assert!(
                svg.contains(&note),
                "{fig}.svg does not say why {m} is missing"
            );
            assert!(
                report
                    .lines()
                    .any(|l| l.starts_with(&format!("- `{fig}`")) && l.contains(&note)),
                "report.md does not say why {m} is missing from {fig}"
            );
        }
    }
    // The quick run has omitted methods (RKEPC2 diverges on the NLS at h = 0.0125), so the
    // check above is exercised.
    assert!(
        omitted > 0,
        "no panel omits a method: the check did not run"
    );
}

#[test]
fn unusable_out_is_a_one_line_error() {
    let dir = TempDir::new("reproduce-bad");
    std::fs::create_dir_all(&dir.0).unwrap();
    // A regular file where the output directory should be (or below it).
    let file = dir.0.join("not-a-dir");
    std::fs::write(&file, b"x").unwrap();
    for out in [file.clone(), file.join("sub")] {
        let (code, stdout, stderr) = ecr(&["reproduce", "--quick", "--out", out.to_str().unwrap()]);
        assert_eq!(code, 2, "stdout: {stdout} stderr: {stderr}");
        assert!(stdout.is_empty());
        assert!(stderr.starts_with("error: "), "{stderr}");
        assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
        assert!(stderr.contains("not-a-dir"), "{stderr}");
    }
}

#[test]
fn help_lists_reproduce() {
    let (code, stdout, _) = ecr(&["--help"]);
    assert_eq!(code, 0);
    assert!(stdout.contains("reproduce"));
    let (code, stdout, _) = ecr(&["reproduce", "--help"]);
    assert_eq!(code, 0);
    assert!(stdout.contains("--quick") && stdout.contains("--out"));
}

/// `reproduce > /dev/full`: the files are complete and stay; the line on stderr says so, and
/// the status is 1 (standard output failed), not 2 (bad input or a failed run).
#[test]
fn full_stdout_keeps_the_files_and_says_so() {
    let out = TempDir::new("reproduce-full");
    let dir = out.0.to_str().unwrap();
    let full = std::fs::File::create("/dev/full").unwrap();
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_ecr"))
        .args(["reproduce", "--quick", "--out", dir])
        .stdout(full)
        .output()
        .unwrap();
    let stderr = String::from_utf8(run.stderr).unwrap();
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    // Besides the plain progress lines, one line.
    let err: Vec<&str> = stderr
        .lines()
        .filter(|l| !l.starts_with("progress: "))
        .collect();
    assert_eq!(err.len(), 1, "{stderr}");
    assert!(
        err[0].starts_with("error: wrote ") && err[0].contains(dir),
        "{stderr}"
    );
    assert!(out.0.join("report.md").is_file());
}

/// Without --out, a quick run writes to its own directory, out/reproduce-quick, and leaves a
/// full run's out/reproduce alone.
#[test]
fn quick_without_out_writes_its_own_directory() {
    let dir = TempDir::new("reproduce-quick-default");
    let full = dir.0.join("out").join("reproduce");
    std::fs::create_dir_all(&full).unwrap();
    std::fs::write(full.join("report.md"), "a full run's report").unwrap();
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_ecr"))
        .args(["reproduce", "--quick"])
        .current_dir(&dir.0)
        .output()
        .unwrap();
    let stdout = String::from_utf8(run.stdout).unwrap();
    assert_eq!(run.status.code(), Some(0), "{stdout}");
    assert!(stdout.contains("out/reproduce-quick"), "{stdout}");
    assert!(dir.0.join("out/reproduce-quick/report.md").is_file());
    assert_eq!(
        std::fs::read_to_string(full.join("report.md")).unwrap(),
        "a full run's report"
    );
}
