//! DOP853 (Dormand–Prince 8(5,3), Hairer–Nørsett–Wanner) as a fixed-macro-step
//! [`Integrator`]: what many users would pick instead of an exponential method (DESIGN.md §5).
//!
//! Each macro step of size h integrates y' = f(y) = Ay + g(y) from 0 to h with the adaptive
//! step-size control of the `ode_solvers` crate's [`ode_solvers::Dop853`] (relative and
//! absolute tolerances, default 1e−12), so the macro step only fixes where the state is
//! reported. The internal step size is carried over from one macro step to the next (the
//! first macro step uses the code's initial step heuristic). Not allocation-free: the crate
//! allocates its stage vectors on every call.

use std::cell::{Cell, RefCell};

use ode_solvers::{DVector, OutputType};

use crate::integrate::Integrator;
use crate::operator::LinearOperator;
use crate::stepper::StepReport;
use crate::system::System;
use crate::{Error, Result};

/// Cumulative statistics of a [`Dop853`] over all its macro steps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Dop853Stats {
    /// Evaluations of f = Ay + g (each is one evaluation of g).
    pub f_evals: usize,
    /// Accepted internal steps.
    pub accepted: usize,
    /// Rejected internal steps.
    pub rejected: usize,
}

/// f(y) = Ay + g(y) for `ode_solvers`, flagging non-finite values.
struct Rhs<'a, S: System> {
    system: &'a S,
    g: &'a RefCell<Vec<f64>>,
    scratch: &'a RefCell<Vec<f64>>,
    non_finite: &'a Cell<bool>,
}

impl<S: System> Rhs<'_, S> {
    fn eval(&self, y: &[f64], dy: &mut [f64]) {
        let mut g = self.g.borrow_mut();
        let mut scratch = self.scratch.borrow_mut();
        self.system.linear().apply(y, dy);
        self.system.nonlinear(y, &mut g, &mut scratch);
        for (d, gi) in dy.iter_mut().zip(g.iter()) {
            *d += gi;
        }
        if dy.iter().any(|v| !v.is_finite()) {
            self.non_finite.set(true);
        }
    }
}

impl<S: System> ode_solvers::System<f64, DVector<f64>> for Rhs<'_, S> {
    fn system(&self, _x: f64, y: &DVector<f64>, dy: &mut DVector<f64>) {
        self.eval(y.as_slice(), dy.as_mut_slice());
    }
}

/// DOP853 with adaptive internal steps over each macro step of size h.
pub struct Dop853<S: System> {
    system: S,
    h: f64,
    rtol: f64,
    atol: f64,
    max_internal_steps: u32,
    /// Internal step size to start the next macro step with (0: the code's heuristic).
    h_internal: f64,
    stats: Dop853Stats,
    g: RefCell<Vec<f64>>,
    scratch: RefCell<Vec<f64>>,
    f0: Vec<f64>,
}

