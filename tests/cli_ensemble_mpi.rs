//! `mpirun -n 2` and `-n 3 ecr ensemble …` (an ecr built with the `mpi` feature) write the
//! table of the single-process run byte for byte: the members split
//! over the ranks and gathered in member order on rank 0.
//!
//! Needs `mpirun` (Open MPI or MPICH). Where it is missing the test says so and passes, except
//! under CI (`CI` set), where it fails: CI installs MPI and must run this test for real. Run
//! it with `cargo test -p ecr --features mpi --test cli_ensemble_mpi`.

#[path = "it/common/mod.rs"]
mod common;

use common::{TempDir, ecr, is_root};
use std::process::Command;

const ENSEMBLE: &[&str] = &[
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
    "--threads",
    "1",
];

/// `mpirun --version`'s first line, if mpirun runs.
fn mpirun() -> Option<String> {
    let out = Command::new("mpirun").arg("--version").output().ok()?;
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    Some(text.lines().next().unwrap_or_default().to_string())
}

#[test]
fn mpi_ranks_write_the_table_of_one_process() {
    let Some(version) = mpirun() else {
        assert!(
            std::env::var_os("CI").is_none(),
            "mpirun is not installed: CI must install MPI (libopenmpi-dev, openmpi-bin) and \
             run this test"
        );
        eprintln!("SKIPPED: mpirun is not installed (apt-get install openmpi-bin libopenmpi-dev)");
        return;
    };
    let dir = TempDir::new("ensemble-mpi");
    std::fs::create_dir_all(&dir.0).unwrap();
    let single = dir.0.join("single.csv");
    let mut args = ENSEMBLE.to_vec();
    args.extend(["--out", single.to_str().unwrap()]);
    let (code, _, err) = ecr(&args);
    assert_eq!(code, 3, "{err}"); // four members fail (no real p1): status 3
    let table = std::fs::read_to_string(&single).unwrap();
    assert_eq!(table.lines().filter(|l| !l.starts_with('#')).count(), 21);
    let open_mpi = version.contains("Open MPI");
    for ranks in [2, 3] {
        let out = dir.0.join(format!("mpi{ranks}.csv"));
        let mut mpirun = Command::new("mpirun");
        mpirun.args(["-n", &ranks.to_string()]);
        if open_mpi {
            // More ranks than cores (2 here), and as root in containers.
            mpirun.arg("--oversubscribe");
            if is_root() {
                mpirun.arg("--allow-run-as-root");
            }
        }
        let run = mpirun
            .arg(env!("CARGO_BIN_EXE_ecr"))
            .args(ENSEMBLE)
            .args(["--out", out.to_str().unwrap()])
            .output()
            .expect("run mpirun");
        let stdout = String::from_utf8_lossy(&run.stdout);
        // Rank 0 says that four members failed with status 3, which mpirun passes on.
        assert_eq!(
            run.status.code(),
            Some(3),
            "mpirun -n {ranks}: {}\n{stdout}\n{}",
            run.status,
            String::from_utf8_lossy(&run.stderr)
        );
        assert!(
            stdout.contains(&format!("20 members on {ranks} MPI ranks")),
            "{ranks} ranks: {stdout}"
        );
        let gathered = std::fs::read_to_string(&out).unwrap();
        assert_eq!(gathered, table, "{ranks} ranks");
    }
}

#[path = "../examples/forced_sweep.rs"]
#[allow(dead_code)]
mod forced_sweep;

/// `mpirun -n N` with the arguments for the launcher (`--oversubscribe` and, as root,
/// `--allow-run-as-root` for Open MPI), or `None` without mpirun (which fails under CI).
fn mpirun_command(ranks: usize) -> Option<Command> {
    let Some(version) = mpirun() else {
        assert!(
            std::env::var_os("CI").is_none(),
            "mpirun is not installed: CI must install MPI and run this test"
        );
        eprintln!("SKIPPED: mpirun is not installed (apt-get install openmpi-bin libopenmpi-dev)");
        return None;
    };
    let mut mpirun = Command::new("mpirun");
    mpirun.args(["-n", &ranks.to_string()]);
    if version.contains("Open MPI") {
        mpirun.arg("--oversubscribe");
        if is_root() {
            mpirun.arg("--allow-run-as-root");
        }
        mpirun.args(["-x", "ECR_EXAMPLE_ARGS"]);
    }
    Some(mpirun)
}

