//! One run of a solve in windows, with the decision after each (keep it, or integrate it again
//! with a smaller step) and the step size of the next window; how it ended
//! ([`Attempt`]) goes to [`attempts`](super::attempts), which starts runs again. It sees the
//! runs through [`Runs`] only, so it is compiled once, not once per system.

use super::between::Trail;
use super::features::{Feature, Recent, local_step};
use super::local::{Local, LocalRun, Verdict};
use super::record::{Observer, Record, cost_since};
use super::runs::{Cost, Runs};
use super::solution::{Stats, Status};
use super::window::{
    Ctx, GridPoint, LIMIT, P_BOLD, State, StepFailure, TARGET, advance, check_order, keep,
    resolution, start_outputs,
};
use crate::error::{Error, Result};

/// Steps per window.
const WINDOW: usize = 8;

/// Failed steps in a row (with ever smaller steps) before the solve gives up.
const STUCK_LIMIT: usize = 8;

/// A window is integrated again at most this often (while a smaller step brings its estimate
/// down) before the run starts again.
const MAX_WINDOW_TRIES: usize = 24;

/// The estimate's rate of growth is read off the windows of the last 1/RECENT of the span.
const RECENT: f64 = 16.0;

/// The least number of windows over the span.
const WINDOWS_MIN: f64 = 32.0;

/// Step sizes are taken from the ladder h₀·2^(k/LADDER): a step size met again finds its
/// banks in the cache.
const LADDER: f64 = 8.0;

/// With an observer, the steps of a run are held until it is kept whole (so that a run started
/// again shows nothing twice), up to this many numbers of their states (32 MiB).
const OBSERVER_HOLD: usize = 1 << 22;

/// How an attempt ended.
pub(super) enum Attempt {
    /// At the end of the span (or a terminal event, or the observer's stop).
    Done(Record),
    /// The estimate cannot be kept within the tolerance by smaller steps from here on: start
    /// again, aiming lower by `factor`.
    Again {
        record: Record,
        factor: f64,
        /// Where the estimate passed the tolerance, or where the projection said it would not
        /// last.
        at: f64,
        /// The modelled round-off there, in units of the tolerance.
        noise: f64,
        /// How fast the estimate grew so far: its largest value per unit time since t₀.
        growth: f64,
        reason: String,
    },
    /// Stuck or out of steps: the best solution so far and why.
    Failed { record: Record, reason: String },
}

/// How a run decides.
#[derive(Clone, Copy, Debug)]
pub(super) enum Mode {
    /// Windows kept or integrated again by the estimate; the run starts again where smaller
    /// steps do not help.
    Verify,
    /// As `Verify`, and each step is also measured for what it makes alone ([`Local`]).
    Local(Local),
    /// Every window kept, whatever its estimate: the best run over the whole span at this
    /// step, for an answer that is not verified.
    Permissive,
}

/// The step of the ladder at or below h.
pub(super) fn on_ladder(h: f64, base: f64) -> f64 {
    let k = (LADDER * (h / base).log2()).floor();
    let q = base * (k / LADDER).exp2();
    // Never above h (rounding of the powers).
    if q > h { h } else { q }
}

/// The estimate at t_end projected from a run that stopped at `t` with estimate `worst`, from
/// the estimates after its kept windows: where the estimate grew more than twofold over the
/// second half of the time run (the difference of two runs amplified by the flow: chaos, a
/// separatrix), at that exponential rate; otherwise linearly in time (an error made at a
/// steady rate). Capped at 1e12.
fn project(history: &[(f64, f64)], t: f64, worst: f64, ctx: &Ctx<'_>) -> f64 {
    let span = ctx.t_end - ctx.t0;
    let elapsed = (t - ctx.t0).max(f64::MIN_POSITIVE);
    let linear = worst * (span / elapsed).max(1.0);
    let mid = ctx.t0 + 0.5 * elapsed;
    let i = history.partition_point(|&(tk, _)| tk <= mid);
    let exponential = match i.checked_sub(1).map(|k| history[k]) {
        Some((tm, wm)) if wm > 0.0 && worst > 2.0 * wm && t > tm => {
            let rate = (worst / wm).ln() / (t - tm);
            worst * (rate * (ctx.t_end - t)).min(27.6).exp()
        }
        _ => 0.0,
    };
    linear.max(exponential).min(1e12)
}

