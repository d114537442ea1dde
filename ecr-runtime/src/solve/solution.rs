//! What a solve returns: the [`Solution`], what it cost ([`Stats`]), how it ended
//! ([`Status`]), and the error that carries an answer that could not be verified
//! ([`SolveError`]).

use std::cell::Cell;
use std::fmt;
use std::sync::Arc;

use super::events::EventHit;
use crate::error::{Error, Result};
use crate::stepper::SolverSettings;
use crate::system::System;

/// What the observer of [`Problem::solve_with`](super::Problem::solve_with) sees after each
/// step.
#[derive(Debug)]
pub struct StepView<'a> {
    /// The time reached.
    pub t: f64,
    /// The state there.
    pub y: &'a [f64],
    /// The number of the step (1 for the first).
    pub step: usize,
    /// Its size.
    pub h: f64,
}

/// How the integration ended.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum Status {
    /// At t_end.
    Completed,
    /// At the zero of a terminal event.
    Terminated {
        /// The index of the event (in the order given to
        /// [`Options::event`](super::Options::event)).
        event: usize,
        /// Its time.
        t: f64,
    },
    /// The observer asked to stop, after the step that reached `t`.
    Stopped {
        /// The time reached.
        t: f64,
    },
    /// A step failed at `t` (only in the best solution of a [`SolveError::Unverified`]: the
    /// integration could not go on, e.g. at a singularity).
    Failed {
        /// The time reached.
        t: f64,
    },
}

/// What a solve cost. Every evaluation of g the solve made is in exactly one of the
/// `*_g_evals` fields ([`total_g_evals`](Self::total_g_evals) sums them).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    /// Steps of the run that is returned.
    pub steps: usize,
    /// Evaluations of g in those steps.
    pub g_evals: usize,
    /// Stage sweeps (fixed-point or Newton iterations) in those steps.
    pub sweeps: usize,
    /// Steps of the run that checks it (the method of order 2r − 2 on the same steps; none for
    /// a fixed method).
    pub check_steps: usize,
    /// Evaluations of g in those steps.
    pub check_g_evals: usize,
    /// Steps of the pilot runs (answer and check) that chose the order and the first step size.
    pub pilot_steps: usize,
    /// Evaluations of g in the pilot runs.
    pub pilot_g_evals: usize,
    /// Steps of both runs over stretches that were integrated again with a smaller step (the
    /// estimate grew too much there, or a step failed) and of runs started again from t₀.
    pub discarded_steps: usize,
    /// Evaluations of g in those steps.
    pub discarded_g_evals: usize,
    /// How often a stretch was integrated again with a smaller step: a window whose estimate
    /// grew too much, or the run from t₀.
    pub retries: usize,
    /// Steps taken to evaluate the solution between grid points (output times, events), of
    /// both runs.
    pub dense_evals: usize,
    /// Evaluations of g in those steps.
    pub dense_g_evals: usize,
}

impl Stats {
    /// Every evaluation of g: the run, its checks, the pilots, the discarded stretches and
    /// the output between grid points.
    pub fn total_g_evals(&self) -> usize {
        self.g_evals
            + self.check_g_evals
            + self.pilot_g_evals
            + self.discarded_g_evals
            + self.dense_g_evals
    }

    /// The evaluations of g spent beyond the run that is returned, per evaluation of that
    /// run: what the automation and its verification cost (0 for a fixed method without
    /// output between grid points).
    pub fn overhead(&self) -> f64 {
        (self.total_g_evals() - self.g_evals) as f64 / self.g_evals.max(1) as f64
    }
}

/// A constant-step stretch of the run: from `t` on, the step size `h`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// Where the stretch starts.
    pub t: f64,
    /// Its step size.
    pub h: f64,
}

/// The solution of a [`Problem`](super::Problem). It owns what it needs: it does not borrow
/// the problem, and the system is shared with it (reference-counted) for
/// [`at`](Self::at). `Solution<()>` (the default) is the same data without the system, as
/// [`SolveError::Unverified`] carries it.
pub struct Solution<S = ()> {
    /// The output times: `t_eval`, or every grid point of the run, t₀ first; up to the end of
    /// the integration.
    pub t: Vec<f64>,
    /// The states at those times.
    pub y: Vec<Vec<f64>>,
    /// The energy H at those times, if the system knows H.
    pub energy: Option<Vec<f64>>,
    /// The estimated global error at each output time, in units of the tolerance
    /// (max_i |e_i| / (atol + rtol |y_i|)): every entry ≤ 1 in a solution that `solve`
    /// returns with `Ok`. Empty for a fixed method.
    pub error_estimates: Vec<f64>,
    /// The largest of [`error_estimates`](Self::error_estimates) and of the events'
    /// estimates; `None` for a fixed method and for a solution with no output.
    pub error_estimate: Option<f64>,
    /// The located zeros of the events, in time order.
    pub events: Vec<EventHit>,
    /// How the integration ended.
    pub status: Status,
    /// What it cost.
    pub stats: Stats,
    /// The order of the answer: r (order 2r); its check was of order 2r − 2.
    pub r: usize,
    /// Gauss–Legendre points per step.
    pub s: usize,
    /// The step size of the last stretch (see [`segments`](Self::segments)).
    pub h: f64,
    /// The constant-step stretches of the run, in time order (one for a run that never
    /// changed its step; several where the time scale of the solution changes, as at the close
    /// passages of an eccentric orbit).
    pub segments: Vec<Segment>,
    pub(super) energy0: Option<f64>,
    pub(super) dense: Option<DenseData<S>>,
}

