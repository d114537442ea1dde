//! The pilots: a few steps of the three runs from t₀ for a few orders, to choose r and the
//! first step size.

use std::sync::Arc;

use super::estimate::{TARGET, divisor, estimate, rescale};
use super::grid::{fit_grid, quantum};
use super::options::Options;
use super::run::{Collect, MEET, Runs, StepFailure};
use super::solution::Stats;
use super::{Problem, SolveCache};
use crate::error::{Error, Result};
use crate::system::System;

/// Blocks of [`MEET`] steps in a pilot's window.
const PILOT_BLOCKS: usize = 2;

/// How far beyond the step of a confirmed level the pilot trusts the step-size law: the check
/// needs its 3h run in the asymptotic regime, which the level showed for its own step only.
const PILOT_REACH: f64 = 1.25;

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
    /// The step at which they showed it.
    pub(super) h_order: f64,
}

/// What one pilot level saw.
#[derive(Clone, Copy, Debug)]
struct Level {
    h: f64,
    /// The largest estimate over the window and over its first half.
    e_w: f64,
    e_half: f64,
    /// The order the differences showed.
    q: f64,
    /// The growth of the estimate from the end of the window to the end of the span.
    growth: f64,
    span_eff: f64,
    g_per_step: f64,
}

/// The largest step the non-asymptotic levels allow with order q: each level's difference
/// projected to the end of the span, divided by the Richardson divisor of q, scaled to
/// [`TARGET`] by the step-size law.
fn caps(coarse: &[(f64, f64)], q: f64, _span: f64) -> f64 {
    coarse
        .iter()
        .map(|&(h, diff)| {
            rescale(
                h,
                TARGET / (diff / divisor(Some(q))).max(f64::MIN_POSITIVE),
                q,
            )
        })
        .fold(f64::INFINITY, f64::min)
}

impl<S: System> Problem<S> {
    /// The pilot's answer from a confirmed level: the step-size law to [`TARGET`] at the end of
    /// the span with order q, trusted up to twice the level's step, capped by what the coarser
    /// levels saw.
    fn pilot_from(
        &self,
        options: &Options,
        r: usize,
        p: f64,
        c: &Level,
        q: f64,
        coarse: &[(f64, f64)],
    ) -> Pilot {
        let predicted = c.e_w * c.growth;
        let law = rescale(
            c.h,
            TARGET / predicted.max(f64::MIN_POSITIVE),
            q.max(0.5 * p),
        );
        let h_run = law.min(PILOT_REACH * c.h).min(c.span_eff / 4.0).min(caps(
            coarse,
            q.max(0.5 * p),
            c.span_eff,
        ));
        options.say(|| {
            format!(
                "solve: pilot EC{r}P: confirmed h = {:.4e} (order {q:.2}), predicted {predicted:.3e}, h_run {h_run:.4e}, g/step {:.2}",
                c.h, c.g_per_step
            )
        });
        Pilot {
            r,
            h: h_run,
            cost: c.g_per_step * c.span_eff / self.grid_step(options, h_run),
            order: q,
            h_order: c.h,
        }
    }

    /// The first order tried for a tolerance: about one more r per two decades, r = 4 at
    /// 1e−6, r = 6 at 1e−10, within the allowed orders.
    pub(super) fn first_order(&self, options: &Options) -> usize {
        let tol = options.rtol.max(options.atol).max(1e-16);
        let guess = (1.0 - tol.log10() / 2.0).round() as usize;
        guess.clamp(*options.orders.start(), *options.orders.end())
    }

