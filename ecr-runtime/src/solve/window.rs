//! A window of the run: a few steps of both runs at one step size from where the run stands,
//! with the estimate at every grid point; and, once the controller keeps it, what the window
//! gives the solution: outputs (at every step, or at the `t_eval` times inside it), located
//! events, the grid for dense output, and the steps for the observer.

use super::between::{Source, Trail, between};
use super::local::LocalRun;
use super::options::Options;
use super::record::{Point, Record};
use super::runs::{Cost, NOISE, Runs, estimate};
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
    /// The time, rounded: the steps taken since t₀ add up to `t + t_lo` (double-double), so
    /// that the rounding of the times where the step size changed does not add up over the
    /// segments (a drift of the times that both runs share, which their difference cannot
    /// see: Duffing ω = 20 at 1e−11 over 1000 time units, 2 839 segments, ended 1.0e−11 short
    /// of t_end, 12 tolerances off under an estimate of 0.11).
    pub(super) t: f64,
    pub(super) t_lo: f64,
    pub(super) n: usize,
    pub(super) worst: f64,
    pub(super) answer: Vec<f64>,
    pub(super) check: Vec<f64>,
}

/// A grid point of a window: its time, both states and the estimate there.
#[derive(Clone, Debug)]
pub(super) struct GridPoint {
    pub(super) t: f64,
    /// What the steps add up to beyond `t` (see [`State::t`]).
    pub(super) t_lo: f64,
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
            t_lo: 0.0,
            n: 0,
            worst: 0.0,
            answer: self.y0.to_vec(),
            check: self.y0.to_vec(),
        }
    }
}

/// `(steps, end)`: `steps` steps of size h (set on the runs by the caller) from `from`, the
/// grid points with their estimates. Their times are a + a_lo + (k + j)·h for the j-th step
/// with `(a, a_lo, k) = origin` (where the steps of this size began in double-double, and how
/// many were taken since: times are computed, not summed), rounded, with what the rounding left
/// in `t_lo`; the last one `end` if given (a step that lands on a stop, its size within the
/// rounding of h). With `local`, also what the window's first and last steps make alone
/// ([`LocalRun::after_step`]).
pub(super) fn advance(
    ctx: &Ctx<'_>,
    runs: &mut dyn Runs,
    from: &State,
    (a, a_lo, k): (f64, f64, usize),
    (steps, end): (usize, Option<f64>),
    mut local: Option<&mut LocalRun>,
    cost: &mut Cost,
) -> std::result::Result<Vec<GridPoint>, StepFailure> {
    let h = runs.step_size();
    let (mut ya, mut yc) = (from.answer.clone(), from.check.clone());
    let mut points = Vec::with_capacity(steps);
    if let Some(l) = local.as_deref_mut() {
        l.start_window();
    }
    let time = |j: usize| grid_time(a, a_lo, k + j, h);
    for j in 1..=steps {
        let (t, t_lo) = match end {
            Some(e) if j == steps => {
                let (t, lo) = time(j);
                (e, (t - e) + lo)
            }
            _ => time(j),
        };
        let t_before = if j == 1 { from.t } else { time(j - 1).0 };
        runs.step(&mut ya, &mut yc, cost)
            .map_err(|error| StepFailure {
                t: t_before,
                h,
                error,
            })?;
        if let Some(l) = local.as_deref_mut() {
            let before = points
                .last()
                .map_or(&from.answer, |q: &GridPoint| &q.answer);
            let measured = j == 1 || j == steps;
            l.after_step(ctx, runs, (before, &ya), measured, cost)
                .map_err(|error| StepFailure {
                    t: t_before,
                    h,
                    error,
                })?;
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
            t_lo,
            answer: ya.clone(),
            check: yc.clone(),
            est,
        });
    }
    Ok(points)
}

/// `a + a_lo + n·h` in double-double: the rounded time and what the rounding left.
pub(super) fn grid_time(a: f64, a_lo: f64, n: usize, h: f64) -> (f64, f64) {
    let n = n as f64;
    let p = n * h;
    let p_lo = n.mul_add(h, -p);
    let (s, e) = crate::phi::two_sum(a, p);
    let lo = e + p_lo + a_lo;
    let t = s + lo;
    (t, lo - (t - s))
}

/// What a kept window adds to the solution.
pub(super) struct Yield {
    /// The largest estimate of its values between grid points (outputs, events).
    pub(super) between: f64,
    /// Where a terminal event ended the run, if one did.
    pub(super) terminal: Option<(usize, f64)>,
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
    // The event functions' samples inside each step: times and the answer's interpolant there.
    let d = start.answer.len();
    let mut scan_t = [0.0; super::hits::SCAN];
    let mut scan_y = if options.events.is_empty() {
        Vec::new()
    } else {
        vec![0.0; super::hits::SCAN * d]
    };
    let mut brackets = Vec::new();
    for (j, p) in points.iter().enumerate() {
        let n = n0 + j;
        // Events: the sign changes of an event function over this step (at its ends and at
        // the interpolant's samples inside it), located by partial steps of the answer from
        // the grid point before it. The trail is the scan's in any run, and the values'
        // between grid points in a checked one (an unchecked run's are its steps').
        let mut first_hit: Option<(usize, Point)> = None;
        let mut scanned = false;
        if !options.events.is_empty() {
            if let Some(trail) = trail.as_deref_mut() {
                let parts = (scan_t.len() + 1) as f64;
                for (i, t) in scan_t.iter_mut().enumerate() {
                    *t = prev.t + (p.t - prev.t) * (i + 1) as f64 / parts;
                }
                scanned =
                    trail.scan(prev.t.midpoint(p.t), &scan_t, runs, &mut cost, &mut scan_y)?;
            }
        }
        for (k, event) in options.events.iter().enumerate() {
            let after = event.value(k, p.t, &p.answer)?;
            let before = ev_prev[k];
            ev_prev[k] = after;
            super::hits::brackets(
                ctx,
                runs,
                (prev, p),
                n,
                (k, event),
                (before, after),
                scanned.then_some((&scan_t[..], &scan_y[..])),
                trail.as_deref_mut().filter(|_| ctx.verified),
                &mut cost,
                &mut brackets,
            )?;
            for &bracket in &brackets {
                let hit = super::hits::hit(
                    ctx,
                    runs,
                    (prev, p),
                    n,
                    (k, event),
                    bracket,
                    trail.as_deref_mut().filter(|_| ctx.verified),
                    &mut cost,
                )?;
                between_worst = between_worst.max(hit.est);
                if event.terminal {
                    if first_hit.as_ref().is_none_or(|(_, q)| hit.t < q.t) {
                        first_hit = Some((k, hit));
                    }
                    break;
                }
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
                            trail.as_deref_mut().filter(|_| ctx.verified),
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
