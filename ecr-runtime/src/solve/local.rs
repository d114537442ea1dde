//! The local mode of a run started again (docs/solve.md §3): each step is also measured for
//! what it makes alone — the check's step from the answer's state before it, against the
//! answer's step ([`Runs::step_local`], [`made`]) — and the steps are cut and sized by
//! error per unit step, so that they shrink on the way into a close passage, where the error
//! made shows only later, magnified.

use super::runs::{Cost, Runs};
use super::window::{Ctx, GridPoint, P_BOLD};
use crate::error::Result;

/// What a step makes alone, in units of the tolerance, that the local mode never cuts a step
/// for: 10⁸ such steps would make the tolerance. Below it, what a step makes may not shrink
/// with the step at all (the rounding of a component near zero), and cutting for it would
/// not end.
const MADE_NEGLIGIBLE: f64 = 1e-8;

/// What a step makes ([`made`]) counts above this many roundings of each component.
const MADE_ROUNDING: f64 = 4.0;

/// What one step of size `h` makes: the difference of the answer's step `answer` and the
/// check's `check` from the same state, per component less a few roundings of it (below that,
/// what a step makes cannot be told from how its stages were rounded: the component's own,
/// and h times the largest component's, which the increment mixes in), in units of the
/// tolerance; the largest over the components whose tolerance is not 0.
fn made(ctx: &Ctx<'_>, answer: &[f64], check: &[f64], h: f64) -> f64 {
    let (rtol, atol) = (ctx.options.rtol, ctx.options.atol);
    let mixed = h.min(1.0) * answer.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    answer
        .iter()
        .zip(check)
        .map(|(a, c)| {
            let w = atol + rtol * a.abs();
            let e = (a - c).abs() - MADE_ROUNDING * ctx.unit * (a.abs().max(c.abs()) + mixed);
            if w > 0.0 && e > 0.0 { e / w } else { 0.0 }
        })
        .fold(0.0, |m, x| if x > m || x.is_nan() { x } else { m })
}

/// What the answer's step from `before` to `after` made alone, against the check's step from
/// `before` ([`Runs::step_local`], into `scratch`).
///
/// # Errors
/// What the check's stepper reports.
fn step_made(
    ctx: &Ctx<'_>,
    runs: &mut dyn Runs,
    (before, after): (&[f64], &[f64]),
    scratch: &mut Vec<f64>,
    cost: &mut Cost,
) -> Result<f64> {
    scratch.resize(before.len(), 0.0);
    runs.step_local(before, scratch, cost)?;
    Ok(made(ctx, after, scratch, runs.step_size()))
}

/// The local mode's target: what a step may make per unit step (`rate`, in units of the
/// tolerance), and the largest step (`cap`: the step the run started again with).
#[derive(Clone, Copy, Debug)]
pub(super) struct Local {
    pub(super) rate: f64,
    pub(super) cap: f64,
}

/// What the window measured calls for.
pub(super) enum Verdict {
    /// Keep it whole.
    Keep,
    /// Keep its first `keep` steps (none: the whole window again) and take the rest again
    /// with the step times `factor`.
    Cut { keep: usize, factor: f64 },
    /// The whole window again at the same step, taken as it is (a smaller step made as much
    /// per unit step).
    AsItIs,
}

/// The local mode over one run: what the steps of the window made, and what it keeps from
/// window to window.
pub(super) struct LocalRun {
    target: Local,
    /// What each step of the window made, NaN where not measured ([`Self::after_step`]).
    made: Vec<f64>,
    /// The check's step for a measure.
    scratch: Vec<f64>,
    /// The largest per unit step over the window's measured steps, and how much it grew
    /// across the window.
    rate: f64,
    trend: f64,
    /// The last step made smaller (its size, what it made, where the next window starts), to
    /// see whether that helped.
    probe: Option<(f64, f64, f64)>,
    /// What a step makes that smaller steps did not bring down: counted as nothing.
    floor: f64,
    /// The last cut (what the step made per unit step, its size, where it started).
    last_cut: Option<(f64, f64, f64)>,
    /// The window is taken without the limit.
    relax: bool,
    /// A step size that was cut, and for how many more kept windows the step stays below it
    /// (where what a smaller step makes is below the floor, nothing else says it would be cut
    /// again: without this the step went up and was cut every other window, Duffing ω = 20 at
    /// 1e−4 over 1000 time units).
    ceiling: Option<(f64, usize)>,
}

/// Kept windows for which a step size that was cut is not taken again.
const CEILING_WINDOWS: usize = 4;

impl LocalRun {
    pub(super) fn new(target: Local) -> Self {
        LocalRun {
            target,
            made: Vec::new(),
            scratch: Vec::new(),
            rate: 0.0,
            trend: 1.0,
            probe: None,
            floor: MADE_NEGLIGIBLE,
            last_cut: None,
            relax: false,
            ceiling: None,
        }
    }

    /// A window begins.
    pub(super) fn start_window(&mut self) {
        self.made.clear();
    }

    /// After the answer's step from `before` to `after`: with `measured`, what it made alone
    /// (the window's first and last steps), else NaN (measured by [`Self::judge`] if need be).
    ///
    /// # Errors
    /// What the check's stepper reports.
    pub(super) fn after_step(
        &mut self,
        ctx: &Ctx<'_>,
        runs: &mut dyn Runs,
        steps: (&[f64], &[f64]),
        measured: bool,
        cost: &mut Cost,
    ) -> Result<()> {
        let m = if measured {
            step_made(ctx, runs, steps, &mut self.scratch, cost)?
        } else {
            f64::NAN
        };
        self.made.push(m);
        Ok(())
    }

