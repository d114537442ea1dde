//! Events: the zeros of user functions e(t, y), located on the continuous solution: first on
//! the grid's interpolant, then, where it does not serve, on the runs' steps ([`hit`]).

use super::between::{INTERP_MAX, Source, Trail, between, between_into};
use super::record::Point;
use super::runs::{Cost, Runs, estimate};
use super::window::{Ctx, GridPoint};
use crate::error::{Error, Result};

/// Which sign changes of an event function count.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// From negative to positive and from positive to negative.
    Both,
    /// From negative to positive only.
    Rising,
    /// From positive to negative only.
    Falling,
}

/// An event function e(t, y). `Send + Sync`, so that [`Options`](super::Options) holding it
/// can be shared by the threads that solve the members of an ensemble.
type EventFn = Box<dyn Fn(f64, &[f64]) -> f64 + Send + Sync>;

/// A user function e(t, y) whose sign changes are located during the integration.
pub struct Event {
    f: EventFn,
    pub(super) terminal: bool,
    direction: Direction,
}

impl Event {
    /// An event at the zeros of `f(t, y)`: its sign changes along the solution, looked for at
    /// the grid points and at four points inside each step on the grid's interpolant (a zero
    /// touched without a sign change is not seen, nor two zeros closer together than a fifth
    /// of a step that the interpolant misses). A NaN from `f` is an error of the solve. `f` is `Send + Sync` (it captures no
    /// `Rc` or `Cell`): the options that hold it may be shared between threads.
    pub fn new(f: impl Fn(f64, &[f64]) -> f64 + Send + Sync + 'static) -> Self {
        Event {
            f: Box::new(f),
            terminal: false,
            direction: Direction::Both,
        }
    }

    /// Stops the integration at the first such zero.
    #[must_use]
    pub fn terminal(mut self) -> Self {
        self.terminal = true;
        self
    }

    /// Only sign changes in this direction count.
    #[must_use]
    pub fn direction(mut self, direction: Direction) -> Self {
        self.direction = direction;
        self
    }

    /// e(t, y); a NaN is an error naming the event and the time.
    pub(super) fn value(&self, index: usize, t: f64, y: &[f64]) -> Result<f64> {
        let v = (self.f)(t, y);
        if v.is_nan() {
            return Err(Error::InvalidInput(format!(
                "event function {index} returned NaN at t = {t:?}"
            )));
        }
        Ok(v)
    }

    pub(super) fn counts(&self, before: f64, after: f64) -> bool {
        let rising = before < 0.0 && after >= 0.0;
        let falling = before > 0.0 && after <= 0.0;
        match self.direction {
            Direction::Both => rising || falling,
            Direction::Rising => rising,
            Direction::Falling => falling,
        }
    }

    /// The time of the zero between (t_a, e_a) and (t_b, e_b), by the Illinois variant of
    /// regula falsi, `eval(t)` giving e at t, to a few ulps of t: the end of the bracket on the
    /// far side, the first time the sign changed. Regula falsi alone creeps at a flat (multiple)
    /// zero, so a bisection is taken whenever three steps have not halved the bracket, and a
    /// point within half the final width of an end is moved that far past it: at most about
    /// 4 x 64 evaluations, usually fewer than 10 (from a bracket a few interpolation errors
    /// wide around a simple zero, 2 or 3).
    pub(super) fn locate<E>(
        &self,
        a: (f64, f64),
        b: (f64, f64),
        eval: impl FnMut(f64) -> std::result::Result<f64, E>,
    ) -> std::result::Result<f64, E> {
        self.locate_within(4.0, a, b, eval)
    }

