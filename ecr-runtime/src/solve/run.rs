//! The runs of a solve, in step: the run that is returned (step h) and, for a verified
//! solve, the two that check it (steps 2h and 3h), compared wherever their grids meet: the
//! answer and the 2h run every 2h, all three every 6h.
//!
//! [`Runs::advance`] integrates one stretch (a chunk) and collects what the caller decides
//! on: the outputs (with the differences between the runs there), the events, the
//! differences at every point the grids share, and the states the observer will see. Nothing
//! of a chunk is final until the caller keeps it; [`Runs::checkpoint`] and
//! [`Runs::restore`] let it integrate the chunk again with another step size.

use super::dense::DenseStep;
use super::estimate::{Maxima, TARGET};
use super::options::Options;
use crate::error::{Error, Result};
use crate::stepper::{EcStepper, SolverSettings, StepReport};
use crate::system::System;

/// Which run a failed step belonged to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Which {
    Fine,
    Coarse,
    Third,
}

/// A step of one of the runs failed.
#[derive(Debug)]
pub(super) struct StepFailure {
    pub(super) which: Which,
    pub(super) t: f64,
    pub(super) h: f64,
    pub(super) error: Error,
    /// Not a failure of the step but of the user's input (an event function that returned
    /// NaN): no smaller step helps.
    pub(super) fatal: bool,
}

/// A value the solve returns at a time (an output or an event), with what its estimate needs.
#[derive(Clone, Debug)]
pub(super) struct Point {
    pub(super) t: f64,
    pub(super) y: Vec<f64>,
    /// The scaled difference to the checking run (step 2h) at t (0 for a fixed method).
    pub(super) diff: f64,
    /// The modelled round-off there, in tolerance units.
    pub(super) noise: f64,
}

/// The differences at a point where the grids of the answer and its 2h check meet.
#[derive(Clone, Copy, Debug)]
pub(super) struct Meet {
    pub(super) t: f64,
    pub(super) diff: f64,
    pub(super) noise: f64,
}

/// A terminal event that ended the chunk.
#[derive(Clone, Copy, Debug)]
pub(super) struct Terminal {
    pub(super) event: usize,
    pub(super) t: f64,
}

/// What one chunk produced.
#[derive(Debug, Default)]
pub(super) struct Chunk {
    pub(super) outputs: Vec<Point>,
    /// Located zeros: (event index, point).
    pub(super) hits: Vec<(usize, Point)>,
    pub(super) meets: Vec<Meet>,
    /// The answer's states after each step (t, step number, state), for the observer.
    pub(super) steps: Vec<(f64, usize, Vec<f64>)>,
    /// Grid states kept for dense output: (t, answer, check).
    pub(super) grid: Vec<(f64, Vec<f64>, Vec<f64>)>,
    pub(super) terminal: Option<Terminal>,
    /// g-evaluations and steps: the answer, the checks, the dense steps.
    pub(super) cost: Cost,
}

/// Steps and evaluations of g of a chunk.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Cost {
    pub(super) steps: usize,
    pub(super) g_evals: usize,
    pub(super) sweeps: usize,
    pub(super) check_steps: usize,
    pub(super) check_g_evals: usize,
    pub(super) dense_steps: usize,
    pub(super) dense_g_evals: usize,
}

impl Cost {
    fn fine(&mut self, rep: &StepReport) {
        self.steps += 1;
        self.g_evals += rep.g_evals;
        self.sweeps += rep.sweeps;
    }
    fn check(&mut self, rep: &StepReport) {
        self.check_steps += 1;
        self.check_g_evals += rep.g_evals;
    }
    fn dense(&mut self, (n, g): (usize, usize)) {
        self.dense_steps += n;
        self.dense_g_evals += g;
    }
    pub(super) fn total_steps(&self) -> usize {
        self.steps + self.check_steps + self.dense_steps
    }
    pub(super) fn total_g_evals(&self) -> usize {
        self.g_evals + self.check_g_evals + self.dense_g_evals
    }
}

