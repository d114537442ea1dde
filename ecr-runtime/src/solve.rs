//! Ask for an accuracy, get the solution where you want it: [`Problem`] → [`Problem::solve`]
//! → [`Solution`].
//!
//! ```
//! use ecr_runtime::prelude::*;
//!
//! // H(q, p) = ½p² + ½q² + ¼q⁴, y = (q, p); ∇V is written into zeros.
//! let grad_v = |y: &[f64], g: &mut [f64]| g[0] = y[0].powi(3);
//! let system = Hamiltonian::canonical(DMatrix::identity(2, 2), grad_v)?
//!     .potential(|y| 0.25 * y[0].powi(4));
//! let problem = Problem::new(system, [1.0, 0.0], (0.0, 50.0))?;
//! let options = Options::tolerance(1e-9).t_eval(linspace(0.0, 50.0, 11)).dense_output();
//! let sol = problem.solve(&options)?;
//! assert_eq!(sol.t.len(), 11);
//! // H is kept to the order of the method, without drift.
//! assert!(sol.energy_error().unwrap() < 1e-9);
//! // Between grid points as accurate as on them: against a run to 1e−13 that ends there.
//! let y = sol.at(27.3)?;
//! let fine = problem.solve(&Options::tolerance(1e-13).t_eval([27.3]))?;
//! assert!((y[0] - fine.y[0][0]).abs() < 1e-8 && (y[1] - fine.y[0][1]).abs() < 1e-8);
//! # Ok::<(), ecr_runtime::Error>(())
//! ```
//!
//! # How the method is chosen
//!
//! With a tolerance (the default, [`Method::Auto`]) the solver pilots a few orders r (s = r
//! Gauss–Legendre points). It starts from about one more r per two decades of tolerance
//! (r = 3 at 1e−4, r = 6 at 1e−10) and moves up or down while the predicted cost falls, within
//! [`Options::orders`] (default 2..=6). A pilot integrates the first [`PILOT_SHARE`] of the
//! span with steps h₀, h₀/2, h₀/4, … on nested grids; each run against the one before, over
//! 2^{2r} − 1 (Richardson), estimates the finer run's global error (its largest value over
//! the window). The estimate is trusted once it has fallen by 2^{2r} (within a factor 4) twice
//! in a row; it is then extrapolated to t_end linearly in time (the phase error of a
//! conservative problem; an overestimate for a damped one), and h is scaled by the order so
//! that the predicted error is half the tolerance in the scaled max-norm
//! `max_i |e_i| / (atol + rtol |y_i|)`. The order with the fewest predicted evaluations of g
//! over the run wins, and the integration runs at its fixed h. A fixed step keeps ECrP's
//! long-time behaviour; a varying one does not. On Duffing ω = 20 with EC6P and 10⁶ steps
//! around h = 0.0576, the largest relative energy error was:
//! - 1.5e−13 with h fixed, bounded (the same in each tenth of the run);
//! - 4.2e−10 with the step cycling pseudo-randomly through 0.8h–1.2h, growing over the run
//!   (`cargo run --release --example variable_step`).
//!
//! # Output
//!
//! Without `t_eval` the solution holds every step. With `t_eval` it holds those times: a time
//! on the step grid takes the step's value; between grid points the value comes from one
//! ECrP step of the same order from the grid point before it (order 2r, the accuracy of the
//! grid; it costs that step's evaluations of g, counted in [`Stats::dense_g_evals`]). When
//! `t_eval` is evenly spaced, h is chosen to divide its spacing (or be a multiple of it), so
//! that every output time is on the grid and costs nothing. [`Solution::at`] evaluates the
//! continuous solution anywhere in the time span after a run with
//! [`Options::dense_output`].

use std::cell::RefCell;
use std::ops::{ControlFlow, RangeInclusive};

use crate::integrate::StepPlan;
use crate::stepper::{EcStepper, Predictor, SolverSettings, StepReport};
use crate::system::System;
use crate::{Error, Result};

/// The share of the time span the pilot runs integrate.
pub const PILOT_SHARE: f64 = 0.125;

/// How often a chosen step size is halved when a step of the integration fails.
const MAX_RETRIES: usize = 3;

/// The fewest steps of the finer pilot run whose error estimate is trusted.
const PILOT_MIN_STEPS: f64 = 16.0;

/// The share of the tolerance the predicted global error is aimed at.
const TARGET_SHARE: f64 = 0.5;

/// How the solver picks the method and its step size.
#[derive(Clone, Debug, PartialEq)]
pub enum Method {
    /// Order and step size from the tolerance (pilot runs, see the module docs).
    Auto,
    /// ECrP of this r (order 2r, s = r), step size from the tolerance.
    Order(usize),
    /// ECrP of this r with this fixed step size h; the tolerance is not used. The last step is
    /// shortened to end at t_end if h does not divide the span.
    Fixed {
        /// r (order 2r).
        r: usize,
        /// The step size.
        h: f64,
    },
}

