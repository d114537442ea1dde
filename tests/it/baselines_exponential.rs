//! The exponential baselines (exprb43, Hochbruck–Ostermann 4) and DOP853: measured orders on
//! Duffing against its exact solution, exactness for y' = Ay, and input validation.
//! Run with `--nocapture` to see the measured numbers.

use ecr::baselines::dop853::{Dop853, Dop853Stepper};
use ecr::baselines::exponential::{Exprb43, HochOst4};
use ecr::problems::Duffing;
use ecr_runtime::Error;
use ecr_runtime::integrate::{IntegrateOptions, Integrator, integrate};
use ecr_runtime::operator::Dense;
use ecr_runtime::phi::phi_dense;
use ecr_runtime::system::Semilinear;
use nalgebra::DMatrix;

fn duffing() -> Duffing {
    Duffing::new(1.0, 0.5).unwrap()
}

/// Max-norm error at T of `n` steps of size T/n from the exact initial value.
fn error_at<I: Integrator>(method: &mut I, duffing: &Duffing, t_end: f64, n: usize) -> f64 {
    method.set_step_size(t_end / n as f64).unwrap();
    let mut y = duffing.initial_value();
    for _ in 0..n {
        method.step_state(&mut y).unwrap();
    }
    let exact = duffing.exact(t_end).unwrap();
    y.iter()
        .zip(exact)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
}

/// Least-squares slope of log(err) against log(h) over the points above `floor`.
fn measured_order(hs: &[f64], errs: &[f64], floor: f64) -> f64 {
    let pts: Vec<(f64, f64)> = hs
        .iter()
        .zip(errs)
        .filter(|&(_, &e)| e > floor)
        .map(|(&h, &e)| (h.ln(), e.ln()))
        .collect();
    assert!(pts.len() >= 3, "too few points above the floor: {pts:?}");
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    sxy / sxx
}

const T_END: f64 = 2.0;
const NS: [usize; 5] = [20, 40, 80, 160, 320];
const FLOOR: f64 = 1e-12;

fn order_of<I: Integrator>(name: &str, method: &mut I) -> f64 {
    let duffing = duffing();
    let hs: Vec<f64> = NS.iter().map(|&n| T_END / n as f64).collect();
    let errs: Vec<f64> = NS
        .iter()
        .map(|&n| error_at(method, &duffing, T_END, n))
        .collect();
    let order = measured_order(&hs, &errs, FLOOR);
    println!("{name}: Duffing(ω = 1, k = 0.5), T = {T_END}");
    for (h, e) in hs.iter().zip(&errs) {
        println!("  h = {h:.5}  error = {e:.3e}");
    }
    println!("  measured order {order:.3}");
    order
}

#[test]
fn exprb43_has_order_four_with_finite_difference_jacobian() {
    let duffing = duffing();
    let mut m = Exprb43::new(duffing.system().unwrap(), 0.1).unwrap();
    assert!(!m.is_frozen());
    let order = order_of("exprb43 (finite-difference Jacobian)", &mut m);
    assert!((order - 4.0).abs() < 0.2, "order {order}");
}

#[test]
fn exprb43_has_order_four_with_exact_jacobian() {
    let duffing = duffing();
    let k2 = duffing.k() * duffing.k();
    // g = (0, 2k²q³): g' = [[0, 0], [6k²q², 0]].
    let jac = move |y: &[f64], m: &mut DMatrix<f64>| m[(1, 0)] = 6.0 * k2 * y[0] * y[0];
    let mut m = Exprb43::with_jacobian(duffing.system().unwrap(), 0.1, jac).unwrap();
    let order = order_of("exprb43 (exact Jacobian)", &mut m);
    assert!((order - 4.0).abs() < 0.2, "order {order}");

    // The finite-difference Jacobian gives (nearly) the same steps.
    let mut fd = Exprb43::new(duffing.system().unwrap(), 0.05).unwrap();
    m.set_step_size(0.05).unwrap();
    let (mut y1, mut y2) = (duffing.initial_value(), duffing.initial_value());
    for _ in 0..40 {
        m.step(&mut y1).unwrap();
        fd.step(&mut y2).unwrap();
    }
    let diff = (y1[0] - y2[0]).abs().max((y1[1] - y2[1]).abs());
    println!("exprb43 exact vs finite-difference Jacobian after 40 steps: {diff:.2e}");
    assert!(diff < 1e-11, "{diff}");
}

