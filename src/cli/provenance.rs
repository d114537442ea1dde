//! Where a measurement was made: the commit of the source and the machine, written beside
//! every benchmark figure so that a reader can tell which code and hardware a number is of.

use std::process::Command;

/// The commit (`git describe --always --dirty`) of the working directory, if it is a git
/// checkout and git is installed; `"unknown"` otherwise.
pub fn commit() -> String {
    Command::new("git")
        .args(["describe", "--always", "--dirty", "--abbrev=12"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "unknown".to_string())
}

/// The CPU model and the number of logical CPUs, e.g. `"AMD EPYC, 2 logical CPUs"`.
pub fn machine() -> String {
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    format!("{model}, {cpus} logical CPUs")
}

/// One Markdown line: "Commit X on MACHINE, release build: yes/no."
pub fn line() -> String {
    format!(
        "Measured at commit `{}` on {} ({} build).",
        commit(),
        machine(),
        if cfg!(debug_assertions) {
            "debug"
        } else {
            "release"
        }
    )
}
