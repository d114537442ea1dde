//! What [`Problem::solve`](super::Problem::solve) is asked for.

use std::fmt;
use std::ops::RangeInclusive;
use std::sync::Arc;

use super::events::Event;
use crate::error::{Error, Result};
use crate::stepper::SolverSettings;

/// How the solver picks the method and its step size.
#[derive(Clone, Debug, PartialEq)]
pub enum Method {
    /// Order and step size from the tolerance, the answer verified (see the module docs).
    Auto,
    /// ECrP of this r (order 2r, s = r), step size from the tolerance, the answer verified.
    Order(usize),
    /// ECrP of this r with this fixed step size h: no tolerance, no verification, no
    /// estimate. The last step is shortened to end at t_end if h does not divide the span;
    /// an h beyond the span is one step of the span.
    Fixed {
        /// r (order 2r).
        r: usize,
        /// The step size.
        h: f64,
    },
}

/// Where the decisions of a solve are told, line by line (see [`Options::trace`]).
type TraceSink = Arc<dyn Fn(&str) + Send + Sync>;

/// What [`Problem::solve`](super::Problem::solve) is asked for: a tolerance (or a fixed
/// method), output times, events.
pub struct Options {
    pub(super) rtol: f64,
    pub(super) atol: f64,
    pub(super) method: Method,
    pub(super) orders: RangeInclusive<usize>,
    pub(super) t_eval: Option<Vec<f64>>,
    pub(super) dense: bool,
    pub(super) events: Vec<Event>,
    pub(super) settings: SolverSettings,
    pub(super) max_steps: usize,
    pub(super) max_step: f64,
    pub(super) tstops: Vec<f64>,
    pub(super) trace: Option<TraceSink>,
}

impl fmt::Debug for Options {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Options")
            .field("rtol", &self.rtol)
            .field("atol", &self.atol)
            .field("method", &self.method)
            .field("orders", &self.orders)
            .field("t_eval", &self.t_eval.as_ref().map(Vec::len))
            .field("dense", &self.dense)
            .field("events", &self.events)
            .field("settings", &self.settings)
            .field("max_steps", &self.max_steps)
            .field("max_step", &self.max_step)
            .field("tstops", &self.tstops)
            .field("trace", &self.trace.is_some())
            .finish()
    }
}

// Options are shared by the threads that solve the members of an ensemble (and may be sent to
// another thread): a compile error, in every build, if a field stops being `Send + Sync`.
const _: () = {
    const fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<Options>();
    assert_send_sync::<Event>();
};

impl Default for Options {
    /// rtol = 1e−6, atol = 1e−9, [`Method::Auto`] over r = 2..=8, output at every step, the
    /// stepper's default [`SolverSettings`], at most 10⁸ steps in one run, no largest step, no
    /// times the steps must land on.
    fn default() -> Self {
        Options {
            rtol: 1e-6,
            atol: 1e-9,
            method: Method::Auto,
            orders: 2..=8,
            t_eval: None,
            dense: false,
            events: Vec::new(),
            settings: SolverSettings::default(),
            max_steps: 100_000_000,
            max_step: f64::INFINITY,
            tstops: Vec::new(),
            trace: None,
        }
    }
}

impl Options {
    /// rtol = atol = `tol`: the global error at every output time within tol·(1 + |y_i|) per
    /// component.
    pub fn tolerance(tol: f64) -> Self {
        Options {
            rtol: tol,
            atol: tol,
            ..Options::default()
        }
    }

    /// ECrP of order 2r with the fixed step size h (no tolerance, no verification).
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

    /// The orders [`Method::Auto`] chooses from (r of the answer, order 2r; default 2..=8). The
    /// answer of order 2r is checked by a method of order 2r − 2, so r ≥ 2.
    #[must_use]
    pub fn orders(mut self, orders: RangeInclusive<usize>) -> Self {
        self.orders = orders;
        self
    }

    /// Output at these times (ascending, within the time span) instead of at every step. They
    /// do not become grid points: a value between grid points comes from the grid's interpolant
    /// or from one step of the answer (and of its check, for its estimate) from the grid point
    /// before it. A value whose estimate is above the tolerance makes its window integrated
    /// again with smaller steps, so output times can change the steps; where every value is
    /// within the tolerance the run takes the steps it takes without them.
    #[must_use]
    pub fn t_eval(mut self, times: impl IntoIterator<Item = f64>) -> Self {
        self.t_eval = Some(times.into_iter().collect());
        self
    }

    /// Keeps the step grid so that [`Solution::at`](super::Solution::at) can evaluate the
    /// solution anywhere.
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

    /// The stage solver's settings (of the run that is returned; the runs that only check it
    /// stop their stage iteration at the accuracy the check needs).
    #[must_use]
    pub fn settings(mut self, settings: SolverSettings) -> Self {
        self.settings = settings;
        self
    }

    /// The most steps one run may take (an error beyond).
    #[must_use]
    pub fn max_steps(mut self, n: usize) -> Self {
        self.max_steps = n;
        self
    }

