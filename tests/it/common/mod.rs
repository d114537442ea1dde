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

/// The name of the file by which ecr marks the output directories it writes.
pub const MARKER: &str = ".ecr-output";

/// Whether the tests run as root (who can `chattr +i` and mount, and whom `chmod` does not stop).
pub fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
}

/// Makes `dir` refuse new entries and renames inside it: `chattr +i` as root (whom permissions
/// do not stop), `chmod 555` otherwise. Returns false if that failed (the test then skips).
pub fn make_unwritable(dir: &std::path::Path) -> bool {
    if is_root() {
        Command::new("chattr")
            .arg("+i")
            .arg(dir)
            .status()
            .is_ok_and(|s| s.success())
    } else {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o555)).is_ok()
    }
}

/// Undoes [`make_unwritable`].
pub fn make_writable(dir: &std::path::Path) {
    if is_root() {
        let _ = Command::new("chattr").arg("-i").arg(dir).status();
    }
    use std::os::unix::fs::PermissionsExt;
    let _ = std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o755));
}

/// Fills `dir` (created afresh) with stand-ins for a previous run's files, whose contents are
/// "previous run", and ecr's marker: what a previous ecr run left. Returns its contents.
pub fn previous_output(dir: &std::path::Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    let _ = std::fs::remove_dir_all(dir);
    std::fs::create_dir_all(dir).unwrap();
    for name in ["report.md", "summary.md", "stale.csv", MARKER] {
        std::fs::write(dir.join(name), b"previous run").unwrap();
    }
    dir_contents(dir).unwrap()
}

/// A small deterministic generator (xorshift64*) for the kill moments.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed.max(1))
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// What the kills of [`kill_at_random_moments`] left in `--out`.
#[derive(Debug, Default)]
pub struct Tally {
    /// Runs killed (signalled before they finished).
    pub kills: usize,
    /// The previous run's files, exactly.
    pub old: usize,
    /// The complete files of a new run (killed after its commit).
    pub new: usize,
    /// Runs that finished before the signal (their output checked like `new`; not counted
    /// as kills: the campaign runs until it has made `kills` kills).
    pub finished: usize,
    /// The time one complete run took, seconds.
    pub run_seconds: f64,
}

/// When [`run_and_signal`] signals the run: seconds after its start, or seconds after its
/// staging directory holds `entries` entries (the last files, the marker and the commit
/// follow).
pub enum Moment {
    After(f64),
    Staged { entries: usize, after: f64 },
}

/// The number of entries of the fullest staging directory beside `dir`.
fn staged_entries(dir: &std::path::Path) -> usize {
    let prefix = format!(".{}.ecr-new-", dir.file_name().unwrap().to_str().unwrap());
    let Ok(list) = std::fs::read_dir(dir.parent().unwrap()) else {
        return 0;
    };
    list.flatten()
        .filter(|e| {
            e.file_name()
                .to_str()
                .is_some_and(|n| n.starts_with(&prefix))
        })
        .map(|e| std::fs::read_dir(e.path()).map_or(0, |d| d.count()))
        .max()
        .unwrap_or(0)
}

/// Runs `ecr ARGS` (which write into `dir`), sends it `signal` (KILL, INT, TERM) at `moment`
/// unless it has finished by then, and waits for it. Returns its status and, for
/// [`Moment::Staged`], when the staging directory was seen holding the entries.
pub fn run_and_signal(
    args: &[&str],
    dir: &std::path::Path,
    moment: Moment,
    signal: &str,
) -> (std::process::ExitStatus, Option<std::time::Instant>) {
    use std::time::{Duration, Instant};
    let mut child = Command::new(env!("CARGO_BIN_EXE_ecr"))
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("run ecr");
    let start = Instant::now();
    let mut deadline = match moment {
        Moment::After(t) => start + Duration::from_secs_f64(t),
        Moment::Staged { .. } => start + Duration::from_secs(600),
    };
    let mut seen = None;
    loop {
        if let Some(status) = child.try_wait().expect("poll ecr") {
            return (status, seen); // finished before the signal
        }
        let now = Instant::now();
        if now >= deadline {
            break;
        }
        match moment {
            Moment::Staged { entries, after } if seen.is_none() => {
                if staged_entries(dir) >= entries {
                    seen = Some(now);
                    deadline = now + Duration::from_secs_f64(after);
                }
            }
            _ => std::thread::sleep((deadline - now).min(Duration::from_millis(1))),
        }
    }
    let number = match signal {
        "INT" => libc::SIGINT,
        "TERM" => libc::SIGTERM,
        _ => libc::SIGKILL,
    };
    // SAFETY: kill(2) on our child, not reaped yet (a zombie at worst: the signal is lost).
    unsafe { libc::kill(child.id() as libc::pid_t, number) };
    (child.wait().expect("wait for ecr"), seen)
}