/// Which sign changes of an event function count.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// From negative to positive and from positive to negative.
    Both,
    /// From negative to positive only.
    Rising,
    /// From positive to negative only.
    Falling,
}

/// An event function e(t, y).
type EventFn = Box<dyn Fn(f64, &[f64]) -> f64>;

/// A user function e(t, y) whose sign changes are located during the integration.
pub struct Event {
    f: EventFn,
    terminal: bool,
    direction: Direction,
}

impl Event {
    /// An event at the zeros of `f(t, y)` (sign changes between grid points; a zero touched
    /// without a sign change inside one step is not seen).
    pub fn new(f: impl Fn(f64, &[f64]) -> f64 + 'static) -> Self {
        Event {
            f: Box::new(f),
            terminal: false,
            direction: Direction::Both,
        }
    }

    /// Stops the integration at the first such zero.
    #[must_use]
    pub fn terminal(mut self) -> Self {
        self.terminal = true;
        self
    }

    /// Only sign changes in this direction count.
    #[must_use]
    pub fn direction(mut self, direction: Direction) -> Self {
        self.direction = direction;
        self
    }

    fn counts(&self, before: f64, after: f64) -> bool {
        let rising = before < 0.0 && after >= 0.0;
        let falling = before > 0.0 && after <= 0.0;
        match self.direction {
            Direction::Both => rising || falling,
            Direction::Rising => rising,
            Direction::Falling => falling,
        }
    }
}

impl std::fmt::Debug for Event {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Event")
            .field("terminal", &self.terminal)
            .field("direction", &self.direction)
            .finish_non_exhaustive()
    }
}

/// What [`Problem::solve`] is asked for: a tolerance (or a fixed method), output times,
/// events.
#[derive(Debug)]
pub struct Options {
    rtol: f64,
    atol: f64,
    method: Method,
    orders: RangeInclusive<usize>,
    t_eval: Option<Vec<f64>>,
    dense: bool,
    events: Vec<Event>,
    settings: SolverSettings,
    max_steps: usize,
}

impl Default for Options {
    /// rtol = 1e−6, atol = 1e−9, [`Method::Auto`] over r = 2..=6, output at every step, the
    /// stepper's default [`SolverSettings`], at most 10⁸ steps.
    fn default() -> Self {
        Options {
            rtol: 1e-6,
            atol: 1e-9,
            method: Method::Auto,
            orders: 2..=6,
            t_eval: None,
            dense: false,
            events: Vec::new(),
            settings: SolverSettings::default(),
            max_steps: 100_000_000,
        }
    }
}

impl Options {
    /// rtol = atol = `tol`: the global error at the end aimed at ≤ tol·(1 + |y_i|) per
    /// component.
    pub fn tolerance(tol: f64) -> Self {
        Options {
            rtol: tol,
            atol: tol,
            ..Options::default()
        }
    }

    /// ECrP of order 2r with the fixed step size h (no tolerance).
    pub fn fixed(r: usize, h: f64) -> Self {
        Options {
            method: Method::Fixed { r, h },
            ..Options::default()
        }
    }

    /// The relative tolerance.
    #[must_use]
    pub fn rtol(mut self, rtol: f64) -> Self {
        self.rtol = rtol;
        self
    }

    /// The absolute tolerance.
    #[must_use]
    pub fn atol(mut self, atol: f64) -> Self {
        self.atol = atol;
        self
    }

    /// The method (default [`Method::Auto`]).
    #[must_use]
    pub fn method(mut self, method: Method) -> Self {
        self.method = method;
        self
    }

    /// The orders [`Method::Auto`] chooses from (r, order 2r; default 2..=6).
    #[must_use]
    pub fn orders(mut self, orders: RangeInclusive<usize>) -> Self {
        self.orders = orders;
        self
    }

    /// Output at these times (ascending, within the time span) instead of at every step.
    #[must_use]
    pub fn t_eval(mut self, times: impl IntoIterator<Item = f64>) -> Self {
        self.t_eval = Some(times.into_iter().collect());
        self
    }

    /// Keeps the step grid so that [`Solution::at`] can evaluate the solution anywhere.
    #[must_use]
    pub fn dense_output(mut self) -> Self {
        self.dense = true;
        self
    }

    /// Locates the zeros of an event function (see [`Event`]).
    #[must_use]
    pub fn event(mut self, event: Event) -> Self {
        self.events.push(event);
        self
    }

    /// The stage solver's settings.
    #[must_use]
    pub fn settings(mut self, settings: SolverSettings) -> Self {
        self.settings = settings;
        self
    }

