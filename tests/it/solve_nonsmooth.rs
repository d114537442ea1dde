//! `solve` on right-hand sides that are not smooth (issue 50), built to break an estimate made
//! of two Gauss orders: g only C^m at a time t_k, placed just after a grid point (where every
//! Gauss node of the step lies past t_k and all orders make the same error) and elsewhere; and
//! a pulse narrower than the steps, with the remedy `Options::max_step`.

use ecr::runtime::operator::Zero;
use ecr::runtime::solve::{Options, Problem, SolveError};
use ecr::runtime::system::Semilinear;

/// y' = max(t − t_k, 0)^m with a clock c' = 1 (state (c, y)): y(t) = max(t − t_k, 0)^(m+1)/(m+1).
fn kink(tk: f64, m: i32) -> Problem<impl ecr::runtime::system::System> {
    let system = Semilinear::new(Zero::new(2), move |y: &[f64], g: &mut [f64]| {
        g[0] = 1.0;
        g[1] = (y[0] - tk).max(0.0).powi(m);
    });
    Problem::new(system, [0.0, 0.0], (0.0, 10.0)).unwrap()
}

/// Over 12 kink times (among them 2.10214400000001, just after a grid point of h = 0.1, where
/// the 2h/3h check returned `Ok` 21 times off), m = 1 … 4 and tol 1e−6, 1e−8, 1e−10: no `Ok`
/// whose error is above 10 tolerances; a refusal is allowed (it says why), a wrong `Ok` is not.
#[test]
fn kinks_never_get_a_wrong_ok() {
    let tks = [
        2.102_144_000_000_01,
        2.1,
        2.100_000_000_000_1,
        1.0,
        3.333_333,
        4.5 + 1e-12,
        5.0,
        6.665_632,
        7.25,
        8.0 - 1e-13,
        0.4,
        9.1,
    ];
    let (mut ok, mut all, mut worst_ok) = (0, 0, 0.0_f64);
    for m in 1..=4 {
        for &tk in &tks {
            let problem = kink(tk, m);
            let exact = (10.0 - tk).powi(m + 1) / f64::from(m + 1);
            for tol in [1e-6, 1e-8, 1e-10] {
                all += 1;
                match problem.solve(&Options::tolerance(tol)) {
                    Ok(sol) => {
                        let y = sol.last().unwrap()[1];
                        let err = (y - exact).abs() / (tol * (1.0 + exact.abs()));
                        worst_ok = worst_ok.max(err);
                        ok += 1;
                        assert!(
                            err <= 10.0,
                            "t_k = {tk}, m = {m}, tol {tol:e}: Ok with error {err:.3e} tolerances \
                             (estimate {:?})",
                            sol.error_estimate
                        );
                    }
                    Err(SolveError::Unverified { reason, .. }) => {
                        assert!(!reason.is_empty());
                    }
                    Err(e) => panic!("t_k = {tk}, m = {m}, tol {tol:e}: {e}"),
                }
            }
        }
    }
    eprintln!("kinks: {ok} of {all} Ok, the largest error of an Ok {worst_ok:.3e} tolerances");
}

/// y' = sech²((t − t_k)/w) with w = 0.003: a pulse far narrower than the steps a tolerance of
/// 1e−8 allows elsewhere. `Options::max_step(w)` makes the steps see it: `Ok`, and within the
/// tolerance of y(10) = w (tanh((10 − t_k)/w) + tanh(t_k/w)). (Without it no sampled method can
/// see the pulse; docs/solve.md says so.)
#[test]
fn a_narrow_pulse_is_seen_with_max_step() {
    let (tk, w) = (6.665_632, 0.003);
    let system = Semilinear::new(Zero::new(2), move |y: &[f64], g: &mut [f64]| {
        g[0] = 1.0;
        let s = 1.0 / ((y[0] - tk) / w).cosh();
        g[1] = s * s;
    });
    let problem = Problem::new(system, [0.0, 0.0], (0.0, 10.0)).unwrap();
    let exact = w * (((10.0 - tk) / w).tanh() + (tk / w).tanh());
    for tol in [1e-6, 1e-8] {
        let sol = problem.solve(&Options::tolerance(tol).max_step(w)).unwrap();
        let y = sol.last().unwrap()[1];
        let err = (y - exact).abs() / (tol * (1.0 + exact.abs()));
        eprintln!(
            "pulse, tol {tol:e}, max_step {w}: EC{}P, error {err:.3e} tolerances",
            sol.r
        );
        assert!(err <= 1.0, "error {err:e} tolerances");
    }
}