/// What [`Solution::at`] needs: the grid states of both runs, the system and the method.
pub(super) struct DenseData<S> {
    pub(super) system: Arc<S>,
    pub(super) r: usize,
    pub(super) settings: SolverSettings,
    /// (rtol, atol) of the solve.
    pub(super) tolerance: (f64, f64),
    /// The grid times.
    pub(super) t: Vec<f64>,
    /// The answer's states at `t` (flat).
    pub(super) answer: Vec<f64>,
    /// The check's states at `t` (flat), for a verified solve.
    pub(super) check: Option<Vec<f64>>,
    /// Steps taken by [`Solution::at`] and their evaluations of g.
    pub(super) evals: Cell<(usize, usize)>,
    /// How much the linear part magnifies a perturbation (for the interpolant's estimate),
    /// computed at the first call that needs it.
    pub(super) stiffness: std::cell::OnceCell<Vec<f64>>,
    /// The slopes at the grid points, evaluated when a stencil first reads them.
    pub(super) slopes: std::cell::RefCell<Slopes>,
}

/// The slopes `Ay + g(y)` of the answer and the check at the grid points of a dense solution
/// (flat, NaN until evaluated), and the scratch of their evaluation.
#[derive(Clone, Debug, Default)]
pub(super) struct Slopes {
    pub(super) answer: Vec<f64>,
    pub(super) check: Vec<f64>,
    pub(super) scratch: Vec<f64>,
}

impl<S> Clone for DenseData<S> {
    fn clone(&self) -> Self {
        DenseData {
            system: Arc::clone(&self.system),
            r: self.r,
            settings: self.settings,
            tolerance: self.tolerance,
            t: self.t.clone(),
            answer: self.answer.clone(),
            check: self.check.clone(),
            evals: self.evals.clone(),
            stiffness: self.stiffness.clone(),
            slopes: self.slopes.clone(),
        }
    }
}

impl<S> Clone for Solution<S> {
    fn clone(&self) -> Self {
        Solution {
            t: self.t.clone(),
            y: self.y.clone(),
            energy: self.energy.clone(),
            error_estimates: self.error_estimates.clone(),
            error_estimate: self.error_estimate,
            events: self.events.clone(),
            status: self.status,
            stats: self.stats,
            r: self.r,
            s: self.s,
            h: self.h,
            segments: self.segments.clone(),
            energy0: self.energy0,
            dense: self.dense.clone(),
        }
    }
}

impl<S> fmt::Debug for Solution<S> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Solution")
            .field("t", &self.t)
            .field("y", &self.y)
            .field("energy", &self.energy)
            .field("error_estimate", &self.error_estimate)
            .field("events", &self.events)
            .field("status", &self.status)
            .field("stats", &self.stats)
            .field("r", &self.r)
            .field("segments", &self.segments)
            .finish_non_exhaustive()
    }
}

impl<S> Solution<S> {
    /// The same solution without the system ([`at`](Self::at) is then unavailable).
    pub fn into_data(self) -> Solution {
        Solution {
            t: self.t,
            y: self.y,
            energy: self.energy,
            error_estimates: self.error_estimates,
            error_estimate: self.error_estimate,
            events: self.events,
            status: self.status,
            stats: self.stats,
            r: self.r,
            s: self.s,
            h: self.h,
            segments: self.segments,
            energy0: self.energy0,
            dense: None,
        }
    }

    /// max over the outputs of |H − H₀| / max(|H₀|, tiny), if the system knows H; NaN if H
    /// was NaN anywhere (a NaN is never hidden by the maximum).
    pub fn energy_error(&self) -> Option<f64> {
        let e0 = self.energy0?;
        let scale = e0.abs().max(f64::MIN_POSITIVE);
        let es = self.energy.as_ref()?;
        let mut worst = 0.0_f64;
        for e in es {
            let x = (e - e0).abs() / scale;
            if x.is_nan() {
                return Some(f64::NAN);
            }
            worst = worst.max(x);
        }
        Some(worst)
    }

