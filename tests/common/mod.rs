//! Shared helpers of the CLI integration tests: run the `ecr` binary, temporary directories.
#![allow(dead_code)]

use std::path::PathBuf;
use std::process::Command;

/// Runs the `ecr` binary with `args`: (exit status, stdout, stderr).
pub fn ecr(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_ecr"))
        .args(args)
        .output()
        .expect("run ecr");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8(out.stdout).unwrap(),
        String::from_utf8(out.stderr).unwrap(),
    )
}

/// A fresh directory under the system temp dir (not created), removed on drop.
pub struct TempDir(pub PathBuf);

impl TempDir {
    pub fn new(tag: &str) -> Self {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos());
        TempDir(std::env::temp_dir().join(format!("ecr-{tag}-{}-{nanos}", std::process::id())))
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Runs the `ecr` binary with `args` under `ulimit -v kib` (address space, KiB): (exit status,
/// stdout, stderr); status -1 if it died by a signal (e.g. an abort on a failed allocation).
pub fn ecr_with_address_space(kib: u64, args: &[&str]) -> (i32, String, String) {
    let out = Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -v {kib} && exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_ecr"))
        .args(args)
        .output()
        .expect("run sh");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8(out.stdout).unwrap(),
        String::from_utf8(out.stderr).unwrap(),
    )
}
