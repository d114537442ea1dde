//! How a solve proceeds: the pilot that picks r and the first h, the chunks of the run, the
//! decision after each chunk (keep it, or integrate it again with a smaller step), and the
//! solution put together from what was kept.

use std::ops::ControlFlow;

use super::options::{Method, Options};
use super::run::{Checkpoint, Chunk, Collect, Cost, Grid, MEET, Point, Runs, StepFailure, Which};
use super::solution::{DenseData, Segment, SolveError, Solution, Stats, Status, StepView};
use super::Problem;
use crate::integrate::StepPlan;
use crate::storage::format_bytes;
use crate::system::System;
use crate::error::{Error, Result};

/// The estimate a verified run aims at, in units of the tolerance.
pub(super) const TARGET: f64 = 0.5;

/// Blocks of [`MEET`] steps in a pilot's window.
const PILOT_BLOCKS: usize = 2;

/// The pilots of further orders stop once they have cost this share of the predicted run.
const PILOT_BUDGET: f64 = 0.1;

/// The first chunk is this share of the span; each next one twice the one before, up to
/// [`LAST_CHUNK_SHARE`].
const FIRST_CHUNK_SHARE: f64 = 1.0 / 64.0;
const LAST_CHUNK_SHARE: f64 = 1.0 / 8.0;

/// Runs started again from t₀ before the solve gives up.
const MAX_RESTARTS: usize = 8;

/// With an observer: chunks integrated again (from their start) before the solve gives up.
const MAX_RETRIES: usize = 10;

/// A run far more accurate than asked starts again with a larger step only this early (an
/// error that grows late is not seen before), once, and at most twice as large.
const UP_SHARE: f64 = 1.0 / 16.0;

/// With an observer, the run is shown to it from this share of the span on.
const SHOW_SHARE: f64 = 1.0 / 8.0;

/// Step-size changes of the run before it keeps the step it has.
const MAX_SEGMENTS: usize = 8;

/// Steps of a fixed-step run kept at once (without an observer).
const FIXED_CHUNK_STEPS: usize = 1024;

/// The step-size law of a verified run: error ∝ h^q.
fn rescale(h: f64, ratio: f64, q: f64) -> f64 {
    h * ratio.powf(1.0 / q.max(1.0))
}

/// The Richardson divisor 2^q − 1 for an observed order q, at least 1: where no order shows
/// (the differences are at round-off level, or do not shrink with the step) the difference
/// itself is the estimate.
fn divisor(order: Option<f64>) -> f64 {
    order.map_or(1.0, |q| (2f64.powf(q) - 1.0).max(1.0))
}

/// The estimate of a point in tolerance units: the Richardson estimate, not below the
/// round-off model.
fn estimate(diff: f64, noise: f64, div: f64) -> f64 {
    let e = diff / div;
    if e.is_nan() { e } else { e.max(noise) }
}

/// What the pilot of one order found.
#[derive(Clone, Copy, Debug)]
struct Pilot {
    r: usize,
    /// The step size predicted to give [`TARGET`] at the end of the span.
    h: f64,
    /// Predicted evaluations of g of the run.
    cost: f64,
}

/// What has been kept of the current run: outputs and hits with their estimates, grid
/// states, the observer's steps not yet shown, and what the kept chunks cost.
#[derive(Default)]
struct Kept {
    outputs: Vec<(Point, f64)>,
    hits: Vec<(usize, Point, f64)>,
    grid: Vec<(f64, Vec<f64>, Vec<f64>)>,
    /// The answer's steps not yet shown to the observer: (t, step, h, state).
    unshown: Vec<(f64, usize, f64, Vec<f64>)>,
    cost: Cost,
    segments: Vec<Segment>,
    status: Option<Status>,
}

impl Kept {
    fn new(t0: f64, h: f64) -> Self {
        Kept {
            segments: vec![Segment { t: t0, h }],
            ..Kept::default()
        }
    }