    /// The last output state.
    pub fn last(&self) -> Option<&[f64]> {
        self.y.last().map(Vec::as_slice)
    }

    /// Steps taken to evaluate the solution between grid points by [`at`](Self::at), and
    /// their evaluations of g (those during the solve are in [`Stats`]).
    pub fn dense_evaluations(&self) -> (usize, usize) {
        self.dense.as_ref().map_or((0, 0), |d| d.evals.get())
    }
}

impl<S: System> Solution<S> {
    /// The solution at any time of the integrated span, up to where the solution's times end
    /// (needs [`Options::dense_output`](super::Options::dense_output)): the grid value on the
    /// grid; between grid points, for a verified solve, the interpolant of the grid where its
    /// estimate is within the tolerance (the interpolant of the check's grid against it, and
    /// the interpolant of one degree more: see the guide's "Between grid points"), else one step
    /// of the answer's method from the grid point before t and one of its check's from the
    /// check's state there, whose difference (with the modelled round-off) is the estimate at t;
    /// for a fixed method one step of its method.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] without dense output or for t outside the integrated span,
    /// [`Error::Unverified`] if the estimate at t exceeds the tolerance, and what the steps
    /// report.
    pub fn at(&self, t: f64) -> Result<Vec<f64>> {
        let d = self.y.first().map_or(0, Vec::len);
        let mut out = vec![0.0; d];
        self.at_into(t, &mut out)?;
        Ok(out)
    }

    /// [`at`](Self::at) into `out`.
    ///
    /// # Errors
    /// As [`at`](Self::at), and [`Error::DimensionMismatch`] for `out`.
    pub fn at_into(&self, t: f64, out: &mut [f64]) -> Result<()> {
        let dense = self.dense.as_ref().ok_or_else(|| {
            Error::InvalidInput("Solution::at needs Options::dense_output()".into())
        })?;
        let d = dense.system.dim();
        if out.len() != d {
            return Err(Error::DimensionMismatch {
                what: "the output and the system",
                expected: d,
                found: out.len(),
            });
        }
        let Some(&first) = dense.t.first() else {
            return Err(Error::InvalidInput("the solution has no grid".into()));
        };
        // The integrated span ends where the solution's times end (a terminal event or an
        // observer's stop between grid points included), not at the last grid point.
        // (All three are in time order: their last elements suffice.)
        let last = self
            .t
            .last()
            .into_iter()
            .chain(self.events.last().map(|e| &e.t))
            .chain(dense.t.last())
            .fold(first, |a, &b| a.max(b));
        if !(first..=last).contains(&t) {
            return Err(Error::InvalidInput(format!(
                "t = {t:?} is outside the integrated span [{first:?}, {last:?}]"
            )));
        }
        let k = dense.t.partition_point(|&tk| tk <= t).saturating_sub(1);
        let answer = &dense.answer[k * d..(k + 1) * d];
        out.copy_from_slice(answer);
        if dense.t[k] == t {
            return Ok(());
        }
        let check = dense.check.as_deref();
        let (rtol, atol) = dense.tolerance;
        let unit = f64::EPSILON.max(dense.settings.tolerance / 5.0);
        let system = &*dense.system;
        // The slopes of the interpolant's stencil (a verified solve), computed once per grid
        // point and kept.
        let stiffness = dense
            .stiffness
            .get_or_init(|| super::runs::stiffness(system));
        let grid = check.map(|check| super::interp::Grid {
            t: &dense.t,
            answer: &dense.answer,
            check,
            d,
            stiffness,
        });
        let stencil = grid.as_ref().and_then(|g| g.stencil(t));
        let mut memo = dense.slopes.borrow_mut();
        if let (Some(stencil), Some(check)) = (stencil, check) {
            let Slopes {
                answer: sa,
                check: sc,
                scratch,
            } = &mut *memo;
            if sa.len() != dense.answer.len() {
                sa.resize(dense.answer.len(), f64::NAN);
                sc.resize(dense.answer.len(), f64::NAN);
            }
            let mut fresh = 0;
            for p in stencil.range() {
                let at = p * d..(p + 1) * d;
                if sa[at.start].is_nan() {
                    super::runs::slope(
                        system,
                        &dense.answer[at.clone()],
                        &mut sa[at.clone()],
                        scratch,
                    )?;
                    super::runs::slope(system, &check[at.clone()], &mut sc[at], scratch)?;
                    fresh += 2;
                }
            }
            if fresh > 0 {
                let (n, g) = dense.evals.get();
                dense.evals.set((n, g + fresh));
            }
        }
        let interp = match (grid, stencil) {
            (Some(grid), Some(stencil)) => {
                let at = stencil.range().start * d..stencil.range().end * d;
                Some((grid, stencil, &memo.answer[at.clone()], &memo.check[at]))
            }
            _ => None,
        };
        let settings = super::between_settings(dense.settings, (rtol, atol), check.is_some());
        let check_k = check.map_or(answer, |c| &c[k * d..(k + 1) * d]);
        let mut cost = super::runs::Cost::default();
        let e = super::between::value_between(
            super::between::ValueAt {
                t,
                base: (dense.t[k], answer, check_k, 0.0),
                n: k,
                tolerance: (rtol, atol),
                unit,
                verified: check.is_some(),
                source: super::between::Source::Rule,
            },
            interp,
            &mut FreshSteps {
                system,
                r: dense.r,
                check: check.is_some(),
                settings,
                seeded: super::value_steps::seed_pays(self.stats.steps, self.stats.sweeps),
                cost: &mut cost,
            },
            (out, None),
        )?;
        let (n, g) = dense.evals.get();
        dense
            .evals
            .set((n + cost.total_steps(), g + cost.total_g_evals()));
        if e.is_nan() || e > 1.0 {
            return Err(Error::Unverified(format!(
                "the estimated error at t = {t:?} is {e:.3e} times the tolerance"
            )));
        }
        Ok(())
    }
}

