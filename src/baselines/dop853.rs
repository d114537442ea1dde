//! DOP853 (Dormand–Prince 8(5,3), Hairer–Nørsett–Wanner), from the `ode_solvers` crate, used
//! the way its users use it: what many users would pick instead of an exponential method
//! (`docs/architecture.md#baselines`).
//!
//! [`Dop853::integrate`] is **one call of the crate over [t0, T]**: its own step-size control
//! from the initial-step heuristic to the end, no restarts, and the state in a fixed-size
//! `SVector` for the dimensions listed in [`FIXED_DIMS`] (so that no step allocates; other
//! dimensions use the crate's `DVector`, which allocates its stage vectors as the crate
//! does). Output is the crate's cheapest, `OutputType::Sparse` (the accepted steps, no dense
//! output coefficients); an observer sees every accepted step through the crate's `solout`
//! hook. [`Dop853::integrate_dense`] is the same one call with the crate's dense output at
//! the multiples of a spacing dx (what its users ask for to get values at output times).
//!
//! [`Dop853Stepper`] adapts it to the fixed-output-step [`Integrator`] interface (one call of
//! the crate per output step h, the internal step size carried over): it exists for
//! comparisons that need the state at every multiple of h, and pays a restart per output
//! step. Speed comparisons use [`Dop853::integrate`].

use std::cell::{Cell, RefCell};

use ode_solvers::{DVector, OutputType, SVector};

use ecr_runtime::integrate::Integrator;
use ecr_runtime::operator::LinearOperator;
use ecr_runtime::stepper::StepReport;
use ecr_runtime::system::System;
use ecr_runtime::{Error, Result};

/// Dimensions whose state is a fixed-size `SVector` (no allocation per step); any other
/// dimension uses a heap `DVector`.
pub const FIXED_DIMS: [usize; 10] = [1, 2, 3, 4, 6, 8, 12, 16, 32, 256];

/// Statistics of one or more integrations.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Dop853Stats {
    /// Evaluations of f = Ay + g (each is one evaluation of g), the initial-step heuristic's
    /// included.
    pub f_evals: usize,
    /// Accepted steps.
    pub accepted: usize,
    /// Rejected steps.
    pub rejected: usize,
}

impl Dop853Stats {
    fn add(&mut self, other: Dop853Stats) {
        self.f_evals += other.f_evals;
        self.accepted += other.accepted;
        self.rejected += other.rejected;
    }
}

/// An observer of the accepted steps: (t, y).
pub type Observer<'a> = &'a mut dyn FnMut(f64, &[f64]);

/// f(y) = Ay + g(y) for `ode_solvers`, flagging non-finite values; `solout` calls the observer
/// and stops the integration once a non-finite value was seen.
struct Rhs<'a, 'o, S: System> {
    system: &'a S,
    /// g(y) and the system's scratch (borrowed per evaluation: `ode_solvers` passes `&self`).
    buffers: RefCell<(Vec<f64>, Vec<f64>)>,
    /// `scratch_len() > 0`.
    needs_scratch: bool,
    non_finite: &'a Cell<bool>,
    observer: Option<Observer<'o>>,
}

impl<S: System> Rhs<'_, '_, S> {
    /// f(y) with g(y) written into the heap buffer.
    fn eval(&self, y: &[f64], dy: &mut [f64]) {
        let mut buffers = self.buffers.borrow_mut();
        let (g, scratch) = &mut *buffers;
        self.eval_into(y, dy, g, scratch);
    }

    /// f(y) with g(y) in `g`.
    #[inline]
    fn eval_into(&self, y: &[f64], dy: &mut [f64], g: &mut [f64], scratch: &mut [f64]) {
        self.system.linear().apply(y, dy);
        self.system.nonlinear(y, g, scratch);
        // One sum instead of a test per entry: a NaN or ±∞ entry makes it non-finite (so
        // does an overflow of the sum itself, at values where the state overflows anyway).
        let mut sum = 0.0;
        for (d, gi) in dy.iter_mut().zip(g.iter()) {
            *d += gi;
            sum += *d;
        }
        if !sum.is_finite() {
            self.non_finite.set(true);
        }
    }

    fn accepted(&mut self, t: f64, y: &[f64]) -> bool {
        if let Some(observer) = self.observer.as_mut() {
            observer(t, y);
        }
        self.non_finite.get()
    }
}

impl<const N: usize, S: System> ode_solvers::System<f64, SVector<f64, N>> for Rhs<'_, '_, S> {
    fn system(&self, _t: f64, y: &SVector<f64, N>, dy: &mut SVector<f64, N>) {
        // g on the stack: no borrow of the shared buffers where the system needs no scratch.
        let mut g = [0.0; N];
        if self.needs_scratch {
            let mut buffers = self.buffers.borrow_mut();
            self.eval_into(y.as_slice(), dy.as_mut_slice(), &mut g, &mut buffers.1);
        } else {
            self.eval_into(y.as_slice(), dy.as_mut_slice(), &mut g, &mut []);
        }
    }
    fn solout(&mut self, t: f64, y: &SVector<f64, N>, _dy: &SVector<f64, N>) -> bool {
        self.accepted(t, y.as_slice())
    }
}

