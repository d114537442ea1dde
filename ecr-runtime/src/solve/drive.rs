//! How a solve proceeds: a fixed-step run, or the pilot and then the verified run in chunks,
//! with the decision after each chunk (keep it, or integrate again with a smaller step).

use std::sync::Arc;

use super::estimate::{
    Profile, TARGET, at_most, divisor, estimate, project, project_noise, project_steep, quantile,
    rescale,
};
use super::grid::{fit_grid, quantum};
use super::kept::{Kept, Observer, discard, ensure_output_fits, finish};
use super::options::{Method, Options};
use super::pilot::Pilot;
use super::run::{Checkpoint, Chunk, Collect, Grid, MEET, Point, Runs, Which};
use super::solution::{Segment, Solution, SolveError, Stats, Status};
use super::{Problem, SOLVE_CACHE_BANKS, SolveCache};
use crate::error::{Error, Result};
use crate::integrate::StepPlan;
use crate::system::System;

/// The first chunk is this share of the span; each next one twice the one before, up to
/// [`LAST_CHUNK_SHARE`].
const FIRST_CHUNK_SHARE: f64 = 1.0 / 64.0;
const LAST_CHUNK_SHARE: f64 = 1.0 / 8.0;

/// Runs started again from t₀ before the solve gives up.
const MAX_RESTARTS: usize = 8;

/// Failures of a step at the same place (with ever smaller steps) before the solve gives up.
const STUCK_LIMIT: usize = 5;

/// With an observer: chunks integrated again (from their start) before the solve gives up.
const MAX_RETRIES: usize = 10;

/// A run far more accurate than asked starts again with a larger step only this early (an
/// error that grows late is not seen before), at most [`MAX_UPS`] times, each at most twice as
/// large.
const UP_SHARE: f64 = 1.0 / 16.0;

/// Upward restarts of a solve.
const MAX_UPS: usize = 2;

/// With an observer, the run is shown to it from this share of the span on.
const SHOW_SHARE: f64 = 1.0 / 8.0;

/// Step-size changes of the run before it keeps the step it has.
const MAX_SEGMENTS: usize = 8;

/// Steps of a fixed-step run kept at once (without an observer).
const FIXED_CHUNK_STEPS: usize = 1024;

impl<S: System> Problem<S> {
    pub(super) fn run(
        &self,
        options: &Options,
        mut observer: Observer<'_>,
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
        let cache = Arc::new(SolveCache::<S>::new(SOLVE_CACHE_BANKS));
        match options.method {
            Method::Fixed { r, h } => Ok(self.fixed(options, r, h, &mut observer, &cache)?),
            _ => self.verified(options, &mut observer, &cache),
        }
    }

    pub(super) fn same_time(&self) -> f64 {
        16.0 * f64::EPSILON
            * self
                .t0
                .abs()
                .max(self.t_end.abs())
                .max(self.t_end - self.t0)
    }

