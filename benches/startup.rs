//! Whole-process start-up of `ecr run` for one step against an empty Rust program (issue 51):
//! both run in turn, `ROUNDS` times each, interleaved, and the fastest wall time of each is
//! reported (the minimum is the run the machine did not disturb).
//!
//! ```text
//! cargo build --release --bin ecr
//! echo 'fn main() {}' > /tmp/empty.rs && rustc -C opt-level=3 /tmp/empty.rs -o /tmp/empty
//! cargo bench --bench startup -- /tmp/empty target/release/ecr
//! ```
//!
//! The `ecr` command timed: `ecr run --problem duffing --t-end 0.1 --r 3 --h 0.1` (EC3P, one
//! step of h = 0.1 on Duffing with its default ω = 5, a 2 × 2 operator), output to
//! /dev/null. Give the statically linked executable of docs/cli.md as ECR_BINARY to time that.

use std::process::{Command, Stdio};
use std::time::Instant;

const ROUNDS: usize = 50;

/// The wall time of one run of `program args`, which must succeed.
fn time(program: &str, args: &[&str]) -> f64 {
    let start = Instant::now();
    let status = Command::new(program)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .unwrap_or_else(|e| panic!("cannot run {program}: {e}"));
    let t = start.elapsed().as_secs_f64();
    assert!(status.success(), "{program} {args:?} failed: {status}");
    t
}

fn main() {
    let paths: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
    let [empty, ecr] = paths.as_slice() else {
        eprintln!("usage: cargo bench --bench startup -- EMPTY_PROGRAM ECR_BINARY");
        std::process::exit(2);
    };
    let run = [
        "run",
        "--problem",
        "duffing",
        "--t-end",
        "0.1",
        "--r",
        "3",
        "--h",
        "0.1",
    ];
    let (mut best_empty, mut best_ecr) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..ROUNDS {
        best_empty = best_empty.min(time(empty, &[]));
        best_ecr = best_ecr.min(time(ecr, &run));
    }
    println!(
        "empty program {:.3} ms, ecr run (one step) {:.3} ms: {:.2}× (fastest of {ROUNDS}, interleaved)",
        best_empty * 1e3,
        best_ecr * 1e3,
        best_ecr / best_empty
    );
}
