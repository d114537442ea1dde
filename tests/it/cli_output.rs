//! Output directories of `reproduce` and `bench` (`--out`): a symlink stays a symlink, a
//! destination that cannot be replaced is refused before the work, a commit that still fails
//! keeps the new files and names where they are, a directory ecr did not write is refused
//! without `--force`, a fallback commit killed half-way is restored, and a staging directory
//! whose run holds its lock is left alone, whatever its name says.

use crate::common;

use common::{MARKER, TempDir, dir_contents, ecr, ecr_interrupted, previous_output};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The cheapest command that writes an output directory (about 0.1 s).
const QUICK: [&str; 4] = ["bench", "--quick", "--only", "scaling"];

fn quick_into(out: &Path, extra: &[&str]) -> (i32, String, String) {
    let mut args: Vec<&str> = QUICK.to_vec();
    args.extend_from_slice(&["--out", out.to_str().unwrap()]);
    args.extend_from_slice(extra);
    ecr(&args)
}

/// The files of a complete `bench --quick --only scaling`, none of them a previous run's.
fn assert_complete(dir: &Path) {
    let files = dir_contents(dir).unwrap_or_else(|| panic!("{} is missing", dir.display()));
    for name in ["scaling.csv", "summary.md", MARKER] {
        assert!(files.contains_key(name), "{}: no {name}", dir.display());
    }
    assert!(
        files.values().all(|v| v != b"previous run"),
        "{}: an old file survived: {:?}",
        dir.display(),
        files.keys()
    );
}

/// The entries of `dir` (sorted names).
fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    v.sort();
    v
}

