//! `ecr tables`: the JSON contract, exact round trip of floats, and one-line errors with
//! exit status 2 on bad input.

use crate::common;

use common::ecr;

use ecr_codegen::{Family, MethodTable};

fn bits(v: &serde_json::Value) -> Vec<u64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap().to_bits())
        .collect()
}

#[test]
fn json_contract_and_exact_round_trip() {
    for (family, fam) in [
        ("ec", Family::Ec),
        ("tc", Family::Tc),
        ("rknc", Family::Rknc),
    ] {
        for (r, s) in [(1, 1), (2, 2), (3, 5), (6, 6)] {
            let (code, out, err) = ecr(&[
                "tables",
                "--family",
                family,
                "--r",
                &r.to_string(),
                "--s",
                &s.to_string(),
                "--format",
                "json",
            ]);
            assert_eq!(code, 0, "{err}");
            let v: serde_json::Value = serde_json::from_str(&out).unwrap();
            let t = MethodTable::generate(fam, r, s).unwrap();
            assert_eq!(v["family"], family);
            assert_eq!(v["r"], r);
            assert_eq!(v["s"], s);
            // Floats parse back to exactly the generator's bits.
            let b = |x: &[f64]| x.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&v["nodes"]), b(&t.nodes_f64()));
            assert_eq!(bits(&v["weights"]), b(&t.weights_f64()));
            let w: Vec<u64> = v["w"].as_array().unwrap().iter().flat_map(bits).collect();
            assert_eq!(v["w"].as_array().unwrap().len(), r);
            assert_eq!(w, b(&t.w_f64()));
            // Exact data as "p/q" strings.
            let c = &v["exact"]["c"];
            assert_eq!(c.as_array().unwrap().len(), r);
            assert_eq!(v["exact"]["legendre"].as_array().unwrap().len(), r);
            assert_eq!(v["exact"]["beta"].as_array().unwrap().len(), r);
            for row in c.as_array().unwrap() {
                for x in row.as_array().unwrap() {
                    let txt = x.as_str().unwrap();
                    assert!(txt.parse::<num_rational::BigRational>().is_ok(), "{txt}");
                }
            }
            if fam == Family::Rknc {
                assert_eq!(v["abar"].as_array().unwrap().len(), s);
            }
        }
    }
}

#[test]
fn rust_and_markdown_formats() {
    let (code, out, _) = ecr(&["tables", "--family", "ec", "--r", "3", "--format", "rust"]);
    assert_eq!(code, 0);
    assert!(out.contains("DO NOT EDIT"));
    assert!(out.contains("pub const NODES: [f64; 3]"));
    assert!(out.contains("pub const W: [f64; 9]"));
    let (code, out, _) = ecr(&[
        "tables", "--family", "rknc", "--r", "2", "--format", "markdown",
    ]);
    assert_eq!(code, 0);
    assert!(out.starts_with("# RKNC tables: r = 2, s = 2"));
    assert!(out.contains("| 1 | 0.2113248654051871 |"));
}

#[test]
fn bad_input_is_one_line_and_exit_status_2() {
    let cases: &[&[&str]] = &[
        &["tables", "--family", "ec", "--r", "0"],
        &["tables", "--family", "ec", "--r", "33"],
        &["tables", "--family", "ec", "--r", "4", "--s", "3"],
        &["tables", "--family", "ec", "--r", "2", "--s", "65"],
        &["tables", "--family", "nope", "--r", "2"],
        &["tables", "--family", "ec", "--r", "2", "--format", "yaml"],
        &["tables", "--family", "ec", "--r", "-1"],
        &["tables", "--family", "ec"],
        &["tables", "--r", "2"],
        &["frobnicate"],
        &[],
    ];
    for args in cases {
        let (code, out, err) = ecr(args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(out.is_empty(), "{args:?}");
        assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
        assert!(err.starts_with("error: "), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}");
    }
}

/// A reader that stops early (`ecr … | head`): the output ends there, silently (nothing on
/// stderr), with status 141, as for a command killed by SIGPIPE — not 0, which told a script
/// that the whole result had been delivered. (It used to be 0.)
#[test]
fn closed_pipe_is_status_141_without_a_message() {
    use std::io::Read;
    use std::process::{Command, Stdio};
    // 16384 numbers of JSON, far more than a pipe holds: the writer meets the closed pipe.
    let mut child = Command::new(env!("CARGO_BIN_EXE_ecr"))
        .args(["run", "--problem", "nls", "--n", "8192", "--r", "1"])
        .args(["--h", "0.01", "--t-end", "0.01"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run ecr");
    let mut first = [0u8; 1];
    child.stdout.take().unwrap().read_exact(&mut first).unwrap();
    let out = child.wait_with_output().unwrap();
    assert_eq!(first[0], b'{');
    assert_eq!(out.status.code(), Some(141), "{out:?}");
    assert!(
        out.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A full device on stdout: one line, status 1 (not 2, which is for bad input).
#[test]
fn full_stdout_is_status_1_with_a_message() {
    let full = std::fs::File::create("/dev/full").unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_ecr"))
        .args(["tables", "--family", "ec", "--r", "2"])
        .stdout(full)
        .output()
        .unwrap();
    let err = String::from_utf8(out.stderr).unwrap();
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.starts_with("error: cannot write output: "), "{err}");
}

/// Runs ecr with `args` through `sh -c`, the redirections `redirect` applied to it.
fn ecr_redirected(redirect: &str, args: &[&str]) -> std::process::Output {
    std::process::Command::new("sh")
        .arg("-c")
        .arg(format!("exec \"$0\" \"$@\" {redirect}"))
        .arg(env!("CARGO_BIN_EXE_ecr"))
        .args(args)
        .output()
        .unwrap()
}

/// A full stderr: the message is lost, but the status still tells: 2 for bad input, 1 when
/// stdout is full too (as without the full stderr); no panic. (Both were 101, a panic.)
#[test]
fn full_stderr_keeps_the_status_and_does_not_panic() {
    for (redirect, args, status) in [
        (
            "2>/dev/full",
            &["tables", "--family", "ec", "--r", "0"][..],
            2,
        ),
        (
            "2>/dev/full",
            &["run", "--problem", "duffing", "--h", "0.1"],
            2,
        ),
        (
            "2>/dev/full >/dev/full",
            &["tables", "--family", "ec", "--r", "2"],
            1,
        ),
        ("2>/dev/full >/dev/full", &["--help"], 1),
        ("2>/dev/full", &["--version"], 0),
    ] {
        let out = ecr_redirected(redirect, args);
        assert_eq!(
            out.status.code(),
            Some(status),
            "{redirect} {args:?}: {out:?}"
        );
    }
}

/// A closed stdout (`>&-`): one line, status 1, before any work. (The output went nowhere,
/// status 0.)
#[test]
fn closed_stdout_is_status_1_with_a_message() {
    for args in [
        &["tables", "--family", "ec", "--r", "2"][..],
        &[
            "run",
            "--problem",
            "duffing",
            "--r",
            "2",
            "--h",
            "0.1",
            "--t-end",
            "1",
        ],
    ] {
        let out = ecr_redirected(">&-", args);
        let err = String::from_utf8(out.stderr).unwrap();
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.starts_with("error: standard output is closed"), "{err}");
    }
    // The closed stderr just loses the message.
    let out = ecr_redirected(">&- 2>&-", &["tables", "--family", "ec", "--r", "2"]);
    assert_eq!(out.status.code(), Some(1), "{out:?}");
}
