//! A window of the run: a few steps of both runs at one step size from where the run stands,
//! with the estimate at every grid point; and, once the controller keeps it, what the window
//! gives the solution: outputs (at every step, or at the `t_eval` times inside it), located
//! events, the grid for dense output, and the steps for the observer.

use super::options::Options;
use super::record::{Point, Record};
use super::runs::{Cost, NOISE, Runs, Seed, estimate};
use super::solution::Status;
use crate::error::{Error, Result};

/// The controller aims the estimate at the end of the span at this share of the tolerance.
pub(super) const TARGET: f64 = 0.5;

/// An estimate above this (the tolerance) anywhere is not kept.
pub(super) const LIMIT: f64 = 1.0;

/// The largest order by which a step size is scaled when a window is integrated again or the
/// run starts again: far from the asymptotic regime (the large steps of a high order) the
/// estimate does not fall like h^p, and a bolder exponent would shrink the step too little.
pub(super) const P_BOLD: f64 = 6.0;

/// The order the check shows: 2(r − 1).
pub(super) fn check_order(r: usize) -> f64 {
    (2 * (r - 1)) as f64
}

/// The resolution of time at t: a step below it could not advance the clock.
pub(super) fn resolution(t: f64) -> f64 {
    crate::integrate::StepPlan::TIME_ULPS * f64::EPSILON * t.abs()
}

/// Where the runs stand: the time, the answer's steps since t₀, the largest estimate so far,
/// the states.
#[derive(Clone, Debug)]
pub(super) struct State {
    pub(super) t: f64,
    pub(super) n: usize,
    pub(super) worst: f64,
    pub(super) answer: Vec<f64>,
    pub(super) check: Vec<f64>,
}

/// A grid point of a window: its time, both states and the estimate there.
#[derive(Clone, Debug)]
pub(super) struct GridPoint {
    pub(super) t: f64,
    pub(super) answer: Vec<f64>,
    pub(super) check: Vec<f64>,
    pub(super) est: f64,
}

/// A step of a window failed.
#[derive(Debug)]
pub(super) struct StepFailure {
    pub(super) t: f64,
    pub(super) h: f64,
    pub(super) error: Error,
}

/// The solve's fixed facts: the options, the span, y₀, which times count as the same, the
/// times the steps must land on.
pub(super) struct Ctx<'o> {
    pub(super) options: &'o Options,
    pub(super) t0: f64,
    pub(super) t_end: f64,
    pub(super) y0: &'o [f64],
    pub(super) same_time: f64,
    /// The times steps land on (`Options::tstops` in the span, then t_end), ascending.
    pub(super) stops: Vec<f64>,
    /// The rounding unit of the noise model.
    pub(super) unit: f64,
    /// Whether the run is checked (a tolerance) or not (a fixed method).
    pub(super) verified: bool,
}

impl<'o> Ctx<'o> {
    pub(super) fn new(
        options: &'o Options,
        (t0, t_end): (f64, f64),
        y0: &'o [f64],
        verified: bool,
    ) -> Self {
        let same_time = 16.0 * f64::EPSILON * t0.abs().max(t_end.abs()).max(t_end - t0);
        let mut stops: Vec<f64> = options
            .tstops
            .iter()
            .copied()
            .filter(|&s| s > t0 + same_time && s < t_end - same_time)
            .collect();
        stops.sort_by(f64::total_cmp);
        stops.dedup();
        stops.push(t_end);
        Ctx {
            options,
            t0,
            t_end,
            y0,
            same_time,
            stops,
            unit: f64::EPSILON.max(options.settings.tolerance / 5.0),
            verified,
        }
    }

    /// The estimate at a grid point after `n` steps, in units of the tolerance: the scaled
    /// difference of the two runs plus the modelled round-off (0 for a fixed method).
    pub(super) fn estimate(&self, answer: &[f64], check: &[f64], n: usize) -> f64 {
        if !self.verified {
            return 0.0;
        }
        let tolerance = (self.options.rtol, self.options.atol);
        estimate(tolerance, self.unit, answer, check, n)
    }