/// A rank of the example's MPI run: does something only when launched by
/// `the_example_runs_over_mpi_ranks` (which sets `ECR_EXAMPLE_ARGS`).
#[test]
fn example_rank() {
    let Ok(args) = std::env::var("ECR_EXAMPLE_ARGS") else {
        return;
    };
    let args: Vec<String> = args.split(' ').map(str::to_string).collect();
    let line = forced_sweep::run(&args).unwrap_or_else(|e| panic!("{args:?}: {e}"));
    if !line.is_empty() {
        println!("{line}");
    }
}

/// The example (a user's own model through `ecr::mpi::write_table`) under `mpirun -n 2` and
/// `-n 3` writes the table of one process, byte for byte.
#[test]
fn the_example_runs_over_mpi_ranks() {
    let dir = TempDir::new("example-mpi");
    std::fs::create_dir_all(&dir.0).unwrap();
    let single = dir.0.join("single.csv");
    let base = "--members 10 --periods 25";
    let args: Vec<String> = format!("{base} {}", single.display())
        .split(' ')
        .map(str::to_string)
        .collect();
    let line = forced_sweep::run(&args).unwrap();
    // "…, N verified (0 kept)": the ranks verify the same members.
    let verified = line
        .split(", ")
        .nth(1)
        .and_then(|v| v.strip_suffix(" verified (0 kept)"))
        .unwrap_or_else(|| panic!("{line}"))
        .to_string();
    let table = std::fs::read_to_string(&single).unwrap();
    assert_eq!(table.lines().filter(|l| !l.starts_with('#')).count(), 11);
    for ranks in [2, 3] {
        let Some(mut mpirun) = mpirun_command(ranks) else {
            return;
        };
        let out = dir.0.join(format!("mpi{ranks}.csv"));
        let run = mpirun
            .env("ECR_EXAMPLE_ARGS", format!("{base} {}", out.display()))
            .arg(std::env::current_exe().unwrap())
            .args([
                "example_rank",
                "--exact",
                "--nocapture",
                "--test-threads",
                "1",
            ])
            .output()
            .expect("run mpirun");
        let stdout = String::from_utf8_lossy(&run.stdout);
        assert!(
            run.status.success(),
            "mpirun -n {ranks}: {}\n{stdout}\n{}",
            run.status,
            String::from_utf8_lossy(&run.stderr)
        );
        assert!(
            stdout.contains(&format!(
                "10 members on {ranks} MPI ranks, {verified} verified"
            )),
            "{stdout}"
        );
        let gathered = std::fs::read_to_string(&out).unwrap();
        assert_eq!(gathered, table, "{ranks} ranks");
    }
}

/// The process of rank 0 among the children of `parent` (Open MPI's `mpirun` starts the
/// ranks of one machine as its children), from their `OMPI_COMM_WORLD_RANK`.
fn rank_zero(parent: u32) -> Option<u32> {
    let tasks = std::fs::read_dir(format!("/proc/{parent}/task")).ok()?;
    let children: Vec<u32> = tasks
        .flatten()
        .filter_map(|t| std::fs::read_to_string(t.path().join("children")).ok())
        .flat_map(|c| {
            c.split_whitespace()
                .filter_map(|p| p.parse().ok())
                .collect::<Vec<u32>>()
        })
        .collect();
    children.into_iter().find(|pid| {
        std::fs::read(format!("/proc/{pid}/environ")).is_ok_and(|env| {
            env.split(|&b| b == 0)
                .any(|v| v == b"OMPI_COMM_WORLD_RANK=0")
        })
    })
}

