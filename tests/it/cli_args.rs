//! Random arguments of `ecr run` and `ecr tables` (proptest, fixed seed), run through the
//! binary: finite, infinite, NaN, huge, tiny, negative and malformed values of every option.
//! Never a panic (status 101) or a signal (an abort), one line on stderr for every refusal,
//! and never status 0 with a non-finite number in the report. Also token soup (valid flags and
//! values mixed with malformed ones, in any order) through the same binary.

use proptest::prelude::*;
use proptest::test_runner::{Config as ProptestConfig, RngSeed};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Values that break numerical code, and malformed ones.
const WILD: [&str; 19] = [
    "0",
    "-0",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "infinity",
    "1e400",
    "-1e400",
    "1e308",
    "-1.7976931348623157e308",
    "1e-300",
    "5e-324",
    "2.2250738585072014e-308",
    "1e15",
    "-1e-12",
    "0x10",
    "",
    "1,5",
];

/// A number as a user might type it: in a plausible range four times in six, else a value
/// from [`WILD`] or any f64 at all.
fn number(plausible: std::ops::Range<f64>) -> impl Strategy<Value = String> {
    prop_oneof![
        4 => plausible.prop_map(|x| format!("{x:e}")),
        1 => prop::sample::select(&WILD[..]).prop_map(str::to_string),
        1 => any::<f64>().prop_map(|x| format!("{x:e}")),
    ]
}

/// A count (r, s, N, max sweeps): small five times in six, else zero, odd, huge, negative or
/// not a number.
fn count(small: std::ops::RangeInclusive<u64>) -> impl Strategy<Value = String> {
    prop_oneof![
        5 => small.prop_map(|n| n.to_string()),
        1 => prop::sample::select(vec![
            "0", "1", "7", "33", "65", "-1", "4294967296", "18446744073709551615",
            "18446744073709551616", "1e3", "2.0", "nan",
        ])
        .prop_map(str::to_string),
    ]
}

fn run_args() -> impl Strategy<Value = Vec<String>> {
    let problem = prop::sample::select(vec![
        "duffing",
        "wind",
        "wind-dissipative",
        "nls",
        "fpu",
        "henon-heiles",
    ]);
    let method = prop::sample::select(vec!["ec", "tc", "rknc"]);
    let option = |name: &'static str, value: BoxedStrategy<String>| {
        prop::option::weighted(0.3, value).prop_map(move |v| v.map(|v| (name, v)))
    };
    // N even and small (a thousand Newton steps stay cheap), or anything from count().
    let n = prop_oneof![5 => (1..=8u64).prop_map(|n| (2 * n).to_string()), 1 => count(1..=8)];
    (
        (
            problem,
            method,
            count(1..=4),
            number(5e-3..0.5),
            number(0.0..0.2),
        ),
        (
            option("--s", count(1..=6).boxed()),
            option("--omega", number(0.1..50.0).boxed()),
            option("--k", number(-1.0..1.0).boxed()),
            option("--theta", number(0.0..std::f64::consts::FRAC_PI_2).boxed()),
            option("--amplitude", number(0.1..50.0).boxed()),
            option("--n", n.boxed()),
            option("--stage-tol", number(1e-16..1e-6).boxed()),
            option("--max-sweeps", count(1..=200).boxed()),
        ),
        prop::collection::vec(
            prop::sample::select(vec![
                "--paper-solver",
                "--constant-start",
                "--newton",
                "--precision=double-double",
            ]),
            0..2,
        ),
        // One case in ten keeps an option that does not belong to the problem.
        prop::bool::weighted(0.1),
    )
        .prop_map(|((problem, method, r, h, t_end), options, flags, stray)| {
            let mut v: Vec<String> = vec!["run".into(), "--problem".into(), problem.into()];
            if problem == "fpu" || stray {
                v.extend(["--method".to_string(), method.to_string()]);
            }
            for (name, value) in [("--r", r), ("--h", h), ("--t-end", t_end)] {
                v.push(format!("{name}={value}"));
            }
            let belongs = |name: &str| match name {
                "--omega" => matches!(problem, "duffing" | "fpu"),
                "--k" => problem == "duffing",
                "--theta" | "--amplitude" => problem.starts_with("wind"),
                "--n" => problem == "nls",
                _ => true,
            };
            let (s, omega, k, theta, amplitude, n, tolerance, max_sweeps) = options;
            for (name, value) in [s, omega, k, theta, amplitude, n, tolerance, max_sweeps]
                .into_iter()
                .flatten()
                .filter(|(name, _)| stray || belongs(name))
            {
                v.push(format!("{name}={value}"));
            }
            v.extend(flags.iter().map(|f| f.to_string()));
            v.dedup();
            v
        })
}

fn tables_args() -> impl Strategy<Value = Vec<String>> {
    (
        prop::sample::select(vec!["ec", "tc", "rknc"]),
        count(1..=6),
        prop::option::of(count(1..=8)),
        prop::sample::select(vec!["json", "rust", "markdown"]),
    )
        .prop_map(|(family, r, s, format)| {
            let mut v = vec![
                "tables".to_string(),
                format!("--family={family}"),
                format!("--r={r}"),
                format!("--format={format}"),
            ];
            v.extend(s.map(|s| format!("--s={s}")));
            v
        })
}

/// Runs ecr with `args` (at most 60 s): (status, stdout, stderr); status None for a signal.
fn ecr(args: &[String]) -> (Option<i32>, String, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_ecr"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(60);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("{args:?}: still running after 60 s");
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let out = child.wait_with_output().unwrap();
    (
        out.status.code(),
        String::from_utf8(out.stdout).unwrap(),
        String::from_utf8(out.stderr).unwrap(),
    )
}

