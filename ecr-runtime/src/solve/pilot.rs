//! The pilot of a solve: the order and the first step size, from a few steps from t₀ of both
//! runs for each order tried.

use super::runs::{Cost, Make};
use super::solution::Stats;
use super::window::{Ctx, P_BOLD, TARGET, advance, check_order, resolution};
use crate::error::Result;

/// Steps of a pilot window.
pub(super) const PILOT_STEPS: usize = 8;

/// A pilot round raises the step by at most this factor.
const UP_ROUND: f64 = 2.0;

/// A step predicted between the largest step measured within the target and the smallest
/// beyond it stays this factor inside them.
const BRACKET_IN: f64 = 1.1;

/// The bracket is narrow enough at this ratio.
const BRACKET_DONE: f64 = 1.3;

/// Pilot rounds per order (each rescales the step from the growth it saw).
pub(super) const PILOT_ROUNDS: usize = 4;

/// The pilot stops (rounds and orders) once it has spent this share of what the run it
/// projects will cost, keeping the best measured step: on a short problem a tour of the orders
/// costs more than a neighbouring order would save.
const PILOT_SHARE: f64 = 0.08;

/// The first order tried for a tolerance: one more r per two and a half decades.
pub(super) fn first_order(ctx: &Ctx<'_>, lo: usize, hi: usize) -> usize {
    let tol = ctx
        .options
        .rtol
        .min(ctx.options.atol)
        .max(ctx.options.rtol.max(ctx.options.atol) * 1e-3);
    let guess = 3.0 + (-tol.max(1e-300).log10() / 2.5).round();
    (guess.max(2.0) as usize).clamp(lo, hi)
}

