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

/// Runs the `ecr` binary with `args`, sends it `signal` (a `kill -s` name: INT, KILL) after
/// `after`, and waits for it. Returns the exit status.
pub fn ecr_interrupted(
    args: &[&str],
    after: std::time::Duration,
    signal: &str,
) -> std::process::ExitStatus {
    let mut child = Command::new(env!("CARGO_BIN_EXE_ecr"))
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("run ecr");
    std::thread::sleep(after);
    // Fails harmlessly if the child has already exited (it is not reaped before the wait).
    let _ = Command::new("kill")
        .args(["-s", signal, &child.id().to_string()])
        .status();
    child.wait().expect("wait for ecr")
}

/// The files of `dir` (names and contents), or None if it does not exist.
pub fn dir_contents(dir: &std::path::Path) -> Option<std::collections::BTreeMap<String, Vec<u8>>> {
    let entries = std::fs::read_dir(dir).ok()?;
    Some(
        entries
            .map(|e| {
                let e = e.unwrap();
                let name = e.file_name().into_string().unwrap();
                (name, std::fs::read(e.path()).unwrap())
            })
            .collect(),
    )
}

/// Kills `ecr ARGS --out DIR` (SIGKILL and SIGINT) at several moments, each time into a
/// directory holding a previous run's files (stand-ins whose contents are "previous run"),
/// and checks that DIR is then either exactly as it was or complete: the names of
/// `complete` and none of the old contents. Finally, no staging directory stays beside it
/// once a run completes.
pub fn check_interrupted_runs_leave_old_or_complete(
    args: &[&str],
    complete: &std::collections::BTreeSet<String>,
    moments: &[(f64, &str)],
) {
    let root = TempDir::new("killed");
    let dir = root.0.join("out");
    let old: std::collections::BTreeMap<String, Vec<u8>> = ["report.md", "summary.md", "stale.csv"]
        .iter()
        .map(|n| (n.to_string(), b"previous run".to_vec()))
        .collect();
    let mut full: Vec<&str> = args.to_vec();
    full.extend_from_slice(&["--out", dir.to_str().unwrap()]);
    for &(seconds, signal) in moments {
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        for (name, bytes) in &old {
            std::fs::write(dir.join(name), bytes).unwrap();
        }
        let status = ecr_interrupted(&full, std::time::Duration::from_secs_f64(seconds), signal);
        let now = dir_contents(&dir).unwrap_or_else(|| panic!("{signal} at {seconds} s: no --out"));
        if now != old {
            let names: std::collections::BTreeSet<String> = now.keys().cloned().collect();
            assert_eq!(
                &names, complete,
                "{signal} at {seconds} s ({status}): mixed files"
            );
            assert!(
                now.values().all(|v| v != b"previous run"),
                "{signal} at {seconds} s: an old file survived"
            );
        }
    }
    let (code, _, err) = ecr(&full);
    assert_eq!(code, 0, "{err}");
    let left: Vec<_> = std::fs::read_dir(&root.0)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .filter(|n| n != "out")
        .collect();
    assert!(left.is_empty(), "left beside --out: {left:?}");
}
