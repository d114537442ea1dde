//! `ecr ensemble`: the table of one run, the same with 1 and 2 threads and from shards joined
//! by `ecr ensemble merge` (byte for byte, and as NPY); failed members as rows;
//! merges of parts that are missing, twice, of another ensemble, cut short or of a killed
//! shard refused in one line.

use crate::common;

use common::{TempDir, ecr};
use std::path::Path;

/// Hénon–Heiles at the energy 1/10 from a 4 × 5 grid of (q2, p2): at the four corners
/// (q2, p2) = (±0.3, ±0.4) no real p1 reaches the energy (failed rows).
const GRID: &[&str] = &[
    "ensemble",
    "--problem",
    "henon-heiles",
    "--vary",
    "q2=-0.3:0.3:4",
    "--vary",
    "p2=-0.4:0.4:5",
    "--energy",
    "0.1",
    "--tol",
    "1e-6",
    "--t-end",
    "5",
];

fn run(extra: &[&str]) -> (i32, String, String) {
    let args: Vec<&str> = GRID.iter().chain(extra).copied().collect();
    ecr(&args)
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap()
}

/// The header row and the rows of a table: its lines but the first line and the
/// fingerprint (`# ` lines).
fn rows(table: &str) -> Vec<&str> {
    table.lines().filter(|l| !l.starts_with('#')).collect()
}

fn path(dir: &TempDir, name: &str) -> String {
    dir.0.join(name).to_str().unwrap().to_string()
}

/// One line on stderr starting with "error: ", exit status 2, containing `what`.
fn assert_refused((code, _, err): (i32, String, String), what: &str) {
    assert_eq!(code, 2, "{err}");
    assert!(
        err.starts_with("error: ") && err.trim_end().lines().count() == 1,
        "{err}"
    );
    assert!(err.contains(what), "'{what}' not in: {err}");
}