    /// What one step of size `h` makes: the difference of the answer's step `answer` and the
    /// check's `check` from the same state, per component less a few roundings of it (below
    /// that, what a step makes cannot be told from how its stages were rounded: the
    /// component's own, and h times the largest component's, which the increment mixes in),
    /// in units of the tolerance; the largest over the components whose tolerance is not 0.
    pub(super) fn made(&self, answer: &[f64], check: &[f64], h: f64) -> f64 {
        let (rtol, atol) = (self.options.rtol, self.options.atol);
        let mixed = h.min(1.0) * answer.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        answer
            .iter()
            .zip(check)
            .map(|(a, c)| {
                let w = atol + rtol * a.abs();
                let e = (a - c).abs() - MADE_ROUNDING * self.unit * (a.abs().max(c.abs()) + mixed);
                if w > 0.0 && e > 0.0 { e / w } else { 0.0 }
            })
            .fold(0.0, |m, x| if x > m || x.is_nan() { x } else { m })
    }

    /// The modelled round-off of the answer `y` after `n` steps, in units of the tolerance.
    pub(super) fn noise(&self, y: &[f64], n: usize) -> f64 {
        estimate((self.options.rtol, self.options.atol), self.unit, y, y, n)
    }

    /// The rounding of one step from y₀ in units of the tolerance, over the components whose
    /// tolerance is not 0: below this nothing can be verified.
    pub(super) fn floor(&self) -> f64 {
        let (rtol, atol) = (self.options.rtol, self.options.atol);
        let big = self.y0.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        let noise = NOISE * self.unit * big.max(f64::MIN_POSITIVE);
        self.y0
            .iter()
            .map(|y| atol + rtol * y.abs())
            .filter(|&w| w > 0.0)
            .map(|w| noise / w)
            .fold(0.0, f64::max)
    }

    /// The next time steps must land on after `t` (a binary search: O(log n) per window, so
    /// 10⁶ stops cost no more than their sort).
    pub(super) fn next_stop(&self, t: f64) -> f64 {
        let after = t + self.same_time;
        let i = self.stops.partition_point(|&s| s <= after);
        self.stops.get(i).copied().unwrap_or(self.t_end)
    }

    /// The least number of steps the stops and `max_step` force on a run over the span: one
    /// step per stretch between stops, ⌈length / max_step⌉ where `max_step` is finite.
    pub(super) fn least_steps(&self) -> f64 {
        let max_step = self.options.max_step;
        let mut from = self.t0;
        let mut steps = 0.0;
        for &s in &self.stops {
            let length = s - from;
            steps += if max_step.is_finite() {
                (length / max_step).ceil().max(1.0)
            } else {
                1.0
            };
            from = s;
        }
        steps
    }

    /// The state at t₀.
    pub(super) fn start(&self) -> State {
        State {
            t: self.t0,
            n: 0,
            worst: 0.0,
            answer: self.y0.to_vec(),
            check: self.y0.to_vec(),
        }
    }
}

/// What a step makes ([`Ctx::made`]) counts above this many roundings of each component.
const MADE_ROUNDING: f64 = 4.0;

/// What the answer's step from `before` to `after` made alone: against the check's step from
/// `before` ([`Runs::step_local`], [`Ctx::made`]).
///
/// # Errors
/// What the check's stepper reports.
pub(super) fn made_step(
    ctx: &Ctx<'_>,
    runs: &mut dyn Runs,
    before: &[f64],
    after: &[f64],
    cost: &mut Cost,
) -> Result<f64> {
    let mut yl = vec![0.0; before.len()];
    runs.step_local(before, &mut yl, cost)?;
    Ok(ctx.made(after, &yl, runs.step_size()))
}

/// Fills the entries of `made` (one per step of `points`, which start at `from`) that
/// [`advance`] did not measure. A step whose measure fails counts as making infinitely much.
pub(super) fn made_all(
    ctx: &Ctx<'_>,
    runs: &mut dyn Runs,
    from: &[f64],
    points: &[GridPoint],
    made: &mut [f64],
    cost: &mut Cost,
) {
    for (j, m) in made.iter_mut().enumerate() {
        if m.is_nan() {
            let before = if j == 0 { from } else { &points[j - 1].answer };
            *m = made_step(ctx, runs, before, &points[j].answer, cost).unwrap_or(f64::INFINITY);
        }
    }
}

