//! Where the zeros of the event functions are over a kept step: the step scanned on the
//! grid's interpolant for sign changes ([`brackets`]), each bracket's zero located first on the
//! interpolant, then moved to from the runs' steps ([`super::moved`]) or searched on them
//! ([`hit`]).

use super::between::{INTERP_MAX, Source, Trail, between, between_into};
use super::events::Event;
use super::moved::{Near, Taylor, correction, moved_zero};
use super::record::Point;
use super::runs::{Cost, Runs};
use super::window::{Ctx, GridPoint};
use crate::error::Result;

/// The width, in units of roundoff of t, to which a zero is searched on the runs' steps: their
/// values are rounded at the stage iteration's tolerance (about 1e−15 of the state, differing
/// with the iteration's start), which moves a zero of a function of slope ~1 by ~1e−14 — more
/// than a few ulps of t, where regula falsi and bisection would creep on noise (Lotka–Volterra,
/// tol 1e−8: up to 36 values for one zero, against 4 to 6 here).
const STEPS_ULPS: f64 = 64.0;

/// The interior points of a step at which the event functions are sampled on the grid's
/// interpolant ([`brackets`]), evenly spaced: two zeros of an event function closer than a
/// fifth of the step to each other (a near touch) can still hide between them.
pub(super) const SCAN: usize = 4;

/// A zero's bracket: two (time, event function) pairs, the function's signs different.
pub(super) type Bracket = ((f64, f64), (f64, f64));

/// The brackets of event `k`'s zeros over the step from `prev` to `p`, where it is `before`
/// and `after`, into `out` in time order. Where the event function sampled on the answer's
/// interpolant at `scan` (times and states inside the step) changes sign more often than its
/// ends say (two zeros in one step, where the ends' signs agree; three where they differ), it
/// is evaluated on the answer's steps at one sample of each stretch the interpolant puts on
/// another side than the stretch before (the one farthest from zero), and each sign change that
/// counts between those values and the ends is a bracket; else the step is the bracket where
/// its ends' change counts.
///
/// # Errors
/// What [`between`] and the event function report.
#[allow(clippy::too_many_arguments)]
pub(super) fn brackets(
    ctx: &Ctx<'_>,
    runs: &mut dyn Runs,
    (prev, p): (&GridPoint, &GridPoint),
    n: usize,
    (k, event): (usize, &Event),
    (before, after): (f64, f64),
    scan: Option<(&[f64], &[f64])>,
    mut trail: Option<&mut Trail>,
    cost: &mut Cost,
    out: &mut Vec<Bracket>,
) -> Result<()> {
    out.clear();
    let whole = event.counts(before, after);
    let side = |e: f64| e >= 0.0;
    // The stretches of samples on one side of zero on the interpolant (a NaN there, off the
    // solution, tells nothing and is passed over): the sample of each farthest from zero.
    let mut stretches = [(0, 0.0_f64); SCAN];
    let mut count = 0;
    if let Some((times, states)) = scan {
        let d = prev.answer.len();
        // A zero at the start has no side: the samples after it set one (a zero it leaves
        // is no sign change, but one it comes back to is).
        let mut last = (before != 0.0).then(|| side(before));
        for (i, &t) in times.iter().enumerate() {
            let e = event.raw(t, &states[i * d..(i + 1) * d]);
            if e.is_nan() {
                continue;
            }
            if last != Some(side(e)) {
                stretches[count] = (i, e.abs());
                count += 1;
                last = Some(side(e));
            } else if count > 0 && e.abs() > stretches[count - 1].1 {
                stretches[count - 1] = (i, e.abs());
            }
        }
        // The last stretch is the end's where it is on the end's side.
        if count > 0 && last == Some(side(after)) {
            count -= 1;
        }
    }
    if count == 0 {
        if whole {
            out.push(((prev.t, before), (p.t, after)));
        }
        return Ok(());
    }
    // More sign changes than the ends show: one sample of each stretch on the answer's steps.
    let times = scan.map_or(&[][..], |(times, _)| times);
    let mut a = (prev.t, before);
    for &(i, _) in &stretches[..count] {
        let t = times[i];
        let (_, e) = on_answer(
            ctx,
            runs,
            (prev, n),
            t,
            trail.as_deref_mut(),
            (k, event),
            cost,
        )?;
        let b = (t, e);
        if event.counts(a.1, b.1) {
            out.push((a, b));
        }
        a = b;
    }
    if event.counts(a.1, after) {
        out.push((a, (p.t, after)));
    }
    Ok(())
}

