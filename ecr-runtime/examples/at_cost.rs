//! What `Solution::at` costs where the grid's interpolant does not serve: Duffing ω = 20,
//! k = 0.07 from (0, ω) over T = 1000 with a dense 2 × 2 linear part, solved to a tolerance
//! with dense output, then `at` at N uneven times (nearly all of which take a partial step of
//! each run, with φ-banks for that step's length).
//!
//! ```text
//! cargo run --release -p ecr-runtime --example at_cost            # ω = 20, tol 1e-8, N = 2000
//! cargo run --release -p ecr-runtime --example at_cost -- 20 1e-8 3000
//! ```
use ecr_runtime::nalgebra::DMatrix;
use ecr_runtime::operator::Dense;
use ecr_runtime::solve::{Options, Problem};
use ecr_runtime::system::Semilinear;
use std::time::Instant;

fn main() {
    let w: f64 = std::env::args().nth(1).map_or(20.0, |s| s.parse().unwrap());
    let tol: f64 = std::env::args().nth(2).map_or(1e-8, |s| s.parse().unwrap());
    let n: usize = std::env::args().nth(3).map_or(2000, |s| s.parse().unwrap());
    // Duffing as in the issue: ω = 20, k = 0.07, y0 = (0, ω), A = [[0, 1], [−ω² − k², 0]],
    // g = (0, 2k²q³).
    let k = 0.07;
    let a = Dense::new(DMatrix::from_row_slice(
        2,
        2,
        &[0.0, 1.0, -(w * w + k * k), 0.0],
    ))
    .unwrap();
    let g = move |y: &[f64], o: &mut [f64]| {
        o[0] = 0.0;
        o[1] = 2.0 * k * k * y[0] * y[0] * y[0];
    };
    let p = Problem::new(Semilinear::new(a, g), [0.0, w], (0.0, 1000.0)).unwrap();
    let t0 = Instant::now();
    let sol = p.solve(&Options::tolerance(tol).dense_output()).unwrap();
    let ts = t0.elapsed().as_secs_f64();
    println!("solve {:.3} s, stats {:?}", ts, sol.stats);
    let times: Vec<f64> = (1..=n)
        .map(|k| 1000.0 * ((k as f64 * 0.618_033_988_749_895) % 1.0))
        .collect();
    let t1 = Instant::now();
    let mut s = 0.0;
    for &t in &times {
        s += sol.at(t).unwrap()[0];
    }
    let el = t1.elapsed().as_secs_f64();
    println!(
        "at: {:.2} us per call (sum of q {s:.3}), (steps, g) between grid points {:?}",
        el / n as f64 * 1e6,
        sol.dense_evaluations()
    );
}