    /// ECrP with a fixed step (no verification), the observer called after every step.
    fn fixed(
        &self,
        options: &Options,
        r: usize,
        h: f64,
        observer: &mut Observer<'_>,
        cache: &Arc<SolveCache<S>>,
    ) -> Result<Solution<S>> {
        let span = self.t_end - self.t0;
        // A step beyond the span is one step of the span.
        let h = if span > 0.0 { h.min(span) } else { h };
        let plan = StepPlan::new(self.t0, self.t_end, h)?;
        let steps = plan.steps();
        if steps > options.max_steps {
            return Err(Error::InvalidInput(format!(
                "the integration needs {steps} steps of h = {h:?}, more than max_steps = {}",
                options.max_steps
            )));
        }
        // Refused before the run rather than aborted on an allocation midway.
        let outputs = options.t_eval.as_ref().map_or(steps + 1, Vec::len);
        let dense = if options.dense { steps + 1 } else { 0 };
        ensure_output_fits(
            self.y0.len(),
            outputs,
            dense,
            usize::from(observer.is_some()),
        )?;
        let grid = Grid {
            a: self.t0,
            h,
            n_end: steps,
            end: self.t_end,
        };
        let system = &*self.system;
        let mut runs = Runs::new(
            system,
            options,
            r,
            false,
            &self.y0,
            grid,
            self.same_time(),
            1.0,
            cache,
        )?;
        let collect = Collect {
            every_step: options.t_eval.is_none(),
            steps: observer.is_some(),
            grid: options.dense,
            events: true,
            t_eval: true,
        };
        let mut kept = Kept::new(self.t0, h);
        let mut first = Chunk::default();
        runs.start(collect, &mut first)?;
        kept.keep(first, None, h)?;
        // With an observer, every step is shown as soon as it is made.
        let chunk_steps = if observer.is_some() {
            1
        } else {
            FIXED_CHUNK_STEPS
        };
        while runs.n < steps && !kept.ended() {
            let stop = (runs.n + chunk_steps).min(steps);
            let chunk = runs
                .advance(stop, collect)
                .map_err(|(f, _)| Error::AtStep {
                    step: runs.total + 1,
                    t: f.t,
                    h: f.h,
                    source: Box::new(f.error),
                })?;
            kept.keep(chunk, None, h)?;
            kept.show(observer);
        }
        let mut stats = Stats::default();
        finish(&mut stats, &kept.cost);
        Ok(self.assemble(options, kept, stats, r, None, None, h))
    }

    /// A tolerance: the floor check, the pilot, then the verified run.
    fn verified(
        &self,
        options: &Options,
        observer: &mut Observer<'_>,
        cache: &Arc<SolveCache<S>>,
    ) -> std::result::Result<Solution<S>, SolveError> {
        let span = self.t_end - self.t0;
        let system = &*self.system;
        let same = self.same_time();
        // The rounding of y₀ and the stage iteration's stopping tolerance alone, in units of
        // the tolerance: below this nothing can be verified.
        let start = Grid {
            a: self.t0,
            h: 1.0,
            n_end: 0,
            end: self.t_end,
        };
        let r0 = self.first_order(options);
        let mut runs = Runs::new(system, options, r0, true, &self.y0, start, same, 1.0, cache)?;
        let floor = runs.noise_at_start();
        if !floor.is_finite() {
            let big = self.y0.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            return Err(Error::InvalidInput(format!(
                "y0 holds {big:e}, too close to the largest f64 ({:e}) for its rounding to be \
                 bounded: the steps would overflow; rescale the problem",
                f64::MAX
            ))
            .into());
        }
        if !at_most(floor, 0.25) {
            return Err(Error::InvalidInput(format!(
                "rtol = {:e}, atol = {:e} is below what f64 can verify for this problem: the \
                 rounding of y0 and of the stage iteration alone is {floor:.2e} times it; ask \
                 for about {:.0e} times the tolerance or more",
                options.rtol,
                options.atol,
                (4.0 * floor).max(1.0)
            ))
            .into());
        }
        let mut stats = Stats::default();
        if span == 0.0 {
            let collect = Collect {
                every_step: options.t_eval.is_none(),
                steps: false,
                grid: options.dense,
                events: true,
                t_eval: true,
            };
            let mut kept = Kept::new(self.t0, 0.0);
            let mut chunk = Chunk::default();
            runs.start(collect, &mut chunk)?;
            kept.keep(chunk, Some(1.0), 0.0)?;
            return Ok(self.assemble(options, kept, stats, r0, Some(1.0), None, 0.0));
        }
        let resolution = StepPlan::TIME_ULPS * f64::EPSILON * self.t0.abs().max(self.t_end.abs());
        if span <= resolution {
            return self.within_rounding_of_time(options, r0, floor, observer, cache);
        }
        let pilot = match options.method {
            Method::Order(r) => self.pilot(options, r, None, &mut stats, cache)?,
            _ => self.pilot_auto(options, &mut stats, cache)?,
        };
        self.verified_run(options, pilot, stats, observer, cache)
    }