/// Kills `ecr ARGS --out DIR` `kills` times at random moments (seed `seed`), each time into a
/// directory holding a previous run's files ([`previous_output`]). The moments rotate between
/// uniform over the run's duration, the last fifth of it (where the files are written and put
/// in place), and the moments after the third-to-last file appeared in the staging directory
/// (the last files, the marker and the commit follow), up to the shortest time seen from there
/// to the end of a run; the duration is the shortest run seen (a first, complete run, then
/// those that finished before their signal, which are not counted as kills). The signal
/// is SIGKILL, or SIGINT or SIGTERM one time in four each. After each run DIR must hold
/// exactly the previous files or the complete new ones (the names of the complete run's
/// files, none with the old contents, none empty). Finally a complete run must leave nothing
/// beside DIR.
pub fn kill_at_random_moments(args: &[&str], kills: usize, seed: u64) -> Tally {
    use std::collections::BTreeSet;
    let root = TempDir::new("killed");
    let dir = root.0.join("out");
    let mut full: Vec<&str> = args.to_vec();
    full.extend_from_slice(&["--out", dir.to_str().unwrap()]);
    let start = std::time::Instant::now();
    let (code, _, err) = ecr(&full);
    let run_seconds = start.elapsed().as_secs_f64();
    assert_eq!(code, 0, "{args:?}: {err}");
    let complete: BTreeSet<String> = dir_contents(&dir).unwrap().into_keys().collect();
    assert!(
        complete.contains(MARKER),
        "{args:?}: no {MARKER} in {complete:?}"
    );
    let is_new = |now: &std::collections::BTreeMap<String, Vec<u8>>| {
        now.keys().cloned().collect::<BTreeSet<_>>() == complete
            && now.values().all(|v| v != b"previous run" && !v.is_empty())
    };
    let mut rng = Rng::new(seed);
    let mut tally = Tally {
        run_seconds,
        ..Tally::default()
    };
    // The shortest run seen so far: runs vary in length with the machine's load, and a
    // moment past the end is no kill.
    let mut shortest = run_seconds;
    // The shortest time seen from the third-to-last staged file to the end of a run.
    let mut tail: f64 = 0.05;
    let mut attempt = 0;
    while tally.kills < kills {
        attempt += 1;
        assert!(
            attempt <= 4 * kills,
            "{args:?}: too many runs finished before the signal"
        );
        let old = previous_output(&dir);
        let (moment, when) = match attempt % 3 {
            1 => {
                let t = rng.unit() * shortest;
                (Moment::After(t), format!("at {t:.3} s"))
            }
            2 => {
                let t = shortest * (0.8 + 0.2 * rng.unit());
                (Moment::After(t), format!("at {t:.3} s"))
            }
            _ => {
                let t = rng.unit() * tail;
                let entries = complete.len() - 3;
                (
                    Moment::Staged { entries, after: t },
                    format!("{:.2} ms after {entries} files were staged", t * 1e3),
                )
            }
        };
        let signal = match (rng.unit() * 4.0) as u32 {
            0 => "INT",
            1 => "TERM",
            _ => "KILL",
        };
        let start = std::time::Instant::now();
        let (status, seen) = run_and_signal(&full, &dir, moment, signal);
        let seen_to_end = seen.map(|t| t.elapsed().as_secs_f64());
        let when = format!("{args:?}, {signal} {when} ({status})");
        let now = dir_contents(&dir).unwrap_or_else(|| panic!("{when}: no --out"));
        let outcome = if status.success() {
            assert!(is_new(&now), "{when}: finished, but holds {:?}", now.keys());
            shortest = shortest.min(start.elapsed().as_secs_f64());
            if let Some(t) = seen_to_end {
                tail = tail.min(t);
            }
            tally.finished += 1;
            "finished before the signal"
        } else if now == old {
            tally.kills += 1;
            tally.old += 1;
            "old"
        } else {
            assert!(
                is_new(&now),
                "{when}: neither old nor new: {:?}",
                now.keys()
            );
            tally.kills += 1;
            tally.new += 1;
            "new"
        };
        println!("{when}: {outcome}");
    }
    previous_output(&dir);
    let (code, _, err) = ecr(&full);
    assert_eq!(code, 0, "{err}");
    assert!(is_new(&dir_contents(&dir).unwrap()));
    let left: Vec<_> = std::fs::read_dir(&root.0)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .filter(|n| n != "out")
        .collect();
    assert!(left.is_empty(), "left beside --out: {left:?}");
    tally
}
