//! `ecr run`: the JSON report of each test problem, accuracy and energy on short runs, and
//! one-line errors with exit status 2 on bad input.

use crate::common;

use common::ecr;

/// Runs `ecr run ARGS`, expects success and returns the parsed report.
fn run_ok(args: &[&str]) -> serde_json::Value {
    let mut full = vec!["run"];
    full.extend_from_slice(args);
    let (code, out, err) = ecr(&full);
    assert_eq!(code, 0, "ecr {full:?} failed: {err}");
    assert!(err.is_empty(), "unexpected stderr: {err}");
    serde_json::from_str(&out).unwrap_or_else(|e| panic!("bad JSON ({e}): {out}"))
}

const FIELDS: [&str; 18] = [
    "problem",
    "method",
    "r",
    "s",
    "h",
    "t_end",
    "steps",
    "y",
    "energy_start",
    "energy_end",
    "max_energy_error",
    "energy_error_units",
    "global_error",
    "sweeps",
    "max_sweeps_per_step",
    "g_evals",
    "unconverged_steps",
    "wall_seconds",
];

fn check_fields(v: &serde_json::Value) {
    for f in FIELDS {
        assert!(v.get(f).is_some(), "missing field {f} in {v}");
    }
}

#[test]
fn duffing_is_accurate_and_reports_every_field() {
    let v = run_ok(&[
        "--problem",
        "duffing",
        "--method",
        "ec",
        "--r",
        "2",
        "--h",
        "0.01",
        "--t-end",
        "1",
    ]);
    check_fields(&v);
    assert_eq!(v["problem"], "duffing");
    assert_eq!(v["method"], "ec");
    assert_eq!(v["r"], 2);
    assert_eq!(v["s"], 2);
    assert_eq!(v["steps"], 100);
    assert_eq!(v["t_end"].as_f64(), Some(1.0));
    assert_eq!(v["y"].as_array().unwrap().len(), 2);
    let global = v["global_error"].as_f64().unwrap();
    assert!(global < 1e-8, "global error {global:e}");
    let energy = v["max_energy_error"].as_f64().unwrap();
    assert!(energy < 1e-8, "energy error {energy:e}");
    assert_eq!(v["unconverged_steps"], 0);
    let sweeps = v["sweeps"].as_u64().unwrap();
    assert!(sweeps >= 100 && v["max_sweeps_per_step"].as_u64().unwrap() >= 1);
    assert!(v["g_evals"].as_u64().unwrap() >= sweeps);
    assert!(v["wall_seconds"].as_f64().unwrap() >= 0.0);
}

/// The run ends at --t-end exactly and reports the time reached (issue 18, items 1 and 2):
/// h larger than the interval takes one shortened step (it used to take none and report
/// t_end = 0 with a "global error" of 0), and a T that is 9e−10 relative past a multiple of h
/// gets its shortened last step (the step count used to be rounded with a 1e−9 relative slack,
/// so the run stopped short while the report claimed T and the error was measured there).
#[test]
fn the_end_time_is_reached_and_reported() {
    let v = run_ok(&[
        "--problem",
        "duffing",
        "--r",
        "2",
        "--h",
        "1e10",
        "--t-end",
        "1",
    ]);
    assert_eq!(v["t_end"].as_f64(), Some(1.0));
    assert_eq!(v["steps"], 1);
    let global = v["global_error"].as_f64().unwrap();
    assert!(
        global > 0.0 && global < 1.0,
        "one step of h = 1: error {global:e}"
    );
    let v = run_ok(&[
        "--problem",
        "duffing",
        "--r",
        "2",
        "--h",
        "1e-3",
        "--t-end",
        "10.000000009",
    ]);
    assert_eq!(v["t_end"].as_f64(), Some(10.000000009));
    assert_eq!(v["steps"], 10_001);
    // Order 4 with h = 1e-3 over [0, 10]: ≈ 1e-12; the old missing 9e-9 of time left an
    // error of |y'|·9e-9 ≈ 5e-8.
    let global = v["global_error"].as_f64().unwrap();
    assert!(global < 1e-10, "global error {global:e}");
    let v = run_ok(&[
        "--problem",
        "duffing",
        "--r",
        "2",
        "--h",
        "0.3",
        "--t-end",
        "1",
    ]);
    assert_eq!(
        (v["t_end"].as_f64(), v["steps"].as_u64()),
        (Some(1.0), Some(4))
    );
}