    /// [`locate`](Self::locate) to `ulps` units of roundoff of t (a function known only to
    /// its own rounding, such as the runs' steps, is searched to a wider bracket than one
    /// computed exactly: below its rounding the signs are noise, and regula falsi creeps).
    pub(super) fn locate_within<E>(
        &self,
        ulps: f64,
        (ta, ea): (f64, f64),
        (tb, eb): (f64, f64),
        mut eval: impl FnMut(f64) -> std::result::Result<f64, E>,
    ) -> std::result::Result<f64, E> {
        if eb == 0.0 {
            return Ok(tb);
        }
        let (mut a, mut fa, mut b, mut fb) = (ta, ea, tb, eb);
        let mut side = 0i8;
        let (mut width, mut since, mut nudges) = (b - a, 0, 0u32);
        loop {
            let tol = ulps * f64::EPSILON * a.abs().max(b.abs());
            if b - a <= tol {
                break;
            }
            // Regula falsi, or a bisection where three steps have not halved the bracket. A
            // point within a least step of an end leaves the other end where it is (regula
            // falsi converges from one side, and so would the bisections after it): the least
            // step past that end instead, doubled at each such point in a row, where it most
            // likely closes the bracket (Dekker's least step).
            let falsi = b - fb * (b - a) / (fb - fa);
            let mid = a.midpoint(b);
            let least = 0.5 * tol * f64::from(1u32 << nudges.min(30));
            let mut c = if since >= 3 || !(falsi > a && falsi < b) {
                mid
            } else {
                falsi
            };
            if (a..=b).contains(&falsi) && (falsi - a < least || b - falsi < least) {
                c = if falsi - a < least {
                    (a + least).min(mid)
                } else {
                    (b - least).max(mid)
                };
                nudges += 1;
            } else {
                nudges = 0;
            }
            let fc = eval(c)?;
            if fc == 0.0 {
                return Ok(c);
            }
            if (fc < 0.0) == (fa < 0.0) {
                a = c;
                fa = fc;
                if side == -1 {
                    fb *= 0.5;
                }
                side = -1;
            } else {
                b = c;
                fb = fc;
                if side == 1 {
                    fa *= 0.5;
                }
                side = 1;
            }
            if b - a <= 0.5 * width {
                (width, since) = (b - a, 0);
            } else {
                since += 1;
            }
            if c == a.midpoint(b) && since > 3 {
                // A bisection that could not shrink the bracket: a and b are neighbours.
                break;
            }
        }
        Ok(b)
    }
}

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
            let e = (event.f)(t, &states[i * d..(i + 1) * d]);
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
            let mut y = vec![0.0; d];
            let mut on_interp = |t: f64| {
                grid.states_at(std::iter::once(t), stencil, slopes, false, &mut y);
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

/// Where the search on the runs' steps starts: the interpolant's zero t₀, the event function
/// on the answer's step there, the event's slope on the interpolant, the step's bracket.
struct Near {
    t0: f64,
    e0: f64,
    slope: f64,
    bracket: (f64, f64),
}

/// The bases a zero's Taylor move is tried from: the interpolant's zero, and where the
/// answer's polynomial bends too much there, the Newton point from it.
const MOVE_BASES: usize = 2;

/// The Taylor polynomial of a run's value is used only where its quadratic term changes the
/// slope by at most this share over the move (so its cubic term is smaller still by about as
/// much: the residual's bound of what it leaves is then its leading term).
const MOVE_BEND: f64 = 0.05;

/// What a move may add to a value's estimate, in tolerances (beyond it the search goes on on
/// the steps, whose values carry no such term).
const MOVE_REST: f64 = 0.05;

/// A run's second-order Taylor polynomial `Y(s) = y + s f + ½ s² f'` at its value y at t₀:
/// the slope f = Ay + g(y) there and half the slope's change per unit time, f' from the slope
/// at the Euler point of the Newton correction δ ([`correction`]; two evaluations of g).
/// `None` where the slope changes by more than [`MOVE_BEND`] of its size over δ.
struct Taylor {
    f: Vec<f64>,
    half: Vec<f64>,
}

impl Taylor {
    fn new(runs: &mut dyn Runs, y: &[f64], delta: f64, cost: &mut Cost) -> Result<Option<Self>> {
        let d = y.len();
        let mut f = vec![0.0; d];
        runs.slope(y, &mut f, cost)?;
        let euler: Vec<f64> = y.iter().zip(&f).map(|(a, b)| a + delta * b).collect();
        let mut fe = vec![0.0; d];
        runs.slope(&euler, &mut fe, cost)?;
        let size = f.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        let bend = f
            .iter()
            .zip(&fe)
            .fold(0.0_f64, |m, (a, b)| m.max((b - a).abs()));
        if bend.is_nan() || bend > MOVE_BEND * size {
            return Ok(None);
        }
        let half = f
            .iter()
            .zip(&fe)
            .map(|(a, b)| 0.5 * (b - a) / delta)
            .collect();
        Ok(Some(Taylor { f, half }))
    }

    /// Y(s) from y into `out`.
    fn at(&self, y: &[f64], s: f64, out: &mut [f64]) {
        for (((o, y), f), q) in out.iter_mut().zip(y).zip(&self.f).zip(&self.half) {
            *o = y + s * (f + s * q);
        }
    }

    /// The largest of |s| |f(Y(s)) − Y'(s)| over the components, each in units of the
    /// tolerance at `weight`'s value (one evaluation of g): the residual of the ODE, zero at
    /// s = 0 and growing like s², whose integral over the move, at most |s| times its value at
    /// s, is the polynomial's distance from the flow of y (three times that of a residual
    /// growing exactly like s²).
    fn rest(
        &self,
        runs: &mut dyn Runs,
        ys: &[f64],
        s: f64,
        (rtol, atol): (f64, f64),
        weight: &[f64],
        cost: &mut Cost,
    ) -> Result<f64> {
        let mut fy = vec![0.0; ys.len()];
        runs.slope(ys, &mut fy, cost)?;
        let mut rest = 0.0_f64;
        for (i, fy) in fy.iter().enumerate() {
            let r = (fy - (self.f[i] + 2.0 * s * self.half[i])).abs() * s.abs();
            if r > 0.0 {
                rest = rest.max(r / (atol + rtol * weight[i].abs()));
            }
        }
        Ok(rest)
    }
}

/// The Newton correction from t₀, where it stays inside the step.
fn correction(near: &Near) -> Option<f64> {
    let delta = -near.e0 / near.slope;
    let t1 = near.t0 + delta;
    (delta.is_finite() && delta != 0.0 && t1 > near.bracket.0 && t1 < near.bracket.1)
        .then_some(delta)
}

/// The zero near t₀ without further steps: the answer's value `ya` there moved along the field
/// by its [`Taylor`] polynomial `pa`, the zero of e(t₀ + s, Y(s)) located on it to a few ulps,
/// the check's value `check` (where the run is checked) moved by its own to the same time. The
/// value's estimate is the runs' difference there plus each polynomial's bound of what it
/// leaves ([`Taylor::rest`]). `None` where that does not apply: the polynomial's values do not
/// bracket the zero within four corrections, or the bound exceeds [`MOVE_REST`] and the
/// estimate with it exceeds [`INTERP_MAX`]; then the search goes on on the steps.
///
/// The steps' own values near t₀ differ from the flow of their value at t₀ by what the
/// method's error changes over s, a share s/h of an error already within the estimate.
#[allow(clippy::too_many_arguments)]
fn moved_zero(
    ctx: &Ctx<'_>,
    runs: &mut dyn Runs,
    (k, event): (usize, &Event),
    near: &Near,
    (ya, pa): (&[f64], &Taylor),
    check: Option<(&[f64], &Taylor)>,
    n: usize,
    cost: &mut Cost,
) -> Result<Option<Point>> {
    let &Near {
        t0,
        e0,
        bracket: (lo, hi),
        ..
    } = near;
    let Some(delta) = correction(near) else {
        return Ok(None);
    };
    let d = ya.len();
    let mut y = vec![0.0; d];
    let mut e_at = |t: f64| -> Result<f64> {
        pa.at(ya, t - t0, &mut y);
        event.value(k, t, &y)
    };
    // A bracket of the zero on the polynomial: t₀ and the Newton point, or a secant point
    // beyond it, overshooting the secant's zero twofold (where the secant converges, its
    // zero is much nearer than its last correction), within four corrections of t₀.
    let (mut last, mut cur) = ((t0, e0), (t0 + delta, e_at(t0 + delta)?));
    let mut far = None;
    for _ in 0..3 {
        if cur.1 == 0.0 || (cur.1 < 0.0) != (e0 < 0.0) {
            far = Some(cur);
            break;
        }
        let step = -cur.1 * (cur.0 - last.0) / (cur.1 - last.1);
        let t = cur.0 + 2.0 * step;
        if !(t > lo && t < hi && (t - t0).abs() <= 4.0 * delta.abs()) {
            break;
        }
        last = cur;
        cur = (t, e_at(t)?);
    }
    let Some(far) = far else {
        return Ok(None);
    };
    let (a, b) = if far.0 > t0 {
        ((t0, e0), far)
    } else {
        (far, (t0, e0))
    };
    let t = event.locate(a, b, &mut e_at)?;
    let s = t - t0;
    let mut y = vec![0.0; d];
    pa.at(ya, s, &mut y);
    let Some((yc, pc)) = check.filter(|_| ctx.verified) else {
        return Ok(Some(Point { t, y, est: 0.0 }));
    };
    let mut c = vec![0.0; d];
    pc.at(yc, s, &mut c);
    let tolerance = (ctx.options.rtol, ctx.options.atol);
    let rest = pa
        .rest(runs, &y, s, tolerance, &y, cost)?
        .max(pc.rest(runs, &c, s, tolerance, &y, cost)?);
    let est = estimate(tolerance, ctx.unit, &y, &c, n + 1) + rest;
    if !est.is_finite() || (rest > MOVE_REST && est > INTERP_MAX) {
        return Ok(None);
    }
    Ok(Some(Point { t, y, est }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Zeros of x^m − c (simple and flat ones): found to a few ulps in few evaluations.
    #[test]
    fn locate_finds_simple_and_multiple_zeros_to_a_few_ulps() {
        let event = Event::new(|_, _| 0.0);
        for m in [1, 3, 5, 9] {
            for root in [0.3_f64, std::f64::consts::FRAC_PI_2, 1e3 + 0.1] {
                let f = |t: f64| (t - root).powi(m);
                let mut n = 0;
                let t = event
                    .locate(
                        (root - 0.7, f(root - 0.7)),
                        (root + 0.2, f(root + 0.2)),
                        |t| {
                            n += 1;
                            Ok::<_, ()>(f(t))
                        },
                    )
                    .unwrap();
                // The bracket ends where f changes sign, which for a flat zero is a band of
                // times whose f underflows or rounds to zero.
                let band = if m == 1 {
                    8.0 * f64::EPSILON * root
                } else {
                    f64::MIN_POSITIVE.powf(1.0 / m as f64) + 8.0 * f64::EPSILON * root
                };
                assert!(
                    (t - root).abs() <= band,
                    "m = {m}, root {root}: {t} ({n} evaluations)"
                );
                assert!(n <= 4 * 64, "m = {m}: {n} evaluations");
                if m == 1 {
                    assert!(n <= 12, "simple zero: {n} evaluations");
                }
            }
        }
    }

    /// A zero within an ulp of one end (regula falsi lands on that end; the Illinois halving
    /// and the bisections after it would creep in from the other): Dekker's least step past
    /// the end closes the bracket at once.
    #[test]
    fn locate_closes_a_bracket_whose_zero_is_at_one_end() {
        let event = Event::new(|_, _| 0.0);
        let b = 7.737_825_807_870_479_f64;
        let a = b - 3.5e-12;
        // The zero a quarter of an ulp of b below it: f(b) rounds to −0.
        let f = |t: f64| (t - b) + 2e-16;
        let mut n = 0;
        let t = event
            .locate((a, f(a)), (b, -1e-16), |t| {
                n += 1;
                Ok::<_, ()>(f(t))
            })
            .unwrap();
        assert!(
            (t - b).abs() <= 8.0 * f64::EPSILON * b,
            "{t} ({n} evaluations)"
        );
        assert!(n <= 3, "{n} evaluations");
    }

    /// A function known to its rounding only (a linear one with a deterministic noise of 1e−14,
    /// as values of the runs' steps are): to 64 ulps in a few evaluations from a bracket a few
    /// interpolation errors wide.
    #[test]
    fn locate_within_a_noisy_function_stops_at_its_width() {
        let event = Event::new(|_, _| 0.0);
        let root = 12.155_801_318_3_f64;
        let f = |t: f64| -0.5 * (t - root) + 1e-14 * (t * 1e9).sin();
        let mut n = 0;
        let (a, b) = (root - 7e-8, root + 7e-8);
        let t = event
            .locate_within(64.0, (a, f(a)), (b, f(b)), |t| {
                n += 1;
                Ok::<_, ()>(f(t))
            })
            .unwrap();
        assert!(
            (t - root).abs() <= 64.0 * f64::EPSILON * root + 4e-14,
            "{t}, {n} evaluations"
        );
        assert!(n <= 6, "{n} evaluations");
    }
}

impl std::fmt::Debug for Event {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Event")
            .field("terminal", &self.terminal)
            .field("direction", &self.direction)
            .finish_non_exhaustive()
    }
}

/// A located zero of an event function.
#[derive(Clone, Debug, PartialEq)]
pub struct EventHit {
    /// The index of the event (in the order given to
    /// [`Options::event`](super::Options::event)).
    pub event: usize,
    /// The time of the zero.
    pub t: f64,
    /// The state there.
    pub y: Vec<f64>,
}