/// One run from t₀ at order 2r with the check, in windows of steps, deciding as `mode` says
/// (the local mode: docs/solve.md §3).
///
/// The step is the run's level `base`, constant unless the estimate says otherwise: the level
/// makes the estimate, growing as it grew since the level last changed (from t₀: linearly from
/// 0), end the span at [`TARGET`]; it is lowered for the rest of the span when that projection
/// exceeds the tolerance (the run starts again from t₀ when that would take more than halving
/// it). It is never raised: an estimate that grew slowly so far may grow fast later (the
/// difference of two orbits shows at their close passages). A window whose estimate
/// passes the tolerance is integrated again with a smaller step while that brings its growth
/// per unit time down (the close passage of an orbit, a kink of g), and the windows after it
/// return to the level by factors of √2: constant-step segments where the time scale of the
/// solution changes.
pub(super) fn run(
    ctx: &Ctx<'_>,
    runs: &mut dyn Runs,
    r: usize,
    h0: f64,
    mode: Mode,
    observer: &mut Observer<'_>,
    stats: &mut Stats,
) -> Result<Attempt> {
    let options = ctx.options;
    let permissive = matches!(mode, Mode::Permissive);
    let local = match mode {
        Mode::Local(l) => Some(l),
        Mode::Verify | Mode::Permissive => None,
    };
    let p = check_order(r);
    let span = ctx.t_end - ctx.t0;
    let max_step = options
        .max_step
        .min(span)
        .min(local.map_or(f64::INFINITY, |l| l.cap));
    let ladder = h0;
    let mut base = h0.min(max_step);
    let mut h = on_ladder(base, ladder);
    let mut state = ctx.start();
    let mut record = Record::new(ctx.t0, h);
    let mut ev_prev = options
        .events
        .iter()
        .enumerate()
        .map(|(k, e)| e.value(k, ctx.t0, ctx.y0))
        .collect::<Result<Vec<_>>>()?;
    let mut t_eval_next = 0;
    start_outputs(ctx, &mut record, &mut t_eval_next)?;
    if options.dense {
        record.grid(ctx.t0, ctx.y0, ctx.y0)?;
    }
    // The last grid points, for values between them by interpolation.
    let mut trail = (options.t_eval.is_some() || !options.events.is_empty()).then(|| {
        let mut trail = Trail::default();
        trail.push(ctx.t0, ctx.y0, ctx.y0);
        trail
    });
    let (mut stuck, mut retries) = (0usize, 0usize);
    // The last failed step: where, with which step, why.
    let mut failure: Option<(f64, f64, String)> = None;
    // The growth of a window that was integrated again, to see whether a smaller step helped.
    let mut rejected: Option<(f64, f64)> = None;
    // Whether this window's retry was doubted once already; windows in a row integrated again.
    let (mut doubted, mut strained) = (false, 0usize);
    let with_observer = observer.is_some();
    // Where the steps of the current size began, their size and how many were kept since.
    let mut segment = ((ctx.t0, 0.0), f64::NAN, 0usize);
    // When the run's level last changed, and the estimate then; the growth of the windows
    // since, over the last 1/RECENT of the span.
    let mut changed = (ctx.t0, 0.0_f64);
    let mut recent = Recent::default();
    // The feature inside one step being passed with smaller steps, if any.
    let mut feature: Option<Feature> = None;
    // The estimate after each kept window, (t, worst), for the projection of a run that
    // starts again.
    let mut history: Vec<(f64, f64)> = Vec::new();
    // The local mode's measures, from window to window.
    let mut local = local.map(LocalRun::new);
    while state.t < ctx.t_end - ctx.same_time && !record.ended() {
        let stop = ctx.next_stop(state.t);
        let room = (stop - state.t) - state.t_lo;
        // A window is at most 1/WINDOWS_MIN of the span.
        let steps_max = WINDOW.min(((span / WINDOWS_MIN / h).floor() as usize).max(1));
        let (steps, hw, end) = if room <= steps_max as f64 * h * (1.0 + 1e-12) {
            let k = ((room / h).ceil() as usize).max(1);
            (k, room / k as f64, Some(stop))
        } else {
            (steps_max, h, None)
        };
        if hw <= resolution(state.t) {
            let reason = match &failure {
                Some((t, hf, why)) => {
                    record.status = Some(Status::Failed { t: state.t });
                    format!(
                        "a step failed at t = {t:?} with h = {hf:e} ({why}), and the steps that \
                         would pass it are below the resolution of time"
                    )
                }
                None => format!(
                    "the step size needed at t = {:?} ({hw:e}) is below the resolution of time",
                    state.t
                ),
            };
            return Ok(Attempt::Failed { record, reason });
        }
        if state.n + steps > options.max_steps {
            return Ok(Attempt::Failed {
                record,
                reason: format!(
                    "the run needs more than max_steps = {} steps (at t = {:?} with h = {hw:e})",
                    options.max_steps, state.t
                ),
            });
        }
        runs.set_step_size(hw)?;
        let origin = if hw == segment.1 {
            (segment.0.0, segment.0.1, segment.2)
        } else {
            (state.t, state.t_lo, 0)
        };
        let mut cost = Cost::default();
        let mut points = match advance(
            ctx,
            runs,
            &state,
            origin,
            (steps, end),
            local.as_mut(),
            &mut cost,
        ) {
            Ok(points) => points,
            Err(StepFailure { t, h: hf, error }) => {
                stats.discard(&cost);
                stuck += 1;
                options.say(|| format!("a step failed at t = {t:?} with h = {hf:e}: {error}"));
                if stuck > STUCK_LIMIT {
                    record.status = Some(Status::Failed { t });
                    return Ok(Attempt::Failed {
                        record,
                        reason: format!(
                            "a step failed at t = {t:?} {stuck} times with ever smaller steps \
                             (down to h = {hf:e}): {error}"
                        ),
                    });
                }
                failure = Some((t, hf, error.to_string()));
                h = on_ladder(hw / 4.0, ladder);
                continue;
            }
        };
        // The local mode: a step that made more than the limit is taken again with a smaller
        // step, and the steps before it are kept.
        let mut cut = false;
        if let Some(l) = local.as_mut() {
            let may_retry = retries < MAX_WINDOW_TRIES && hw > resolution(state.t) * 16.0;
            let from = (state.t, &state.answer[..]);
            match l.judge(ctx, runs, from, &points, hw, p, may_retry, &mut cost) {
                Verdict::Keep => {}
                Verdict::Cut { keep, factor } => {
                    stats.retries += 1;
                    retries += 1;
                    h = on_ladder(hw * factor, ladder);
                    if keep == 0 {
                        stats.discard(&cost);
                        continue;
                    }
                    let whole = points.len();
                    stats.discard(&cost.take_share(whole - keep, whole));
                    points.truncate(keep);
                    cut = true;
                }
                Verdict::AsItIs => {
                    stats.discard(&cost);
                    continue;
                }
            }
        }
        let last = points.last().expect("a window has a step");
        let worst = points.iter().map(|q| q.est).fold(state.worst, f64::max);
        let growth = worst - state.worst;
        let duration = last.t - state.t;
        // A window may not take the estimate past the tolerance, nor take more than half of what
        // is left of it (a kink or a close passage would leave the rest of the span nothing).
        let room = (LIMIT - state.worst).max(0.0);
        let over = worst > LIMIT;
        // A retry whose estimate fell by far more than the check's order allows: the two methods
        // may err alike by chance at a kink of g in this window (their difference vanishes where
        // their quadrature errors cross); once more with another step, which takes its estimate.
        // A window cut in the local mode keeps its steps before the cut, as one shortened at a
        // feature does.
        let mut shrunk = cut && !over;
        let rate_now = growth / duration;
        let implausible = rejected
            .is_some_and(|(g, hr)| hw < hr && rate_now < g * (hw / hr).powf(p + 2.0) && !doubted);
        if implausible && retries < MAX_WINDOW_TRIES && !permissive && !cut {
            stats.discard(&cost);
            stats.retries += 1;
            retries += 1;
            doubted = true;
            options.say(|| {
                format!(
                    "window at t = {:?}, h = {hw:.4e}: estimate fell from {:.3e} to {rate_now:.3e} per \
                     unit time, more than the order explains → again with h × 0.7",
                    state.t,
                    rejected.map_or(0.0, |r| r.0)
                )
            });
            h = on_ladder(hw * 0.7, ladder);
            continue;
        }
        // A feature inside one step of the window — a jump or a kink of g at a time nobody
        // announced, a close passage — adds its error in that step: the step that carries most
        // of the window's growth. Its step is made smaller while that brings what the step adds
        // down (compared as it is, not per unit time: the error of a jump is made once, in
        // proportion to the step over it), the steps before it are kept, and the steps grow
        // back after it.
        if (over || growth > 0.5 * room) && !permissive && !shrunk {
            let local = local_step(&points, state.worst)
                .filter(|_| retries < MAX_WINDOW_TRIES && hw > resolution(state.t) * 16.0);
            if let Some((j, delta)) = local {
                let helped = feature.is_none_or(|f: Feature| delta < 0.7 * f.delta);
                if helped {
                    // The order of what the step adds, seen from the last two tries at this
                    // feature (a jump of g: 1; a kink: 2; a smooth passage: the check's), or
                    // 2 at the first try.
                    let (q, least) = match feature {
                        Some(f) if hw < f.h && delta < f.delta => (
                            ((f.delta / delta).ln() / (f.h / hw).ln()).clamp(1.0, P_BOLD),
                            1.0 / 64.0,
                        ),
                        _ => (2.0, 0.125),
                    };
                    let factor = (0.25 * room / delta).powf(1.0 / q).clamp(least, 0.5);
                    feature = Some(Feature {
                        delta,
                        h: hw,
                        until: points[j].t,
                    });
                    stats.retries += 1;
                    retries += 1;
                    h = on_ladder(hw * factor, ladder);
                    let before = points[..j]
                        .iter()
                        .map(|q| q.est)
                        .fold(state.worst, f64::max);
                    let t_feature = points[j].t;
                    options.say(|| {
                        format!(
                            "window at t = {:?}, h = {hw:.4e}: the step to t = {t_feature:?} adds \
                         {delta:.3e} of the estimate's {growth:.3e} → that step again with \
                         h × {factor:.3e} (order {q:.2})",
                            state.t
                        )
                    });
                    if j > 0 && before <= LIMIT && before - state.worst <= 0.5 * room {
                        // Keep the steps before the feature.
                        stats.discard(&cost.take_share(points.len() - j, points.len()));
                        points.truncate(j);
                        shrunk = true;
                    } else {
                        stats.discard(&cost);
                        continue;
                    }
                }
            }
        }
        let last = points.last().expect("a window has a step");
        let worst = points.iter().map(|q| q.est).fold(state.worst, f64::max);
        let growth = worst - state.worst;
        if (over || growth > 0.5 * room) && !permissive && !shrunk {
            // A smaller step for this window while that brings its growth down. Compared per
            // unit time: a smaller step also makes the window shorter, which lowers the growth
            // of an error carried into it (amplified by the flow) as much as its duration, that
            // of an error made in it by the order of the check besides.
            let rate = growth / duration;
            let helped = rejected.is_none_or(|(g, _)| rate < g * 0.7);
            if helped && retries < MAX_WINDOW_TRIES && hw > resolution(state.t) * 16.0 {
                stats.discard(&cost);
                stats.retries += 1;
                retries += 1;
                rejected = Some((rate, hw));
                let want = 0.25 * room;
                let factor = if growth > 0.0 && want > 0.0 {
                    (want / growth).powf(1.0 / p.min(P_BOLD)).clamp(0.125, 0.5)
                } else {
                    0.5
                };
                options.say(|| {
                    format!(
                        "window at t = {:?}, h = {hw:.4e}: estimate {worst:.3e} (growth \
                     {growth:.3e}) → again with h × {factor:.3}",
                        state.t
                    )
                });
                h = on_ladder(hw * factor, ladder);
                continue;
            }
            if over {
                stats.discard(&cost);
                let projected = project(&history, last.t, worst.max(LIMIT), ctx);
                return Ok(Attempt::Again {
                    record,
                    factor: TARGET / projected,
                    at: last.t,
                    noise: ctx.noise(&last.answer, state.n + points.len()),
                    growth: worst.max(LIMIT) / (last.t - ctx.t0),
                    reason: format!(
                        "the estimate reaches {worst:.3e} times the tolerance at t = {:?} and a \
                     smaller step for that stretch does not bring it down",
                        last.t
                    ),
                });
            }
        }
        let last = points.last().expect("a window has a step");
        let worst = points.iter().map(|q| q.est).fold(state.worst, f64::max);
        let growth = worst - state.worst;
        // Keep the window (unless its values between grid points are over the tolerance).
        let mark = record.mark();
        let (ev_save, t_eval_save) = (ev_prev.clone(), t_eval_next);
        let start = GridPoint {
            t: state.t,
            t_lo: state.t_lo,
            answer: state.answer.clone(),
            check: state.check.clone(),
            est: state.worst,
        };
        let trail_mark = trail.as_ref().map_or(0, Trail::len);
        if let Some(trail) = &mut trail {
            for q in &points {
                trail.push(q.t, &q.answer, &q.check);
            }
        }
        let kept = keep(
            ctx,
            runs,
            &mut record,
            &start,
            state.n,
            &points,
            &mut t_eval_next,
            &mut ev_prev,
            with_observer,
            trail.as_mut(),
        );
        let failed_between = match &kept {
            Ok(y) => (y.between > LIMIT && retries < MAX_WINDOW_TRIES && !permissive)
                .then(|| format!("a value between grid points has estimate {:.3e}", y.between)),
            Err(Error::InvalidInput(_)) => None,
            Err(e) => Some(format!("a step between grid points failed: {e}")),
        };
        if let Some(why) = failed_between {
            let spent = cost_since(&record, mark);
            stats.discard(&cost);
            stats.discard(&spent);
            record.rollback(mark);
            if let Some(trail) = &mut trail {
                trail.truncate(trail_mark);
            }
            (ev_prev, t_eval_next) = (ev_save, t_eval_save);
            retries += 1;
            stuck += usize::from(kept.is_err());
            options.say(|| format!("window at t = {:?}: {why} → again with h / 2", state.t));
            if stuck > STUCK_LIMIT {
                return Ok(Attempt::Failed {
                    record,
                    reason: format!("near t = {:?}: {why}", state.t),
                });
            }
            h = on_ladder(hw / 2.0, ladder);
            continue;
        }
        let yielded = kept?;
        if let Some(trail) = &mut trail {
            trail.trim();
        }
        record.cost.add(&cost);
        record.step_size_from(state.t, hw);
        segment = ((origin.0, origin.1), hw, origin.2 + points.len());
        // Windows integrated again in a row: the run's level is too high for the stretch, not
        // one passage in it; the level comes down to twice the step that was kept.
        // A feature inside one step (being passed) does not say that.
        strained = if rejected.is_some() && feature.is_none() {
            strained + 1
        } else {
            0
        };
        if strained >= 3 && base > 2.0 * hw {
            base = 2.0 * hw;
            strained = 0;
        }
        if shrunk {
            // The next window starts at the feature: a retry of the window before compares
            // with nothing there.
            (rejected, doubted) = (None, false);
        } else {
            (stuck, retries, rejected, doubted) = (0, 0, None, false);
        }
        if feature.is_some_and(|f| last.t >= f.until) {
            feature = None;
        }
        if failure.as_ref().is_some_and(|f| last.t > f.0) {
            failure = None;
        }
        // The run's estimate is its grid's: the values between grid points (outputs, events)
        // were each checked against the limit above and are in the record with their own
        // estimates, but they do not set the level. An interpolated output carries its
        // interpolant's estimate (up to half a tolerance, often several times the grid's
        // there); taken into the run's estimate, it hid the growth of the grid's from the
        // level's projection, and the run went on at its first level until an output reached
        // the tolerance (Duffing ω = 20, 1e−8, 4000 outputs: 656 windows integrated again and
        // a start again from t₀, 228 ms where the plain solve's grid now serves in 57).
        state = State {
            t: yielded.terminal.map_or(last.t, |(_, t)| t),
            t_lo: if yielded.terminal.is_some() {
                0.0
            } else {
                last.t_lo
            },
            n: state.n + points.len(),
            worst,
            answer: last.answer.clone(),
            check: last.check.clone(),
        };
        // The observer sees the run once it is kept whole, unless holding its steps till then
        // would take more than OBSERVER_HOLD numbers (from then on the run is not started again).
        if with_observer && record.unshown.len().saturating_mul(ctx.y0.len().max(1)) > OBSERVER_HOLD
        {
            record.show(observer);
        }
        if record.ended() || ctx.t_end - state.t <= ctx.same_time {
            break;
        }
        // The run's level: the estimate projected to t_end at the rate it grew over the recent
        // windows since the level last changed, without the largest growth of one window (a
        // kink or a close passage adds to the estimate once, it does not set its rate).
        recent.push(state.t, growth);
        let since = changed.0.max(state.t - span / RECENT);
        recent.expire(since);
        let elapsed = state.t - changed.0;
        let left = ctx.t_end - state.t;
        let (sum, top) = recent.sum_and_top();
        let duration = state.t - since;
        let rate = if recent.len() >= 3 { sum - top } else { sum } / duration;
        let projected = worst + rate * left;
        history.push((state.t, worst));
        if projected > LIMIT && elapsed >= span / 32.0 && !permissive {
            let budget = 0.95 * LIMIT - worst;
            let factor = if budget > 0.0 {
                (budget / (rate * left)).powf(1.0 / p.min(P_BOLD))
            } else {
                0.0
            };
            if factor < 0.125 && !record.shown {
                let projected = projected.max(project(&history, state.t, worst, ctx));
                return Ok(Attempt::Again {
                    record,
                    factor: TARGET / projected,
                    at: ctx.t_end,
                    noise: 0.0,
                    growth: worst / (state.t - ctx.t0),
                    reason: format!(
                        "the estimate, {worst:.3e} times the tolerance at t = {:?}, projects to \
                         {projected:.3e} at t_end",
                        state.t
                    ),
                });
            }
            let factor = factor.clamp(0.125, 1.0);
            if factor < 0.95 {
                base *= factor;
                changed = (state.t, worst);
                recent.clear();
                options.say(|| {
                    format!(
                        "t = {:?}: projection {projected:.3e} → level × {factor:.3}",
                        state.t
                    )
                });
            }
        }
        // Back towards the run's level after a window integrated again with a smaller step: by
        // up to 4 at once where the window used little of what is left of the tolerance (after
        // a jump of g the steps come back from far below the level), else by √2.
        if !shrunk {
            let left = (LIMIT - worst).max(0.0);
            let up = if growth <= 0.01 * left {
                4.0
            } else if growth <= 0.1 * left {
                2.0
            } else {
                std::f64::consts::SQRT_2
            };
            h = on_ladder(base.min(max_step).min(up * hw), ladder);
        }
        if let Some(l) = local.as_mut().filter(|_| !cut) {
            // The step is the smaller of what error per unit step calls for and what the
            // estimate does.
            let mine = on_ladder((hw * l.factor(hw, p)).min(max_step), ladder);
            if mine < h {
                l.shrunk(hw, state.t);
            }
            h = h.min(mine);
        }
        options.say(|| {
            format!(
                "kept t = {:?} h = {hw:.4e} base {base:.4e} estimate {worst:.3e} → h = {h:.4e}",
                state.t
            )
        });
    }
    Ok(Attempt::Done(record))
}