    /// The most steps the integration may take (an error beyond).
    #[must_use]
    pub fn max_steps(mut self, n: usize) -> Self {
        self.max_steps = n;
        self
    }

    fn validate(&self) -> Result<()> {
        let tol_ok = |x: f64| x.is_finite() && x >= 0.0;
        if !tol_ok(self.rtol) || !tol_ok(self.atol) || self.rtol + self.atol == 0.0 {
            return Err(Error::InvalidParameter(format!(
                "tolerances need rtol, atol >= 0, finite, not both 0 (got rtol = {:?}, atol = {:?})",
                self.rtol, self.atol
            )));
        }
        let (lo, hi) = (*self.orders.start(), *self.orders.end());
        if lo == 0 || hi < lo {
            return Err(Error::InvalidParameter(format!(
                "orders must be a non-empty range of r >= 1 (got {lo}..={hi})"
            )));
        }
        if let Method::Fixed { h, .. } = self.method {
            if !(h.is_finite() && h > 0.0) {
                return Err(Error::InvalidStepSize(h));
            }
        }
        if let Some(ts) = &self.t_eval {
            if ts.iter().any(|t| !t.is_finite()) {
                return Err(Error::NonFinite("t_eval"));
            }
            if ts.windows(2).any(|w| w[1] < w[0]) {
                return Err(Error::InvalidInput("t_eval must be ascending".into()));
            }
        }
        self.settings.validate()
    }
}

