//! The strong peer methods (issue 14): splittings with the exact linear flow, composed
//! Störmer–Verlet, split-step Fourier and ETDRK4. Measured orders (least-squares slope of
//! log(error) vs log(h) over points clear of the round-off floor, within 0.15 of nominal),
//! what each method conserves and what it does not, FSAL bookkeeping, allocation-free steps
//! and input validation. Run with `--nocapture` to see the measured numbers.

use std::f64::consts::PI;

use crate::counting::allocations;

use ecr::baselines::etdrk4::Etdrk4;
use ecr::baselines::split_step::SplitStep;
use ecr::baselines::splitting::{
    LinearFlowSplitting, RotationSplitting, StormerVerlet, composition,
};
use ecr::problems::{Duffing, Nls};
use ecr_runtime::Error;
use ecr_runtime::integrate::{IntegrateOptions, Integrator, integrate};
use ecr_runtime::operator::Dense;
use ecr_runtime::second_order::{Omega, SecondOrder, SecondOrderSystem};
use ecr_runtime::stepper::EcStepper;
use ecr_runtime::system::{Semilinear, System};

// ---------------------------------------------------------------------------------------------
// Helpers.

/// The Duffing problem used for the orders: ω = 1, k = 0.9 (m = 0.81, a strongly nonlinear
/// oscillation, so that the splitting errors are far above round-off).
fn duffing() -> Duffing {
    Duffing::new(1.0, 0.9).unwrap()
}

/// Duffing as q'' = −(ω² + k²)q + 2k²q³: Ω = ω² + k², ∇U = −2k²q³, U = −k²q⁴/2.
struct DuffingSecondOrder {
    omega: Omega,
    k2: f64,
}

impl SecondOrderSystem for DuffingSecondOrder {
    fn omega(&self) -> &Omega {
        &self.omega
    }
    fn force(&self, q: &[f64], out: &mut [f64]) {
        out[0] = -2.0 * self.k2 * q[0].powi(3);
    }
    fn potential(&self, q: &[f64]) -> Option<f64> {
        Some(-0.5 * self.k2 * q[0].powi(4))
    }
}

fn duffing_second_order(d: &Duffing) -> DuffingSecondOrder {
    let k2 = d.k() * d.k();
    DuffingSecondOrder {
        omega: Omega::scalar(d.omega() * d.omega() + k2, 1).unwrap(),
        k2,
    }
}

fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// `n` steps of size T/n from y0 through [`integrate`].
fn run<I: Integrator>(method: &mut I, y0: &[f64], t_end: f64, n: usize) -> Vec<f64> {
    method.set_step_size(t_end / n as f64).unwrap();
    let mut y = y0.to_vec();
    let options = IntegrateOptions {
        energy_every: 0,
        observe_every: 0,
    };
    let report = integrate(method, 0.0, t_end, &mut y, options, |_, _, _| {}).unwrap();
    assert_eq!(report.steps, n);
    y
}

/// Least-squares slope of log(err) against log(h) over the points with err > floor; panics
/// if fewer than three points remain.
fn measured_order(hs: &[f64], errs: &[f64], floor: f64) -> f64 {
    let pts: Vec<(f64, f64)> = hs
        .iter()
        .zip(errs)
        .filter(|&(_, &e)| e > floor)
        .map(|(&h, &e)| (h.ln(), e.ln()))
        .collect();
    assert!(
        pts.len() >= 3,
        "only {} points above the floor {floor:e}: {errs:?}",
        pts.len()
    );
    slope(&pts)
}

fn sci(v: &[f64]) -> String {
    let parts: Vec<String> = v.iter().map(|x| format!("{x:.2e}")).collect();
    format!("[{}]", parts.join(", "))
}

fn slope(pts: &[(f64, f64)]) -> f64 {
    let n = pts.len() as f64;
    let (mx, my) = pts
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let sxy: f64 = pts.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = pts.iter().map(|(x, _)| (x - mx) * (x - mx)).sum();
    sxy / sxx
}

/// Errors at T for the step counts `ns`, measured by `error(n)`; prints and checks the order.
fn check_order(
    name: &str,
    nominal: f64,
    t_end: f64,
    ns: &[usize],
    mut error: impl FnMut(usize) -> f64,
) {
    let hs: Vec<f64> = ns.iter().map(|&n| t_end / n as f64).collect();
    let errs: Vec<f64> = ns.iter().map(|&n| error(n)).collect();
    // Round-off floor: errors below 1e-12 (≈ 4500 ε for solutions of size ~1) are not used.
    let order = measured_order(&hs, &errs, 1e-12);
    println!(
        "{name}: measured order {order:.3} (nominal {nominal}); h = {}, err = {}",
        sci(&hs),
        sci(&errs)
    );
    assert!(
        (order - nominal).abs() <= 0.15,
        "{name}: measured order {order:.3}, nominal {nominal}; errors {errs:?}"
    );
}

