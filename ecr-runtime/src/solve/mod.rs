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
//! The answer is ECrP of order 2r on the r Gauss–Legendre points of each step. Beside it runs
//! its check: ECr−1P of order 2r − 2 on the r + 1 Gauss–Lobatto points of the step (both ends
//! included), on the same steps, from its own state. Every grid point is a meeting point: the
//! difference of the two there is the global error of the check (the answer's is of higher
//! order, and measured 10 to 10⁴ times smaller), and that difference, plus a model of the
//! round-off, is the estimate of the answer's error that [`Solution::error_estimates`]
//! report. No asymptotic regime is needed: the difference of two orders on the same steps
//! estimates the error also at the large steps where the cheapest runs live. The check looks
//! at g at the ends of every step, where the answer's Gauss points do not: a kink of g just
//! after a grid point, which every Gauss method integrates as if g were smooth, shows in the
//! difference. A value between grid points (an output time, an event, [`Solution::at`]) is one
//! step of each method from the grid point before it, estimated the same way.
//!
//! # How the step is chosen
//!
//! Pilots integrate a few steps from t₀ with both runs for a few orders (from one more r per
//! two and a half decades of tolerance, up while the cost per unit time falls, then down,
//! within [`Options::orders`]) and take the order and step whose estimate, growing as it grew
//! over the pilot, would end the span at half the tolerance at the least cost. The run then
//! goes in windows of 16 steps. After each window the growth of the estimate over the last
//! windows, scaled by the check's order, sets the step of the next so that the estimate would
//! end the span at half the tolerance: the step grows where the solution is slow and shrinks
//! where it is fast (the close passage of an orbit), in constant-step segments
//! ([`Solution::segments`]) whose sizes come from a ladder of ratio 2^⅛, so that a size met
//! again finds its φ-banks built. A window whose estimate grows past the tolerance, or far past
//! its share of what is left, is integrated again with a smaller step; where a smaller step no
//! longer brings the growth down (the error is carried by the flow, not made in the window:
//! chaos, a separatrix) the run starts again from t₀ aiming lower, at most four times, and then
//! the answer is [`SolveError::Unverified`] with the reason.
//!
//! [`Options::max_step`] and [`Options::tstops`] are the remedies for features the sampled
//! methods cannot see: a pulse narrower than the steps, a kink at a known time.

mod attempts;
mod between;
mod control;
mod events;
mod features;
mod fixed;
mod hits;
mod interp;
mod local;
mod moved;
mod options;
mod pilot;
mod record;
mod runs;
mod solution;
mod value_steps;
mod window;

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

/// Banks a solve keeps at once (besides the ones in use): the answer's and the check's for the
/// step sizes of the ladder the run moves on.
pub(crate) const SOLVE_CACHE_BANKS: usize = 16;

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

impl<S: System> Problem<S> {
    /// The solve: options checked, then a fixed-step run or the verified one.
    fn run(
        &self,
        options: &Options,
        observer: record::Observer<'_>,
    ) -> std::result::Result<Solution<S>, SolveError> {
        let cache = Arc::new(SolveCache::<S>::new(SOLVE_CACHE_BANKS));
        self.run_sharing(options, observer, &cache)
    }

    /// [`solve`](Self::solve) taking the φ-banks from `cache` and putting the ones it builds
    /// there: solves of problems whose linear operators are equal may share one cache (the
    /// members of an ensemble that share their system). The cache must serve only such
    /// problems: its keys do not identify the operator.
    pub(crate) fn solve_sharing(
        &self,
        options: &Options,
        cache: &Arc<SolveCache<S>>,
    ) -> std::result::Result<Solution<S>, SolveError> {
        self.run_sharing(options, None, cache)
    }

