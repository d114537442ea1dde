//! Ask for an accuracy, get a verified answer where you want it: [`Problem`] →
//! [`Problem::solve`] → [`Solution`].
//!
//! ```
//! use ecr_runtime::prelude::*;
//!
//! // H(q, p) = ½p² + ½q² + ¼q⁴, y = (q, p); ∇V is written into zeros.
//! let grad_v = |y: &[f64], g: &mut [f64]| g[0] = y[0].powi(3);
//! let system = Hamiltonian::canonical(DMatrix::identity(2, 2), grad_v)?
//!     .potential(|y| 0.25 * y[0].powi(4));
//! let options = Options::tolerance(1e-9).t_eval(linspace(0.0, 50.0, 11)).dense_output();
//! let sol = Problem::new(system, [1.0, 0.0], (0.0, 50.0))?.solve(&options)?;
//! assert_eq!(sol.t.len(), 11);
//! // Ok means: the estimated global error is within the tolerance at every output time.
//! assert!(sol.error_estimates.iter().all(|&e| e <= 1.0));
//! // H is kept to the order of the method, without drift.
//! assert!(sol.energy_error().unwrap() < 1e-9);
//! // Between grid points too (checked there as well).
//! let y = sol.at(27.3)?;
//! assert!(y[0].abs() <= 1.0 + 1e-9);
//! # Ok::<(), ecr_runtime::Error>(())
//! ```
//!
//! # The promise
//!
//! With a tolerance (every [`Method`] but `Fixed`), `Ok(solution)` means that an a-posteriori
//! estimate of the global error at every output time — every `t_eval` point (and every
//! located event), or without `t_eval` every point where the error was checked — is at most
//! 1 in the norm `max_i |e_i| / (atol + rtol |y_i|)`: [`Solution::error_estimates`] holds
//! them. The estimate covers the whole span: it is not extrapolated from a part of it. When
//! the solve cannot verify its answer (a tolerance below the round-off floor of the run,
//! chaos beyond predictability at that tolerance, a singularity, a right-hand side not
//! smooth enough for the order) it returns [`SolveError::Unverified`], which says why and
//! carries the best solution it has with its estimates.
//!
//! # How it is checked
//!
//! The run that is returned (ECrP of order 2r, step h) is integrated together with two runs
//! of steps 2h and 4h over the whole span; the grids meet at every second step. Where the
//! answer and the 2h run meet, their difference D over 2^q − 1 estimates the answer's error
//! (Richardson); q is the order the runs show: log₂ of the ratio of the largest 4h–2h
//! difference to the largest 2h–h difference so far (at most 2r; where the difference does
//! not shrink as the step does — the runs are far from the asymptotic regime, or apart by
//! chaos — q is small and the whole difference counts). The estimate never goes below a
//! model of the run's round-off. Between grid points (output times, events) each run is
//! stepped from its last meeting point: the answer in two steps of half the distance, the
//! 2h run in one.
//!
//! # How the step is chosen
//!
//! Pilots integrate a few steps from t₀ with the three runs for a few orders r (from one more r per two decades of tolerance, up and down while the predicted
//! cost falls, within [`Options::orders`]) and project the estimate to the end of the span
//! by its growth over the window. The run then goes in chunks (1/64 of the span at first,
//! growing to 1/8); a chunk whose estimate anywhere exceeds the tolerance is integrated again
//! with a smaller step, and after each kept chunk the estimate so far is projected to the end
//! to set the step of the rest. The step is constant over long stretches
//! ([`Solution::segments`], few): a step that changes from step to step destroys ECrP's
//! long-time energy behaviour (docs/solve.md measures it).

mod dense;
mod drive;
mod estimate;
mod events;
mod grid;
mod hermite;
mod kept;
mod options;
mod pilot;
mod run;
mod solution;
mod trail;

use std::ops::ControlFlow;
use std::sync::Arc;

pub use events::{Direction, Event, EventHit};
pub use options::{Method, Options};
pub use solution::{Segment, Solution, SolveError, Stats, Status, StepView};

use crate::error::{Error, Result};
use crate::operator::LinearOperator;
use crate::stepper::BankCache;
use crate::system::System;

/// The banks of one solve, shared by its pilots, runs, checking runs and output steps.
pub(crate) type SolveCache<S> = BankCache<<<S as System>::Op as LinearOperator>::Bank>;

/// Banks a solve keeps at once (besides the ones in use): every step size of the three runs of
/// the current attempt and of the one before.
const SOLVE_CACHE_BANKS: usize = 12;

/// An initial value problem y' = Ay + g(y), y(t₀) = y₀, on [t₀, t_end]. The system is held
/// behind a reference count, so that the solutions share it rather than borrow the problem.
#[derive(Debug)]
pub struct Problem<S> {
    system: Arc<S>,
    y0: Vec<f64>,
    t0: f64,
    t_end: f64,
}

impl<S> Clone for Problem<S> {
    fn clone(&self) -> Self {
        Problem {
            system: Arc::clone(&self.system),
            y0: self.y0.clone(),
            t0: self.t0,
            t_end: self.t_end,
        }
    }
}

