//! What the automation costs: `solve` with a tolerance (pilots, the run, its two checking
//! runs, any run started again — everything) against the cheapest fixed-step ECrP run that
//! meets the same tolerance, found by scanning r = 1..=8 and h (8 step sizes per factor 2),
//! both through the same `Problem::solve` (`Options::fixed(r, h)` for the
//! fixed runs), output at t_end, error in the solve's norm against the exact solution
//! (Duffing) or a reference run (NLS: EC8P, h = 1/128). The fastest of 5 runs each; the six
//! fixed runs with the fewest g-evaluations among those that meet the tolerance are timed. `cargo bench --bench solve_cost` (a few minutes).
//!
//! Cases (issue 25): Duffing ω = 20, k = 0.07, T = 1000 at 1e−6, 1e−8, 1e−10; the NLS N = 128,
//! T = 10 at 1e−6, 1e−8.

use ecr::problems::{Duffing, Nls};
use ecr::runtime::solve::{Options, Problem};
use ecr::runtime::system::System;
use std::time::Instant;

/// max_i |a_i − b_i| / (tol (1 + |b_i|)).
fn scaled(a: &[f64], b: &[f64], tol: f64) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / (tol + tol * y.abs()))
        .fold(0.0, f64::max)
}

/// The fastest of `rounds` timings of `f` (seconds; single-threaded, so the fastest wall
/// time is the CPU time on a machine that was quiet for that round), its value from the last
/// call.
fn fastest<T>(rounds: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..rounds {
        let start = Instant::now();
        let v = f();
        best = best.min(start.elapsed().as_secs_f64());
        out = Some(v);
    }
    (best, out.expect("at least one round"))
}

fn case<S: System>(name: &str, problem: &Problem<S>, t_end: f64, reference: &[f64], tol: f64) {
    let (t_solve, sol) = fastest(5, || {
        problem.solve(&Options::tolerance(tol).t_eval([t_end]))
    });
    let sol = match sol {
        Ok(sol) => sol,
        Err(e) => {
            println!("{name} tol {tol:e}: solve not verified: {e}");
            return;
        }
    };
    let err = scaled(sol.last().unwrap(), reference, tol);
    // The scan: every (r, h) that meets tol, by g-evaluations; the cheapest few timed.
    let span = t_end;
    let mut meeting: Vec<(usize, f64, usize, f64)> = Vec::new();
    for r in 1..=8 {
        let mut h = span / 4.0;
        let mut met = 0;
        while h > span / 2e6 && met < 6 {
            if let Ok(f) = problem.solve(&Options::fixed(r, h).t_eval([t_end])) {
                let e = scaled(f.last().unwrap(), reference, tol);
                if e <= 1.0 {
                    meeting.push((r, h, f.stats.total_g_evals(), e));
                    met += 1;
                }
            }
            h /= 2f64.powf(1.0 / 8.0);
        }
    }
    meeting.sort_by_key(|m| m.2);
    let mut best = (f64::INFINITY, 0, 0.0, 0.0);
    for &(r, h, _, e) in meeting.iter().take(6) {
        let (t, _) = fastest(5, || problem.solve(&Options::fixed(r, h).t_eval([t_end])));
        if t < best.0 {
            best = (t, r, h, e);
        }
    }
    let s = &sol.stats;
    println!(
        "{name} tol {tol:e}: solve EC{}P {:.2} ms (error/tol {err:.3}, estimate {:.3}; g: run {}, \
         checks {}, pilots {}, discarded {}) | cheapest fixed EC{}P h = {:.4e} {:.2} ms \
         (error/tol {:.3}) | ratio {:.2}",
        sol.r,
        t_solve * 1e3,
        sol.error_estimate.unwrap_or(f64::NAN),
        s.g_evals,
        s.check_g_evals,
        s.pilot_g_evals,
        s.discarded_g_evals,
        best.1,
        best.2,
        best.0 * 1e3,
        best.3,
        t_solve / best.0
    );
}

fn main() {
    let d = Duffing::new(20.0, 0.07).unwrap();
    let duffing = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, 1000.0)).unwrap();
    let exact = d.exact(1000.0).unwrap();
    for tol in [1e-6, 1e-8, 1e-10] {
        case("duffing ω = 20, T = 1000", &duffing, 1000.0, &exact, tol);
    }
    let n = Nls::new(128).unwrap();
    let nls = Problem::new(n.system().unwrap(), n.initial_value(), (0.0, 10.0)).unwrap();
    let reference = nls
        .solve(&Options::fixed(8, 10.0 / 1280.0).t_eval([10.0]))
        .unwrap();
    let reference = reference.last().unwrap().to_vec();
    for tol in [1e-6, 1e-8] {
        case("nls N = 128, T = 10", &nls, 10.0, &reference, tol);
    }
}
