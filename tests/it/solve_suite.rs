//! The adversarial suite (issues 25 and 42): `Problem::solve` over 23 problems of 21 classes
//! built to defeat a global-error estimate, at tol = 1e−3 … 1e−11 (rtol = atol = tol), errors
//! measured against references accurate to ≤ 1e−13 (`tests/common_suite`).
//!
//! ```text
//! cargo test --release --test it solve_suite:: -- --nocapture                 # table + checks
//! cargo test --release -p ecr --test it solve_suite::generate_references -- --ignored --nocapture
//! cargo test --release -p ecr --test it solve_suite::acceptance -- --ignored        # the unmet targets
//! cargo bench --bench solve_cost_suite                # cost against the cheapest fixed run
//! ```
//!
//! The second regenerates the missing or stale entries of `tests/data/solve_suite_refs.json`
//! (needed after changing a case; `stored_references_are_current` fails until then). The
//! table is also written to `target/tmp/solve_suite.txt`. The error of a pair is the largest
//! over its output times of max_i |y_i − ref_i| / (tol + tol |ref_i|); its CPU time is the
//! thread CPU time of one solve, system and problem built anew.
//!
//! The acceptance of issue 42, each its own test: no `Ok` with an error above 10× the
//! tolerance at any output time; at least 85 % of the pairs `Ok`; the median error/tol of the
//! `Ok` pairs between 0.05 and 1; none of them below 1e−3 at tol ≥ 1e−9; and every `Ok`
//! solution's own estimates finite and ≤ 1. Those the solver does not meet yet are ignored,
//! each with the figure measured; [`no_false_ok_but_the_known_ones`] keeps the false `Ok`
//! answers from spreading meanwhile. [`one_ulp_of_y0_moves_the_sensitive_cases`] checks that
//! the suite holds what the promise is hardest to keep on: answers that one ulp of y₀ moves by
//! more than the tolerance.

use crate::common_suite;

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::sync::OnceLock;
use std::time::Instant;

use common_suite::measure::{self, Kind, Row, median, unit_error};
use common_suite::stored::{self, Stored};
use common_suite::{Case, Reference, TOLERANCES, cases};
use ecr::runtime::solve::Options;
use rayon::prelude::*;

struct Sweep {
    rows: Vec<Row>,
    seconds: f64,
}

/// The stored references, checked to belong to the cases as defined now.
fn checked_refs() -> BTreeMap<String, Stored> {
    let refs = stored::load();
    for case in cases() {
        if let Reference::Taylor { .. } | Reference::Runs = case.reference {
            let stored = refs.get(case.name).unwrap_or_else(|| {
                panic!(
                    "{}: no stored reference; run `{}`",
                    case.name,
                    stored::COMMAND
                )
            });
            assert_eq!(
                stored.hash,
                case.hash(),
                "{}: the stored reference is stale; run `{}`",
                case.name,
                stored::COMMAND
            );
        }
    }
    refs
}

/// Every case at every tolerance, once for all the tests of this file.
fn sweep() -> &'static Sweep {
    static SWEEP: OnceLock<Sweep> = OnceLock::new();
    SWEEP.get_or_init(|| {
        let refs = checked_refs();
        let start = Instant::now();
        let all = cases();
        let pairs: Vec<(&Case, f64)> = all
            .iter()
            .flat_map(|c| TOLERANCES.iter().map(move |&tol| (c, tol)))
            .collect();
        // On the threads of rayon's pool (one per core): each solve runs on one thread and is
        // timed in that thread's CPU time, so the times are those of a solve alone.
        let rows = pairs
            .par_iter()
            .map(|&(case, tol)| measure::measure(case, &refs, tol))
            .collect();
        Sweep {
            rows,
            seconds: start.elapsed().as_secs_f64(),
        }
    })
}

/// An error above 10× the tolerance (or NaN).
fn is_false_ok(r: &Row) -> bool {
    r.error.is_nan() || r.error > 10.0
}

fn oks() -> Vec<&'static Row> {
    sweep().rows.iter().filter(|r| r.kind == Kind::Ok).collect()
}

fn fmt_opt(x: Option<f64>) -> String {
    x.map_or("-".into(), |v| format!("{v:.2e}"))
}