/// `(steps, end)`: `steps` steps of size h (set on the runs by the caller) from `from`, the
/// grid points with their estimates. Their times are a + (k + j)·h for the j-th step with
/// `(a, k) = origin` (where the steps of this size began, and how many were taken since: times
/// are computed, not summed), the last one `end` if given (a step that lands on a stop, its
/// size within the rounding of h). With `made`, also what the window's first and last steps make alone
/// ([`made_step`]), in units of the tolerance; `made` then holds an entry per step, NaN where
/// not measured ([`made_all`] fills them).
pub(super) fn advance(
    ctx: &Ctx<'_>,
    runs: &mut dyn Runs,
    from: &State,
    (a, k): (f64, usize),
    (steps, end): (usize, Option<f64>),
    mut made: Option<&mut Vec<f64>>,
    cost: &mut Cost,
) -> std::result::Result<Vec<GridPoint>, StepFailure> {
    let h = runs.step_size();
    let (mut ya, mut yc) = (from.answer.clone(), from.check.clone());
    let mut points = Vec::with_capacity(steps);
    if let Some(m) = made.as_deref_mut() {
        m.clear();
    }
    let time = |j: usize| ((k + j) as f64).mul_add(h, a);
    for j in 1..=steps {
        let t = match end {
            Some(e) if j == steps => e,
            _ => time(j),
        };
        let t_before = if j == 1 { from.t } else { time(j - 1) };
        let before = made
            .as_ref()
            .filter(|_| j == 1 || j == steps)
            .map(|_| ya.clone());
        runs.step(&mut ya, &mut yc, cost)
            .map_err(|error| StepFailure {
                t: t_before,
                h,
                error,
            })?;
        if let Some(m) = made.as_deref_mut() {
            m.push(match &before {
                Some(y) => made_step(ctx, runs, y, &ya, cost).map_err(|error| StepFailure {
                    t: t_before,
                    h,
                    error,
                })?,
                None => f64::NAN,
            });
        }
        let est = ctx.estimate(&ya, &yc, from.n + j);
        if est.is_nan() {
            return Err(StepFailure {
                t: t_before,
                h,
                error: Error::NonFinite("the estimate of the error"),
            });
        }
        points.push(GridPoint {
            t,
            answer: ya.clone(),
            check: yc.clone(),
            est,
        });
    }
    Ok(points)
}

/// What a kept window adds to the solution.
pub(super) struct Yield {
    /// The largest estimate of its values between grid points (outputs, events).
    pub(super) between: f64,
    /// Where a terminal event ended the run, if one did.
    pub(super) terminal: Option<(usize, f64)>,
}

/// The values of the runs at `t` between the grid point `base` (before t) and the next:
/// partial steps of both (the grid value itself where t is the grid point's time, moved along
/// the field where t is within the rounding of it).
#[allow(clippy::too_many_arguments)]
pub(super) fn between(
    ctx: &Ctx<'_>,
    runs: &mut dyn Runs,
    base: &GridPoint,
    n: usize,
    t: f64,
    trail: Option<&mut Trail>,
    source: Source<'_>,
    cost: &mut Cost,
) -> Result<Point> {
    let d = base.answer.len();
    let tolerance = (ctx.options.rtol, ctx.options.atol);
    let mut interp = None;
    if let Some(trail) = trail {
        if let Some(stencil) = trail.grid(d).stencil(t) {
            trail.slopes(stencil.range(), runs, cost)?;
            interp = Some((&*trail, stencil));
        }
    }
    let mut y = vec![0.0; d];
    let est = value_between(
        ValueAt {
            t,
            base: (base.t, &base.answer, &base.check, base.est),
            n,
            tolerance,
            unit: ctx.unit,
            verified: ctx.verified,
            source,
        },
        interp.map(|(trail, stencil)| {
            let (sa, sc) = trail.slopes_at(stencil.range());
            (trail.grid(d), stencil, sa, sc)
        }),
        &mut RunSteps(runs, cost),
        &mut y,
    )?;
    Ok(Point { t, y, est })
}

/// Where a value between grid points comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Source<'a> {
    /// The interpolant where its estimate allows, else a step of each run (the one rule of
    /// [`value_between`]).
    Rule,
    /// A step of each run (one source for all the values of a search).
    Steps,
    /// A step of the answer alone, without an estimate (a search's trial values: only the
    /// value it stops at needs the check's).
    Answer,
    /// The answer's value given (a trial value of a search, where it stopped), and a step of
    /// the check for its estimate.
    Check(&'a [f64]),
}

/// Which runs a step to a value between grid points advances.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Which {
    Both,
    Answer,
    Check,
}

