//! The runs of a solve, in step: the run that is returned (step h) and, for a verified
//! solve, the two that check it (steps 2h and 3h), compared wherever their grids meet: the
//! answer and the 2h run every 2h, all three every 6h.
//!
//! [`Runs::advance`] integrates one stretch (a chunk) and collects what the caller decides
//! on: the outputs (with the differences between the runs there), the events, the
//! differences at every point the grids share, and the states the observer will see. Nothing
//! of a chunk is final until the caller keeps it; [`Runs::checkpoint`] and
//! [`Runs::restore`] let it integrate the chunk again with another step size.

use std::sync::Arc;

use super::SolveCache;
use super::dense::DenseStep;
use super::estimate::{Maxima, TARGET};
use super::options::Options;
use super::trail::{Trail, stencil_width};
use crate::error::{Error, Result};
use crate::integrate::StepPlan;
use crate::operator::LinearOperator;
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
    /// The estimated error of the interpolation between grid points, in tolerance units (0 at
    /// grid points and for values computed by steps of the method).
    pub(super) interp: f64,
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
    /// The outputs of `t_eval` (not in pilots).
    pub(super) t_eval: bool,
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
    y: [Vec<f64>; 4],
    grid: Grid,
    n: usize,
    total: usize,
    ev_prev: Vec<f64>,
    maxima: Maxima,
    t_eval_next: usize,
    trail: Option<Trail>,
    pending: Vec<PendingHit>,
    sensitivity: f64,
}

/// A zero of an event function seen between two grid points of the answer, to be located on
/// the interpolant once the grid around it is known.
#[derive(Clone, Copy, Debug)]
struct PendingHit {
    event: usize,
    a: (f64, f64),
    b: (f64, f64),
}

/// The runs of a solve.
pub(super) struct Runs<'a, 'o, S: System> {
    system: &'a S,
    options: &'o Options,
    r: usize,
    /// Whether the checking runs (2h, 3h) run.
    check: bool,
    steppers: Vec<EcStepper<&'a S>>,
    /// The states: answer, check 2h, check 3h, and the 3h run perturbed by rounding (the
    /// sensitivity run, see [`Runs::perturb_sensitivity`]).
    y: [Vec<f64>; 4],
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
    /// The sensitivity run's state before its last step (its increment sizes its rounding).
    sens_before: Vec<f64>,
    /// The order the differences are expected to show (for the checking runs' stage
    /// tolerances).
    order_hint: f64,
    /// The rounding amplified by the flow at the last point where the 3h runs met the answer
    /// (the sensitivity run's difference to the 3h run), in tolerance units.
    sensitivity: f64,
    /// The banks of the solve.
    cache: Arc<SolveCache<S>>,
    /// The answer's last grid points, where output between them is asked for (`t_eval`,
    /// events): values there by interpolation.
    trail: Option<Trail>,
    /// The interpolation's stencil width.
    width: usize,
    /// Zeros of events waiting for the grid around them.
    pending: Vec<PendingHit>,
}

/// The largest estimated interpolation error (in tolerance units) at which an output between
/// grid points takes the interpolant; above it, the output is computed by steps of the method
/// from the grid point before it.
const INTERP_MAX: f64 = 0.25;

