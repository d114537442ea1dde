//! Random command lines (proptest, fixed seed) through the in-process entry point [`super::run`]:
//! every one either succeeds or returns a one-line [`UsageError`]; none panics. The vocabulary
//! mixes valid flags and values with malformed ones, and keeps valid runs to a few steps
//! (`reproduce` and `bench` are left out: they write files and run for seconds).

use super::{UsageError, run};
use proptest::prelude::*;
use proptest::test_runner::{Config as ProptestConfig, RngSeed};

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

fn command_line() -> impl Strategy<Value = Vec<&'static str>> {
    (
        prop::sample::select(SUBCOMMANDS),
        prop::collection::vec(prop::sample::select(TOKENS), 0..10),
    )
        .prop_map(|(sub, rest)| {
            let mut v = vec!["ecr"];
            if !sub.is_empty() {
                v.push(sub);
            }
            v.extend(rest);
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
    fn random_command_lines_never_panic(args in command_line()) {
        let mut out = Vec::new();
        match run(args.clone(), &mut out) {
            Ok(()) => {}
            Err(UsageError(msg)) => {
                prop_assert!(!msg.trim().is_empty(), "{args:?}: empty message");
                prop_assert!(!msg.contains('\n'), "{args:?}: multi-line message {msg:?}");
            }
        }
    }
}

/// A few valid command lines from the vocabulary do run (so the fuzz reaches the commands).
#[test]
fn the_vocabulary_reaches_the_commands() {
    for args in [
        &[
            "ecr",
            "run",
            "--problem",
            "duffing",
            "--r",
            "2",
            "--h",
            "0.01",
            "--t-end",
            "0.05",
        ][..],
        &[
            "ecr",
            "run",
            "--problem",
            "fpu",
            "--method",
            "tc",
            "--r",
            "1",
            "--h",
            "0.01",
            "--t-end",
            "0",
        ],
        &[
            "ecr", "tables", "--family", "tc", "--r", "2", "--format", "markdown",
        ],
    ] {
        let mut out = Vec::new();
        assert!(run(args.to_vec(), &mut out).is_ok(), "{args:?}");
        assert!(!out.is_empty());
    }
}