#[test]
fn frozen_exprb43_has_only_order_two() {
    let duffing = duffing();
    let mut m = Exprb43::frozen(duffing.system().unwrap(), 0.1).unwrap();
    assert!(m.is_frozen());
    let order = order_of("exprb43 frozen at J = A", &mut m);
    assert!((order - 2.0).abs() < 0.2, "order {order}");
}

#[test]
fn hochost4_has_order_four() {
    let duffing = duffing();
    let mut m = HochOst4::new(duffing.system().unwrap(), 0.1).unwrap();
    let order = order_of("HochOst4", &mut m);
    assert!((order - 4.0).abs() < 0.2, "order {order}");
}

#[test]
fn dop853_reaches_1e10_at_t10() {
    let duffing = duffing();
    let mut m = Dop853Stepper::new(duffing.system().unwrap(), 0.5).unwrap();
    assert_eq!(m.dop853().tolerances(), (1e-12, 1e-12));
    let mut y = duffing.initial_value();
    let report = integrate(
        &mut m,
        0.0,
        10.0,
        &mut y,
        IntegrateOptions::default(),
        |_, _, _| {},
    )
    .unwrap();
    let exact = duffing.exact(10.0).unwrap();
    let err = (y[0] - exact[0]).abs().max((y[1] - exact[1]).abs());
    let stats = m.stats();
    println!(
        "DOP853 rtol = atol = 1e-12, macro h = 0.5, T = 10: error {err:.3e}, {} f-evaluations \
         ({} accepted, {} rejected internal steps), max |ΔH|/H0 = {:.2e}",
        report.g_evals,
        stats.accepted,
        stats.rejected,
        report.max_energy_error.unwrap()
    );
    assert!(err <= 1e-10, "{err}");
    assert_eq!(report.steps, 20);
    assert_eq!(report.g_evals, stats.f_evals);
    assert!(report.g_evals > 12 * 20);
}

/// One call of the crate over [0, T] (how its users call it): the same accuracy with fewer
/// evaluations than restarting every output step; the observer sees every accepted step,
/// in order, ending at T.
#[test]
fn dop853_one_call_over_the_interval() {
    let duffing = duffing();
    let dop = Dop853::new(duffing.system().unwrap(), 1e-12, 1e-12).unwrap();
    let mut y = duffing.initial_value();
    let mut times = Vec::new();
    let stats = dop
        .integrate_observed(0.0, 10.0, &mut y, &mut |t, _| times.push(t))
        .unwrap();
    let exact = duffing.exact(10.0).unwrap();
    let err = (y[0] - exact[0]).abs().max((y[1] - exact[1]).abs());
    println!(
        "DOP853 one call, rtol = atol = 1e-12, T = 10: error {err:.3e}, {} f-evaluations ({} \
         accepted, {} rejected)",
        stats.f_evals, stats.accepted, stats.rejected
    );
    assert!(err <= 1e-10, "{err}");
    assert_eq!(times.len(), stats.accepted);
    assert!(times.windows(2).all(|w| w[0] < w[1]));
    assert_eq!(*times.last().unwrap(), 10.0);
    // The same run without the observer: bit-identical.
    let mut y2 = duffing.initial_value();
    let stats2 = dop.integrate(0.0, 10.0, &mut y2).unwrap();
    assert_eq!((y, stats), (y2, stats2));
    // Restarting every 0.5 time units costs evaluations (each restart ends on a shortened
    // step and begins anew).
    let mut m = Dop853Stepper::new(duffing.system().unwrap(), 0.5).unwrap();
    let mut y3 = duffing.initial_value();
    for _ in 0..20 {
        m.step(&mut y3).unwrap();
    }
    assert!(
        stats.f_evals < m.stats().f_evals,
        "{stats:?} {:?}",
        m.stats()
    );
    // Bad intervals and tolerances are errors, y unchanged.
    let mut y4 = duffing.initial_value();
    for (t0, t1) in [
        (0.0, 0.0),
        (1.0, 0.0),
        (0.0, f64::NAN),
        (f64::INFINITY, 1.0),
    ] {
        assert!(matches!(
            dop.integrate(t0, t1, &mut y4),
            Err(Error::InvalidInput(_))
        ));
    }
    assert_eq!(y4, duffing.initial_value());
    assert!(matches!(
        Dop853::new(duffing.system().unwrap(), 0.0, 1e-10),
        Err(Error::InvalidParameter(_))
    ));
}

