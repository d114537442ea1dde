//! The series of the work–precision runs: what a series is ([`Series`]: a method with fixed
//! parameters, swept over step sizes or tolerances), how its method runs ([`Run`]), the stage
//! solver and the Duffing parameters every series of the benchmark shares, and the small
//! systems as a user writes them. The run-time, macro and peer series are built on it
//! (`sweep.rs`, `macros.rs`, `peers.rs`).

use crate::cli::reproduce::methods::BoxedIntegrator;
use ecr_runtime::integrate::{IntegrateOptions, integrate};
use ecr_runtime::nalgebra::{DMatrix, SMatrix};
use ecr_runtime::operator::DenseStatic;
use ecr_runtime::stepper::{Predictor, SolverSettings};
use ecr_runtime::system::{Semilinear, System};
use std::hint::black_box;
use std::time::Instant;

/// The stage solver of every implicit method in the benchmark (ECrP, TCrP, HBVM family):
/// the defaults (tolerance 1e-15, convergence required) with the extrapolating predictor.
pub fn solver() -> SolverSettings {
    SolverSettings {
        predictor: Predictor::Extrapolate,
        ..SolverSettings::default()
    }
}

/// Duffing of the benchmark.
pub const OMEGA: f64 = 20.0;
pub const K: f64 = 0.07;

/// What a series sweeps over.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Knob {
    /// Step sizes h0/2^i.
    Step { h0: f64 },
    /// DOP853 tolerances (rtol = atol), one call over [0, T].
    Tol,
}

/// Which kind of method a series is: the summary compares the best of this project's
/// methods (run-time and `ecr_method!` steppers) with the best peer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Family {
    /// ECrP/TCrP with the run-time-r stepper (what `ecr run` uses).
    Runtime,
    /// ECrP with the fixed-order stepper of `ecr_method!`.
    Macro,
    /// Any other method.
    Peer,
}

impl Family {
    /// This project's methods (either stepper).
    pub fn is_ours(self) -> bool {
        self != Family::Peer
    }
}

/// Called with the state after every step.
pub type Observe<'a> = &'a mut dyn FnMut(&[f64]);

/// A method ready to integrate, its set-up done.
pub trait Run {
    /// Integrates y over [0, t_end] in place, calling `observe(y)` after every step when
    /// given (accepted steps for adaptive methods).
    /// Returns the evaluations of g the method reports (DOP853: of f = Ay + g).
    fn run(
        &mut self,
        y: &mut [f64],
        t_end: f64,
        observe: Option<Observe<'_>>,
    ) -> Result<usize, String>;
}

/// A fixed-step integrator, driven by [`integrate`].
struct Stepped(BoxedIntegrator);

impl Run for Stepped {
    fn run(
        &mut self,
        y: &mut [f64],
        t_end: f64,
        observe: Option<Observe<'_>>,
    ) -> Result<usize, String> {
        let options = IntegrateOptions {
            energy_every: 0,
            observe_every: usize::from(observe.is_some()),
        };
        match observe {
            Some(f) => integrate(&mut self.0, 0.0, t_end, y, options, |_, y, _| f(y)),
            None => integrate(&mut self.0, 0.0, t_end, y, options, |_, _, _| {}),
        }
        .map(|report| report.g_evals)
        .map_err(err_s)
    }
}

/// A built method.
pub type BoxedRun = Box<dyn Run>;

/// Wraps a fixed-step integrator as a [`Run`].
pub fn stepped(integrator: ecr_runtime::Result<BoxedIntegrator>) -> ecr_runtime::Result<BoxedRun> {
    Ok(Box::new(Stepped(integrator?)))
}

/// Builds a series's method for h (or tol).
pub type BuildFn = Box<dyn Fn(f64) -> ecr_runtime::Result<BoxedRun>>;

/// Times `n` evaluations of the g a series' stepper calls, cycling through the given states;
/// returns the fastest of `repeats` timings (seconds).
pub type GCostFn = Box<dyn Fn(&[Vec<f64>], usize, usize) -> ecr_runtime::Result<f64>>;

/// The fastest of `repeats` timings of `n` evaluations of `sys`'s g (what its stepper calls on
/// the hot path, with the same scratch), cycling through `states`; `black_box` keeps every
/// evaluation (nothing hoisted, no output dropped).
pub fn time_g<S: System>(sys: &S, states: &[Vec<f64>], n: usize, repeats: usize) -> f64 {
    let mut out = vec![0.0; sys.dim()];
    let mut scratch = vec![0.0; sys.scratch_len()];
    let mut best = f64::INFINITY;
    for _ in 0..repeats.max(1) {
        let start = Instant::now();
        for y in states.iter().cycle().take(n) {
            sys.nonlinear(black_box(y), black_box(&mut out), black_box(&mut scratch));
        }
        black_box(&out);
        best = best.min(start.elapsed().as_secs_f64());
    }
    best
}

/// One curve: a method with fixed parameters.
pub struct Series {
    pub label: String,
    /// Panel of the figures it is drawn in.
    pub group: &'static str,
    pub family: Family,
    pub r: Option<usize>,
    pub s: Option<usize>,
    pub knob: Knob,
    /// Builds the integrator for h (Step) or tol (Tol).
    pub build: BuildFn,
    /// This project's series: the cost of evaluating its stepper's g (the points record their
    /// g evaluations and that cost).
    pub g_cost: Option<GCostFn>,
}

impl Series {
    pub fn with_rs(mut self, r: usize, s: usize) -> Self {
        self.r = Some(r);
        self.s = Some(s);
        self
    }

    /// Marks a series as one of this project's methods with the run-time stepper, whose g
    /// costs `g_cost`.
    pub fn ours(mut self, g_cost: GCostFn) -> Self {
        self.family = Family::Runtime;
        self.g_cost = Some(g_cost);
        self
    }
}

pub fn step_series(
    label: &str,
    group: &'static str,
    h0: f64,
    build: impl Fn(f64) -> ecr_runtime::Result<BoxedIntegrator> + 'static,
) -> Series {
    Series {
        label: label.to_string(),
        group,
        family: Family::Peer,
        r: None,
        s: None,
        knob: Knob::Step { h0 },
        build: Box::new(move |h| stepped(build(h))),
        g_cost: None,
    }
}

fn static_2x2(a: &DMatrix<f64>) -> ecr_runtime::Result<DenseStatic<2>> {
    DenseStatic::new(SMatrix::<f64, 2, 2>::from_iterator(a.iter().copied()))
}

/// y' = Ay + g(y) with a 2 × 2 A as a static matrix and g a closure: how a user writes a
/// small system.
pub fn static_system<G: Fn(&[f64], &mut [f64])>(
    a: &DMatrix<f64>,
    g: G,
) -> ecr_runtime::Result<Semilinear<DenseStatic<2>, G>> {
    Ok(Semilinear::new(static_2x2(a)?, g))
}

fn err_s(e: ecr_runtime::Error) -> String {
    e.to_string()
}