fn describe(r: &Row) -> String {
    format!(
        "{} at tol {:.0e}: error/tol {:.3e} (t = {}), estimate {}, {:?}",
        r.case,
        r.tol,
        r.error,
        r.t_worst,
        fmt_opt(r.estimate),
        r.kind
    )
}

/// The table of every pair.
pub fn pair_table(rows: &[Row]) -> String {
    let mut s = String::new();
    writeln!(
        s,
        "{:<15} {:<24} {:>6} {:<10} {:>10} {:>8} {:>9} {:>2} {:>7} {:>9} {:>5} {:>8}",
        "problem",
        "class",
        "tol",
        "outcome",
        "error/tol",
        "at t",
        "estimate",
        "r",
        "steps",
        "g evals",
        "outs",
        "cpu s"
    )
    .unwrap();
    for r in rows {
        writeln!(
            s,
            "{:<15} {:<24} {:>6.0e} {:<10} {:>10.3e} {:>8.3} {:>9} {:>2} {:>7} {:>9} {:>5} {:>8.4}{}",
            r.case,
            r.class,
            r.tol,
            format!("{:?}", r.kind),
            r.error,
            r.t_worst,
            fmt_opt(r.estimate),
            r.r,
            r.steps,
            r.g_evals,
            r.outputs,
            r.seconds,
            if r.kind == Kind::Ok && r.error > 10.0 { "  FALSE OK" } else { "" }
        )
        .unwrap();
    }
    s
}

/// Per problem: the `Ok` pairs, their error/tol (median, largest, smallest), where not `Ok`.
pub fn problem_table(rows: &[Row]) -> String {
    let mut s = String::new();
    writeln!(
        s,
        "| problem | class | Ok of {} | error/tol of the Ok: median | largest | smallest | \
         not Ok at | CPU s (all tols) |",
        TOLERANCES.len()
    )
    .unwrap();
    writeln!(s, "|---|---|---|---|---|---|---|---|").unwrap();
    let mut names: Vec<&str> = rows.iter().map(|r| r.case).collect();
    names.dedup();
    for name in names {
        let of: Vec<&Row> = rows.iter().filter(|r| r.case == name).collect();
        let ok: Vec<f64> = of
            .iter()
            .filter(|r| r.kind == Kind::Ok)
            .map(|r| r.error)
            .collect();
        let not: Vec<String> = of
            .iter()
            .filter(|r| r.kind != Kind::Ok)
            .map(|r| format!("{:.0e}", r.tol))
            .collect();
        let e = |x: f64| {
            if x.is_finite() {
                format!("{x:.1e}")
            } else {
                "–".into()
            }
        };
        writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {:.2} |",
            name,
            of[0].class,
            ok.len(),
            e(median(ok.clone())),
            e(ok.iter().copied().fold(f64::NAN, f64::max)),
            e(ok.iter().copied().fold(f64::NAN, f64::min)),
            if not.is_empty() {
                "–".into()
            } else {
                not.join(", ")
            },
            of.iter().map(|r| r.seconds).sum::<f64>()
        )
        .unwrap();
    }
    s
}

