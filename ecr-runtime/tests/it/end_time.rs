//! `integrate` reaches the requested end time exactly, for every (h, T) (issue 18, items 1
//! and 2): h larger than the interval, T not a multiple of h, long runs where the old 1e−9
//! relative slack on the step count skipped or added a partial step. The test problem y' = 1
//! (A = 0, g = 1) is integrated exactly by every step, so y(T) − y(t0) is the length of time
//! actually integrated.

use ecr_runtime::integrate::{IntegrateOptions, StepPlan, integrate};
use ecr_runtime::operator::Zero;
use ecr_runtime::stepper::EcStepper;
use ecr_runtime::system::Semilinear;
use num_rational::BigRational;
use num_traits::{Signed, ToPrimitive};

/// Integrates y' = 1 from (t0, 0) to t_end with step h: (y(t_end), reported t_end, steps).
fn run(t0: f64, t_end: f64, h: f64) -> (f64, f64, usize) {
    let sys = Semilinear::new(Zero::new(1), |_: &[f64], g: &mut [f64]| g[0] = 1.0);
    let mut st = EcStepper::new(sys, 1, h).unwrap();
    let mut y = [0.0];
    let mut times = Vec::new();
    let opts = IntegrateOptions {
        energy_every: 0,
        observe_every: 1,
    };
    let rep = integrate(&mut st, t0, t_end, &mut y, opts, |t, _, _| times.push(t)).unwrap();
    assert_eq!(st.step_size(), h, "h restored after a shortened last step");
    assert_eq!(times.first(), Some(&t0));
    assert_eq!(times.last(), Some(&t_end), "the observer sees T last");
    // Step n ends at t0 + n h (no drift from repeated addition).
    for (n, t) in times.iter().enumerate().take(rep.steps).skip(1) {
        assert_eq!(*t, t0 + n as f64 * h, "t after step {n}");
    }
    (y[0], rep.t_end, rep.steps)
}

/// The integrated length y(T) equals T − t0 up to the round-off of summing the steps: each
/// step adds its length with one rounding of |y| ≤ T, so n steps are within n ε T.
fn assert_reached(t0: f64, t_end: f64, h: f64) {
    let (y, t, steps) = run(t0, t_end, h);
    assert_eq!(
        t, t_end,
        "h = {h:e}, [{t0:e}, {t_end:e}]: reported end time"
    );
    let tol = (steps as f64 + 2.0) * f64::EPSILON * t_end.abs().max(1.0);
    assert!(
        (y - (t_end - t0)).abs() <= tol,
        "h = {h:e}, [{t0:e}, {t_end:e}]: integrated {y:e} in {steps} steps, want {:e} (± {tol:e})",
        t_end - t0
    );
}

#[test]
fn a_step_larger_than_the_interval_is_shortened_to_it() {
    // Before: h ≥ 1e9·T took no step and reported t_end = t0.
    for h in [1e10, 1e300, 2.0, 1.0 + 1e-12] {
        assert_reached(0.0, 1.0, h);
        let (_, _, steps) = run(0.0, 1.0, h);
        assert_eq!(steps, 1, "h = {h:e}");
    }
    assert_reached(3.0, 3.5, 1e12);
}

#[test]
fn the_end_time_is_reached_exactly_in_long_runs() {
    // Before: 1e7 steps of h = 1 ended 0.005 past T = 1e7 − 0.005 and 0.009 short of
    // T = 1e7 + 0.009 (the step count rounded with a relative slack of 1e−9).
    let plan = StepPlan::new(0.0, 1e7 - 0.005, 1.0).unwrap();
    assert_eq!((plan.full_steps, plan.steps()), (9_999_999, 10_000_000));
    let plan = StepPlan::new(0.0, 1e7 + 0.009, 1.0).unwrap();
    assert_eq!((plan.full_steps, plan.steps()), (10_000_000, 10_000_001));
    assert!((plan.last.unwrap() - 0.009).abs() < 1e-9);
    // Shorter runs with the same relative offsets, integrated.
    assert_reached(0.0, 1e5 - 5e-5, 1.0);
    assert_reached(0.0, 1e5 + 9e-5, 1.0);
    assert_reached(0.0, 1.000_000_000_9, 1e-5);
}