    /// Pilots from the first order up, and down, while the predicted cost falls.
    pub(super) fn pilot_auto(
        &self,
        options: &Options,
        stats: &mut Stats,
        cache: &Arc<SolveCache<S>>,
    ) -> Result<Pilot> {
        let first = self.first_order(options);
        let mut best = self.pilot(options, first, None, stats, cache)?;
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
                let Ok(p) = self.pilot(options, next, Some(h_from), stats, cache) else {
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
        cache: &Arc<SolveCache<S>>,
    ) -> Result<Pilot> {
        let span = self.t_end - self.t0;
        let p = (2 * r) as f64;
        let system = &*self.system;
        let blocks = (PILOT_BLOCKS * MEET) as f64;
        let mut h = h_start.unwrap_or(span / 64.0).min(span / blocks);
        let collect = Collect {
            every_step: false,
            steps: false,
            grid: false,
            events: false,
            t_eval: false,
        };
        let (mut grown, mut refined) = (0, false);
        let mut last_failure: Option<StepFailure> = None;
        // Levels whose differences showed no asymptotic order: (step, the largest difference
        // projected to the end of the span). Once the order is known, each caps the step: a
        // finer level over a shorter window does not see what a coarser one over a longer
        // window saw.
        let mut coarse: Vec<(f64, f64)> = Vec::new();
        // An asymptotic level waiting for the next finer one to confirm it: a short window at
        // a large step can show a clean order by chance (the steps alias an oscillation).
        let mut candidate: Option<Level> = None;
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
                cache,
            )?;
            let chunk = match runs.advance(grid.n_end, collect) {
                Ok(c) => c,
                Err((f, _)) if f.fatal => return Err(f.error),
                Err((f, cost)) => {
                    stats.pilot_steps += cost.total_steps();
                    stats.pilot_g_evals += cost.total_g_evals();
                    last_failure = Some(f);
                    refined = true;
                    candidate = None;
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
            // The work of a step of the answer, in evaluations of g (see `work_per_g_eval`).
            let g_per_step =
                chunk.cost.g_evals as f64 / chunk.cost.steps.max(1) as f64 * runs.work_per_g_eval();
            let at_noise = e_w <= 2.0 * noise || order.is_none();
            options.say(|| format!(
                    "solve: pilot EC{r}P h = {:.4e}: window estimate {e_w:.3e} (half {e_half:.3e}), noise {noise:.3e}, order {order:?}",
                    grid.h
                ));
            // Growth over the window, as a power of time: from a plateau (a damped problem)
            // to linear (the phase error of a conservative one); the run checks the rest.
            let alpha = if e_half > 0.0 {
                (e_w / e_half).log2().clamp(0.25, 1.0)
            } else {
                1.0
            };
            let growth = (span_eff / (end - self.t0)).powf(alpha);
            let level = Level {
                h: grid.h,
                e_w,
                e_half,
                q: order.unwrap_or(p),
                growth,
                span_eff,
                g_per_step,
            };
            if at_noise {
                if let Some(c) = candidate.take() {
                    // The finer level agrees to round-off: the candidate is confirmed if its
                    // estimate at the same time, scaled by the order, is at that level too.
                    if c.e_half / 2f64.powf(c.q) <= 8.0 * noise.max(e_w) {
                        return Ok(self.pilot_from(options, r, p, &c, c.q, &coarse));
                    }
                    coarse.push((c.h, c.e_w * divisor(Some(c.q)) * c.growth));
                }
                if !refined && grown < 4 && window < span / 4.0 {
                    // The runs agree to round-off: the step can be larger.
                    h *= 4.0;
                    grown += 1;
                    continue;
                }
                let q = order.unwrap_or(0.5 * p);
                let caps = caps(&coarse, p.max(q), span_eff);
                let h_run = (4.0 * grid.h).min(span_eff / 4.0).min(caps);
                return Ok(Pilot {
                    r,
                    h: h_run,
                    cost: g_per_step * span_eff / self.grid_step(options, h_run),
                    order: q,
                    h_order: grid.h,
                });
            }
            if level.q < 0.5 * p {
                // Not in the asymptotic regime (nor was a candidate before it, if it
                // disagrees).
                if let Some(c) = candidate.take() {
                    coarse.push((c.h, c.e_w * divisor(Some(c.q)) * c.growth));
                }
                coarse.push((level.h, e_w * div * growth));
                refined = true;
                h /= 2.0;
                continue;
            }
            match candidate.take() {
                Some(c) => {
                    // Consistent: the coarser level's estimate at the end of this window
                    // (its half window) is this one's times 2^q, within a factor 16.
                    let q = c.q.min(level.q);
                    let ratio = c.e_half / e_w;
                    let expected = 2f64.powf(q);
                    if ratio >= expected / 16.0 && ratio <= expected * 16.0 {
                        return Ok(self.pilot_from(options, r, p, &c, q, &coarse));
                    }
                    coarse.push((c.h, c.e_w * divisor(Some(c.q)) * c.growth));
                    candidate = Some(level);
                }
                None => candidate = Some(level),
            }
            refined = true;
            h /= 2.0;
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