/// What a value between grid points is asked for: the time, the grid point before it (its
/// time, the answer's and the check's states and its estimate), the steps to it, the tolerance
/// and the round-off model's unit.
pub(super) struct ValueAt<'a> {
    pub(super) t: f64,
    pub(super) base: (f64, &'a [f64], &'a [f64], f64),
    pub(super) n: usize,
    pub(super) tolerance: (f64, f64),
    pub(super) unit: f64,
    /// A checked run (else the estimate is 0 and no interpolant is tried).
    pub(super) verified: bool,
    /// Where the value comes from (the interpolant, where it does not serve the value, still
    /// starts the steps' stage iterations).
    pub(super) source: Source<'a>,
}

/// A stencil of the grid and its slopes (answer's, check's at the stencil's points).
pub(super) type Interp<'g> = (
    super::interp::Grid<'g>,
    super::interp::Stencil,
    &'g [f64],
    &'g [f64],
);

/// How a value between grid points is reached where the interpolant does not serve.
pub(super) trait PartialSteps {
    /// `y` moved along the vector field by `dt` (a time within the rounding of a grid point's).
    ///
    /// # Errors
    /// [`Error::NonFinite`] if the field is not finite there.
    fn drift(&mut self, y: &mut [f64], dt: f64) -> Result<()>;
    /// One step of length `dt` of the answer's method from `from.0` into `out.0` and of the
    /// check's from `from.1` into `out.1`, or only those `which` names (what is not stepped
    /// may be left as anything), their stage iterations started from `seed` where given.
    ///
    /// # Errors
    /// What the steps report.
    fn partial(
        &mut self,
        from: (&[f64], &[f64]),
        dt: f64,
        out: (&mut [f64], &mut [f64]),
        seed: Option<Seed<'_>>,
        which: Which,
    ) -> Result<()>;
}

/// The run's own steppers for values between grid points, with the cost counted.
struct RunSteps<'r>(&'r mut dyn Runs, &'r mut Cost);

impl PartialSteps for RunSteps<'_> {
    fn drift(&mut self, y: &mut [f64], dt: f64) -> Result<()> {
        self.0.drift(y, dt)
    }
    fn partial(
        &mut self,
        from: (&[f64], &[f64]),
        dt: f64,
        out: (&mut [f64], &mut [f64]),
        seed: Option<Seed<'_>>,
        which: Which,
    ) -> Result<()> {
        self.0.partial(from, dt, out, seed, which, self.1)
    }
}

/// The one rule for a value between grid points, used by outputs (`t_eval`), events and
/// [`Solution::at`](super::Solution::at): the grid value where t is its time; the grid value
/// moved along the field (`drift`) where t is within the rounding of it; the interpolant of
/// the grid where its estimate is at most [`INTERP_MAX`] tolerances; else one partial step of
/// each run from the grid point ([`PartialSteps`]), whose difference is the estimate. The
/// value goes to `out`; returns its estimate in tolerances.
pub(super) fn value_between(
    at: ValueAt<'_>,
    interp: Option<Interp<'_>>,
    steps: &mut dyn PartialSteps,
    out: &mut [f64],
) -> Result<f64> {
    let ValueAt {
        t,
        base: (t_base, answer, check, est),
        n,
        tolerance,
        unit,
        verified,
        source,
    } = at;
    let dt = t - t_base;
    out.copy_from_slice(answer);
    if dt <= 0.0 {
        return Ok(est);
    }
    if dt < 4.0 * f64::MIN_POSITIVE
        || dt <= crate::integrate::StepPlan::TIME_ULPS * f64::EPSILON * t.abs()
    {
        steps.drift(out, dt)?;
        return Ok(est);
    }
    // The interpolant of the grid where its estimate holds (no step, no φ-bank); where it
    // does not, it still starts the stage iterations of the steps (fewer sweeps than from the
    // grid state).
    let interp = interp.filter(|_| verified);
    if let Some((grid, stencil, sa, sc)) = interp.as_ref().filter(|_| source == Source::Rule) {
        let e = grid.value(t, *stencil, sa, sc, tolerance, unit, n + 1, out);
        if e <= INTERP_MAX {
            return Ok(e);
        }
    }
    let seed = |nodes: &[f64], check: bool, out: &mut [f64]| {
        if let Some((grid, stencil, sa, sc)) = &interp {
            let times = nodes.iter().map(|&c| t_base + c * dt);
            grid.states_at(times, *stencil, (sa, sc), check, out);
        }
    };
    let mut yc = vec![0.0; out.len()];
    let seed: Option<Seed<'_>> = interp.is_some().then_some(&seed);
    let which = match source {
        Source::Rule | Source::Steps => Which::Both,
        Source::Answer => Which::Answer,
        Source::Check(_) => Which::Check,
    };
    steps.partial((answer, check), dt, (out, &mut yc), seed, which)?;
    if let Source::Check(given) = source {
        out.copy_from_slice(given);
    }
    if !verified || which == Which::Answer {
        return Ok(0.0);
    }
    let e = super::runs::estimate(tolerance, unit, out, &yc, n + 1);
    if e.is_nan() {
        return Err(Error::NonFinite(
            "the estimate of the error between grid points",
        ));
    }
    Ok(e)
}

