//! What a φ-bank costs (issue 51, item 2): one step of `Options::fixed(r, 0.1)` from a fresh
//! `Problem` (about one kernel-bank build: the stage nodes, τ = 1 with its double-double
//! propagator, and the predictor's nodes), g = −y³, for a `Dense` A that is symmetric (the
//! periodic second difference), the same matrix through `Symmetric`, and a non-normal `Dense`
//! (the bidiagonal-plus stencil −3 on, 2 below, 1 above the diagonal, not periodic), at
//! d = 2, 16, 64 and r = 2, 4, 6, 8. The fastest of 20 runs each (single-threaded: on a
//! machine quiet for one round it is the CPU time). `cargo bench --bench bank_build`.

use ecr::runtime::operator::{Dense, LinearOperator, Symmetric};
use ecr::runtime::solve::{Options, Problem};
use ecr::runtime::system::Semilinear;
use nalgebra::DMatrix;
use std::time::Instant;

/// The periodic second difference (symmetric).
fn laplacian(d: usize) -> DMatrix<f64> {
    DMatrix::from_fn(d, d, |i, j| {
        if i == j {
            -2.0
        } else if (i + 1) % d == j || (j + 1) % d == i {
            1.0
        } else {
            0.0
        }
    })
}

/// −3 on the diagonal, 2 below and 1 above it (not periodic: non-normal).
fn nonnormal(d: usize) -> DMatrix<f64> {
    DMatrix::from_fn(d, d, |i, j| {
        if i == j {
            -3.0
        } else if i == j + 1 {
            2.0
        } else if j == i + 1 {
            1.0
        } else {
            0.0
        }
    })
}

/// The fastest of `rounds` timings of one step of EC(r)P, h = 0.1, the operator made by
/// `make` inside the timing (a fresh operator: nothing cached from the previous round).
fn one_step<A: LinearOperator>(rounds: usize, d: usize, r: usize, make: impl Fn() -> A) -> f64 {
    let y0: Vec<f64> = (0..d).map(|i| (i as f64 * 0.3).sin()).collect();
    let mut best = f64::INFINITY;
    for _ in 0..rounds {
        let start = Instant::now();
        let system = Semilinear::new(make(), |y: &[f64], g: &mut [f64]| {
            for (g, y) in g.iter_mut().zip(y) {
                *g = -y * y * y;
            }
        });
        let problem = Problem::new(system, y0.clone(), (0.0, 0.1)).expect("problem");
        let sol = problem.solve(&Options::fixed(r, 0.1)).expect("one step");
        std::hint::black_box(sol);
        best = best.min(start.elapsed().as_secs_f64());
    }
    best
}

/// One row of the table: the fastest time of one step for an order r.
type Timing = Box<dyn Fn(usize) -> f64>;

fn main() {
    // `cargo bench` passes `--bench`; no other arguments.
    let rounds = 20;
    println!("one step of Options::fixed(r, 0.1), fastest of {rounds} (ms)");
    println!(
        "{:<22} {:>4} {:>9} {:>9} {:>9} {:>9}",
        "operator", "d", "r=2", "r=4", "r=6", "r=8"
    );
    for d in [2usize, 16, 64] {
        let rows: [(&str, Timing); 3] = [
            (
                "Dense (symmetric)",
                Box::new(move |r| {
                    one_step(rounds, d, r, || Dense::new(laplacian(d)).expect("dense"))
                }),
            ),
            (
                "Symmetric",
                Box::new(move |r| {
                    one_step(rounds, d, r, || {
                        Symmetric::new(laplacian(d)).expect("symmetric")
                    })
                }),
            ),
            (
                "Dense (non-normal)",
                Box::new(move |r| {
                    one_step(rounds, d, r, || Dense::new(nonnormal(d)).expect("dense"))
                }),
            ),
        ];
        for (name, f) in rows {
            let t: Vec<String> = [2, 4, 6, 8]
                .iter()
                .map(|&r| format!("{:9.3}", f(r) * 1e3))
                .collect();
            println!("{name:<22} {d:>4} {}", t.join(" "));
        }
    }
}