// ---------------------------------------------------------------------------------------------
// Measured orders.

#[test]
fn linear_flow_splitting_orders_on_duffing() {
    let d = duffing();
    let t_end = 2.0;
    let exact = d.exact(t_end).unwrap();
    let y0 = d.initial_value();
    for (order, ns) in [
        (2, [16, 32, 64, 128, 256]),
        (4, [8, 16, 32, 64, 128]),
        (6, [4, 8, 16, 32, 64]),
        (8, [8, 12, 16, 20, 24]),
    ] {
        let mut m = LinearFlowSplitting::new(d.system().unwrap(), order, 0.1).unwrap();
        check_order(
            &format!("LinearFlowSplitting order {order}"),
            order as f64,
            t_end,
            &ns,
            |n| max_diff(&run(&mut m, &y0, t_end, n), &exact),
        );
    }
}

/// The scalar-rotation form: the same orders, and the same method as the φ-bank form on the
/// first-order system (their steps differ only by the rounding of the rotations), with FSAL
/// counts, a bounded energy error and a diagonal Ω required.
#[test]
fn rotation_splitting_orders_agreement_and_energy() {
    let d = duffing();
    let t_end = 2.0;
    let exact = d.exact(t_end).unwrap();
    let y0 = d.initial_value();
    for (order, ns) in [
        (2, [16, 32, 64, 128, 256]),
        (4, [8, 16, 32, 64, 128]),
        (6, [4, 8, 16, 32, 64]),
        (8, [8, 12, 16, 20, 24]),
    ] {
        let mut m = RotationSplitting::new(duffing_second_order(&d), order, 0.1).unwrap();
        check_order(
            &format!("RotationSplitting order {order}"),
            order as f64,
            t_end,
            &ns,
            |n| max_diff(&run(&mut m, &y0, t_end, n), &exact),
        );
        let mut lfs = LinearFlowSplitting::new(d.system().unwrap(), order, 0.1).unwrap();
        let diff = max_diff(&run(&mut m, &y0, t_end, 20), &run(&mut lfs, &y0, t_end, 20));
        assert!(
            diff < 1e-13,
            "order {order}: {diff:e} from LinearFlowSplitting"
        );
        // FSAL: 10 steps cost 10 s + 1 evaluations of ∇U.
        let mut fresh = RotationSplitting::new(duffing_second_order(&d), order, 0.01).unwrap();
        let mut y = y0.clone();
        let evals: usize = (0..10).map(|_| fresh.step(&mut y).unwrap().g_evals).sum();
        assert_eq!(evals, 10 * composition(order).unwrap().len() + 1);
    }
    let mut m = RotationSplitting::new(duffing_second_order(&d), 4, 0.1).unwrap();
    let (max, ratio, _) = energy_windows(&mut m, &y0, 0.1, 100_000);
    println!("RotationSplitting order 4: max |ΔH| {max:.2e}, last/first window {ratio:.3}");
    assert!(max < 1e-3 && ratio < 1.5, "{max:e} {ratio}");
    let dense = SecondOrder::new(
        Omega::dense(nalgebra::DMatrix::from_row_slice(
            2,
            2,
            &[2.0, 1.0, 1.0, 2.0],
        ))
        .unwrap(),
        |_: &[f64], f: &mut [f64]| f.fill(0.0),
    );
    assert!(matches!(
        RotationSplitting::new(dense, 2, 0.1),
        Err(Error::InvalidParameter(_))
    ));
}

#[test]
fn stormer_verlet_orders_on_second_order_duffing() {
    let d = duffing();
    let t_end = 2.0;
    let exact = d.exact(t_end).unwrap();
    let y0 = d.initial_value(); // (q, p) = (0, ω)
    for (order, ns) in [
        (2, [16, 32, 64, 128, 256]),
        (4, [16, 32, 64, 128, 256]),
        (6, [8, 16, 32, 64, 128]),
        (8, [8, 12, 16, 24, 32]),
    ] {
        let mut m = StormerVerlet::new(duffing_second_order(&d), order, 0.1).unwrap();
        check_order(
            &format!("StormerVerlet order {order}"),
            order as f64,
            t_end,
            &ns,
            |n| max_diff(&run(&mut m, &y0, t_end, n), &exact),
        );
    }
}

#[test]
fn etdrk4_order_on_duffing() {
    let d = duffing();
    let t_end = 2.0;
    let exact = d.exact(t_end).unwrap();
    let y0 = d.initial_value();
    let mut m = Etdrk4::new(d.system().unwrap(), 0.1).unwrap();
    check_order("ETDRK4", 4.0, t_end, &[16, 32, 64, 128, 256], |n| {
        max_diff(&run(&mut m, &y0, t_end, n), &exact)
    });
}