    /// A span within the rounding of time (a few ulps of t): one step of the span, checked
    /// against y₀ moved along the vector field by the span (their difference bounds the
    /// step's error from above while the step is that small), or the rounding of y₀ if that is
    /// larger.
    fn within_rounding_of_time(
        &self,
        options: &Options,
        r: usize,
        floor: f64,
        observer: &mut Observer<'_>,
        cache: &Arc<SolveCache<S>>,
    ) -> std::result::Result<Solution<S>, SolveError> {
        let span = self.t_end - self.t0;
        let mut solution = self.fixed(options, r, span, observer, cache)?;
        let mut moved = self.y0.clone();
        super::run::drift(&*self.system, &mut moved, span)?;
        let end = match solution.y.last() {
            Some(y) if solution.t.last() == Some(&self.t_end) => {
                let e = options.scaled(y.iter().zip(&moved).map(|(a, b)| a - b), y);
                floor.max(e)
            }
            _ => floor,
        };
        if !at_most(end, 1.0) {
            return Err(Error::InvalidInput(format!(
                "the span [{:?}, {:?}] is within the rounding of time, yet one step of it and \
                 y0 moved along the vector field differ by {end:.2e} times the tolerance",
                self.t0, self.t_end
            ))
            .into());
        }
        let n = solution.t.len();
        solution.error_estimates = vec![floor; n];
        if let Some(last) = solution.error_estimates.last_mut() {
            *last = end;
        }
        solution.error_estimate = Some(end);
        Ok(solution)
    }

