//! Bad input everywhere (issue: numerical stability at the extremes, item 5): every case is an
//! `Err` naming its cause, never a panic, NaN or silent garbage, and a failed step leaves the
//! state as it was. Each assertion names the exact variant and, where the error carries one,
//! the name of the offending quantity.

use ecr::problems::Duffing;
use ecr_runtime::Error;
use ecr_runtime::ecr_method;
use ecr_runtime::integrate::{IntegrateOptions, integrate};
use ecr_runtime::operator::{Circulant, Dense, DenseStatic, Diagonal, Scalar, Symmetric};
use ecr_runtime::stepper::{EcStepper, SolverSettings, StageScale};
use ecr_runtime::system::{GradientFlow, Hamiltonian, Semilinear, System};
use nalgebra::{DMatrix, SMatrix};
use std::cell::Cell;

ecr_method!(r = 2);

const BAD: [f64; 3] = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY];

fn duffing() -> (Duffing, impl System<Op = Dense>) {
    let p = Duffing::default();
    let pg = p.clone();
    let sys = Semilinear::new(
        Dense::new(p.linear_matrix()).unwrap(),
        move |y: &[f64], o: &mut [f64]| pg.nonlinear(y, o),
    );
    (p, sys)
}

#[test]
fn non_finite_state_is_named_and_leaves_the_state_alone() {
    let (p, sys) = duffing();
    let mut st = EcStepper::new(&sys, 2, 0.01).unwrap();
    for bad in BAD {
        for i in 0..2 {
            let mut y = p.initial_value();
            y[i] = bad;
            let before: Vec<u64> = y.iter().map(|v| v.to_bits()).collect();
            assert_eq!(
                st.step(&mut y),
                Err(Error::NonFinite("state y")),
                "y[{i}] = {bad}"
            );
            let after: Vec<u64> = y.iter().map(|v| v.to_bits()).collect();
            assert_eq!(before, after);
        }
    }
}

#[test]
fn non_finite_step_size_or_non_positive_step_size() {
    let (_, sys) = duffing();
    for h in [0.0, -0.0, -0.1, -1e-300, f64::NAN, f64::INFINITY] {
        assert!(
            matches!(EcStepper::new(&sys, 2, h), Err(Error::InvalidStepSize(x)) if x.to_bits() == h.to_bits()),
            "h = {h}"
        );
    }
    let mut st = EcStepper::new(&sys, 2, 0.01).unwrap();
    for h in [0.0, -1.0, f64::NAN, f64::NEG_INFINITY] {
        assert!(matches!(
            st.set_step_size(h),
            Err(Error::InvalidStepSize(_))
        ));
        assert_eq!(
            st.step_size(),
            0.01,
            "a rejected h leaves the stepper as it was"
        );
    }
}

#[test]
fn non_finite_linear_part_is_named_by_every_operator() {
    for bad in BAD {
        let mut a = DMatrix::<f64>::identity(2, 2);
        a[(1, 0)] = bad;
        assert_eq!(
            Dense::new(a.clone()).err(),
            Some(Error::NonFinite("dense operator"))
        );
        let sa: SMatrix<f64, 2, 2> = SMatrix::from_iterator(a.iter().copied());
        assert_eq!(
            DenseStatic::new(sa).err(),
            Some(Error::NonFinite("dense operator"))
        );
        let mut sym = DMatrix::<f64>::identity(2, 2);
        sym[(0, 0)] = bad;
        assert_eq!(
            Symmetric::new(sym).err(),
            Some(Error::NonFinite("symmetric operator"))
        );
        assert_eq!(
            Diagonal::new(vec![1.0, bad]).err(),
            Some(Error::NonFinite("diagonal"))
        );
        assert_eq!(
            Scalar::new(bad, 3).err(),
            Some(Error::NonFinite("scalar operator a"))
        );
        assert_eq!(
            Circulant::new(vec![1.0, bad, 0.0, 0.0]).err(),
            Some(Error::NonFinite("circulant first column"))
        );
        // Q and M of the Hamiltonian form, and M of a gradient flow.
        let gv = |_: &[f64], o: &mut [f64]| o.fill(0.0);
        let q = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -1.0, 0.0]);
        let mut m = DMatrix::<f64>::identity(2, 2);
        m[(1, 1)] = bad;
        assert!(matches!(
            Hamiltonian::new(q.clone(), m.clone(), gv),
            Err(Error::NonFinite(_))
        ));
        let mut qb = q.clone();
        qb[(0, 1)] = bad;
        assert!(matches!(
            Hamiltonian::new(qb, DMatrix::identity(2, 2), gv),
            Err(Error::NonFinite(_))
        ));
        assert!(matches!(
            GradientFlow::<_, fn(&[f64]) -> f64>::new(m, gv, None),
            Err(Error::NonFinite(_))
        ));
    }
}