/// The zero of event `k` in the bracket `(lo, hi)` (times and the event function's values,
/// of different signs) inside the step from `prev` to `p` (the whole step, or a part of it
/// where a scan found more than one sign change in it), and the value there.
///
/// Each evaluation on the solution is a value between grid points ([`between`]), which costs a
/// step of each run where the interpolant does not serve. So the zero is first located on the
/// grid's interpolant (no evaluation of g beyond its slopes). Where the interpolant serves the
/// value there (its estimate within [`INTERP_MAX`]), that is the zero and its value. Else both
/// runs step to the interpolant's zero t₀, and their values there are moved along the field
/// to the zero nearby ([`moved_zero`]: a second-order Taylor polynomial of each run, from
/// three evaluations of g each, its distance from the flow bounded a posteriori and added to
/// the estimate); where the answer's polynomial bends too much over the correction, its step to
/// the Newton point from t₀ is the next base, with the secant's slope. Where the move does not
/// apply (the zero too far from both bases for the polynomial),
/// the zero is searched on the answer's steps alone (one source for every value of the
/// search: a function that switched between the interpolant and the steps would jump by up to
/// their difference, and the search would creep at the jump; the check's step is taken only at
/// the zero found, for the estimate of the value returned): from t₀ and a little beyond it on
/// the side the interpolant's slope predicts (twice the Newton correction), a bracket a few
/// interpolation errors wide in most cases, which regula falsi closes in two or three more
/// values; where those points do not bracket the zero, the search goes on from the tightest
/// bracket they left, to [`STEPS_ULPS`] units of roundoff of t. Either way the value returned
/// is the one at the zero's time.
///
/// # Errors
/// What [`between`] and the event function report.
#[allow(clippy::too_many_arguments)]
pub(super) fn hit(
    ctx: &Ctx<'_>,
    runs: &mut dyn Runs,
    (prev, p): (&GridPoint, &GridPoint),
    n: usize,
    (k, event): (usize, &Event),
    (lo, hi): Bracket,
    mut trail: Option<&mut Trail>,
    cost: &mut Cost,
) -> Result<Point> {
    let d = prev.answer.len();
    // The zero on the interpolant, and the slope of the event function there.
    let mut guess = None;
    if let Some(trail) = trail.as_deref_mut() {
        if let Some(stencil) = trail.grid(d).stencil(lo.0.midpoint(hi.0)) {
            trail.slopes(stencil.range(), runs, cost)?;
            let slopes = trail.slopes_at(stencil.range());
            let grid = trail.grid(d);
            let interpolant = grid.interpolant(stencil, slopes, false);
            let mut y = vec![0.0; d];
            let mut on_interp = |t: f64| {
                interpolant.at(t, &mut y);
                event.value(k, t, &y)
            };
            let t0 = event.locate(lo, hi, &mut on_interp)?;
            let dt = 1e-6 * (p.t - prev.t);
            let (a, b) = ((t0 - dt).max(lo.0), (t0 + dt).min(hi.0));
            let slope = (on_interp(b)? - on_interp(a)?) / (b - a);
            if ctx.verified && t0 > lo.0 && t0 < hi.0 {
                // The interpolant's own estimate there: where it serves, the zero is found.
                let tolerance = (ctx.options.rtol, ctx.options.atol);
                let est = grid.value(
                    t0,
                    stencil,
                    slopes.0,
                    slopes.1,
                    tolerance,
                    ctx.unit,
                    n + 1,
                    &mut y,
                );
                if est <= INTERP_MAX {
                    return Ok(Point { t: t0, y, est });
                }
            }
            guess = Some((t0, slope));
        }
    }
    let (mut lo, mut hi) = (lo, hi);
    // The values of the search on the steps, and the first of them (with the slope there).
    let mut seen: Vec<Point> = Vec::new();
    let mut first = None;
    let narrow = |(t, e): (f64, f64), lo: &mut (f64, f64), hi: &mut (f64, f64)| {
        if t > lo.0 && t < hi.0 {
            if (e < 0.0) == (lo.1 < 0.0) && e != 0.0 {
                *lo = (t, e);
            } else {
                *hi = (t, e);
            }
        }
    };
    if let Some((t0, slope)) = guess {
        if t0 > lo.0 && t0 < hi.0 {
            // The answer at the interpolant's zero; where the zero on the steps is that close
            // to it that the field's Taylor polynomial from there reaches it, the check there
            // too, and no more steps. Where the answer's polynomial bends too much over the
            // correction (a zero farther from t₀ than the polynomial reaches), the answer at
            // the Newton point is the next base, with the secant's slope: its correction is
            // the Newton step's error, far smaller ([`MOVE_BASES`] bases at most).
            let (mut base, mut slope) = (t0, slope);
            let mut last: Option<(f64, f64)> = None;
            for _ in 0..MOVE_BASES {
                let (v, e0) = on_answer(
                    ctx,
                    runs,
                    (prev, n),
                    base,
                    trail.as_deref_mut(),
                    (k, event),
                    cost,
                )?;
                if let Some((tl, el)) = last {
                    let secant = (e0 - el) / (base - tl);
                    if secant.is_finite() && secant != 0.0 {
                        slope = secant;
                    }
                }
                let near = Near {
                    t0: base,
                    e0,
                    slope,
                    bracket: (lo.0, hi.0),
                };
                if e0 == 0.0 {
                    let source = if ctx.verified {
                        Source::Check(&v.y)
                    } else {
                        Source::Answer
                    };
                    return between(ctx, runs, prev, n, base, trail, source, cost);
                }
                // A move that fails (g or the event function not finite off the solution,
                // where the Euler point lies) leaves the search on the steps, which reports
                // what is wrong on the solution itself.
                let taylor =
                    |runs: &mut dyn Runs, y: &[f64], cost: &mut Cost| match correction(&near) {
                        Some(delta) => Taylor::new(runs, y, delta, cost).ok().flatten(),
                        None => None,
                    };
                let answer = taylor(runs, &v.y, cost);
                let bent = answer.is_none();
                if let Some(pa) = answer {
                    let mut yc = vec![0.0; d];
                    let check = if ctx.verified {
                        between_into(
                            ctx,
                            runs,
                            prev,
                            n,
                            base,
                            trail.as_deref_mut(),
                            Source::Check(&v.y),
                            Some(&mut yc),
                            cost,
                        )?;
                        taylor(runs, &yc, cost)
                    } else {
                        None
                    };
                    if ctx.verified == check.is_some() {
                        let check = check.as_ref().map(|pc| (&yc[..], pc));
                        let moved =
                            moved_zero(ctx, runs, (k, event), &near, (&v.y, &pa), check, n, cost);
                        if let Ok(Some(point)) = moved {
                            return Ok(point);
                        }
                    }
                }
                seen.push(v);
                narrow((base, e0), &mut lo, &mut hi);
                first = Some((base, e0, slope));
                let next = correction(&near).map(|delta| base + delta);
                match next.filter(|&t| bent && t > lo.0 && t < hi.0) {
                    Some(t) => {
                        last = Some((base, e0));
                        base = t;
                    }
                    None => break,
                }
            }
        }
    }
    // The search's values: the answer's steps alone (the check's is needed only where it
    // stops), kept for that one.
    let mut on_steps = |t: f64, seen: &mut Vec<Point>| -> Result<f64> {
        let (v, e) = on_answer(
            ctx,
            runs,
            (prev, n),
            t,
            trail.as_deref_mut(),
            (k, event),
            cost,
        )?;
        seen.push(v);
        Ok(e)
    };
    if let Some((t0, e0, slope)) = first {
        let t1 = t0 - 2.0 * e0 / slope;
        if e0 != 0.0 && t1 > lo.0 && t1 < hi.0 && t1 != t0 {
            let e1 = on_steps(t1, &mut seen)?;
            narrow((t1, e1), &mut lo, &mut hi);
        }
    }
    let t_hit = if hi.1 == 0.0 {
        hi.0
    } else {
        event.locate_within(STEPS_ULPS, lo, hi, |t| on_steps(t, &mut seen))?
    };
    // The check's step there, for the value's estimate (both runs where the search stopped at
    // a value it did not take: the end of the step).
    let source = match seen.iter().rfind(|q| q.t == t_hit) {
        Some(q) => Source::Check(&q.y),
        None => Source::Steps,
    };
    between(ctx, runs, prev, n, t_hit, trail, source, cost)
}

/// The answer's step from the grid point `prev` (the `n`-th) to `t`, and event `k` there.
///
/// # Errors
/// What [`between`] and the event function report.
fn on_answer(
    ctx: &Ctx<'_>,
    runs: &mut dyn Runs,
    (prev, n): (&GridPoint, usize),
    t: f64,
    trail: Option<&mut Trail>,
    (k, event): (usize, &Event),
    cost: &mut Cost,
) -> Result<(Point, f64)> {
    let v = between(ctx, runs, prev, n, t, trail, Source::Answer, cost)?;
    let e = event.value(k, t, &v.y)?;
    Ok((v, e))
}

/// The bases a zero's Taylor move is tried from: the interpolant's zero, and where the
/// answer's polynomial bends too much there, the Newton point from it.
const MOVE_BASES: usize = 2;