/// A value between grid points takes the interpolant where its estimate is at most this many
/// tolerances (else one step of each method, whose own estimate is usually far smaller).
pub(super) const INTERP_MAX: f64 = 0.5;

/// The last grid points of the run (times, the answer's and the check's states), for the
/// interpolant of values between them.
#[derive(Default)]
pub(super) struct Trail {
    t: Vec<f64>,
    answer: Vec<f64>,
    check: Vec<f64>,
    /// The runs' slopes there, NaN until a stencil needs them.
    slope_answer: Vec<f64>,
    slope_check: Vec<f64>,
    /// The runs' [`stiffness`](super::runs::stiffness), taken with the first slopes.
    stiffness: Vec<f64>,
}

impl Trail {
    /// Points kept besides a window's: an interpolant's stencil and its check before it.
    const KEEP: usize = super::interp::POINTS + 1;

    pub(super) fn push(&mut self, t: f64, answer: &[f64], check: &[f64]) {
        self.t.push(t);
        self.answer.extend_from_slice(answer);
        self.check.extend_from_slice(check);
        let d = answer.len();
        self.slope_answer
            .resize(self.slope_answer.len() + d, f64::NAN);
        self.slope_check
            .resize(self.slope_check.len() + d, f64::NAN);
    }

    /// Evaluates the slopes of the points in `range` not evaluated yet.
    ///
    /// # Errors
    /// What [`Runs::slope`] reports.
    pub(super) fn slopes(
        &mut self,
        range: std::ops::Range<usize>,
        runs: &mut dyn Runs,
        cost: &mut Cost,
    ) -> Result<()> {
        if self.stiffness.is_empty() {
            self.stiffness = runs.stiffness().to_vec();
        }
        let d = self.answer.len() / self.t.len().max(1);
        for j in range {
            let at = j * d..(j + 1) * d;
            if self.slope_answer[at.start].is_nan() {
                runs.slope(
                    &self.answer[at.clone()],
                    &mut self.slope_answer[at.clone()],
                    cost,
                )?;
                runs.slope(&self.check[at.clone()], &mut self.slope_check[at], cost)?;
            }
        }
        Ok(())
    }

    /// The slopes of the points in `range` (evaluated by [`Trail::slopes`]).
    pub(super) fn slopes_at(&self, range: std::ops::Range<usize>) -> (&[f64], &[f64]) {
        let d = self.answer.len() / self.t.len().max(1);
        let at = range.start * d..range.end * d;
        (&self.slope_answer[at.clone()], &self.slope_check[at])
    }

    /// The number of points held.
    pub(super) fn len(&self) -> usize {
        self.t.len()
    }

    /// Back to `len` points (the ones pushed after are dropped).
    pub(super) fn truncate(&mut self, len: usize) {
        let d = self.answer.len().checked_div(self.t.len()).unwrap_or(0);
        self.t.truncate(len);
        self.answer.truncate(len * d);
        self.check.truncate(len * d);
        self.slope_answer.truncate(len * d);
        self.slope_check.truncate(len * d);
    }

    /// Keeps only the last [`Trail::KEEP`] points.
    pub(super) fn trim(&mut self) {
        let n = self.t.len();
        if n > Self::KEEP {
            let d = self.answer.len() / n;
            let drop = n - Self::KEEP;
            self.t.drain(..drop);
            self.answer.drain(..drop * d);
            self.check.drain(..drop * d);
            self.slope_answer.drain(..drop * d);
            self.slope_check.drain(..drop * d);
        }
    }

    pub(super) fn grid(&self, d: usize) -> super::interp::Grid<'_> {
        super::interp::Grid {
            t: &self.t,
            answer: &self.answer,
            check: &self.check,
            d,
            stiffness: &self.stiffness,
        }
    }
}