impl<S: System> ode_solvers::System<f64, DVector<f64>> for Rhs<'_, '_, S> {
    fn system(&self, _t: f64, y: &DVector<f64>, dy: &mut DVector<f64>) {
        self.eval(y.as_slice(), dy.as_mut_slice());
    }
    fn solout(&mut self, t: f64, y: &DVector<f64>, _dy: &DVector<f64>) -> bool {
        self.accepted(t, y.as_slice())
    }
}

/// DOP853 with relative and absolute tolerances on a [`System`].
pub struct Dop853<S: System> {
    system: S,
    rtol: f64,
    atol: f64,
    max_steps: u32,
}

/// What one call of the crate needs besides the right-hand side.
struct Call {
    t0: f64,
    t_end: f64,
    /// Initial step size (0: the code's heuristic).
    h_start: f64,
    /// Largest step size.
    h_max: f64,
    /// The spacing of the dense output (`None`: the accepted steps' end points, of which
    /// only the last is returned).
    dense: Option<f64>,
}

/// What one call returns: the crate's result and its outputs (all dense outputs, or the
/// last accepted step's state).
type CallOutput = (CrateResult, Vec<f64>, Vec<Vec<f64>>);

/// One call of `ode_solvers::Dop853` with the state type `$vec` built from `$y0`.
macro_rules! call_crate {
    ($self:ident, $rhs:ident, $call:ident, $y:ident, $vec:ty) => {{
        let mut solver = ode_solvers::Dop853::from_param(
            $rhs,
            $call.t0,
            $call.t_end,
            $call.dense.unwrap_or($call.t_end - $call.t0),
            <$vec>::from_column_slice($y),
            $self.rtol,
            $self.atol,
            0.9,   // safety factor (Hairer's default)
            0.0,   // beta: no PI control (default)
            0.333, // fac_min (default)
            6.0,   // fac_max (default)
            $call.h_max,
            $call.h_start,
            $self.max_steps,
            1000, // stiffness test every 1000 accepted steps (default)
            if $call.dense.is_some() {
                OutputType::Dense
            } else {
                OutputType::Sparse
            },
        );
        let result = solver.integrate();
        if $call.dense.is_some() {
            let ys = solver
                .y_out()
                .iter()
                .map(|v| v.as_slice().to_vec())
                .collect();
            (result, solver.x_out().clone(), ys)
        } else {
            let last = solver.y_out().last().map(|v| v.as_slice().to_vec());
            (result, Vec::new(), last.into_iter().collect())
        }
    }};
}

impl<S: System> Dop853<S> {
    /// DOP853 with the given tolerances (the error of each step is measured against
    /// `atol + rtol·|y_i|`, as in Hairer's code).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] unless rtol and atol are finite and positive; the errors of
    /// [`check_system`](ecr_runtime::system::check_system).
    pub fn new(system: S, rtol: f64, atol: f64) -> Result<Self> {
        for (name, tol) in [("rtol", rtol), ("atol", atol)] {
            if !(tol.is_finite() && tol > 0.0) {
                return Err(Error::InvalidParameter(format!(
                    "DOP853 {name} = {tol:e} must be finite and > 0"
                )));
            }
        }
        ecr_runtime::system::check_system(&system)?;
        Ok(Dop853 {
            system,
            rtol,
            atol,
            max_steps: u32::MAX,
        })
    }

    /// Sets the largest number of steps (accepted or rejected) of one integration (default:
    /// no limit).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] if `n` is 0.
    pub fn set_max_steps(&mut self, n: u32) -> Result<()> {
        if n == 0 {
            return Err(Error::InvalidParameter(
                "DOP853 needs at least one step".into(),
            ));
        }
        self.max_steps = n;
        Ok(())
    }

    /// The system.
    pub fn system(&self) -> &S {
        &self.system
    }

    /// (rtol, atol).
    pub fn tolerances(&self) -> (f64, f64) {
        (self.rtol, self.atol)
    }

    /// Integrates y from t0 to t_end in place: one call of the crate.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] unless t0 < t_end are finite, [`Error::DimensionMismatch`] for
    /// a wrong length, [`Error::NonFinite`] if y or f is NaN/infinite, [`Error::Numerical`]
    /// if the code gives up (too many steps, step size underflow, stiffness detected). On
    /// error, y is unchanged.
    pub fn integrate(&self, t0: f64, t_end: f64, y: &mut [f64]) -> Result<Dop853Stats> {
        self.run(t0, t_end, 0.0, y, None)
    }

