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
    let mut tried: Vec<Tried> = Vec::new();
    let mut measure = |r: usize, h0: f64, stats: &mut Stats| -> Result<(Tried, bool)> {
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
                    // A step that fails above one measured within the target ends the rounds
                    // with that one: the steps below it would be measured again on the way up,
                    // and a step just below where the stage iteration fails at t₀ may fail
                    // later in the run.
                    if good > 0.0 {
                        break;
                    }
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
            // A step measured already (the best one) says nothing new.
            if closed || next == h || next == good || over_budget {
                break;
            }
            h = next;
        }
        let found = good > 0.0;
        let h = if found { good } else { h };
        // An estimate far below the target over the pilot says nothing of how the orders
        // compare (nothing happens there yet, or only rounding shows).
        let informative = seen > 1e-3 * TARGET;
        // An order whose rounds found no step within the target has a cost per unit time only
        // at a step never measured (the last prediction): it competes as infinitely dear
        // while another order found one ([`Tried`]).
        let cost = per_step / h;
        Ok((Tried { r, h, cost, found }, informative))
    };
    let (t0, informative) = measure(first, h, stats)?;
    let h0 = t0.h;
    tried.push(t0);
    if !informative {
        ctx.options
            .say(|| format!("pilot: the estimate says nothing yet → EC{first}P, h = {h0:.4e}"));
        return Ok((first, h0));
    }
    h = h0;
    let c0 = t0.rank();
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
            let (t, _) = measure(r, h, stats)?;
            tried.push(t);
            if t.rank() >= best {
                break;
            }
            best = t.rank();
            h = t.h;
        }
        if tried.iter().any(|t| t.r > first && t.rank() < c0) {
            break;
        }
    }
    let Tried { r, h, .. } = choose(&tried).expect("one order was tried");
    ctx.options.say(|| {
        let list: Vec<String> = tried
            .iter()
            .map(|t| {
                let how = if t.found {
                    ""
                } else {
                    " (no step within the target)"
                };
                format!("r = {} h = {:.3e} cost {:.3e}{how}", t.r, t.h, t.cost)
            })
            .collect();
        format!("pilot: {} → EC{r}P, h = {h:.4e}", list.join("; "))
    });
    Ok((r, h))
}

/// The order the pilot returns: the cheapest that found a step within the target; where none
/// did, the cheapest at its last prediction.
fn choose(tried: &[Tried]) -> Option<Tried> {
    let pick = |found: bool| {
        tried
            .iter()
            .filter(|t| t.found || !found)
            .min_by(|a, b| a.cost.total_cmp(&b.cost))
            .copied()
    };
    pick(true).or_else(|| pick(false))
}

/// An order the pilot tried: the step it returns, the cost per unit time there (evaluations of
/// g of both runs per unit time), and whether a round found that step within the target (else
/// it is the last prediction, never measured).
#[derive(Clone, Copy, Debug)]
struct Tried {
    r: usize,
    h: f64,
    cost: f64,
    found: bool,
}

impl Tried {
    /// The cost the orders are compared by: infinite where no step was found within the
    /// target (the step was never measured: at a first order whose rounds all missed, Duffing
    /// ω = 20 at 1e−3 chose EC4P at the unmeasured hω = 20, four times cheaper on paper than
    /// the orders that found their steps, and its run started again twice).
    fn rank(&self) -> f64 {
        if self.found { self.cost } else { f64::INFINITY }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tried(r: usize, cost: f64, found: bool) -> Tried {
        Tried {
            r,
            h: 1.0 / r as f64,
            cost,
            found,
        }
    }

    /// An order whose step was never measured within the target loses to every order whose
    /// step was, however cheap its last prediction looks, and wins only where no order found
    /// one (the case of Duffing ω = 20 at 1e−4: EC4P at 39.5 unmeasured against EC5P at 154).
    #[test]
    fn an_unmeasured_step_does_not_win_against_a_measured_one() {
        let list = [
            tried(4, 39.5, false),
            tried(5, 154.0, true),
            tried(3, 151.0, true),
        ];
        assert_eq!(choose(&list).map(|t| t.r), Some(3));
        let none = [tried(4, 39.5, false), tried(5, 154.0, false)];
        assert_eq!(choose(&none).map(|t| t.r), Some(4));
        assert!(choose(&[]).is_none());
        assert_eq!(tried(4, 39.5, false).rank(), f64::INFINITY);
        assert_eq!(tried(5, 154.0, true).rank(), 154.0);
    }
}