/// Gives the solution what the kept window `points` (after the grid point `start`, the answer's
/// step `n0` there) holds: every grid point as an output (without `t_eval`) or the `t_eval`
/// times in (start, last], the zeros of the events, the grid, the steps for the observer.
/// `t_eval_next` is the index of the next `t_eval` time not yet produced; `ev_prev` the event
/// functions at the start.
///
/// # Errors
/// What the steps between grid points report, an event function's NaN, storage.
#[allow(clippy::too_many_arguments)]
pub(super) fn keep(
    ctx: &Ctx<'_>,
    runs: &mut dyn Runs,
    record: &mut Record,
    start: &GridPoint,
    n0: usize,
    points: &[GridPoint],
    t_eval_next: &mut usize,
    ev_prev: &mut [f64],
    with_observer: bool,
    mut trail: Option<&mut Trail>,
) -> Result<Yield> {
    let options = ctx.options;
    let mut cost = Cost::default();
    let mut between_worst = 0.0_f64;
    let mut terminal = None;
    let h = runs.step_size();
    let mut prev = start;
    for (j, p) in points.iter().enumerate() {
        let n = n0 + j;
        // Events: a sign change of an event function over this step, located by partial steps
        // of the answer from the grid point before it.
        let mut first_hit: Option<(usize, Point)> = None;
        for (k, event) in options.events.iter().enumerate() {
            let after = event.value(k, p.t, &p.answer)?;
            let before = ev_prev[k];
            ev_prev[k] = after;
            if !event.counts(before, after) {
                continue;
            }
            let hit = super::events::hit(
                ctx,
                runs,
                (prev, p),
                n,
                (k, event),
                (before, after),
                trail.as_deref_mut(),
                &mut cost,
            )?;
            between_worst = between_worst.max(hit.est);
            if event.terminal && first_hit.as_ref().is_none_or(|(_, q)| hit.t < q.t) {
                first_hit = Some((k, hit.clone()));
            }
            if !event.terminal {
                record.hits.push((k, hit));
            }
        }
        let end = first_hit.as_ref().map_or(p.t, |(_, q)| q.t);
        // Outputs up to the end of this step (or the terminal event).
        match &options.t_eval {
            None => {
                if first_hit.is_none() {
                    record.output(Point {
                        t: p.t,
                        y: p.answer.clone(),
                        est: p.est,
                    })?;
                }
            }
            Some(ts) => {
                while let Some(&t) = ts.get(*t_eval_next) {
                    if t > end + ctx.same_time || (first_hit.is_some() && t > end) {
                        break;
                    }
                    let v = if (t - p.t).abs() <= ctx.same_time {
                        Point {
                            t,
                            y: p.answer.clone(),
                            est: p.est,
                        }
                    } else {
                        between(
                            ctx,
                            runs,
                            prev,
                            n,
                            t,
                            trail.as_deref_mut(),
                            Source::Rule,
                            &mut cost,
                        )?
                    };
                    between_worst = between_worst.max(v.est);
                    record.output(v)?;
                    *t_eval_next += 1;
                }
            }
        }
        if let Some((k, hit)) = first_hit {
            let t = hit.t;
            if options.t_eval.is_none() {
                record.output(hit.clone())?;
            }
            record.hits.push((k, hit));
            terminal = Some((k, t));
            break;
        }
        if options.dense {
            record.grid(p.t, &p.answer, &p.check)?;
        }
        if with_observer {
            record.step_for_observer(p.t, n + 1, h, &p.answer);
        }
        prev = p;
    }
    record.cost.add(&cost);
    if let Some((event, t)) = terminal {
        record.stop_at(t, Status::Terminated { event, t });
    }
    Ok(Yield {
        between: between_worst,
        terminal,
    })
}

/// The outputs at t₀: y₀ (every step's output starts there; `t_eval` times at t₀).
pub(super) fn start_outputs(
    ctx: &Ctx<'_>,
    record: &mut Record,
    t_eval_next: &mut usize,
) -> Result<()> {
    let est = ctx.estimate(ctx.y0, ctx.y0, 0);
    match &ctx.options.t_eval {
        None => record.output(Point {
            t: ctx.t0,
            y: ctx.y0.to_vec(),
            est,
        }),
        Some(ts) => {
            while let Some(&t) = ts.get(*t_eval_next) {
                if t > ctx.t0 + ctx.same_time {
                    break;
                }
                record.output(Point {
                    t,
                    y: ctx.y0.to_vec(),
                    est,
                })?;
                *t_eval_next += 1;
            }
            Ok(())
        }
    }
}