/// NLS on N = 32 points from a non-trivial initial value (|ψ| not constant, several modes):
/// p = 0.5 + 0.3 cos(μx), q = 0.2 sin(2μx).
fn nls_problem() -> (Nls, Vec<f64>) {
    let nls = Nls::new(32).unwrap();
    let n = nls.n();
    let mut y = vec![0.0; 2 * n];
    for j in 0..n {
        let x = 2.0 * PI * j as f64 / n as f64; // μ x_j
        y[j] = 0.5 + 0.3 * x.cos();
        y[n + j] = 0.2 * (2.0 * x).sin();
    }
    (nls, y)
}

/// The NLS solution at T by ECrP (r = 4, order 8) with 400 steps: an independent reference
/// (its own error, checked against 800 steps, is below 1e-13).
fn nls_reference(nls: &Nls, y0: &[f64], t_end: f64, steps: usize) -> Vec<f64> {
    let mut ec = EcStepper::new(nls.system().unwrap(), 4, t_end / steps as f64).unwrap();
    let mut y = y0.to_vec();
    for _ in 0..steps {
        ec.step(&mut y).unwrap();
    }
    y
}

#[test]
fn split_step_orders_on_nls() {
    let (nls, y0) = nls_problem();
    let t_end = 1.0;
    let reference = nls_reference(&nls, &y0, t_end, 400);
    let check = nls_reference(&nls, &y0, t_end, 800);
    let ref_err = max_diff(&reference, &check);
    println!("NLS reference: ECrP r = 4, 400 vs 800 steps differ by {ref_err:.2e}");
    assert!(ref_err < 1e-13, "reference not converged: {ref_err:e}");
    for (order, ns) in [
        (2, [16, 32, 64, 128, 256]),
        (4, [8, 16, 32, 64, 128]),
        (6, [8, 16, 24, 32, 48]),
        (8, [16, 20, 24, 28, 32]),
    ] {
        let mut m = SplitStep::nls(nls.system().unwrap(), order, 0.1).unwrap();
        check_order(
            &format!("SplitStep order {order}"),
            order as f64,
            t_end,
            &ns,
            |n| max_diff(&run(&mut m, &y0, t_end, n), &reference),
        );
    }
}

// ---------------------------------------------------------------------------------------------
// What the methods conserve.

/// |H(y_n) − H(y_0)| over n steps of size h, reduced to the maxima over 10 windows of equal
/// length; returns (overall max, last window max / first window max, least-squares slope of
/// the window maxima against time).
fn energy_windows<I: Integrator>(method: &mut I, y0: &[f64], h: f64, n: usize) -> (f64, f64, f64) {
    method.set_step_size(h).unwrap();
    let mut y = y0.to_vec();
    let e0 = method.energy_of(&y).unwrap();
    let mut windows = [0.0f64; 10];
    for i in 0..n {
        method.step_state(&mut y).unwrap();
        let e = (method.energy_of(&y).unwrap() - e0).abs();
        let w = &mut windows[i * 10 / n];
        *w = w.max(e);
    }
    let t_end = h * n as f64;
    let pts: Vec<(f64, f64)> = windows
        .iter()
        .enumerate()
        .map(|(k, &m)| ((k as f64 + 0.5) * t_end / 10.0, m))
        .collect();
    let max = windows.iter().copied().fold(0.0, f64::max);
    (max, windows[9] / windows[0], slope(&pts))
}

/// Symplectic splittings: the energy error over 1e5 steps (T = 1e4, ~2000 periods) stays
/// bounded, with no drift: the last tenth's maximum is within a factor 1.5 of the first
/// tenth's (a quasi-periodic error has the same envelope in every window). ETDRK4 on the same
/// run drifts (ratio ≈ 19, linear growth), so the check can fail.
#[test]
fn splittings_have_bounded_energy_error_and_etdrk4_drifts() {
    let d = duffing();
    let y0 = d.initial_value();
    let (h, n) = (0.1, 100_000);
    for order in [2, 4] {
        let mut m = LinearFlowSplitting::new(d.system().unwrap(), order, h).unwrap();
        let (max, ratio, slope) = energy_windows(&mut m, &y0, h, n);
        println!(
            "LinearFlowSplitting order {order}: max |ΔH| {max:.2e}, last/first window {ratio:.3}, slope {slope:.2e}"
        );
        assert!(
            (1.0 / 1.5..=1.5).contains(&ratio),
            "order {order}: drift ratio {ratio}"
        );
        let mut v = StormerVerlet::new(duffing_second_order(&d), order, h).unwrap();
        let (max, ratio, slope) = energy_windows(&mut v, &y0, h, n);
        println!(
            "StormerVerlet order {order}: max |ΔH| {max:.2e}, last/first window {ratio:.3}, slope {slope:.2e}"
        );
        assert!(
            (1.0 / 1.5..=1.5).contains(&ratio),
            "order {order}: drift ratio {ratio}"
        );
    }
    let mut e = Etdrk4::new(d.system().unwrap(), h).unwrap();
    let (max, ratio, slope) = energy_windows(&mut e, &y0, h, n);
    println!("ETDRK4: max |ΔH| {max:.2e}, last/first window {ratio:.3}, slope {slope:.2e}");
    assert!(
        ratio > 5.0,
        "ETDRK4 energy error expected to drift: ratio {ratio}"
    );
}

