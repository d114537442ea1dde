//! One (case, options) solve measured: how it ended, its error against the reference at
//! every output time in the suite's norm, its own estimate, its counts and its CPU time.
//! Shared by the suite (`tests/it/solve_suite.rs`) and the cost scan
//! (`benches/solve_cost_suite.rs`).

use std::collections::BTreeMap;
use std::panic::{AssertUnwindSafe, catch_unwind};

use ecr::runtime::solve::{Options, Solution, SolveError};

use super::stored::Stored;
use super::{Case, Outcome, Reference};

/// The CPU time of the calling thread, in seconds. A solve runs on the calling thread (the
/// runtime's concurrent paths start at d = 2¹⁵, far above the suite's sizes), so this is its
/// CPU time, unaffected by other processes sharing the machine.
pub fn thread_cpu_seconds() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; CLOCK_THREAD_CPUTIME_ID exists on Linux.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    assert_eq!(rc, 0, "clock_gettime(CLOCK_THREAD_CPUTIME_ID)");
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// `f()` and the thread CPU time it took.
pub fn cpu_timed<T>(f: impl FnOnce() -> T) -> (f64, T) {
    let start = thread_cpu_seconds();
    let v = f();
    (thread_cpu_seconds() - start, v)
}

/// The fastest of `rounds` thread-CPU timings of `f` (seconds) and the last value.
pub fn fastest<T>(rounds: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..rounds {
        let (t, v) = cpu_timed(&mut f);
        best = best.min(t);
        out = Some(v);
    }
    (best, out.expect("at least one round"))
}

/// How a solve ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    Ok,
    Unverified,
    Failed,
    Panicked,
}

/// One (problem, tolerance) pair.
pub struct Row {
    pub case: &'static str,
    pub class: &'static str,
    pub tol: f64,
    pub kind: Kind,
    /// The worst error/tol over the output times returned (NaN without any).
    pub error: f64,
    /// Where it was worst.
    pub t_worst: f64,
    /// The solve's own estimate (largest over its outputs).
    pub estimate: Option<f64>,
    /// All of the solution's estimates finite and ≤ 1.
    pub estimates_within_one: bool,
    pub outputs: usize,
    pub r: usize,
    pub steps: usize,
    pub g_evals: usize,
    /// CPU seconds of the solve (system and problem built, solved; nothing reused).
    pub seconds: f64,
    pub reason: String,
}

/// max_i |y_i − ref_i| / (1 + |ref_i|): the error in the suite's norm times the tolerance
/// (rtol = atol = tol: the error/tol of a pair is this divided by tol).
pub fn unit_error(y: &[f64], reference: &[f64]) -> f64 {
    y.iter()
        .zip(reference)
        .map(|(y, r)| (y - r).abs() / (1.0 + r.abs()))
        .fold(0.0, |m, e| if e.is_nan() || e > m { e } else { m })
}

/// max_i |y_i − ref_i| / (tol + tol |ref_i|).
pub fn scaled_error(y: &[f64], reference: &[f64], tol: f64) -> f64 {
    y.iter()
        .zip(reference)
        .map(|(y, r)| (y - r).abs() / (tol + tol * r.abs()))
        .fold(0.0, |m, e| if e.is_nan() || e > m { e } else { m })
}

/// The reference at the given output times (exact solutions at any time; stored ones at
/// their own times only).
///
/// # Panics
/// At a time without a stored reference.
pub fn reference_at(case: &Case, refs: &BTreeMap<String, Stored>, ts: &[f64]) -> Vec<Vec<f64>> {
    match case.reference {
        Reference::Exact(f) => f(ts),
        Reference::Taylor { .. } | Reference::Runs => {
            let stored = &refs[case.name];
            ts.iter()
                .map(|t| {
                    let k = stored
                        .t
                        .iter()
                        .position(|s| s == t)
                        .unwrap_or_else(|| panic!("{}: no reference at t = {t}", case.name));
                    stored.y[k].clone()
                })
                .collect()
        }
    }
}

/// The largest [`unit_error`] over a solution's outputs and where it is (NaN without any).
pub fn worst_unit_error(
    case: &Case,
    refs: &BTreeMap<String, Stored>,
    sol: &Solution,
) -> (f64, f64) {
    worst_unit_error_at(case, refs, &sol.t, &sol.y)
}

