//! What uneven `t_eval` outputs cost beyond the plain solve: Duffing ω = 20, k = 0.07 from
//! (0, ω) over T = 1000 with a dense 2 × 2 linear part (as `at_cost`), solved to a tolerance
//! without and with N uneven output times; the fastest of `runs` solves of each, and the cost
//! per output of the difference.
//!
//! ```text
//! cargo run --release -p ecr-runtime --example teval_cost            # tol 1e-8, N = 1e5, 3 runs
//! cargo run --release -p ecr-runtime --example teval_cost -- 1e-8 100000 3
//! ```
use ecr_runtime::nalgebra::DMatrix;
use ecr_runtime::operator::Dense;
use ecr_runtime::solve::{Options, Problem};
use ecr_runtime::system::Semilinear;
use std::time::Instant;

fn main() {
    let arg = |i: usize| std::env::args().nth(i);
    let tol: f64 = arg(1).map_or(1e-8, |s| s.parse().expect("a tolerance"));
    let n: usize = arg(2).map_or(100_000, |s| s.parse().expect("a number of outputs"));
    let runs: usize = arg(3).map_or(3, |s| s.parse().expect("a number of runs"));
    let (w, k) = (20.0f64, 0.07);
    let a = Dense::new(DMatrix::from_row_slice(
        2,
        2,
        &[0.0, 1.0, -(w * w + k * k), 0.0],
    ))
    .expect("a finite matrix");
    let g = move |y: &[f64], o: &mut [f64]| {
        o[0] = 0.0;
        o[1] = 2.0 * k * k * y[0] * y[0] * y[0];
    };
    let p = Problem::new(Semilinear::new(a, g), [0.0, w], (0.0, 1000.0)).expect("a problem");
    let mut times: Vec<f64> = (1..=n)
        .map(|i| 1000.0 * ((i as f64 * 0.618_033_988_749_895) % 1.0))
        .collect();
    times.sort_by(f64::total_cmp);
    let best = |opts: &Options| {
        (0..runs)
            .map(|_| {
                let t0 = Instant::now();
                let sol = p.solve(opts).expect("a verified solve");
                (t0.elapsed().as_secs_f64(), sol.stats)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .expect("one run at least")
    };
    let (plain, _) = best(&Options::tolerance(tol));
    let (with, stats) = best(&Options::tolerance(tol).t_eval(times));
    println!(
        "plain {:.1} ms, with {n} t_eval {:.1} ms: {:.2} us per output; (steps, g) between grid points ({}, {})",
        plain * 1e3,
        with * 1e3,
        (with - plain) / n as f64 * 1e6,
        stats.dense_evals,
        stats.dense_g_evals
    );
}