#[test]
fn multiples_of_h_take_no_extra_step_and_others_shorten_the_last() {
    // T = n·h up to the rounding of h: exactly n steps, T reported.
    for (t0, t_end, h, n) in [
        (0.0, 1.0, 0.1, 10),
        (0.0, 0.3, 0.1, 3),
        (0.0, 10.0, 10.0 / 7.0, 7),
        (5.0, 15.0, 10.0 / 3.0, 3),
        (0.0, 1e6, 0.1, 10_000_000),
    ] {
        let plan = StepPlan::new(t0, t_end, h).unwrap();
        // n steps; the n-th corrected by the round-off of n·fl(h) against the span, if any
        // (issue 27: `the_step_sizes_add_up_to_the_span`).
        assert_eq!(plan.steps(), n, "[{t0}, {t_end}], h = {h}");
        if let Some(last) = plan.last {
            let tol = StepPlan::TIME_ULPS * f64::EPSILON * t_end.abs();
            assert!(
                (last - h).abs() <= tol,
                "[{t0}, {t_end}], h = {h}: last {last:e}"
            );
        }
    }
    for (t0, t_end, h) in [(0.0, 1.05, 0.1), (0.0, 0.25, 0.1), (2.0, 2.0 + 1e-7, 0.01)] {
        assert_reached(t0, t_end, h);
    }
    // An empty interval: no step, t0 reported.
    let (y, t, steps) = run(1.0, 1.0, 0.1);
    assert_eq!((y, t, steps), (0.0, 1.0, 0));
}

#[test]
fn step_counts_beyond_exact_f64_are_refused() {
    assert!(StepPlan::new(0.0, 1.0, 1e-300).is_err());
    assert!(StepPlan::new(0.0, 1.0, f64::MIN_POSITIVE).is_err());
}

/// Issue 27: the sizes of the steps (full_steps · fl(h) + last, in exact arithmetic) add up to
/// t_end − t0 up to the rounding of the last step (half an ulp of it, and the two roundings of
/// an exact remainder far below the span), not up to n·ulp(h)/2: 10⁴ steps of fl(0.1) miss
/// T = 1000 by 5.6e−14, which on Duffing ω = 20 alone is an error of 2e−11.
#[test]
fn the_step_sizes_add_up_to_the_span() {
    let exact = |x: f64| BigRational::from_float(x).unwrap();
    let mut cases = vec![
        (0.0, 1000.0, 0.1),
        (0.0, 1000.0, 0.05),
        (0.0, 1000.0, 0.07),
        (0.0, 1.0, 0.1),
        (0.0, 0.3, 0.1),
        (0.0, 10.0, 10.0 / 7.0),
        (5.0, 15.0, 10.0 / 3.0),
        (0.0, 1e6, 0.1),
        (0.1, 1000.3, 0.013),
        (-7.3, 2.9, 0.017),
        (0.0, 1.05, 0.1),
        (2.0, 2.0 + 1e-7, 0.01),
        (0.0, 1.0, 1e10),
    ];
    // 20 step sizes between 0.05 and 0.2 over [0, 1000], as the floor test of `ecr run`.
    cases.extend((0..20).map(|k| (0.0, 1000.0, 0.05 * 4f64.powf(k as f64 / 19.0))));
    for (t0, t_end, h) in cases {
        let plan = StepPlan::new(t0, t_end, h).unwrap();
        let last = plan.last.unwrap_or(0.0);
        let sum = exact(h) * BigRational::from_integer(plan.full_steps.into()) + exact(last);
        let miss = (sum - (exact(t_end) - exact(t0))).abs();
        // Half an ulp of the last step (or of h), twice over.
        let tol = f64::EPSILON * last.max(h).min(t_end - t0);
        assert!(
            miss <= exact(tol),
            "[{t0}, {t_end}], h = {h}: the steps miss the span by {:e}",
            miss.to_f64().unwrap_or(f64::NAN)
        );
    }
}
