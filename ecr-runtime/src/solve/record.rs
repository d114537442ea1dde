//! What a run keeps: its outputs with their estimates, the located events, the grid for
//! [`Solution::at`](super::Solution::at), the observer's steps not yet shown, the step sizes
//! and what it cost; and the solution put together from it.

use std::ops::ControlFlow;
use std::sync::Arc;

use super::events::EventHit;
use super::options::Options;
use super::runs::Cost;
use super::solution::{DenseData, Segment, Solution, Stats, Status, StepView};
use crate::error::{Error, Result};
use crate::storage::format_bytes;

/// The observer of a solve, if any.
pub(super) type Observer<'f> = Option<&'f mut dyn FnMut(&StepView<'_>) -> ControlFlow<()>>;

/// A value the solve returns at a time (an output or an event), with its estimate in units of
/// the tolerance (0 for a fixed method).
#[derive(Clone, Debug)]
pub(super) struct Point {
    pub(super) t: f64,
    pub(super) y: Vec<f64>,
    pub(super) est: f64,
}

/// What a run has kept so far.
#[derive(Default)]
pub(super) struct Record {
    pub(super) outputs: Vec<Point>,
    pub(super) hits: Vec<(usize, Point)>,
    /// For dense output: the grid times and the answer's and the check's states there (flat).
    pub(super) grid_t: Vec<f64>,
    pub(super) grid_answer: Vec<f64>,
    pub(super) grid_check: Vec<f64>,
    /// The answer's steps not yet shown to the observer: (t, step number, h, state).
    pub(super) unshown: Vec<(f64, usize, f64, Vec<f64>)>,
    /// Whether the observer has seen a step (the run can no longer be started again then).
    pub(super) shown: bool,
    pub(super) segments: Vec<Segment>,
    pub(super) status: Option<Status>,
    pub(super) cost: Cost,
}

/// Where a record stood, to go back to if what was added after is not kept.
#[derive(Clone, Copy, Debug)]
pub(super) struct Mark {
    outputs: usize,
    hits: usize,
    grid: usize,
    unshown: usize,
    cost: Cost,
}

impl Mark {
    /// The record's cost at the mark.
    pub(super) fn cost(&self) -> Cost {
        self.cost
    }
}

impl Record {
    pub(super) fn mark(&self) -> Mark {
        Mark {
            outputs: self.outputs.len(),
            hits: self.hits.len(),
            grid: self.grid_t.len(),
            unshown: self.unshown.len(),
            cost: self.cost,
        }
    }

    /// Back to `mark`: what was added since is dropped, the status cleared (the cost of the
    /// dropped work is the caller's to count as discarded).
    pub(super) fn rollback(&mut self, mark: Mark) {
        let d = self
            .grid_answer
            .len()
            .checked_div(self.grid_t.len())
            .unwrap_or(0);
        self.outputs.truncate(mark.outputs);
        self.hits.truncate(mark.hits);
        self.grid_t.truncate(mark.grid);
        self.grid_answer.truncate(mark.grid * d);
        self.grid_check.truncate(mark.grid * d);
        self.unshown.truncate(mark.unshown);
        self.cost = mark.cost;
        self.status = None;
    }

    pub(super) fn new(t0: f64, h: f64) -> Self {
        Record {
            segments: vec![Segment { t: t0, h }],
            ..Record::default()
        }
    }

    /// Notes that the steps from `t` on have size `h`.
    pub(super) fn step_size_from(&mut self, t: f64, h: f64) {
        match self.segments.last_mut() {
            Some(s) if s.h == h => {}
            Some(s) if s.t == t => s.h = h,
            _ => self.segments.push(Segment { t, h }),
        }
    }

    /// Keeps an output.
    ///
    /// # Errors
    /// If its storage cannot be allocated (naming the size).
    pub(super) fn output(&mut self, p: Point) -> Result<()> {
        reserve(&mut self.outputs, 1, p.y.len())?;
        self.outputs.push(p);
        Ok(())
    }

    /// Keeps a grid point for dense output.
    ///
    /// # Errors
    /// If its storage cannot be allocated.
    pub(super) fn grid(&mut self, t: f64, answer: &[f64], check: &[f64]) -> Result<()> {
        reserve(&mut self.grid_t, 1, 2 * answer.len())?;
        self.grid_t.push(t);
        self.grid_answer.extend_from_slice(answer);
        self.grid_check.extend_from_slice(check);
        Ok(())
    }

    /// Holds a step of the answer for the observer.
    pub(super) fn step_for_observer(&mut self, t: f64, step: usize, h: f64, y: &[f64]) {
        self.unshown.push((t, step, h, y.to_vec()));
    }

    /// Shows the held steps to the observer; a `Break` stops the run there: what lies beyond
    /// that step is dropped and the status says where it stopped.
    pub(super) fn show(&mut self, observer: &mut Observer<'_>) {
        let Some(obs) = observer.as_mut() else {
            self.unshown.clear();
            return;
        };
        let mut stop = None;
        for (t, step, h, y) in self.unshown.drain(..) {
            self.shown = true;
            if obs(&StepView { t, y: &y, step, h }).is_break() {
                stop = Some(t);
                break;
            }
        }
        self.unshown.clear();
        if let Some(t) = stop {
            self.stop_at(t, Status::Stopped { t });
        }
    }

    /// Ends the record at `t` with `status`: what lies beyond is dropped.
    pub(super) fn stop_at(&mut self, t: f64, status: Status) {
        self.outputs.retain(|p| p.t <= t);
        self.hits.retain(|(_, p)| p.t <= t);
        let keep = self.grid_t.partition_point(|&g| g <= t);
        let d = self
            .grid_answer
            .len()
            .checked_div(self.grid_t.len())
            .unwrap_or(0);
        self.grid_t.truncate(keep);
        self.grid_answer.truncate(keep * d);
        self.grid_check.truncate(keep * d);
        self.segments.retain(|s| s.t <= t);
        self.status = Some(status);
    }

    pub(super) fn ended(&self) -> bool {
        self.status.is_some()
    }

    /// The largest estimate of the outputs and the hits (0 if none).
    pub(super) fn worst(&self) -> f64 {
        self.outputs
            .iter()
            .map(|p| p.est)
            .chain(self.hits.iter().map(|(_, p)| p.est))
            .fold(0.0, |m, e| if e > m || e.is_nan() { e } else { m })
    }

    /// The solution: outputs, events, the grid for `at` (with the system), what it cost.
    pub(super) fn into_solution<S: crate::system::System>(
        self,
        options: &Options,
        system: &Arc<S>,
        y0: &[f64],
        verified: bool,
        r: usize,
        mut stats: Stats,
    ) -> Solution<S> {
        stats.steps += self.cost.steps;
        stats.g_evals += self.cost.g_evals;
        stats.sweeps += self.cost.sweeps;
        stats.check_steps += self.cost.check_steps;
        stats.check_g_evals += self.cost.check_g_evals;
        stats.dense_evals += self.cost.dense_steps;
        stats.dense_g_evals += self.cost.dense_g_evals;
        let energy0 = system.energy(y0);
        let worst = self.worst();
        let (mut t, mut y, mut est, mut energies) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for p in self.outputs {
            if energy0.is_some() {
                energies.push(system.energy(&p.y).unwrap_or(f64::NAN));
            }
            t.push(p.t);
            y.push(p.y);
            est.push(p.est);
        }
        let mut events: Vec<EventHit> = self
            .hits
            .into_iter()
            .map(|(event, p)| EventHit {
                event,
                t: p.t,
                y: p.y,
            })
            .collect();
        events.sort_by(|a, b| a.t.total_cmp(&b.t));
        // Nothing kept, nothing estimated: `None`, not a zero that reads as exact.
        let error_estimate = (verified && !(t.is_empty() && events.is_empty())).then_some(worst);
        let h = self.segments.last().map_or(0.0, |s| s.h);
        let dense = options.dense.then(|| DenseData {
            system: Arc::clone(system),
            r,
            settings: options.settings,
            tolerance: (options.rtol, options.atol),
            t: self.grid_t,
            answer: self.grid_answer,
            check: verified.then_some(self.grid_check),
            evals: std::cell::Cell::new((0, 0)),
            stiffness: std::cell::OnceCell::new(),
            slopes: std::cell::RefCell::default(),
        });
        Solution {
            t,
            y,
            energy: energy0.is_some().then_some(energies),
            error_estimates: if verified { est } else { Vec::new() },
            error_estimate,
            events,
            status: self.status.unwrap_or(Status::Completed),
            stats,
            r,
            s: r,
            h,
            segments: self.segments,
            energy0,
            dense,
        }
    }
}

/// `Err` naming the size if `n` more entries of `d` numbers each cannot be stored.
fn reserve<T>(v: &mut Vec<T>, n: usize, d: usize) -> Result<()> {
    if v.capacity() - v.len() >= n {
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

/// `Err` naming the size if the output of a run cannot be stored: `outputs` output states,
/// `grid` grid points kept for dense output (two states each: the answer and the check), of `d`
/// numbers each (and what each entry costs besides: its vector's header and the allocator's,
/// its time, energy and estimate). Checked before a run whose number of steps is known, so
/// that it fails with this error rather than aborting on an allocation midway.
pub(super) fn ensure_output_fits(d: usize, outputs: usize, grid: usize) -> Result<()> {
    let per_state = d.saturating_add(9);
    let entries = outputs
        .saturating_add(grid.saturating_mul(2))
        .checked_mul(per_state);
    crate::storage::ensure_allocatable(
        &format!(
            "the solution's output ({outputs} states of {d} numbers{})",
            if grid > 0 {
                format!(", {grid} grid points for dense output")
            } else {
                String::new()
            }
        ),
        entries,
    )
}

impl Stats {
    pub(super) fn discard(&mut self, c: &Cost) {
        self.discarded_steps += c.total_steps();
        self.discarded_g_evals += c.total_g_evals();
    }

    pub(super) fn pilot(&mut self, c: &Cost) {
        self.pilot_steps += c.total_steps();
        self.pilot_g_evals += c.total_g_evals();
    }
}

/// The cost the record gathered since `mark` (steps between grid points of a window that is not
/// kept).
pub(super) fn cost_since(record: &Record, mark: super::record::Mark) -> Cost {
    let mut c = record.cost;
    let m = mark.cost();
    c.steps -= m.steps;
    c.g_evals -= m.g_evals;
    c.sweeps -= m.sweeps;
    c.check_steps -= m.check_steps;
    c.check_g_evals -= m.check_g_evals;
    c.dense_steps -= m.dense_steps;
    c.dense_g_evals -= m.dense_g_evals;
    c
}