impl<S: System> Dop853<S> {
    /// DOP853 with macro step h and rtol = atol = 1e−12.
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`] if h is not finite and positive.
    pub fn new(system: S, h: f64) -> Result<Self> {
        Self::with_tolerances(system, h, 1e-12, 1e-12)
    }

    /// DOP853 with macro step h and the given tolerances (the error of each internal step is
    /// measured against `atol + rtol·|y_i|`, as in Hairer's code).
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`]; [`Error::InvalidParameter`] unless rtol and atol are finite
    /// and positive; the errors of [`check_system`](crate::system::check_system).
    pub fn with_tolerances(system: S, h: f64, rtol: f64, atol: f64) -> Result<Self> {
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidStepSize(h));
        }
        for (name, tol) in [("rtol", rtol), ("atol", atol)] {
            if !(tol.is_finite() && tol > 0.0) {
                return Err(Error::InvalidParameter(format!(
                    "DOP853 {name} = {tol} must be finite and > 0"
                )));
            }
        }
        crate::system::check_system(&system)?;
        let d = system.dim();
        let scratch = RefCell::new(vec![0.0; system.scratch_len()]);
        Ok(Dop853 {
            system,
            h,
            rtol,
            atol,
            max_internal_steps: 100_000,
            h_internal: 0.0,
            stats: Dop853Stats::default(),
            g: RefCell::new(vec![0.0; d]),
            scratch,
            f0: vec![0.0; d],
        })
    }

    /// Sets the largest number of internal steps (accepted or rejected) in one macro step
    /// (default 100 000).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] if `n` is 0.
    pub fn set_max_internal_steps(&mut self, n: u32) -> Result<()> {
        if n == 0 {
            return Err(Error::InvalidParameter(
                "DOP853 needs at least one internal step".into(),
            ));
        }
        self.max_internal_steps = n;
        Ok(())
    }

    /// The system.
    pub fn system(&self) -> &S {
        &self.system
    }

    /// The macro step size.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// (rtol, atol).
    pub fn tolerances(&self) -> (f64, f64) {
        (self.rtol, self.atol)
    }

    /// Cumulative statistics of all macro steps so far.
    pub fn stats(&self) -> Dop853Stats {
        self.stats
    }

    /// Changes the macro step size.
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`].
    pub fn set_step_size(&mut self, h: f64) -> Result<()> {
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidStepSize(h));
        }
        self.h = h;
        Ok(())
    }

    /// Integrates y over one macro step of size h in place; `g_evals` of the report counts
    /// the evaluations of f (including the initial-step heuristic's).
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] for a wrong length, [`Error::NonFinite`] if y or f is
    /// NaN/infinite, [`Error::Numerical`] if the code gives up (too many internal steps, step
    /// size underflow, stiffness detected). On error, y is unchanged.
    pub fn step(&mut self, y: &mut [f64]) -> Result<StepReport> {
        let d = self.system.dim();
        if y.len() != d {
            return Err(Error::DimensionMismatch {
                what: "state y",
                expected: d,
                found: y.len(),
            });
        }
        if y.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("state y"));
        }
        let non_finite = Cell::new(false);
        let rhs = Rhs {
            system: &self.system,
            g: &self.g,
            scratch: &self.scratch,
            non_finite: &non_finite,
        };
        // A non-finite f(y0) would make the code shrink its step until it gives up.
        rhs.eval(y, &mut self.f0);
        if non_finite.get() {
            return Err(Error::NonFinite("f(y) = Ay + g(y)"));
        }
        let h = self.h;
        let h_start = self.h_internal.min(h);
        let mut solver = ode_solvers::Dop853::from_param(
            rhs,
            0.0,
            h,
            h,
            DVector::from_column_slice(y),
            self.rtol,
            self.atol,
            0.9,   // safety factor (Hairer's default)
            0.0,   // beta: no PI control (default)
            0.333, // fac_min (default)
            6.0,   // fac_max (default)
            h,     // h_max
            h_start,
            self.max_internal_steps,
            1000, // stiffness test every 1000 accepted steps (default)
            OutputType::Sparse,
        );
        let result = solver.integrate();
        if non_finite.get() {
            return Err(Error::NonFinite("f(y) = Ay + g(y) at an internal stage"));
        }
        let stats = result.map_err(|e| Error::Numerical(format!("DOP853: {e}")))?;
        let y1 = solver
            .y_out()
            .last()
            .ok_or_else(|| Error::Numerical("DOP853 returned no state".into()))?;
        if y1.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("DOP853 step result"));
        }
        y.copy_from_slice(y1.as_slice());
        let accepted = stats.accepted_steps as usize;
        let f_evals = stats.num_eval as usize + 1;
        self.stats.f_evals += f_evals;
        self.stats.accepted += accepted;
        self.stats.rejected += stats.rejected_steps as usize;
        if accepted > 0 {
            self.h_internal = h / accepted as f64;
        }
        Ok(StepReport {
            sweeps: 0,
            residual: 0.0,
            g_evals: f_evals,
            converged: true,
        })
    }
}

impl<S: System> Integrator for Dop853<S> {
    fn step_size(&self) -> f64 {
        self.h
    }
    fn set_step_size(&mut self, h: f64) -> Result<()> {
        Dop853::set_step_size(self, h)
    }
    fn step_state(&mut self, y: &mut [f64]) -> Result<StepReport> {
        self.step(y)
    }
    fn energy_of(&self, y: &[f64]) -> Option<f64> {
        self.system.energy(y)
    }
}