    /// No step longer than `h`. A feature of the solution narrower than the steps the
    /// tolerance allows elsewhere — a pulse, a short forcing — can fall between the points where
    /// the methods sample g, and then no estimate sees it (no sampled method can): a largest
    /// step below its width makes the steps see it. For a feature at a known time,
    /// [`tstops`](Self::tstops) is cheaper. A largest step (with the stops) that needs more
    /// than [`max_steps`](Self::max_steps) steps over the span is refused before the run.
    #[must_use]
    pub fn max_step(mut self, h: f64) -> Self {
        self.max_step = h;
        self
    }

    /// Times the steps land on (within the span; others are ignored): a kink or a jump of g at
    /// a known time is then a grid point, where the methods of the step start afresh, instead
    /// of lying inside a step whose polynomial cannot follow it. The remedy for a right-hand
    /// side that is not smooth at known times; see also [`max_step`](Self::max_step).
    #[must_use]
    pub fn tstops(mut self, times: impl IntoIterator<Item = f64>) -> Self {
        self.tstops = times.into_iter().collect();
        self
    }

    /// What of the options decides a solve's numbers, field by field as the fingerprint of an
    /// ensemble's table writes them ([`crate::ensemble::fingerprint`]): the method, the
    /// tolerances, the orders, the largest step, the most steps, the stops, the output times,
    /// dense output, the number of events (their functions cannot be seen) and the stage
    /// solver's settings. Not the trace (it changes nothing). Lists of numbers are written by
    /// `numbers` (the fingerprint's own form: `solve` sits below `ensemble` and does not
    /// import it).
    pub(crate) fn fingerprint_fields(
        &self,
        numbers: impl Fn(&[f64]) -> String,
    ) -> Vec<(&'static str, String)> {
        vec![
            ("method", format!("{:?}", self.method)),
            ("rtol", format!("{:?}", self.rtol)),
            ("atol", format!("{:?}", self.atol)),
            ("orders", format!("{:?}", self.orders)),
            ("max_step", format!("{:?}", self.max_step)),
            ("max_steps", self.max_steps.to_string()),
            ("tstops", numbers(&self.tstops)),
            (
                "t_eval",
                self.t_eval
                    .as_deref()
                    .map_or_else(|| "every step".to_string(), &numbers),
            ),
            ("dense", self.dense.to_string()),
            ("events", self.events.len().to_string()),
            ("settings", format!("{:?}", self.settings)),
        ]
    }

    /// The answer's orders r a verified solve may choose (r ≥ 2: its check is of order 2r − 2).
    pub(super) fn answer_orders(&self) -> Result<(usize, usize)> {
        let (lo, hi) = match self.method {
            Method::Order(r) => (r, r),
            _ => (*self.orders.start(), *self.orders.end()),
        };
        if hi < 2 {
            return Err(Error::InvalidParameter(format!(
                "a verified solve needs r >= 2 (order 4 or more: the answer of order 2r is checked \
                 by a method of order 2r - 2); got r = {hi}; for order 2 without a check use \
                 Options::fixed(1, h)"
            )));
        }
        let top = ecr_codegen::MAX_R;
        if hi > top {
            return Err(Error::InvalidParameter(format!(
                "r = {hi} is beyond the largest supported r = {top}"
            )));
        }
        Ok((lo.max(2), hi))
    }
    /// Tells `sink` every decision of the solve, one line each (starting with `solve: `): every
    /// pilot round (its order, step and estimate), every kept window with its step and
    /// estimate, every window integrated again and every run started again, and why. For finding out why a solve chose what
    /// it chose, or why it could not verify its answer; the library itself never prints.
    ///
    /// ```
    /// use ecr_runtime::solve::Options;
    /// let options = Options::tolerance(1e-8).trace(|line| eprintln!("{line}"));
    /// ```
    #[must_use]
    pub fn trace(mut self, sink: impl Fn(&str) + Send + Sync + 'static) -> Self {
        self.trace = Some(Arc::new(sink));
        self
    }

    /// Gives the line `line()` to the trace sink, if there is one (the line is not formatted
    /// otherwise).
    pub(super) fn say(&self, line: impl FnOnce() -> String) {
        if let Some(sink) = &self.trace {
            sink(&format!("solve: {}", line()));
        }
    }

    pub(crate) fn validate(&self) -> Result<()> {
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
        match self.method {
            Method::Fixed { r, h } => {
                if !(h.is_finite() && h > 0.0) {
                    return Err(Error::InvalidStepSize(h));
                }
                if r == 0 {
                    return Err(Error::InvalidParameter("r must be >= 1".into()));
                }
            }
            Method::Order(0) => return Err(Error::InvalidParameter("r must be >= 1".into())),
            _ => {}
        }
        if let Some(ts) = &self.t_eval {
            if ts.iter().any(|t| !t.is_finite()) {
                return Err(Error::NonFinite("t_eval"));
            }
            if ts.windows(2).any(|w| w[1] < w[0]) {
                return Err(Error::InvalidInput("t_eval must be ascending".into()));
            }
        }
        if self.max_steps == 0 {
            return Err(Error::InvalidParameter("max_steps must be >= 1".into()));
        }
        if self.max_step.is_nan() || self.max_step <= 0.0 {
            return Err(Error::InvalidParameter(format!(
                "max_step must be > 0 (got {:?})",
                self.max_step
            )));
        }
        if self.tstops.iter().any(|t| !t.is_finite()) {
            return Err(Error::NonFinite("tstops"));
        }
        self.settings.validate()
    }
}
