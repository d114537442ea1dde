//! Random input to the public step API (proptest, fixed seed): constructors and steps of ECrP and
//! TCrP with arbitrary r, s, h, solver settings and states (NaN, ±∞, huge, wrong length) return
//! `Ok` or a specific `Err` — never a panic — and a failed step leaves the state unchanged.

use ecr::problems::{Duffing, Fpu};
use ecr_runtime::Error;
use ecr_runtime::operator::BankArithmetic;
use ecr_runtime::second_order::TcStepper;
use ecr_runtime::stepper::{
    EcStepper, PARALLEL_MIN_DIM, Predictor, SolverSettings, StageScale, StageSolver, SweepLimit,
};
use proptest::prelude::*;
use proptest::test_runner::{Config as ProptestConfig, RngSeed};

fn config() -> ProptestConfig {
    ProptestConfig {
        cases: 192,
        rng_seed: RngSeed::Fixed(0x0EC8_F022),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

/// Floats including the values that break numerical code.
fn any_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(0.0),
        Just(-0.0),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(f64::MAX),
        Just(f64::MIN_POSITIVE),
        Just(1e300),
        -1e3..1e3f64,
        -1.0..1.0f64,
    ]
}

fn step_size() -> impl Strategy<Value = f64> {
    prop_oneof![any_f64(), 1e-6..2.0f64]
}

fn settings() -> impl Strategy<Value = SolverSettings> {
    (
        prop_oneof![
            Just(1e-15),
            Just(0.0),
            Just(-1.0),
            Just(f64::NAN),
            0.0..1e-3f64
        ],
        0usize..8,
        any::<bool>(),
        any::<bool>(),
        0usize..3,
        prop::option::of(any_f64()),
        any::<bool>(),
        any::<bool>(),
    )
        .prop_map(
            |(tolerance, max_sweeps, accept, extrapolate, solver, atol, parallel, f64_banks)| {
                SolverSettings {
                    tolerance,
                    max_sweeps,
                    on_limit: if accept {
                        SweepLimit::Accept
                    } else {
                        SweepLimit::Error
                    },
                    predictor: if extrapolate {
                        Predictor::Extrapolate
                    } else {
                        Predictor::Constant
                    },
                    solver: [
                        StageSolver::FixedPoint,
                        StageSolver::Newton,
                        StageSolver::SimplifiedNewton,
                    ][solver],
                    scale: atol
                        .map_or(StageScale::Global, |atol| StageScale::PerComponent { atol }),
                    compensated: !accept,
                    // The concurrent stage path for any d, or the default.
                    parallel_min_dim: if parallel { 0 } else { PARALLEL_MIN_DIM },
                    banks: if f64_banks {
                        BankArithmetic::F64
                    } else {
                        BankArithmetic::Extended
                    },
                }
            },
        )
}

fn state(max_len: usize) -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(any_f64(), 0..=max_len)
}

/// The error variants bad input may produce (anything else is a bug in the report).
fn expected(e: &Error) -> bool {
    matches!(
        e,
        Error::InvalidStepSize(_)
            | Error::InvalidParameter(_)
            | Error::InvalidInput(_)
            | Error::DimensionMismatch { .. }
            | Error::NonFinite(_)
            | Error::NoConvergence { .. }
            | Error::Numerical(_)
            | Error::Overflow(_)
    )
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn ec_step_never_panics(
        r in 0usize..=9,
        extra in 0usize..=3,
        below in any::<bool>(),
        h in step_size(),
        set in settings(),
        ys in prop::collection::vec(state(3), 1..4),
    ) {
        let s = if below { r.saturating_sub(1) } else { r + extra };
        let d = Duffing::new(5.0, 0.07).unwrap();
        match EcStepper::with_nodes(d.system().unwrap(), r, s, h, set) {
            Err(e) => prop_assert!(expected(&e), "constructor: {e:?}"),
            Ok(mut st) => {
                for mut y in ys {
                    let before = y.clone();
                    match st.step(&mut y) {
                        Ok(_) => prop_assert!(y.iter().all(|v| v.is_finite())),
                        Err(e) => {
                            prop_assert!(expected(&e), "step: {e:?}");
                            let same = y.iter().zip(&before)
                                .all(|(a, b)| a.to_bits() == b.to_bits());
                            prop_assert!(same, "state changed by a failed step");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn tc_step_never_panics(
        r in 0usize..=6,
        extra in 0usize..=2,
        h in step_size(),
        set in settings(),
        q in state(7),
        p in state(7),
    ) {
        let fpu = Fpu::new(3, 50.0).unwrap();
        match TcStepper::with_nodes(fpu.system().unwrap(), r, r + extra, h, set) {
            Err(e) => prop_assert!(expected(&e), "constructor: {e:?}"),
            Ok(mut st) => {
                let (mut q1, mut p1) = (q.clone(), p.clone());
                match st.step(&mut q1, &mut p1) {
                    Ok(_) => prop_assert!(q1.iter().chain(&p1).all(|v| v.is_finite())),
                    Err(e) => {
                        prop_assert!(expected(&e), "step: {e:?}");
                        let same = |a: &[f64], b: &[f64]| {
                            a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
                        };
                        prop_assert!(same(&q1, &q) && same(&p1, &p), "state changed");
                    }
                }
            }
        }
    }
}