/// Split-step: both substeps are unitary, so the mass Σ|ψ|² changes by round-off only. The
/// unit factors are rounded (|cos θ + i sin θ|² = 1 + O(ε), and the same for the bank's
/// e^{iτhλ}), and because the same factors recur step after step the rounding is partly
/// systematic: the error accumulates linearly. Measured after n = 1e4 steps (h = 0.01, N = 32):
/// 1.1e−13, 2.6e−12, 4.3e−12, 8.3e−12 (orders 2, 4, 6, 8); ETDRK4 5.8e−6. The per-step change is within the ~2e−15 noise of
/// evaluating Σ|ψ|² itself. Asserted: below (2m + 1)·n·ε, i.e. less than one ulp of relative
/// change per substep (2m + 1 substeps per step). ETDRK4 on the same run exceeds the order-2
/// bound by orders of magnitude, so the check can fail.
#[test]
fn split_step_conserves_mass_and_etdrk4_does_not() {
    let (nls, y0) = nls_problem();
    let mass = |y: &[f64]| y.iter().map(|v| v * v).sum::<f64>();
    let m0 = mass(&y0);
    let (h, n) = (0.01, 10_000);
    let max_mass_error = |method: &mut dyn FnMut(&mut [f64])| {
        let mut y = y0.clone();
        let (mut worst, mut step_worst, mut prev) = (0.0f64, 0.0f64, m0);
        for _ in 0..n {
            method(&mut y);
            let m = mass(&y);
            worst = worst.max((m - m0).abs() / m0);
            step_worst = step_worst.max((m - prev).abs() / m0);
            prev = m;
        }
        println!(
            "   per-step max {:.2e}, final {:.2e}",
            step_worst,
            (prev - m0) / m0
        );
        worst
    };
    for (order, linear_substeps) in [(2, 1), (4, 6), (6, 9), (8, 15)] {
        let mut m = SplitStep::nls(nls.system().unwrap(), order, h).unwrap();
        let err = max_mass_error(&mut |y| {
            m.step(y).unwrap();
        });
        let bound = (2 * linear_substeps + 1) as f64 * n as f64 * f64::EPSILON;
        println!(
            "SplitStep order {order}: max relative mass error over {n} steps {err:.2e} (bound {bound:.1e})"
        );
        assert!(
            err <= bound,
            "order {order}: mass error {err:e} > {bound:e}"
        );
    }
    let mut e = Etdrk4::new(nls.system().unwrap(), h).unwrap();
    let err = max_mass_error(&mut |y| {
        e.step(y).unwrap();
    });
    println!("ETDRK4: max relative mass error over {n} steps {err:.2e}");
    assert!(
        err > 100.0 * 3.0 * n as f64 * f64::EPSILON,
        "ETDRK4 mass error unexpectedly small: {err:e}"
    );
}

/// With g = 0 (Duffing with k = 0: y' = Ay, y = (sin 5t, 5 cos 5t)) the splitting and ETDRK4
/// are the exact flow: after 1000 steps only round-off remains (≤ 1e−12 against |y| = 5; the
/// order-2 splitting error with g ≠ 0 at this h would be ~1e−5).
#[test]
fn linear_problems_are_integrated_exactly() {
    let d = Duffing::new(5.0, 0.0).unwrap();
    let y0 = d.initial_value();
    let t_end = 10.0;
    let exact = d.exact(t_end).unwrap();
    for order in [2, 4, 6, 8] {
        let mut m = LinearFlowSplitting::new(d.system().unwrap(), order, 0.01).unwrap();
        let err = max_diff(&run(&mut m, &y0, t_end, 1000), &exact);
        println!("g = 0, LinearFlowSplitting order {order}: error {err:.2e}");
        assert!(err <= 1e-12, "order {order}: {err:e}");
    }
    let mut e = Etdrk4::new(d.system().unwrap(), 0.01).unwrap();
    let err = max_diff(&run(&mut e, &y0, t_end, 1000), &exact);
    println!("g = 0, ETDRK4: error {err:.2e}");
    assert!(err <= 1e-12, "ETDRK4: {err:e}");
}

// ---------------------------------------------------------------------------------------------
// FSAL bookkeeping, golden evaluation counts, allocation-free steps.