    /// The verified run (see the module docs): chunks of the three runs from t₀; after each
    /// chunk the estimate is checked at its outputs and projected to the end of the span. A
    /// chunk over the tolerance, or a projection over it, starts the run again from t₀ with
    /// a step from the step-size law (errors already made keep growing: a smaller step
    /// later cannot undo them), as long as nothing has been shown to an observer. With an
    /// observer, the run is shown from [`SHOW_SHARE`] of the span on, chunk by chunk; a later
    /// chunk over the tolerance is then integrated again from its start with a smaller step.
    fn verified_run(
        &self,
        options: &Options,
        pilot: Pilot,
        mut stats: Stats,
        observer: &mut Observer<'_>,
        cache: &Arc<SolveCache<S>>,
    ) -> std::result::Result<Solution<S>, SolveError> {
        let r = pilot.r;
        let p = (2 * r) as f64;
        let span = self.t_end - self.t0;
        let system = &*self.system;
        let quantum = quantum(options.t_eval.as_deref(), self.t0, self.t_end);
        let collect = Collect {
            every_step: options.t_eval.is_none(),
            steps: observer.is_some(),
            grid: options.dense,
            events: true,
            t_eval: true,
        };
        let mut h_want = pilot.h;
        // The order the differences show: the pilot's, then the last run's.
        let mut order_hint = pilot.order;
        // The highest order the differences showed at a step no larger than the current one:
        // where the runs are in their asymptotic regime. A lower order seen at a larger step
        // is the checking runs leaving that regime; the step-size law follows the asymptotic
        // one.
        let mut asymptotic = (pilot.order, pilot.h_order);
        // What every attempt so far saw (a later attempt projects its end from them too).
        let mut seen: Vec<Profile> = Vec::new();
        let mut restarts = 0;
        let mut ups = 0;
        // An attempt went on to the end of the span to measure the rounding (at most once),
        // and what it measured there: (the round-off, its steps).
        let mut scouted = false;
        let mut measured_floor: Option<(f64, usize)> = None;
        // Where the last step failure was, and how often in a row a step failed there.
        let (mut failed_at, mut stuck): (Option<f64>, usize) = (None, 0);
        // The smallest step that was over the tolerance (or projected to be): a larger step is
        // never tried again.
        let mut h_fail = f64::INFINITY;
        loop {
            let grid = fit_grid(h_want, self.t0, self.t_end, quantum, options.max_steps)?;
            let meets = grid.n_end / 2 + 1;
            let outputs = options.t_eval.as_ref().map_or(meets, Vec::len);
            let dense = if options.dense { meets } else { 0 };
            let held = if observer.is_some() {
                (grid.n_end as f64 * LAST_CHUNK_SHARE.max(SHOW_SHARE)) as usize + 1
            } else {
                0
            };
            ensure_output_fits(self.y0.len(), outputs, dense, held)?;
            options.say(|| {
                format!(
                    "solve: EC{r}P from t0 with h = {:.4e} ({} steps)",
                    grid.h, grid.n_end
                )
            });
            let mut runs = Runs::new(
                system,
                options,
                r,
                true,
                &self.y0,
                grid,
                self.same_time(),
                order_hint,
                cache,
            )?;
            let mut kept = Kept::new(self.t0, grid.h);
            let mut first = Chunk::default();
            runs.start(collect, &mut first)?;
            kept.keep(first, Some(1.0), grid.h)?;
            // Shown to the observer: the run cannot start again from t₀.
            let mut shown = false;
            // (time since t₀, the controlled statistic so far) after each kept chunk.
            let mut history: Vec<(f64, f64)> = Vec::new();
            // The round-off model (with the measured sensitivity) after each chunk.
            let mut noise_history: Vec<(f64, f64)> = Vec::new();
            // This attempt runs to the end of the span whatever its estimate, to measure the
            // rounding there.
            let mut scouting = false;
            // The largest output estimate of the chunks a scouting attempt kept regardless.
            let mut scout_worst = 0.0_f64;
            let mut controlled = 0.0_f64;
            let mut chunk_share = FIRST_CHUNK_SHARE;
            let mut retries = 0;
            let mut restart_with: Option<f64> = None;
            // The estimate of a chunk that was not kept (the profile of the attempt ends there).
            let mut failed_point: Option<(f64, f64)> = None;
            while runs.n < runs.grid.n_end && !kept.ended() {
                let ck: Checkpoint = runs.checkpoint();
                let block = MEET as f64 * runs.grid.h;
                let blocks = ((chunk_share * span / block).ceil() as usize).max(1);
                let unit = quantum.map_or(1, |q| (q / block).round().max(1.0) as usize);
                let n_stop = runs.n + MEET * blocks.div_ceil(unit) * unit;
                let h = runs.grid.h;
                // The chunk's verdict: kept, or again with a smaller step (and why).
                let again: (f64, String) = match runs.advance(n_stop, collect) {
                    Err((f, _)) if f.fatal => return Err(f.error.into()),
                    Err((f, cost)) => {
                        discard(&mut stats, &cost);
                        // A step that fails at the same place whatever the step size (a
                        // singularity, g not finite there): smaller steps will not help.
                        let here = 6.0 * h;
                        stuck = match failed_at {
                            Some(t) if (f.t - t).abs() <= here => stuck + 1,
                            _ => 1,
                        };
                        failed_at = Some(f.t);
                        // A step that failed is never tried again (no step up to it).
                        h_fail = h_fail.min(h);
                        let which = match f.which {
                            Which::Fine => "returned",
                            Which::Coarse => "2h checking",
                            Which::Third => "3h checking",
                        };
                        let why = format!(
                            "a step of the {which} run failed at t = {:?} (h = {:.3e}): {}",
                            f.t, f.h, f.error
                        );
                        if stuck >= STUCK_LIMIT {
                            runs.restore(&ck)?;
                            let why = format!(
                                "{why}; the step failed there {stuck} times, each time with a \
                                 smaller step"
                            );
                            return Err(
                                self.best_effort(options, runs, kept, stats, r, why, observer)
                            );
                        }
                        // The estimate in hand: where it projects over the tolerance, the
                        // step-size law sets the next step (a step failure of a checking run
                        // comes with an answer that is often far from verified anyway).
                        let q = asymptotic.0.clamp(0.5 * p, p);
                        let projected = if history.is_empty() {
                            0.0
                        } else {
                            project(&history, span)
                        };
                        let law = if projected > 0.7 * TARGET && projected.is_finite() {
                            rescale(h, 0.7 * TARGET / projected, q)
                        } else {
                            h
                        };
                        let h_new = if f.which == Which::Fine {
                            (h / 2.0).min(law)
                        } else {
                            (h / 1.5).min(law)
                        };
                        (h_new.max(h / 8.0), why)
                    }
                    Ok(chunk) => {
                        let order = runs.maxima.order(p);
                        let div = divisor(order);
                        // The step-size law: the observed order, but not below r (far from
                        // the asymptotic regime a smaller order would shrink the step far
                        // too much), nor below the order the runs showed where they were
                        // asymptotic (a low order at this step is the checking runs leaving
                        // that regime: the answer's error is far below the estimate).
                        let q = order.unwrap_or(p).max(asymptotic.0).clamp(0.5 * p, p);
                        // As the kept solution will report it: with the interpolation's own
                        // estimate at outputs between grid points.
                        let est = |pt: &Point| estimate(pt.diff, pt.noise, div) + pt.interp;
                        let worst_out = chunk
                            .outputs
                            .iter()
                            .map(est)
                            .chain(chunk.hits.iter().map(|(_, pt)| est(pt)))
                            .fold(0.0, |m: f64, e| {
                                if e.is_nan() || m.is_nan() {
                                    f64::NAN
                                } else {
                                    m.max(e)
                                }
                            });
                        let mut meets: Vec<f64> = chunk
                            .meets
                            .iter()
                            .map(|m| estimate(m.diff, m.noise, div))
                            .collect();
                        let noise = chunk
                            .meets
                            .iter()
                            .map(|m| m.noise)
                            .chain(chunk.outputs.iter().map(|pt| pt.noise))
                            .fold(0.0, f64::max);
                        let t = runs.t();
                        let at_end = runs.n >= runs.grid.n_end || chunk.terminal.is_some();
                        // What the outputs still to come will see: with K of them, the
                        // estimate at the meeting points that K draws exceed with even odds
                        // (the largest for output at every step).
                        let to_come = match options.t_eval.as_deref() {
                            Some(ts) => ts.len() - ts.partition_point(|&te| te <= t),
                            None => (runs.grid.n_end - runs.n) / 2,
                        };
                        let level = 1.0 - 1.0 / (2.0 * to_come as f64 + 1.0);
                        let stat = quantile(&mut meets, level);
                        let now = controlled.max(stat);
                        history.push((t - self.t0, now));
                        if let Some(q) = order.filter(|q| *q >= 0.5 * p) {
                            if h <= asymptotic.1 || q > asymptotic.0 {
                                asymptotic = (asymptotic.0.max(q), asymptotic.1.max(h));
                            }
                        }
                        // What earlier attempts saw beyond this point, scaled to this step.
                        let elapsed = t - self.t0;
                        let from_seen = seen
                            .iter()
                            .filter(|pr| pr.points.last().is_some_and(|l| l.0 > elapsed))
                            .map(|pr| {
                                // The order that attempt showed where it was asymptotic (at
                                // least r, the least the pilot accepts); the nominal 2r where
                                // it showed none or less: runs outside their asymptotic regime
                                // say only that their step was too large, not by how much.
                                let q = pr.order.filter(|&q| q >= 0.5 * p).unwrap_or(p);
                                let scaled = Profile {
                                    order: Some(q),
                                    ..pr.clone()
                                };
                                scaled.predict(h, p, span)
                            })
                            .fold(0.0, f64::max);
                        // This attempt's own projection, and with what earlier ones saw.
                        let own = if at_end {
                            worst_out
                        } else {
                            project(&history, span).max(worst_out)
                        };
                        let projected = if at_end { own } else { own.max(from_seen) };
                        options.say(|| format!(
                                "solve:   t = {t:.4}: outputs {worst_out:.3e}, meets (q {level:.3}) {stat:.3e}, noise {noise:.3e}, order {order:?}, projected {projected:.3e}"
                            ));
                        let over = !at_most(worst_out, 1.0);
                        noise_history.push((t - self.t0, noise));
                        // Over (or projected over) by round-off alone: no step helps. The
                        // rounding grows like a random walk, or faster where the flow amplifies
                        // it (measured by the sensitivity run).
                        // What the rounding will be at the end: measured there by an earlier
                        // attempt (it grows with the square root of the steps), or projected
                        // like a random walk from here; the projection at the rate it grew
                        // over the last stretch decides whether to measure it.
                        let walk = project_noise(&history, noise, span);
                        let floor = if at_end {
                            noise
                        } else if let Some((m, steps)) = measured_floor {
                            let ratio = (runs.grid.n_end as f64 / steps as f64).max(1.0);
                            walk.max(m * ratio.sqrt())
                        } else {
                            walk
                        };
                        let steep = project_steep(&noise_history, span);
                        // Over (or projected over) while the differences between the runs are
                        // at the level of the rounding: no step size helps. Where only the
                        // projection of the rounding says so, the attempt goes on to the end
                        // of the span to measure it (once): a smaller step would not change it.
                        // Differences at the rounding's level (no order) are the floor only
                        // if this attempt's own growth projects them over the tolerance: an
                        // earlier attempt's larger step says nothing about this one's rounding.
                        let at_floor = floor >= 0.5 * projected.max(worst_out)
                            || (order.is_none() && runs.maxima.fine > 0.0 && own > 1.0);
                        if (over || projected > 1.0)
                            && (at_floor || steep > 1.0)
                            && !at_end
                            && !shown
                            && !scouted
                            && observer.is_none()
                        {
                            options.say(|| format!(
                                "solve:   the rounding is projected to reach {:.3e} times the tolerance: on to the end of the span with h = {h:.4e} to measure it", floor.max(steep)
                            ));
                            scouted = true;
                            scouting = true;
                        }
                        if scouting && !at_end {
                            scout_worst = scout_worst.max(worst_out);
                            kept.keep(chunk, Some(div), h)?;
                            controlled = now;
                            chunk_share = (2.0 * chunk_share).min(LAST_CHUNK_SHARE);
                            continue;
                        }
                        if scouting && at_end {
                            measured_floor = Some((noise, runs.grid.n_end));
                        }
                        // A scouting attempt kept its chunks whatever their estimates: it is
                        // over if any of them was (NaN included).
                        let (worst_out, over) = if scouting && at_end {
                            let w = if scout_worst.is_nan() {
                                scout_worst
                            } else {
                                worst_out.max(scout_worst)
                            };
                            (w, !at_most(w, 1.0))
                        } else {
                            (worst_out, over)
                        };
                        // Nor is it at the floor where its chunks were over by more than the
                        // rounding.
                        let at_floor = at_floor && floor >= 0.5 * worst_out;
                        // At the end of the span the rounding is measured, not projected: over
                        // the tolerance by itself, no step verifies the answer.
                        if (over || projected > 1.0) && (at_floor || (at_end && noise > 1.0)) {
                            discard(&mut stats, &chunk.cost);
                            let steps = runs.total;
                            runs.restore(&ck)?;
                            let why = format!(
                                "the tolerance is at the round-off floor of this problem: by t = \
                                 {t:?} the rounding of {steps} steps (and of time itself), \
                                 amplified by the flow, is {noise:.2e} times the tolerance \
                                 ({:.2e} projected to the end of the span{}), and the \
                                 differences between the runs are no larger: no step size \
                                 verifies the answer at this tolerance",
                                floor.max(own.min(steep)),
                                if own.min(steep) > floor {
                                    " at the rate it grows"
                                } else {
                                    ""
                                }
                            );
                            return Err(
                                self.best_effort(options, runs, kept, stats, r, why, observer)
                            );
                        }
                        if over || (projected > 1.0 && !shown) {
                            failed_point = history.pop();
                            discard(&mut stats, &chunk.cost);
                            h_fail = h_fail.min(h);
                            let worst = if over { worst_out.max(stat) } else { projected };
                            // Rounding amplified by the flow: an attempt with a clearly larger
                            // step had as small an estimate here, so the step does not make
                            // it shrink.
                            // Only runs that resolved the start (their first stretch well
                            // within the tolerance) count: far from the asymptotic regime the
                            // estimate need not shrink either.
                            let elapsed = t - self.t0;
                            let now_here = worst_out.max(stat).max(now);
                            let resolved =
                                |pts: &[(f64, f64)]| pts.first().is_some_and(|f| f.1 <= 0.1);
                            let stalled = seen
                                .iter()
                                .filter(|pr| {
                                    pr.h >= 1.4 * h && resolved(&pr.points) && resolved(&history)
                                })
                                .find_map(|pr| {
                                    pr.at(elapsed)
                                        // Over the tolerance with both steps: a larger
                                        // step that met it here says the step can.
                                        .filter(|&e| {
                                            now_here > 1.0 && e > 1.0 && now_here >= 0.5 * e
                                        })
                                        .map(|e| (pr.h, e))
                                });
                            if let Some((h_prev, e_prev)) = stalled {
                                discard(&mut stats, &chunk.cost);
                                runs.restore(&ck)?;
                                let why = format!(
                                    "the estimate does not shrink with the step: {now_here:.3e} \
                                     times the tolerance by t = {t:?} with h = {h:.3e}, \
                                     {e_prev:.3e} with h = {h_prev:.3e}: the differences between \
                                     the runs are rounding amplified by the flow (chaos, an \
                                     orbit near a separatrix), which no step size removes at \
                                     this tolerance"
                                );
                                return Err(
                                    self.best_effort(options, runs, kept, stats, r, why, observer)
                                );
                            }
                            let law = if worst.is_finite() {
                                rescale(h, 0.7 * TARGET / worst, q)
                            } else {
                                h / 4.0
                            };
                            let h_new = law.max(h / 8.0).min(h / 1.1);
                            let seen = order.map_or("none: differences at round-off".into(), |q| {
                                format!("{q:.2}")
                            });
                            let why = if over {
                                format!(
                                    "the estimate reached {worst_out:.3e} times the tolerance \
                                     by t = {t:?} with h = {h:.3e} (observed order {seen})"
                                )
                            } else {
                                format!(
                                    "the estimate was projected to reach {projected:.3e} times \
                                     the tolerance with h = {h:.3e} (observed order {seen})"
                                )
                            };
                            (h_new, why)
                        } else {
                            kept.keep(chunk, Some(div), h)?;
                            controlled = now;
                            chunk_share = (2.0 * chunk_share).min(LAST_CHUNK_SHARE);
                            if observer.is_some() && t - self.t0 >= SHOW_SHARE * span {
                                shown = true;
                                kept.show(observer);
                            }
                            if kept.ended() || at_end {
                                break;
                            }
                            // At most twice the step, and below the smallest that was too
                            // large (halfway there, on a log scale).
                            let up = (2.0 * h).min((h * h_fail).sqrt());
                            if projected < TARGET / 20.0
                                && order.is_some()
                                && !shown
                                && ups < MAX_UPS
                                && t - self.t0 <= UP_SHARE * span
                                && up > 1.1 * h
                            {
                                // Far more accurate than asked: again with a larger step, below
                                // the smallest that was too large.
                                ups += 1;
                                let grow = TARGET / projected.max(f64::MIN_POSITIVE);
                                let up = rescale(h, grow, q).min(up);
                                options.say(|| {
                                    format!(
                                        "solve:   again with h = {up:.4e}: far below the tolerance"
                                    )
                                });
                                restart_with = Some(up);
                                break;
                            }
                            if shown && projected > 1.0 && kept.segments.len() < MAX_SEGMENTS {
                                // Shown already: the rest with a smaller step.
                                let room = (TARGET - controlled).max(0.1 * TARGET);
                                let growth = (projected - controlled).max(f64::MIN_POSITIVE);
                                let h_next = rescale(h, room / growth, q).max(h / 16.0);
                                let g =
                                    fit_grid(h_next, t, self.t_end, quantum, options.max_steps)?;
                                runs.set_grid(g)?;
                                kept.segments.push(Segment { t, h: g.h });
                            }
                            continue;
                        }
                    }
                };
                // Over the tolerance (or a failed step).
                let (h_new, why) = again;
                stats.retries += 1;
                options.say(|| format!("solve:   again with h = {h_new:.4e}: {why}"));
                if !shown {
                    restarts += 1;
                    if restarts > MAX_RESTARTS {
                        runs.restore(&ck)?;
                        let why = format!(
                            "no step size verified the answer in {restarts} runs; the last: {why}"
                        );
                        return Err(self.best_effort(options, runs, kept, stats, r, why, observer));
                    }
                    restart_with = Some(h_new);
                    break;
                }
                retries += 1;
                runs.restore(&ck)?;
                let t = runs.t();
                if retries > MAX_RETRIES {
                    let why = format!(
                        "no step size verified the answer from t = {t:?} on in {retries} tries; \
                         the last: {why}"
                    );
                    return Err(self.best_effort(options, runs, kept, stats, r, why, observer));
                }
                match fit_grid(h_new, t, self.t_end, quantum, options.max_steps) {
                    Ok(g) => {
                        runs.set_grid(g)?;
                        if kept.segments.last().is_some_and(|s| s.t == t) {
                            kept.segments.pop();
                        }
                        kept.segments.push(Segment { t, h: g.h });
                    }
                    Err(e) => {
                        let why = format!("{e} (after: {why})");
                        return Err(self.best_effort(options, runs, kept, stats, r, why, observer));
                    }
                }
            }
            if let Some(h_new) = restart_with {
                discard(&mut stats, &kept.cost);
                let mut points = history.clone();
                points.extend(failed_point);
                if !points.is_empty() {
                    seen.push(Profile {
                        h: runs.grid.h,
                        order: runs.maxima.order(p),
                        points,
                    });
                }
                h_want = h_new;
                if let Some(q) = runs.maxima.order(p) {
                    order_hint = q;
                }
                continue;
            }
            // Verified.
            kept.show(observer);
            let order = runs.maxima.order(p);
            let div = divisor(order);
            let h = runs.grid.h;
            finish(&mut stats, &kept.cost);
            return Ok(self.assemble(options, kept, stats, r, Some(div), order, h));
        }
    }

