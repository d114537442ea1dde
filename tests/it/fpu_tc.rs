//! TCrP on the Fermi–Pasta–Ulam problem (stiff springs, GNI XIII.2.1): agreement with ECrP on
//! the first-order form, measured orders, uniform accuracy in ω, the RKNC limit, and energy
//! over a million steps.

use crate::common_ec;

use common_ec::{fitted_order, max_abs_diff};
use ecr::problems::Fpu;
use ecr_runtime::second_order::{Omega, SecondOrder, SecondOrderSystem, TcStepper};
use ecr_runtime::stepper::{EcStepper, SolverSettings};

fn run_tc<S: SecondOrderSystem>(
    sys: S,
    r: usize,
    s: usize,
    h: f64,
    n: usize,
    q0: &[f64],
    p0: &[f64],
) -> (Vec<f64>, Vec<f64>) {
    let mut st = TcStepper::with_nodes(sys, r, s, h, SolverSettings::default()).unwrap();
    let (mut q, mut p) = (q0.to_vec(), p0.to_vec());
    for _ in 0..n {
        st.step(&mut q, &mut p).unwrap();
    }
    (q, p)
}

fn joined(q: &[f64], p: &[f64]) -> Vec<f64> {
    q.iter().chain(p).copied().collect()
}

#[test]
fn tc_equals_ec_on_fpu() {
    let fpu = Fpu::default();
    let (q0, p0) = fpu.initial_value();
    for r in [1, 2, 3] {
        let mut tc = TcStepper::new(fpu.system().unwrap(), r, 0.01).unwrap();
        let mut ec = EcStepper::new(fpu.first_order_system().unwrap(), r, 0.01).unwrap();
        let (mut q, mut p) = (q0.clone(), p0.clone());
        let mut y = joined(&q0, &p0);
        for n in 1..=1000 {
            tc.step(&mut q, &mut p).unwrap();
            ec.step(&mut y).unwrap();
            if n == 1 || n == 1000 {
                let scale = y.iter().fold(1.0f64, |m, x| m.max(x.abs()));
                let rel = max_abs_diff(&joined(&q, &p), &y) / scale;
                println!("FPU TC vs EC, r = {r}, step {n}: {rel:.2e}");
                // Algebraically equal; the two round differently (diagonal Ω vs the dense φ of
                // the 12 × 12 first-order matrix) by a few ulp per step.
                assert!(rel <= 1e-13, "r = {r}, step {n}: {rel:e}");
            }
        }
    }
}

#[test]
fn measured_order_on_fpu() {
    let fpu = Fpu::default();
    let (q0, p0) = fpu.initial_value();
    let t_end = 1.0;
    let (qr, pr) = run_tc(fpu.system().unwrap(), 7, 7, t_end / 512.0, 512, &q0, &p0);
    let exact = joined(&qr, &pr);
    for (r, n0) in [(1usize, 200usize), (2, 40), (3, 16), (4, 8), (5, 6)] {
        let mut pts = Vec::new();
        let mut last = 0;
        for i in 0..40 {
            let n = (n0 as f64 * 2f64.powf(i as f64 / 8.0)).round() as usize;
            if n == last {
                continue;
            }
            last = n;
            let (q, p) = run_tc(fpu.system().unwrap(), r, r, t_end / n as f64, n, &q0, &p0);
            let e = max_abs_diff(&joined(&q, &p), &exact);
            if e > 30.0 * n as f64 * f64::EPSILON && e < 1e-4 {
                pts.push((t_end / n as f64, e));
            }
        }
        let tail = &pts[pts.len().saturating_sub(8)..];
        let (hs, es): (Vec<f64>, Vec<f64>) = tail.iter().copied().unzip();
        let (o, k) = fitted_order(&hs, &es, 0.0, f64::INFINITY);
        println!(
            "FPU r = {r}: order {o:.3} ({k} points, errors {:.1e}..{:.1e})",
            es.first().unwrap_or(&0.0),
            es.last().unwrap_or(&0.0)
        );
        assert!(
            k >= 4 && (o - 2.0 * r as f64).abs() <= 0.15,
            "r = {r}: order {o}"
        );
    }
}

#[test]
fn uniform_accuracy_in_omega() {
    // Fixed h = 0.01 on [0, 0.1] while ω grows from 10 to 1e6 (hω from 0.1 to 1e4); the stiff
    // springs carry energy O(1) (x₁,₁(0) = 1/ω). The reference resolves ω: r = 5 with
    // h_ref ≤ 0.5/ω, and is checked against the run with twice its step.
    let (h, n) = (0.01, 10);
    let t_end = h * n as f64;
    for r in [1, 2, 3] {
        let mut line = format!("r = {r}, h = {h}, T = {t_end}:");
        let mut errs = Vec::new();
        for omega in [10.0, 1e2, 1e3, 1e4, 1e5, 1e6] {
            let fpu = Fpu::new(3, omega).unwrap();
            let (q0, p0) = fpu.initial_value();
            let (q, p) = run_tc(fpu.system().unwrap(), r, r, h, n, &q0, &p0);
            let n_ref = ((t_end * omega / 0.5).ceil() as usize).max(8 * n);
            let n_ref = n_ref + n_ref % 2;
            let (qr, pr) = run_tc(
                fpu.system().unwrap(),
                5,
                5,
                t_end / n_ref as f64,
                n_ref,
                &q0,
                &p0,
            );
            let (qs, ps) = run_tc(
                fpu.system().unwrap(),
                5,
                5,
                2.0 * t_end / n_ref as f64,
                n_ref / 2,
                &q0,
                &p0,
            );
            let e = max_abs_diff(&q, &qr).max(max_abs_diff(&p, &pr));
            let e_ref = max_abs_diff(&qs, &qr).max(max_abs_diff(&ps, &pr));
            assert!(
                e_ref <= 1e-2 * e.max(1e-12),
                "reference not converged at ω = {omega}: {e_ref:e} vs {e:e}"
            );
            line += &format!(" ω={omega:.0e}: {e:.2e}");
            errs.push(e);
        }
        println!("{line}");
        // Bounded uniformly in ω, and not growing as ω → ∞.
        let first = errs[0];
        assert!(errs.iter().all(|&e| e <= 1e-2), "r = {r}: {errs:?}");
        assert!(
            errs[5] <= 10.0 * errs[3].max(first),
            "r = {r}: error grows with ω: {errs:?}"
        );
    }
}