/// The table and the summary (with `--nocapture`; also in `target/tmp/solve_suite.txt`).
#[test]
fn table_and_summary() {
    let sweep = sweep();
    let mut s = pair_table(&sweep.rows);
    writeln!(s, "\nwhy not Ok:").unwrap();
    for r in sweep.rows.iter().filter(|r| r.kind != Kind::Ok) {
        writeln!(
            s,
            "  {} tol {:.0e} ({:?}): {}",
            r.case, r.tol, r.kind, r.reason
        )
        .unwrap();
    }
    writeln!(s, "\n{}", problem_table(&sweep.rows)).unwrap();
    let oks = oks();
    let n = sweep.rows.len();
    let false_ok = oks.iter().filter(|r| is_false_ok(r)).count();
    let low = oks
        .iter()
        .filter(|r| r.tol >= 1e-9 && r.error < 1e-3)
        .count();
    let mut classes: Vec<&str> = sweep.rows.iter().map(|r| r.class).collect();
    classes.sort_unstable();
    classes.dedup();
    writeln!(
        s,
        "summary: {} problems ({} classes), {n} pairs in {:.1} s ({:.1} s of solve CPU): {} Ok \
         ({:.1} %), {} Unverified, {} Failed, {} panicked; false Ok (error > 10 tol): \
         {false_ok}; median error/tol of Ok: {:.3e}; Ok at tol >= 1e-9 below 1e-3 of it: \
         {low}; Ok with an estimate above 1 or not finite: {}",
        cases().len(),
        classes.len(),
        sweep.seconds,
        sweep.rows.iter().map(|r| r.seconds).sum::<f64>(),
        oks.len(),
        100.0 * oks.len() as f64 / n as f64,
        sweep
            .rows
            .iter()
            .filter(|r| r.kind == Kind::Unverified)
            .count(),
        sweep.rows.iter().filter(|r| r.kind == Kind::Failed).count(),
        sweep
            .rows
            .iter()
            .filter(|r| r.kind == Kind::Panicked)
            .count(),
        median(oks.iter().map(|r| r.error).collect()),
        oks.iter().filter(|r| !r.estimates_within_one).count(),
    )
    .unwrap();
    eprintln!("{s}");
    let dir = env!("CARGO_TARGET_TMPDIR");
    let _ = std::fs::write(format!("{dir}/solve_suite.txt"), &s);
    assert!(classes.len() >= 16, "{} classes", classes.len());
}

/// Acceptance (issue 42): no `Ok` whose error exceeds 10× the tolerance at any output time.
/// Met since the perturbed 3h run measures the rounding the flow amplifies (before it, the ten
/// pairs of [`KNOWN_FALSE_OK`], all where one ulp of y₀ moves the answer by more than the
/// tolerance, see [`one_ulp_of_y0_moves_the_sensitive_cases`]).
#[test]
fn acceptance_no_false_ok() {
    let bad: Vec<String> = oks()
        .iter()
        .filter(|r| is_false_ok(r))
        .map(|r| describe(r))
        .collect();
    assert!(
        bad.is_empty(),
        "{} of {} Ok answers have an error above 10x the tolerance:\n  {}",
        bad.len(),
        oks().len(),
        bad.join("\n  ")
    );
}

/// The false `Ok` answers measured on 2026-11-27 with the controller of issue 25, and their
/// error/tol: lorenz 19; lorenz_long 22, 199, 617; henon_heiles 30, 26; pendulum_sep 26, 239;
/// duffing_sep 737, 1.0e4.
const KNOWN_FALSE_OK: &[(&str, f64)] = &[
    ("lorenz", 1e-11),
    ("lorenz_long", 1e-9),
    ("lorenz_long", 1e-10),
    ("lorenz_long", 1e-11),
    ("henon_heiles", 1e-10),
    ("henon_heiles", 1e-11),
    ("pendulum_sep", 1e-10),
    ("pendulum_sep", 1e-11),
    ("duffing_sep", 1e-6),
    ("duffing_sep", 1e-8),
];

/// No false `Ok` but those known: a new one fails here (the known ones may disappear: then
/// shrink the list, and when it is empty un-ignore [`acceptance_no_false_ok`]).
#[test]
fn no_false_ok_but_the_known_ones() {
    let new: Vec<String> = oks()
        .iter()
        .filter(|r| is_false_ok(r) && !KNOWN_FALSE_OK.contains(&(r.case, r.tol)))
        .map(|r| describe(r))
        .collect();
    assert!(
        new.is_empty(),
        "false Ok answers besides the known ones:\n  {}",
        new.join("\n  ")
    );
}

/// No pair costs more than 4 million evaluations of g, refused or not (the largest 1.4 million
/// on 2026-11-29: lorenz at 1e−11). A run started again in the local mode whose steps shrank
/// for what was rounding took 12 million at duffing_sep 1e−11 and 3.6·10⁹ at 1e−9
/// (docs/solve.md §3).
#[test]
fn no_pair_costs_more_than_4_million_evaluations() {
    let over: Vec<String> = sweep()
        .rows
        .iter()
        .filter(|r| r.g_evals > 4_000_000)
        .map(|r| format!("{} {:.0e}: {} evaluations of g", r.case, r.tol, r.g_evals))
        .collect();
    assert!(over.is_empty(), "{}", over.join("\n"));
}