    /// As [`integrate`](Self::integrate), calling `observer(t, y)` after every accepted step.
    ///
    /// # Errors
    /// As [`integrate`](Self::integrate).
    pub fn integrate_observed(
        &self,
        t0: f64,
        t_end: f64,
        y: &mut [f64],
        observer: Observer<'_>,
    ) -> Result<Dop853Stats> {
        self.run(t0, t_end, 0.0, y, Some(observer))
    }

    /// As [`integrate`](Self::integrate) (one call of the crate), with the crate's dense
    /// output: the states at t0, t0 + dx, t0 + 2dx, …, t_end from the method's 7th-order
    /// continuous extension of each accepted step, at the times as the crate accumulates them
    /// (`t += dx`, so within rounding of the multiples of dx). Returns the output times, the
    /// states there and the statistics; y is left at the last output. The crate is called
    /// over [t0, t_end + 1e−8 (1 + |t_end|)]: its own end point is an extrapolation from the
    /// step before (ode_solvers 0.6.2), so t_end is an interior output; the output at t0 is
    /// y itself (the crate's is the state after its first step).
    ///
    /// # Errors
    /// As [`integrate`](Self::integrate); [`Error::InvalidParameter`] unless dx is finite and
    /// positive; [`Error::Numerical`] when the outputs do not end at t_end (dx must divide
    /// t_end − t0).
    pub fn integrate_dense(
        &self,
        t0: f64,
        t_end: f64,
        dx: f64,
        y: &mut [f64],
    ) -> Result<(Vec<f64>, Vec<Vec<f64>>, Dop853Stats)> {
        if !(dx.is_finite() && dx > 0.0) {
            return Err(Error::InvalidParameter(format!(
                "DOP853 dense output spacing dx = {dx:e} must be finite and > 0"
            )));
        }
        let mut ts = Vec::new();
        let mut ys = Vec::new();
        let stats = self.call(t0, t_end, 0.0, Some(dx), y, None, &mut ts, &mut ys)?;
        Ok((ts, ys, stats))
    }

    fn run(
        &self,
        t0: f64,
        t_end: f64,
        h_start: f64,
        y: &mut [f64],
        observer: Option<Observer<'_>>,
    ) -> Result<Dop853Stats> {
        let (mut ts, mut ys) = (Vec::new(), Vec::new());
        self.call(t0, t_end, h_start, None, y, observer, &mut ts, &mut ys)
    }

    /// One call of the crate; with `dense`, its dense outputs in `ts`, `ys`.
    #[allow(clippy::too_many_arguments)]
    fn call(
        &self,
        t0: f64,
        t_end: f64,
        h_start: f64,
        dense: Option<f64>,
        y: &mut [f64],
        observer: Option<Observer<'_>>,
        ts: &mut Vec<f64>,
        ys: &mut Vec<Vec<f64>>,
    ) -> Result<Dop853Stats> {
        let d = self.system.dim();
        if y.len() != d {
            return Err(Error::DimensionMismatch {
                what: "state y",
                expected: d,
                found: y.len(),
            });
        }
        if !(t0.is_finite() && t_end.is_finite() && t_end > t0) {
            return Err(Error::InvalidInput(format!(
                "DOP853 needs finite t0 < t_end, got [{t0:e}, {t_end:e}]"
            )));
        }
        if y.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("state y"));
        }
        let non_finite = Cell::new(false);
        let rhs = Rhs {
            system: &self.system,
            buffers: RefCell::new((vec![0.0; d], vec![0.0; self.system.scratch_len()])),
            needs_scratch: self.system.scratch_len() > 0,
            non_finite: &non_finite,
            observer,
        };
        // A non-finite f(y0) would make the code shrink its step until it gives up.
        let mut f0 = vec![0.0; d];
        rhs.eval(y, &mut f0);
        if non_finite.get() {
            return Err(Error::NonFinite("f(y) = Ay + g(y)"));
        }
        // ode_solvers 0.6.2's dense output pushes its point "at t_end" as soon as the next
        // output time comes within 1e−9 of the end of the integration, which is right after
        // the output before it: an extrapolation of that step (measured: Lotka–Volterra's
        // state at t_end off by 1e−2 at any rtol). Integrating 1e−8 (1 + |t_end|) further
        // keeps the output at t_end an interpolation on the step that contains it.
        let crate_end = match dense {
            Some(_) => t_end + 1e-8 * (1.0 + t_end.abs()),
            None => t_end,
        };
        let call = Call {
            t0,
            t_end: crate_end,
            h_start,
            h_max: t_end - t0,
            dense,
        };
        let (result, xs, mut outputs) = self.dispatch(rhs, &call, y);
        if non_finite.get() {
            return Err(Error::NonFinite("f(y) = Ay + g(y) at a stage"));
        }
        let stats = result.map_err(|e| Error::Numerical(format!("DOP853: {e}")))?;
        if outputs.iter().flatten().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("DOP853 result"));
        }
        if let Some(dx) = dense {
            // The crate accumulates the output times (t += dx): the last is t_end only to
            // within that sum's rounding, and it is missing where dx does not divide the span.
            *ts = xs;
            let last = ts.last().copied().unwrap_or(f64::NAN);
            if last.is_nan() || (last - t_end).abs() > 1e-9 * (t_end.abs() + dx) {
                return Err(Error::Numerical(format!(
                    "DOP853's dense output ends at t = {last:e}, not at t_end = {t_end:e} \
                     (dx must divide the span)"
                )));
            }
            // The crate's output at t0 is the state after its first step (0.6.2): t0's own.
            if ts.first() == Some(&t0) {
                outputs[0].copy_from_slice(y);
            }
            y.copy_from_slice(outputs.last().expect("t_end's output"));
            *ys = outputs;
        } else {
            let y1 = outputs
                .pop()
                .ok_or_else(|| Error::Numerical("DOP853 returned no state".into()))?;
            y.copy_from_slice(&y1);
        }
        Ok(Dop853Stats {
            // + 1: the check of f(y0) above.
            f_evals: stats.num_eval as usize + 1,
            accepted: stats.accepted_steps as usize,
            rejected: stats.rejected_steps as usize,
        })
    }

    /// Calls the crate with the fixed-size state type for `d` where there is one.
    fn dispatch(&self, rhs: Rhs<'_, '_, S>, call: &Call, y: &[f64]) -> CallOutput {
        macro_rules! fixed {
            ($($n:literal),*) => {
                match y.len() {
                    $($n => return call_crate!(self, rhs, call, y, SVector<f64, $n>),)*
                    _ => call_crate!(self, rhs, call, y, DVector<f64>),
                }
            };
        }
        fixed!(1, 2, 3, 4, 6, 8, 12, 16, 32, 256)
    }
}