/// An initial value problem y' = Ay + g(y), y(t₀) = y₀, on [t₀, t_end].
#[derive(Debug, Clone)]
pub struct Problem<S> {
    system: S,
    y0: Vec<f64>,
    t0: f64,
    t_end: f64,
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
        if !t0.is_finite() || !t_end.is_finite() {
            return Err(Error::NonFinite("the time span"));
        }
        if t_end < t0 {
            return Err(Error::InvalidInput(format!(
                "t_end = {t_end:?} is before t0 = {t0:?}"
            )));
        }
        Ok(Problem {
            system,
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

    /// Solves the problem (see the module docs).
    ///
    /// # Errors
    /// Bad options ([`Error::InvalidParameter`], [`Error::InvalidInput`], ...), a pilot that
    /// finds no step size, and a failed step as [`Error::AtStep`].
    pub fn solve(&self, options: &Options) -> Result<Solution<'_, S>> {
        self.solve_with(options, |_| ControlFlow::Continue(()))
    }

    /// [`solve`](Self::solve) with an observer called after every step with its time, state
    /// and number; returning [`ControlFlow::Break`] stops the integration there
    /// ([`Status::Stopped`]).
    ///
    /// # Errors
    /// As [`solve`](Self::solve).
    pub fn solve_with(
        &self,
        options: &Options,
        mut observer: impl FnMut(&StepView<'_>) -> ControlFlow<()>,
    ) -> Result<Solution<'_, S>> {
        options.validate()?;
        if let Some(ts) = &options.t_eval {
            if let Some(&t) = ts.iter().find(|&&t| t < self.t0 || t > self.t_end) {
                return Err(Error::InvalidInput(format!(
                    "t_eval holds {t:?}, outside the time span [{:?}, {:?}]",
                    self.t0, self.t_end
                )));
            }
        }
        let mut stats = Stats::default();
        let (r, h, estimate) = match options.method {
            Method::Fixed { r, h } => (r, h, None),
            Method::Order(r) => {
                let p = self.pilot_order(options, r, None, &mut stats)?;
                (r, p.h, Some(p.predicted))
            }
            Method::Auto => {
                let p = self.pilot_auto(options, &mut stats)?;
                (p.r, p.h, Some(p.predicted))
            }
        };
        let h = if matches!(options.method, Method::Fixed { .. }) {
            h
        } else {
            grid_step(h, self.t0, self.t_end, options.t_eval.as_deref())
        };
        if matches!(options.method, Method::Fixed { .. }) {
            return self.integrate(options, r, h, estimate, stats, &mut observer);
        }
        // A chosen h whose stage iteration fails beyond the pilot's window: halve it.
        let mut h = h;
        let mut retries = 0;
        loop {
            match self.integrate(options, r, h, estimate, stats, &mut observer) {
                Err(Error::AtStep { source, .. })
                    if retries < MAX_RETRIES
                        && matches!(
                            *source,
                            Error::NoConvergence { .. } | Error::NonFinite(_) | Error::Overflow(_)
                        ) =>
                {
                    retries += 1;
                    h /= 2.0;
                }
                result => return result,
            }
        }
    }

    /// The settings of the steppers that evaluate the continuous solution: from the grid
    /// point, so the stages start from y₀.
    fn dense_settings(settings: SolverSettings) -> SolverSettings {
        SolverSettings {
            predictor: Predictor::Constant,
            ..settings
        }
    }

    fn integrate(
        &self,
        options: &Options,
        r: usize,
        h: f64,
        estimate: Option<f64>,
        mut stats: Stats,
        observer: &mut impl FnMut(&StepView<'_>) -> ControlFlow<()>,
    ) -> Result<Solution<'_, S>> {
        let (t0, t_end) = (self.t0, self.t_end);
        let d = self.y0.len();
        let plan = StepPlan::new(t0, t_end, h)?;
        let steps = plan.steps();
        if steps > options.max_steps {
            return Err(Error::InvalidInput(format!(
                "the integration needs {steps} steps of h = {h:?}, more than max_steps = {}",
                options.max_steps
            )));
        }
        let mut stepper = EcStepper::with_nodes(&self.system, r, r, h, options.settings)?;
        let dense = RefCell::new(DenseStepper::new(
            &self.system,
            r,
            Self::dense_settings(options.settings),
        ));
        let time_of = |n: usize| {
            if n == steps { t_end } else { t0 + n as f64 * h }
        };
        let on_grid_tol = StepPlan::TIME_ULPS * f64::EPSILON * t0.abs().max(t_end.abs());

        let mut out = Output::new(self.system.energy(&self.y0).is_some());
        let mut grid = options.dense.then(|| Grid {
            t: vec![t0],
            y: vec![self.y0.clone()],
        });
        let mut t_eval = options.t_eval.as_deref().unwrap_or(&[]);
        let every_step = options.t_eval.is_none();
        let energy = |y: &[f64]| self.system.energy(y);

        let mut y = self.y0.clone();
        let mut y_prev = y.clone();
        if every_step {
            out.push(t0, &y, energy(&y));
        }
        while let Some((&t, rest)) = t_eval.split_first() {
            if t > t0 + on_grid_tol {
                break;
            }
            out.push(t, &y, energy(&y));
            t_eval = rest;
        }
        let mut ev_prev: Vec<f64> = options.events.iter().map(|e| (e.f)(t0, &y)).collect();
        let mut ev_now = ev_prev.clone();
        let mut status = Status::Completed;
        let mut scratch = vec![0.0; d];

        for n in 1..=steps {
            let t_prev = time_of(n - 1);
            let this_h = if n == steps {
                plan.last.unwrap_or(h)
            } else {
                h
            };
            y_prev.copy_from_slice(&y);
            if this_h != h {
                stepper.set_step_size(this_h)?;
            }
            let rep = stepper.step(&mut y).map_err(|e| Error::AtStep {
                step: n,
                t: t_prev,
                h: this_h,
                source: Box::new(e),
            })?;
            stats.add_step(&rep);
            let t = time_of(n);

            // Events: the earliest located zero of a terminal event ends the run there.
            let mut stop_at: Option<(f64, usize)> = None;
            for (k, e) in options.events.iter().enumerate() {
                ev_now[k] = (e.f)(t, &y);
                if e.counts(ev_prev[k], ev_now[k]) {
                    let te = dense.borrow_mut().locate(
                        e,
                        (t_prev, ev_prev[k]),
                        (t, ev_now[k]),
                        &y_prev,
                        &mut scratch,
                        &mut stats,
                    )?;
                    if e.terminal && stop_at.is_none_or(|(ts, _)| te < ts) {
                        stop_at = Some((te, k));
                    }
                    out.hits.push((te, k));
                }
            }
            let t_last = stop_at.map_or(t, |(te, _)| te);
            if let Some((te, _)) = stop_at {
                // Only the zeros up to the terminal one happened.
                out.hits.retain(|&(tz, _)| tz <= te);
            }

            // Requested outputs in (t_prev, t_last].
            let limit = if stop_at.is_some() {
                t_last
            } else {
                t + on_grid_tol
            };
            while let Some((&te, rest)) = t_eval.split_first() {
                if te > limit {
                    break;
                }
                if (te - t).abs() <= on_grid_tol && stop_at.is_none() {
                    out.push(te, &y, energy(&y));
                } else {
                    dense
                        .borrow_mut()
                        .advance(&y_prev, te - t_prev, &mut scratch, &mut stats)?;
                    out.push(te, &scratch, energy(&scratch));
                }
                t_eval = rest;
            }
            let hits_before = out.events.len();
            for &(te, k) in &out.hits {
                let ye = if (te - t).abs() <= on_grid_tol {
                    y.clone()
                } else {
                    dense
                        .borrow_mut()
                        .advance(&y_prev, te - t_prev, &mut scratch, &mut stats)?;
                    scratch.clone()
                };
                out.events.push(EventHit {
                    event: k,
                    t: te,
                    y: ye,
                });
            }
            out.events[hits_before..].sort_by(|a, b| a.t.total_cmp(&b.t));
            out.hits.clear();

            if let Some((te, k)) = stop_at {
                let ye = out
                    .events
                    .iter()
                    .rev()
                    .find(|hit| hit.event == k && hit.t == te)
                    .map(|hit| hit.y.clone())
                    .unwrap_or_else(|| y.clone());
                if every_step {
                    out.push(te, &ye, energy(&ye));
                }
                if let Some(g) = grid.as_mut() {
                    g.t.push(te);
                    g.y.push(ye);
                }
                status = Status::Terminated { event: k, t: te };
                break;
            }
            if every_step {
                out.push(t, &y, energy(&y));
            }
            if let Some(g) = grid.as_mut() {
                g.t.push(t);
                g.y.push(y.clone());
            }
            std::mem::swap(&mut ev_prev, &mut ev_now);
            let view = StepView {
                t,
                y: &y,
                step: n,
                h: this_h,
            };
            if observer(&view).is_break() {
                status = Status::Stopped { t };
                break;
            }
        }
        let s = stepper.s();
        Ok(Solution {
            t: out.t,
            y: out.y,
            energy: out.energy,
            events: out.events,
            status,
            stats,
            r,
            s,
            h,
            predicted_error: estimate,
            energy0: energy(&self.y0),
            grid,
            dense,
            problem: self,
        })
    }

    /// The pilot of one order r: the step size for the tolerance and the predicted cost.
    ///
    /// It integrates the first [`PILOT_SHARE`] of the span with steps h₀, h₀/2, h₀/4, …
    /// (nested grids): each run against the one before, over 2^{2r} − 1 (Richardson),
    /// estimates the finer run's global error, its largest value over the window taken. Once
    /// two successive estimates fall by 2^{2r} (within a factor 4: the error is in its
    /// asymptotic regime), the estimate is extrapolated to t_end linearly in time (the phase
    /// error of a conservative problem; an overestimate for a damped one) and h scaled by the
    /// order so that the predicted error is half the tolerance.
    fn pilot_order(
        &self,
        options: &Options,
        r: usize,
        h_start: Option<f64>,
        stats: &mut Stats,
    ) -> Result<Pilot> {
        let span = self.t_end - self.t0;
        if span == 0.0 {
            return Ok(Pilot {
                r,
                h: 1.0,
                predicted: 0.0,
                cost: 0.0,
            });
        }
        let p = (2 * r) as i32;
        let window = span * PILOT_SHARE;
        let d = self.y0.len();
        let richardson = 2f64.powi(p) - 1.0;
        let weight = |a: f64, c: f64| options.atol + options.rtol * a.abs().max(c.abs());
        // Round-off of the comparison itself, in tolerance units.
        let noise = 64.0
            * f64::EPSILON
            * self
                .y0
                .iter()
                .map(|c| c.abs().max(1.0) / weight(*c, *c))
                .fold(0.0, f64::max);
        let mut n = h_start.map_or(8.0, |h| (window / h).ceil()).max(2.0);
        let mut stepper: Option<EcStepper<&S>> = None;
        // The previous run's states at its grid points, and its error estimate.
        let mut coarse: Option<Vec<f64>> = None;
        let mut estimate: Option<f64> = None;
        let mut held_before = false;
        let mut y = vec![0.0; d];
        for _ in 0..24 {
            if n > 1e7 {
                break;
            }
            let h = window / n;
            let st = match &mut stepper {
                Some(st) => {
                    st.set_step_size(h)?;
                    st
                }
                slot => slot.insert(EcStepper::with_nodes(
                    &self.system,
                    r,
                    r,
                    h,
                    options.settings,
                )?),
            };
            let steps = n as usize;
            let mut states = Vec::with_capacity(steps * d);
            y.copy_from_slice(&self.y0);
            let mut g_evals = 0;
            let mut failed = false;
            for _ in 0..steps {
                match st.step(&mut y) {
                    Ok(rep) => {
                        stats.add_pilot(&rep);
                        g_evals += rep.g_evals;
                        states.extend_from_slice(&y);
                    }
                    Err(_) => {
                        failed = true;
                        break;
                    }
                }
            }
            if failed {
                // The stage iteration does not converge (or a step overflows): smaller steps,
                // and a new sequence.
                n *= 4.0;
                coarse = None;
                estimate = None;
                held_before = false;
                continue;
            }
            let g_per_step = g_evals as f64 / steps as f64;
            let Some(prev) = coarse.replace(states) else {
                n *= 2.0;
                continue;
            };
            let fine = coarse.as_ref().expect("just stored");
            // The finer run at the coarse grid: every second state.
            let err = prev
                .chunks_exact(d)
                .zip(fine.chunks_exact(2 * d))
                .map(|(a, b)| {
                    a.iter()
                        .zip(&b[d..])
                        .map(|(a, b)| (a - b).abs() / weight(*a, *b))
                        .fold(0.0, f64::max)
                })
                .fold(0.0, f64::max)
                / richardson;
            let predicted = err / PILOT_SHARE;
            let law_holds = estimate.is_some_and(|e| {
                let law = e / err / 2f64.powi(p);
                (0.25..=4.0).contains(&law)
            });
            // Twice in a row: once can be a coincidence of a pre-asymptotic error.
            let asymptotic = law_holds && held_before;
            held_before = law_holds;
            // The law is only trusted with enough steps in the window to show it.
            if n >= PILOT_MIN_STEPS && (err <= noise || asymptotic) {
                let h_new = h * (TARGET_SHARE / predicted.max(noise)).powf(1.0 / p as f64);
                // Not beyond the coarsest step at which the law was seen to hold.
                let h_new = h_new.min(2.0 * h).min(span);
                return Ok(Pilot {
                    r,
                    h: h_new,
                    predicted: TARGET_SHARE.min(predicted),
                    cost: span / h_new * g_per_step,
                });
            }
            estimate = Some(err);
            n *= 2.0;
        }
        Err(Error::Numerical(format!(
            "the pilot of EC{r}P found no step size at which the error behaves as order {p} \
             (last tried h = {:?})",
            window / n
        )))
    }

    /// The first order tried for a tolerance: about one more r per two decades (r = 3 at
    /// 1e−4, 6 at 1e−10), within the allowed orders.
    fn first_order(options: &Options) -> usize {
        let tol = options.rtol.max(options.atol).max(1e-16);
        let guess = (1.0 - tol.log10() / 2.0).round() as usize;
        guess.clamp(*options.orders.start(), *options.orders.end())
    }

    /// Pilots from the first order up and down while the predicted cost falls.
    fn pilot_auto(&self, options: &Options, stats: &mut Stats) -> Result<Pilot> {
        let first = Self::first_order(options);
        let mut best = self.pilot_order(options, first, None, stats)?;
        let (lo, hi) = (*options.orders.start(), *options.orders.end());
        for up in [true, false] {
            let mut r = first;
            let mut h_from = 2.0 * best.h;
            loop {
                let next = if up { r + 1 } else { r.wrapping_sub(1) };
                if next < lo || next > hi {
                    break;
                }
                let Ok(p) = self.pilot_order(options, next, Some(h_from), stats) else {
                    break;
                };
                h_from = 2.0 * p.h;
                r = next;
                if p.cost < best.cost {
                    best = p;
                } else {
                    break;
                }
            }
            if best.r != first && up {
                // Going up paid: going down will not.
                break;
            }
        }
        Ok(best)
    }
}

/// The step size used on the grid: h rounded down so that the steps fit the span, or
/// evenly spaced output times, exactly.
fn grid_step(h: f64, t0: f64, t_end: f64, t_eval: Option<&[f64]>) -> f64 {
    let span = t_end - t0;
    if span == 0.0 {
        return h;
    }
    if let Some(ts) = t_eval.filter(|ts| ts.len() >= 3) {
        let m = ts.len() - 1;
        let delta = (ts[m] - ts[0]) / m as f64;
        let even = delta > 0.0
            && ts.iter().enumerate().all(|(i, &t)| {
                (t - (ts[0] + i as f64 * delta)).abs() <= 1e-12 * delta.max(t.abs())
            });
        let offset = (ts[0] - t0) / delta;
        let ends = (t_end - t0) / delta;
        if even && (offset - offset.round()).abs() < 1e-9 && (ends - ends.round()).abs() < 1e-9 {
            return if delta >= h {
                delta / (delta / h).ceil()
            } else {
                delta * (h / delta).floor()
            };
        }
    }
    span / (span / h).ceil()
}

/// The result of one pilot: the step size and what a run with it is predicted to cost.
struct Pilot {
    r: usize,
    h: f64,
    /// The predicted global error, in tolerance units.
    predicted: f64,
    /// Predicted evaluations of g.
    cost: f64,
}

/// Steps that evaluate the continuous solution from a grid point (one ECrP step of the
/// distance to the requested time).
struct DenseStepper<'a, S: System> {
    system: &'a S,
    r: usize,
    settings: SolverSettings,
    stepper: Option<EcStepper<&'a S>>,
    /// Steps taken and their g-evaluations, over the run and `Solution::at`.
    evals: (usize, usize),
}

