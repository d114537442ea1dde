//! The estimate of the answer's error from the differences between the runs, the order they
//! show, the round-off floor, and its projection to the end of the span.

/// `x ≤ limit`, false for a NaN: the comparison whose failure means "not verified".
pub(super) fn at_most(x: f64, limit: f64) -> bool {
    x <= limit
}

/// The estimate a verified run aims at, in units of the tolerance.
pub(super) const TARGET: f64 = 0.5;

/// Running maxima over the points the grids of all three runs share (every 6h): the scaled
/// differences answer–2h (`fine`) and 2h–3h (`coarse`), and the round-off model there.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Maxima {
    pub(super) fine: f64,
    pub(super) coarse: f64,
    pub(super) noise: f64,
    /// The two differences at the last meeting point.
    pub(super) last: (f64, f64),
}

impl Maxima {
    /// The observed order q within [0, p]: with errors C h^q, the 2h–3h difference over the
    /// h–2h difference is (3^q − 2^q) / (2^q − 1), increasing in q. `None` while the
    /// differences are at round-off level.
    pub(super) fn order(&self, p: f64) -> Option<f64> {
        if self.coarse <= 4.0 * self.noise || self.coarse == 0.0 {
            return None;
        }
        if self.fine == 0.0 {
            return Some(p);
        }
        let q = order_of_ratio(self.coarse / self.fine, p);
        // Where the differences are now near their largest, the order they show there too:
        // once amplified round-off dominates them (chaotic motion at a tight tolerance) they
        // no longer shrink with the step there, though they did where they were largest before.
        let (fine, coarse) = self.last;
        if fine >= 0.25 * self.fine && coarse > 4.0 * self.noise {
            return Some(q.min(order_of_ratio(coarse / fine, p)));
        }
        Some(q)
    }
}

