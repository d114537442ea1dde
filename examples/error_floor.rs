//! The error floor of ECrP per r (issue: numerical stability at the extremes), and the
//! conditioning of the moment weights.
//!
//! For r = 1..=12 (s = r and s = r + 2; for r = 12 also s = 16): the smallest global error ECrP reaches on
//! Duffing (ω = 1, k = 0.5, T = 10, exact solution) as h is halved from 1. For context, the
//! size of the φ-form moment weights w_kj = b_j β_k(c_j) of DESIGN.md §2 and how far their
//! f64 values are from the exact identity Σ_k w_kj/(k+1)! = b_j: large |w_kj| with
//! alternating signs lose digits. The stepper uses the Legendre form instead (moments with
//! weights ℓ_kj = b_j P̃_k(c_j), |ℓ_kj| ≤ b_j, and directly computed kernels; see
//! `ecr_runtime::stepper`), whose floor this table shows. The φ-form floor, for comparison,
//! is what this example printed before the change (commit aa3baab).
//!
//! Run: `cargo run --release --example error_floor`.

use ecr::runtime::problems::Duffing;
use ecr::runtime::stepper::{EcStepper, RuntimeKernel, SolverSettings};

fn main() -> Result<(), ecr::runtime::Error> {
    let p = Duffing::new(1.0, 0.5)?;
    let t_end = 10.0;
    let exact = p.exact(t_end)?;
    println!(
        "| r | s | min error over h = 1/2^i, i < 14 | at h | median error, h = 1/2^9..1/2^13 | max abs w_kj | max rel. error of sum_k w_kj/(k+1)! vs b_j | max abs l_kj |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for r in 1..=12usize {
        let points: &[usize] = if r == 12 { &[12, 14, 16] } else { &[r, r + 2] };
        for &s in points {
            let kernel = RuntimeKernel::new(r, s)?;
            let c = kernel.coefficients();
            let mut weight_err = 0.0f64;
            for j in 0..s {
                // Σ_k w_kj/(k+1)! accumulated in f64, as the stepper's A = 0 update does.
                let (mut sum, mut fact) = (0.0, 1.0);
                for k in 0..r {
                    fact *= (k + 1) as f64;
                    sum += c.w[k * s + j] / fact;
                }
                weight_err = weight_err.max(((sum - c.weights[j]) / c.weights[j]).abs());
            }
            let wmax = c.w.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let lmax = c.lw.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let (mut best, mut best_h) = (f64::INFINITY, 0.0);
            let mut smallest_h = Vec::new();
            let mut failures = Vec::new();
            for i in 0..14 {
                let h = 1.0 / 2f64.powi(i);
                let mut st =
                    EcStepper::with_nodes(p.system()?, r, s, h, SolverSettings::default())?;
                let mut y = p.initial_value();
                let n = (t_end / h).round() as usize;
                if let Err(e) = (0..n).try_for_each(|_| st.step(&mut y).map(|_| ())) {
                    failures.push(format!("h = 1/{}: {e}", 1u64 << i));
                    continue;
                }
                let err = y
                    .iter()
                    .zip(&exact)
                    .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
                if i >= 9 {
                    smallest_h.push(err);
                }
                if err < best {
                    best = err;
                    best_h = h;
                }
            }
            smallest_h.sort_by(f64::total_cmp);
            let median = smallest_h
                .get(smallest_h.len() / 2)
                .copied()
                .unwrap_or(f64::NAN);
            println!(
                "| {r} | {s} | {best:.2e} | {best_h} | {median:.2e} | {wmax:.3e} | {weight_err:.2e} | {lmax:.3} |"
            );
            for f in failures {
                println!("|   |   | failed: {f} | | | | | |");
            }
        }
    }
    Ok(())
}