impl<'a, S: System> DenseStepper<'a, S> {
    fn new(system: &'a S, r: usize, settings: SolverSettings) -> Self {
        DenseStepper {
            system,
            r,
            settings,
            stepper: None,
            evals: (0, 0),
        }
    }

    /// `out` = the solution a time `dt ≥ 0` after the state `from`.
    fn advance(&mut self, from: &[f64], dt: f64, out: &mut [f64], stats: &mut Stats) -> Result<()> {
        out.copy_from_slice(from);
        if dt <= 0.0 {
            return Ok(());
        }
        let stepper = match &mut self.stepper {
            Some(st) => {
                st.set_step_size(dt)?;
                st
            }
            slot => slot.insert(EcStepper::with_nodes(
                self.system,
                self.r,
                self.r,
                dt,
                self.settings,
            )?),
        };
        // The stages start from y₀ (constant predictor); the stepper carries no compensation
        // into this step, as it does not start where its previous one ended.
        let rep = stepper.step(out)?;
        stats.dense_evals += 1;
        stats.dense_g_evals += rep.g_evals;
        self.evals.0 += 1;
        self.evals.1 += rep.g_evals;
        Ok(())
    }

    /// The time of the zero of `event` between (t_a, e_a) and (t_b, e_b), by the Illinois
    /// variant of regula falsi on the continuous solution, to a few ulps of t.
    fn locate(
        &mut self,
        event: &Event,
        (ta, ea): (f64, f64),
        (tb, eb): (f64, f64),
        y_a: &[f64],
        scratch: &mut [f64],
        stats: &mut Stats,
    ) -> Result<f64> {
        if eb == 0.0 {
            return Ok(tb);
        }
        let (mut a, mut fa, mut b, mut fb) = (ta, ea, tb, eb);
        let mut side = 0i8;
        for _ in 0..100 {
            let tol = 4.0 * f64::EPSILON * a.abs().max(b.abs());
            if b - a <= tol {
                break;
            }
            let mut c = b - fb * (b - a) / (fb - fa);
            if !(c > a && c < b) {
                c = 0.5 * (a + b);
            }
            self.advance(y_a, c - ta, scratch, stats)?;
            let fc = (event.f)(c, scratch);
            if fc == 0.0 {
                return Ok(c);
            }
            if (fc < 0.0) == (fa < 0.0) {
                a = c;
                fa = fc;
                if side == -1 {
                    fb *= 0.5;
                }
                side = -1;
            } else {
                b = c;
                fb = fc;
                if side == 1 {
                    fa *= 0.5;
                }
                side = 1;
            }
        }
        // The end whose side the zero was approached from: the first time the sign changed.
        Ok(b)
    }
}