/// g-evaluations per step: s (FSAL) plus one on the first step; a state other than the last
/// result (compared bit for bit) pays the extra evaluation again and gives the same result as
/// a fresh method.
#[test]
fn fsal_counts_and_invalidation() {
    // Ten steps of a power of two end exactly at 10h (a last step that differs from h by an
    // ulp is a new step size, which drops SplitStep's carried phases).
    const H: f64 = 1.0 / 128.0;
    let d = duffing();
    let y0 = d.initial_value();
    let options = IntegrateOptions::default();
    for order in [2, 4, 6, 8] {
        let s = composition(order).unwrap().len();
        let mut m = LinearFlowSplitting::new(d.system().unwrap(), order, H).unwrap();
        let mut y = y0.clone();
        let rep = integrate(&mut m, 0.0, 10.0 * H, &mut y, options, |_, _, _| {}).unwrap();
        assert_eq!(rep.g_evals, 10 * s + 1, "LinearFlowSplitting order {order}");
        y[0] += 1e-3;
        let mut fresh = LinearFlowSplitting::new(d.system().unwrap(), order, H).unwrap();
        let mut z = y.clone();
        assert_eq!(m.step(&mut y).unwrap().g_evals, s + 1);
        fresh.step(&mut z).unwrap();
        assert_eq!(
            y, z,
            "LinearFlowSplitting order {order}: stale FSAL value used"
        );
        assert_eq!(m.step(&mut y).unwrap().g_evals, s);

        let mut v = StormerVerlet::new(duffing_second_order(&d), order, H).unwrap();
        let mut y = y0.clone();
        let rep = integrate(&mut v, 0.0, 10.0 * H, &mut y, options, |_, _, _| {}).unwrap();
        assert_eq!(rep.g_evals, 10 * s + 1, "StormerVerlet order {order}");
        y[0] += 1e-3;
        let mut fresh = StormerVerlet::new(duffing_second_order(&d), order, H).unwrap();
        let mut z = y.clone();
        assert_eq!(v.step(&mut y).unwrap().g_evals, s + 1);
        fresh.step(&mut z).unwrap();
        assert_eq!(y, z, "StormerVerlet order {order}: stale FSAL value used");
    }
    let (nls, y0) = nls_problem();
    for (order, m_sub) in [(2, 1), (4, 6), (6, 9), (8, 15)] {
        let mut m = SplitStep::nls(nls.system().unwrap(), order, H).unwrap();
        let mut y = y0.clone();
        let rep = integrate(&mut m, 0.0, 10.0 * H, &mut y, options, |_, _, _| {}).unwrap();
        assert_eq!(rep.g_evals, 10 * m_sub + 1, "SplitStep order {order}");
        y[3] += 1e-3;
        let mut fresh = SplitStep::nls(nls.system().unwrap(), order, H).unwrap();
        let mut z = y.clone();
        assert_eq!(m.step(&mut y).unwrap().g_evals, m_sub + 1);
        fresh.step(&mut z).unwrap();
        assert_eq!(y, z, "SplitStep order {order}: stale FSAL phases used");
    }
    let mut e = Etdrk4::new(d.system().unwrap(), H).unwrap();
    let mut y = duffing().initial_value();
    let rep = integrate(&mut e, 0.0, 10.0 * H, &mut y, options, |_, _, _| {}).unwrap();
    assert_eq!(rep.g_evals, 40);
}

#[test]
fn steps_allocate_nothing() {
    let d = duffing();
    let y0 = d.initial_value();
    let (nls, z0) = nls_problem();
    let mut lfs = LinearFlowSplitting::new(d.system().unwrap(), 8, 0.01).unwrap();
    let mut sv = StormerVerlet::new(duffing_second_order(&d), 8, 0.01).unwrap();
    let mut et = Etdrk4::new(d.system().unwrap(), 0.01).unwrap();
    let mut ss = SplitStep::nls(nls.system().unwrap(), 4, 0.01).unwrap();
    let mut et_nls = Etdrk4::new(nls.system().unwrap(), 0.01).unwrap();
    let (mut a, mut b, mut c) = (y0.clone(), y0.clone(), y0.clone());
    let (mut p, mut q) = (z0.clone(), z0.clone());
    let before = allocations();
    for _ in 0..100 {
        lfs.step(&mut a).unwrap();
        sv.step(&mut b).unwrap();
        et.step(&mut c).unwrap();
        ss.step(&mut p).unwrap();
        et_nls.step(&mut q).unwrap();
    }
    assert_eq!(
        allocations() - before,
        0,
        "heap allocations during 500 steps"
    );
}

// ---------------------------------------------------------------------------------------------
// Input validation; a failed step leaves the state unchanged.