/// The q in [0, p] with (3^q − 2^q) / (2^q − 1) = ratio (0 below the value at q → 0,
/// log(3/2)/log 2; p above the value at p), by bisection.
pub(super) fn order_of_ratio(ratio: f64, p: f64) -> f64 {
    let f = |q: f64| (3f64.powf(q) - 2f64.powf(q)) / (2f64.powf(q) - 1.0);
    if at_most(ratio, (1.5f64).ln() / 2f64.ln()) || ratio.is_nan() {
        return 0.0;
    }
    if ratio >= f(p) {
        return p;
    }
    let (mut lo, mut hi) = (1e-9, p);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if f(mid) < ratio {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The step-size law of a verified run: error ∝ h^q.
pub(super) fn rescale(h: f64, ratio: f64, q: f64) -> f64 {
    h * ratio.powf(1.0 / q.max(1.0))
}

/// The Richardson divisor 2^q − 1 for an observed order q, at least 1: where no order shows
/// (the differences are at round-off level, or do not shrink with the step) the difference
/// itself is the estimate.
pub(super) fn divisor(order: Option<f64>) -> f64 {
    order.map_or(1.0, |q| (2f64.powf(q) - 1.0).max(1.0))
}

/// The estimate of a point in tolerance units: the Richardson estimate, not below the
/// round-off model.
pub(super) fn estimate(diff: f64, noise: f64, div: f64) -> f64 {
    let e = diff / div;
    if e.is_nan() { e } else { e.max(noise) }
}

/// The round-off model at the end of the span: like the rounding of the steps, growing with
/// the square root of the time.
pub(super) fn project_noise(history: &[(f64, f64)], noise: f64, span: f64) -> f64 {
    history
        .last()
        .map_or(noise, |&(t, _)| noise * (span / t).sqrt())
}

/// The value of `xs` at quantile `level` in [0, 1] (0 for none), reordering them.
pub(super) fn quantile(xs: &mut [f64], level: f64) -> f64 {
    if xs.is_empty() {
        return 0.0;
    }
    if xs.iter().any(|x| x.is_nan()) {
        return f64::NAN;
    }
    xs.sort_by(f64::total_cmp);
    let k = ((xs.len() - 1) as f64 * level.clamp(0.0, 1.0)).round() as usize;
    xs[k]
}

/// The largest estimate at the end of the span, from its growth so far: E(τ) ∝ τ^α, α from
/// the last point and the one nearest half its time (within [0, 2]; ½ — between a bounded
/// error and a linearly growing one — with too little history).
///
/// A truncation error that grows exponentially for a while (near an unstable equilibrium, at
/// a close passage) usually stops growing so; projecting that rate over the whole span asks
/// for steps so small that the runs differ by rounding only. The power law is followed
/// instead, and the chunks that come check it.
pub(super) fn project(history: &[(f64, f64)], span: f64) -> f64 {
    let Some(&(tk, ek)) = history.last() else {
        return 0.0;
    };
    let half = history
        .iter()
        .rev()
        .find(|(t, _)| *t <= 0.5 * tk)
        .filter(|(_, e)| *e > 0.0);
    let alpha = half.map_or(0.5, |&(t, e)| {
        ((ek / e).ln() / (tk / t).ln()).clamp(0.0, 2.0)
    });
    ek * (span / tk).powf(alpha)
}

/// As [`project`], but where the last stretch grew faster than τ² (rounding amplified by an
/// instability or chaos) at that exponential rate: whether the rounding may reach the
/// tolerance, which the solve then measures by running on to the end of the span once.
pub(super) fn project_steep(history: &[(f64, f64)], span: f64) -> f64 {
    let power = project(history, span);
    let n = history.len();
    let Some(&(tk, ek)) = history.last() else {
        return power;
    };
    let steep = (n >= 2)
        .then(|| history[n - 2])
        .filter(|&(t, e)| e > 0.0 && t > 0.0 && tk > t && ek > e * (tk / t).powi(2))
        .map_or(0.0, |(t, e)| {
            let rate = (ek / e).ln() / (tk - t);
            ek * (rate * (span - tk)).min(700.0).exp()
        });
    power.max(steep)
}

/// What an attempt of the verified run (or a pilot) saw: its step size, the order its
/// differences showed, and the controlled estimate after each kept chunk (time since t₀,
/// estimate), up to where it got.
#[derive(Clone, Debug)]
pub(super) struct Profile {
    pub(super) h: f64,
    pub(super) order: Option<f64>,
    pub(super) points: Vec<(f64, f64)>,
}

impl Profile {
    /// The estimate it had at time `t` since t₀ (its points are running maxima): geometric
    /// interpolation between the points around t; the last point if it is at 0.9 t or later;
    /// `None` if it did not get that far.
    pub(super) fn at(&self, t: f64) -> Option<f64> {
        let k = self.points.partition_point(|&(tp, _)| tp < t);
        match (k.checked_sub(1).map(|i| self.points[i]), self.points.get(k)) {
            (_, Some(&(tp, e))) if tp == t => Some(e),
            (Some((ta, ea)), Some(&(tb, eb))) if ea > 0.0 && eb > 0.0 => {
                let w = (t - ta) / (tb - ta);
                Some(ea * (eb / ea).powf(w))
            }
            (_, Some(&(_, eb))) => Some(eb),
            (Some((ta, ea)), None) if ta >= 0.9 * t => Some(ea),
            _ => None,
        }
    }

    /// The estimate this profile predicts at the end of the span for a run of step `h` with
    /// nominal order `p`: its own projection to the end, scaled by (h/h_P)^q — q the order it
    /// showed (at least 1) for a smaller step, p for a larger one (the less favourable in each
    /// direction).
    pub(super) fn predict(&self, h: f64, p: f64, span: f64) -> f64 {
        let end = project(&self.points, span);
        let ratio = h / self.h;
        let q = if ratio < 1.0 {
            self.order.unwrap_or(1.0).clamp(1.0, p)
        } else {
            p
        };
        end * ratio.powf(q)
    }
}
