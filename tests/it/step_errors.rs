//! Errors instead of panics or silent wrong results (issue 18, items 3, 7, 8): systems whose
//! dimensions are inconsistent or zero are refused by every constructor; dense output needs a
//! completed step; overflow is told apart from a diverging stage iteration, and `integrate`
//! says at which step and time a step failed.

use ecr::baselines::collocation::{ExpAvf, avf, gauss_collocation, rkepc2};
use ecr::baselines::dop853::Dop853;
use ecr::baselines::etdrk4::Etdrk4;
use ecr::baselines::exponential::{Exprb43, HochOst4};
use ecr::baselines::krylov::Exprb43Krylov;
use ecr::baselines::splitting::LinearFlowSplitting;
use ecr_runtime::Error;
use ecr_runtime::integrate::{IntegrateOptions, integrate};
use ecr_runtime::operator::{Dense, Scalar, Zero};
use ecr_runtime::second_order::{Omega, SecondOrder, TcStepper};
use ecr_runtime::stepper::{EcStepper, SolverSettings};
use ecr_runtime::system::{Semilinear, System};
use nalgebra::DMatrix;
use std::cell::Cell;

/// A system that claims dimension `dim` over a 2 × 2 linear part.
struct Claims {
    dim: usize,
    op: Dense,
}

impl System for Claims {
    type Op = Dense;
    fn dim(&self) -> usize {
        self.dim
    }
    fn linear(&self) -> &Dense {
        &self.op
    }
    fn nonlinear(&self, _y: &[f64], out: &mut [f64], _scratch: &mut [f64]) {
        out.fill(0.0);
    }
}

fn claims(dim: usize) -> Claims {
    Claims {
        dim,
        op: Dense::new(DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -1.0, 0.0])).unwrap(),
    }
}

/// Every constructor taking a `System`, as "Ok or the error".
fn construct_all(sys: &Claims) -> Vec<(&'static str, Option<Error>)> {
    let set = SolverSettings::default;
    let h = 0.1;
    vec![
        ("EcStepper", EcStepper::new(sys, 2, h).err()),
        (
            "gauss_collocation",
            gauss_collocation(sys, 2, h, set()).err(),
        ),
        ("rkepc2", rkepc2(sys, h, set()).err()),
        ("avf", avf(sys, 3, h, set()).err()),
        ("ExpAvf", ExpAvf::new(sys, 3, h, set()).err()),
        ("Dop853", Dop853::new(sys, 1e-10, 1e-10).err()),
        (
            "LinearFlowSplitting",
            LinearFlowSplitting::new(sys, 4, h).err(),
        ),
        ("Etdrk4", Etdrk4::new(sys, h).err()),
        ("Exprb43", Exprb43::new(sys, h).err()),
        ("HochOst4", HochOst4::new(sys, h).err()),
        ("Exprb43Krylov", Exprb43Krylov::new(sys, h).err()),
    ]
}

#[test]
fn inconsistent_or_zero_dimensions_are_refused_at_construction() {
    // Before: construction succeeded and the first step panicked ("dimension mismatch in
    // combine"), or, for d = 0, "chunk size must be non-zero".
    for (name, err) in construct_all(&claims(2)) {
        assert_eq!(err, None, "{name}: a consistent system");
    }
    for (name, err) in construct_all(&claims(3)) {
        match err {
            Some(Error::DimensionMismatch {
                expected: 2,
                found: 3,
                ..
            }) => {}
            other => panic!("{name}: dim() = 3 over a 2 × 2 operator gave {other:?}"),
        }
    }
    let zero = Semilinear::new(Zero::new(0), |_: &[f64], _: &mut [f64]| {});
    match EcStepper::new(&zero, 2, 0.1) {
        Err(Error::InvalidInput(msg)) => assert!(msg.contains("dimension 0"), "{msg}"),
        Err(e) => panic!("d = 0: {e:?}"),
        Ok(_) => panic!("d = 0 accepted"),
    }
    for (name, err) in construct_all(&Claims {
        dim: 0,
        op: Dense::new(DMatrix::zeros(0, 0)).unwrap(),
    }) {
        assert!(
            matches!(err, Some(Error::InvalidInput(ref m)) if m.contains("dimension 0")),
            "{name}: d = 0 gave {err:?}"
        );
    }
    let tc = TcStepper::new(
        SecondOrder::new(Omega::zero(0), |_: &[f64], _: &mut [f64]| {}),
        2,
        0.1,
    );
    assert!(
        matches!(tc, Err(Error::InvalidInput(_))),
        "TcStepper, d = 0"
    );
}

