//! The pilot of a solve: the order and the first step size, from a few steps from t₀ of both
//! runs for each order tried.

use super::runs::{Cost, Make};
use super::solution::Stats;
use super::window::{Ctx, P_BOLD, TARGET, advance, check_order, resolution};
use crate::error::Result;

/// Steps of a pilot window.
pub(super) const PILOT_STEPS: usize = 8;

/// Pilot rounds per order (each rescales the step from the growth it saw).
pub(super) const PILOT_ROUNDS: usize = 4;

/// The first order tried for a tolerance: one more r per two and a half decades.
pub(super) fn first_order(ctx: &Ctx<'_>, lo: usize, hi: usize) -> usize {
    let tol = ctx
        .options
        .rtol
        .min(ctx.options.atol)
        .max(ctx.options.rtol.max(ctx.options.atol) * 1e-3);
    let guess = 2.0 + (-tol.max(1e-300).log10() / 2.5).round();
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
        for round in 0..PILOT_ROUNDS {
            runs.set_step_size(h)?;
            let window = (span / 8.0).min(PILOT_STEPS as f64 * h);
            let steps = ((window / h).ceil() as usize).max(1);
            let mut cost = Cost::default();
            let result = advance(
                ctx,
                &mut *runs,
                &ctx.start(),
                (ctx.t0, 0),
                steps,
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
            let rate = growth / duration;
            let wanted = TARGET / span;
            // At most PILOT_STEPS steps of the pilot fit in 1/8 of the span: a step beyond that is
            // not measured by enough steps.
            let next = if rate > 0.0 {
                (h * (wanted / rate).powf(1.0 / p.min(P_BOLD))).clamp(h / 16.0, h * 4.0)
            } else {
                h * 4.0
            }
            .min(max_step)
            .min(span / 8.0 / PILOT_STEPS as f64);
            ctx.options.say(|| {
                format!(
                    "pilot EC{r}P round {round}: h = {h:.4e}, {steps} steps, estimate {growth:.3e} → h = {next:.4e}"
                )
            });
            let settled = next <= 3.0 * h && next >= h / 3.0;
            h = next;
            if settled {
                break;
            }
        }
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