/// Member rows (the header not counted) in the unfinished file of `out`
/// (`.NAME.ecr-partial-<hash>` beside it), if there is one.
fn partial_rows(out: &std::path::Path) -> Option<usize> {
    let name = format!(".{}.ecr-partial-", out.file_name()?.to_str()?);
    let entry = std::fs::read_dir(out.parent()?)
        .ok()?
        .flatten()
        .find(|e| e.file_name().to_str().is_some_and(|n| n.starts_with(&name)))?;
    let text = std::fs::read(entry.path()).ok()?;
    Some(
        text.split(|&b| b == b'\n')
            .filter(|l| !l.is_empty() && !l.starts_with(b"#"))
            .count()
            .saturating_sub(1),
    )
}

/// `mpirun -n 2 ecr ensemble … --resume` with rank 0 killed by SIGKILL as soon as the launch has
/// added rows to the unfinished table (so that neither a slow nor a fast machine lets a launch
/// finish before its kill), three times, then resumed on 3 ranks: the table of one process, byte
/// for byte. A killed launch leaves no table, or (killed after its last rename) the whole table.
#[test]
fn mpi_runs_killed_and_resumed_write_the_table_of_one_process() {
    if mpirun().is_none_or(|v| !v.contains("Open MPI")) {
        eprintln!("SKIPPED: needs Open MPI's mpirun (its ranks are its children)");
        assert!(std::env::var_os("CI").is_none(), "CI installs Open MPI");
        return;
    }
    let dir = TempDir::new("ensemble-mpi-resume");
    std::fs::create_dir_all(&dir.0).unwrap();
    let grid = [
        "ensemble",
        "--problem",
        "henon-heiles",
        "--vary",
        "q2=-0.3:0.3:25",
        "--vary",
        "p2=-0.3:0.3:24",
        "--energy",
        "0.125",
        "--tol",
        "1e-8",
        "--t-end",
        "40",
        "--threads",
        "1",
        "--quiet",
    ];
    let single = dir.0.join("single.csv");
    let mut args = grid.to_vec();
    args.extend(["--out", single.to_str().unwrap()]);
    let (code, _, err) = ecr(&args);
    assert_eq!(code, 0, "{err}");
    let table = std::fs::read_to_string(&single).unwrap();
    let out = dir.0.join("mpi.csv");
    let mut killed = 0;
    // A launch that finishes before its kill (little left to do) leaves the whole table, which
    // is removed: the next starts over. Up to eight launches for three kills.
    for _ in 0..8 {
        if killed == 3 {
            break;
        }
        let before = partial_rows(&out).unwrap_or(0);
        let mut mpirun = mpirun_command(2).unwrap();
        let mut child = mpirun
            .arg(env!("CARGO_BIN_EXE_ecr"))
            .args(grid)
            .args(["--resume", "--out", out.to_str().unwrap()])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("run mpirun");
        let mut victim = None;
        let mut this = false;
        while child.try_wait().unwrap().is_none() {
            victim = victim.or_else(|| rank_zero(child.id()));
            let grown = partial_rows(&out).is_some_and(|rows| rows > before);
            if let (Some(pid), true) = (victim, grown) {
                // SAFETY: kill(2) of rank 0 of our mpirun.
                unsafe { libc::kill(pid as libc::pid_t, libc::SIGKILL) };
                this = true;
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        let status = child.wait().unwrap();
        if this && out.exists() {
            // The kill fell after the rename: the table must then be whole.
            assert_eq!(std::fs::read_to_string(&out).unwrap(), table);
            std::fs::remove_file(&out).unwrap();
        } else if this {
            killed += 1;
            assert!(
                !status.success(),
                "a launch whose rank 0 was killed succeeded"
            );
            assert!(
                partial_rows(&out).is_some_and(|rows| rows > before),
                "a killed launch lost rows it had written"
            );
        } else {
            assert!(status.success());
            assert_eq!(std::fs::read_to_string(&out).unwrap(), table);
            std::fs::remove_file(&out).unwrap();
        }
    }
    assert!(killed >= 2, "only {killed} launches were killed");
    let mut mpirun = mpirun_command(3).unwrap();
    let run = mpirun
        .arg(env!("CARGO_BIN_EXE_ecr"))
        .args(grid)
        .args(["--resume", "--out", out.to_str().unwrap()])
        .output()
        .expect("run mpirun");
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(stdout.contains("600 members on 3 MPI ranks"), "{stdout}");
    assert_eq!(std::fs::read_to_string(&out).unwrap(), table);
}
