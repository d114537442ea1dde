//! Tables across runs: a resume or a merge of another run's rows refused naming the field of
//! the fingerprint that differs (nothing written), corrupt rows of an unfinished table solved
//! again, a merge onto one of its own parts refused.

use super::*;
use crate::error::Result;
use crate::operator::Dense;
use crate::solve::{Options, Problem, Solution};
use crate::system::Semilinear;
use nalgebra::DMatrix;
use std::fs;
use std::ops::ControlFlow;
use std::path::Path;
use std::path::PathBuf;

/// What a run is made of: each field changes what the rows hold.
#[derive(Clone, Copy, Debug)]
struct Run {
    /// The tolerance (or, with `fixed`, the step of a fixed method).
    tol: f64,
    fixed: bool,
    /// Member i starts from q = q0 + i / 100.
    q0: f64,
    /// The parameter c of q'' = −q − c q³.
    c: f64,
    t_end: f64,
    members: usize,
    key: &'static str,
    description: &'static str,
}

const BASE: Run = Run {
    tol: 1e-6,
    fixed: false,
    q0: 0.5,
    c: 1.0,
    t_end: 0.5,
    members: 40,
    key: "",
    description: "q'' = -q - c q^3",
};

/// The refusals the fingerprint must give: a run that differs from [`BASE`] in one thing, and
/// the field it must name.
fn others() -> Vec<(Run, &'static str)> {
    vec![
        (Run { tol: 1e-9, ..BASE }, "rtol"),
        (
            Run {
                fixed: true,
                tol: 0.05,
                ..BASE
            },
            "method",
        ),
        (Run { q0: 0.25, ..BASE }, "y0"),
        (Run { c: 2.0, ..BASE }, "inputs"),
        (
            Run {
                t_end: 0.75,
                ..BASE
            },
            "span",
        ),
        (
            Run {
                members: 41,
                ..BASE
            },
            "members",
        ),
        (
            Run {
                key: "model v2",
                ..BASE
            },
            "key",
        ),
        (
            Run {
                description: "another",
                ..BASE
            },
            "description",
        ),
    ]
}

/// Writes the table of `run` at `path` with `control` (part `part` of 2 as a part file) on
/// one thread.
fn write(run: Run, path: &Path, control: &Control<'_>, part: Option<usize>) -> Result<TableReport> {
    let a = Dense::new(DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -1.0, 0.0])).unwrap();
    let c = run.c;
    let system = Semilinear::new(a, move |y: &[f64], g: &mut [f64]| {
        g[0] = 0.0;
        g[1] = -c * y[0].powi(3);
    });
    let ensemble = Ensemble::new((), run.members, |_: &(), i| {
        Problem::new(&system, [run.q0 + i as f64 / 100.0, 0.0], (0.0, run.t_end))
    });
    let options = if run.fixed {
        Options::fixed(2, run.tol)
    } else {
        Options::tolerance(run.tol)
    };
    let table = Table::new(
        run.description,
        vec![Column::f64("q_end"), Column::f64("estimate")],
    )
    .inputs(
        vec![Column::f64("c"), Column::f64("q0")],
        move |i, cells| {
            cells.extend([Cell::F64(run.c), Cell::F64(run.q0 + i as f64 / 100.0)]);
        },
    )
    .key(run.key);
    let table = if part.is_some() {
        table.as_part()
    } else {
        table
    };
    let control = match part {
        Some(k) => control.split(k, 2, 0),
        None => control.split(0, 1, 0),
    };
    let output = |_: usize, s: &Solution| {
        vec![
            Cell::F64(s.last().map_or(f64::NAN, |y| y[0])),
            s.error_estimate.into(),
        ]
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    pool.install(|| ensemble.write_table(&options, &control, &table, output, path))
}

/// A fresh directory for one test.
fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ecr-{name}-{}", std::process::id()));
    let _ = fs::remove_dir_all(&d);
    fs::create_dir_all(&d).unwrap();
    d
}

/// The unfinished file of `path` (the only one).
fn stage(path: &Path) -> PathBuf {
    let name = path.file_name().unwrap().to_str().unwrap();
    let prefix = format!(".{name}.ecr-partial-");
    let mut found: Vec<PathBuf> = fs::read_dir(path.parent().unwrap())
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_str().unwrap().starts_with(&prefix))
        .map(|e| e.path())
        .collect();
    assert_eq!(found.len(), 1, "{found:?}");
    found.pop().unwrap()
}

/// Stops a run after `n` members.
fn stop_after(n: usize) -> Control<'static> {
    Control::new().resume().progress(move |p| {
        if p.done >= n {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    })
}