#[test]
fn dense_output_needs_a_completed_step() {
    let poisoned = Cell::new(false);
    let sys = Semilinear::new(Scalar::new(-1.0, 1).unwrap(), |y: &[f64], g: &mut [f64]| {
        g[0] = if poisoned.get() {
            f64::NAN
        } else {
            y[0] * y[0]
        };
    });
    let mut st = EcStepper::new(&sys, 2, 0.1).unwrap();
    // Before any step: it used to return Ok([0]).
    assert_eq!(st.dense_output(0.5), Err(Error::NoCompletedStep));
    assert_eq!(st.dense_output(0.0), Err(Error::NoCompletedStep));
    let mut y = [0.5];
    st.step(&mut y).unwrap();
    let mid = st.dense_output(0.5).unwrap();
    assert!(
        mid[0] > y[0] && mid[0] < 0.5,
        "{mid:?} between 0.5 and {y:?}"
    );
    // A failed step: it used to mix the failed step's y₀ with the last step's moments.
    poisoned.set(true);
    assert!(matches!(st.step(&mut y), Err(Error::NonFinite(_))));
    assert_eq!(st.dense_output(0.5), Err(Error::NoCompletedStep));
    poisoned.set(false);
    st.step(&mut y).unwrap();
    assert!(st.dense_output(0.5).is_ok());
    // A new step size: the moments belong to the old h.
    st.set_step_size(0.05).unwrap();
    assert_eq!(st.dense_output(0.5), Err(Error::NoCompletedStep));
    assert!(Error::NoCompletedStep.to_string().contains("dense output"));
}

#[test]
fn overflow_of_the_solution_is_named_with_its_step_and_time() {
    // y' = 700 y, y(0) = 1: e^{700 t} leaves the f64 range at t = 709.78/700 ≈ 1.0140; with
    // h = 0.01 the step from t = 1.01 (step 102) overflows. It used to be reported as "the
    // stage iteration diverged", without saying where.
    let sys = Semilinear::new(
        Scalar::new(700.0, 1).unwrap(),
        |_: &[f64], g: &mut [f64]| g[0] = 0.0,
    );
    let mut st = EcStepper::new(&sys, 2, 0.01).unwrap();
    let mut y = [1.0];
    let err = integrate(
        &mut st,
        0.0,
        2.0,
        &mut y,
        IntegrateOptions::default(),
        |_, _, _| {},
    )
    .unwrap_err();
    match &err {
        Error::AtStep { step, t, h, source } => {
            assert_eq!(*step, 102, "{err}");
            assert!((t - 1.01).abs() < 1e-12, "{err}");
            assert_eq!(*h, 0.01);
            assert!(matches!(**source, Error::Overflow(_)), "{err}");
        }
        other => panic!("{other:?}"),
    }
    let msg = err.to_string();
    for part in ["step 102", "t = 1.01", "overflowed", "smaller h"] {
        assert!(msg.contains(part), "{part:?} missing from: {msg}");
    }
    assert!(!msg.contains("diverged"), "{msg}");
    assert!(matches!(err.root(), Error::Overflow(_)));
    assert!(
        y[0].is_finite() && y[0] > 1e300,
        "state left at step 101: {y:?}"
    );
}

#[test]
fn an_unstable_step_size_says_what_to_try() {
    // y' = g(y) = −700 y with fixed-point sweeps and h = 0.01: the iteration's contraction
    // factor is ≈ 7, so it cannot converge.
    let sys = Semilinear::new(Zero::new(1), |y: &[f64], g: &mut [f64]| {
        g[0] = -700.0 * y[0]
    });
    let mut st = EcStepper::new(&sys, 2, 0.01).unwrap();
    let mut y = [1.0];
    let err = integrate(
        &mut st,
        0.0,
        1.0,
        &mut y,
        IntegrateOptions::default(),
        |_, _, _| {},
    )
    .unwrap_err();
    assert!(
        matches!(
            err,
            Error::AtStep {
                step: 1,
                t: 0.0,
                ..
            }
        ),
        "{err:?}"
    );
    let msg = err.to_string();
    for part in ["step 1 from t = 0.0", "smaller h", "Newton"] {
        assert!(msg.contains(part), "{part:?} missing from: {msg}");
    }
    assert!(!msg.contains("overflowed"), "{msg}");
}
