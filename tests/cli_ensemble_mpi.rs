//! `mpirun -n 2` and `-n 3 ecr ensemble …` (an ecr built with the `mpi` feature) write the
//! table of the single-process run byte for byte, its CPU column aside: the members split
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

/// The table without its last column (the CPU seconds).
fn without_cpu(text: &str) -> String {
    text.lines()
        .map(|l| &l[..l.rfind(',').expect("a column")])
        .collect::<Vec<_>>()
        .join("\n")
}

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
    assert_eq!(code, 0, "{err}");
    let table = std::fs::read_to_string(&single).unwrap();
    assert_eq!(table.lines().count(), 21);
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
        assert!(
            run.status.success(),
            "mpirun -n {ranks}: {}\n{stdout}\n{}",
            run.status,
            String::from_utf8_lossy(&run.stderr)
        );
        assert!(
            stdout.contains(&format!("20 members on {ranks} MPI ranks")),
            "{ranks} ranks: {stdout}"
        );
        let gathered = std::fs::read_to_string(&out).unwrap();
        assert_eq!(without_cpu(&gathered), without_cpu(&table), "{ranks} ranks");
    }
}