/// The step grid kept for [`Solution::at`].
#[derive(Debug, Clone)]
struct Grid {
    t: Vec<f64>,
    y: Vec<Vec<f64>>,
}

struct Output {
    t: Vec<f64>,
    y: Vec<Vec<f64>>,
    energy: Option<Vec<f64>>,
    events: Vec<EventHit>,
    hits: Vec<(f64, usize)>,
}

impl Output {
    fn new(with_energy: bool) -> Self {
        Output {
            t: Vec::new(),
            y: Vec::new(),
            energy: with_energy.then(Vec::new),
            events: Vec::new(),
            hits: Vec::new(),
        }
    }

    fn push(&mut self, t: f64, y: &[f64], energy: Option<f64>) {
        self.t.push(t);
        self.y.push(y.to_vec());
        if let (Some(es), Some(e)) = (self.energy.as_mut(), energy) {
            es.push(e);
        }
    }
}

/// What the observer of [`Problem::solve_with`] sees after each step.
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
pub enum Status {
    /// At t_end.
    Completed,
    /// At the zero of a terminal event.
    Terminated {
        /// The index of the event (in the order given to [`Options::event`]).
        event: usize,
        /// Its time.
        t: f64,
    },
    /// The observer asked to stop, after the step that reached `t`.
    Stopped {
        /// The time reached.
        t: f64,
    },
}

