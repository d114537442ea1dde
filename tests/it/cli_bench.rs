//! `ecr bench --quick`: one CSV per problem with finite numbers, PNG and SVG figures,
//! summary.md covering every problem and target; `--problem` restricts the work–precision
//! part; an unusable --out or a bad --problem is a one-line error with exit status 2.

use crate::common;

use common::{TempDir, ecr};

use std::path::Path;

const PROBLEMS: [&str; 3] = ["duffing", "wind", "nls"];
const HEADER: [&str; 11] = [
    "method",
    "r",
    "s",
    "h",
    "tol",
    "cpu_seconds",
    "global_error",
    "max_energy_error",
    "setup_seconds",
    "g_evals",
    "g_seconds",
];

fn non_empty(path: &Path) -> Vec<u8> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert!(!bytes.is_empty(), "{} is empty", path.display());
    bytes
}

/// Checks the header and that every numeric cell is finite ("-": not applicable; g_evals and
/// g_seconds are given exactly for this project's series, the rows named EC…/TC…); returns
/// the method names of the rows.
fn check_csv(path: &Path) -> Vec<String> {
    let text = String::from_utf8(non_empty(path)).expect("UTF-8 CSV");
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    assert_eq!(header, HEADER, "{}", path.display());
    let mut methods = Vec::new();
    for line in lines {
        let row: Vec<&str> = line.split(',').collect();
        assert_eq!(row.len(), HEADER.len(), "{}: {line}", path.display());
        assert!(!row[0].is_empty());
        methods.push(row[0].to_string());
        let ours = row[0].starts_with("EC") || row[0].starts_with("TC");
        for (cell, col) in row.iter().zip(HEADER).skip(1) {
            if *cell == "-" && matches!(col, "r" | "s" | "tol") {
                continue;
            }
            if matches!(col, "g_evals" | "g_seconds") {
                assert_eq!(*cell != "-", ours, "{}: {col} of {line}", path.display());
                if !ours {
                    continue;
                }
                let x: f64 = cell.parse().unwrap();
                assert!(
                    x > 0.0 && x.is_finite(),
                    "{}: {col} = {cell}",
                    path.display()
                );
            }
            let x: f64 = cell
                .parse()
                .unwrap_or_else(|e| panic!("{}: {col} = {cell:?}: {e}", path.display()));
            assert!(
                x.is_finite() && x >= 0.0,
                "{}: {col} = {cell}",
                path.display()
            );
        }
        let cpu: f64 = row[5].parse().unwrap();
        assert!(cpu > 0.0, "{}: cpu {cpu}", path.display());
    }
    assert!(!methods.is_empty(), "{}: no rows", path.display());
    methods
}

#[test]
fn quick_bench_writes_everything() {
    let dir = TempDir::new("bench-quick");
    let out = dir.0.join("nested").join("out");
    let (code, stdout, stderr) = ecr(&["bench", "--quick", "--out", out.to_str().unwrap()]);
    assert_eq!(code, 0, "stderr: {stderr}");
    assert!(stdout.contains("summary.md"), "{stdout}");

    for id in PROBLEMS {
        let methods = check_csv(&out.join(format!("{id}.csv")));
        assert!(
            methods.iter().any(|m| m.starts_with("EC")),
            "{id}: no ECrP rows"
        );
        assert!(
            methods.iter().any(|m| m == "DOP853"),
            "{id}: no DOP853 rows"
        );
        for q in ["error", "energy"] {
            let png = non_empty(&out.join(format!("{id}-{q}.png")));
            assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "{id}-{q}.png is not a PNG");
            let svg = String::from_utf8(non_empty(&out.join(format!("{id}-{q}.svg")))).unwrap();
            assert!(
                svg.contains("<svg") && svg.contains("</svg>"),
                "{id}-{q}.svg"
            );
        }
    }
    let duffing = check_csv(&out.join("duffing.csv"));
    for m in [
        "TC2P",
        "RKEPC2",
        "EEI3s4",
        "HochOst4",
        "Gauss2",
        "AVF",
        "ExpAVF",
        "Rot8 (Kahan–Li)",
        "Rot8 C (Kahan–Li)",
        "Rot8 C plain (Kahan–Li)",
        "Rot2 C (Strang)",
    ] {
        assert!(duffing.iter().any(|x| x == m), "duffing.csv lacks {m}");
    }
    let nls = check_csv(&out.join("nls.csv"));
    assert!(
        nls.iter().any(|x| x.ends_with("dense")),
        "nls.csv lacks dense EC"
    );
    for m in ["EC6P", "EC6P dense", "EC6P macro"] {
        assert!(nls.iter().any(|x| x == m), "nls.csv lacks {m}");
    }

    check_scaling(&out, true);

    let summary = String::from_utf8(non_empty(&out.join("summary.md"))).unwrap();
    for needle in [
        "Duffing",
        "wind",
        "NLS",
        "1e-6",
        "1e-8",
        "1e-10",
        "1e-12",
        "DOP853",
        "RKEPC2",
        "single-threaded",
        "set-up included",
        "best ours",
        "best peer",
        "round-off floor",
        "ns (",
        "Measured at commit",
        "Scaling",
        "d log₂ d",
        "Time over own g-evaluation cost",
        "in parentheses without set-up",
        "Run-time / macro",
        "Same CPU budget",
        "Integration, not process start-up",
        "### Duffing: the rotation splitting in C against the library's, loop against loop",
        "| 8 | ",
        "## Process start-up (in none of the times above)",
        "`ecr --version` (start-up alone)",
    ] {
        assert!(summary.contains(needle), "summary.md lacks {needle:?}");
    }
}