    /// The solve with a bank cache.
    fn run_sharing(
        &self,
        options: &Options,
        mut observer: record::Observer<'_>,
        cache: &Arc<SolveCache<S>>,
    ) -> std::result::Result<Solution<S>, SolveError> {
        options.validate()?;
        if let Some(ts) = &options.t_eval {
            if let Some(&t) = ts.iter().find(|&&t| t < self.t0 || t > self.t_end) {
                return Err(Error::InvalidInput(format!(
                    "t_eval holds {t:?}, outside the time span [{:?}, {:?}]",
                    self.t0, self.t_end
                ))
                .into());
            }
        }
        let system = &*self.system;
        let verified = !matches!(options.method, Method::Fixed { .. });
        let ctx = window::Ctx::new(options, (self.t0, self.t_end), &self.y0, verified);
        let settings = stage_settings(options, verified);
        let mut make = |r: usize, check: bool, h: f64| -> Result<Box<dyn runs::Runs + '_>> {
            crate::storage::ensure_bytes_allocatable(
                &format!(
                    "the steppers of EC{r}P for this solve (d = {}{})",
                    system.dim(),
                    if check { ", with its check" } else { "" }
                ),
                solve_stepper_bytes(system, r, check, &settings),
            )?;
            let between = between_settings(settings, (options.rtol, options.atol), check);
            let runs = runs::PairRuns::new(system, r, check, h, settings, between, cache)?;
            Ok(Box::new(runs))
        };
        match options.method {
            Method::Fixed { r, h } => {
                let span = self.t_end - self.t0;
                // A step beyond the span is one step of the span.
                let h = if span > 0.0 { h.min(span) } else { h };
                let plan = crate::integrate::StepPlan::new(self.t0, self.t_end, h)?;
                let steps = plan.steps();
                if steps > options.max_steps {
                    return Err(Error::InvalidInput(format!(
                        "the integration needs {steps} steps of h = {h:?}, more than max_steps = {}",
                        options.max_steps
                    ))
                    .into());
                }
                // Refused before the run rather than aborted on an allocation midway.
                let outputs = options.t_eval.as_ref().map_or(steps + 1, Vec::len);
                let grid = if options.dense { steps + 1 } else { 0 };
                record::ensure_output_fits(self.y0.len(), outputs, grid)?;
                let mut runs = make(r, false, plan.last.filter(|_| steps == 1).unwrap_or(h))?;
                let record = fixed::fixed(&ctx, &mut *runs, h, plan, &mut observer)?;
                Ok(record.into_solution(
                    options,
                    &self.system,
                    &self.y0,
                    false,
                    r,
                    Stats::default(),
                ))
            }
            _ => {
                if !self.y0.iter().all(|v| v.abs() < f64::MAX / 16.0) {
                    let big = self.y0.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
                    return Err(Error::InvalidInput(format!(
                        "y0 holds {big:e}, too close to the largest f64 ({:e}) for its rounding \
                         to be bounded: the steps would overflow; rescale the problem",
                        f64::MAX
                    ))
                    .into());
                }
                // Stops and a largest step that need more steps than allowed: refused before
                // the run, with the count (counted without building the grid).
                let least = ctx.least_steps();
                if least > options.max_steps as f64 {
                    return Err(Error::InvalidInput(format!(
                        "max_step = {:e} and {} tstops in the span need at least {least:.0} \
                         steps, more than max_steps = {}",
                        options.max_step,
                        ctx.stops.len() - 1,
                        options.max_steps
                    ))
                    .into());
                }
                let floor = ctx.floor();
                if floor > 0.25 {
                    return Err(Error::InvalidInput(format!(
                        "rtol = {:e}, atol = {:e} is below what f64 can verify for this problem: \
                         the rounding of y0 alone is {floor:.2e} times it; ask for about {:.0e} \
                         times the tolerance or more",
                        options.rtol,
                        options.atol,
                        (4.0 * floor).max(1.0)
                    ))
                    .into());
                }
                let out = attempts::verified(&ctx, &mut make, &mut observer)?;
                let solution = out.record.into_solution(
                    options,
                    &self.system,
                    &self.y0,
                    true,
                    out.r,
                    out.stats,
                );
                match out.unverified {
                    None => Ok(solution),
                    Some(reason) => Err(SolveError::Unverified {
                        reason,
                        solution: Box::new(solution.into_data()),
                    }),
                }
            }
        }
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

/// The stage solver's settings of a solve: the user's, and for a solve to a tolerance whose
/// stage scale is the default [`StageScale::Global`](crate::stepper::StageScale::Global) (the
/// stage update measured against max(1, ‖Y‖∞)) that scale with the floor atol/rtol (at most 1,
/// at least the least normal f64): the tolerance's own weights atol + rtol·|y| say what size is
/// small, so a state of 1e−100 solved with rtol alone converges relative to its size, as one
/// of size 1 does. A tolerance with atol ≥ rtol keeps the floor 1: the same steps, to the bit.
///
/// A verified solve's runs build their banks as
/// [`BankArithmetic::StepExtended`](crate::operator::BankArithmetic::StepExtended) where the
/// settings ask for the default `Extended`: the step's propagator, common to the answer and its
/// check, as accurate as in a fixed run; the stage and predictor nodes, which differ between
/// the two methods (or only start an iteration), in f64.
fn stage_settings(options: &Options, verified: bool) -> crate::stepper::SolverSettings {
    use crate::operator::BankArithmetic;
    use crate::stepper::StageScale;
    let mut settings = options.settings;
    if verified && settings.banks == BankArithmetic::Extended {
        settings.banks = BankArithmetic::StepExtended;
    }
    if verified && settings.scale == StageScale::Global && options.rtol > 0.0 {
        let floor = (options.atol / options.rtol).clamp(f64::MIN_POSITIVE, 1.0);
        if floor < 1.0 {
            settings.scale = StageScale::GlobalFloor { floor };
        }
    }
    settings
}

/// Values between grid points of a verified solve take their one partial step with f64 banks
/// ([`BankArithmetic::F64`](crate::operator::BankArithmetic::F64)) when the tolerance is at
/// least this: a bank's error (a few d·ε relative, docs/banks.md) then enters one step's value
/// far below the tolerance, and nothing carries it on. Tighter tolerances take the banks of the
/// runs ([`BankArithmetic::StepExtended`](crate::operator::BankArithmetic::StepExtended)), and
/// fixed-step solves the default banks.
pub const F64_BETWEEN_MIN_TOL: f64 = 1e-10;

/// The banks' arithmetic of the partial steps to values between grid points.
pub(super) fn between_banks(
    rtol: f64,
    atol: f64,
    verified: bool,
) -> crate::operator::BankArithmetic {
    use crate::operator::BankArithmetic;
    if !verified {
        BankArithmetic::Extended
    } else if rtol.max(atol) >= F64_BETWEEN_MIN_TOL {
        BankArithmetic::F64
    } else {
        BankArithmetic::StepExtended
    }
}

/// The stage solver's settings of the partial steps to values between grid points: the
/// runs' `settings` started from the interpolant or the grid state (no predictor), with
/// [`between_banks`], and in a verified solve with a relative tolerance the stage iteration
/// stopped at [`BETWEEN_SWEEP_SHARE`] of the tolerance, each component in its own scale
/// ([`StageScale::PerComponent`](crate::stepper::StageScale::PerComponent) with the floor
/// atol/rtol: an update of at most `BETWEEN_SWEEP_SHARE · (atol + rtol·|Yᵢ|)` in every
/// component), not at round-off: nothing carries a value between grid points on, so round-off
/// buys nothing there, and from a seed a few sweeps reach the share. A user's own looser
/// iteration tolerance, or per-component scale, is kept.
pub(super) fn between_settings(
    settings: crate::stepper::SolverSettings,
    (rtol, atol): (f64, f64),
    verified: bool,
) -> crate::stepper::SolverSettings {
    use crate::stepper::{Predictor, SolverSettings, StageScale};
    let mut out = SolverSettings {
        predictor: Predictor::Constant,
        banks: between_banks(rtol, atol, verified),
        ..settings
    };
    if verified && rtol > 0.0 && !matches!(settings.scale, StageScale::PerComponent { .. }) {
        out.tolerance = settings.tolerance.max(BETWEEN_SWEEP_SHARE * rtol);
        out.scale = StageScale::PerComponent {
            atol: (atol / rtol).max(f64::MIN_POSITIVE),
        };
    }
    out
}

/// The share of the tolerance a value between grid points' stage iteration stops at
/// ([`between_settings`]); the value's estimate counts it in ([`between::value_between`]).
pub(super) const BETWEEN_SWEEP_SHARE: f64 = 1e-2;

/// The bytes the steppers of one solve of `system` at order 2r hold at their peak, or `None`
/// if the count overflows a `usize`: the answer (s = r) and its check (ECr−1P on r + 1
/// Gauss–Lobatto points) and their copies for values between grid points, each as
/// [`ec_stepper_bytes`](crate::stepper::ec_stepper_bytes) counts it, together
/// with the largest bank once more (a change of step size builds the new bank before the old
/// one goes) and the banks the solve keeps for step sizes it may come back to (at most 16, and
/// at most 256 MiB beyond the largest). With `check == false` (a fixed-step solve) the answer
/// and its copy only.
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
    let between_settings = SolverSettings {
        predictor: Predictor::Constant,
        ..*settings
    };
    let mut held = vec![
        ec_stepper_bytes(system, r, r, settings)?,
        ec_stepper_bytes(system, r, r, &between_settings)?,
    ];
    if check {
        held.push(ec_stepper_bytes(system, r - 1, r + 1, settings)?);
        held.push(ec_stepper_bytes(system, r - 1, r + 1, &between_settings)?);
    }
    let run = held[0];
    let peak = StepperBytes::peak_of(&held)?;
    let budget = (crate::stepper::CACHE_BUDGET * size_of::<f64>()).max(run.bank);
    let kept = run.bank.saturating_mul(SOLVE_CACHE_BANKS).min(budget);
    peak.checked_add(kept)
}
