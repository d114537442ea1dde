//! Kepler e = 0.9 over 10 orbits from apoapsis: what `solve` pays to verify an orbit with close
//! passages, against the cheapest constant step that meets the tolerance (found with
//! hindsight: r = 2 … 8, eight step sizes per factor 2 from h = 0.1 down, the largest that meets
//! it for each r). After whole periods the exact state is y₀ again.
//!
//! The periapsis is at 0.1, where the speed is 19 times that at apoapsis: a run started again
//! there measures what each step makes and shrinks the step on the way in (docs/solve.md §3).
//!
//! `cargo run --release --example close_passages` (the table of docs/solve.md §4.2; with
//! `ECR_SOLVE_TRACE=1` every decision of the controller on stderr)
use ecr::runtime::operator::Zero;
use ecr::runtime::solve::{Options, Problem, SolveError};
use ecr::runtime::system::Semilinear;
use std::f64::consts::PI;

const E: f64 = 0.9;
const ORBITS: f64 = 10.0;
const TOLS: [f64; 4] = [1e-4, 1e-6, 1e-8, 1e-10];

fn main() {
    let v = ((1.0 - E) / (1.0 + E)).sqrt();
    let g = |y: &[f64], o: &mut [f64]| {
        let r2 = y[0] * y[0] + y[1] * y[1];
        let r3 = r2 * r2.sqrt();
        o[0] = y[2];
        o[1] = y[3];
        o[2] = -y[0] / r3;
        o[3] = -y[1] / r3;
    };
    let y0 = [1.0 + E, 0.0, 0.0, v];
    let problem = Problem::new(
        Semilinear::new(Zero::new(4), g),
        y0,
        (0.0, ORBITS * 2.0 * PI),
    )
    .expect("a valid problem");
    // The error at t_end in tolerances, per component relative to 1 + |y₀|.
    let error = |y: &[f64]| {
        y.iter()
            .zip(y0)
            .map(|(a, b)| (a - b).abs() / (1.0 + b.abs()))
            .fold(0.0, f64::max)
    };
    println!(
        "| tol | solve (order, segments) | run / check / pilots / discarded | error/tol | cheapest constant step | ratio |"
    );
    println!("|---|---|---|---|---|---|");
    for tol in TOLS {
        let mut options = Options::tolerance(tol);
        if std::env::var_os("ECR_SOLVE_TRACE").is_some() {
            options = options.trace(|line| eprintln!("{line}"));
        }
        let (status, sol) = match problem.solve(&options) {
            Ok(sol) => ("Ok", sol.into_data()),
            Err(SolveError::Unverified { solution, .. }) => ("Unverified", *solution),
            Err(e) => panic!("tol {tol:e}: {e}"),
        };
        let s = sol.stats;
        let k = |n: usize| format!("{}k", (n as f64 / 1e3).round());
        let (g_fixed, r_fixed, h_fixed) = cheapest_constant_step(&problem, tol, &error);
        println!(
            "| {tol:e} | {status}, EC{}P, {} | {} / {} / {} / {} | {:.1e} | EC{r_fixed}P h = {h_fixed:.3}: {} | {:.1} |",
            sol.r,
            sol.segments.len(),
            k(s.g_evals),
            k(s.check_g_evals),
            k(s.pilot_g_evals),
            k(s.discarded_g_evals),
            error(sol.last().expect("a state")) / tol,
            k(g_fixed),
            s.total_g_evals() as f64 / g_fixed as f64,
        );
    }
}

/// The constant-step run with the fewest evaluations of g that meets `tol` at t_end:
/// (evaluations, r, h).
fn cheapest_constant_step<S: ecr::runtime::system::System>(
    problem: &Problem<S>,
    tol: f64,
    error: &dyn Fn(&[f64]) -> f64,
) -> (usize, usize, f64) {
    let mut best = (usize::MAX, 0, f64::NAN);
    for r in 2..=8 {
        for k in 0..96 {
            let h = 0.1 * (-f64::from(k) / 8.0).exp2();
            let Ok(sol) = problem.solve(&Options::fixed(r, h)) else {
                continue;
            };
            if error(sol.last().expect("a state")) <= tol {
                let g = sol.stats.total_g_evals();
                if g < best.0 {
                    best = (g, r, h);
                }
                break;
            }
        }
    }
    best
}
