//! The concurrent stage path of large systems (`SolverSettings::parallel_min_dim`) computes
//! bit for bit the steps of the serial path: the same code per stage, only the schedule
//! differs. Each case runs two steppers that differ only in the threshold (`usize::MAX`:
//! serial; 0: concurrent whatever d) and compares the states bit for bit after every step.

use ecr::problems::{Nls, Nls2d};
use ecr_runtime::operator::Dense;
use ecr_runtime::stepper::{
    EcStepper, PARALLEL_MIN_DIM, Predictor, SolverSettings, StageSolver, StepReport,
};
use ecr_runtime::system::{Concurrent, Semilinear, System};

fn with_threshold(settings: SolverSettings, parallel_min_dim: usize) -> SolverSettings {
    SolverSettings {
        parallel_min_dim,
        ..settings
    }
}

/// `steps` steps of ECrP (r, s) serial and concurrent from `y0`; asserts equal reports and
/// bit-identical states after every step.
fn assert_identical<S: System>(
    make: impl Fn() -> S,
    y0: &[f64],
    (r, s, h): (usize, usize, f64),
    settings: SolverSettings,
    steps: usize,
    label: &str,
) {
    let mut serial =
        EcStepper::with_nodes(make(), r, s, h, with_threshold(settings, usize::MAX)).unwrap();
    let mut par = EcStepper::with_nodes(make(), r, s, h, with_threshold(settings, 0)).unwrap();
    let (mut a, mut b) = (y0.to_vec(), y0.to_vec());
    let mut sweeps = 0;
    for n in 0..steps {
        let ra: StepReport = serial.step(&mut a).unwrap();
        let rb = par.step(&mut b).unwrap();
        assert_eq!(ra, rb, "{label}: reports at step {n}");
        let same = a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits());
        assert!(same, "{label}: states differ at step {n}");
        sweeps += ra.sweeps;
    }
    // The dense output reads the step's moments: the same too.
    assert_eq!(
        serial.dense_output(0.3).unwrap(),
        par.dense_output(0.3).unwrap(),
        "{label}: dense output"
    );
    assert!(
        sweeps >= 2 * steps,
        "{label}: the iteration ran ({sweeps} sweeps)"
    );
}

/// The 1D NLS with N = 2^14 (d = 32768: at the default threshold): 20 steps of EC2P and EC3P,
/// with the constant and the extrapolating predictor, compensated and plain updates, s > r.
#[test]
fn nls_steps_are_bit_identical() {
    let p = Nls::new(1 << 14).unwrap();
    assert!(p.dim() >= PARALLEL_MIN_DIM);
    let y0 = p.initial_value();
    let h = 1.0 / 200.0;
    let extrapolate = SolverSettings {
        predictor: Predictor::Extrapolate,
        ..SolverSettings::default()
    };
    let plain = SolverSettings {
        compensated: false,
        ..SolverSettings::default()
    };
    for (rsh, settings, label) in [
        ((2, 2, h), SolverSettings::default(), "EC2P"),
        ((3, 3, h), extrapolate, "EC3P extrapolating"),
        ((2, 3, h), plain, "EC2P s = 3 plain update"),
    ] {
        assert_identical(|| p.system().unwrap(), &y0, rsh, settings, 20, label);
    }
}

/// The 2D NLS (a skew pair of the 2D circulant), 32 × 32.
#[test]
fn nls2d_steps_are_bit_identical() {
    let p = Nls2d::new(32).unwrap();
    let y0 = p.initial_value();
    let settings = SolverSettings {
        predictor: Predictor::Extrapolate,
        ..SolverSettings::default()
    };
    assert_identical(
        || p.system().unwrap(),
        &y0,
        (2, 2, 0.01),
        settings,
        10,
        "2D",
    );
}

/// A system without a concurrent bank (dense: the fused sweeps) and Newton, with g evaluated
/// concurrently through the `Concurrent` wrapper: the end of the step and the stage
/// evaluations take the concurrent path.
#[test]
fn dense_newton_with_concurrent_g_is_bit_identical() {
    let a = nalgebra::DMatrix::from_row_slice(
        4,
        4,
        &[
            0.0, 1.0, 0.0, 0.0, -4.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, -9.0, 0.0,
        ],
    );
    let make = || {
        Concurrent(Semilinear::new(
            Dense::new(a.clone()).unwrap(),
            |y: &[f64], out: &mut [f64]| {
                for (o, v) in out.iter_mut().zip(y) {
                    *o = -0.3 * v * v * v;
                }
            },
        ))
    };
    let y0 = [0.5, 0.0, -0.2, 0.3];
    for solver in [StageSolver::FixedPoint, StageSolver::Newton] {
        let settings = SolverSettings {
            solver,
            predictor: Predictor::Extrapolate,
            ..SolverSettings::default()
        };
        assert_identical(make, &y0, (3, 3, 0.05), settings, 20, "dense");
    }
}

/// A new step size rebuilds the concurrent path's workspaces with the bank.
#[test]
fn new_step_size_keeps_the_paths_identical() {
    let p = Nls::new(1 << 10).unwrap();
    let settings = |min| with_threshold(SolverSettings::default(), min);
    let mut serial =
        EcStepper::with_nodes(p.system().unwrap(), 2, 2, 0.01, settings(usize::MAX)).unwrap();
    let mut par = EcStepper::with_nodes(p.system().unwrap(), 2, 2, 0.01, settings(0)).unwrap();
    let (mut a, mut b) = (p.initial_value(), p.initial_value());
    for h in [0.01, 0.005, 0.02] {
        serial.set_step_size(h).unwrap();
        par.set_step_size(h).unwrap();
        for _ in 0..3 {
            serial.step(&mut a).unwrap();
            par.step(&mut b).unwrap();
        }
        assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
    }
}

ecr_runtime::ecr_method!(r = 3);

/// A kernel emitted by `ecr_method!` on run-time storage: its moments, which the concurrent
/// path computes from the kernel's coefficients, agree bit for bit too (and with the run-time
/// kernel's steps).
#[test]
fn macro_kernel_steps_are_bit_identical() {
    let p = Nls::new(1 << 10).unwrap();
    let h = 1.0 / 200.0;
    let settings = |min| with_threshold(SolverSettings::default(), min);
    let mut serial: Ec3Dyn<_> =
        Ec3Dyn::with_settings(p.system().unwrap(), h, settings(usize::MAX)).unwrap();
    let mut par: Ec3Dyn<_> = Ec3Dyn::with_settings(p.system().unwrap(), h, settings(0)).unwrap();
    let mut run_time = EcStepper::with_nodes(p.system().unwrap(), 3, 3, h, settings(0)).unwrap();
    let (mut a, mut b, mut c) = (p.initial_value(), p.initial_value(), p.initial_value());
    for n in 0..10 {
        serial.step(&mut a).unwrap();
        par.step(&mut b).unwrap();
        run_time.step(&mut c).unwrap();
        assert!(
            a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
            "step {n}"
        );
        assert!(
            a.iter().zip(&c).all(|(x, y)| x.to_bits() == y.to_bits()),
            "step {n}"
        );
    }
}