/// A refusal (status 2): nothing on stdout, one line on stderr starting with `error: `.
fn one_line_refusal(args: &[String], stdout: &str, stderr: &str) -> Result<(), TestCaseError> {
    prop_assert!(stdout.is_empty(), "{args:?}: {stdout}");
    prop_assert!(stderr.starts_with("error: "), "{args:?}: {stderr}");
    prop_assert_eq!(
        stderr.trim_end().lines().count(),
        1,
        "{:?}: {}",
        args,
        stderr
    );
    Ok(())
}

/// Every number of the report is finite (serde_json writes a non-finite one as null).
fn finite_report(v: &serde_json::Value) -> Result<(), String> {
    for key in [
        "t_end",
        "energy_start",
        "energy_end",
        "max_energy_error",
        "h",
    ] {
        if !v[key].as_f64().is_some_and(f64::is_finite) {
            return Err(format!("{key} = {}", v[key]));
        }
    }
    if !(v["global_error"].is_null() || v["global_error"].as_f64().is_some_and(f64::is_finite)) {
        return Err(format!("global_error = {}", v["global_error"]));
    }
    let y = v["y"].as_array().ok_or("no y")?;
    if y.is_empty() || !y.iter().all(|x| x.as_f64().is_some_and(f64::is_finite)) {
        return Err("y has a non-finite entry".to_string());
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 128,
        rng_seed: RngSeed::Fixed(0x0EC8_0A28),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn random_arguments_never_panic_abort_or_report_non_finite_numbers(
        args in prop_oneof![4 => run_args(), 1 => tables_args()]
    ) {
        let (status, stdout, stderr) = ecr(&args);
        prop_assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        match status {
            Some(0) => {
                prop_assert!(stderr.is_empty(), "{args:?}: {stderr}");
                if args[0] == "run" {
                    let v: serde_json::Value = serde_json::from_str(&stdout)
                        .map_err(|e| TestCaseError::fail(format!("{args:?}: {e}")))?;
                    if let Err(e) = finite_report(&v) {
                        prop_assert!(false, "{args:?}: status 0 with {e}");
                    }
                }
            }
            Some(2) => one_line_refusal(&args, &stdout, &stderr)?,
            other => prop_assert!(false, "{args:?}: status {other:?}: {stderr}"),
        }
    }
}

/// A command line as token soup: a subcommand (or none, a misspelt one, `--help`) and up to
/// nine tokens mixing valid flags and values with malformed ones. Valid runs stay at a few
/// steps; `reproduce` and `bench` are left out (they write files and run for seconds).
const SUBCOMMANDS: &[&str] = &[
    "run", "run", "run", "tables", "tables", "", "runn", "--help",
];

const TOKENS: &[&str] = &[
    "--problem",
    "duffing",
    "wind",
    "wind-dissipative",
    "nls",
    "fpu",
    "schrodinger",
    "--method",
    "ec",
    "tc",
    "rknc",
    "rk4",
    "--r",
    "1",
    "2",
    "3",
    "0",
    "33",
    "-1",
    "x",
    "2.5",
    "--s",
    "4",
    "70",
    "1e3",
    "--h",
    "0.01",
    "0.05",
    "0",
    "-0.1",
    "nan",
    "inf",
    "1e-320",
    "abc",
    "--t-end",
    "0.05",
    "0",
    "-1",
    "NaN",
    "1e400",
    "--omega",
    "--k",
    "--theta",
    "--amplitude",
    "--n",
    "8",
    "5",
    "1e9",
    "0.5",
    "10",
    "--tolerance",
    "--stage-tol",
    "--tol",
    "--max-sweeps",
    "--paper-solver",
    "--extrapolate",
    "--constant-start",
    "--newton",
    "--family",
    "--format",
    "json",
    "rust",
    "markdown",
    "yaml",
    "--",
    "-",
    "--unknown",
    "",
    "é",
    "--h=0.01",
    "--r=2",
];

fn token_soup() -> impl Strategy<Value = Vec<String>> {
    (
        prop::sample::select(SUBCOMMANDS),
        prop::collection::vec(prop::sample::select(TOKENS), 0..10),
    )
        .prop_map(|(sub, rest)| {
            let mut v = Vec::new();
            if !sub.is_empty() {
                v.push(sub.to_string());
            }
            v.extend(rest.iter().map(|t| t.to_string()));
            v
        })
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 400,
        rng_seed: RngSeed::Fixed(0x0EC8_0C11),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn token_soup_never_panics_and_refuses_in_one_line(args in token_soup()) {
        let (status, stdout, stderr) = ecr(&args);
        prop_assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        match status {
            Some(0) => prop_assert!(stderr.is_empty(), "{args:?}: {stderr}"),
            Some(2) => one_line_refusal(&args, &stdout, &stderr)?,
            other => prop_assert!(false, "{args:?}: status {other:?}: {stderr}"),
        }
    }
}

/// A few valid command lines of the token soup's vocabulary do run (so the soup reaches the
/// commands, not only the argument parser).
#[test]
fn the_vocabulary_reaches_the_commands() {
    for line in [
        "run --problem duffing --r 2 --h 0.01 --t-end 0.05",
        "run --problem fpu --method tc --r 1 --h 0.01 --t-end 0",
        "tables --family tc --r 2 --format markdown",
    ] {
        let args: Vec<String> = line.split(' ').map(str::to_string).collect();
        let (status, stdout, stderr) = ecr(&args);
        assert_eq!(status, Some(0), "{args:?}: {stderr}");
        assert!(!stdout.is_empty(), "{args:?}");
    }
}
