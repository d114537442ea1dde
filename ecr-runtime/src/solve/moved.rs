//! A zero near a run's value moved to without further steps: each run's second-order Taylor
//! polynomial from its value at the interpolant's zero, with an a posteriori bound of what it
//! leaves (used by [`super::hits::hit`]).

use super::between::INTERP_MAX;
use super::events::Event;
use super::record::Point;
use super::runs::{Cost, Runs, estimate};
use super::window::Ctx;
use crate::error::Result;

/// Where the search on the runs' steps starts: the interpolant's zero t₀, the event function
/// on the answer's step there, the event's slope on the interpolant, the step's bracket.
pub(super) struct Near {
    pub(super) t0: f64,
    pub(super) e0: f64,
    pub(super) slope: f64,
    pub(super) bracket: (f64, f64),
}

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
pub(super) struct Taylor {
    f: Vec<f64>,
    half: Vec<f64>,
}

impl Taylor {
    pub(super) fn new(
        runs: &mut dyn Runs,
        y: &[f64],
        delta: f64,
        cost: &mut Cost,
    ) -> Result<Option<Self>> {
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
pub(super) fn correction(near: &Near) -> Option<f64> {
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
pub(super) fn moved_zero(
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
