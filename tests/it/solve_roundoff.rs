//! Rounding amplified by the flow is part of what `Ok` promises (issue 42, item 4): on an orbit
//! that runs along a separatrix, one ulp of y₀ or of any step moves the answer by more than the
//! tolerance, and the three runs of the check share that rounding in kind (their differences
//! show their truncation only). The solve must then say that it cannot verify the answer, or
//! return one that is within the tolerance — never an `Ok` that the rounding has broken.
//!
//! Duffing with k = ω = 5 (elliptic parameter m = 1) from (0, 5) is the heteroclinic orbit
//! q = tanh 5t, p = 5 sech² 5t, which approaches the saddle (1, 0) as e^{−10t}: a perturbation
//! of the orbit grows like e^{10t}·… until it leaves. The pendulum q'' = −sin q from (0, 2)
//! is the upper separatrix q = 4 atan(eᵗ) − π, p = 2 sech t.

use ecr::problems::Duffing;
use ecr::runtime::operator::Zero;
use ecr::runtime::solve::{Options, Problem, SolveError};
use ecr::runtime::system::Semilinear;

/// max_i |y_i − e_i| / (tol (1 + |e_i|)).
fn scaled(y: &[f64], exact: &[f64], tol: f64) -> f64 {
    y.iter()
        .zip(exact)
        .map(|(a, b)| (a - b).abs() / (tol + tol * b.abs()))
        .fold(0.0, f64::max)
}

/// How a solve of a case ended: `Ok(error/tol)` or `Err(reason)` for an unverified answer.
fn outcome<S: ecr::runtime::system::System>(
    problem: &Problem<S>,
    t_end: f64,
    tol: f64,
    exact: &[f64],
) -> Result<f64, String> {
    match problem.solve(&Options::tolerance(tol).t_eval([t_end])) {
        Ok(sol) => Ok(scaled(sol.last().unwrap(), exact, tol)),
        Err(SolveError::Unverified { reason, .. }) => Err(reason),
        Err(e) => panic!("t_end {t_end}, tol {tol:e}: failed: {e}"),
    }
}

/// The Duffing heteroclinic orbit (`ecr run --problem duffing --k 5 --t-end 3 --tol 1e-5`
/// returned `Ok` with 32 times the tolerance before the checking run was perturbed).
#[test]
fn the_duffing_separatrix_is_never_a_false_ok() {
    let d = Duffing::new(5.0, 5.0).unwrap();
    for (t_end, tol) in [(3.0, 1e-5), (3.5, 1e-3), (2.0, 1e-8), (3.0, 1e-7)] {
        let problem = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, t_end)).unwrap();
        let s = (5.0 * t_end).cosh().recip();
        let exact = [(5.0 * t_end).tanh(), 5.0 * s * s];
        match outcome(&problem, t_end, tol, &exact) {
            Ok(err) => assert!(
                err <= 10.0,
                "T = {t_end}, tol {tol:e}: Ok with an error of {err:.3} times the tolerance"
            ),
            Err(reason) => assert!(
                reason.contains("round"),
                "T = {t_end}, tol {tol:e}: unverified, but not for rounding: {reason}"
            ),
        }
    }
}

/// The pendulum on its separatrix (`Ok` at 1e−9 and 1e−10 with 5.2 and 4.7 times the
/// tolerance before).
#[test]
fn the_pendulum_separatrix_is_never_a_false_ok() {
    let g = |y: &[f64], out: &mut [f64]| {
        out[0] = y[1];
        out[1] = -y[0].sin();
    };
    let t_end = 20.0_f64;
    let exact = [
        4.0 * t_end.exp().atan() - std::f64::consts::PI,
        2.0 / t_end.cosh(),
    ];
    for tol in [1e-6, 1e-9, 1e-10] {
        let problem =
            Problem::new(Semilinear::new(Zero::new(2), g), [0.0, 2.0], (0.0, t_end)).unwrap();
        match outcome(&problem, t_end, tol, &exact) {
            Ok(err) => assert!(
                err <= 10.0,
                "tol {tol:e}: Ok with an error of {err:.3} times the tolerance"
            ),
            Err(reason) => assert!(
                reason.contains("round"),
                "tol {tol:e}: unverified, but not for rounding: {reason}"
            ),
        }
    }
}

/// The times of a run whose step size changes often are summed without their rounding adding
/// up: Duffing ω = 20 over 1000 time units at 1e−11 ends after 2 839 constant-step segments
/// (the local mode of a run started again), and each change of step size rounded the time
/// where it changed. Both runs share those times, so their difference cannot see the drift:
/// before the times were carried in double-double the steps added up to 1.0e−11 less than
/// t_end, and the answer was `Ok` 11.8 tolerances off under an estimate of 0.11 (10.0 at main
/// 46b0ac5).
#[test]
fn many_segments_do_not_drift_in_time() {
    let d = Duffing::new(20.0, 0.07).unwrap();
    let t_end = 1000.0;
    let tol = 1e-11;
    let problem = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, t_end)).unwrap();
    let sol = match problem.solve(&Options::tolerance(tol).t_eval([t_end])) {
        Ok(sol) => sol,
        Err(e) => panic!("Duffing at 1e-11 is verified: {e}"),
    };
    assert!(
        sol.segments.len() > 100,
        "the case needs many segments: {}",
        sol.segments.len()
    );
    let err = scaled(sol.last().unwrap(), &d.exact(t_end).unwrap(), tol);
    assert!(
        err <= 1.0,
        "Ok with an error of {err:.3} times the tolerance"
    );
}