/// The order and the first step size: for each order tried, a few steps from t₀ whose estimate
/// growth, projected over the span, says the step that meets the target; the order of least
/// cost per unit time wins. Orders are tried from the first guess up while the cost falls,
/// then down.
pub(super) fn pilot(
    ctx: &Ctx<'_>,
    make: &mut Make<'_, '_>,
    lo: usize,
    hi: usize,
    stats: &mut Stats,
) -> Result<(usize, f64)> {
    let span = ctx.t_end - ctx.t0;
    let max_step = ctx.options.max_step.min(span);
    let first = first_order(ctx, lo, hi);
    let mut h = (span / 8.0 / PILOT_STEPS as f64).min(max_step);
    let mut tried: Vec<(usize, f64, f64)> = Vec::new();
    let mut measure = |r: usize, h0: f64, stats: &mut Stats| -> Result<(f64, f64, bool)> {
        let p = check_order(r);
        let mut h = h0;
        let mut runs = make(r, true, h)?;
        let (mut per_step, mut seen) = (0.0, 0.0_f64);
        let (mut good, mut bad) = (0.0_f64, f64::INFINITY);
        for round in 0..PILOT_ROUNDS {
            runs.set_step_size(h)?;
            let window = (span / 8.0).min(PILOT_STEPS as f64 * h);
            let steps = ((window / h).ceil() as usize).max(1);
            let mut cost = Cost::default();
            let result = advance(
                ctx,
                &mut *runs,
                &ctx.start(),
                (ctx.t0, 0.0, 0),
                (steps, None),
                None,
                &mut cost,
            );
            stats.pilot(&cost);
            let points = match result {
                Ok(points) => points,
                Err(f) => {
                    ctx.options.say(|| {
                        format!(
                            "pilot EC{r}P h = {h:.3e}: a step failed at t = {:?} ({})",
                            f.t, f.error
                        )
                    });
                    h /= 4.0;
                    if h < resolution(ctx.t0.abs().max(ctx.t_end.abs())) {
                        return Err(f.error);
                    }
                    continue;
                }
            };
            per_step = cost.total_g_evals() as f64 / steps as f64;
            let duration = steps as f64 * h;
            let growth = points.iter().map(|q| q.est).fold(0.0, f64::max);
            seen = seen.max(growth);
            // The growth of the pilot's second half, per unit time, projected over the span
            // from where the pilot ends: the first steps make the difference of the two runs
            // from nothing, which the later ones do not repeat.
            let half = points.len() / 2;
            let early = points[..half].iter().map(|q| q.est).fold(0.0, f64::max);
            let late = if half > 0 {
                (growth - early) / (duration / 2.0)
            } else {
                growth / duration
            };
            let projected = growth + late.max(0.0) * (span - duration).max(0.0);
            let (rate, wanted) = (projected / span, TARGET / span);
            // A bracket: the largest step measured within the target and the smallest beyond it.
            // Far from the asymptotic regime the estimate does not grow like h^p, and a large
            // step can cross a cliff where the check no longer follows g (Duffing ω = 20 at
            // EC7P: 1e−5 per unit time at hω = 2.4, 5 at hω = 4.7); so the step returned is one
            // that was measured, and the next one is predicted inside the bracket.
            if rate <= wanted {
                good = good.max(h);
            } else {
                bad = bad.min(h);
            }
            let predicted = if rate > 0.0 {
                h * (wanted / rate).powf(1.0 / p.min(P_BOLD))
            } else {
                h * UP_ROUND
            };
            let top = max_step.min(span / 8.0 / PILOT_STEPS as f64);
            let next = if good == 0.0 {
                predicted.clamp(h / 16.0, h / 2.0)
            } else if bad.is_infinite() {
                predicted.clamp(h, h * UP_ROUND).min(top)
            } else if bad / good > BRACKET_IN * BRACKET_IN {
                // Inside the bracket: the prediction, kept away from its ends.
                predicted.clamp(good * BRACKET_IN, bad / BRACKET_IN)
            } else {
                (good * bad).sqrt()
            };
            ctx.options.say(|| {
                format!(
                    "pilot EC{r}P round {round}: h = {h:.4e}, {steps} steps, estimate {growth:.3e} → h = {next:.4e}"
                )
            });
            let closed = good > 0.0 && (bad / good <= BRACKET_DONE || good >= top);
            // The run this pilot projects, both runs over the span at the best step measured.
            let spent = stats.pilot_g_evals as f64;
            let over_budget = good > 0.0 && spent > PILOT_SHARE * per_step * span / good;
            if closed || next == h || over_budget {
                break;
            }
            h = next;
        }
        let h = if good > 0.0 { good } else { h };
        // An estimate far below the target over the pilot says nothing of how the orders
        // compare (nothing happens there yet, or only rounding shows).
        let informative = seen > 1e-3 * TARGET;
        Ok((h, per_step / h, informative))
    };
    let (h0, c0, informative) = measure(first, h, stats)?;
    tried.push((first, h0, c0));
    if !informative {
        ctx.options
            .say(|| format!("pilot: the estimate says nothing yet → EC{first}P, h = {h0:.4e}"));
        return Ok((first, h0));
    }
    h = h0;
    // Up while the cost per unit time falls, then down.
    for dir in [1isize, -1] {
        let mut r = first;
        let mut best = c0;
        loop {
            let next = r as isize + dir;
            if next < lo as isize || next > hi as isize {
                break;
            }
            r = next as usize;
            if stats.pilot_g_evals as f64 > PILOT_SHARE * best * span {
                break;
            }
            let (hr, cr, _) = measure(r, h, stats)?;
            tried.push((r, hr, cr));
            if cr >= best {
                break;
            }
            best = cr;
            h = hr;
        }
        if tried.iter().any(|t| t.0 > first && t.2 < c0) {
            break;
        }
    }
    let &(r, h, _) = tried
        .iter()
        .min_by(|a, b| a.2.total_cmp(&b.2))
        .expect("one order was tried");
    ctx.options.say(|| {
        let list: Vec<String> = tried
            .iter()
            .map(|t| format!("r = {} h = {:.3e} cost {:.3e}", t.0, t.1, t.2))
            .collect();
        format!("pilot: {} → EC{r}P, h = {h:.4e}", list.join("; "))
    });
    Ok((r, h))
}
