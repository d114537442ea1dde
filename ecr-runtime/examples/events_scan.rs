//! What the scan of each step for two zeros costs, and what it finds: Duffing ω = 20,
//! k = 0.07 from (0, ω) over T = 1000 with a dense 2 × 2 linear part, solved to each
//! tolerance without an event, with one that never fires (q = 100: the scan alone), and with
//! the crossings of q = 0 (6366 of them; at 1e−4 most steps hold two).
//!
//! ```text
//! cargo run --release -p ecr-runtime --example events_scan
//! ```
use ecr_runtime::nalgebra::DMatrix;
use ecr_runtime::operator::Dense;
use ecr_runtime::solve::{Event, Options, Problem};
use ecr_runtime::system::Semilinear;
use std::time::Instant;

fn main() {
    let (w, k) = (20.0_f64, 0.07);
    let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -(w * w + k * k), 0.0]);
    let duffing = Problem::new(
        Semilinear::new(Dense::new(a).unwrap(), move |y: &[f64], o: &mut [f64]| {
            o[0] = 0.0;
            o[1] = 2.0 * k * k * y[0] * y[0] * y[0];
        }),
        [0.0, w],
        (0.0, 1000.0),
    )
    .unwrap();
    for tol in [1e-4, 1e-6, 1e-8, 1e-10] {
        let timed = |options: &Options| {
            let start = Instant::now();
            let sol = duffing.solve(options).unwrap();
            (sol, start.elapsed().as_secs_f64() * 1e3)
        };
        let (plain, t_plain) = timed(&Options::tolerance(tol));
        let never = Event::new(|_, y: &[f64]| y[0] - 100.0);
        let (quiet, t_quiet) = timed(&Options::tolerance(tol).event(never));
        let (zeros, t_zeros) =
            timed(&Options::tolerance(tol).event(Event::new(|_, y: &[f64]| y[0])));
        let (g, gq) = (plain.stats.total_g_evals(), quiet.stats.total_g_evals());
        println!(
            "tol {tol:e}: no event {g} g ({t_plain:.1} ms); one that never fires {gq} g \
             ({:+.1} %, {t_quiet:.1} ms); q = 0: {} crossings, {} g ({t_zeros:.1} ms)",
            100.0 * (gq as f64 / g as f64 - 1.0),
            zeros.events.len(),
            zeros.stats.total_g_evals(),
        );
    }
}