/// `--problem wind`: only wind's files; the summary has no Duffing section and none of the
/// Duffing-only measurements (DOP853's overhead, the equal-CPU energy comparison), but wind's
/// g-cost and run-time / macro tables.
#[test]
fn problem_restricts_the_work_precision_part() {
    let dir = TempDir::new("bench-problem");
    let (code, stdout, stderr) = ecr(&[
        "bench",
        "--quick",
        "--only",
        "work-precision",
        "--problem",
        "wind",
        "--out",
        dir.0.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "stderr: {stderr}");
    assert!(stdout.contains("wind.csv"), "{stdout}");
    let methods = check_csv(&dir.0.join("wind.csv"));
    assert!(methods.iter().any(|m| m == "EC6P macro"), "{methods:?}");
    for id in ["duffing", "nls"] {
        assert!(
            !dir.0.join(format!("{id}.csv")).exists(),
            "{id}.csv written"
        );
    }
    assert!(!dir.0.join("scaling.csv").exists());
    let summary = String::from_utf8(non_empty(&dir.0.join("summary.md"))).unwrap();
    for needle in [
        "### conservative wind",
        "Problems run (`--problem`): wind.",
        "Time over own g-evaluation cost",
        "Run-time / macro",
    ] {
        assert!(summary.contains(needle), "summary.md lacks {needle:?}");
    }
    for absent in [
        "### Duffing",
        "| duffing |",
        "Same CPU budget",
        "DOP853's cost per evaluation",
        "rotation splitting in C",
    ] {
        assert!(!summary.contains(absent), "summary.md has {absent:?}");
    }
}

/// A bad --problem (unknown, empty, in a comma list, or with --only scaling) is rejected before
/// any work: one line on stderr naming the problem, status 2.
#[test]
fn bad_problem_is_a_one_line_error() {
    let cases: &[(&[&str], &str)] = &[
        (&["bench", "--problem", "heat"], "heat"),
        (&["bench", "--problem", "wind,heat"], "heat"),
        (
            &["bench", "--quick", "--problem", "wind", "--problem", "NLS"],
            "NLS",
        ),
        (
            &["bench", "--quick", "--only", "scaling", "--problem", "wind"],
            "--problem",
        ),
    ];
    for (args, named) in cases {
        let (code, stdout, stderr) = ecr(args);
        assert_eq!(code, 2, "{args:?}: stdout {stdout} stderr {stderr}");
        assert!(stdout.is_empty(), "{args:?}: {stdout}");
        assert!(stderr.starts_with("error: "), "{args:?}: {stderr}");
        assert_eq!(stderr.trim_end().lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.contains(named), "{args:?}: {stderr}");
    }
}

/// scaling.csv: 1D rows N = 2^7.. and 2D rows, finite positive timings, d = 2N or 2n²,
/// energy changes at round-off level; the figure in both formats.
fn check_scaling(out: &Path, expect_2d: bool) {
    let text = String::from_utf8(non_empty(&out.join("scaling.csv"))).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "case,grid,d,steps,seconds_per_step,sweeps_per_step,energy_error,setup_seconds"
    );
    let (mut one, mut two) = (0, 0);
    for line in lines {
        let row: Vec<&str> = line.split(',').collect();
        assert_eq!(row.len(), 8, "{line}");
        let d: usize = row[2].parse().unwrap();
        match row[0] {
            "1D" => {
                one += 1;
                assert_eq!(row[1], format!("N = {}", d / 2), "{line}");
            }
            "2D" => {
                two += 1;
                let n = ((d / 2) as f64).sqrt() as usize;
                assert_eq!(row[1], format!("{n} × {n}"), "{line}");
            }
            other => panic!("unknown case {other}"),
        }
        for cell in &row[4..] {
            let x: f64 = cell.parse().unwrap();
            assert!(x.is_finite() && x >= 0.0, "{line}");
        }
        let sweeps: f64 = row[5].parse().unwrap();
        assert!(sweeps >= 1.0, "{line}");
        // A few steps of an order-4 method at h = 1/200: the energy moves by far less than 1e-6.
        let energy: f64 = row[6].parse().unwrap();
        assert!(energy < 1e-6, "{line}");
    }
    assert!(one >= 3, "too few 1D sizes: {one}");
    assert_eq!(two > 0, expect_2d);
    for ext in ["png", "svg"] {
        non_empty(&out.join(format!("scaling.{ext}")));
    }
}