/// The default extrapolating predictor against --constant-start: the same solution to the
/// solver tolerance, fewer sweeps; --extrapolate is the default.
#[test]
fn extrapolating_predictor_saves_sweeps() {
    let args = [
        "--problem",
        "duffing",
        "--omega",
        "20",
        "--r",
        "3",
        "--h",
        "0.05",
        "--t-end",
        "20",
    ];
    let fast = run_ok(&args);
    let mut with: Vec<&str> = args.to_vec();
    with.push("--constant-start");
    let plain = run_ok(&with);
    check_fields(&fast);
    assert_eq!(fast["solver"]["extrapolate"], true);
    assert_eq!(plain["solver"]["extrapolate"], false);
    with.pop();
    with.push("--extrapolate");
    assert_eq!(run_ok(&with)["y"], fast["y"]);
    let sweeps = |v: &serde_json::Value| v["sweeps"].as_u64().unwrap();
    assert!(
        (sweeps(&fast) as f64) < 0.85 * sweeps(&plain) as f64,
        "{} vs {}",
        sweeps(&fast),
        sweeps(&plain)
    );
    let (a, b) = (&plain["y"], &fast["y"]);
    for i in 0..2 {
        let d = (a[i].as_f64().unwrap() - b[i].as_f64().unwrap()).abs();
        assert!(d <= 1e-12, "y[{i}] differs by {d:e}");
    }
}

#[test]
fn duffing_paper_solver_and_more_nodes() {
    let v = run_ok(&[
        "--problem",
        "duffing",
        "--omega",
        "10",
        "--r",
        "2",
        "--s",
        "3",
        "--h",
        "0.01",
        "--t-end",
        "0.5",
        "--paper-solver",
    ]);
    check_fields(&v);
    assert_eq!(v["s"], 3);
    assert!(v["max_sweeps_per_step"].as_u64().unwrap() <= 5);
    assert!(v["global_error"].as_f64().unwrap() < 1e-6);
}

#[test]
fn wind_problems_run() {
    for problem in ["wind", "wind-dissipative"] {
        let v = run_ok(&[
            "--problem",
            problem,
            "--r",
            "2",
            "--h",
            "0.01",
            "--t-end",
            "0.5",
        ]);
        check_fields(&v);
        assert_eq!(v["problem"], problem);
        assert!(v["global_error"].is_null());
        assert_eq!(v["y"].as_array().unwrap().len(), 2);
        let (e0, e1) = (
            v["energy_start"].as_f64().unwrap(),
            v["energy_end"].as_f64().unwrap(),
        );
        if problem == "wind" {
            // Nearly preserved: a bounded O(h^{2r}) error (A ≠ 0), ≈ 5e-7 here.
            let energy = v["max_energy_error"].as_f64().unwrap();
            assert!(energy < 1e-5, "wind energy error {energy:e}");
        } else {
            // Dissipative: H does not increase (up to the method's small error).
            assert!(e1 <= e0 * (1.0 + 1e-10), "H grew: {e0} -> {e1}");
        }
    }
}

/// Issue 28: the command of the issue failed at step 2 with "diverging stage iteration" (the
/// iteration from the extrapolated guess diverged where the one from y₀ converges). A step
/// whose guess fails is restarted from y₀: the run succeeds and ends where the run with
/// `--constant-start` does, up to the stage solver's tolerance carried over 10 steps.
#[test]
fn wind_r12_h05_from_the_issue_runs() {
    let cmd = [
        "--problem",
        "wind",
        "--method",
        "ec",
        "--r",
        "12",
        "--h",
        "0.5",
    ];
    let v = run_ok(&[&cmd[..], &["--t-end", "5"]].concat());
    let c = run_ok(&[&cmd[..], &["--t-end", "5", "--constant-start"]].concat());
    assert_eq!(v["steps"], 10);
    assert_eq!(v["t_end"].as_f64(), Some(5.0));
    assert_eq!(v["unconverged_steps"], 0);
    let (y, yc) = (v["y"].as_array().unwrap(), c["y"].as_array().unwrap());
    let scale = yc
        .iter()
        .fold(1.0f64, |m, x| m.max(x.as_f64().unwrap().abs()));
    for (a, b) in y.iter().zip(yc) {
        let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
        // Both iterate each step to the same fixed point to 1e−15 (scaled): 1e−12 leaves
        // room for that carried over 10 steps of a mildly unstable rotation.
        assert!(
            (a - b).abs() <= 1e-12 * scale,
            "y {a} vs {b} (--constant-start)"
        );
    }
    println!(
        "g evaluations: default {}, --constant-start {}",
        v["g_evals"], c["g_evals"]
    );
}

