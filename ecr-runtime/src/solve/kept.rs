//! What is kept of a run: its outputs with their estimates, the observer's steps, what it
//! cost; and the solution put together from it.

use std::ops::ControlFlow;

use super::Problem;
use super::estimate::estimate;
use super::options::Options;
use super::run::{Chunk, Cost, Point};
use super::solution::{DenseData, Segment, Solution, Stats, Status, StepView};
use crate::error::{Error, Result};
use crate::operator::LinearOperator;
use crate::storage::format_bytes;
use crate::system::System;

/// What has been kept of the current run: outputs and hits with their estimates, grid
/// states, the observer's steps not yet shown, and what the kept chunks cost.
#[derive(Default)]
pub(super) struct Kept {
    pub(super) outputs: Vec<(Point, f64)>,
    pub(super) hits: Vec<(usize, Point, f64)>,
    pub(super) grid: Vec<(f64, Vec<f64>, Vec<f64>)>,
    /// The answer's steps not yet shown to the observer: (t, step, h, state).
    pub(super) unshown: Vec<(f64, usize, f64, Vec<f64>)>,
    pub(super) cost: Cost,
    pub(super) segments: Vec<Segment>,
    pub(super) status: Option<Status>,
}

impl Kept {
    pub(super) fn new(t0: f64, h: f64) -> Self {
        Kept {
            segments: vec![Segment { t: t0, h }],
            ..Kept::default()
        }
    }

    /// Keeps a chunk with its estimates (`div`: the Richardson divisor; `None` for a fixed
    /// method, estimates 0). `Err` if its storage cannot be allocated.
    pub(super) fn keep(&mut self, chunk: Chunk, div: Option<f64>, h: f64) -> Result<()> {
        let est = |p: &Point| div.map_or(0.0, |div| estimate(p.diff, p.noise, div) + p.interp);
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
    pub(super) fn show(&mut self, observer: &mut Observer<'_>) {
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

    pub(super) fn ended(&self) -> bool {
        self.status.is_some()
    }
}

pub(super) fn add_cost(to: &mut Cost, c: &Cost) {
    to.steps += c.steps;
    to.g_evals += c.g_evals;
    to.sweeps += c.sweeps;
    to.check_steps += c.check_steps;
    to.check_g_evals += c.check_g_evals;
    to.dense_steps += c.dense_steps;
    to.dense_g_evals += c.dense_g_evals;
}

/// Work that was done and thrown away (a chunk over the tolerance, a run started again).
pub(super) fn discard(stats: &mut Stats, c: &Cost) {
    stats.discarded_steps += c.total_steps();
    stats.discarded_g_evals += c.total_g_evals();
}

/// The kept run's cost into the statistics.
pub(super) fn finish(stats: &mut Stats, c: &Cost) {
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

/// `Err` naming the size if the output of a run cannot be stored: `outputs` output states,
/// `grid` grid points kept for dense output (three states each: the answer, the 2h run and the
/// derivative), `observed` states held for the
/// observer at once, of `d` numbers each (and what each entry costs besides: its vectors'
/// headers and the allocator's, its time, energy and estimate). Checked before the run, so
/// that it fails with this error rather than aborting on an allocation midway.
pub(super) fn ensure_output_fits(
    d: usize,
    outputs: usize,
    grid: usize,
    observed: usize,
) -> Result<()> {
    let per_state = d.saturating_add(9);
    let entries = outputs
        .saturating_add(grid.saturating_mul(3))
        .saturating_add(observed)
        .checked_mul(per_state);
    crate::storage::ensure_allocatable(
        &format!(
            "the solution's output ({outputs} states of {d} numbers{}{})",
            if grid > 0 {
                format!(", {grid} grid points for dense output")
            } else {
                String::new()
            },
            if observed > 0 {
                format!(", {observed} steps held for the observer")
            } else {
                String::new()
            }
        ),
        entries,
    )
}

/// The observer of a solve, if any.
pub(super) type Observer<'f> = Option<&'f mut dyn FnMut(&StepView<'_>) -> ControlFlow<()>>;

impl<S: System> Problem<S> {
    /// The solution from what was kept.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn assemble(
        &self,
        options: &Options,
        kept: Kept,
        mut stats: Stats,
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
        // Nothing kept, nothing estimated: `None`, not a zero that reads as exact.
        let error_estimate = (verified && !(es.is_empty() && events.is_empty()))
            .then(|| es.iter().copied().fold(event_worst, f64::max));
        let dense = options.dense.then(|| {
            let d = self.y0.len();
            let (mut gt, mut gh, mut fine, mut coarse) =
                (Vec::new(), Vec::new(), Vec::new(), Vec::new());
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
            // For a verified solve: each grid point's derivative (for the Hermite interpolant
            // of `Solution::at`) and its estimate (the scaled difference to the 2h run).
            let (mut deriv, mut grid_est) = (Vec::new(), Vec::new());
            if let (true, Some(div)) = (verified, div) {
                let system = &*self.system;
                let (mut f, mut g) = (vec![0.0; d], vec![0.0; d]);
                let mut scratch = vec![0.0; system.scratch_len()];
                for (_, y, c) in &kept.grid {
                    system.linear().apply(y, &mut f);
                    system.nonlinear(y, &mut g, &mut scratch);
                    // Counted with the output between grid points, which they serve.
                    stats.dense_g_evals += 1;
                    deriv.extend(f.iter().zip(&g).map(|(a, b)| a + b));
                    let e = options.scaled(y.iter().zip(c.iter()).map(|(a, b)| (a - b) / div), y);
                    grid_est.push(e);
                }
            }
            DenseData {
                deriv,
                grid_est,
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