/// The crate's dense output (one call, values at the multiples of dx): every output, t_end's
/// included, within a few tolerances of Duffing's exact solution. Called over [0, t_end]
/// itself, ode_solvers 0.6.2 extrapolates its last output from the step holding the output
/// before it (on the suite's Lotka–Volterra, 1e−2 off at t_end whatever the tolerance), and
/// its output at t0 is the state after the first step; `integrate_dense` corrects both.
#[test]
fn dop853_dense_output_at_every_spacing_point() {
    let duffing = duffing();
    for tol in [1e-6, 1e-9, 1e-12] {
        let dop = Dop853::new(duffing.system().unwrap(), tol, tol).unwrap();
        let mut y = duffing.initial_value();
        let (ts, ys, stats) = dop.integrate_dense(0.0, 10.0, 0.5, &mut y).unwrap();
        assert_eq!(ts.len(), 21, "{ts:?}");
        assert!((ts[20] - 10.0).abs() <= 1e-12, "{ts:?}");
        let mut worst: f64 = 0.0;
        assert_eq!(ys[0], duffing.initial_value());
        for (t, v) in ts.iter().zip(&ys) {
            let exact = duffing.exact(*t).unwrap();
            worst = worst.max((v[0] - exact[0]).abs().max((v[1] - exact[1]).abs()));
        }
        println!(
            "DOP853 dense output, rtol = atol = {tol:e}: worst error {worst:.2e} over 21 outputs, \
             {} f-evaluations",
            stats.f_evals
        );
        assert!(worst <= 100.0 * tol, "{tol:e}: {worst:e}");
        assert_eq!(y, ys[20]);
    }
    let mut y = duffing.initial_value();
    let dop = Dop853::new(duffing.system().unwrap(), 1e-8, 1e-8).unwrap();
    assert!(matches!(
        dop.integrate_dense(0.0, 10.0, 0.0, &mut y),
        Err(Error::InvalidParameter(_))
    ));
    // A spacing that does not divide the span leaves t_end without an output: an error.
    assert!(matches!(
        dop.integrate_dense(0.0, 10.0, 0.3, &mut y),
        Err(Error::Numerical(_))
    ));
}

/// The fixed-size (SVector) and heap (DVector) paths of the crate solve the same problem:
/// d = 5 is not in `FIXED_DIMS`, d = 4 is. Two decoupled cubic oscillators, padded by a
/// constant component to d = 5, agree to the tolerance (not to the bit: the code's error
/// norm divides by d, so the step sequences differ).
#[test]
fn dop853_fixed_and_dynamic_states_agree() {
    use ecr::baselines::dop853::FIXED_DIMS;
    assert!(FIXED_DIMS.contains(&4) && !FIXED_DIMS.contains(&5));
    let run = |d: usize| {
        let mut a = DMatrix::zeros(d, d);
        a[(0, 1)] = 1.0;
        a[(1, 0)] = -4.0;
        a[(2, 3)] = 1.0;
        a[(3, 2)] = -4.0;
        let g = |y: &[f64], out: &mut [f64]| {
            out.fill(0.0);
            out[1] = -y[0].powi(3);
            out[3] = -y[2].powi(3);
        };
        let dop = Dop853::new(Semilinear::new(Dense::new(a).unwrap(), g), 1e-10, 1e-10).unwrap();
        let mut y = vec![0.0; d];
        y[..4].copy_from_slice(&[1.0, 0.0, 0.5, 0.3]);
        let stats = dop.integrate(0.0, 3.0, &mut y).unwrap();
        (y[..4].to_vec(), stats)
    };
    let (y4, s4) = run(4);
    let (y5, s5) = run(5);
    let diff = y4
        .iter()
        .zip(&y5)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    println!("d = 4 (SVector) vs d = 5 (DVector): max difference {diff:.1e}; {s4:?} {s5:?}");
    assert!(diff < 1e-8, "{diff}");
    assert!(s4.accepted > 10 && s5.accepted > 10);
}