/// Status 2, nothing on stdout, and on stderr one line besides the plain progress lines
/// (`progress: …`, printed when stderr is not a terminal and the work has started).
fn assert_one_line_error(code: i32, stdout: &str, stderr: &str) {
    assert_eq!(code, 2, "stdout: {stdout} stderr: {stderr}");
    assert!(stdout.is_empty(), "{stdout}");
    let lines: Vec<&str> = stderr
        .lines()
        .filter(|l| !l.starts_with("progress: "))
        .collect();
    assert_eq!(lines.len(), 1, "{stderr}");
    assert!(lines[0].starts_with("error: "), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// `--out` a symlink to a directory: the new files replace the target's, the link stays.
/// (It used to be replaced by a real directory, the target keeping the old files.)
#[test]
fn symlinked_out_stays_a_symlink() {
    let root = TempDir::new("out-symlink");
    let real = root.0.join("real");
    previous_output(&real);
    let link = root.0.join("link");
    std::os::unix::fs::symlink("real", &link).unwrap();
    let (code, stdout, stderr) = quick_into(&link, &[]);
    assert_eq!(code, 0, "{stderr}");
    assert!(stdout.contains("replacing its previous"), "{stdout}");
    let meta = std::fs::symlink_metadata(&link).unwrap();
    assert!(
        meta.file_type().is_symlink(),
        "--out is no longer a symlink"
    );
    assert_eq!(std::fs::read_link(&link).unwrap(), Path::new("real"));
    assert_complete(&real);
    assert_eq!(entries(&root.0), ["link", "real"]);
    // The same with a trailing slash (which made the commit fail, after the work).
    let (code, _, stderr) = quick_into(&root.0.join("link/"), &[]);
    assert_eq!(code, 0, "{stderr}");
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert_complete(&real);
    assert_eq!(entries(&root.0), ["link", "real"]);
}

/// A dangling symlink: the directory is created where it points, and the link stays. (The
/// run used to fail only after the work, naming a staging directory it had removed.) A link
/// into a directory that does not exist is refused before the work.
#[test]
fn dangling_symlink_out_is_created_at_its_target() {
    let root = TempDir::new("out-dangling");
    std::fs::create_dir_all(&root.0).unwrap();
    let link = root.0.join("link");
    std::os::unix::fs::symlink("target", &link).unwrap();
    let (code, _, stderr) = quick_into(&link, &[]);
    assert_eq!(code, 0, "{stderr}");
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert_complete(&root.0.join("target"));
    assert_eq!(entries(&root.0), ["link", "target"]);

    let deep = root.0.join("deep");
    std::os::unix::fs::symlink("missing-dir/target", &deep).unwrap();
    let (code, stdout, stderr) = quick_into(&deep, &[]);
    assert_one_line_error(code, &stdout, &stderr);
    assert!(stderr.contains("missing-dir"), "{stderr}");
    assert!(
        !stderr.contains(".ecr-"),
        "names a staging directory: {stderr}"
    );
    assert_eq!(entries(&root.0), ["deep", "link", "target"]);
}

/// A mount point cannot be renamed: refused before the work, in one line that says so. (The
/// run used to fail after the work: "Device or resource busy", naming a removed staging
/// directory.) Needs a mount namespace (root); skipped otherwise.
#[test]
fn mount_point_out_is_refused_before_the_work() {
    let root = TempDir::new("out-mount");
    let out = root.0.join("mnt");
    std::fs::create_dir_all(&out).unwrap();
    let script = "mount -t tmpfs ecr-test \"$1\" || exit 77; shift; exec \"$@\"";
    let run = Command::new("unshare")
        .args(["-m", "sh", "-c", script, "sh"])
        .arg(&out)
        .arg(env!("CARGO_BIN_EXE_ecr"))
        .args(QUICK)
        .arg("--out")
        .arg(&out)
        .stderr(Stdio::piped())
        .stdout(Stdio::piped())
        .output();
    let Ok(run) = run else {
        eprintln!("skipped: no unshare");
        return;
    };
    if run.status.code() == Some(77) || !run.status.success() && run.stderr.starts_with(b"unshare")
    {
        eprintln!("skipped: cannot mount here");
        return;
    }
    let (stdout, stderr) = (
        String::from_utf8(run.stdout).unwrap(),
        String::from_utf8(run.stderr).unwrap(),
    );
    assert_one_line_error(run.status.code().unwrap_or(-1), &stdout, &stderr);
    assert!(stderr.contains("mount point"), "{stderr}");
    assert!(
        !stderr.contains(".ecr-"),
        "names a staging directory: {stderr}"
    );
    assert_eq!(entries(&root.0), ["mnt"]);
}

/// An immutable `--out` (`chattr +i`) cannot be renamed: refused before the work, the old
/// files untouched. Needs root; skipped otherwise.
#[test]
fn immutable_out_is_refused_before_the_work() {
    let root = TempDir::new("out-immutable");
    let out = root.0.join("out");
    let old = previous_output(&out);
    if !common::is_root() || !common::make_unwritable(&out) {
        eprintln!("skipped: cannot chattr +i");
        return;
    }
    let (code, stdout, stderr) = quick_into(&out, &[]);
    common::make_writable(&out);
    assert_one_line_error(code, &stdout, &stderr);
    assert!(stderr.contains("immutable"), "{stderr}");
    assert!(
        !stderr.contains(".ecr-"),
        "names a staging directory: {stderr}"
    );
    assert_eq!(dir_contents(&out).unwrap(), old);
    assert_eq!(entries(&root.0), ["out"]);
}

/// When the commit fails all the same (here the parent turns read-only while the run
/// computes), the new files stay, complete, where the one-line error says; `--out` keeps the
/// previous run's files. (The message used to name a staging directory it had removed.)
#[test]
fn failed_commit_keeps_the_new_files_and_names_them() {
    let root = TempDir::new("out-commit-fails");
    let out = root.0.join("out");
    let old = previous_output(&out);
    let child = Command::new(env!("CARGO_BIN_EXE_ecr"))
        .args(["reproduce", "--quick", "--out"])
        .arg(&out)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Until the run writes its first file into the staging directory: then it is past the
    // checks of the parent (a staging directory alone can appear just before them, and a
    // parent turned read-only then is refused before any work, with nothing to keep).
    let deadline = Instant::now() + Duration::from_secs(20);
    while !entries(&root.0)
        .iter()
        .filter(|e| e.starts_with(".out.ecr-new-"))
        .any(|e| std::fs::read_dir(root.0.join(e)).is_ok_and(|mut d| d.next().is_some()))
    {
        assert!(Instant::now() < deadline, "no staged file appeared");
        std::thread::sleep(Duration::from_millis(1));
    }
    let pid = child.id().to_string();
    let signal = |s: &str| Command::new("kill").args(["-s", s, &pid]).status().unwrap();
    signal("STOP");
    let unwritable = common::make_unwritable(&root.0);
    signal("CONT");
    let run = child.wait_with_output().unwrap();
    common::make_writable(&root.0);
    if !unwritable {
        eprintln!("skipped: cannot make the parent read-only");
        return;
    }
    let (stdout, stderr) = (
        String::from_utf8(run.stdout).unwrap(),
        String::from_utf8(run.stderr).unwrap(),
    );
    assert_one_line_error(run.status.code().unwrap_or(-1), &stdout, &stderr);
    assert_eq!(dir_contents(&out).unwrap(), old, "--out changed");
    // The quoted paths of the message: one of them holds the new files.
    let kept = stderr
        .split('\'')
        .skip(1)
        .step_by(2)
        .map(Path::new)
        .find(|p| std::fs::read(p.join("report.md")).is_ok_and(|r| r != b"previous run"));
    let kept = kept.unwrap_or_else(|| panic!("no named directory holds the new files: {stderr}"));
    let files = dir_contents(kept).unwrap();
    assert!(
        files.contains_key(MARKER) && files.len() > 20,
        "{:?}",
        files.keys()
    );
}

/// A non-empty directory without ecr's marker is not replaced: one line naming --force, the
/// files untouched; with --force it is replaced. An empty directory is used as is. (Any
/// directory used to be replaced without asking.)
#[test]
fn foreign_directory_is_refused_without_force() {
    let root = TempDir::new("out-foreign");
    let out = root.0.join("out");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("thesis.tex"), b"years of work").unwrap();
    let before = dir_contents(&out).unwrap();
    let (code, stdout, stderr) = quick_into(&out, &[]);
    assert_one_line_error(code, &stdout, &stderr);
    assert!(stderr.contains("--force"), "{stderr}");
    assert_eq!(dir_contents(&out).unwrap(), before);
    assert_eq!(entries(&root.0), ["out"]);
    let (code, _, stderr) = ecr(&["reproduce", "--quick", "--out", out.to_str().unwrap()]);
    assert_eq!(code, 2, "{stderr}");
    assert_eq!(dir_contents(&out).unwrap(), before);

    let (code, _, stderr) = quick_into(&out, &["--force"]);
    assert_eq!(code, 0, "{stderr}");
    assert_complete(&out);
    assert!(!out.join("thesis.tex").exists());

    let empty = root.0.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let (code, _, stderr) = quick_into(&empty, &[]);
    assert_eq!(code, 0, "{stderr}");
    assert_complete(&empty);

    let (code, stdout, _) = ecr(&["reproduce", "--help"]);
    assert_eq!(code, 0);
    assert!(stdout.contains("--force"), "{stdout}");
}

/// The state a fallback commit (two renames, where the directories cannot be exchanged)
/// leaves when killed between them: no `--out`, the previous files complete in
/// `.out.ecr-old-*`, the new ones in `.out.ecr-new-*`. The next run restores the previous
/// files before anything else, so that killed at once it leaves them in place. (It used to
/// delete both directories: their process was gone.)
#[test]
fn fallback_commit_killed_half_way_is_restored() {
    let root = TempDir::new("out-fallback");
    let out = root.0.join("out");
    let old = previous_output(&root.0.join(".out.ecr-old-999999999"));
    let new = root.0.join(".out.ecr-new-999999999");
    std::fs::create_dir_all(&new).unwrap();
    std::fs::write(new.join("scaling.csv"), b"new").unwrap();
    let args = ["reproduce", "--quick", "--out", out.to_str().unwrap()];
    let status = ecr_interrupted(&args, Duration::from_millis(500), "KILL");
    assert!(!status.success());
    assert_eq!(
        dir_contents(&out),
        Some(old),
        "the previous files were not restored"
    );
    let (code, _, stderr) = quick_into(&out, &[]);
    assert_eq!(code, 0, "{stderr}");
    assert_complete(&out);
    assert_eq!(entries(&root.0), ["out"]);
}

/// A staging directory whose run holds its lock is live, whatever process id its name has (a
/// run in another PID namespace, a container sharing the directory): it is left alone; once
/// the lock is gone, the next run removes it. (Runs used to remove it when no process of
/// that id was visible.)
#[test]
fn locked_staging_directory_is_left_alone() {
    use std::os::unix::io::AsRawFd;
    let root = TempDir::new("out-locked");
    let out = root.0.join("out");
    let live = root.0.join(".out.ecr-new-999999999");
    std::fs::create_dir_all(&live).unwrap();
    std::fs::write(live.join("scaling.csv"), b"being written").unwrap();
    let handle = std::fs::File::open(&live).unwrap();
    // SAFETY: a valid open descriptor.
    assert_eq!(unsafe { libc::flock(handle.as_raw_fd(), libc::LOCK_EX) }, 0);
    let (code, _, stderr) = quick_into(&out, &[]);
    assert_eq!(code, 0, "{stderr}");
    assert!(
        live.join("scaling.csv").is_file(),
        "a live staging directory was removed"
    );
    drop(handle);
    let (code, _, stderr) = quick_into(&out, &[]);
    assert_eq!(code, 0, "{stderr}");
    assert_eq!(entries(&root.0), ["out"]);
}

/// A legal `--out` name of 250 bytes is written and replaced: the names beside it (staging,
/// `-old-`) fit in the 255 bytes a file name may have. (The staging name used to carry the
/// whole name and failed with "File name too long" before the work.)
#[test]
fn out_with_a_250_byte_name_is_written_and_replaced() {
    let root = TempDir::new("long-out");
    std::fs::create_dir_all(&root.0).unwrap();
    let out = root.0.join("o".repeat(250));
    for _ in 0..2 {
        let (code, _, err) = quick_into(&out, &[]);
        assert_eq!(code, 0, "{err}");
        assert_complete(&out);
    }
    assert_eq!(entries(&root.0), ["o".repeat(250)]);
}

/// A file that cannot be written (here: past `ulimit -f`, with SIGXFSZ ignored, so the write
/// fails with EFBIG as on a full disk) is one line naming the file and the cause, for the
/// figures as for the tables: the figures are drawn in memory and written like every other
/// file. (A figure's failed write used to print the plotting backend's debug dump,
/// `BackendError(DrawingError(ImageError(…)))`, naming no path.) The previous output stays.
#[test]
fn a_figure_that_cannot_be_written_is_one_line_naming_it() {
    let root = TempDir::new("fsize");
    let out = root.0.join("out");
    let (code, _, err) = quick_into(&out, &[]);
    assert_eq!(code, 0, "{err}");
    let before = dir_contents(&out).unwrap();
    // 24 blocks (12 KiB in dash's 512-byte blocks, 24 KiB in bash's): the CSV and the summary
    // fit, a figure does not.
    let run = Command::new("sh")
        .arg("-c")
        .arg("trap '' XFSZ; ulimit -f 24 && exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_ecr"))
        .args(QUICK)
        .args(["--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    let (stdout, stderr) = (
        String::from_utf8(run.stdout).unwrap(),
        String::from_utf8(run.stderr).unwrap(),
    );
    assert_one_line_error(run.status.code().unwrap_or(-1), &stdout, &stderr);
    assert!(
        stderr.contains("cannot write '")
            && stderr.contains("scaling.png'")
            && stderr.contains("File too large"),
        "{stderr}"
    );
    assert!(!stderr.contains("Error("), "{stderr}");
    assert_eq!(dir_contents(&out).unwrap(), before);
}