#[test]
fn nls_runs_with_small_energy_error() {
    let v = run_ok(&[
        "--problem",
        "nls",
        "--n",
        "32",
        "--r",
        "2",
        "--h",
        "0.01",
        "--t-end",
        "0.05",
    ]);
    check_fields(&v);
    assert_eq!(v["steps"], 5);
    assert_eq!(v["y"].as_array().unwrap().len(), 64);
    assert!(v["global_error"].is_null());
    let energy = v["max_energy_error"].as_f64().unwrap();
    assert!(energy < 1e-10, "NLS energy error {energy:e}");
}

/// Replacements of base option values, extra arguments.
type Case<'a> = (&'a [(&'a str, &'a str)], &'a [&'a str]);

/// --newton: the same solution as fixed-point sweeps, reported in the JSON.
#[test]
fn newton_stage_solver() {
    let args = [
        "--problem",
        "wind",
        "--r",
        "3",
        "--h",
        "0.05",
        "--t-end",
        "5",
    ];
    let plain = run_ok(&args);
    let mut with: Vec<&str> = args.to_vec();
    with.push("--newton");
    let newton = run_ok(&with);
    check_fields(&newton);
    assert_eq!(newton["solver"]["newton"], true);
    let (a, b) = (&plain["y"], &newton["y"]);
    for i in 0..2 {
        let d = (a[i].as_f64().unwrap() - b[i].as_f64().unwrap()).abs();
        assert!(d <= 1e-12, "y[{i}] differs by {d:e}");
    }
    // TCrP runs on the same stepper, Newton included (it used to be refused).
    let tc = [
        "--problem",
        "fpu",
        "--method",
        "tc",
        "--r",
        "2",
        "--h",
        "0.01",
        "--t-end",
        "1",
    ];
    let plain = run_ok(&tc);
    let mut with: Vec<&str> = tc.to_vec();
    with.push("--newton");
    let newton = run_ok(&with);
    assert_eq!(newton["solver"]["newton"], true);
    let (a, b) = (
        plain["y"].as_array().unwrap(),
        newton["y"].as_array().unwrap(),
    );
    for (x, y) in a.iter().zip(b) {
        let d = (x.as_f64().unwrap() - y.as_f64().unwrap()).abs();
        assert!(d <= 1e-12, "TCrP: differs by {d:e}");
    }
}

