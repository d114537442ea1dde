//! What `solve` costs on the adversarial suite (`tests/common_suite`, issue 42): for every
//! (problem, tolerance) pair, the CPU time of `solve` with that tolerance (pilots, the run,
//! its checks, any run started again — everything, system and problem built anew) against
//! the cheapest fixed-step ECrP run that meets the same tolerance at the same output times.
//!
//! ```text
//! cargo bench --bench solve_cost_suite                     # every case (tens of minutes)
//! cargo bench --bench solve_cost_suite -- lorenz kepler    # cases by name
//! ```
//!
//! The table is printed and written to `target/tmp/solve_cost_suite.txt`.
//!
//! The cheapest fixed run: `Problem::solve(&Options::fixed(r, h))` with the case's output
//! times (a case without them: the fixed run's own steps are its outputs) for r = 8, 7, …, 1
//! and h = span/4 · 2^{−j/8} (eight step sizes per factor 2), each run once; its error is
//! the largest over its outputs of max_i |y_i − ref_i| / (1 + |ref_i|), and it meets a
//! tolerance tol when that is ≤ tol (error/tol ≤ 1 in the suite's norm). An r stops when
//! three of its runs have met the tightest tolerance or when a run needs more than three times
//! the g-evaluations of the dearest cheapest run found so far (or more than 2²⁰ steps); a run
//! that fails (a step whose stage iteration does not converge) is skipped. Among the runs
//! meeting a tolerance, the four with the fewest g-evaluations are timed and the fastest is
//! the cheapest fixed run.
//!
//! Times are thread CPU times (`clock_gettime(CLOCK_THREAD_CPUTIME_ID)`: a solve runs on the
//! calling thread at these sizes), the fastest of `ECR_COST_ROUNDS` (default 3) calls, the
//! same for `solve` and the fixed runs. Nothing is reused from one call to the next: each
//! builds its system and problem.

#[path = "../tests/it/common_suite/mod.rs"]
mod common_suite;

use std::collections::BTreeMap;
use std::fmt::Write as _;

use common_suite::measure::{self, Kind, Row, fastest, median, quantile, worst_unit_error};
use common_suite::stored::{self, Stored};
use common_suite::{Case, TOLERANCES};
use ecr::runtime::solve::Options;

/// A fixed run of the scan.
#[derive(Clone, Copy)]
struct Fixed {
    r: usize,
    h: f64,
    g_evals: usize,
    /// Its error in the suite's unit (error/tol = unit / tol).
    unit: f64,
}

fn fixed_options(r: usize, h: f64) -> Options {
    Options::fixed(r, h)
}

/// Every fixed run of the scan that succeeded (see the module docs).
fn scan(case: &Case, refs: &BTreeMap<String, Stored>) -> Vec<Fixed> {
    let span = case.span.1 - case.span.0;
    let tightest = TOLERANCES.iter().copied().fold(f64::INFINITY, f64::min);
    let mut runs: Vec<Fixed> = Vec::new();
    for r in (1..=8).rev() {
        let mut met_tightest = 0;
        let mut h = span / 4.0;
        while met_tightest < 3 && span / h <= (1u64 << 20) as f64 {
            // The g-evaluations of the dearest of the cheapest runs per tolerance so far
            // (infinite while a tolerance has none).
            let cap = TOLERANCES
                .iter()
                .map(|&tol| {
                    runs.iter()
                        .filter(|f| f.unit <= tol)
                        .map(|f| f.g_evals)
                        .min()
                        .map_or(f64::INFINITY, |g| g as f64)
                })
                .filter(|g| g.is_finite())
                .fold(0.0, f64::max);
            let outcome = measure::catching(|| case.solve(fixed_options(r, h)));
            if let Ok(Ok(sol)) = outcome {
                let (unit, _) = worst_unit_error(case, refs, &sol);
                let g_evals = sol.stats.total_g_evals();
                if unit.is_finite() {
                    runs.push(Fixed {
                        r,
                        h,
                        g_evals,
                        unit,
                    });
                    if unit <= tightest {
                        met_tightest += 1;
                    }
                }
                if cap > 0.0 && g_evals as f64 > 3.0 * cap {
                    break;
                }
            }
            h /= 2f64.powf(1.0 / 8.0);
        }
    }
    runs
}

/// A pair measured: the solve's row, and the cheapest fixed run meeting its tolerance with
/// its CPU time.
struct Pair {
    row: Row,
    fixed: Option<(Fixed, f64)>,
}

impl Pair {
    fn ratio(&self) -> Option<f64> {
        self.fixed.map(|(_, t)| self.row.seconds / t)
    }
}

