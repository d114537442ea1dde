//! The error floor of ECrP per r (issue: numerical stability at the extremes), and the
//! conditioning of the moment weights.
//!
//! For r = 1..=12 (s = r and s = r + 2; for r = 12 also s = 16): the smallest global error ECrP reaches on
//! Duffing (ω = 1, k = 0.5, T = 10, exact solution) as h is halved from 1. For context, the
//! size of the φ-form moment weights w_kj = b_j β_k(c_j) (`docs/method.md#moment-form`) and how
//! far their f64 values are from the exact identity Σ_k w_kj/(k+1)! = b_j: large |w_kj| with
//! alternating signs lose digits. The stepper uses the Legendre form instead (moments with
//! weights ℓ_kj = b_j P̃_k(c_j), |ℓ_kj| ≤ b_j, and directly computed kernels; see
//! `ecr_runtime::stepper`), whose floor this table shows. The φ-form floor, for comparison,
//! is what this example printed before the change (commit aa3baab).
//!
//! A second table does the same for TCrP (the ECrP stepper on the second-order form, with the
//! oscillator operator) on Duffing in second-order form, q'' + (ω² + k²) q = 2k² q³ (exact
//! solution), and on the Fermi–Pasta–Ulam chain (m = 3, ω = 50, T = 10; reference: ECrP with
//! r = 8 on the dense first-order form at h = 2⁻¹⁴, a different evaluation of the same flow),
//! errors in the max-norm relative to the largest component.
//!
//! Run: `cargo run --release --example error_floor`.

use ecr::problems::{Duffing, Fpu};
use ecr::runtime::second_order::{Omega, SecondOrder, SecondOrderSystem, TcStepper};
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
    second_order()
}

/// Median relative error of TCrP for h = 2⁻⁹..2⁻¹³ over [0, t_end] against `exact`.
fn tc_floor<S: SecondOrderSystem>(
    sys: &S,
    r: usize,
    y0: &[f64],
    t_end: f64,
    exact: &[f64],
) -> Result<f64, ecr::runtime::Error> {
    let n = y0.len() / 2;
    let scale = exact.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut errs = Vec::new();
    for i in 9..14 {
        let h = 1.0 / 2f64.powi(i);
        let mut st = TcStepper::new(sys, r, h)?;
        let (mut q, mut p) = (y0[..n].to_vec(), y0[n..].to_vec());
        for _ in 0..(t_end / h).round() as usize {
            st.step(&mut q, &mut p)?;
        }
        let err = q
            .iter()
            .chain(&p)
            .zip(exact)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        errs.push(err / scale);
    }
    errs.sort_by(f64::total_cmp);
    Ok(errs[errs.len() / 2])
}

fn second_order() -> Result<(), ecr::runtime::Error> {
    let (w, k) = (1.0, 0.5);
    let duffing = Duffing::new(w, k)?;
    let k2 = k * k;
    let sys = SecondOrder::new(
        Omega::scalar(w * w + k2, 1)?,
        move |q: &[f64], f: &mut [f64]| f[0] = -2.0 * k2 * q[0].powi(3),
    );
    let exact = duffing.exact(10.0)?;
    let fpu = Fpu::new(3, 50.0)?;
    let fpu_sys = fpu.system()?;
    let y0 = fpu.initial_value_first_order();
    let t_fpu = 10.0;
    let h_ref = 1.0 / 2f64.powi(14);
    let mut reference = y0.clone();
    let mut st = EcStepper::with_nodes(
        fpu.first_order_system()?,
        8,
        8,
        h_ref,
        SolverSettings::default(),
    )?;
    for _ in 0..(t_fpu / h_ref).round() as usize {
        st.step(&mut reference)?;
    }
    println!();
    println!(
        "| r | TCrP Duffing (T = 10), median error h = 1/2^9..1/2^13 | TCrP FPU (T = 10), same |"
    );
    println!("|---|---|---|");
    for r in 2..=12usize {
        let d = tc_floor(&sys, r, &duffing.initial_value(), 10.0, &exact)?;
        let f = tc_floor(&fpu_sys, r, &y0, t_fpu, &reference)?;
        println!("| {r} | {d:.2e} | {f:.2e} |");
    }
    Ok(())
}