/// Partial steps for [`Solution::at`]: steppers of both runs at the step's length, their banks
/// built for it (in a cache of their own: a length is met once).
struct FreshSteps<'a, S: System> {
    system: &'a S,
    r: usize,
    check: bool,
    /// The steppers' settings; their banks' arithmetic serves both runs' steps.
    settings: SolverSettings,
    /// Whether a step starts from the interpolant ([`seed_pays`](super::value_steps::seed_pays)).
    seeded: bool,
    cost: &'a mut super::runs::Cost,
}

impl<S: System> super::between::PartialSteps for FreshSteps<'_, S> {
    fn drift(&mut self, y: &mut [f64], dt: f64) -> Result<()> {
        super::runs::drift(self.system, y, dt)
    }

    fn partial(
        &mut self,
        from: (&[f64], &[f64]),
        dt: f64,
        out: (&mut [f64], &mut [f64]),
        seed: Option<super::value_steps::Seed<'_>>,
        which: super::between::Which,
    ) -> Result<()> {
        let cache = Arc::new(super::SolveCache::<S>::new(4));
        let mut runs = super::runs::PairRuns::new(
            self.system,
            self.r,
            self.check && which != super::between::Which::Answer,
            dt,
            self.settings,
            self.settings,
            &cache,
        )?;
        let seed = seed.filter(|_| self.seeded);
        runs.value_step(from, out, seed, which, self.cost)
    }
}

/// A solve that did not return a verified answer.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub enum SolveError {
    /// The answer could not be verified to the tolerance (a tolerance below what f64 reaches
    /// for the problem, chaos beyond predictability at this tolerance, a singularity, a
    /// right-hand side not smooth enough for the order, …): why, and the best solution the
    /// solve has, with its error estimates ([`Solution::error_estimates`], some above 1).
    Unverified {
        /// Why, in words.
        reason: String,
        /// The best solution, with its estimates.
        solution: Box<Solution>,
    },
    /// Bad input or a failure that left no solution.
    Failed(Error),
}

impl SolveError {
    /// The best solution of an unverified answer.
    pub fn solution(&self) -> Option<&Solution> {
        match self {
            SolveError::Unverified { solution, .. } => Some(solution),
            SolveError::Failed(_) => None,
        }
    }

    /// The best solution of an unverified answer, by value.
    pub fn into_solution(self) -> Option<Solution> {
        match self {
            SolveError::Unverified { solution, .. } => Some(*solution),
            SolveError::Failed(_) => None,
        }
    }
}

impl From<Error> for SolveError {
    fn from(e: Error) -> Self {
        SolveError::Failed(e)
    }
}

impl From<SolveError> for Error {
    /// [`Error::Unverified`] with the reason (the best solution is dropped), or the failure.
    fn from(e: SolveError) -> Self {
        match e {
            SolveError::Failed(e) => e,
            e @ SolveError::Unverified { .. } => Error::Unverified(e.to_string()),
        }
    }
}

impl fmt::Display for SolveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SolveError::Unverified { reason, solution } => {
                write!(f, "{reason}")?;
                if let Some(e) = solution.error_estimate {
                    write!(f, " (largest estimate {e:.3e} times the tolerance")?;
                    write!(
                        f,
                        " over the {} outputs returned with this error)",
                        solution.t.len()
                    )?;
                }
                Ok(())
            }
            SolveError::Failed(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for SolveError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            SolveError::Failed(e) => Some(e),
            SolveError::Unverified { .. } => None,
        }
    }
}