/// A located zero of an event function.
#[derive(Clone, Debug, PartialEq)]
pub struct EventHit {
    /// The index of the event (in the order given to [`Options::event`]).
    pub event: usize,
    /// The time of the zero.
    pub t: f64,
    /// The state there.
    pub y: Vec<f64>,
}

/// What an integration cost.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    /// Steps of the integration.
    pub steps: usize,
    /// Evaluations of g in those steps.
    pub g_evals: usize,
    /// Fixed-point sweeps in those steps.
    pub sweeps: usize,
    /// Steps of the pilot runs that chose the method.
    pub pilot_steps: usize,
    /// Evaluations of g in the pilot runs.
    pub pilot_g_evals: usize,
    /// Steps taken to evaluate the solution between grid points (output times, events).
    pub dense_evals: usize,
    /// Evaluations of g in those steps.
    pub dense_g_evals: usize,
}

impl Stats {
    fn add_step(&mut self, rep: &StepReport) {
        self.steps += 1;
        self.g_evals += rep.g_evals;
        self.sweeps += rep.sweeps;
    }

    fn add_pilot(&mut self, rep: &StepReport) {
        self.pilot_steps += 1;
        self.pilot_g_evals += rep.g_evals;
    }

    /// Every evaluation of g: steps, pilots and output.
    pub fn total_g_evals(&self) -> usize {
        self.g_evals + self.pilot_g_evals + self.dense_g_evals
    }
}