#[test]
fn only_scaling_runs_only_the_scaling_study() {
    let dir = TempDir::new("bench-only");
    let (code, stdout, stderr) = ecr(&[
        "bench",
        "--quick",
        "--only",
        "scaling",
        "--out",
        dir.0.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "stderr: {stderr}");
    assert!(stdout.contains("scaling.csv"), "{stdout}");
    check_scaling(&dir.0, true);
    for id in PROBLEMS {
        assert!(
            !dir.0.join(format!("{id}.csv")).exists(),
            "{id}.csv written"
        );
    }
    let summary = String::from_utf8(non_empty(&dir.0.join("summary.md"))).unwrap();
    assert!(summary.contains("Fitted exponents"), "{summary}");
    assert!(!summary.contains("Work–precision"), "{summary}");

    let (code, stdout, stderr) = ecr(&["bench", "--only", "everything"]);
    assert_eq!(code, 2, "stdout: {stdout} stderr: {stderr}");
    assert!(stderr.contains("everything"), "{stderr}");
}

#[test]
fn unusable_out_is_a_one_line_error() {
    let dir = TempDir::new("bench-bad");
    std::fs::create_dir_all(&dir.0).unwrap();
    let file = dir.0.join("not-a-dir");
    std::fs::write(&file, b"x").unwrap();
    for out in [file.clone(), file.join("sub")] {
        let (code, stdout, stderr) = ecr(&["bench", "--quick", "--out", out.to_str().unwrap()]);
        assert_eq!(code, 2, "stdout: {stdout} stderr: {stderr}");
        assert!(stdout.is_empty());
        assert!(stderr.starts_with("error: "), "{stderr}");
        assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
        assert!(stderr.contains("not-a-dir"), "{stderr}");
    }
}

#[test]
fn malformed_arguments_are_one_line_errors() {
    // Every command, and none at all: rejected before any work, one line on stderr, status 2.
    let cases: &[&[&str]] = &[
        &[],
        &["benchmark"],
        &["bench", "--only", "nonsense"],
        &["bench", "--only"],
        &["bench", "--quick", "extra"],
        &["bench", "--out"],
        &["bench", "--quick=yes"],
        &["bench", "--problem"],
        &["bench", "--problem", ""],
        &["reproduce", "--bogus"],
        &["reproduce", "--out"],
        &["reproduce", "--quick", "--quick"],
        &["tables", "--r"],
        &["tables", "--family", "ec", "--r", "3", "--s", "-1"],
        &["run"],
        &[
            "run",
            "--problem",
            "duffing",
            "--r",
            "2",
            "--h",
            "0.1",
            "--t-end",
        ],
    ];
    for args in cases {
        let (code, stdout, stderr) = ecr(args);
        assert_eq!(code, 2, "{args:?}: stdout {stdout} stderr {stderr}");
        assert!(stdout.is_empty(), "{args:?}: {stdout}");
        assert!(stderr.starts_with("error: "), "{args:?}: {stderr}");
        assert_eq!(stderr.trim_end().lines().count(), 1, "{args:?}: {stderr}");
    }
}