fn measure_case(case: &Case, refs: &BTreeMap<String, Stored>, rounds: usize) -> Vec<Pair> {
    let runs = scan(case, refs);
    let mut timed: BTreeMap<(usize, u64), f64> = BTreeMap::new();
    let mut pairs = Vec::new();
    for &tol in &TOLERANCES {
        let (seconds, outcome) = fastest(rounds, || {
            measure::catching(|| case.solve(Options::tolerance(tol)))
        });
        let row = measure::row(case, refs, tol, outcome, seconds);
        let mut meeting: Vec<Fixed> = runs.iter().copied().filter(|f| f.unit <= tol).collect();
        meeting.sort_by_key(|f| f.g_evals);
        let mut best: Option<(Fixed, f64)> = None;
        for f in meeting.into_iter().take(4) {
            let t = *timed
                .entry((f.r, f.h.to_bits()))
                .or_insert_with(|| fastest(rounds, || case.solve(fixed_options(f.r, f.h))).0);
            if best.is_none_or(|(_, b)| t < b) {
                best = Some((f, t));
            }
        }
        pairs.push(Pair { row, fixed: best });
    }
    pairs
}

fn table(pairs: &[Pair]) -> String {
    let mut s = String::new();
    writeln!(
        s,
        "{:<15} {:>6} {:<10} {:>9} {:>8} {:>2} {:>7} {:>9} {:>9} | {:>2} {:>10} {:>9} {:>9} {:>9} | {:>6}",
        "problem",
        "tol",
        "outcome",
        "err/tol",
        "estimate",
        "r",
        "steps",
        "g evals",
        "cpu ms",
        "r",
        "h",
        "g evals",
        "err/tol",
        "cpu ms",
        "ratio"
    )
    .unwrap();
    for p in pairs {
        let r = &p.row;
        write!(
            s,
            "{:<15} {:>6.0e} {:<10} {:>9.2e} {:>8} {:>2} {:>7} {:>9} {:>9.3} | ",
            r.case,
            r.tol,
            format!("{:?}", r.kind),
            r.error,
            r.estimate.map_or("-".into(), |e| format!("{e:.1e}")),
            r.r,
            r.steps,
            r.g_evals,
            r.seconds * 1e3,
        )
        .unwrap();
        match p.fixed {
            Some((f, t)) => writeln!(
                s,
                "{:>2} {:>10.4e} {:>9} {:>9.2e} {:>9.3} | {:>6.2}",
                f.r,
                f.h,
                f.g_evals,
                f.unit / r.tol,
                t * 1e3,
                r.seconds / t
            )
            .unwrap(),
            None => writeln!(
                s,
                "{:>2} {:>10} {:>9} {:>9} {:>9} | {:>6}",
                "-", "none meets", "", "", "", "-"
            )
            .unwrap(),
        }
    }
    s
}

fn summary(pairs: &[Pair]) -> String {
    let ok: Vec<f64> = pairs
        .iter()
        .filter(|p| p.row.kind == Kind::Ok)
        .filter_map(Pair::ratio)
        .collect();
    let all: Vec<f64> = pairs.iter().filter_map(Pair::ratio).collect();
    let mut s = String::new();
    writeln!(
        s,
        "solve CPU / cheapest fixed run: median {:.2} over the {} Ok pairs with a fixed run \
         meeting the tolerance (quartiles {:.2}, {:.2}; largest {:.2}); median {:.2} over all {} \
         pairs with one; {} pairs without any fixed run meeting the tolerance",
        median(ok.clone()),
        ok.len(),
        quantile(&ok, 0.25),
        quantile(&ok, 0.75),
        ok.iter().copied().fold(f64::NAN, f64::max),
        median(all.clone()),
        all.len(),
        pairs.iter().filter(|p| p.fixed.is_none()).count()
    )
    .unwrap();
    s.push_str(&measure::per_problem_table(
        pairs
            .iter()
            .filter(|p| p.row.kind == Kind::Ok)
            .filter_map(|p| Some((p.row.case, p.ratio()?))),
    ));
    s
}

fn main() {
    let rounds: usize = std::env::var("ECR_COST_ROUNDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3);
    let refs = stored::load();
    let mut pairs = Vec::new();
    for case in measure::selected_cases(&refs) {
        let start = std::time::Instant::now();
        let measured = measure_case(&case, &refs, rounds);
        eprintln!(
            "{}: {:.1} s\n{}",
            case.name,
            start.elapsed().as_secs_f64(),
            table(&measured)
        );
        pairs.extend(measured);
    }
    let text = format!("{}\n{}", table(&pairs), summary(&pairs));
    println!("{text}");
    let dir = env!("CARGO_TARGET_TMPDIR");
    let path = format!("{dir}/solve_cost_suite.txt");
    match std::fs::write(&path, &text) {
        Ok(()) => eprintln!("wrote {path}"),
        Err(e) => eprintln!("{path}: {e}"),
    }
}