#[test]
fn bad_input_gives_one_line_and_exit_2() {
    let base = [
        "--problem",
        "duffing",
        "--r",
        "2",
        "--h",
        "0.01",
        "--t-end",
        "1",
    ];
    // (replacements of base option values, extra arguments)
    let cases: &[Case] = &[
        (&[("--h", "0")], &[]),
        (&[("--h", "-0.1")], &[]),
        (&[("--h", "NaN")], &[]),
        (&[("--h", "inf")], &[]),
        (&[("--h", "abc")], &[]),
        (&[("--t-end", "-1")], &[]),
        (&[("--t-end", "nan")], &[]),
        (&[("--h", "1e-300")], &[]),
        (&[("--r", "0")], &[]),
        (&[("--r", "-1")], &[]),
        (&[("--problem", "lorenz")], &[]),
        (&[("--problem", "nls")], &["--n", "31"]),
        (&[("--problem", "nls")], &["--n", "0"]),
        (&[("--problem", "nls")], &["--omega", "3"]),
        (&[("--problem", "wind")], &["--theta", "2"]),
        (&[("--problem", "wind")], &["--amplitude", "-1"]),
        (&[("--problem", "wind")], &["--k", "1"]),
        (&[], &["--s", "1"]),
        (&[], &["--omega", "0"]),
        (&[], &["--omega", "-5"]),
        (&[], &["--omega", "nan"]),
        (&[], &["--k", "6"]),
        (&[], &["--n", "32"]),
        (&[], &["--method", "tc"]),
        (&[], &["--method", "rknc"]),
        (&[], &["--method", "rk4"]),
        (&[("--problem", "fpu")], &["--method", "rknc"]),
        (
            &[("--problem", "fpu")],
            &["--method", "tc", "--omega", "-1"],
        ),
        (&[("--problem", "fpu")], &["--method", "tc", "--theta", "1"]),
        (&[], &["--stage-tol", "-1"]),
        (&[], &["--max-sweeps", "0"]),
        (&[], &["--bogus"]),
        // Non-convergence is a runtime failure with the same contract.
        (&[], &["--max-sweeps", "1"]),
    ];
    for (replace, extra) in cases {
        let mut args: Vec<&str> = vec!["run"];
        args.extend_from_slice(&base);
        for (opt, val) in *replace {
            let i = args.iter().position(|a| a == opt).unwrap();
            args[i + 1] = val;
        }
        args.extend_from_slice(extra);
        let (code, out, err) = ecr(&args);
        assert_eq!(code, 2, "{args:?}: stdout {out} stderr {err}");
        assert!(out.is_empty(), "{args:?}: stdout {out}");
        assert!(err.starts_with("error: "), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    // Missing required arguments.
    for args in [&["run"][..], &["run", "--problem", "duffing"]] {
        let (code, _, err) = ecr(args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
    }
}

/// How to run is never a guess: without --h and --tol the error offers both ways, and the
/// former --tolerance (the stage solver's, easily read as the run's) is refused naming which
/// option does what (issue 49).
#[test]
fn tol_and_stage_tol_cannot_be_confused() {
    let base = ["run", "--problem", "duffing", "--t-end", "1"];
    let (code, out, err) = ecr(&base);
    assert_eq!((code, out.as_str()), (2, ""), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    for needle in ["--tol TOL", "--r R --h H"] {
        assert!(err.contains(needle), "{err}");
    }
    for extra in [
        &["--tolerance", "1e-8"][..],
        &["--r", "2", "--h", "0.1", "--tolerance", "1e-14"],
    ] {
        let mut args = base.to_vec();
        args.extend_from_slice(extra);
        let (code, out, err) = ecr(&args);
        assert_eq!((code, out.as_str()), (2, ""), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        for needle in ["--tol TOL", "--stage-tol TOL"] {
            assert!(err.contains(needle), "{args:?}: {err}");
        }
    }
    // --stage-tol is the stage solver's tolerance of a fixed-step run, not a way to run.
    let (code, _, err) = ecr(&[
        "run",
        "--problem",
        "duffing",
        "--t-end",
        "1",
        "--stage-tol",
        "1e-14",
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--tol TOL") && err.contains("--r R --h H"),
        "{err}"
    );
    let (code, out, err) = ecr(&[
        "run",
        "--problem",
        "duffing",
        "--t-end",
        "1",
        "--r",
        "2",
        "--h",
        "0.1",
        "--stage-tol",
        "1e-14",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("\"tolerance\": 1e-14"), "{out}");
}

/// Errors caused by an input name it, numbers are printed in shortest form, and messages have
/// no stray spaces (issue 18, item 9). They used to say "matrix contains NaN or infinity"
/// (--h 1e308), "dense operator contains NaN or infinity" (--omega 1e200), print θ = 1e300
/// with 301 digits.
#[test]
fn errors_name_the_input_that_caused_them() {
    let fail = |args: &[&str]| {
        let mut full = vec!["run"];
        full.extend_from_slice(args);
        let (code, out, err) = ecr(&full);
        assert_eq!(code, 2, "{full:?}: stdout {out} stderr {err}");
        assert_eq!(err.lines().count(), 1, "{full:?}: {err}");
        assert!(!err.contains("  "), "{full:?}: stray spaces in {err:?}");
        assert!(err.len() < 300, "{full:?}: {err}");
        err
    };
    let base = ["--problem", "duffing", "--r", "2", "--t-end", "1"];
    let with = |extra: &[&'static str]| {
        let mut v: Vec<&str> = base.to_vec();
        v.extend_from_slice(extra);
        v
    };
    let err = fail(&with(&["--h", "1e308"]));
    assert!(err.contains("step size h = 1e308"), "{err}");
    let err = fail(&with(&["--h", "0.01", "--omega", "1e200"]));
    assert!(
        err.contains("ω = 1e200") && err.contains("overflows"),
        "{err}"
    );
    let err = fail(&[
        "--problem",
        "wind",
        "--r",
        "2",
        "--h",
        "0.01",
        "--t-end",
        "1",
        "--theta",
        "1e300",
    ]);
    assert!(err.contains("θ = 1e300"), "{err}");
}

#[test]
fn fpu_with_tc_rknc_and_ec() {
    let run = |extra: &[&str]| {
        let mut args = vec![
            "run",
            "--problem",
            "fpu",
            "--r",
            "2",
            "--h",
            "0.01",
            "--t-end",
            "1",
        ];
        args.extend_from_slice(extra);
        let (code, out, err) = ecr(&args);
        assert_eq!(code, 0, "{args:?}: {err}");
        serde_json::from_str::<serde_json::Value>(&out).unwrap()
    };
    let tc = run(&["--method", "tc"]);
    let ec = run(&["--method", "ec"]);
    assert_eq!(tc["method"], "tc");
    assert_eq!(tc["steps"], 100);
    assert_eq!(tc["y"].as_array().unwrap().len(), 12);
    // TCrP and ECrP on the first-order form are the same method.
    for (a, b) in tc["y"]
        .as_array()
        .unwrap()
        .iter()
        .zip(ec["y"].as_array().unwrap())
    {
        assert!((a.as_f64().unwrap() - b.as_f64().unwrap()).abs() < 1e-13);
    }
    assert!(tc["max_energy_error"].as_f64().unwrap() < 1e-5);
    let rknc = run(&["--method", "rknc", "--omega", "0"]);
    assert_eq!(rknc["parameters"]["omega"], 0.0);
    // RKNC is ECrP with the nilpotent A = [[0, I], [0, 0]] (not A = 0), so H is nearly, not
    // exactly, conserved: O(h⁴) ≈ 3e-9 here.
    assert!(rknc["max_energy_error"].as_f64().unwrap() < 1e-7);
}

#[test]
fn help_mentions_exit_status() {
    let (code, out, _) = ecr(&["run", "--help"]);
    assert_eq!(code, 0);
    assert!(out.contains("status 2"), "{out}");
    assert!(out.contains("--paper-solver"));
}

/// Sizes are checked before anything is allocated: an NLS grid or a Newton matrix that does
/// not fit in memory is one line and exit status 2 (they used to abort: "memory allocation of
/// 17179869184 bytes failed", SIGABRT). Every case runs under `ulimit -v` 8 GiB, so that a
/// regression aborts instead of taking the machine's memory; --n 16777216 (about 11 GB) might
/// fit in a large machine's memory but not in the 8 GiB, and the message names the limit
/// (MemAvailable where the machine has less).
#[test]
fn nls_memory_is_checked_before_allocating() {
    const LIMIT_KIB: u64 = 8 * 1024 * 1024;
    let nls = |n: &'static str, extra: &[&'static str]| {
        let mut args = vec![
            "run",
            "--problem",
            "nls",
            "--n",
            n,
            "--r",
            "2",
            "--h",
            "0.01",
            "--t-end",
            "0.01",
        ];
        args.extend_from_slice(extra);
        args
    };
    for (args, limit) in [
        (nls("2147483648", &[]), ""),
        (nls("18446744073709551614", &[]), ""),
        (nls("65536", &["--newton"]), ""),
        (nls("16777216", &[]), "ulimit -v"),
    ] {
        let (code, out, err) = common::ecr_with_address_space(LIMIT_KIB, &args);
        assert_eq!(code, 2, "{args:?}: stdout {out} stderr {err}");
        assert!(out.is_empty(), "{args:?}: stdout {out}");
        assert!(
            err.starts_with("error: --problem nls --n"),
            "{args:?}: {err}"
        );
        assert!(
            err.contains("needs about") && err.contains("of memory"),
            "{args:?}: {err}"
        );
        assert!(
            err.contains(limit) || err.contains("MemAvailable"),
            "{args:?}: {err}"
        );
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
    }
    // A grid that fits runs under the same limit.
    let (code, _, err) = common::ecr_with_address_space(LIMIT_KIB, &nls("4096", &[]));
    assert_eq!(code, 0, "{err}");
}

/// SIGINT (Ctrl-C) or SIGTERM on a long run: one line on stderr saying where it got to (t,
/// steps of total), exit status 130 resp. 143, nothing on stdout. (It used to die silently by
/// the signal; SIGTERM did until issue 44.) In a pipe, as here, no progress bar is drawn:
/// stderr holds only that line.
fn signalled_run_reports_where_it_got_to(signal: &str, status: i32, what: &str) {
    let args = [
        "run",
        "--problem",
        "duffing",
        "--r",
        "2",
        "--h",
        "1e-6",
        "--t-end",
        "100",
    ];
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_ecr"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run ecr");
    std::thread::sleep(std::time::Duration::from_millis(700));
    let sent = std::process::Command::new("kill")
        .args(["-s", signal, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(sent.success());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8(out.stderr).unwrap();
    assert_eq!(out.status.code(), Some(status), "{signal}: {err}");
    assert!(out.stdout.is_empty());
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.starts_with(&format!("error: {what} at t = ")), "{err}");
    assert!(err.contains(" of 100000000 steps"), "{err}");
    let steps: u64 = err
        .split(" after ")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(steps > 0, "{err}");
}

#[test]
fn interrupted_run_reports_where_it_got_to() {
    signalled_run_reports_where_it_got_to("INT", 130, "interrupted");
}

#[test]
fn terminated_run_reports_where_it_got_to() {
    signalled_run_reports_where_it_got_to("TERM", 143, "terminated (SIGTERM)");
}

/// `--n 65536` takes the concurrent path (d ≥ 2¹⁵), whose threads each reserved a 64 MiB
/// malloc arena outside the estimate: under `ulimit -v 200000` the run aborted (SIGABRT,
/// "memory allocation of 1048576 bytes failed") in 1 to 3 runs of 4. Around that limit every
/// run now either completes or is refused in one line naming the size; none is killed by a
/// signal.
#[test]
fn nls_on_the_concurrent_path_never_aborts_under_an_address_space_limit() {
    let args = [
        "run",
        "--problem",
        "nls",
        "--n",
        "65536",
        "--r",
        "2",
        "--h",
        "0.01",
        "--t-end",
        "0.01",
    ];
    let mut outcomes = Vec::new();
    for kib in [180_000, 190_000, 200_000, 205_000, 210_000, 220_000] {
        for _ in 0..3 {
            let (code, out, err) = common::ecr_with_address_space(kib, &args);
            match code {
                0 => {
                    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
                    assert!(v["y"].as_array().unwrap().iter().all(|y| y.is_f64()));
                }
                2 => {
                    assert_eq!(err.lines().count(), 1, "{kib} KiB: {err}");
                    assert!(
                        err.starts_with("error: --problem nls --n 65536")
                            && err.contains("needs about"),
                        "{kib} KiB: {err}"
                    );
                }
                _ => panic!("ulimit -v {kib}: status {code} (-1: a signal): {err}"),
            }
            outcomes.push((kib, code));
        }
    }
    println!("(ulimit -v KiB, status): {outcomes:?}");
}

/// Issue 27, the method's floor for any h: on Duffing ω = 20 over T = 1000, N steps of fl(h)
/// used to end at N·fl(h) ≠ T (h = 0.1: 5.6e−14 past T, an error of 2e−11 alone), and the
/// dense propagator was that of fl(h·A) (a frequency off by up to ε/2), so the error floor of
/// an accurate run depended on how h rounds (3.7e−13 to 2.3e−11 across the 20 step sizes
/// below, 61×; the smallest a lucky cancellation against the reference's own 5.5e−12). The
/// last step now makes the sizes add up to T and the propagator is that of h·A: the floor is
/// the same for every h, within 3× of the best one (measured: 5.35e−12 to 5.46e−12). r = 12 (order 24), whose truncation error is
/// below the floor over the whole range; EC6P (r = 6) has 1e−10 to 1e−6 there for h > 0.077,
/// and its floor is that of the same runs at h ≤ 0.07.
#[test]
fn the_error_floor_is_the_same_for_every_h() {
    let errors: Vec<(f64, f64)> = (0..20)
        .map(|k| {
            let h = 0.05 * 4f64.powf(k as f64 / 19.0);
            let hs = format!("{h}");
            let v = run_ok(&[
                "--problem",
                "duffing",
                "--omega",
                "20",
                "--r",
                "12",
                "--h",
                &hs,
                "--t-end",
                "1000",
            ]);
            assert_eq!(v["t_end"].as_f64(), Some(1000.0));
            // The last step is h corrected by round-off, or a shortened one.
            let last = v["h_last"].as_f64().unwrap();
            assert!(
                last > 0.0 && last <= h * (1.0 + 1e-12),
                "h = {h}: h_last = {last}"
            );
            (h, v["global_error"].as_f64().unwrap())
        })
        .collect();
    let best = errors.iter().map(|e| e.1).fold(f64::INFINITY, f64::min);
    let worst = errors.iter().map(|e| e.1).fold(0.0, f64::max);
    for (h, e) in &errors {
        println!("h = {h:.6}: error {e:.3e}");
    }
    assert!(
        worst <= 3.0 * best,
        "error floor from {best:e} to {worst:e} across h: {errors:?}"
    );
}

/// The digits of every JSON number in `text` that follows `"key": [` (an array of numbers).
fn array_numbers<'a>(text: &'a str, key: &str) -> Vec<&'a str> {
    let start = text.find(&format!("\"{key}\": [")).expect("the key") + key.len() + 5;
    let end = start + text[start..].find(']').expect("the array's end");
    text[start..end]
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .collect()
}

/// Significant digits of a number written `d.ddd…e±x`.
fn significant_digits(number: &str) -> usize {
    let mantissa = number.trim_start_matches('-').split('e').next().unwrap();
    mantissa.chars().filter(char::is_ascii_digit).count()
}

#[test]
fn double_double_duffing_prints_34_digits_and_meets_the_exact_solution() {
    // EC8P on Duffing, h = 0.05, T = 10.
    let duffing = [
        "--problem",
        "duffing",
        "--r",
        "8",
        "--h",
        "0.05",
        "--t-end",
        "10",
    ];
    let mut args = vec!["run"];
    args.extend(duffing);
    args.extend(["--precision", "double-double"]);
    let (code, out, err) = ecr(&args);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["precision"], "double-double");
    assert_eq!(v["steps"], 200);
    let ys = array_numbers(&out, "y");
    assert_eq!(ys.len(), 2);
    for y in &ys {
        assert!(significant_digits(y) >= 32, "{y}");
    }
    // 2.9e−28 measured (docs/method.md#measured-orders); f64 cannot go below ~1e−15.
    let e = v["global_error"].as_f64().unwrap();
    assert!(e < 1e-26, "global error {e:e}");
    assert!(v["max_energy_error"].as_f64().unwrap() < 1e-25);
    // The state agrees with the f64 run of the same method to f64 accuracy.
    let f = run_ok(&duffing);
    for (a, b) in ys.iter().zip(f["y"].as_array().unwrap()) {
        let (a, b) = (a.parse::<f64>().unwrap(), b.as_f64().unwrap());
        assert!((a - b).abs() < 1e-13, "{a} vs {b}");
    }
}

#[test]
fn double_double_runs_wind_and_henon_heiles_like_f64() {
    for problem in ["wind", "wind-dissipative", "henon-heiles"] {
        let args = [
            "--problem",
            problem,
            "--r",
            "4",
            "--h",
            "0.01",
            "--t-end",
            "1",
        ];
        let f = run_ok(&args);
        let mut dd_args = args.to_vec();
        dd_args.extend(["--precision", "double-double"]);
        let d = run_ok(&dd_args);
        for (a, b) in d["y"]
            .as_array()
            .unwrap()
            .iter()
            .zip(f["y"].as_array().unwrap())
        {
            let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
            assert!(
                (a - b).abs() <= 1e-12 * b.abs().max(1.0),
                "{problem}: {a} vs {b}"
            );
        }
        assert_eq!(d["steps"], 100);
    }
}

#[test]
fn double_double_refuses_what_it_does_not_run() {
    for (args, want) in [
        (
            vec!["--problem", "nls", "--r", "2", "--h", "0.1"],
            "not --problem nls",
        ),
        (
            vec!["--problem", "fpu", "--r", "2", "--h", "0.1"],
            "not --problem fpu",
        ),
        (vec!["--problem", "duffing", "--tol", "1e-8"], "--tol"),
        (
            vec!["--problem", "duffing", "--r", "2", "--h", "0.1", "--newton"],
            "--newton",
        ),
        (
            vec![
                "--problem",
                "duffing",
                "--r",
                "2",
                "--h",
                "0.1",
                "--paper-solver",
            ],
            "--paper-solver",
        ),
    ] {
        let mut full = vec!["run", "--t-end", "1", "--precision", "double-double"];
        full.extend(args);
        let (code, out, err) = ecr(&full);
        assert_eq!(code, 2, "{full:?}");
        assert!(out.is_empty());
        assert!(err.starts_with("error: ") && err.contains(want), "{err}");
        assert_eq!(err.lines().count(), 1, "{err}");
    }
}

/// Double-double runs every r the f64 path runs: r = 26..=32 on Duffing and the wind (r ≥ 27
/// used to panic, "index out of bounds: the len is 49 but the index is 49", status 101: the
/// table of 1/n! stopped at 48! while φ_r's Taylor series takes up to 1/(22 + r)!). Each agrees
/// with the f64 run of the same method to f64 accuracy.
#[test]
fn double_double_runs_every_r_up_to_32() {
    for problem in ["duffing", "wind"] {
        for r in 26..=32 {
            let r = r.to_string();
            let args = [
                "--problem",
                problem,
                "--t-end",
                "1",
                "--r",
                &r,
                "--h",
                "0.1",
            ];
            let f = run_ok(&args);
            let mut dd_args = args.to_vec();
            dd_args.extend(["--precision", "double-double"]);
            let d = run_ok(&dd_args);
            assert_eq!(d["steps"], 10, "{problem} r = {r}");
            for (a, b) in d["y"]
                .as_array()
                .unwrap()
                .iter()
                .zip(f["y"].as_array().unwrap())
            {
                let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
                assert!(
                    (a - b).abs() <= 1e-11 * b.abs().max(1.0),
                    "{problem} r = {r}: {a} vs {b}"
                );
            }
        }
    }
}

/// In double-double, stage equations that do not converge within --max-sweeps suggest what
/// double-double takes (a smaller --h, more --max-sweeps), not the Newton solver it refuses.
#[test]
fn double_double_non_convergence_suggests_what_it_takes() {
    let (code, out, err) = ecr(&[
        "run",
        "--problem",
        "duffing",
        "--r",
        "4",
        "--h",
        "0.5",
        "--t-end",
        "1",
        "--precision",
        "double-double",
        "--max-sweeps",
        "1",
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(out.is_empty());
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.starts_with("error: integration failed: step 1 from t = 0.0 (h = 0.5): the stage equations did not converge")
            && err.contains("--max-sweeps")
            && !err.to_lowercase().contains("newton"),
        "{err}"
    );
}

/// An unverified `--tol` run (exit 2) that kept no output reports no made-up numbers: the
/// state, its errors and the energy error are null (or real numbers of a state it has), and
/// `missing` says why. (It printed `"y": []` with error_estimate, achieved_error and
/// energy_error all 0.0 while its reason said 26.6 times the tolerance.)
#[test]
fn unverified_tolerance_run_reports_no_made_up_zeros() {
    let (code, out, err) = ecr(&[
        "run",
        "--problem",
        "duffing",
        "--k",
        "5",
        "--t-end",
        "5",
        "--tol",
        "1e-4",
    ]);
    assert_eq!(code, 2, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["verified"], false);
    match v["y"].as_array() {
        None => {
            assert!(v["y"].is_null(), "{out}");
            for key in ["error_estimate", "achieved_error", "energy_error", "t_end"] {
                assert!(v[key].is_null(), "{key} without a state: {out}");
            }
            assert!(
                v["missing"].as_str().unwrap().contains("no output"),
                "{out}"
            );
        }
        Some(y) => {
            assert_eq!(y.len(), 2, "{out}");
            assert!(v["missing"].is_null(), "{out}");
            // A state it has: the error achieved is measured, not 0.
            assert!(v["achieved_error"].as_f64().unwrap() > 0.0, "{out}");
        }
    }
}

/// `--tol` on a large NLS grid: the estimate counts the steppers the solve holds at once (the
/// answer, its two checks and the dense output's, each with its kernel bank for r up to 8), so
/// a run that cannot get them is refused in one line before the work, under `ulimit -v`. (The
/// estimate said 1.36 GiB for N = 262144, the real peak was 3.24 GB: under `ulimit -v
/// 3000000` the run aborted after 13 s, status 134, no report.)
#[test]
fn tolerance_run_past_the_address_space_is_refused_before_the_work() {
    let args = [
        "run",
        "--problem",
        "nls",
        "--n",
        "262144",
        "--t-end",
        "0.05",
        "--tol",
        "1e-4",
    ];
    let (code, out, err) = common::ecr_with_address_space(3_000_000, &args);
    assert_eq!(code, 2, "{err}");
    assert!(out.is_empty());
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.starts_with("error: --problem nls --n 262144 --tol with r up to 8 needs about"),
        "{err}"
    );
}

/// The solve's trace goes where the CLI's other messages go and follows their rules: a stderr
/// that cannot be written (/dev/full) does not end the run (it exited 101 with nothing on
/// stdout), and `ECR_SOLVE_TRACE=0` turns it off (it turned it on).
#[test]
fn the_trace_never_breaks_the_run() {
    let args = [
        "run",
        "--problem",
        "duffing",
        "--t-end",
        "20",
        "--tol",
        "1e-8",
    ];
    let run = |value: &str, stderr: std::process::Stdio| {
        std::process::Command::new(env!("CARGO_BIN_EXE_ecr"))
            .args(args)
            .env("ECR_SOLVE_TRACE", value)
            .stderr(stderr)
            .output()
            .expect("run ecr")
    };
    let full = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/full")
        .expect("/dev/full");
    let out = run("1", full.into());
    assert_eq!(out.status.code(), Some(0), "{:?}", out.status);
    let report = String::from_utf8(out.stdout).unwrap();
    assert!(report.contains("\"error_estimate\""), "{report}");
    let on = run("1", std::process::Stdio::piped());
    assert!(String::from_utf8_lossy(&on.stderr).contains("solve:"));
    for off in ["0", "", "false", "off"] {
        let out = run(off, std::process::Stdio::piped());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!err.contains("solve:"), "ECR_SOLVE_TRACE={off:?}: {err}");
    }
}
