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
/// `after` unless it has finished by then, and waits for it. Returns the exit status.
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
    let deadline = std::time::Instant::now() + after;
    while std::time::Instant::now() < deadline {
        if let Some(status) = child.try_wait().expect("poll ecr") {
            return status; // finished before the signal
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    // Fails harmlessly if the child has exited since the last poll (not reaped yet).
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

/// Kills `ecr ARGS --out DIR` (SIGKILL and SIGINT) at the given moments (seconds), each time
/// into a directory holding a previous run's files (stand-ins whose contents are "previous
/// run"), then lets one run complete the same way. Checks that DIR was each time either
/// exactly as it was or complete (the names of the completed run's files, none of the old
/// contents), and that no staging directory stays beside it once a run completes.
pub fn check_interrupted_runs_leave_old_or_complete(args: &[&str], moments: &[(f64, &str)]) {
    use std::collections::{BTreeMap, BTreeSet};
    let root = TempDir::new("killed");
    let dir = root.0.join("out");
    let old: BTreeMap<String, Vec<u8>> = ["report.md", "summary.md", "stale.csv"]
        .iter()
        .map(|n| (n.to_string(), b"previous run".to_vec()))
        .collect();
    let mut full: Vec<&str> = args.to_vec();
    full.extend_from_slice(&["--out", dir.to_str().unwrap()]);
    let reset = || {
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        for (name, bytes) in &old {
            std::fs::write(dir.join(name), bytes).unwrap();
        }
    };
    let mut seen = Vec::new();
    for &(seconds, signal) in moments {
        reset();
        let status = ecr_interrupted(&full, std::time::Duration::from_secs_f64(seconds), signal);
        let now = dir_contents(&dir);
        seen.push((format!("{signal} at {seconds} s ({status})"), now));
    }
    reset();
    let (code, _, err) = ecr(&full);
    assert_eq!(code, 0, "{err}");
    let done = dir_contents(&dir).unwrap();
    assert!(
        done.values().all(|v| v != b"previous run"),
        "an old file survived"
    );
    let complete: BTreeSet<&String> = done.keys().collect();
    for (when, now) in seen {
        let now = now.unwrap_or_else(|| panic!("{when}: no --out"));
        if now != old {
            assert_eq!(
                now.keys().collect::<BTreeSet<_>>(),
                complete,
                "{when}: mixed files"
            );
            assert!(
                now.values().all(|v| v != b"previous run"),
                "{when}: an old file survived"
            );
        }
    }
    let left: Vec<_> = std::fs::read_dir(&root.0)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .filter(|n| n != "out")
        .collect();
    assert!(left.is_empty(), "left beside --out: {left:?}");
}