/// The share of (problem, tolerance) pairs `Ok`, with those that are not.
fn ok_share() -> (usize, usize, String) {
    let n = sweep().rows.len();
    let ok = oks().len();
    let not: Vec<String> = sweep()
        .rows
        .iter()
        .filter(|r| r.kind != Kind::Ok)
        .map(|r| format!("{} {:.0e} {:?}", r.case, r.tol, r.kind))
        .collect();
    (ok, n, not.join(", "))
}

/// Acceptance (issue 42): at least 85 % of the (problem, tolerance) pairs `Ok`. Met since the
/// local mode of a run started again (docs/solve.md §3): 184 of 207 (88.9 %) on 2026-11-29,
/// 178 before it, 170 on 2026-11-28; 180 (87.0 %) on 2026-12-01, since the check's state is
/// kicked by a unit of rounding per step (docs/solve.md §2.3).
#[test]
fn acceptance_at_least_85_percent_ok() {
    let (ok, n, not) = ok_share();
    assert!(
        ok as f64 >= 0.85 * n as f64,
        "{ok} of {n} pairs Ok ({:.1} %, need 85 %); not Ok: {not}",
        100.0 * ok as f64 / n as f64,
    );
}

/// Acceptance (issue 55): at least 90 % of the pairs `Ok`. Not met on 2026-12-01: 180 of 207
/// (87.0 %; 184 on 2026-11-29, before the check's kicks, which cost pendulum 1e−9, henon_heiles
/// 1e−8 and 1e−9 and duffing_sep 1e−4, pairs where one ulp per step grows to a share of the
/// tolerance). The 23 refusals of 2026-11-29: duffing_sep (8) and pendulum_sep (3) on their separatrices,
/// lorenz_long (4), lorenz, pendulum and henon_heiles at 1e−10 … 1e−11 (5), all with the
/// estimate passing the tolerance however small the step; kepler_passage at 1e−9 … 1e−11
/// (3), where what a step makes at the passage is below the rounding that can be told from it.
#[test]
#[ignore = "target not met: 180 of 207 Ok (87.0 %), no false Ok (2026-12-01)"]
fn acceptance_at_least_90_percent_ok() {
    let (ok, n, not) = ok_share();
    assert!(
        ok as f64 >= 0.9 * n as f64,
        "{ok} of {n} pairs Ok ({:.1} %, need 90 %); not Ok: {not}",
        100.0 * ok as f64 / n as f64,
    );
}

/// Acceptance (issue 42): the median error/tol of the `Ok` pairs between 0.05 and 1 (the
/// tolerance neither missed nor wasted). Not met on 2026-11-28: the median is 1.2e−2 (2.7e−3
/// with the 2h/3h check on 2026-11-27).
#[test]
#[ignore = "target not met: median error/tol of the 170 Ok pairs 1.2e-2 (2026-11-28)"]
fn acceptance_median_error_of_ok_between_0_05_and_1() {
    let m = median(oks().iter().map(|r| r.error).collect());
    assert!(
        (0.05..=1.0).contains(&m),
        "median error/tol of the {} Ok pairs is {m:.3e}, not in [0.05, 1]",
        oks().len()
    );
}

/// Acceptance (issue 42): no `Ok` pair at tol ≥ 1e−9 with an error below 1e−3 of the
/// tolerance (a thousandfold waste; below 1e−9 the round-off floor may force it). Not met on
/// 2026-11-28: 35 such pairs (53 with the 2h/3h check).
#[test]
#[ignore = "target not met: 35 Ok pairs at tol >= 1e-9 below 1e-3 of the tolerance (2026-11-28)"]
fn acceptance_no_ok_far_below_tolerance() {
    let bad: Vec<String> = oks()
        .iter()
        .filter(|r| r.tol >= 1e-9 && r.error < 1e-3)
        .map(|r| describe(r))
        .collect();
    assert!(
        bad.is_empty(),
        "{} Ok pairs at tol >= 1e-9 have error/tol below 1e-3:\n  {}",
        bad.len(),
        bad.join("\n  ")
    );
}