/// y' = Ay with a non-normal 3 × 3 A: both exponential methods are the exact flow.
#[test]
fn linear_problems_are_solved_exactly() {
    let a = DMatrix::from_row_slice(3, 3, &[-1.0, 2.0, 0.5, -2.0, -0.3, 1.0, 0.0, 0.7, -2.5]);
    let zero_g = |_: &[f64], out: &mut [f64]| out.fill(0.0);
    let (h, n) = (0.25, 8);
    let y0 = [1.0, -0.5, 2.0];
    let flow = &phi_dense(&(&a * (h * n as f64)), 0).unwrap()[0];
    let exact: Vec<f64> = (flow * nalgebra::DVector::from_column_slice(&y0))
        .iter()
        .copied()
        .collect();
    let check = |name: &str, y: &[f64]| {
        let err = y
            .iter()
            .zip(&exact)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        println!("{name}: y' = Ay, {n} steps, error vs e^(TA) y0 = {err:.2e}");
        assert!(err < 1e-13, "{name}: {err}");
    };
    let sys = || Semilinear::new(Dense::new(a.clone()).unwrap(), zero_g);
    let mut y = y0.to_vec();
    let mut m = Exprb43::new(sys(), h).unwrap();
    (0..n).for_each(|_| _ = m.step(&mut y).unwrap());
    check("exprb43", &y);
    let mut y = y0.to_vec();
    let mut m = Exprb43::frozen(sys(), h).unwrap();
    (0..n).for_each(|_| _ = m.step(&mut y).unwrap());
    check("exprb43 frozen", &y);
    let mut y = y0.to_vec();
    let mut m = HochOst4::new(sys(), h).unwrap();
    (0..n).for_each(|_| _ = m.step(&mut y).unwrap());
    check("HochOst4", &y);
}

#[test]
fn reports_count_g_evaluations() {
    let duffing = duffing();
    let mut y = duffing.initial_value();
    let mut m = Exprb43::new(duffing.system().unwrap(), 0.1).unwrap();
    assert_eq!(m.step(&mut y).unwrap().g_evals, 3 + 2 * 2);
    let mut m = Exprb43::frozen(duffing.system().unwrap(), 0.1).unwrap();
    assert_eq!(m.step(&mut y).unwrap().g_evals, 3);
    let mut m = HochOst4::new(duffing.system().unwrap(), 0.1).unwrap();
    assert_eq!(m.step(&mut y).unwrap().g_evals, 5);
    // The energy is the system's.
    assert_eq!(m.energy_of(&y), Some(duffing.energy(&y)));
}