/// What a chunk is asked to collect besides the differences.
#[derive(Clone, Copy, Debug)]
pub(super) struct Collect {
    /// Output at every meeting point of answer and check (every step for a fixed method).
    pub(super) every_step: bool,
    /// The answer's state after each step (for an observer).
    pub(super) steps: bool,
    /// The grid states (for [`Solution::at`](super::Solution::at)).
    pub(super) grid: bool,
    /// Events: all of them, or only the terminal ones (pilots).
    pub(super) events: bool,
}

/// The answer's steps between the points where all three runs of a verified solve meet.
pub(super) const MEET: usize = 6;

/// The constant-step stretch the runs are on: from `a`, steps of h, `n_end` of them to
/// `end` (the last one is shortened for a fixed method whose h does not divide the span;
/// for a verified solve `n_end` is a multiple of [`MEET`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct Grid {
    pub(super) a: f64,
    pub(super) h: f64,
    pub(super) n_end: usize,
    pub(super) end: f64,
}

impl Grid {
    /// The time of the answer's n-th grid point: a + n·h, the last one `end`.
    pub(super) fn time(&self, n: usize) -> f64 {
        if n >= self.n_end {
            self.end
        } else {
            self.a + n as f64 * self.h
        }
    }
}

/// What [`Runs::restore`] goes back to.
#[derive(Clone, Debug)]
pub(super) struct Checkpoint {
    y: [Vec<f64>; 3],
    grid: Grid,
    n: usize,
    total: usize,
    ev_prev: Vec<f64>,
    maxima: Maxima,
    t_eval_next: usize,
}

/// The runs of a solve.
pub(super) struct Runs<'a, 'o, S: System> {
    system: &'a S,
    options: &'o Options,
    r: usize,
    /// Whether the checking runs (2h, 3h) run.
    check: bool,
    steppers: Vec<EcStepper<&'a S>>,
    /// The states: answer, check 2h, check 3h.
    y: [Vec<f64>; 3],
    pub(super) grid: Grid,
    /// The answer's steps since `grid.a`.
    pub(super) n: usize,
    /// The answer's steps since t₀ (all stretches).
    pub(super) total: usize,
    ev_prev: Vec<f64>,
    pub(super) maxima: Maxima,
    /// The next output time of `t_eval` not yet produced.
    t_eval_next: usize,
    /// Where the answer's and the check's states are kept between meeting points, for
    /// dense output: (t, answer, check).
    base: (f64, Vec<f64>, Vec<f64>),
    dense: DenseStep<'a, S>,
    /// Times within this distance count as the same.
    pub(super) same_time: f64,
    /// The stage tolerance of the run that is returned.
    fine_tolerance: f64,
    /// The answer's state before its last step (for the rate of change in the round-off
    /// model).
    before: Vec<f64>,
    /// The order the differences are expected to show (for the checking runs' stage
    /// tolerances).
    order_hint: f64,
}

/// The round-off model: per step, each component is rounded relative to the whole state
/// (the propagator and the stage sums mix all components), by this many units of
/// max(ε, the stage tolerance / 5); the errors add up like a random walk.
const NOISE_FACTOR: f64 = 2.0;