/// Acceptance (issues 25 and 42): every `Ok` solution's own estimates are finite and ≤ 1,
/// one per output.
#[test]
fn ok_estimates_are_finite_and_within_one() {
    let bad: Vec<String> = oks()
        .iter()
        .filter(|r| !r.estimates_within_one)
        .map(|r| describe(r))
        .collect();
    assert!(
        bad.is_empty(),
        "{} Ok solutions have an estimate above 1, not finite, or missing:\n  {}",
        bad.len(),
        bad.join("\n  ")
    );
}

/// The cases on which amplified rounding decides the answer at tight tolerances (chaos, a
/// separatrix, a close passage), and by at least how much one ulp of y₀ must move them at
/// 1e−11, in units of that tolerance. They are in the suite for that: if a change of a case
/// loses it, this fails.
const SENSITIVE: &[(&str, f64)] = &[
    ("lorenz", 1.0),
    ("lorenz_long", 10.0),
    ("henon_heiles", 10.0),
    ("pendulum", 1.0),
    ("pendulum_sep", 10.0),
    ("duffing_sep", 10.0),
    ("kepler_passage", 10.0),
];

/// y₀ with component `i` moved by one ulp away from zero.
fn one_ulp(y0: &[f64], i: usize) -> Vec<f64> {
    let mut y = y0.to_vec();
    let v = y[i];
    y[i] = f64::from_bits(v.abs().to_bits() + 1).copysign(v);
    y
}

/// The largest change one ulp of a (nonzero) component of y₀ makes to a fixed run (the
/// case's `fine` ECrP run) at the output times, in the suite's unit (divided by tol: in
/// tolerances), the component, and the error of that run against the reference (NaN while
/// the stored reference is missing or stale).
fn sensitivity(case: &Case, refs: &BTreeMap<String, Stored>) -> (f64, usize, f64) {
    let (r, h) = case.fine;
    let base = case
        .solve(Options::fixed(r, h))
        .unwrap_or_else(|e| panic!("{}: fixed EC{r}P h = {h}: {e}", case.name));
    let current = match case.reference {
        Reference::Exact(_) => true,
        _ => refs.get(case.name).is_some_and(|s| s.hash == case.hash()),
    };
    let own = if current {
        measure::worst_unit_error(case, refs, &base).0
    } else {
        f64::NAN
    };
    let mut worst = (0.0, 0);
    for i in (0..case.y0.len()).filter(|&i| case.y0[i] != 0.0) {
        let moved = case
            .solve_from(one_ulp(&case.y0, i), Options::fixed(r, h))
            .unwrap_or_else(|e| panic!("{}: perturbed fixed run: {e}", case.name));
        let change = base
            .y
            .iter()
            .zip(&moved.y)
            .map(|(a, b)| unit_error(b, a))
            .fold(0.0, f64::max);
        if change > worst.0 {
            worst = (change, i);
        }
    }
    (worst.0, worst.1, own)
}

/// One ulp of y₀ moves each sensitive case's answer by at least its bound (in tolerances at
/// 1e−11); prints the change at every tolerance (`--nocapture`). Pairs where it exceeds the
/// tolerance cannot be answered `Ok` honestly unless the solver's own rounding happens to be
/// smaller than one ulp of y₀.
#[test]
fn one_ulp_of_y0_moves_the_sensitive_cases() {
    let refs = stored::load();
    let all = cases();
    let mut s = String::from(
        "one ulp of y0 (the component that moves it most), in tolerances at each tol:\n",
    );
    write!(
        s,
        "{:<15} {:>9} {:>9} {:>2}",
        "problem", "own err", "change", "i"
    )
    .unwrap();
    for tol in TOLERANCES {
        write!(s, " {:>8.0e}", tol).unwrap();
    }
    writeln!(s).unwrap();
    let mut short = Vec::new();
    for &(name, bound) in SENSITIVE {
        let case = all.iter().find(|c| c.name == name).expect("a case");
        let (change, i, own) = sensitivity(case, &refs);
        write!(s, "{name:<15} {own:>9.1e} {change:>9.1e} {i:>2}").unwrap();
        for tol in TOLERANCES {
            write!(s, " {:>8.1e}", change / tol).unwrap();
        }
        writeln!(s).unwrap();
        if change / 1e-11 < bound {
            short.push(format!("{name}: {:.2} < {bound}", change / 1e-11));
        }
    }
    eprintln!("{s}");
    assert!(
        short.is_empty(),
        "cases that lost their sensitivity: {}",
        short.join(", ")
    );
}