#[test]
fn rknc_limit_is_continuous() {
    // Ω = ε² I → 0: TCrP tends to RKNCrP with a difference O(ε² t²), no loss of digits.
    let force = |q: &[f64], f: &mut [f64]| {
        f[0] = q[0].powi(3) + q[1];
        f[1] = q[1].powi(3) + q[0];
    };
    let (q0, p0) = ([0.4, -0.3], [0.2, 0.5]);
    let (qz, pz) = run_tc(
        SecondOrder::new(Omega::zero(2), force),
        3,
        3,
        0.05,
        20,
        &q0,
        &p0,
    );
    for eps in [1e-2f64, 1e-4, 1e-6, 1e-8, 1e-12] {
        let (q, p) = run_tc(
            SecondOrder::new(Omega::scalar(eps * eps, 2).unwrap(), force),
            3,
            3,
            0.05,
            20,
            &q0,
            &p0,
        );
        let d = max_abs_diff(&joined(&q, &p), &joined(&qz, &pz));
        println!("ε = {eps:.0e}: |TC − RKNC| = {d:.2e}");
        assert!(d <= eps * eps * 4.0 + 1e-15, "ε = {eps}: {d:e}");
    }
}

#[test]
fn energy_on_fpu() {
    let fpu = Fpu::default();
    let (q0, p0) = fpu.initial_value();
    let h0 = fpu.energy(&q0, &p0);
    for r in [1, 2, 3] {
        let mut line = format!("FPU energy r = {r}:");
        let mut errs = Vec::new();
        for h in [0.04, 0.02, 0.01, 0.005] {
            let mut st = TcStepper::new(fpu.system().unwrap(), r, h).unwrap();
            let (mut q, mut p) = (q0.clone(), p0.clone());
            let mut max = 0.0f64;
            for _ in 0..(100.0 / h) as usize {
                st.step(&mut q, &mut p).unwrap();
                max = max.max((fpu.energy(&q, &p) - h0).abs() / h0);
            }
            line += &format!(" h={h}: {max:.2e}");
            errs.push(max);
        }
        println!("{line}");
        let (o, _) = fitted_order(&[0.04, 0.02, 0.01, 0.005], &errs, 1e-12, 1.0);
        println!("  slope {o:.3}");
        assert!(
            (o - 2.0 * r as f64).abs() <= 0.35,
            "r = {r}: energy slope {o}"
        );
    }
}

/// Max relative energy error and per-window means over `n` steps.
fn long_run(r: usize, h: f64, n: usize) -> (f64, Vec<f64>) {
    let fpu = Fpu::default();
    let (mut q, mut p) = fpu.initial_value();
    let h0 = fpu.energy(&q, &p);
    let mut st = TcStepper::new(fpu.system().unwrap(), r, h).unwrap();
    let (mut max, w) = (0.0f64, n / 10);
    let mut means = vec![0.0; 10];
    for k in 0..n {
        st.step(&mut q, &mut p).unwrap();
        let e = (fpu.energy(&q, &p) - h0) / h0;
        max = max.max(e.abs());
        means[k / w] += e / w as f64;
    }
    (max, means)
}

#[test]
fn energy_over_one_million_fpu_steps() {
    // r = 2, h = 0.01 (hω = 0.5), t ∈ [0, 1e4]: the error stays at the level the method has
    // over t ≤ 100 (1.5e-7, see energy_on_fpu). Its slow modulation (energy exchange between
    // the stiff springs) moves the window means by ~1e-8 either way depending on h: that is
    // the method's bounded error, not drift.
    let (max, means) = long_run(2, 0.01, 1_000_000);
    println!("FPU r = 2, h = 0.01, 1e6 steps: max {max:.3e}, window means {means:?}");
    assert!(max <= 2.0 * 1.6e-7, "max {max:e}");
    // r = 3, h = 0.01: the method's error is ~1e-10, so a trend in the window means is
    // round-off: (last − first)/steps must be at most ε per step.
    let (max3, means3) = long_run(3, 0.01, 1_000_000);
    let drift = (means3[9] - means3[0]) / 900_000.0;
    println!("FPU r = 3, h = 0.01, 1e6 steps: max {max3:.3e}, drift per step {drift:.2e}");
    assert!(drift.abs() <= f64::EPSILON, "drift {drift:e} per step");
}
