//! Random `Options` and spans (proptest, fixed seed): finite, infinite, NaN, huge, tiny and
//! negative tolerances, step sizes, orders, output times and spans. `Problem::new` and
//! `Problem::solve` never panic; every `Ok` holds finite states only, at finite times inside
//! the span; every refusal has a message. (160 cases, 29 of them `Ok`, 2026-11-25.)

use ecr::problems::Duffing;
use ecr::runtime::solve::{Options, Problem, SolveError};
use proptest::prelude::*;
use proptest::test_runner::{Config as ProptestConfig, RngSeed};
use std::panic::{AssertUnwindSafe, catch_unwind};

/// Values that break numerical code.
const WILD: [f64; 14] = [
    0.0,
    -0.0,
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    1e308,
    f64::MAX,
    f64::MIN,
    1e-300,
    5e-324,
    f64::MIN_POSITIVE,
    1e15,
    -1e-12,
    -1.0,
];

/// A number in a plausible range four times in six, else a wild value or any bits at all.
fn number(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => (lo.ln()..hi.ln()).prop_map(f64::exp),
        1 => proptest::sample::select(WILD.to_vec()),
        1 => any::<u64>().prop_map(f64::from_bits),
    ]
}

#[derive(Debug, Clone)]
enum Kind {
    Tolerance(f64),
    Fixed(usize, f64),
}

fn kind() -> impl Strategy<Value = Kind> {
    prop_oneof![
        number(1e-12, 1e-2).prop_map(Kind::Tolerance),
        (0usize..12, number(1e-3, 1.0)).prop_map(|(r, h)| Kind::Fixed(r, h)),
    ]
}

#[derive(Debug, Clone)]
struct Case {
    kind: Kind,
    rtol: Option<f64>,
    atol: Option<f64>,
    orders: Option<(usize, usize)>,
    t_eval: Option<Vec<f64>>,
    t_end: f64,
    dense: bool,
    max_steps: Option<usize>,
}

fn case() -> impl Strategy<Value = Case> {
    (
        kind(),
        proptest::option::of(number(1e-12, 1e-2)),
        proptest::option::of(number(1e-12, 1e-2)),
        proptest::option::of((0usize..12, 0usize..12)),
        proptest::option::of(proptest::collection::vec(number(1e-3, 2.0), 0..6)),
        number(1e-3, 2.0),
        any::<bool>(),
        proptest::option::of(prop_oneof![
            Just(0usize),
            Just(1),
            1usize..100_000,
            Just(usize::MAX)
        ]),
    )
        .prop_map(
            |(kind, rtol, atol, orders, t_eval, t_end, dense, max_steps)| Case {
                kind,
                rtol,
                atol,
                orders,
                t_eval,
                t_end,
                dense,
                max_steps,
            },
        )
}

fn options(c: &Case) -> Options {
    let mut o = match c.kind {
        Kind::Tolerance(tol) => Options::tolerance(tol),
        Kind::Fixed(r, h) => Options::fixed(r, h),
    };
    if let Some(x) = c.rtol {
        o = o.rtol(x);
    }
    if let Some(x) = c.atol {
        o = o.atol(x);
    }
    if let Some((a, b)) = c.orders {
        o = o.orders(a..=b);
    }
    if let Some(ts) = &c.t_eval {
        o = o.t_eval(ts.iter().copied());
    }
    if c.dense {
        o = o.dense_output();
    }
    if let Some(n) = c.max_steps {
        o = o.max_steps(n);
    }
    o
}

/// At most this many steps in any run, so that a case is quick whatever it asks for.
const CAP: usize = 200_000;

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 160,
        rng_seed: RngSeed::Fixed(20261125),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn random_options_never_panic_nor_return_non_finite_states(c in case()) {
        let d = Duffing::default();
        let outcome = catch_unwind(AssertUnwindSafe(|| {
            let problem = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, c.t_end))?;
            let o = options(&c).max_steps(c.max_steps.unwrap_or(CAP).min(CAP));
            problem.solve(&o)
        }));
        let result = match outcome {
            Ok(r) => r,
            Err(_) => panic!("solve panicked on {c:?}"),
        };
        match result {
            Ok(sol) => {
                let none_asked = c.t_eval.as_ref().is_some_and(Vec::is_empty);
                prop_assert!(!sol.t.is_empty() || none_asked, "Ok without output: {c:?}");
                for (t, y) in sol.t.iter().zip(&sol.y) {
                    prop_assert!(t.is_finite() && *t >= 0.0 && *t <= c.t_end, "t = {t} in {c:?}");
                    prop_assert!(y.iter().all(|v| v.is_finite()), "non-finite state at {t}: {c:?}");
                }
                if let Some(e) = sol.error_estimate {
                    prop_assert!(e.is_finite() && e <= 1.0, "Ok with estimate {e}: {c:?}");
                }
            }
            Err(SolveError::Unverified { reason, .. }) => {
                prop_assert!(!reason.is_empty());
            }
            Err(e) => {
                prop_assert!(!e.to_string().is_empty());
            }
        }
    }
}