/// The solution of a [`Problem`].
pub struct Solution<'p, S: System> {
    /// The output times: `t_eval`, or every step (t₀ first); up to the end of the run.
    pub t: Vec<f64>,
    /// The states at those times.
    pub y: Vec<Vec<f64>>,
    /// The energy H at those times, if the system knows H.
    pub energy: Option<Vec<f64>>,
    /// The located zeros of the events, in time order.
    pub events: Vec<EventHit>,
    /// How the run ended.
    pub status: Status,
    /// What it cost.
    pub stats: Stats,
    /// The order used: r (order 2r).
    pub r: usize,
    /// Gauss–Legendre points per step.
    pub s: usize,
    /// The step size (the last step may be shorter, to end at t_end).
    pub h: f64,
    /// The global error at t_end the pilot predicted, in tolerance units (≤ 1 is within the
    /// tolerance); `None` for [`Method::Fixed`].
    pub predicted_error: Option<f64>,
    energy0: Option<f64>,
    grid: Option<Grid>,
    dense: RefCell<DenseStepper<'p, S>>,
    problem: &'p Problem<S>,
}

impl<S: System> std::fmt::Debug for Solution<'_, S> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Solution")
            .field("t", &self.t)
            .field("y", &self.y)
            .field("energy", &self.energy)
            .field("events", &self.events)
            .field("status", &self.status)
            .field("stats", &self.stats)
            .field("r", &self.r)
            .field("h", &self.h)
            .finish_non_exhaustive()
    }
}

impl<S: System> Solution<'_, S> {
    /// max over the outputs of |H − H₀| / max(|H₀|, tiny), if the system knows H.
    pub fn energy_error(&self) -> Option<f64> {
        let e0 = self.energy0?;
        let scale = e0.abs().max(f64::MIN_POSITIVE);
        let es = self.energy.as_ref()?;
        Some(
            es.iter()
                .map(|e| (e - e0).abs() / scale)
                .fold(0.0, f64::max),
        )
    }

    /// Steps taken to evaluate the solution between grid points, and their evaluations of g:
    /// during the run (as in [`Stats`]) and by [`at`](Self::at) since.
    pub fn dense_evaluations(&self) -> (usize, usize) {
        self.dense.borrow().evals
    }

    /// The last output state.
    pub fn last(&self) -> Option<&[f64]> {
        self.y.last().map(Vec::as_slice)
    }

    /// The solution at any time of the run (needs [`Options::dense_output`]): the grid value
    /// on the grid, else one ECrP step of the run's order from the grid point before t.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] without dense output or for t outside the integrated span,
    /// and what that step reports.
    pub fn at(&self, t: f64) -> Result<Vec<f64>> {
        let mut out = vec![0.0; self.problem.y0.len()];
        self.at_into(t, &mut out)?;
        Ok(out)
    }

    /// [`at`](Self::at) into `out`.
    ///
    /// # Errors
    /// As [`at`](Self::at), and [`Error::DimensionMismatch`] for `out`.
    pub fn at_into(&self, t: f64, out: &mut [f64]) -> Result<()> {
        let grid = self.grid.as_ref().ok_or_else(|| {
            Error::InvalidInput("Solution::at needs Options::dense_output()".into())
        })?;
        if out.len() != self.problem.y0.len() {
            return Err(Error::DimensionMismatch {
                what: "the output and the system",
                expected: self.problem.y0.len(),
                found: out.len(),
            });
        }
        let (first, last) = (grid.t[0], *grid.t.last().unwrap_or(&grid.t[0]));
        if !(first..=last).contains(&t) {
            return Err(Error::InvalidInput(format!(
                "t = {t:?} is outside the integrated span [{first:?}, {last:?}]"
            )));
        }
        let n = grid.t.partition_point(|&tn| tn <= t).saturating_sub(1);
        if grid.t[n] == t {
            out.copy_from_slice(&grid.y[n]);
            return Ok(());
        }
        let mut stats = Stats::default();
        self.dense
            .borrow_mut()
            .advance(&grid.y[n], t - grid.t[n], out, &mut stats)
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
