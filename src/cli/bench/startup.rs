//! Process start-up, measured apart: every time of the work–precision part is measured inside
//! this process (set-up and integration), so what a command-line run pays before and after it
//! integrates — loading the executable, the standard library's start, parsing arguments,
//! writing its output — is in none of them. This runs this executable as a child: `ecr
//! --version` (start-up alone) and `ecr run` for one short step of Duffing (start-up, one
//! EC6P set-up and step, and its JSON report).

use std::process::{Command, Stdio};
use std::time::Instant;

/// The `ecr run` whose process time is measured: Duffing ω = 20, EC6P, one step of h = 0.1.
pub const ONE_STEP: [&str; 11] = [
    "run",
    "--problem",
    "duffing",
    "--omega",
    "20",
    "--r",
    "6",
    "--h",
    "0.1",
    "--t-end",
    "0.1",
];

/// What was measured (wall-clock seconds from spawning the child to its exit, the fastest of
/// `runs` interleaved runs of each).
pub struct Startup {
    pub runs: usize,
    /// `ecr --version`.
    pub version: f64,
    /// `ecr` with [`ONE_STEP`].
    pub one_step: f64,
}

/// Runs both commands `runs` times, interleaved.
///
/// # Errors
/// A message if this executable cannot be found or run, or a command fails.
pub fn measure(runs: usize) -> Result<Startup, String> {
    let exe = std::env::current_exe().map_err(|e| format!("cannot find this executable: {e}"))?;
    let time = |args: &[&str]| -> Result<f64, String> {
        let start = Instant::now();
        let status = Command::new(&exe)
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .map_err(|e| format!("cannot run {}: {e}", exe.display()))?;
        let seconds = start.elapsed().as_secs_f64();
        if !status.success() {
            return Err(format!("`ecr {}` failed: {status}", args.join(" ")));
        }
        Ok(seconds)
    };
    let (mut version, mut one_step) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..runs.max(1) {
        version = version.min(time(&["--version"])?);
        one_step = one_step.min(time(&ONE_STEP)?);
    }
    Ok(Startup {
        runs: runs.max(1),
        version,
        one_step,
    })
}
