//! The pilots: a few steps of the three runs from t₀ for a few orders, to choose r and the
//! first step size.

use super::Problem;
use super::estimate::{TARGET, divisor, estimate, rescale};
use super::grid::{fit_grid, quantum};
use super::options::Options;
use super::run::{Collect, MEET, Runs, StepFailure};
use super::solution::Stats;
use crate::error::{Error, Result};
use crate::system::System;

/// Blocks of [`MEET`] steps in a pilot's window.
const PILOT_BLOCKS: usize = 2;

/// The pilots of further orders stop once they have cost this share of the predicted run.
const PILOT_BUDGET: f64 = 0.1;

/// What the pilot of one order found.
#[derive(Clone, Copy, Debug)]
pub(super) struct Pilot {
    pub(super) r: usize,
    /// The step size predicted to give [`TARGET`] at the end of the span.
    pub(super) h: f64,
    /// Predicted evaluations of g of the run.
    pub(super) cost: f64,
    /// The order the differences showed (r, half the nominal, where they were at round-off).
    pub(super) order: f64,
}

impl<S: System> Problem<S> {
    /// The first order tried for a tolerance: about one more r per two decades, r = 4 at
    /// 1e−6, r = 6 at 1e−10, within the allowed orders.
    pub(super) fn first_order(&self, options: &Options) -> usize {
        let tol = options.rtol.max(options.atol).max(1e-16);
        let guess = (1.0 - tol.log10() / 2.0).round() as usize;
        guess.clamp(*options.orders.start(), *options.orders.end())
    }

    /// Pilots from the first order up, and down, while the predicted cost falls.
    pub(super) fn pilot_auto(&self, options: &Options, stats: &mut Stats) -> Result<Pilot> {
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

    /// The step the run will take for a step `h` allows: with evenly spaced output times
    /// every one is a meeting point of the runs, so at most a sixth of their spacing (where
    /// that binds, a lower order costs less for the same step).
    fn grid_step(&self, options: &Options, h: f64) -> f64 {
        let q = quantum(options.t_eval.as_deref(), self.t0, self.t_end);
        fit_grid(h, self.t0, self.t_end, q, usize::MAX).map_or(h, |g| g.h)
    }

    /// The pilot of one order: the three runs over a window of [`PILOT_BLOCKS`] blocks of
    /// [`MEET`] steps from t₀ (up to a terminal event). Starting from `h_start` (or 1/64 of the
    /// span), the step grows while the runs agree to round-off, then halves until they show
    /// an order of at least r (half the nominal 2r); the estimate is projected to the end of
    /// the span by its growth over the window, and h scaled to [`TARGET`] (at most twice the
    /// step at which the law was seen).
    pub(super) fn pilot(
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
        // The largest step any level's estimate allows: a finer level over a shorter window
        // does not see what a coarser one over a longer window saw.
        let mut h_cap = f64::INFINITY;
        for _ in 0..60 {
            let window = (blocks * h).min(span);
            let grid = fit_grid(h, self.t0, self.t0 + window, None, usize::MAX)?;
            if h < span * 1e-12 {
                break;
            }
            let mut runs = Runs::new(
                system,
                options,
                r,
                true,
                &self.y0,
                grid,
                self.same_time(),
                1.0,
            )?;
            let chunk = match runs.advance(grid.n_end, collect) {
                Ok(c) => c,
                Err((f, _)) if f.fatal => return Err(f.error),
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
                let h_run = (4.0 * grid.h).min(span_eff / 4.0).min(h_cap);
                return Ok(Pilot {
                    r,
                    h: h_run,
                    cost: g_per_step * span_eff / self.grid_step(options, h_run),
                    order: order.unwrap_or(0.5 * p),
                });
            }
            let q = order.unwrap_or(p);
            // Growth over the window, as a power of time: from a plateau (a damped problem)
            // to linear (the phase error of a conservative one); the run checks the rest.
            let alpha = if e_half > 0.0 {
                (e_w / e_half).log2().clamp(0.25, 1.0)
            } else {
                1.0
            };
            let predicted = e_w * (span_eff / (end - self.t0)).powf(alpha);
            // The law is trusted up to twice the step at which it was seen.
            let law = rescale(grid.h, TARGET / predicted, q.max(0.5 * p));
            h_cap = h_cap.min(law);
            if q < 0.5 * p {
                // Not yet in the asymptotic regime.
                refined = true;
                h /= 2.0;
                continue;
            }
            let h_run = law.min(2.0 * grid.h).min(span_eff / 4.0).min(h_cap);
            if trace {
                eprintln!(
                    "solve: pilot EC{r}P: alpha {alpha:.2}, predicted {predicted:.3e}, h_run {h_run:.4e}, g/step {g_per_step:.2}"
                );
            }
            return Ok(Pilot {
                r,
                h: h_run,
                cost: g_per_step * span_eff / self.grid_step(options, h_run),
                order: q,
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
}