#[test]
fn threads_and_shards_merged_give_the_table_of_one_run() {
    let dir = TempDir::new("ensemble-merge");
    std::fs::create_dir_all(&dir.0).unwrap();
    let one = path(&dir, "one.csv");
    let (code, out, err) = run(&["--threads", "1", "--out", &one]);
    assert_eq!(code, 3, "{err}"); // four members fail: status 3
    assert!(out.contains("20 members"), "{out}");
    let table = read(Path::new(&one));
    assert!(
        table.starts_with("# ecr ensemble table of 20 members: ecr "),
        "{table}"
    );
    assert!(table.contains("\n# rtol: 1e-6\n"), "{table}");
    let lines = rows(&table);
    assert_eq!(lines.len(), 21);
    assert_eq!(
        lines[0],
        "member,q2,p2,status,t,q1_end,q2_end,p1_end,p2_end,error_estimate,energy_error,\
         g_evals,message"
    );
    assert!(
        lines[1].starts_with("0,-0.3,-0.4,failed,,,,,,,,,"),
        "{}",
        lines[1]
    );
    assert!(
        lines[2].starts_with("1,-0.3,-0.2,verified,5.0,"),
        "{}",
        lines[2]
    );
    let failed = lines.iter().filter(|l| l.contains(",failed,")).count();
    assert_eq!(failed, 4, "{table}");
    let verified = lines.iter().filter(|l| l.contains(",verified,")).count();
    assert_eq!(verified, 16, "{table}");

    let two = path(&dir, "two.csv");
    let two_npy = path(&dir, "two.npy");
    assert_eq!(
        run(&["--threads", "2", "--npy", &two_npy, "--out", &two]).0,
        3
    );
    assert_eq!(read(Path::new(&two)), table);
    let npy = std::fs::read(&two_npy).unwrap();
    assert!(npy.starts_with(b"\x93NUMPY"), "{npy:?}");

    let parts: Vec<String> = (1..=3)
        .map(|k| path(&dir, &format!("part{k}.csv")))
        .collect();
    for (k, part) in parts.iter().enumerate() {
        let shard = format!("{}/3", k + 1);
        let (code, _, err) = run(&["--shard", &shard, "--out", part]);
        assert!(code == 0 || code == 3, "{err}");
    }
    let part1 = read(Path::new(&parts[0]));
    assert!(
        part1.starts_with("# ecr ensemble part 1/3 of 20 members: "),
        "{part1}"
    );
    let end = part1.lines().last().unwrap();
    let digest = end
        .strip_prefix("# end of part 1/3: 7 rows, sha256 ")
        .unwrap_or_else(|| panic!("{part1}"));
    assert!(
        digest.len() == 64 && digest.bytes().all(|b| b.is_ascii_hexdigit()),
        "{end}"
    );
    let merged = path(&dir, "merged.csv");
    let merged_npy = path(&dir, "merged.npy");
    let (code, out, err) = ecr(&[
        "ensemble",
        "merge",
        "--out",
        &merged,
        "--npy",
        &merged_npy,
        &parts[2],
        &parts[0],
        &parts[1],
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("20 members from 3 parts"), "{out}");
    assert_eq!(read(Path::new(&merged)), table);
    assert!(
        std::fs::read(&merged_npy).unwrap() == npy,
        "the NPY of the merge differs"
    );
}

#[test]
fn merges_of_incomplete_or_mixed_parts_are_refused() {
    let dir = TempDir::new("ensemble-refuse");
    std::fs::create_dir_all(&dir.0).unwrap();
    let parts: Vec<String> = (1..=3)
        .map(|k| path(&dir, &format!("part{k}.csv")))
        .collect();
    for (k, part) in parts.iter().enumerate() {
        let shard = format!("{}/3", k + 1);
        assert!([0, 3].contains(&run(&["--shard", &shard, "--out", part]).0));
    }
    let merged = path(&dir, "merged.csv");
    let merge = |parts: &[&str]| {
        let mut args = vec!["ensemble", "merge", "--out", &merged];
        args.extend(parts);
        ecr(&args)
    };
    assert_refused(merge(&[&parts[0], &parts[2]]), "1 of 3 parts missing: 2");
    assert_refused(merge(&[&parts[0], &parts[1], &parts[1]]), "given twice");

    // A part of another ensemble (another T).
    let other = path(&dir, "other.csv");
    let mut args: Vec<&str> = GRID.to_vec();
    let t = args.iter().position(|a| *a == "--t-end").unwrap();
    args[t + 1] = "6";
    args.extend(["--shard", "2/3", "--out", &other]);
    assert_eq!(ecr(&args).0, 3);
    assert_refused(
        merge(&[&parts[0], &other, &parts[2]]),
        "are parts of different runs (t_eval: [5.0] in ",
    );

    // Cut short: without its end line, or in the middle of a row.
    let full = read(Path::new(&parts[1]));
    let cut = path(&dir, "cut.csv");
    let without_end = &full[..full.trim_end().rfind('\n').unwrap() + 1];
    for text in [without_end, &full[..full.len() / 2]] {
        std::fs::write(&cut, text).unwrap();
        assert_refused(
            merge(&[&parts[0], &cut, &parts[2]]),
            "its shard was killed or has not finished",
        );
    }
    // A row removed (the end line kept): the rows no longer follow the members.
    let mut lines: Vec<&str> = full.lines().collect();
    let header = lines.iter().position(|l| !l.starts_with('#')).unwrap();
    lines.remove(header + 2);
    std::fs::write(&cut, lines.join("\n") + "\n").unwrap();
    assert_refused(
        merge(&[&parts[0], &cut, &parts[2]]),
        "was changed after its shard",
    );
    // Not a part at all: a whole table.
    let whole = path(&dir, "whole.csv");
    assert_eq!(run(&["--out", &whole]).0, 3);
    assert_refused(merge(&[&whole]), "is not a part");
    assert!(
        !Path::new(&merged).exists(),
        "a refused merge wrote its --out"
    );
}

/// A shard killed while it solves leaves no table at its --out (at most a hidden staging
/// file, which the next run there removes), and the merge without it is refused.
#[test]
fn a_killed_shard_leaves_no_table() {
    let dir = TempDir::new("ensemble-kill");
    std::fs::create_dir_all(&dir.0).unwrap();
    let part = path(&dir, "part2.csv");
    let mut args: Vec<&str> = GRID.to_vec();
    let t = args.iter().position(|a| *a == "--t-end").unwrap();
    args[t + 1] = "100000"; // far longer than the kill's delay
    args.extend(["--shard", "2/3", "--out", &part]);
    let status = common::ecr_interrupted(&args, std::time::Duration::from_millis(500), "KILL");
    assert!(!status.success());
    assert!(!Path::new(&part).exists(), "a killed shard left {part}");
    let left: Vec<String> = std::fs::read_dir(&dir.0)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert!(
        left.iter()
            .all(|f| f.starts_with(".part2.csv.ecr-partial-")),
        "{left:?}"
    );
    let (p1, p3) = (path(&dir, "part1.csv"), path(&dir, "part3.csv"));
    assert_eq!(run(&["--shard", "1/3", "--out", &p1]).0, 3);
    assert_eq!(run(&["--shard", "3/3", "--out", &p3]).0, 0);
    let merged = path(&dir, "merged.csv");
    assert_refused(
        ecr(&["ensemble", "merge", "--out", &merged, &p1, &p3]),
        "parts missing: 2",
    );
    // The next run with the same --out removes the staging file of the killed one.
    assert_eq!(run(&["--shard", "2/3", "--out", &part]).0, 3);
    let mut left: Vec<String> = std::fs::read_dir(&dir.0)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    left.sort();
    assert_eq!(left, ["part1.csv", "part2.csv", "part3.csv"]);
}

#[test]
fn a_fixed_step_run_and_bad_input() {
    let dir = TempDir::new("ensemble-fixed");
    std::fs::create_dir_all(&dir.0).unwrap();
    let out = path(&dir, "duffing.csv");
    let (code, _, err) = ecr(&[
        "ensemble",
        "--problem",
        "duffing",
        "--vary",
        "omega=5:10:3",
        "--vary",
        "k=0:0.1:2",
        "--r",
        "2",
        "--h",
        "0.01",
        "--t-end",
        "1",
        "--cpu-seconds",
        "--out",
        &out,
    ]);
    assert_eq!(code, 0, "{err}");
    let table = read(Path::new(&out));
    let lines = rows(&table);
    assert_eq!(lines.len(), 7);
    assert_eq!(
        lines[0],
        "member,omega,k,status,t,q_end,p_end,error_estimate,energy_error,g_evals,message,\
         cpu_seconds"
    );
    // No estimate for a fixed step; member 5 is ω = 10, k = 0.1.
    assert!(lines[6].starts_with("5,10.0,0.1,ok,1.0,"), "{}", lines[6]);
    let fields: Vec<&str> = lines[6].split(',').collect();
    assert_eq!(fields[7], "");

    let bad: &[(&[&str], &str)] = &[
        (
            &["--problem", "henon-heiles", "--vary", "omega=1:2:2"],
            "q1, q2, p1, p2",
        ),
        (
            &[
                "--problem",
                "duffing",
                "--vary",
                "k=0:1:2",
                "--energy",
                "0.1",
            ],
            "--energy",
        ),
        (
            &[
                "--problem",
                "duffing",
                "--vary",
                "k=0:1:2",
                "--vary",
                "k=0:1:2",
            ],
            "twice",
        ),
        (&["--problem", "duffing", "--vary", "k=0:1:0"], "COUNT"),
        (
            &[
                "--problem",
                "duffing",
                "--vary",
                "k=0:1:2",
                "--shard",
                "4/3",
            ],
            "K must be",
        ),
        (
            &[
                "--problem",
                "duffing",
                "--vary",
                "k=0:1:2",
                "--threads",
                "0",
            ],
            "--threads",
        ),
        (
            &["--problem", "duffing", "--vary", "k=0:1:2", "--r", "40"],
            "--r 40",
        ),
    ];
    for (args, what) in bad {
        let mut all = vec!["ensemble"];
        all.extend(*args);
        if !all.contains(&"--r") {
            all.extend(["--tol", "1e-6"]);
        } else {
            all.extend(["--h", "0.1"]);
        }
        all.extend(["--t-end", "1", "--out", &out]);
        assert_refused(ecr(&all), what);
    }
    assert_refused(
        ecr(&[
            "ensemble",
            "--problem",
            "duffing",
            "--vary",
            "k=0:1:2",
            "--tol",
            "1e-6",
            "--t-end",
            "1",
            "--out",
            dir.0.to_str().unwrap(),
        ]),
        "is a directory",
    );
    // The refused runs left the table as it was.
    assert_eq!(read(Path::new(&out)), table);
}

/// Issue 52, item 5: counts whose table cannot be written (or counted) are one line and exit
/// status 2 at once, before anything large is allocated (they panicked, aborted, or took
/// 7.8 GB before refusing).
#[test]
fn huge_counts_are_refused_in_one_line() {
    let dir = TempDir::new("ensemble-huge");
    std::fs::create_dir_all(&dir.0).unwrap();
    let out = path(&dir, "a.csv");
    for count in ["18446744073709551615", "3000000000", "1000000000"] {
        let vary = format!("q0=0:1:{count}");
        let args = [
            "ensemble",
            "--problem",
            "duffing",
            "--tol",
            "1e-6",
            "--t-end",
            "1",
            "--vary",
            &vary,
            "--out",
            &out,
        ];
        assert_refused(ecr(&args), "members");
    }
    assert!(!Path::new(&out).exists());
}

/// Issue 52, item 6: a run where members fail exits with a status that says so (3), the
/// table written all the same.
#[test]
fn failed_members_give_a_nonzero_status() {
    let dir = TempDir::new("ensemble-status");
    std::fs::create_dir_all(&dir.0).unwrap();
    let out = path(&dir, "a.csv");
    let (code, stdout, err) = ecr(&[
        "ensemble",
        "--problem",
        "duffing",
        "--tol",
        "1e-20",
        "--t-end",
        "1",
        "--vary",
        "q0=0:0.1:2",
        "--out",
        &out,
    ]);
    assert_eq!(code, 3, "{stdout}{err}");
    assert!(stdout.contains("0 verified"), "{stdout}");
    assert_eq!(rows(&read(Path::new(&out))).len(), 3);
}

/// Issue 52, item 8: absurd thread counts and negative shards are one readable line.
#[test]
fn absurd_threads_and_negative_shards_are_refused_in_one_line() {
    let dir = TempDir::new("ensemble-threads");
    std::fs::create_dir_all(&dir.0).unwrap();
    let out = path(&dir, "a.csv");
    let base = [
        "ensemble",
        "--problem",
        "duffing",
        "--tol",
        "1e-6",
        "--t-end",
        "1",
        "--vary",
        "q0=0:0.1:2",
        "--out",
        &out,
    ];
    let mut args = base.to_vec();
    args.extend(["--threads", "5000"]);
    assert_refused(ecr(&args), "--threads 5000");
    let mut args = base.to_vec();
    args.extend(["--shard", "-1/3"]);
    assert_refused(ecr(&args), "--shard -1/3");
}

/// Issue 52, item 8: a part with an edited row (same member, same count, same end line) is
/// refused by the merge: the end line carries a digest of the rows.
#[test]
fn a_part_with_an_edited_row_is_refused() {
    let dir = TempDir::new("ensemble-digest");
    std::fs::create_dir_all(&dir.0).unwrap();
    let parts: Vec<String> = (1..=2)
        .map(|k| path(&dir, &format!("part{k}.csv")))
        .collect();
    for (k, part) in parts.iter().enumerate() {
        let shard = format!("{}/2", k + 1);
        let (code, _, err) = run(&["--shard", &shard, "--out", part]);
        assert!(code == 0 || code == 3, "{err}");
    }
    let text = read(Path::new(&parts[1]));
    let edited = text.replacen(",verified,5.0,", ",verified,5.0000001,", 1);
    assert_ne!(edited, text);
    std::fs::write(&parts[1], edited).unwrap();
    let merged = path(&dir, "merged.csv");
    assert_refused(
        ecr(&["ensemble", "merge", "--out", &merged, &parts[0], &parts[1]]),
        "digest",
    );
    assert!(!Path::new(&merged).exists());
}

/// A run killed by SIGKILL at random moments (several times, on one and on two threads) and
/// resumed each time writes, once it completes, the table of an uninterrupted run byte for
/// byte; a killed run never leaves a table at --out; the unfinished
/// file it leaves holds whole rows only, which the next --resume keeps.
#[test]
fn runs_killed_at_random_moments_and_resumed_write_the_table_of_one_run() {
    use common::{Moment, Rng};
    let dir = TempDir::new("ensemble-resume");
    std::fs::create_dir_all(&dir.0).unwrap();
    let grid = [
        "ensemble",
        "--problem",
        "henon-heiles",
        "--vary",
        "q2=-0.3:0.3:30",
        "--vary",
        "p2=-0.3:0.3:30",
        "--energy",
        "0.125",
        "--tol",
        "1e-8",
        // Long enough (about 3 s on one thread, debug build) that a kill at a fifth of it
        // comes after the first sync of the unfinished file (rows are synced every second).
        "--t-end",
        "120",
    ];
    let one = path(&dir, "one.csv");
    let mut args = grid.to_vec();
    args.extend(["--threads", "1", "--quiet", "--out", &one]);
    let start = std::time::Instant::now();
    let (code, _, err) = ecr(&args);
    assert_eq!(code, 0, "{err}");
    let duration = start.elapsed().as_secs_f64();
    let table = read(Path::new(&one));
    assert_eq!(rows(&table).len(), 901);
    let mut rng = Rng::new(52);
    for (threads, kills) in [("1", 4), ("2", 3)] {
        let out = path(&dir, &format!("resumed{threads}.csv"));
        let mut args = grid.to_vec();
        args.extend(["--threads", threads, "--quiet", "--resume", "--out", &out]);
        let mut killed = 0;
        let mut rows_before = 0;
        let mut completed = false;
        for _ in 0..kills {
            // Early enough in what is left that two of the runs are killed: each resumed
            // run has less to do, and two threads take about half the time of one.
            let per_thread = duration / threads.parse::<f64>().unwrap();
            let moment = Moment::After(per_thread * (0.2 + 0.25 * rng.unit()));
            let (status, _) = common::run_and_signal(&args, &dir.0, moment, "KILL");
            if status.success() {
                // A resumed run finished before its kill: the table is complete.
                completed = true;
                break;
            }
            killed += 1;
            assert!(!Path::new(&out).exists(), "a killed run left {out}");
            // Whole rows of the members in order, more than the previous kill left.
            let partial = std::fs::read_dir(&dir.0)
                .unwrap()
                .map(|e| e.unwrap().path())
                .find(|p| {
                    p.file_name()
                        .unwrap()
                        .to_str()
                        .unwrap()
                        .starts_with(&format!(".resumed{threads}.csv.ecr-partial-"))
                })
                .expect("an unfinished file");
            let text = String::from_utf8(std::fs::read(&partial).unwrap()).unwrap();
            let rows = rows(&text).len().saturating_sub(1);
            assert!(rows >= rows_before, "{rows} rows after {rows_before}");
            rows_before = rows;
        }
        assert!(
            killed >= 2,
            "{threads} threads: only {killed} runs were killed"
        );
        assert!(
            rows_before > 0,
            "{threads} threads: the killed runs kept no row"
        );
        if !completed {
            let (code, stdout, err) = ecr(&args);
            assert_eq!(code, 0, "{err}");
            assert!(
                stdout.contains("rows kept from the unfinished run"),
                "{stdout}"
            );
        }
        assert_eq!(read(Path::new(&out)), table, "{threads} threads");
    }
    // Nothing is left beside the tables.
    let mut left: Vec<String> = std::fs::read_dir(&dir.0)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    left.sort();
    assert_eq!(left, ["one.csv", "resumed1.csv", "resumed2.csv"]);
}

/// `--summary` writes per output column the count, mean, variance, extremes and quantiles
/// over the verified members (memory independent of the members), the same with 1 and 2
/// threads; progress lines appear on a non-terminal stderr, and not with --quiet.
#[test]
fn a_summary_and_progress_lines() {
    let dir = TempDir::new("ensemble-summary");
    std::fs::create_dir_all(&dir.0).unwrap();
    let out = path(&dir, "summary.csv");
    let table = path(&dir, "table.csv");
    let mut summaries = Vec::new();
    for threads in ["1", "2"] {
        let out = path(&dir, &format!("summary{threads}.csv"));
        let output = std::process::Command::new(env!("CARGO_BIN_EXE_ecr"))
            .args(GRID)
            .args([
                "--summary",
                "--quantiles",
                "0,0.5,1",
                "--threads",
                threads,
                "--out",
                &out,
            ])
            .env("ECR_PROGRESS_SECONDS", "0")
            .output()
            .unwrap();
        let (stdout, stderr) = (
            String::from_utf8_lossy(&output.stdout),
            String::from_utf8_lossy(&output.stderr),
        );
        assert_eq!(output.status.code(), Some(3), "{stdout}{stderr}");
        assert!(
            stdout.contains("summary of 20 members: 16 verified"),
            "{stdout}"
        );
        assert!(
            stderr.contains("ecr ensemble: 20 of 20 members (100.0 %)"),
            "{stderr}"
        );
        summaries.push(read(Path::new(&out)));
    }
    assert_eq!(summaries[0], summaries[1]);
    let lines: Vec<&str> = summaries[0].lines().collect();
    assert_eq!(
        lines[0],
        "output,count,non_finite,mean,variance,min,max,q0.0,q0.5,q1.0"
    );
    // The q1_end row against the table's column: count, min = q0, max = q1.
    let (code, _, _) = run(&["--quiet", "--out", &table]);
    assert_eq!(code, 3);
    let rows = read(Path::new(&table));
    let q1: Vec<f64> = rows
        .lines()
        .skip(1)
        .filter(|l| l.contains(",verified,"))
        .map(|l| l.split(',').nth(5).unwrap().parse().unwrap())
        .collect();
    let row: Vec<&str> = lines
        .iter()
        .find(|l| l.starts_with("q1_end,"))
        .unwrap()
        .split(',')
        .collect();
    assert_eq!(row[1], "16");
    let min = q1.iter().copied().fold(f64::INFINITY, f64::min);
    let max = q1.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    assert_eq!(row[5].parse::<f64>().unwrap(), min);
    assert_eq!(row[6].parse::<f64>().unwrap(), max);
    assert_eq!(row[7].parse::<f64>().unwrap(), min);
    assert_eq!(row[9].parse::<f64>().unwrap(), max);
    let mean = q1.iter().sum::<f64>() / q1.len() as f64;
    assert!((row[3].parse::<f64>().unwrap() - mean).abs() <= 1e-13 * mean.abs().max(1.0));
    // --quiet: no progress lines.
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_ecr"))
        .args(GRID)
        .args(["--quiet", "--out", &out])
        .env("ECR_PROGRESS_SECONDS", "0")
        .output()
        .unwrap();
    assert!(
        output.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
}

/// The unfinished file of `out` in `dir`, if there is one.
fn unfinished(dir: &Path, out: &str) -> Option<std::path::PathBuf> {
    let prefix = format!(".{out}.ecr-partial-");
    std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .find(|e| e.file_name().to_str().unwrap().starts_with(&prefix))
        .map(|e| e.path())
}

/// Issue 57, item 1: `--resume` of another command (another --tol, --t-end, grid) is refused
/// in one line naming the field of the fingerprint that differs, and leaves the unfinished
/// table as it was.
#[test]
fn a_resume_of_another_command_is_refused_naming_the_field() {
    let dir = TempDir::new("ensemble-other-run");
    std::fs::create_dir_all(&dir.0).unwrap();
    let out = path(&dir, "r.csv");
    let command = |tol: &'static str, t_end: &'static str, grid: &'static str| {
        let mut args = vec![
            "ensemble",
            "--problem",
            "henon-heiles",
            "--vary",
            grid,
            "--energy",
            "0.125",
            "--tol",
            tol,
            "--t-end",
            t_end,
            "--threads",
            "1",
            "--quiet",
            "--resume",
            "--out",
        ];
        args.push(Box::leak(out.clone().into_boxed_str()));
        args
    };
    // A long run killed once its unfinished table holds a few rows.
    let long = command("1e-8", "400", "q2=-0.3:0.3:900");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_ecr"))
        .args(&long)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    let stage = loop {
        assert!(
            start.elapsed().as_secs() < 120,
            "no rows in the unfinished table"
        );
        assert!(child.try_wait().unwrap().is_none(), "the run finished");
        if let Some(p) = unfinished(&dir.0, "r.csv") {
            let text = std::fs::read_to_string(&p).unwrap_or_default();
            if rows(&text).len() >= 3 {
                break p;
            }
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    };
    child.kill().unwrap();
    child.wait().unwrap();
    let before = std::fs::read(&stage).unwrap();
    for (args, field) in [
        (command("1e-7", "400", "q2=-0.3:0.3:900"), "rtol"),
        (command("1e-8", "401", "q2=-0.3:0.3:900"), "t_eval"),
        (command("1e-8", "400", "q2=-0.3:0.3:901"), "members"),
        (command("1e-8", "400", "q2=-0.3:0.4:900"), "inputs"),
    ] {
        assert_refused(ecr(&args), &format!("is of another run ({field}: "));
        assert_eq!(std::fs::read(&stage).unwrap(), before, "{field}");
        assert!(!Path::new(&out).exists(), "{field}");
    }
}

/// Issue 57, item 3: `ecr ensemble merge` never writes its table over one of its parts.
#[test]
fn a_merge_onto_one_of_its_parts_is_refused() {
    let dir = TempDir::new("ensemble-merge-onto");
    std::fs::create_dir_all(&dir.0).unwrap();
    let parts: Vec<String> = (1..=2)
        .map(|k| path(&dir, &format!("part{k}.csv")))
        .collect();
    for (k, part) in parts.iter().enumerate() {
        let shard = format!("{}/2", k + 1);
        assert!([0, 3].contains(&run(&["--shard", &shard, "--out", part]).0));
    }
    let before = read(Path::new(&parts[0]));
    let other_spelling = format!("{}/./part1.csv", dir.0.display());
    for out in [&parts[0], &parts[1], &other_spelling] {
        assert_refused(
            ecr(&["ensemble", "merge", "--out", out, &parts[0], &parts[1]]),
            "would replace its part",
        );
        assert_eq!(read(Path::new(&parts[0])), before);
    }
    let merged = path(&dir, "merged.csv");
    let (code, _, err) = ecr(&["ensemble", "merge", "--out", &merged, &parts[0], &parts[1]]);
    assert_eq!(code, 0, "{err}");
}

/// Issue 57, item 6: a negative or non-finite value of a numeric option reaches its rule
/// (not clap's "unexpected argument '-1' found"), named and in the same words for `run` and
/// `ensemble`; an unknown option gets no tip about another one.
#[test]
fn numeric_options_are_refused_by_name_with_their_rule_in_both_commands() {
    let dir = TempDir::new("ensemble-numbers");
    std::fs::create_dir_all(&dir.0).unwrap();
    let out = path(&dir, "a.csv");
    let ensemble = |option: &'static str, value: &'static str| {
        let mut args = vec![
            "ensemble",
            "--problem",
            "henon-heiles",
            "--vary",
            "q2=0:0.1:2",
            "--tol",
            "1e-6",
            "--t-end",
            "1",
            "--out",
            Box::leak(out.clone().into_boxed_str()),
        ];
        match args.iter().position(|a| *a == option) {
            Some(i) => args[i + 1] = value,
            None => args.extend([option, value]),
        }
        if option == "--h" {
            args.retain(|a| *a != "--tol" && *a != "1e-6");
            args.extend(["--r", "2"]);
        }
        ecr(&args)
    };
    let run = |option: &'static str, value: &'static str| {
        let mut args = vec![
            "run",
            "--problem",
            "duffing",
            "--tol",
            "1e-6",
            "--t-end",
            "1",
        ];
        match args.iter().position(|a| *a == option) {
            Some(i) => args[i + 1] = value,
            None => args.extend([option, value]),
        }
        if option == "--h" {
            args.retain(|a| *a != "--tol" && *a != "1e-6");
            args.extend(["--r", "2"]);
        }
        ecr(&args)
    };
    let rules = [
        ("--tol", "-1e-8", "must be finite and > 0"),
        ("--tol", "nan", "must be finite and > 0"),
        ("--tol", "inf", "must be finite and > 0"),
        ("--tol", "0", "must be finite and > 0"),
        ("--h", "-1e-3", "must be finite and > 0"),
        ("--t-end", "-5e-1", "must be finite and >= 0"),
        ("--t-end", "NaN", "must be finite and >= 0"),
        ("--r", "-2", "must be a whole number from 1"),
    ];
    for (option, value, rule) in rules {
        let named = format!("invalid value '{value}' for '{option} <");
        let (e, r) = (ensemble(option, value), run(option, value));
        for result in [e, r] {
            assert_refused(result.clone(), &named);
            assert_refused(result, rule);
        }
    }
    assert_refused(
        ensemble("--energy", "-inf"),
        "'--energy <ENERGY>': must be finite",
    );
    assert_refused(
        ensemble("--quantiles", "-0.5"),
        "'-0.5' is not a quantile in [0, 1]",
    );
    assert_refused(
        run("--omega", "-5e-1"),
        "'--omega <OMEGA>': must be finite and >= 0",
    );
    assert_refused(run("--stage-tol", "-1e-20"), "must be finite and >= 0");
    for result in [ensemble("--frobnicate", "1"), run("--frobnicate", "1")] {
        assert_refused(result.clone(), "unexpected argument '--frobnicate' found");
        assert!(
            !result.2.contains("tip") && !result.2.contains("similar"),
            "{result:?}"
        );
    }
}