/// A 64-bit mix of `x` (SplitMix64's finaliser).
fn splitmix(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
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
        cache: &Arc<SolveCache<S>>,
    ) -> Result<Self> {
        crate::storage::ensure_bytes_allocatable(
            &format!(
                "the steppers of EC{r}P for this solve (d = {}{})",
                system.dim(),
                if check {
                    ", with its checking runs"
                } else {
                    ""
                }
            ),
            super::solve_stepper_bytes(system, r, check, &options.settings),
        )?;
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
            y: [y0.to_vec(), y0.to_vec(), y0.to_vec(), y0.to_vec()],
            grid,
            n: 0,
            total: 0,
            ev_prev,
            maxima: Maxima::default(),
            t_eval_next: 0,
            base: (grid.a, y0.to_vec(), y0.to_vec()),
            dense: DenseStep::new(system, r, options.settings, cache),
            same_time,
            fine_tolerance: options.settings.tolerance,
            before: y0.to_vec(),
            sens_before: y0.to_vec(),
            order_hint,
            sensitivity: 0.0,
            cache: Arc::clone(cache),
            trail: None,
            width: stencil_width(r),
            pending: Vec::new(),
        };
        if options.t_eval.is_some() || options.events.iter().any(|e| !e.terminal) {
            let w = runs.width;
            // The stencil, one more point on each side, and the lag behind the newest point.
            let mut trail = Trail::new(2 * w + 2 * MEET + 4);
            trail.push(grid.a, y0);
            runs.trail = Some(trail);
        }
        if let Some(ts) = &options.t_eval {
            runs.t_eval_next = ts.partition_point(|&t| t < grid.a - same_time);
        }
        runs.set_grid(grid)?;
        if check {
            // y₀ as rounded as the answer's states will be.
            runs.perturb_sensitivity(0, 1.0);
        }
        Ok(runs)
    }

    /// Puts the runs on a new stretch starting where they are (`grid.a` = the current time),
    /// with stage tolerances for the checking runs from the tolerance and the steps left.
    pub(super) fn set_grid(&mut self, grid: Grid) -> Result<()> {
        self.grid = grid;
        self.n = 0;
        let settings = self.options.settings;
        if self.steppers.is_empty() {
            self.steppers.push(EcStepper::with_nodes_cached(
                self.system,
                (self.r, self.r),
                grid.h,
                settings,
                &self.cache,
            )?);
        } else {
            self.steppers[0].set_step_size(grid.h)?;
        }
        if self.check {
            let (tc, tq) = self.check_tolerances();
            self.steppers.truncate(1);
            for (ratio, tol) in [(2.0, tc), (3.0, tq), (3.0, tq)] {
                let s = SolverSettings {
                    tolerance: tol,
                    ..settings
                };
                self.steppers.push(EcStepper::with_nodes_cached(
                    self.system,
                    (self.r, self.r),
                    ratio * grid.h,
                    s,
                    &self.cache,
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
            trail: self.trail.clone(),
            pending: self.pending.clone(),
            sensitivity: self.sensitivity,
        }
    }

    /// Back to a checkpoint, on the grid it had.
    pub(super) fn restore(&mut self, ck: &Checkpoint) -> Result<()> {
        self.y = ck.y.clone();
        self.total = ck.total;
        self.ev_prev = ck.ev_prev.clone();
        self.maxima = ck.maxima;
        self.t_eval_next = ck.t_eval_next;
        self.trail = ck.trail.clone();
        self.pending = ck.pending.clone();
        self.sensitivity = ck.sensitivity;
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

    /// The work of an evaluation of g in the answer's steps, in units of the evaluation itself,
    /// for comparing orders: where the stepper fuses its sweeps into dense maps (small dense
    /// systems), a sweep also costs its s²d² multiply-adds, about s·d/8 evaluations of a cheap
    /// g per stage; elsewhere the operator's work scales with the evaluations.
    pub(super) fn work_per_g_eval(&self) -> f64 {
        let st = &self.steppers[0];
        if st.fused_maps().is_some() {
            1.0 + (st.s() * self.y[0].len()) as f64 / 8.0
        } else {
            1.0
        }
    }

    /// The time reached.
    pub(super) fn t(&self) -> f64 {
        self.grid.time(self.n)
    }

    /// The scaled round-off model at a state after `total` steps, in tolerance units: the
    /// rounding of the steps (see [`NOISE_FACTOR`]), and the resolution of time itself (a time
    /// t is only known to ε|t|, which is |y'| ε|t| in y; |y'| from the last step).
    fn noise(&self, y: &[f64], total: usize) -> f64 {
        self.noise_model(y, total).max(self.sensitivity)
    }

    /// The round-off model without the measured sensitivity.
    fn noise_model(&self, y: &[f64], total: usize) -> f64 {
        let big = y.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        let unit = f64::EPSILON.max(self.fine_tolerance / 5.0);
        let walk = NOISE_FACTOR * unit * ((total + 1) as f64).sqrt();
        let t = self.t().abs().max(self.grid.a.abs());
        let clock = f64::EPSILON * t / self.grid.h;
        y.iter()
            .zip(&self.before)
            .map(|(v, b)| {
                // Below the smallest normal number f64 keeps fewer digits: a subnormal
                // state's steps differ by far more than ε|y| (by as much as 1e-315 at
                // |y| = 1e-310), so a difference below it is round-off whatever its ratio.
                let n = walk * (v.abs() + big) + clock * (v - b).abs() + f64::MIN_POSITIVE;
                let w = self.options.atol + self.options.rtol * v.abs();
                // A component measured relative to itself at 0 (atol = 0): only an exact
                // agreement verifies it, which the differences themselves show.
                if w == 0.0 { 0.0 } else { n / w }
            })
            .fold(0.0, f64::max)
    }

    /// The round-off model at the current state of the answer, before any step.
    pub(super) fn noise_at_start(&self) -> f64 {
        self.noise_model(&self.y[0], 0)
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
        let last = from + ratio >= self.grid.n_end;
        // What the steps of the stretch leave of it after this one, exactly (rounded once): 0,
        // or a few units of round-off where n·fl(h) misses the stretch, or the whole shortening
        // of a last step that h does not divide.
        let rest = if last {
            crate::integrate::exact_rest(
                self.grid.a,
                self.grid.end,
                (from + ratio) as f64,
                self.grid.h,
            )
        } else {
            0.0
        };
        let scale = self.grid.a.abs().max(self.grid.end.abs());
        let by_rounding = rest.abs() <= StepPlan::TIME_ULPS * f64::EPSILON * scale;
        // A last step off by round-off is a full step and a move along the vector field by the
        // difference (its error O(rest²), far below the rounding of time): no φ-bank for a
        // step size used once.
        let h = if by_rounding { nominal } else { nominal + rest };
        let short = h != self.steppers[k].step_size();
        let res = (|| {
            if short {
                self.steppers[k].set_step_size(h)?;
            }
            if k == 3 {
                self.sens_before.copy_from_slice(&self.y[3]);
            }
            let rep = self.steppers[k].step(&mut self.y[k]);
            if short {
                self.steppers[k].set_step_size(nominal)?;
            }
            let rep = rep?;
            if by_rounding && rest != 0.0 {
                drift(self.system, &mut self.y[k], rest)?;
            }
            if k == 3 {
                // Three of the answer's steps of rounding.
                self.perturb_sensitivity(from + ratio, 3f64.sqrt());
            }
            Ok(rep)
        })();
        res.map_err(|error| StepFailure {
            which: [Which::Fine, Which::Coarse, Which::Third, Which::Third][k],
            t,
            h,
            error,
            fatal: false,
        })
    }

    /// Rounding made visible. The answer's own rounding (and the rounding of y₀) is shared in
    /// kind by all three runs, so that their differences do not show it where the flow
    /// amplifies it (chaos, an orbit near a separatrix). The sensitivity run is the 3h run
    /// again with its state changed after each step (and at its start) by about what the
    /// answer's `steps` steps round it (below), with signs from a fixed
    /// pseudo-random sequence of the step and the component; its difference to the 3h run is
    /// that rounding amplified by the flow, and bounds the estimate from below. Deterministic:
    /// the same numbers for the same run, whatever the thread.
    ///
    /// The size: one rounding of each component per answer step (half an ulp of the
    /// component, and of its increment for a component near zero), `steps` of them added like
    /// a random walk. That is what a plain f64 update rounds; the compensated update rounds
    /// less. (Sized like the round-off model instead, relative to the whole state and twice
    /// over, it measured 100–300 times what one ulp of y₀ moves the answer on the pendulum and
    /// Hénon–Heiles, and refused tolerances their runs meet.)
    fn perturb_sensitivity(&mut self, step: usize, steps: f64) {
        let unit = f64::EPSILON.max(self.fine_tolerance / 5.0);
        let size = 0.5 * unit * steps;
        let seed = (step as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        let start = step == 0;
        let y = &mut self.y[3];
        let before = &self.sens_before;
        self.steppers[3].perturb_state(y, |i, v| {
            let sign = if splitmix(seed ^ i as u64) & 1 == 0 {
                1.0
            } else {
                -1.0
            };
            let delta = if start { 0.0 } else { (v - before[i]).abs() };
            v + sign * size * (v.abs() + delta)
        });
    }

    /// Evaluates the answer (and for a verified solve the check) at t from the grid point
    /// `(t_b, answer, check)` before it: the answer in two steps of half the distance (one step
    /// for a fixed method), the check in one step. Returns the point.
    fn dense_point_from(
        &mut self,
        (t_b, ya, yc): (f64, &[f64], &[f64]),
        t: f64,
        cost: &mut Cost,
    ) -> Result<Point> {
        let d = ya.len();
        let dt = t - t_b;
        let mut yf = vec![0.0; d];
        let fine_steps = if self.check { 2 } else { 1 };
        cost.dense(self.dense.advance(ya, dt, fine_steps, &mut yf)?);
        let (diff, noise) = if self.check {
            let mut ycc = vec![0.0; d];
            cost.dense(self.dense.advance(yc, dt, 1, &mut ycc)?);
            (self.diff(&yf, &ycc), self.noise(&yf, self.total))
        } else {
            (0.0, 0.0)
        };
        Ok(Point {
            t,
            y: yf,
            diff,
            noise,
            interp: 0.0,
        })
    }

    /// [`dense_point_from`](Self::dense_point_from) the last meeting point (`base`).
    fn dense_point(&mut self, t: f64, cost: &mut Cost) -> Result<Point> {
        let (tb, ya, yc) = std::mem::take(&mut self.base);
        let p = self.dense_point_from((tb, &ya, &yc), t, cost);
        self.base = (tb, ya, yc);
        p
    }

    /// The answer alone at t (for locating events).
    fn dense_fine(&mut self, t: f64, out: &mut [f64], cost: &mut Cost) -> Result<()> {
        let fine_steps = if self.check { 2 } else { 1 };
        let dt = t - self.base.0;
        cost.dense(self.dense.advance(&self.base.1, dt, fine_steps, out)?);
        Ok(())
    }

    /// The answer at t between grid points held by the trail: the interpolant where its
    /// estimated error is at most [`INTERP_MAX`] (and the trail has the check's data around t
    /// for a verified solve), else steps of the method from the meeting point (or grid point)
    /// before t.
    fn between(&mut self, t: f64, cost: &mut Cost) -> Result<Point> {
        let d = self.y[0].len();
        let verified = self.check;
        let options = self.options;
        let width = self.width;
        let system = self.system;
        if let Some(trail) = self.trail.as_mut() {
            let mut y = vec![0.0; d];
            let scaled = |e: &[f64], at: &[f64]| options.scaled(e.iter().copied(), at);
            if let Some(ip) = trail.interpolate(system, t, width, verified, scaled, &mut y) {
                if ip.interp <= INTERP_MAX {
                    return Ok(Point {
                        t,
                        y,
                        diff: ip.diff,
                        noise: ip.noise,
                        interp: ip.interp,
                    });
                }
            }
            // Steps of the method from the grid point before t that the check knows.
            let from = if verified {
                trail.meet_before(t)
            } else {
                trail.points.iter().rev().find(|p| p.t <= t)
            };
            if let Some(p) = from {
                let (tb, ya) = (p.t, p.y.clone());
                let yc = p
                    .meet
                    .as_ref()
                    .map_or_else(|| ya.clone(), |m| m.check.clone());
                return self.dense_point_from((tb, &ya, &yc), t, cost);
            }
        }
        self.dense_point(t, cost)
    }

    /// Outputs of `t_eval` up to `limit` (inclusive, within the same-time tolerance unless
    /// `exact`): at a meeting point its point `at_meet`, between grid points by
    /// [`between`](Self::between). With `all` false only those whose interpolation stencil the
    /// trail already holds around them (the others wait for the next grid points).
    fn outputs_until(
        &mut self,
        limit: f64,
        exact: bool,
        all: bool,
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
            let at_grid = self.trail.as_ref().and_then(|tr| {
                tr.points
                    .iter()
                    .rev()
                    .find(|p| (te - p.t).abs() <= self.same_time)
            });
            let point = match (at_meet, at_grid) {
                (Some(p), _) if (te - p.t).abs() <= self.same_time => Point { t: te, ..p.clone() },
                (_, Some(g)) if g.meet.is_some() || !self.check => {
                    let (diff, noise) = g.meet.as_ref().map_or((0.0, 0.0), |m| (m.diff, m.noise));
                    Point {
                        t: te,
                        y: g.y.clone(),
                        diff,
                        noise,
                        interp: 0.0,
                    }
                }
                _ => {
                    let ready = all
                        || self
                            .trail
                            .as_ref()
                            .is_none_or(|tr| tr.centred(te, self.width));
                    if !ready {
                        break;
                    }
                    self.between(te, &mut chunk.cost)?
                }
            };
            chunk.outputs.push(point);
            self.t_eval_next += 1;
        }
        Ok(())
    }

    /// The zeros of events seen between grid points, located on the interpolant once the
    /// trail holds the grid around them (all of them with `all`), each a hit with its point.
    fn resolve_hits(
        &mut self,
        all: bool,
        chunk: &mut Chunk,
    ) -> std::result::Result<(), AdvanceError> {
        let mut i = 0;
        while i < self.pending.len() {
            let hit = self.pending[i];
            let ready = all
                || self
                    .trail
                    .as_ref()
                    .is_none_or(|tr| tr.centred(hit.b.0, self.width));
            if !ready {
                i += 1;
                continue;
            }
            self.pending.remove(i);
            let options: &'o Options = self.options;
            let event = &options.events[hit.event];
            let d = self.y[0].len();
            let mut y = vec![0.0; d];
            let system = self.system;
            let width = self.width;
            let mut cost = Cost::default();
            let te = match self.trail.as_mut() {
                Some(trail) => event.locate(hit.a, hit.b, |tt| {
                    let no_scale = |_: &[f64], _: &[f64]| 0.0;
                    trail.interpolate(system, tt, width, false, no_scale, &mut y);
                    event
                        .value(hit.event, tt, &y)
                        .map_err(|e| AdvanceError::Other(e, true))
                })?,
                None => hit.b.0,
            };
            let point = self.between(te, &mut cost)?;
            add_cost_into(&mut chunk.cost, &cost);
            chunk.hits.push((hit.event, point));
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
            interp: 0.0,
        };
        if collect.every_step {
            chunk.outputs.push(p.clone());
        }
        if collect.grid {
            chunk.grid.push((t0, self.y[0].clone(), self.y[1].clone()));
        }
        if let Some(trail) = self.trail.as_mut() {
            if trail.points.is_empty() {
                trail.push(t0, &self.y[0]);
            }
            trail.mark_meet(0.0, 0.0, &self.y[1]);
        }
        self.outputs_until(t0, false, false, Some(&p), chunk)
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
            let at_end = self.n >= self.grid.n_end;
            if collect.steps {
                chunk.steps.push((t, self.total, self.y[0].clone()));
            }
            if let Some(trail) = self.trail.as_mut() {
                trail.push(t, &self.y[0]);
            }

            // Events on the answer: a terminal one located at once between the last meeting
            // point and t, the others when the grid around them is known (on the interpolant).
            let mut stop: Option<Terminal> = None;
            let options: &'o Options = self.options;
            let events = &options.events;
            for (k, e) in events.iter().enumerate() {
                if !collect.events && !e.terminal {
                    continue;
                }
                let now = e
                    .value(k, t, &self.y[0])
                    .map_err(|e| AdvanceError::Other(e, true))?;
                let before = self.ev_prev[k];
                if e.counts(before, now) {
                    if e.terminal || self.trail.is_none() {
                        let te = e.locate((t_prev, before), (t, now), |tt| {
                            self.dense_fine(tt, &mut scratch, &mut chunk.cost)?;
                            e.value(k, tt, &scratch)
                                .map_err(|e| AdvanceError::Other(e, true))
                        })?;
                        if e.terminal {
                            if stop.is_none_or(|s| te < s.t) {
                                stop = Some(Terminal { event: k, t: te });
                            }
                        } else {
                            let point = self.dense_point(te, &mut chunk.cost)?;
                            chunk.hits.push((k, point));
                        }
                    } else {
                        self.pending.push(PendingHit {
                            event: k,
                            a: (t_prev, before),
                            b: (t, now),
                        });
                    }
                }
                self.ev_prev[k] = now;
            }
            if let Some(stop) = stop {
                // The run ends here: every zero before it, every output up to it.
                self.resolve_hits(true, chunk)?;
                chunk.hits.retain(|(_, p)| p.t <= stop.t);
                let point = if (stop.t - t).abs() <= self.same_time && !self.check {
                    Point {
                        t: stop.t,
                        y: self.y[0].clone(),
                        diff: 0.0,
                        noise: 0.0,
                        interp: 0.0,
                    }
                } else {
                    self.dense_point(stop.t, &mut chunk.cost)?
                };
                chunk.hits.push((stop.event, point.clone()));
                self.outputs_until(stop.t, true, true, None, chunk)?;
                if collect.every_step {
                    chunk.outputs.push(point);
                }
                chunk.terminal = Some(stop);
                return Ok(());
            }
            if self.check && self.n % 3 == 0 {
                let rep = self.step(2, 3, self.n - 3)?;
                chunk.cost.check(&rep);
                let rep = self.step(3, 3, self.n - 3)?;
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
                if self.n % MEET == 0 {
                    // The amplified rounding, where the 3h runs meet the answer.
                    self.sensitivity = self.options.scaled(
                        self.y[3].iter().zip(&self.y[2]).map(|(a, b)| a - b),
                        &self.y[0],
                    );
                }
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
                if let Some(trail) = self.trail.as_mut() {
                    trail.mark_meet(diff, noise, &self.y[1]);
                }
                Point {
                    t,
                    y: self.y[0].clone(),
                    diff,
                    noise,
                    interp: 0.0,
                }
            } else {
                Point {
                    t,
                    y: self.y[0].clone(),
                    diff: 0.0,
                    noise: 0.0,
                    interp: 0.0,
                }
            };
            if collect.t_eval {
                self.outputs_until(t, false, at_end, Some(&point), chunk)?;
            }
            self.resolve_hits(at_end, chunk)?;
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

/// `to += c`.
fn add_cost_into(to: &mut Cost, c: &Cost) {
    super::kept::add_cost(to, c);
}

/// y ← y + dt·(Ay + g(y)): the state moved along the vector field by a time `dt` of the order of
/// the rounding of time (the error, O(dt²), is far below ε).
pub(super) fn drift<S: System>(system: &S, y: &mut [f64], dt: f64) -> Result<()> {
    let d = y.len();
    let mut f = vec![0.0; d];
    let mut g = vec![0.0; d];
    let mut scratch = vec![0.0; system.scratch_len()];
    system.linear().apply(y, &mut f);
    system.nonlinear(y, &mut g, &mut scratch);
    for ((v, a), b) in y.iter_mut().zip(&f).zip(&g) {
        let dy = dt * (a + b);
        if !dy.is_finite() {
            return Err(Error::NonFinite("the vector field at the end of the span"));
        }
        *v += dy;
    }
    Ok(())
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
