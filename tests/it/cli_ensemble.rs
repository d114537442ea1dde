//! `ecr ensemble`: the table of one run, the same with 1 and 2 threads and from shards joined
//! by `ecr ensemble merge` (byte for byte, the CPU column aside); failed members as rows;
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

/// The text without its last column (the CPU seconds) on the table's lines.
fn without_cpu(text: &str) -> String {
    text.lines()
        .map(|l| {
            if l.starts_with('#') {
                l
            } else {
                &l[..l.rfind(',').expect("a column")]
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap()
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
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("20 members"), "{out}");
    let table = read(Path::new(&one));
    let lines: Vec<&str> = table.lines().collect();
    assert_eq!(lines.len(), 21);
    assert_eq!(
        lines[0],
        "member,q2,p2,status,t,q1_end,q2_end,p1_end,p2_end,error_estimate,energy_error,\
         g_evals,message,cpu_seconds"
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
    assert_eq!(run(&["--threads", "2", "--out", &two]).0, 0);
    assert_eq!(without_cpu(&read(Path::new(&two))), without_cpu(&table));

    let parts: Vec<String> = (1..=3)
        .map(|k| path(&dir, &format!("part{k}.csv")))
        .collect();
    for (k, part) in parts.iter().enumerate() {
        let shard = format!("{}/3", k + 1);
        let (code, _, err) = run(&["--shard", &shard, "--out", part]);
        assert_eq!(code, 0, "{err}");
    }
    let part1 = read(Path::new(&parts[0]));
    assert!(
        part1.starts_with("# ecr ensemble part 1/3 of 20 members: "),
        "{part1}"
    );
    assert!(part1.ends_with("# end of part 1/3: 7 rows\n"), "{part1}");
    let merged = path(&dir, "merged.csv");
    let (code, out, err) = ecr(&[
        "ensemble", "merge", "--out", &merged, &parts[2], &parts[0], &parts[1],
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("20 members from 3 parts"), "{out}");
    assert_eq!(without_cpu(&read(Path::new(&merged))), without_cpu(&table));
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
        assert_eq!(run(&["--shard", &shard, "--out", part]).0, 0);
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
    assert_eq!(ecr(&args).0, 0);
    assert_refused(
        merge(&[&parts[0], &other, &parts[2]]),
        "parts of different ensembles",
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
    lines.remove(3);
    std::fs::write(&cut, lines.join("\n") + "\n").unwrap();
    assert_refused(
        merge(&[&parts[0], &cut, &parts[2]]),
        "was changed after its shard",
    );
    // Not a part at all: a whole table.
    let whole = path(&dir, "whole.csv");
    assert_eq!(run(&["--out", &whole]).0, 0);
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
        left.iter().all(|f| f.starts_with(".part2.csv.ecr-new-")),
        "{left:?}"
    );
    let (p1, p3) = (path(&dir, "part1.csv"), path(&dir, "part3.csv"));
    assert_eq!(run(&["--shard", "1/3", "--out", &p1]).0, 0);
    assert_eq!(run(&["--shard", "3/3", "--out", &p3]).0, 0);
    let merged = path(&dir, "merged.csv");
    assert_refused(
        ecr(&["ensemble", "merge", "--out", &merged, &p1, &p3]),
        "parts missing: 2",
    );
    // The next run with the same --out removes the staging file of the killed one.
    assert_eq!(run(&["--shard", "2/3", "--out", &part]).0, 0);
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
        "--out",
        &out,
    ]);
    assert_eq!(code, 0, "{err}");
    let table = read(Path::new(&out));
    let lines: Vec<&str> = table.lines().collect();
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