#[test]
fn non_finite_nonlinearity_is_named_and_leaves_the_state_alone() {
    let p = Duffing::default();
    for bad in BAD {
        // g non-finite everywhere, and only away from y₀ (found in a later sweep).
        let everywhere = move |_: &[f64], o: &mut [f64]| o.fill(bad);
        let y_start = p.initial_value();
        let away = move |y: &[f64], o: &mut [f64]| {
            o.fill(0.0);
            if y != y_start.as_slice() {
                o[1] = bad;
            }
        };
        let mut st = EcStepper::new(
            Semilinear::new(Dense::new(p.linear_matrix()).unwrap(), everywhere),
            2,
            0.1,
        )
        .unwrap();
        let mut y = p.initial_value();
        assert_eq!(st.step(&mut y), Err(Error::NonFinite("g(Y) at a stage")));
        assert_eq!(y, p.initial_value());
        let mut st = EcStepper::new(
            Semilinear::new(Dense::new(p.linear_matrix()).unwrap(), away),
            2,
            0.1,
        )
        .unwrap();
        assert_eq!(st.step(&mut y), Err(Error::NonFinite("g(Y) at a stage")));
        assert_eq!(y, p.initial_value());
    }
}

/// g is not checked after every sweep (the residual and y₁ are): a non-finite g at any
/// evaluation of a step, the last sweep's included, and a g that maps non-finite stages back to
/// finite values, are still reported as g's fault, by the run-time stepper and by a macro
/// stepper (whose stage arrays are local), with the state unchanged.
#[test]
fn non_finite_g_at_any_sweep_is_named() {
    let p = Duffing::default();
    let a = p.linear_matrix();
    let sa: SMatrix<f64, 2, 2> = SMatrix::from_iterator(a.iter().copied());
    // The evaluations of g in one good step.
    let mut probe = EcStepper::new(
        Semilinear::new(
            Dense::new(a.clone()).unwrap(),
            |y: &[f64], o: &mut [f64]| Duffing::default().nonlinear(y, o),
        ),
        2,
        0.1,
    )
    .unwrap();
    let evals = probe.step(&mut p.initial_value()).unwrap().g_evals;
    assert!(evals > 4, "several sweeps ({evals} evaluations of g)");
    for bad in BAD {
        for sanitize in [false, true] {
            // Evaluation `at` (counted from 1) returns `bad`; with `sanitize`, g is 0 at
            // non-finite input (so that only the sweep after the bad value sees it).
            for at in 1..=evals {
                let calls = Cell::new(0);
                let g = |y: &[f64], o: &mut [f64]| {
                    calls.set(calls.get() + 1);
                    if sanitize && y.iter().any(|v| !v.is_finite()) {
                        o.fill(0.0);
                    } else {
                        Duffing::default().nonlinear(y, o);
                        if calls.get() == at {
                            o[1] = bad;
                        }
                    }
                };
                let mut rt =
                    EcStepper::new(Semilinear::new(Dense::new(a.clone()).unwrap(), &g), 2, 0.1)
                        .unwrap();
                let mut y = p.initial_value();
                assert_eq!(
                    rt.step(&mut y),
                    Err(Error::NonFinite("g(Y) at a stage")),
                    "run-time: g = {bad} at evaluation {at}, sanitize {sanitize}"
                );
                assert_eq!(y, p.initial_value());
                calls.set(0);
                let mut fixed: Ec2<_, 2> =
                    Ec2::fixed(Semilinear::new(DenseStatic::new(sa).unwrap(), &g), 0.1).unwrap();
                let mut y = [p.initial_value()[0], p.initial_value()[1]];
                assert_eq!(
                    fixed.step(&mut y),
                    Err(Error::NonFinite("g(Y) at a stage")),
                    "macro: g = {bad} at evaluation {at}, sanitize {sanitize}"
                );
                assert_eq!(y.as_slice(), p.initial_value().as_slice());
            }
        }
    }
}