    /// Keeps a chunk with its estimates (`div`: the Richardson divisor; `None` for a fixed
    /// method, estimates 0). `Err` if its storage cannot be allocated.
    fn keep(&mut self, chunk: Chunk, div: Option<f64>, h: f64) -> Result<()> {
        let est = |p: &Point| div.map_or(0.0, |div| estimate(p.diff, p.noise, div));
        let d = chunk.outputs.first().map_or(0, |p| p.y.len());
        reserve(&mut self.outputs, chunk.outputs.len(), d)?;
        reserve(&mut self.grid, chunk.grid.len(), 2 * d)?;
        add_cost(&mut self.cost, &chunk.cost);
        for p in chunk.outputs {
            let e = est(&p);
            self.outputs.push((p, e));
        }
        for (k, p) in chunk.hits {
            let e = est(&p);
            self.hits.push((k, p, e));
        }
        self.grid.extend(chunk.grid);
        self.unshown
            .extend(chunk.steps.into_iter().map(|(t, n, y)| (t, n, h, y)));
        if let Some(term) = chunk.terminal {
            self.status = Some(Status::Terminated {
                event: term.event,
                t: term.t,
            });
        }
        Ok(())
    }

    /// Shows the kept steps to the observer; a `Break` stops the run there.
    fn show(&mut self, observer: &mut Observer<'_>) {
        let Some(obs) = observer.as_mut() else {
            return;
        };
        let mut stop = None;
        for (t, step, h, y) in self.unshown.drain(..) {
            let view = StepView { t, y: &y, step, h };
            if obs(&view).is_break() {
                stop = Some(t);
                break;
            }
        }
        self.unshown.clear();
        if let Some(t) = stop {
            self.outputs.retain(|(p, _)| p.t <= t);
            self.hits.retain(|(_, p, _)| p.t <= t);
            self.grid.retain(|g| g.0 <= t);
            self.status = Some(Status::Stopped { t });
        }
    }

    fn ended(&self) -> bool {
        self.status.is_some()
    }
}

fn add_cost(to: &mut Cost, c: &Cost) {
    to.steps += c.steps;
    to.g_evals += c.g_evals;
    to.sweeps += c.sweeps;
    to.check_steps += c.check_steps;
    to.check_g_evals += c.check_g_evals;
    to.dense_steps += c.dense_steps;
    to.dense_g_evals += c.dense_g_evals;
}

/// Work that was done and thrown away (a chunk over the tolerance, a run started again).
fn discard(stats: &mut Stats, c: &Cost) {
    stats.discarded_steps += c.total_steps();
    stats.discarded_g_evals += c.total_g_evals();
}

/// The kept run's cost into the statistics.
fn finish(stats: &mut Stats, c: &Cost) {
    stats.steps += c.steps;
    stats.g_evals += c.g_evals;
    stats.sweeps += c.sweeps;
    stats.check_steps += c.check_steps;
    stats.check_g_evals += c.check_g_evals;
    stats.dense_evals += c.dense_steps;
    stats.dense_g_evals += c.dense_g_evals;
}

/// `Err` naming the size if `n` more entries of `d` numbers each cannot be stored.
fn reserve<T>(v: &mut Vec<T>, n: usize, d: usize) -> Result<()> {
    if n == 0 {
        return Ok(());
    }
    let entries = v.len().saturating_add(n).saturating_mul(d.max(1));
    crate::storage::ensure_allocatable("the solution's output", Some(entries))?;
    v.try_reserve(n).map_err(|_| {
        Error::InvalidInput(format!(
            "the solution's output ({} states of {d} numbers, {}) cannot be allocated",
            v.len() + n,
            format_bytes((entries * 8) as f64)
        ))
    })
}