#[test]
fn bad_input_is_rejected() {
    let d = duffing();
    assert!(matches!(
        LinearFlowSplitting::new(d.system().unwrap(), 3, 0.1),
        Err(Error::InvalidParameter(_))
    ));
    assert!(matches!(
        StormerVerlet::new(duffing_second_order(&d), 10, 0.1),
        Err(Error::InvalidParameter(_))
    ));
    let nls = Nls::new(8).unwrap();
    assert!(matches!(
        SplitStep::nls(nls.system().unwrap(), 3, 0.1),
        Err(Error::InvalidParameter(_))
    ));
    for h in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            LinearFlowSplitting::new(d.system().unwrap(), 2, h),
            Err(Error::InvalidStepSize(_))
        ));
        assert!(matches!(
            StormerVerlet::new(duffing_second_order(&d), 2, h),
            Err(Error::InvalidStepSize(_))
        ));
        assert!(matches!(
            SplitStep::nls(nls.system().unwrap(), 2, h),
            Err(Error::InvalidStepSize(_))
        ));
        assert!(matches!(
            Etdrk4::new(d.system().unwrap(), h),
            Err(Error::InvalidStepSize(_))
        ));
    }
    // An odd dimension cannot hold (Re ψ, Im ψ).
    let odd = Dense::new(nalgebra::DMatrix::zeros(3, 3)).unwrap();
    assert!(matches!(
        SplitStep::new(odd, |u: f64| u, 2, 0.1),
        Err(Error::InvalidParameter(_))
    ));

    let mut m = LinearFlowSplitting::new(d.system().unwrap(), 4, 0.1).unwrap();
    let mut v = StormerVerlet::new(duffing_second_order(&d), 4, 0.1).unwrap();
    let mut e = Etdrk4::new(d.system().unwrap(), 0.1).unwrap();
    let mut s = SplitStep::nls(nls.system().unwrap(), 4, 0.1).unwrap();
    let mut short = vec![0.0; 3];
    assert!(matches!(
        m.step(&mut short),
        Err(Error::DimensionMismatch { .. })
    ));
    assert!(matches!(
        v.step(&mut short),
        Err(Error::DimensionMismatch { .. })
    ));
    assert!(matches!(
        e.step(&mut short),
        Err(Error::DimensionMismatch { .. })
    ));
    assert!(matches!(
        s.step(&mut short),
        Err(Error::DimensionMismatch { .. })
    ));
    let mut nan = vec![f64::NAN, 1.0];
    assert!(matches!(m.step(&mut nan), Err(Error::NonFinite(_))));
    assert!(matches!(v.step(&mut nan), Err(Error::NonFinite(_))));
    assert!(matches!(e.step(&mut nan), Err(Error::NonFinite(_))));
    assert!(nan[0].is_nan() && nan[1] == 1.0);
    assert!(matches!(
        m.set_step_size(f64::NAN),
        Err(Error::InvalidStepSize(_))
    ));
    assert_eq!(m.step_size(), 0.1);
}

/// g (or ρ) becomes NaN once |q| exceeds 0.5: a step that reaches such a stage fails with
/// `NonFinite` and leaves the state exactly as it was (also on a second attempt, after the
/// FSAL value was dropped).
#[test]
fn failed_steps_leave_the_state_unchanged() {
    let a = Duffing::default().linear_matrix();
    let g = |y: &[f64], out: &mut [f64]| {
        out[0] = 0.0;
        out[1] = if y[0].abs() > 0.5 {
            f64::NAN
        } else {
            y[0].powi(3)
        };
    };
    let y_start = vec![0.45, 5.0]; // q grows past 0.5 within h = 0.1
    let mut m =
        LinearFlowSplitting::new(Semilinear::new(Dense::new(a.clone()).unwrap(), g), 4, 0.1)
            .unwrap();
    let mut e = Etdrk4::new(Semilinear::new(Dense::new(a).unwrap(), g), 0.1).unwrap();
    let sys = SecondOrder::new(
        Omega::scalar(25.0, 1).unwrap(),
        |q: &[f64], out: &mut [f64]| {
            out[0] = if q[0].abs() > 0.5 {
                f64::NAN
            } else {
                -q[0].powi(3)
            };
        },
    );
    let mut v = StormerVerlet::new(sys, 4, 0.1).unwrap();
    for _ in 0..2 {
        let mut y = y_start.clone();
        assert!(matches!(m.step(&mut y), Err(Error::NonFinite(_))));
        assert_eq!(y, y_start);
        assert!(matches!(e.step(&mut y), Err(Error::NonFinite(_))));
        assert_eq!(y, y_start);
        assert!(matches!(v.step(&mut y), Err(Error::NonFinite(_))));
        assert_eq!(y, y_start);
    }
    // Split-step with ρ NaN above |ψ|² = 0.3: fails at the first substep from this state.
    let nls = Nls::new(8).unwrap();
    let op = nls.system().unwrap().linear().clone();
    let mut s = SplitStep::new(
        op,
        |u: f64| if u > 0.3 { f64::NAN } else { 2.0 * u },
        2,
        0.1,
    )
    .unwrap();
    let z_start: Vec<f64> = (0..16).map(|j| 0.1 * j as f64).collect();
    let mut z = z_start.clone();
    assert!(matches!(s.step(&mut z), Err(Error::NonFinite(_))));
    assert_eq!(z, z_start);
    assert!(s.energy_of(&z).is_none());
}