#[test]
fn shapes_that_do_not_match() {
    let (p, sys) = duffing();
    let mut st = EcStepper::new(&sys, 2, 0.1).unwrap();
    for len in [0, 1, 3] {
        let mut y = vec![0.5; len];
        assert_eq!(
            st.step(&mut y),
            Err(Error::DimensionMismatch {
                what: "state y",
                expected: 2,
                found: len
            })
        );
    }
    let mut y = p.initial_value();
    assert!(
        st.step(&mut y).is_ok(),
        "the stepper still works after the errors"
    );
    assert!(matches!(
        Dense::from_row_slice(2, &[1.0, 2.0, 3.0]),
        Err(Error::DimensionMismatch {
            expected: 4,
            found: 3,
            ..
        })
    ));
    assert!(matches!(
        Dense::new(DMatrix::zeros(2, 3)),
        Err(Error::NotSquare {
            rows: 2,
            cols: 3,
            ..
        })
    ));
    let gv = |_: &[f64], o: &mut [f64]| o.fill(0.0);
    let q = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -1.0, 0.0]);
    assert!(matches!(
        Hamiltonian::new(DMatrix::zeros(2, 3), DMatrix::identity(2, 2), gv),
        Err(Error::NotSquare { .. })
    ));
    assert!(matches!(
        Hamiltonian::new(q.clone(), DMatrix::identity(3, 3), gv),
        Err(Error::DimensionMismatch {
            expected: 2,
            found: 3,
            ..
        })
    ));
    assert!(matches!(
        Hamiltonian::new(q, DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 0.0, 1.0]), gv),
        Err(Error::InvalidInput(_))
    ));
}

#[test]
fn time_interval_must_be_finite_and_forward() {
    let (p, sys) = duffing();
    let mut st = EcStepper::new(&sys, 2, 0.1).unwrap();
    let opts = IntegrateOptions::default();
    for (t0, t1) in [
        (1.0, 0.0),
        (0.0, -1e-300),
        (0.0, f64::NAN),
        (f64::NAN, 1.0),
        (0.0, f64::INFINITY),
        (f64::NEG_INFINITY, 0.0),
    ] {
        let mut y = p.initial_value();
        let rep = integrate(&mut st, t0, t1, &mut y, opts, |_, _, _| {});
        match rep {
            Err(Error::InvalidInput(msg)) => assert!(msg.contains("t"), "{msg}"),
            other => panic!("[{t0}, {t1}]: expected InvalidInput, got {other:?}"),
        }
        assert_eq!(y, p.initial_value());
    }
}

#[test]
fn orders_and_node_counts_outside_the_supported_range() {
    let (_, sys) = duffing();
    let s = SolverSettings::default();
    for (r, n) in [
        (0, 0),
        (0, 2),
        (33, 33),
        (3, 2),
        (1, 65),
        (usize::MAX, usize::MAX),
    ] {
        match EcStepper::with_nodes(&sys, r, n, 0.1, s) {
            Err(Error::InvalidParameter(msg)) => assert!(!msg.is_empty()),
            Err(e) => panic!("r = {r}, s = {n}: expected InvalidParameter, got {e:?}"),
            Ok(_) => panic!("r = {r}, s = {n}: accepted"),
        }
    }
    for bad in [
        SolverSettings { max_sweeps: 0, ..s },
        SolverSettings {
            tolerance: f64::NAN,
            ..s
        },
        SolverSettings {
            tolerance: -1e-15,
            ..s
        },
        SolverSettings {
            scale: StageScale::PerComponent { atol: 0.0 },
            ..s
        },
        SolverSettings {
            scale: StageScale::PerComponent { atol: -1e-30 },
            ..s
        },
        SolverSettings {
            scale: StageScale::PerComponent { atol: f64::NAN },
            ..s
        },
        SolverSettings {
            scale: StageScale::PerComponent {
                atol: f64::INFINITY,
            },
            ..s
        },
    ] {
        assert!(matches!(
            EcStepper::with_nodes(&sys, 2, 2, 0.1, bad),
            Err(Error::InvalidParameter(_))
        ));
    }
}
