//! Where `solve`'s evaluations of g go on the adversarial suite (`tests/it/common_suite`): for
//! every (problem, tolerance) pair how it ended, its error in tolerances against the stored
//! reference, the order, all evaluations of g and the shares of the pilots and of discarded
//! work (windows integrated again, runs started again), the retries and the segments; then
//! the totals: `Ok` pairs, wrong `Ok` (error above 10 tolerances), the median error/tol of the
//! `Ok`, and the pilots' and discarded shares of all g. A minute on 2 cores.
//!
//! ```text
//! cargo bench --bench solve_suite_shares                  # every case, the suite's 9 tolerances
//! cargo bench --bench solve_suite_shares -- kepler 1e-6   # cases by name, tolerances by value
//! TRACE=1 cargo bench --bench solve_suite_shares -- lorenz 1e-8   # with the solve's trace
//! ```
#[path = "../tests/it/common_suite/mod.rs"]
mod common_suite;
use common_suite::measure::{self, Kind};
use ecr::runtime::solve::{Options, SolveError};

fn main() {
    // `cargo bench` passes `--bench`; names and tolerances are the other arguments.
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let tols: Vec<f64> = args.iter().filter_map(|a| a.parse().ok()).collect();
    let names: Vec<&String> = args.iter().filter(|a| a.parse::<f64>().is_err()).collect();
    let tols = if tols.is_empty() {
        common_suite::TOLERANCES.to_vec()
    } else {
        tols
    };
    let refs = common_suite::stored::load();
    let (mut okc, mut n, mut wrong) = (0, 0, 0);
    let mut ratios = Vec::new();
    let (mut pil, mut dis, mut tot) = (0usize, 0usize, 0usize);
    for case in common_suite::cases() {
        if !names.is_empty() && !names.iter().any(|nm| case.name.contains(nm.as_str())) {
            continue;
        }
        for &tol in &tols {
            let opts = if std::env::var("TRACE").is_ok() {
                Options::tolerance(tol).trace(|l| eprintln!("{l}"))
            } else {
                Options::tolerance(tol)
            };
            let (secs, outcome) = measure::cpu_timed(|| measure::catching(|| case.solve(opts)));
            let stats = match &outcome {
                Ok(Ok(s)) => Some((s.stats, s.segments.len())),
                Ok(Err(SolveError::Unverified { solution, .. })) => {
                    Some((solution.stats, solution.segments.len()))
                }
                _ => None,
            };
            let row = measure::row(&case, &refs, tol, outcome, secs);
            n += 1;
            if row.kind == Kind::Ok {
                okc += 1;
                ratios.push(row.error);
                if row.error > 10.0 {
                    wrong += 1;
                }
            }
            let (p, d, t, segs, retries) = stats.map_or((0, 0, 0, 0, 0), |(s, segs)| {
                (
                    s.pilot_g_evals,
                    s.discarded_g_evals,
                    s.total_g_evals(),
                    segs,
                    s.retries,
                )
            });
            pil += p;
            dis += d;
            tot += t;
            println!(
                "{:<20} {tol:>6.0e} {:<10} err/tol {:>9.2e} r {} g {:>9} pilot {:>4.1}% disc {:>4.1}% retries {:>3} segs {:>4} {:>8.4} s",
                case.name,
                format!("{:?}", row.kind),
                row.error,
                row.r,
                t,
                100.0 * p as f64 / t.max(1) as f64,
                100.0 * d as f64 / t.max(1) as f64,
                retries,
                segs,
                secs
            );
        }
    }
    println!(
        "Ok {okc}/{n}, wrong Ok (>10x) {wrong}, median err/tol of Ok {:.2e}, pilots {:.1}% discarded {:.1}% of {} g",
        measure::median(ratios),
        100.0 * pil as f64 / tot as f64,
        100.0 * dis as f64 / tot as f64,
        tot
    );
}