/// `SecondOrderSystem` energy is what `StormerVerlet` reports through `Integrator`.
#[test]
fn integrator_energy_is_the_systems() {
    let d = duffing();
    let y = [0.3, 0.7];
    let v = StormerVerlet::new(duffing_second_order(&d), 2, 0.1).unwrap();
    let expected = duffing_second_order(&d).energy(&y[..1], &y[1..]).unwrap();
    assert_eq!(v.energy_of(&y), Some(expected));
    assert!((expected - d.energy(&y)).abs() <= 1e-15);
    let m = LinearFlowSplitting::new(d.system().unwrap(), 2, 0.1).unwrap();
    assert_eq!(m.energy_of(&y), d.system().unwrap().energy(&y));
}

/// Dense Ω: Störmer–Verlet in physical coordinates agrees with the same method on the
/// diagonalised system (Ω = R diag(1, 4) Rᵀ, ∇U(q) = (q·r₁)³ r₁ in both frames), to round-off
/// (1e−13 after 100 steps of |q| ~ 1).
#[test]
fn stormer_verlet_dense_stiffness_matches_the_modal_system() {
    let (c, s) = (0.6_f64, 0.8_f64); // rotation R = [[c, −s], [s, c]]
    let dense = nalgebra::DMatrix::from_row_slice(
        2,
        2,
        &[
            c * c + 4.0 * s * s,
            c * s - 4.0 * c * s,
            c * s - 4.0 * c * s,
            s * s + 4.0 * c * c,
        ],
    );
    // Modal coordinate x = Rᵀq, x₁ = c q₁ + s q₂; U = x₁⁴/4.
    let phys = SecondOrder::new(
        Omega::dense(dense).unwrap(),
        move |q: &[f64], out: &mut [f64]| {
            let x1 = c * q[0] + s * q[1];
            out[0] = x1.powi(3) * c;
            out[1] = x1.powi(3) * s;
        },
    );
    let modal = SecondOrder::new(
        Omega::diagonal(vec![1.0, 4.0]).unwrap(),
        |x: &[f64], out: &mut [f64]| {
            out[0] = x[0].powi(3);
            out[1] = 0.0;
        },
    );
    let mut a = StormerVerlet::new(phys, 4, 0.05).unwrap();
    let mut b = StormerVerlet::new(modal, 4, 0.05).unwrap();
    let q = [0.3, -0.7];
    let p = [0.5, 0.2];
    let to_modal = |v: &[f64]| [c * v[0] + s * v[1], -s * v[0] + c * v[1]];
    let mut y = vec![q[0], q[1], p[0], p[1]];
    let (xq, xp) = (to_modal(&q), to_modal(&p));
    let mut x = vec![xq[0], xq[1], xp[0], xp[1]];
    for _ in 0..100 {
        a.step(&mut y).unwrap();
        b.step(&mut x).unwrap();
    }
    let (yq, yp) = (to_modal(&y[..2]), to_modal(&y[2..]));
    let diff = max_diff(&[yq[0], yq[1], yp[0], yp[1]], &x);
    assert!(diff <= 1e-13, "dense vs modal Ω: {diff:e}");
}

/// On a plane wave |ψ| is constant, so the linear and nonlinear flows commute and every
/// split-step scheme is exact: after n = 100 steps only round-off remains, below one ulp per
/// substep, (2m + 1)·n·ε (measured 1.3e−14, 6.4e−14, 1.0e−13, 1.6e−13 for orders 2–8). This pins
/// the sign convention of the linear flow and ρ(u) = 2u to [`Nls::plane_wave`] (ρ(u) = u
/// would leave an error of ~0.3 here).
#[test]
fn split_step_is_exact_on_plane_waves() {
    let nls = Nls::new(32).unwrap();
    let (amplitude, wavenumber, t_end) = (0.7, 3, 1.0);
    let y0 = nls.plane_wave(amplitude, wavenumber, 0.0).unwrap();
    let exact = nls.plane_wave(amplitude, wavenumber, t_end).unwrap();
    for (order, linear_substeps) in [(2, 1), (4, 6), (6, 9), (8, 15)] {
        let mut m = SplitStep::nls(nls.system().unwrap(), order, 0.01).unwrap();
        let err = max_diff(&run(&mut m, &y0, t_end, 100), &exact);
        let bound = (2 * linear_substeps + 1) as f64 * 100.0 * f64::EPSILON;
        println!("plane wave, SplitStep order {order}: error {err:.2e} (bound {bound:.1e})");
        assert!(err <= bound, "order {order}: {err:e}");
    }
}

