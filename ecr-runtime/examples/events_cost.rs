//! What an event costs in evaluations of g: Lotka–Volterra u' = u(2/3 − 4/3 v),
//! v' = v(u − 1) from (0.9, 0.9) over (0, 50), solved to a tolerance with and without the event
//! u = 1 (its crossings located to a few ulps of t), all evaluations of g of each solve, and
//! the time of each (the fastest of `ROUNDS` solves, the two kinds interleaved): where g costs
//! nanoseconds the time tells what a user pays beyond the evaluations.
//!
//! ```text
//! cargo run --release -p ecr-runtime --example events_cost
//! ```

use ecr_runtime::operator::Zero;
use ecr_runtime::solve::{Event, Options, Problem};
use ecr_runtime::system::Semilinear;
use std::time::Instant;

/// Solves of each kind timed, interleaved; the fastest counts.
const ROUNDS: usize = 20;

fn main() {
    let system = Semilinear::new(Zero::new(2), |y: &[f64], g: &mut [f64]| {
        g[0] = y[0] * (2.0 / 3.0 - 4.0 / 3.0 * y[1]);
        g[1] = y[1] * (y[0] - 1.0);
    });
    let problem = Problem::new(system, [0.9, 0.9], (0.0, 50.0)).expect("a valid problem");
    for tol in [1e-6, 1e-8, 1e-10] {
        let plain = problem
            .solve(&Options::tolerance(tol))
            .expect("verified")
            .stats;
        let with = problem
            .solve(&Options::tolerance(tol).event(Event::new(|_, y| y[0] - 1.0)))
            .expect("verified");
        let (mut fastest, mut fastest_with) = (f64::INFINITY, f64::INFINITY);
        for _ in 0..ROUNDS {
            let start = Instant::now();
            let _ = problem.solve(&Options::tolerance(tol)).expect("verified");
            fastest = fastest.min(start.elapsed().as_secs_f64());
            let start = Instant::now();
            let _ = problem
                .solve(&Options::tolerance(tol).event(Event::new(|_, y| y[0] - 1.0)))
                .expect("verified");
            fastest_with = fastest_with.min(start.elapsed().as_secs_f64());
        }
        let (a, b) = (plain.total_g_evals(), with.stats.total_g_evals());
        println!(
            "tol {tol:e}: {} crossings; g without the event {a}, with it {b}: {:+.1} %; \
             time {:.0} us against {:.0} us: {:+.1} %",
            with.events.len(),
            100.0 * (b as f64 / a as f64 - 1.0),
            fastest_with * 1e6,
            fastest * 1e6,
            100.0 * (fastest_with / fastest - 1.0)
        );
        if std::env::var("STATS").is_ok() {
            println!("  {:?}", with.stats);
        }
    }
}