impl<S: System> Problem<S> {
    /// The problem of `system` from `y0` over `span = (t₀, t_end)`.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] if `y0` does not have the system's dimension,
    /// [`Error::NonFinite`] for a NaN or infinite entry of `y0` or time, [`Error::InvalidInput`]
    /// if t_end < t₀, and what [`check_system`](crate::system::check_system) reports.
    pub fn new(system: S, y0: impl Into<Vec<f64>>, span: (f64, f64)) -> Result<Self> {
        crate::system::check_system(&system)?;
        let y0 = y0.into();
        if y0.len() != system.dim() {
            return Err(Error::DimensionMismatch {
                what: "y0 and the system",
                expected: system.dim(),
                found: y0.len(),
            });
        }
        if y0.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("y0"));
        }
        let (t0, t_end) = span;
        if !t0.is_finite() || !t_end.is_finite() || !(t_end - t0).is_finite() {
            return Err(Error::NonFinite("the time span"));
        }
        if t_end < t0 {
            return Err(Error::InvalidInput(format!(
                "t_end = {t_end:?} is before t0 = {t0:?}"
            )));
        }
        Ok(Problem {
            system: Arc::new(system),
            y0,
            t0,
            t_end,
        })
    }

    /// The system.
    pub fn system(&self) -> &S {
        &self.system
    }

    /// y₀.
    pub fn y0(&self) -> &[f64] {
        &self.y0
    }

    /// (t₀, t_end).
    pub fn span(&self) -> (f64, f64) {
        (self.t0, self.t_end)
    }

    /// Solves the problem (see the module docs): `Ok` only with the answer verified to the
    /// tolerance at every output time (for a fixed method: the run completed).
    ///
    /// # Errors
    /// [`SolveError::Unverified`] with the best solution when the answer could not be
    /// verified; [`SolveError::Failed`] for bad options ([`Error::InvalidParameter`],
    /// [`Error::InvalidInput`], ...), a tolerance below what f64 can verify, output that
    /// cannot be stored, and a failed step of a fixed method ([`Error::AtStep`]).
    pub fn solve(&self, options: &Options) -> std::result::Result<Solution<S>, SolveError> {
        self.run(options, None)
    }

    /// [`solve`](Self::solve) with an observer called after every step of the run that is
    /// returned, once, in time order, when the stretch holding it is verified (for a fixed
    /// method: at once); returning [`ControlFlow::Break`] stops the integration there
    /// ([`Status::Stopped`]). A stretch integrated again with a smaller step is never shown
    /// to it twice: it sees only what the solution holds.
    ///
    /// # Errors
    /// As [`solve`](Self::solve).
    pub fn solve_with(
        &self,
        options: &Options,
        mut observer: impl FnMut(&StepView<'_>) -> ControlFlow<()>,
    ) -> std::result::Result<Solution<S>, SolveError> {
        self.run(options, Some(&mut observer))
    }
}

/// `n` evenly spaced points from `a` to `b` (both included; `[a]` for n = 1).
pub fn linspace(a: f64, b: f64, n: usize) -> Vec<f64> {
    match n {
        0 => Vec::new(),
        1 => vec![a],
        _ => (0..n)
            .map(|i| {
                if i == n - 1 {
                    b
                } else {
                    a + (b - a) * (i as f64 / (n - 1) as f64)
                }
            })
            .collect(),
    }
}

/// The bytes the steppers of one solve of `system` at order 2r hold at their peak, or `None`
/// if the count overflows a `usize`: the returned run, its three checking runs (2h, 3h and
/// the perturbed 3h run that measures the sensitivity to rounding) and the output stepper,
/// each as [`ec_stepper_bytes`](crate::stepper::ec_stepper_bytes) counts it (s = r), together
/// with the largest bank once more (a change of step size builds the new bank before the old
/// one goes) and the banks the solve keeps for step sizes it may come back to (at most 12, and
/// at most 256 MiB beyond the largest). With `check == false` (a fixed-step solve) the
/// returned run and the output stepper only.
///
/// [`Problem::solve`] compares this with what can be allocated before it builds the steppers
/// of an order, and refuses that order with an error naming the size rather than aborting
/// part-way; the CLI adds its own overheads to it for its `--tol` memory check.
pub fn solve_stepper_bytes<S: System>(
    system: &S,
    r: usize,
    check: bool,
    settings: &crate::stepper::SolverSettings,
) -> Option<usize> {
    use crate::stepper::{Predictor, SolverSettings, StepperBytes, ec_stepper_bytes};
    let run = ec_stepper_bytes(system, r, r, settings)?;
    let output = ec_stepper_bytes(
        system,
        r,
        r,
        &SolverSettings {
            predictor: Predictor::Constant,
            ..*settings
        },
    )?;
    let mut held = vec![run; if check { 4 } else { 1 }];
    held.push(output);
    let peak = StepperBytes::peak_of(&held)?;
    let budget = (crate::stepper::CACHE_BUDGET * size_of::<f64>()).max(run.bank);
    let kept = run.bank.saturating_mul(SOLVE_CACHE_BANKS).min(budget);
    peak.checked_add(kept)
}