type Observer<'f> = Option<&'f mut dyn FnMut(&StepView<'_>) -> ControlFlow<()>>;

/// The step grid of a stretch from `a` to `end` with a step close to `h` (not larger), so
/// that the stretch is a whole number of blocks of [`MEET`] steps (where all three runs
/// meet) and, with evenly spaced output times (spacing `quantum`), every output time is the
/// end of a block.
fn fit_grid(h: f64, a: f64, end: f64, quantum: Option<f64>, max_steps: usize) -> Result<Grid> {
    let span = end - a;
    let block = MEET as f64;
    let (h, n_end) = match quantum {
        Some(q) if ((span / q) - (span / q).round()).abs() < 1e-9 && q > 0.0 => {
            let m = (q / (block * h)).ceil().max(1.0);
            (q / (block * m), block * m * (span / q).round())
        }
        _ => {
            let m = (span / (block * h)).ceil().max(1.0);
            (span / (block * m), block * m)
        }
    };
    if !(n_end <= max_steps as f64) || !h.is_finite() || h <= 0.0 {
        return Err(Error::InvalidInput(format!(
            "the run needs {n_end:.0} steps of h = {h:.3e} over [{a:?}, {end:?}], more than \
             max_steps = {max_steps}"
        )));
    }
    Ok(Grid {
        a,
        h,
        n_end: n_end as usize,
        end,
    })
}

/// The spacing of evenly spaced output times that start and end on multiples of it from
/// t₀ (so that a grid can pass through all of them), if they are.
fn quantum(t_eval: Option<&[f64]>, t0: f64, t_end: f64) -> Option<f64> {
    let ts = t_eval.filter(|ts| ts.len() >= 2)?;
    let m = ts.len() - 1;
    let delta = (ts[m] - ts[0]) / m as f64;
    if !(delta > 0.0) {
        return None;
    }
    let even = ts
        .iter()
        .enumerate()
        .all(|(i, &t)| (t - (ts[0] + i as f64 * delta)).abs() <= 1e-12 * delta.max(t.abs()));
    let on = |x: f64| (x / delta - (x / delta).round()).abs() < 1e-9;
    (even && on(ts[0] - t0) && on(t_end - t0)).then_some(delta)
}

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
        match options.method {
            Method::Fixed { r, h } => Ok(self.fixed(options, r, h, &mut observer)?),
            _ => self.verified(options, &mut observer),
        }
    }

    fn same_time(&self) -> f64 {
        16.0 * f64::EPSILON * self.t0.abs().max(self.t_end.abs()).max(self.t_end - self.t0)
    }

    /// ECrP with a fixed step (no verification), the observer called after every step.
    fn fixed(
        &self,
        options: &Options,
        r: usize,
        h: f64,
        observer: &mut Observer<'_>,
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
        let grid = Grid {
            a: self.t0,
            h,
            n_end: steps,
            end: self.t_end,
        };
        let system = &*self.system;
        let mut runs = Runs::new(system, options, r, false, &self.y0, grid, self.same_time())?;
        let collect = Collect {
            every_step: options.t_eval.is_none(),
            steps: observer.is_some(),
            grid: options.dense,
            events: true,
        };
        let mut kept = Kept::new(self.t0, h);
        let mut first = Chunk::default();
        runs.start(collect, &mut first)?;
        kept.keep(first, None, h)?;
        // With an observer, every step is shown as soon as it is made.
        let chunk_steps = if observer.is_some() { 1 } else { FIXED_CHUNK_STEPS };
        while runs.n < steps && !kept.ended() {
            let stop = (runs.n + chunk_steps).min(steps);
            let chunk = runs.advance(stop, collect).map_err(|(f, _)| Error::AtStep {
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
        let mut runs = Runs::new(system, options, r0, true, &self.y0, start, same)?;
        let floor = runs.noise_at_start();
        if !(floor <= 0.25) {
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
            };
            let mut kept = Kept::new(self.t0, 0.0);
            let mut chunk = Chunk::default();
            runs.start(collect, &mut chunk)?;
            kept.keep(chunk, Some(1.0), 0.0)?;
            return Ok(self.assemble(options, kept, stats, r0, Some(1.0), None, 0.0));
        }
        let pilot = match options.method {
            Method::Order(r) => self.pilot(options, r, None, &mut stats)?,
            _ => self.pilot_auto(options, &mut stats)?,
        };
        self.verified_run(options, pilot, stats, observer)
    }

    /// The first order tried for a tolerance: about one more r per two decades, r = 4 at
    /// 1e−6, r = 6 at 1e−10, within the allowed orders.
    fn first_order(&self, options: &Options) -> usize {
        let tol = options.rtol.max(options.atol).max(1e-16);
        let guess = (1.0 - tol.log10() / 2.0).round() as usize;
        guess.clamp(*options.orders.start(), *options.orders.end())
    }

    /// Pilots from the first order up, and down, while the predicted cost falls.
    fn pilot_auto(&self, options: &Options, stats: &mut Stats) -> Result<Pilot> {
        let first = self.first_order(options);
        let mut best = self.pilot(options, first, None, stats)?;
        let (lo, hi) = (*options.orders.start(), *options.orders.end());
        for up in [true, false] {
            let mut r = first;
            let mut h_from = best.h;
            loop {
                let next = if up { r + 1 } else { r.wrapping_sub(1) };
                // Exploring stops where it would cost more than a tenth of the run.
                let spent = stats.pilot_g_evals as f64;
                if next < lo || next > hi || spent > PILOT_BUDGET * best.cost {
                    break;
                }
                let Ok(p) = self.pilot(options, next, Some(h_from), stats) else {
                    break;
                };
                h_from = p.h;
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

    /// The pilot of one order: the three runs over a window of [`PILOT_BLOCKS`] blocks of
    /// [`MEET`] steps from t₀ (up to a terminal event). Starting from `h_start` (or 1/64 of the
    /// span), the step grows while the runs agree to round-off, then halves until they show
    /// an order of at least r (half the nominal 2r); the estimate is projected to the end of
    /// the span by its growth over the window, and h scaled to [`TARGET`] (at most twice the
    /// step at which the law was seen).
    fn pilot(
        &self,
        options: &Options,
        r: usize,
        h_start: Option<f64>,
        stats: &mut Stats,
    ) -> Result<Pilot> {
        let span = self.t_end - self.t0;
        let p = (2 * r) as f64;
        let system = &*self.system;
        let trace = std::env::var_os("ECR_SOLVE_TRACE").is_some();
        let blocks = (PILOT_BLOCKS * MEET) as f64;
        let mut h = h_start.unwrap_or(span / 64.0).min(span / blocks);
        let collect = Collect {
            every_step: false,
            steps: false,
            grid: false,
            events: false,
        };
        let (mut grown, mut refined) = (0, false);
        let mut last_failure: Option<StepFailure> = None;
        for _ in 0..60 {
            let window = (blocks * h).min(span);
            let grid = fit_grid(h, self.t0, self.t0 + window, None, usize::MAX)?;
            if h < span * 1e-12 {
                break;
            }
            let mut runs = Runs::new(system, options, r, true, &self.y0, grid, self.same_time())?;
            let chunk = match runs.advance(grid.n_end, collect) {
                Ok(c) => c,
                Err((f, cost)) => {
                    stats.pilot_steps += cost.total_steps();
                    stats.pilot_g_evals += cost.total_g_evals();
                    last_failure = Some(f);
                    refined = true;
                    h /= 4.0;
                    continue;
                }
            };
            stats.pilot_steps += chunk.cost.total_steps();
            stats.pilot_g_evals += chunk.cost.total_g_evals();
            let end = chunk.terminal.map_or(self.t0 + window, |t| t.t);
            let span_eff = chunk.terminal.map_or(span, |t| t.t - self.t0);
            let order = runs.maxima.order(p);
            let div = divisor(order);
            let est_until = |t_max: f64| {
                chunk
                    .meets
                    .iter()
                    .filter(|m| m.t <= t_max)
                    .map(|m| estimate(m.diff, m.noise, div))
                    .fold(0.0, f64::max)
            };
            let e_w = est_until(end);
            let e_half = est_until(self.t0 + 0.5 * (end - self.t0));
            let noise = chunk.meets.iter().map(|m| m.noise).fold(0.0, f64::max);
            let g_per_step = chunk.cost.g_evals as f64 / chunk.cost.steps.max(1) as f64;
            let at_noise = e_w <= 2.0 * noise || order.is_none();
            if trace {
                eprintln!(
                    "solve: pilot EC{r}P h = {:.4e}: window estimate {e_w:.3e} (half {e_half:.3e}), noise {noise:.3e}, order {order:?}",
                    grid.h
                );
            }
            if at_noise {
                if !refined && grown < 4 && window < span / 4.0 {
                    // The runs agree to round-off: the step can be larger.
                    h *= 4.0;
                    grown += 1;
                    continue;
                }
                let h_run = (4.0 * grid.h).min(span_eff / 4.0);
                return Ok(Pilot {
                    r,
                    h: h_run,
                    cost: g_per_step * span_eff / h_run,
                });
            }
            let q = order.unwrap_or(p);
            if q < 0.5 * p {
                // Not yet in the asymptotic regime.
                refined = true;
                h /= 2.0;
                continue;
            }
            // Growth over the window, as a power of time: from a plateau (a damped problem)
            // to linear (the phase error of a conservative one); the run checks the rest.
            let alpha = if e_half > 0.0 {
                (e_w / e_half).log2().clamp(0.25, 1.0)
            } else {
                1.0
            };
            let predicted = e_w * (span_eff / (end - self.t0)).powf(alpha);
            // The law is trusted up to twice the step at which it was seen.
            let h_run = rescale(grid.h, TARGET / predicted, q)
                .min(2.0 * grid.h)
                .min(span_eff / 4.0);
            if trace {
                eprintln!("solve: pilot EC{r}P: alpha {alpha:.2}, predicted {predicted:.3e}, h_run {h_run:.4e}, g/step {g_per_step:.2}");
            }
            return Ok(Pilot {
                r,
                h: h_run,
                cost: g_per_step * span_eff / h_run,
            });
        }
        Err(match last_failure {
            Some(f) => Error::Numerical(format!(
                "the pilot of EC{r}P found no step size at which its steps succeed (last: h = \
                 {:.3e} at t = {:?}: {})",
                f.h, f.t, f.error
            )),
            None => Error::Numerical(format!(
                "the pilot of EC{r}P found no step size at which the error behaves as an order \
                 of at least {r} (last tried h = {h:.3e})"
            )),
        })
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
        };
        let trace = std::env::var_os("ECR_SOLVE_TRACE").is_some();
        let mut h_want = pilot.h;
        let mut restarts = 0;
        let mut ups = 0;
        // The smallest step that was over the tolerance (or projected to be): a larger step is
        // never tried again.
        let mut h_fail = f64::INFINITY;
        loop {
            let grid = fit_grid(h_want, self.t0, self.t_end, quantum, options.max_steps)?;
            if trace {
                eprintln!("solve: EC{r}P from t0 with h = {:.4e} ({} steps)", grid.h, grid.n_end);
            }
            let mut runs = Runs::new(system, options, r, true, &self.y0, grid, self.same_time())?;
            let mut kept = Kept::new(self.t0, grid.h);
            let mut first = Chunk::default();
            runs.start(collect, &mut first)?;
            kept.keep(first, Some(1.0), grid.h)?;
            // Shown to the observer: the run cannot start again from t₀.
            let mut shown = false;
            // (time since t₀, the controlled statistic so far) after each kept chunk.
            let mut history: Vec<(f64, f64)> = Vec::new();
            let mut controlled = 0.0_f64;
            let mut chunk_share = FIRST_CHUNK_SHARE;
            let mut retries = 0;
            let mut restart_with: Option<f64> = None;
            while runs.n < runs.grid.n_end && !kept.ended() {
                let ck: Checkpoint = runs.checkpoint();
                let block = MEET as f64 * runs.grid.h;
                let unit = quantum.map_or(1, |q| (q / block).round().max(1.0) as usize);
                let blocks = ((chunk_share * span / block).ceil() as usize).max(1);
                let n_stop = runs.n + MEET * blocks.div_ceil(unit) * unit;
                let h = runs.grid.h;
                // The chunk's verdict: kept, or again with a smaller step (and why).
                let again: (f64, String) = match runs.advance(n_stop, collect) {
                    Err((f, cost)) => {
                        add_cost(&mut kept.cost, &cost);
                        let which = match f.which {
                            Which::Fine => "returned",
                            Which::Coarse => "2h checking",
                            Which::Third => "3h checking",
                        };
                        let why = format!(
                            "a step of the {which} run failed at t = {:?} (h = {:.3e}): {}",
                            f.t, f.h, f.error
                        );
                        (h / 2.0, why)
                    }
                    Ok(chunk) => {
                        let order = runs.maxima.order(p);
                        let div = divisor(order);
                        // The step-size law: the observed order, but not below r (far from
                        // the asymptotic regime a smaller order would shrink the step far
                        // too much).
                        let q = order.unwrap_or(p).clamp(0.5 * p, p);
                        let est = |pt: &Point| estimate(pt.diff, pt.noise, div);
                        let worst_out = chunk
                            .outputs
                            .iter()
                            .map(est)
                            .chain(chunk.hits.iter().map(|(_, pt)| est(pt)))
                            .fold(0.0, |m: f64, e| {
                                if e.is_nan() || m.is_nan() { f64::NAN } else { m.max(e) }
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
                        let projected = if at_end {
                            worst_out
                        } else {
                            project(&history, span).max(worst_out)
                        };
                        if trace {
                            eprintln!(
                                "solve:   t = {t:.4}: outputs {worst_out:.3e}, meets (q {level:.3}) {stat:.3e}, noise {noise:.3e}, order {order:?}, projected {projected:.3e}"
                            );
                        }
                        let over = !(worst_out <= 1.0);
                        // Over (or projected over) by round-off alone: no step helps.
                        let floor = if at_end { noise } else { project_noise(&history, noise, span) };
                        if (over || projected > 1.0) && floor >= 0.5 * projected.max(worst_out) {
                            add_cost(&mut kept.cost, &chunk.cost);
                            let steps = runs.total;
                            runs.restore(&ck)?;
                            let why = format!(
                                "the tolerance is at the round-off floor of this problem: by t = \
                                 {t:?} the rounding of {steps} steps (and of time itself) is \
                                 modelled at {noise:.2e} times the tolerance, {floor:.2e} by the \
                                 end of the span"
                            );
                            return Err(self.best_effort(options, runs, kept, stats, r, why, observer));
                        }
                        if over || (projected > 1.0 && !shown) {
                            history.pop();
                            add_cost(&mut kept.cost, &chunk.cost);
                            h_fail = h_fail.min(h);
                            let worst = if over { worst_out.max(stat) } else { projected };
                            let law = if worst.is_finite() {
                                rescale(h, 0.9 * TARGET / worst, q)
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
                            if projected < TARGET / 20.0
                                && order.is_some()
                                && !shown
                                && ups < 1
                                && t - self.t0 <= UP_SHARE * span
                                && 2.0 * h < h_fail
                            {
                                // Far more accurate than asked: again with a larger step, below
                                // the smallest that was too large.
                                ups += 1;
                                let grow = TARGET / projected.max(f64::MIN_POSITIVE);
                                let up = rescale(h, grow, q).min(2.0 * h);
                                if trace {
                                    eprintln!("solve:   again with h = {up:.4e}: far below the tolerance");
                                }
                                restart_with = Some(up);
                                break;
                            }
                            if shown && projected > 1.0 && kept.segments.len() < MAX_SEGMENTS {
                                // Shown already: the rest with a smaller step.
                                let room = (TARGET - controlled).max(0.1 * TARGET);
                                let growth = (projected - controlled).max(f64::MIN_POSITIVE);
                                let h_next = rescale(h, room / growth, q).max(h / 16.0);
                                let g = fit_grid(h_next, t, self.t_end, quantum, options.max_steps)?;
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
                if trace {
                    eprintln!("solve:   again with h = {h_new:.4e}: {why}");
                }
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
                h_want = h_new;
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
                Err((f, cost)) => {
                    add_cost(&mut kept.cost, &cost);
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

    /// The solution from what was kept.
    #[allow(clippy::too_many_arguments)]
    fn assemble(
        &self,
        options: &Options,
        kept: Kept,
        stats: Stats,
        r: usize,
        div: Option<f64>,
        order: Option<f64>,
        h: f64,
    ) -> Solution<S> {
        let energy = |y: &[f64]| self.system.energy(y);
        let with_energy = energy(&self.y0).is_some();
        let verified = div.is_some();
        let (mut t, mut y, mut es, mut energies) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (p, e) in kept.outputs {
            if with_energy {
                energies.push(energy(&p.y).unwrap_or(f64::NAN));
            }
            t.push(p.t);
            y.push(p.y);
            es.push(e);
        }
        let mut events = Vec::new();
        let mut event_worst = 0.0_f64;
        for (k, p, e) in kept.hits {
            event_worst = event_worst.max(e);
            events.push(super::events::EventHit {
                event: k,
                t: p.t,
                y: p.y,
            });
        }
        events.sort_by(|a, b| a.t.total_cmp(&b.t));
        let error_estimate =
            verified.then(|| es.iter().copied().fold(event_worst, f64::max));
        let dense = options.dense.then(|| {
            let d = self.y0.len();
            let (mut gt, mut gh, mut fine, mut coarse) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            for (tk, f, c) in &kept.grid {
                gt.push(*tk);
                let seg = kept
                    .segments
                    .iter()
                    .rev()
                    .find(|s| s.t <= *tk)
                    .map_or(h, |s| s.h);
                gh.push(seg);
                fine.extend_from_slice(f);
                coarse.extend_from_slice(&c[..d.min(c.len())]);
            }
            DenseData {
                system: std::sync::Arc::clone(&self.system),
                r,
                settings: options.settings,
                tolerance: (options.rtol, options.atol),
                t: gt,
                h: gh,
                fine,
                coarse: verified.then_some(coarse),
                divisor: div.unwrap_or(1.0),
                evals: std::cell::Cell::new((0, 0)),
            }
        });
        Solution {
            t,
            y,
            energy: with_energy.then_some(energies),
            error_estimates: if verified { es } else { Vec::new() },
            error_estimate,
            observed_order: if verified { order } else { None },
            events,
            status: kept.status.unwrap_or(Status::Completed),
            stats,
            r,
            s: r,
            h,
            segments: kept.segments,
            energy0: energy(&self.y0),
            dense,
        }
    }
}

/// The round-off model at the end of the span: like the rounding of the steps, growing with
/// the square root of the time.
fn project_noise(history: &[(f64, f64)], noise: f64, span: f64) -> f64 {
    history
        .last()
        .map_or(noise, |&(t, _)| noise * (span / t).sqrt())
}

/// The value of `xs` at quantile `level` in [0, 1] (0 for none), reordering them.
fn quantile(xs: &mut [f64], level: f64) -> f64 {
    if xs.is_empty() {
        return 0.0;
    }
    if xs.iter().any(|x| x.is_nan()) {
        return f64::NAN;
    }
    xs.sort_by(f64::total_cmp);
    let k = ((xs.len() - 1) as f64 * level.clamp(0.0, 1.0)).round() as usize;
    xs[k]
}

/// The largest estimate at the end of the span, from its growth so far: E(τ) ∝ τ^α, α from
/// the last point and the one nearest half its time (within [0, 2]; ½ — between a bounded
/// error and a linearly growing one — with too little history).
fn project(history: &[(f64, f64)], span: f64) -> f64 {
    let Some(&(tk, ek)) = history.last() else {
        return 0.0;
    };
    let alpha = history
        .iter()
        .rev()
        .find(|(t, _)| *t <= 0.5 * tk)
        .filter(|(_, e)| *e > 0.0)
        .map_or(0.5, |&(t, e)| ((ek / e).ln() / (tk / t).ln()).clamp(0.0, 2.0));
    ek * (span / tk).powf(alpha)
}