type CrateResult =
    std::result::Result<ode_solvers::dop_shared::Stats, ode_solvers::dop_shared::IntegrationError>;

/// [`Dop853`] as a fixed-output-step [`Integrator`]: each step of size h is one call of the
/// crate over [0, h], starting with the internal step size the previous call ended with
/// (the first uses the code's heuristic). For output at every multiple of h; it pays a
/// restart per output step, so timings use [`Dop853::integrate`].
pub struct Dop853Stepper<S: System> {
    dop: Dop853<S>,
    h: f64,
    /// Internal step size to start the next call with (0: the code's heuristic).
    h_internal: f64,
    stats: Dop853Stats,
}

impl<S: System> Dop853Stepper<S> {
    /// Output step h, rtol = atol = 1e−12.
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`] if h is not finite and positive.
    pub fn new(system: S, h: f64) -> Result<Self> {
        Self::with_tolerances(system, h, 1e-12, 1e-12)
    }

    /// Output step h and the given tolerances.
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`]; as [`Dop853::new`].
    pub fn with_tolerances(system: S, h: f64, rtol: f64, atol: f64) -> Result<Self> {
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidStepSize(h));
        }
        Ok(Dop853Stepper {
            dop: Dop853::new(system, rtol, atol)?,
            h,
            h_internal: 0.0,
            stats: Dop853Stats::default(),
        })
    }

    /// The underlying integrator.
    pub fn dop853(&self) -> &Dop853<S> {
        &self.dop
    }

    /// Cumulative statistics of all steps so far.
    pub fn stats(&self) -> Dop853Stats {
        self.stats
    }

    /// One output step of size h in place.
    ///
    /// # Errors
    /// As [`Dop853::integrate`]; on error, y is unchanged.
    pub fn step(&mut self, y: &mut [f64]) -> Result<StepReport> {
        let stats = self
            .dop
            .run(0.0, self.h, self.h_internal.min(self.h), y, None)?;
        self.stats.add(stats);
        if stats.accepted > 0 {
            self.h_internal = self.h / stats.accepted as f64;
        }
        Ok(StepReport {
            sweeps: 0,
            residual: 0.0,
            g_evals: stats.f_evals,
            converged: true,
            jacobian_evals: 0,
            newton_refreshes: 0,
        })
    }
}

impl<S: System> Integrator for Dop853Stepper<S> {
    fn step_size(&self) -> f64 {
        self.h
    }
    fn set_step_size(&mut self, h: f64) -> Result<()> {
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidStepSize(h));
        }
        self.h = h;
        Ok(())
    }
    fn step_state(&mut self, y: &mut [f64]) -> Result<StepReport> {
        self.step(y)
    }
    fn energy_of(&self, y: &[f64]) -> Option<f64> {
        self.dop.system.energy(y)
    }
}