    /// The verdict on a window of step `hw` from `(t, answer)` whose steps are `points`
    /// (check's order p); `may_retry` whether the controller may take it again at all. Every
    /// step is measured (into `cost`) where the first or last makes more than the limit.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn judge(
        &mut self,
        ctx: &Ctx<'_>,
        runs: &mut dyn Runs,
        (t, answer): (f64, &[f64]),
        points: &[GridPoint],
        hw: f64,
        p: f64,
        may_retry: bool,
        cost: &mut Cost,
    ) -> Verdict {
        let options = ctx.options;
        let rho = self.target.rate;
        // A smaller step that made about as much as the larger one just before it or in its
        // place (less than the square of their ratio would take off; a smooth error falls by
        // the power p + 1): what a step makes here is rounding, not the method's error, and
        // steps are not made smaller for it again.
        let first = self.made.first().copied().unwrap_or(0.0);
        if let Some((hp, mp, tp)) = self.probe.take() {
            if t == tp && hw < hp && first >= self.floor && first > mp * (hw / hp).powi(2) {
                self.floor = self.floor.max(2.0 * first);
                options.say(|| {
                    format!(
                        "t = {t:?}: h = {hw:.4e} made {first:.3e} where h = {hp:.4e} made \
                         {mp:.3e} → from now on a step may make {:.3e}",
                        self.floor
                    )
                });
            }
        }
        // A step may make up to twice the target, and never needs to make less than the
        // floor. The first and last steps are measured; where one makes more, every step is,
        // and the window is cut before the first that does.
        let floor = self.floor;
        let limit = if self.relax {
            f64::INFINITY
        } else {
            (2.0 * rho * hw).max(floor)
        };
        // What the measured steps made, each counted as 0 below the floor.
        let measured = |m: &[f64]| {
            m.iter()
                .filter(|&&x| x >= floor)
                .fold(0.0_f64, |a, &b| a.max(b))
        };
        let j_cut = if self.made.first().is_some_and(|&x| x > limit) {
            Some(0)
        } else if measured(&self.made) > limit {
            // Every step measured; one whose measure fails counts as making infinitely much.
            for (j, m) in self.made.iter_mut().enumerate() {
                if m.is_nan() {
                    let before = if j == 0 {
                        answer
                    } else {
                        &points[j - 1].answer
                    };
                    let steps = (before, &points[j].answer[..]);
                    *m = step_made(ctx, runs, steps, &mut self.scratch, cost)
                        .unwrap_or(f64::INFINITY);
                }
            }
            self.made.iter().position(|&x| x > limit)
        } else {
            None
        };
        let m = &self.made;
        self.rate = measured(m) / hw;
        // Where what the steps make grew across the window (an approach), the next window
        // makes more again: the trend, first step to last, carried forward.
        self.trend = match (m.first(), m.last()) {
            (Some(&a), Some(&b)) if a >= floor && b > a => (b / a).min(1e6),
            _ => 1.0,
        };
        let Some(j) = j_cut else {
            return Verdict::Keep;
        };
        let rate = m[j] / hw;
        let t_start = if j == 0 { t } else { points[j - 1].t };
        // Compared with the last cut where this is the same step made smaller: the first of a
        // window that starts where that step started.
        let helped = self
            .last_cut
            .is_none_or(|(g, hc, tc)| j > 0 || t != tc || hw >= hc || rate < 0.7 * g);
        if helped && may_retry {
            self.last_cut = Some((rate, hw, t_start));
            self.ceiling = Some((hw, CEILING_WINDOWS));
            self.probe = Some((hw, m[j], t_start));
            let factor = (0.5 * rho / rate)
                .powf(1.0 / p.min(P_BOLD))
                .clamp(0.125, 0.5);
            options.say(|| {
                format!(
                    "window at t = {t:?}, h = {hw:.4e}: the step from t = {t_start:?} makes \
                     {rate:.3e} per unit step (target {rho:.3e}) → from there with h × \
                     {factor:.3}"
                )
            });
            Verdict::Cut { keep: j, factor }
        } else {
            // A smaller step does not make less per unit step (a jump of g makes an error in
            // proportion to the step over it): taken as it is.
            self.relax = true;
            options.say(|| {
                format!(
                    "window at t = {t:?}, h = {hw:.4e}: a smaller step made as much per unit \
                     step → taken as it is"
                )
            });
            Verdict::AsItIs
        }
    }

    /// After a window of step `hw` kept whole: the factor on it that error per unit step calls
    /// for — down to aim at half the target where a step made more than it
    /// (the window's trend carried forward), up by up to 2 only where that grows the step by a
    /// fourth at least, 1 in between (segments of one step size).
    pub(super) fn factor(&mut self, hw: f64, p: f64) -> f64 {
        (self.last_cut, self.relax) = (None, false);
        let rho = self.target.rate;
        let ahead = self.rate * self.trend;
        let aim = (0.5 * rho / ahead.max(f64::MIN_POSITIVE)).powf(1.0 / p);
        let factor = if ahead > rho {
            aim.max(0.5)
        } else if aim >= 1.25 {
            aim.min(2.0)
        } else {
            1.0
        };
        match self.ceiling.take() {
            Some((size, left)) if left > 0 => {
                self.ceiling = Some((size, left - 1));
                // Below the size that was cut: a rung of the ladder below it at most.
                factor.min((0.9 * size / hw).max(1.0))
            }
            _ => factor,
        }
    }

    /// The step was made smaller than `hw` after the window that ended at `t`: the next window
    /// tells whether that helped.
    pub(super) fn shrunk(&mut self, hw: f64, t: f64) {
        let last = self.made.last().copied();
        self.probe = last.filter(|x| !x.is_nan()).map(|x| (hw, x, t));
    }
}