impl<'a, 'o, S: System> Runs<'a, 'o, S> {
    /// The runs from (t₀, y₀) on the grid; with `check`, the checking runs too, their stage
    /// iterations stopped at `check_tolerance` (2h) and `third_tolerance` (3h).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
        system: &'a S,
        options: &'o Options,
        r: usize,
        check: bool,
        y0: &[f64],
        grid: Grid,
        same_time: f64,
        order_hint: f64,
    ) -> Result<Self> {
        let ev_prev = options
            .events
            .iter()
            .enumerate()
            .map(|(k, e)| e.value(k, grid.a, y0))
            .collect::<Result<Vec<_>>>()?;
        let mut runs = Runs {
            system,
            options,
            r,
            check,
            steppers: Vec::new(),
            y: [y0.to_vec(), y0.to_vec(), y0.to_vec()],
            grid,
            n: 0,
            total: 0,
            ev_prev,
            maxima: Maxima::default(),
            t_eval_next: 0,
            base: (grid.a, y0.to_vec(), y0.to_vec()),
            dense: DenseStep::new(system, r, options.settings),
            same_time,
            fine_tolerance: options.settings.tolerance,
            before: y0.to_vec(),
            order_hint,
        };
        if let Some(ts) = &options.t_eval {
            runs.t_eval_next = ts.partition_point(|&t| t < grid.a - same_time);
        }
        runs.set_grid(grid)?;
        Ok(runs)
    }

    /// Puts the runs on a new stretch starting where they are (`grid.a` = the current time),
    /// with stage tolerances for the checking runs from the tolerance and the steps left.
    pub(super) fn set_grid(&mut self, grid: Grid) -> Result<()> {
        self.grid = grid;
        self.n = 0;
        let settings = self.options.settings;
        if self.steppers.is_empty() {
            self.steppers.push(EcStepper::with_nodes(
                self.system,
                self.r,
                self.r,
                grid.h,
                settings,
            )?);
        } else {
            self.steppers[0].set_step_size(grid.h)?;
        }
        if self.check {
            let (tc, tq) = self.check_tolerances();
            self.steppers.truncate(1);
            for (ratio, tol) in [(2.0, tc), (3.0, tq)] {
                let s = SolverSettings {
                    tolerance: tol,
                    ..settings
                };
                self.steppers.push(EcStepper::with_nodes(
                    self.system,
                    self.r,
                    self.r,
                    ratio * grid.h,
                    s,
                )?);
            }
        }
        Ok(())
    }

    /// Stage tolerances of the checking runs: their iteration error, added up over their
    /// steps, stays below 1 % of the difference each is to show when the answer's error is
    /// [`TARGET`] times the tolerance and the order is `order_hint` (2^q − 1 resp. 3^q − 2^q
    /// times it), in the stepper's scale (relative to max(1, ‖Y‖∞)); never looser than 1e−6,
    /// never tighter than the answer's.
    fn check_tolerances(&self) -> (f64, f64) {
        let y = &self.y[0];
        let big = y.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
        let w = y
            .iter()
            .map(|v| self.options.atol + self.options.rtol * v.abs())
            .filter(|w| *w > 0.0)
            .fold(f64::INFINITY, f64::min)
            / big;
        let w = if w.is_finite() { w } else { 0.0 };
        let q = self.order_hint.max(1.0);
        let steps = self.grid.n_end.max(2) as f64;
        let base = 0.01 * TARGET * w;
        let lo = self.fine_tolerance;
        let hi = 1e-6_f64.max(lo);
        let tc = (base * (2f64.powf(q) - 1.0) / (steps / 2.0)).clamp(lo, hi);
        let tq = (base * (3f64.powf(q) - 2f64.powf(q)) / (steps / 3.0)).clamp(lo, hi);
        (tc, tq)
    }

    pub(super) fn checkpoint(&self) -> Checkpoint {
        Checkpoint {
            y: self.y.clone(),
            grid: self.grid,
            n: self.n,
            total: self.total,
            ev_prev: self.ev_prev.clone(),
            maxima: self.maxima,
            t_eval_next: self.t_eval_next,
        }
    }

    /// Back to a checkpoint, on the grid it had.
    pub(super) fn restore(&mut self, ck: &Checkpoint) -> Result<()> {
        self.y = ck.y.clone();
        self.total = ck.total;
        self.ev_prev = ck.ev_prev.clone();
        self.maxima = ck.maxima;
        self.t_eval_next = ck.t_eval_next;
        let t = ck.grid.time(ck.n);
        self.base = (t, self.y[0].clone(), self.y[1].clone());
        if ck.grid.h != self.grid.h {
            self.set_grid(ck.grid)?;
        } else {
            self.grid = ck.grid;
        }
        self.n = ck.n;
        Ok(())
    }

    /// The time reached.
    pub(super) fn t(&self) -> f64 {
        self.grid.time(self.n)
    }

    /// The scaled round-off model at a state after `total` steps, in tolerance units: the
    /// rounding of the steps (see [`NOISE_FACTOR`]), and the resolution of time itself (a time
    /// t is only known to ε|t|, which is |y'| ε|t| in y; |y'| from the last step).
    fn noise(&self, y: &[f64], total: usize) -> f64 {
        let big = y.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        let unit = f64::EPSILON.max(self.fine_tolerance / 5.0);
        let walk = NOISE_FACTOR * unit * ((total + 1) as f64).sqrt();
        let t = self.t().abs().max(self.grid.a.abs());
        let clock = f64::EPSILON * t / self.grid.h;
        y.iter()
            .zip(&self.before)
            .map(|(v, b)| {
                let n = walk * (v.abs() + big) + clock * (v - b).abs();
                let w = self.options.atol + self.options.rtol * v.abs();
                // A component measured relative to itself at 0 (atol = 0): only an exact
                // agreement verifies it, which the differences themselves show.
                if w == 0.0 { 0.0 } else { n / w }
            })
            .fold(0.0, f64::max)
    }

    /// The round-off model at the current state of the answer, before any step.
    pub(super) fn noise_at_start(&self) -> f64 {
        self.noise(&self.y[0], 0)
    }

    /// The scaled difference of two states, weighted at the first.
    fn diff(&self, fine: &[f64], other: &[f64]) -> f64 {
        self.options
            .scaled(other.iter().zip(fine).map(|(o, f)| o - f), fine)
    }

    /// One step of run `k` (answer, 2h, 3h) of `ratio` answer steps, from the answer's step
    /// `from` on: the last one of the stretch ends at its end exactly (its size computed, the
    /// stepper's own step restored after it).
    fn step(
        &mut self,
        k: usize,
        ratio: usize,
        from: usize,
    ) -> std::result::Result<StepReport, StepFailure> {
        let t = self.grid.time(from);
        let nominal = ratio as f64 * self.grid.h;
        let h = if from + ratio >= self.grid.n_end {
            self.grid.end - t
        } else {
            nominal
        };
        let short = h != self.steppers[k].step_size();
        let res = (|| {
            if short {
                self.steppers[k].set_step_size(h)?;
            }
            let rep = self.steppers[k].step(&mut self.y[k]);
            if short {
                self.steppers[k].set_step_size(nominal)?;
            }
            rep
        })();
        res.map_err(|error| StepFailure {
            which: [Which::Fine, Which::Coarse, Which::Third][k],
            t,
            h,
            error,
            fatal: false,
        })
    }

    /// Evaluates the answer (and for a verified solve the check) at t in (base, next meeting
    /// point] from the base: the answer two steps of half the distance (one step for a fixed
    /// method), the check one step. Returns the point.
    fn dense_point(&mut self, t: f64, cost: &mut Cost) -> Result<Point> {
        let d = self.y[0].len();
        let dt = t - self.base.0;
        let mut yf = vec![0.0; d];
        let fine_steps = if self.check { 2 } else { 1 };
        cost.dense(self.dense.advance(&self.base.1, dt, fine_steps, &mut yf)?);
        let (diff, noise) = if self.check {
            let mut yc = vec![0.0; d];
            cost.dense(self.dense.advance(&self.base.2, dt, 1, &mut yc)?);
            (self.diff(&yf, &yc), self.noise(&yf, self.total))
        } else {
            (0.0, 0.0)
        };
        Ok(Point {
            t,
            y: yf,
            diff,
            noise,
        })
    }

    /// The answer alone at t (for locating events).
    fn dense_fine(&mut self, t: f64, out: &mut [f64], cost: &mut Cost) -> Result<()> {
        let fine_steps = if self.check { 2 } else { 1 };
        let dt = t - self.base.0;
        cost.dense(self.dense.advance(&self.base.1, dt, fine_steps, out)?);
        Ok(())
    }

    /// Outputs of `t_eval` up to `limit` (inclusive, within the same-time tolerance unless
    /// `exact`), the one at `t_meet` from `at_meet` (its point), the others between grid
    /// points.
    fn outputs_until(
        &mut self,
        limit: f64,
        exact: bool,
        at_meet: Option<&Point>,
        chunk: &mut Chunk,
    ) -> Result<()> {
        let Some(ts) = self.options.t_eval.as_deref() else {
            return Ok(());
        };
        let slack = if exact { 0.0 } else { self.same_time };
        while let Some(&te) = ts.get(self.t_eval_next) {
            if te > limit + slack {
                break;
            }
            let point = match at_meet {
                Some(p) if (te - p.t).abs() <= self.same_time => Point { t: te, ..p.clone() },
                _ if te <= self.base.0 => Point {
                    t: te,
                    y: self.base.1.clone(),
                    diff: if self.check {
                        self.diff(&self.base.1, &self.base.2)
                    } else {
                        0.0
                    },
                    noise: if self.check {
                        self.noise(&self.base.1, self.total)
                    } else {
                        0.0
                    },
                },
                _ => self.dense_point(te, &mut chunk.cost)?,
            };
            chunk.outputs.push(point);
            self.t_eval_next += 1;
        }
        Ok(())
    }

    /// The start of the integration: outputs at t₀.
    pub(super) fn start(&mut self, collect: Collect, chunk: &mut Chunk) -> Result<()> {
        let t0 = self.grid.a;
        let p = Point {
            t: t0,
            y: self.y[0].clone(),
            diff: 0.0,
            noise: 0.0,
        };
        if collect.every_step {
            chunk.outputs.push(p.clone());
        }
        if collect.grid {
            chunk.grid.push((t0, self.y[0].clone(), self.y[1].clone()));
        }
        self.outputs_until(t0, false, Some(&p), chunk)
    }

    /// Integrates until the answer has made `n_stop` steps of the stretch (a multiple of
    /// [`MEET`] for a verified solve) or a terminal event ends it. Returns the chunk, or the step that
    /// failed (the runs are then somewhere inside the chunk: restore a checkpoint).
    pub(super) fn advance(
        &mut self,
        n_stop: usize,
        collect: Collect,
    ) -> std::result::Result<Chunk, (StepFailure, Cost)> {
        let mut chunk = Chunk::default();
        match self.advance_into(n_stop, collect, &mut chunk) {
            Ok(()) => Ok(chunk),
            Err(AdvanceError::Step(f)) => Err((f, chunk.cost)),
            Err(AdvanceError::Other(e, fatal)) => {
                let t = self.t();
                Err((
                    StepFailure {
                        which: Which::Fine,
                        t,
                        h: self.grid.h,
                        error: e,
                        fatal,
                    },
                    chunk.cost,
                ))
            }
        }
    }

    fn advance_into(
        &mut self,
        n_stop: usize,
        collect: Collect,
        chunk: &mut Chunk,
    ) -> std::result::Result<(), AdvanceError> {
        let stride = if self.check { 2 } else { 1 };
        let d = self.y[0].len();
        let mut scratch = vec![0.0; d];
        while self.n < n_stop.min(self.grid.n_end) {
            // The answer's step (the last one of the stretch ends at its end).
            let t_prev = self.t();
            self.before.copy_from_slice(&self.y[0]);
            let rep = self.step(0, 1, self.n)?;
            chunk.cost.fine(&rep);
            self.n += 1;
            self.total += 1;
            let t = self.t();
            if collect.steps {
                chunk.steps.push((t, self.total, self.y[0].clone()));
            }

            // Events on the answer, located between the base and t.
            let mut stop: Option<Terminal> = None;
            let options: &'o Options = self.options;
            let events = &options.events;
            let mut found: Vec<(usize, f64)> = Vec::new();
            for (k, e) in events.iter().enumerate() {
                if !collect.events && !e.terminal {
                    continue;
                }
                let now = e
                    .value(k, t, &self.y[0])
                    .map_err(|e| AdvanceError::Other(e, true))?;
                let before = self.ev_prev[k];
                if e.counts(before, now) {
                    let te = e.locate((t_prev, before), (t, now), |tt| {
                        self.dense_fine(tt, &mut scratch, &mut chunk.cost)?;
                        e.value(k, tt, &scratch)
                            .map_err(|e| AdvanceError::Other(e, true))
                    })?;
                    if e.terminal && stop.is_none_or(|s| te < s.t) {
                        stop = Some(Terminal { event: k, t: te });
                    }
                    found.push((k, te));
                }
                self.ev_prev[k] = now;
            }
            if let Some(stop) = stop {
                found.retain(|&(_, te)| te <= stop.t);
            }
            found.sort_by(|a, b| a.1.total_cmp(&b.1));
            for (k, te) in found {
                let point = if (te - t).abs() <= self.same_time && !self.check {
                    Point {
                        t: te,
                        y: self.y[0].clone(),
                        diff: 0.0,
                        noise: 0.0,
                    }
                } else {
                    self.dense_point(te, &mut chunk.cost)?
                };
                chunk.hits.push((k, point));
            }
            if let Some(stop) = stop {
                self.outputs_until(stop.t, true, None, chunk)?;
                if collect.every_step {
                    let p = chunk
                        .hits
                        .iter()
                        .rev()
                        .find(|(k, p)| *k == stop.event && p.t == stop.t)
                        .map(|(_, p)| p.clone());
                    if let Some(p) = p {
                        chunk.outputs.push(p);
                    }
                }
                chunk.terminal = Some(stop);
                return Ok(());
            }
            if self.check && self.n % 3 == 0 {
                let rep = self.step(2, 3, self.n - 3)?;
                chunk.cost.check(&rep);
            }
            if self.n % stride != 0 {
                continue;
            }

            // A meeting point of the answer and its checks.
            let point = if self.check {
                let rep = self.step(1, 2, self.n - 2)?;
                chunk.cost.check(&rep);
                let diff = self.diff(&self.y[0], &self.y[1]);
                let noise = self.noise(&self.y[0], self.total);
                if self.n % MEET == 0 {
                    // The 2h–3h difference, weighted at the answer.
                    let c3 = self.options.scaled(
                        self.y[2].iter().zip(&self.y[1]).map(|(a, b)| a - b),
                        &self.y[0],
                    );
                    let m = &mut self.maxima;
                    m.fine = m.fine.max(diff);
                    m.last = (diff, c3);
                    m.coarse = m.coarse.max(c3);
                    m.noise = m.noise.max(noise);
                }
                chunk.meets.push(Meet { t, diff, noise });
                Point {
                    t,
                    y: self.y[0].clone(),
                    diff,
                    noise,
                }
            } else {
                Point {
                    t,
                    y: self.y[0].clone(),
                    diff: 0.0,
                    noise: 0.0,
                }
            };
            self.outputs_until(t, false, Some(&point), chunk)?;
            if collect.grid {
                chunk.grid.push((t, self.y[0].clone(), self.y[1].clone()));
            }
            if collect.every_step {
                chunk.outputs.push(point);
            }
            self.base = (t, self.y[0].clone(), self.y[1].clone());
        }
        Ok(())
    }
}

enum AdvanceError {
    Step(StepFailure),
    /// An error on the way (a step between grid points), or with `true` one that no step
    /// size can mend (an event function's NaN).
    Other(Error, bool),
}

impl From<StepFailure> for AdvanceError {
    fn from(f: StepFailure) -> Self {
        AdvanceError::Step(f)
    }
}

impl From<Error> for AdvanceError {
    fn from(e: Error) -> Self {
        AdvanceError::Other(e, false)
    }
}