/// The stored references belong to the cases as defined now (hash of the definition, y₀, span
/// and output times), are as accurate as the suite needs, and the high-precision right-hand
/// sides agree with the f64 systems at the reference states.
#[test]
fn stored_references_are_current() {
    let refs = stored::load();
    for case in cases() {
        let dy = match case.reference {
            Reference::Exact(_) => continue,
            Reference::Taylor { .. } | Reference::Runs => {
                let s = refs.get(case.name).unwrap_or_else(|| {
                    panic!(
                        "{}: no stored reference; run `{}`",
                        case.name,
                        stored::COMMAND
                    )
                });
                assert_eq!(
                    s.hash,
                    case.hash(),
                    "{}: stale; run `{}`",
                    case.name,
                    stored::COMMAND
                );
                assert_eq!(Some(&s.t), case.t_eval.as_ref(), "{}", case.name);
                // High precision: ≤ 1e−13 in the suite's unit (errors/tol exact to 1e−2 at
                // tol 1e−11). Two f64 runs (the large NLS): what their agreement shows, ≤ 5e−12
                // (±0.5 in error/tol at 1e−11, ±0.05 at 1e−10); the peer's own round-off,
                // proportional to its step count, is most of it (stored::runs).
                let bound = if matches!(case.reference, Reference::Runs) {
                    5e-12
                } else {
                    1e-13
                };
                assert!(
                    s.accuracy <= bound,
                    "{}: accuracy {:e} ({})",
                    case.name,
                    s.accuracy,
                    s.method
                );
                &s.dy
            }
        };
        let Some(dy) = dy else { continue };
        let s = &refs[case.name];
        for (y, dy) in s.y.iter().zip(dy) {
            let f = case.rhs(y);
            // The two codings agree to round-off of f64 (|f| up to ~1e3 on these states).
            let e = stored::agreement(std::slice::from_ref(&f), std::slice::from_ref(dy));
            assert!(
                e <= 1e-12,
                "{}: f(y) of the f64 system and of the reference differ by {e:e}",
                case.name
            );
        }
    }
}

/// The exact solutions evaluated in f64 (for the outputs at every step) agree with their
/// high-precision evaluation to 1e−14 in the suite's unit, at 2001 times of each span.
#[test]
fn exact_solutions_in_f64_match_high_precision() {
    use common_suite::{
        BILINEAR_T_END, KEPLER_T_END, bilinear_exact, bilinear_exact_hp, kepler_exact,
        kepler_exact_hp,
    };
    type Exact = fn(&[f64]) -> Vec<Vec<f64>>;
    let pairs: [(&str, f64, Exact, Exact); 2] = [
        ("kepler", KEPLER_T_END, kepler_exact, kepler_exact_hp),
        (
            "bilinear",
            BILINEAR_T_END,
            bilinear_exact,
            bilinear_exact_hp,
        ),
    ];
    for (name, t_end, fast, exact) in pairs {
        let ts: Vec<f64> = (0..=2000).map(|i| t_end * i as f64 / 2000.0).collect();
        let e = stored::agreement(&fast(&ts), &exact(&ts));
        eprintln!("{name}: f64 vs high precision {e:.2e}");
        assert!(e <= 1e-14, "{name}: {e:e}");
    }
}

/// Regenerates the missing or stale entries of `tests/data/solve_suite_refs.json` (all of
/// them with `ECR_SUITE_REFS=all`; see the module docs).
#[test]
#[ignore = "minutes: regenerates the stored references"]
fn generate_references() {
    let previous = match std::env::var("ECR_SUITE_REFS").as_deref() {
        Ok("all") => None,
        _ => stored::load_json(),
    };
    let value = stored::generate(&cases(), previous.as_ref());
    let text = stored::render(&value, 0);
    std::fs::create_dir_all(std::path::Path::new(stored::PATH).parent().unwrap()).unwrap();
    std::fs::write(stored::PATH, text + "\n").unwrap();
    eprintln!("wrote {}", stored::PATH);
}