/// The largest [`unit_error`] over the states `y` at the times `t` and where it is (NaN
/// without any).
pub fn worst_unit_error_at(
    case: &Case,
    refs: &BTreeMap<String, Stored>,
    t: &[f64],
    y: &[Vec<f64>],
) -> (f64, f64) {
    let reference = reference_at(case, refs, t);
    let mut worst = (f64::NAN, f64::NAN);
    for ((t, y), r) in t.iter().zip(y).zip(&reference) {
        let e = unit_error(y, r);
        if worst.0.is_nan() || e > worst.0 || e.is_nan() {
            worst = (e, *t);
        }
    }
    worst
}

/// The outcome of `f` with a panic caught (as its message).
pub fn catching(f: impl FnOnce() -> Outcome) -> Result<Outcome, String> {
    catch_unwind(AssertUnwindSafe(f)).map_err(|p| {
        p.downcast_ref::<String>()
            .cloned()
            .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_default()
    })
}

/// The row of one solve's outcome (already timed: `seconds`).
pub fn row(
    case: &Case,
    refs: &BTreeMap<String, Stored>,
    tol: f64,
    outcome: Result<Outcome, String>,
    seconds: f64,
) -> Row {
    let (kind, solution, reason): (Kind, Option<Solution>, String) = match outcome {
        Ok(Ok(s)) => (Kind::Ok, Some(s), String::new()),
        Ok(Err(SolveError::Unverified { reason, solution })) => {
            (Kind::Unverified, Some(*solution), reason)
        }
        Ok(Err(e)) => (Kind::Failed, None, e.to_string()),
        Err(msg) => (Kind::Panicked, None, msg),
    };
    let mut row = Row {
        case: case.name,
        class: case.class,
        tol,
        kind,
        error: f64::NAN,
        t_worst: f64::NAN,
        estimate: None,
        estimates_within_one: false,
        outputs: 0,
        r: 0,
        steps: 0,
        g_evals: 0,
        seconds,
        reason,
    };
    if let Some(sol) = solution {
        let (e, t) = worst_unit_error(case, refs, &sol);
        row.error = e / tol;
        row.t_worst = t;
        row.estimate = sol.error_estimate;
        row.estimates_within_one = sol
            .error_estimates
            .iter()
            .all(|e| e.is_finite() && *e <= 1.0)
            && sol.error_estimates.len() == sol.t.len();
        row.outputs = sol.t.len();
        row.r = sol.r;
        row.steps = sol.stats.steps;
        row.g_evals = sol.stats.total_g_evals();
    }
    row
}

/// `case` solved once at `tol` (rtol = atol = tol), timed in thread CPU time.
pub fn measure(case: &Case, refs: &BTreeMap<String, Stored>, tol: f64) -> Row {
    let (seconds, outcome) = cpu_timed(|| catching(|| case.solve(Options::tolerance(tol))));
    row(case, refs, tol, outcome, seconds)
}

/// The median (NaN of nothing).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// The q-quantile (the nearest rank; NaN of nothing).
pub fn quantile(v: &[f64], q: f64) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return f64::NAN;
    }
    v[((v.len() - 1) as f64 * q).round() as usize]
}

/// The cases named on the command line (all without names), each with a stored reference
/// checked against the case's hash (for the benches over the suite).
///
/// # Panics
/// On a missing or stale stored reference.
pub fn selected_cases(refs: &BTreeMap<String, Stored>) -> Vec<Case> {
    let names: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let mut selected = Vec::new();
    for case in super::cases() {
        if !names.is_empty() && !names.iter().any(|n| n == case.name) {
            continue;
        }
        if let Reference::Taylor { .. } | Reference::Runs = case.reference {
            let s = refs
                .get(case.name)
                .unwrap_or_else(|| panic!("{}: no stored reference", case.name));
            assert_eq!(s.hash, case.hash(), "{}: stale reference", case.name);
        }
        selected.push(case);
    }
    selected
}

/// The markdown table of the median and largest ratio per problem, from (problem, ratio)
/// in the suite's order.
pub fn per_problem_table<'a>(ratios: impl Iterator<Item = (&'a str, f64)> + Clone) -> String {
    use std::fmt::Write as _;
    let mut names: Vec<&str> = ratios.clone().map(|(n, _)| n).collect();
    names.dedup();
    let mut s = String::from(
        "\n| problem | median ratio of the Ok | largest | pairs |\n|---|---|---|---|\n",
    );
    for name in names {
        let v: Vec<f64> = ratios
            .clone()
            .filter(|(n, _)| *n == name)
            .map(|(_, r)| r)
            .collect();
        writeln!(
            s,
            "| {name} | {:.2} | {:.2} | {} |",
            median(v.clone()),
            v.iter().copied().fold(f64::NAN, f64::max),
            v.len()
        )
        .unwrap();
    }
    s
}