#[test]
fn a_resume_of_another_run_is_refused_naming_the_field_and_writes_nothing() {
    let d = dir("fingerprint-resume");
    let whole = d.join("whole.csv");
    assert!(write(BASE, &whole, &Control::new(), None).unwrap().complete);
    let text = fs::read_to_string(&whole).unwrap();
    assert!(
        text.starts_with("# ecr ensemble table of 40 members: q'' = -q - c q^3\n# version: "),
        "{text}"
    );
    for field in [
        "rtol: 1e-6",
        "y0: [0.5, 0.0]",
        "span: (0.0, 0.5)",
        "inputs: sha256 ",
    ] {
        assert!(text.contains(&format!("\n# {field}")), "{field}: {text}");
    }
    let path = d.join("t.csv");
    let r = write(BASE, &path, &stop_after(12), None).unwrap();
    assert!(!r.complete && r.written >= 12, "{r:?}");
    let unfinished = stage(&path);
    let before = fs::read(&unfinished).unwrap();
    for (run, field) in others() {
        let e = write(run, &path, &Control::new().resume(), None).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains(&format!("of another run ({field}: ")) && msg.lines().count() == 1,
            "{field}: {msg}"
        );
        assert_eq!(fs::read(&unfinished).unwrap(), before, "{field}");
        assert!(!path.exists(), "{field}");
    }
    // The same run resumes, and its table is the uninterrupted one.
    let r = write(BASE, &path, &Control::new().resume(), None).unwrap();
    assert!(r.complete && r.kept >= 12, "{r:?}");
    assert!(fs::read(&path).unwrap() == fs::read(&whole).unwrap());
    fs::remove_dir_all(&d).unwrap();
}

#[test]
fn corrupt_rows_of_an_unfinished_table_are_solved_again() {
    let d = dir("fingerprint-rows");
    let whole = d.join("whole.csv");
    write(BASE, &whole, &Control::new(), None).unwrap();
    let path = d.join("t.csv");
    write(BASE, &path, &stop_after(12), None).unwrap();
    let unfinished = stage(&path);
    let good = fs::read_to_string(&unfinished).unwrap();
    let lines: Vec<&str> = good.split_inclusive('\n').collect();
    let first_row = lines.iter().position(|l| l.starts_with("0,")).unwrap();
    // Row 5 (member 5) made wrong in each way; rows 0..5 are kept, the rest solved again.
    let row = |i: usize| lines[first_row + i].trim_end_matches('\n');
    let corrupt: Vec<(&str, String)> = vec![
        ("an extra column", format!("{},1.0", row(5))),
        ("a cell that is not a number", {
            let mut f: Vec<&str> = row(5).split(',').collect();
            f[4] = "0.4x";
            f.join(",")
        }),
        ("a number written otherwise", {
            let mut f: Vec<&str> = row(5).split(',').collect();
            let q: f64 = f[4].parse().unwrap();
            let longer = format!("{q:.20}");
            f[4] = &longer;
            f.join(",")
        }),
        ("a duplicate index", row(4).to_string()),
        ("an index out of range", row(5).replacen("5,", "4000,", 1)),
        ("an index written otherwise", format!("+{}", row(5))),
        ("another input cell", row(5).replacen("5,1.0,", "5,1.5,", 1)),
        ("an unknown status", row(5).replacen("verified", "done", 1)),
        (
            "a missing field",
            row(5).rsplit_once(',').unwrap().0.to_string(),
        ),
    ];
    for (what, bad) in corrupt {
        let mut text: String = lines[..first_row + 5].concat();
        text += &bad;
        text += "\n";
        text += &lines[first_row + 6..].concat();
        fs::write(&unfinished, &text).unwrap();
        let r = write(BASE, &path, &Control::new().resume(), None).unwrap();
        assert!(r.complete && r.kept == 5, "{what}: {r:?}");
        assert!(
            fs::read(&path).unwrap() == fs::read(&whole).unwrap(),
            "{what}"
        );
        fs::remove_file(&path).unwrap();
    }
    fs::remove_dir_all(&d).unwrap();
}

#[test]
fn parts_of_other_runs_and_merges_onto_a_part_are_refused() {
    let d = dir("fingerprint-merge");
    let whole = d.join("whole.csv");
    write(BASE, &whole, &Control::new(), None).unwrap();
    let part = |run: Run, k: usize, name: &str| {
        let p = d.join(name);
        assert!(write(run, &p, &Control::new(), Some(k)).unwrap().complete);
        p
    };
    let first = part(BASE, 0, "a1.csv");
    let second = part(BASE, 1, "a2.csv");
    let out = d.join("merged.csv");
    for (run, field) in others() {
        let other = part(run, 1, "b2.csv");
        let msg = merge_parts(&[&first, &other], &out)
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains(&format!("are parts of different runs ({field}: "))
                && msg.lines().count() == 1,
            "{field}: {msg}"
        );
        assert!(!out.exists(), "{field}");
    }
    // Never onto one of its parts: by the same path, another spelling of it, or a symlink.
    let before = fs::read(&first).unwrap();
    fs::create_dir_all(d.join("sub")).unwrap();
    let mut onto = vec![first.clone(), d.join("sub").join("..").join("a1.csv")];
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(&second, d.join("link.csv")).unwrap();
        onto.push(d.join("link.csv"));
    }
    for target in onto {
        let msg = merge_parts(&[&first, &second], &target)
            .unwrap_err()
            .to_string();
        assert!(msg.contains("would replace its part"), "{msg}");
        assert_eq!(fs::read(&first).unwrap(), before);
    }
    // The parts of one run merge into its table, byte for byte.
    merge_parts(&[&second, &first], &out).unwrap();
    assert!(fs::read(&out).unwrap() == fs::read(&whole).unwrap());
    let npy = d.join("merged.npy");
    assert_eq!(table_to_npy(&out, &npy).unwrap(), 40);
    fs::remove_dir_all(&d).unwrap();
}