#[test]
fn bad_input_is_an_error() {
    let duffing = duffing();
    let sys = || duffing.system().unwrap();
    for h in [0.0, -0.1, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            Exprb43::new(sys(), h),
            Err(Error::InvalidStepSize(_))
        ));
        assert!(matches!(
            Exprb43::frozen(sys(), h),
            Err(Error::InvalidStepSize(_))
        ));
        assert!(matches!(
            HochOst4::new(sys(), h),
            Err(Error::InvalidStepSize(_))
        ));
        assert!(matches!(
            Dop853Stepper::new(sys(), h),
            Err(Error::InvalidStepSize(_))
        ));
    }
    for tol in [0.0, -1e-8, f64::NAN] {
        assert!(matches!(
            Dop853Stepper::with_tolerances(sys(), 0.1, tol, 1e-10),
            Err(Error::InvalidParameter(_))
        ));
        assert!(matches!(
            Dop853Stepper::with_tolerances(sys(), 0.1, 1e-10, tol),
            Err(Error::InvalidParameter(_))
        ));
    }

    let mut methods: Vec<Box<dyn Integrator>> = vec![
        Box::new(Exprb43::new(sys(), 0.1).unwrap()),
        Box::new(Exprb43::frozen(sys(), 0.1).unwrap()),
        Box::new(HochOst4::new(sys(), 0.1).unwrap()),
        Box::new(Dop853Stepper::new(sys(), 0.1).unwrap()),
    ];
    for m in &mut methods {
        let mut short = [0.0];
        assert!(matches!(
            m.step_state(&mut short),
            Err(Error::DimensionMismatch {
                expected: 2,
                found: 1,
                ..
            })
        ));
        let mut bad = [f64::NAN, 1.0];
        assert!(matches!(m.step_state(&mut bad), Err(Error::NonFinite(_))));
        assert!(matches!(
            m.set_step_size(0.0),
            Err(Error::InvalidStepSize(_))
        ));
        assert_eq!(m.step_size(), 0.1);
        let mut y = duffing.initial_value();
        m.step_state(&mut y).unwrap();
    }

    // g that overflows: an error, and y unchanged.
    let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -1.0, 0.0]);
    let blow_up = |y: &[f64], out: &mut [f64]| {
        out[0] = 0.0;
        out[1] = if y[0].abs() > 0.5 {
            f64::INFINITY
        } else {
            y[0]
        };
    };
    let sys2 = || Semilinear::new(Dense::new(a.clone()).unwrap(), blow_up);
    let mut methods: Vec<Box<dyn Integrator>> = vec![
        Box::new(Exprb43::new(sys2(), 0.1).unwrap()),
        Box::new(HochOst4::new(sys2(), 0.1).unwrap()),
        Box::new(Dop853Stepper::new(sys2(), 0.1).unwrap()),
    ];
    for m in &mut methods {
        let mut y = [1.0, 0.0];
        assert!(matches!(m.step_state(&mut y), Err(Error::NonFinite(_))));
        assert_eq!(y, [1.0, 0.0]);
    }

    // A Jacobian closure that writes NaN, or replaces the matrix by one of the wrong shape.
    let nan_jac = |_: &[f64], m: &mut DMatrix<f64>| m[(0, 0)] = f64::NAN;
    let mut m = Exprb43::with_jacobian(sys(), 0.1, nan_jac).unwrap();
    let mut y = duffing.initial_value();
    assert!(matches!(m.step(&mut y), Err(Error::NonFinite(_))));
    assert_eq!(y, duffing.initial_value());
    let wrong = |_: &[f64], m: &mut DMatrix<f64>| *m = DMatrix::zeros(3, 3);
    let mut m = Exprb43::with_jacobian(sys(), 0.1, wrong).unwrap();
    assert!(matches!(
        m.step(&mut y),
        Err(Error::DimensionMismatch { .. })
    ));
    assert_eq!(y, duffing.initial_value());

    // A strongly unstable A: the φ-functions overflow, reported not panicked.
    let huge = DMatrix::from_row_slice(2, 2, &[1e6, 0.0, 0.0, 1.0]);
    let sys3 = Semilinear::new(Dense::new(huge).unwrap(), |_: &[f64], o: &mut [f64]| {
        o.fill(0.0)
    });
    assert!(HochOst4::new(&sys3, 1.0).is_err());
    assert!(Exprb43::frozen(&sys3, 1.0).is_err());
    let mut m = Exprb43::new(&sys3, 1.0).unwrap();
    let mut y = [1.0, 1.0];
    assert!(m.step(&mut y).is_err());
    assert_eq!(y, [1.0, 1.0]);
}