/// RotationSplitting on a pure oscillator (∇U = 0, ω = 5 and 20): each rotation is applied as
/// the identity plus an increment (cos θ − 1 = −2 sin²(θ/2)), so its rounding does not make
/// det ≠ 1 and the amplitude does not grow or shrink at the rate of an ulp per step: over 10⁶
/// steps the relative energy error is 4.1e−14 in the first tenth and 3.7e−13 in the last. The
/// rotation matrix with f64 entries [[cos θ, sin θ/ω], [−ω sin θ, cos θ]] (before the change)
/// drifted 20 times as fast: 7.7e−13, then 7.4e−12 (the bound 1e−12 fails it).
#[test]
fn rotation_splitting_keeps_the_amplitude_of_a_pure_oscillator() {
    let oscillator = SecondOrder::new(
        Omega::diagonal(vec![25.0, 400.0]).unwrap(),
        |_: &[f64], f: &mut [f64]| f.fill(0.0),
    );
    let mut m = RotationSplitting::new(oscillator, 2, 0.0123).unwrap();
    let energy =
        |y: &[f64]| 0.5 * (y[2] * y[2] + y[3] * y[3] + 25.0 * y[0] * y[0] + 400.0 * y[1] * y[1]);
    let mut y = vec![1.0, 0.5, 0.3, -2.0];
    let e0 = energy(&y);
    let (mut first, mut last) = (0.0f64, 0.0f64);
    let n = 1_000_000;
    for i in 0..n {
        m.step(&mut y).unwrap();
        let e = (energy(&y) - e0).abs() / e0;
        if i < n / 10 {
            first = first.max(e);
        } else if i >= n - n / 10 {
            last = last.max(e);
        }
    }
    println!(
        "pure oscillator, 1e6 steps: relative energy error, first tenth {first:.2e}, last tenth {last:.2e}"
    );
    assert!(last < 1e-12, "energy error {last:e}");
}

/// `RotationSplitting` steps systems of up to four modes in a fixed-size form (state in
/// registers, issue 27: it took 2.2× the time of the same method in C on Duffing) and larger
/// ones through slices. Both must be the same method to the bit: four coupled modes stepped
/// alone (fixed form) and with a fifth, decoupled mode (slice form) give the same four modes,
/// bit for bit, after 2000 steps of order 8; and a ∇U that overflows at a stage is an error.
#[test]
fn rotation_splitting_fixed_and_slice_forms_agree_bit_for_bit() {
    fn grad(q: &[f64], f: &mut [f64]) {
        // Coupled cubic neighbours on the first four modes; the fifth (if any) feels nothing.
        for i in 0..4 {
            let left = if i > 0 { q[i] - q[i - 1] } else { q[i] };
            let right = if i < 3 { q[i] - q[i + 1] } else { q[i] };
            f[i] = 0.3 * (left.powi(3) + right.powi(3)) + 0.1 * q[i] * q[(i + 1) % 4];
        }
        f[4..].fill(0.0);
    }
    let stiff = vec![1.0, 4.0, 9.0, 30.0];
    let four = SecondOrder::new(Omega::diagonal(stiff.clone()).unwrap(), grad);
    let mut five_stiff = stiff.clone();
    five_stiff.push(7.0);
    let five = SecondOrder::new(Omega::diagonal(five_stiff).unwrap(), grad);
    for order in [2, 8] {
        let mut a = RotationSplitting::new(&four, order, 0.01).unwrap();
        let mut b = RotationSplitting::new(&five, order, 0.01).unwrap();
        let mut ya = vec![0.5, -0.2, 0.1, 0.3, 0.0, 0.4, -0.1, 0.2];
        let mut yb = vec![0.5, -0.2, 0.1, 0.3, 0.7, 0.0, 0.4, -0.1, 0.2, -0.3];
        for _ in 0..2000 {
            a.step(&mut ya).unwrap();
            b.step(&mut yb).unwrap();
        }
        let (qb, pb) = (&yb[..4], &yb[5..9]);
        for i in 0..4 {
            assert_eq!(ya[i].to_bits(), qb[i].to_bits(), "order {order}, q[{i}]");
            assert_eq!(
                ya[4 + i].to_bits(),
                pb[i].to_bits(),
                "order {order}, p[{i}]"
            );
        }
    }
    // A force that overflows from the second stage on: an error, and y is left as it was.
    let blow_up = SecondOrder::new(
        Omega::scalar(1.0, 1).unwrap(),
        |q: &[f64], f: &mut [f64]| f[0] = if q[0] > 1.0 { f64::MAX * q[0] } else { 0.0 },
    );
    let mut m = RotationSplitting::new(blow_up, 8, 0.5).unwrap();
    let mut y = vec![0.9, 5.0];
    assert!(matches!(m.step(&mut y), Err(Error::NonFinite(_))));
    assert_eq!(y, vec![0.9, 5.0]);
}