    /// The error of an answer that could not be verified, with the best solution: what was
    /// kept, and the rest of the span integrated with the last step tried, every estimate
    /// recorded, up to where a step fails.
    #[allow(clippy::too_many_arguments)]
    fn best_effort(
        &self,
        options: &Options,
        mut runs: Runs<'_, '_, S>,
        mut kept: Kept,
        mut stats: Stats,
        r: usize,
        reason: String,
        observer: &mut Observer<'_>,
    ) -> SolveError {
        let p = (2 * r) as f64;
        let collect = Collect {
            every_step: options.t_eval.is_none(),
            steps: observer.is_some(),
            grid: options.dense,
            events: true,
            t_eval: true,
        };
        while !kept.ended() && runs.n < runs.grid.n_end {
            let n_stop = runs.grid.n_end;
            match runs.advance(n_stop, collect) {
                Ok(chunk) => {
                    let div = divisor(runs.maxima.order(p));
                    let h = runs.grid.h;
                    if kept.keep(chunk, Some(div), h).is_err() {
                        kept.status = Some(Status::Failed { t: runs.t() });
                    }
                }
                Err((f, _)) if f.fatal => return SolveError::Failed(f.error),
                Err((f, cost)) => {
                    discard(&mut stats, &cost);
                    kept.status = Some(Status::Failed { t: f.t });
                }
            }
        }
        kept.show(observer);
        let order = runs.maxima.order(p);
        let div = divisor(order);
        let h = runs.grid.h;
        finish(&mut stats, &kept.cost);
        let solution = self.assemble(options, kept, stats, r, Some(div), order, h);
        SolveError::Unverified {
            reason,
            solution: Box::new(solution.into_data()),
        }
    }
}
