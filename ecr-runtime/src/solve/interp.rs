//! Values between grid points by interpolation, where it can be shown to hold: the Hermite
//! polynomial of the answer's grid states and slopes (y' = Ay + g(y) there) around t, with an
//! estimate that does not share the error it estimates. It adds up
//!
//! - the difference of the same interpolant of the check's grid states and slopes: the two
//!   runs' difference carried to t (the grid's own estimate, interpolated). In a stiff problem
//!   a slope multiplies its state's error by ‖A‖; the check's slope does the same to the
//!   check's larger error, so this term grows with it (the earlier estimate by a shifted
//!   stencil shared that error and said "within one tolerance" where the value was 179 off);
//! - the difference to the interpolant with one more grid point: the interpolation error,
//!   measured (a polynomial that does not follow the solution differs from its neighbour of
//!   two degrees more, where one that does agrees to the next terms), twice;
//! - the round-off model of the run.
//!
//! Where the estimate exceeds the tolerance the value is one step of each method from the
//! grid point before t instead. The slopes are evaluated only for the points a stencil reads
//! (two evaluations of g per point, counted with the output's).

use super::runs::estimate;

/// Points of the interpolant (values and slopes: degree `2 POINTS − 1`); the estimate's
/// interpolant has one more.
pub(super) const POINTS: usize = 5;

/// The interpolation error is taken as this many times the difference to the interpolant with
/// one more point (which, at the end of the grid, measured 0.97 of the error on sin 2t).
const SAFETY: f64 = 2.0;

/// The points an interpolant at t reads: the `POINTS + 1` from `first_x` (the estimate's),
/// among them the `POINTS` from `first` (the value's).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Stencil {
    pub(super) first: usize,
    pub(super) first_x: usize,
}

impl Stencil {
    /// The points whose slopes the interpolant needs.
    pub(super) fn range(&self) -> std::ops::Range<usize> {
        self.first_x..self.first_x + POINTS + 1
    }
}

/// The grid the interpolant reads: times and the answer's and the check's states there (flat,
/// `d` numbers per point).
pub(super) struct Grid<'a> {
    pub(super) t: &'a [f64],
    pub(super) answer: &'a [f64],
    pub(super) check: &'a [f64],
    pub(super) d: usize,
    /// How much the linear part magnifies a perturbation of a state, per component (see
    /// `runs::stiffness`): the slopes' rounding.
    pub(super) stiffness: &'a [f64],
}

/// The weights of an event scan's interpolant at its sample times ([`Grid::scan_weights`]),
/// kept while the grid's geometry stays (a constant step).
#[derive(Default)]
pub(super) struct ScanWeights {
    /// The points' and the times' places, relative to the first point, in units of the
    /// points' span.
    places: Vec<f64>,
    w: Vec<f64>,
}

impl ScanWeights {
    /// Whether these weights hold for the grid points `range` and `times` (their places
    /// agree to 1e−12 of the span: the samples only tell where to look, on the steps).
    pub(super) fn fits(
        &self,
        grid: &Grid<'_>,
        range: std::ops::Range<usize>,
        times: &[f64],
    ) -> bool {
        let xs = &grid.t[range];
        let scale = xs[xs.len() - 1] - xs[0];
        self.places.len() == xs.len() + times.len()
            && xs
                .iter()
                .chain(times)
                .zip(&self.places)
                .all(|(&x, &p)| ((x - xs[0]) / scale - p).abs() <= 1e-12)
    }
}

/// The Hermite interpolant at `t` of the values `y` and slopes `dy` (component `i` of `d`, at
/// the points `xs`), by divided differences on the doubled nodes, in the scaled variable
/// (x − xs₀)/`scale`.
fn hermite(xs: &[f64], y: &[f64], dy: &[f64], d: usize, i: usize, t: f64, scale: f64) -> f64 {
    Newton::new(xs, y, dy, d, i, scale).at(t)
}

/// The Hermite interpolant of one component in Newton's form: the doubled nodes and the
/// divided differences on them, in the scaled variable (x − xs₀)/`scale`.
struct Newton {
    z: [f64; 2 * (POINTS + 1)],
    c: [f64; 2 * (POINTS + 1)],
    n: usize,
    x0: f64,
    scale: f64,
}

impl Newton {
    fn new(xs: &[f64], y: &[f64], dy: &[f64], d: usize, i: usize, scale: f64) -> Self {
        const N: usize = 2 * (POINTS + 1);
        let m = xs.len();
        let n = 2 * m;
        let mut z = [0.0; N];
        let mut c = [0.0; N];
        for j in 0..m {
            let s = (xs[j] - xs[0]) / scale;
            z[2 * j] = s;
            z[2 * j + 1] = s;
            c[2 * j] = y[j * d + i];
            c[2 * j + 1] = y[j * d + i];
        }
        // First differences: the slope at a doubled node, the secant between nodes.
        for k in (1..n).rev() {
            c[k] = if k % 2 == 1 {
                dy[(k / 2) * d + i] * scale
            } else {
                (c[k] - c[k - 1]) / (z[k] - z[k - 1])
            };
        }
        for level in 2..n {
            for k in (level..n).rev() {
                c[k] = (c[k] - c[k - 1]) / (z[k] - z[k - level]);
            }
        }
        Newton {
            z,
            c,
            n,
            x0: xs[0],
            scale,
        }
    }

    fn at(&self, t: f64) -> f64 {
        let s = (t - self.x0) / self.scale;
        let mut p = self.c[self.n - 1];
        for k in (0..self.n - 1).rev() {
            p = p * (s - self.z[k]) + self.c[k];
        }
        p
    }
}

/// One run's Hermite interpolant on a stencil, a component at a time ([`Grid::interpolant`]).
pub(super) struct Interpolant(Vec<Newton>);

impl Interpolant {
    /// The state at `t` into `out`.
    pub(super) fn at(&self, t: f64, out: &mut [f64]) {
        for (o, newton) in out.iter_mut().zip(&self.0) {
            *o = newton.at(t);
        }
    }
}

impl Grid<'_> {
    /// The number of grid points.
    pub(super) fn len(&self) -> usize {
        self.t.len()
    }

    /// The stencil for `t`, or `None` where the grid is too short for an interpolant and its
    /// check (fewer than `POINTS + 1` points) or `t` lies outside it.
    pub(super) fn stencil(&self, t: f64) -> Option<Stencil> {
        let n = self.len();
        if n < POINTS + 1 || !(self.t[0]..=self.t[n - 1]).contains(&t) {
            return None;
        }
        // The interval [t_k, t_k+1] holding t, and the stencil centred on it.
        let k = self
            .t
            .partition_point(|&tk| tk <= t)
            .saturating_sub(1)
            .min(n - 2);
        let first = (k + 1).saturating_sub(POINTS / 2).min(n - POINTS);
        // One more point on the side nearer t (where there is one).
        let first_x = if first == 0 {
            0
        } else if first + POINTS == n || t - self.t[first - 1] < self.t[first + POINTS] - t {
            first - 1
        } else {
            first
        };
        Some(Stencil { first, first_x })
    }

    /// One run's interpolant (the check's with `check`, else the answer's) at the times
    /// `times` (in the interval of `stencil`), state after state into `out`: a start for the
    /// stage iterations of a step. A component at a time, without allocating.
    pub(super) fn states_at(
        &self,
        times: impl Iterator<Item = f64> + Clone,
        stencil: Stencil,
        slopes: (&[f64], &[f64]),
        check: bool,
        out: &mut [f64],
    ) {
        let d = self.d;
        for i in 0..d {
            let newton = self.component(stencil, slopes, check, i);
            for (j, t) in times.clone().enumerate() {
                out[j * d + i] = newton.at(t);
            }
        }
    }

    /// One run's interpolant on `stencil` (the check's with `check`, else the answer's), built
    /// once for the values at many times (an event's zero located on it).
    pub(super) fn interpolant(
        &self,
        stencil: Stencil,
        slopes: (&[f64], &[f64]),
        check: bool,
    ) -> Interpolant {
        Interpolant(
            (0..self.d)
                .map(|i| self.component(stencil, slopes, check, i))
                .collect(),
        )
    }

    /// Component `i` of one run's interpolant on `stencil`.
    fn component(
        &self,
        stencil: Stencil,
        slopes: (&[f64], &[f64]),
        check: bool,
        i: usize,
    ) -> Newton {
        let d = self.d;
        let Stencil { first, first_x } = stencil;
        let more = POINTS + 1;
        let xs = &self.t[first..first + POINTS];
        let scale = self.t[first_x + more - 1] - self.t[first_x];
        let states = if check { self.check } else { self.answer };
        let y = &states[first * d..];
        let shift = (first - first_x) * d;
        let dy = &if check { slopes.1 } else { slopes.0 }[shift..];
        Newton::new(xs, y, dy, d, i, scale)
    }

    /// The grid points an event scan at `t` reads: the interval holding t and the point after
    /// it (the one before at the grid's end; one geometry along a constant step, so the
    /// [`ScanWeights`] hold), `None` where t lies outside the grid.
    pub(super) fn scan_range(&self, t: f64) -> Option<std::ops::Range<usize>> {
        let n = self.len();
        if n < 2 || !(self.t[0]..=self.t[n - 1]).contains(&t) {
            return None;
        }
        let k = self
            .t
            .partition_point(|&tk| tk <= t)
            .saturating_sub(1)
            .min(n - 2);
        if n == 2 {
            return Some(0..2);
        }
        Some(if k + 2 == n { k - 1..k + 2 } else { k..k + 3 })
    }

    /// The weights of the Hermite interpolant on the grid points `range` (from
    /// [`scan_range`](Self::scan_range)) at `times`: for each time, two per point (the
    /// point's value's, its slope's), into `weights`, and the geometry they hold for (the
    /// points' and times' places relative to the first point and the points' span), which
    /// [`ScanWeights::fits`] compares.
    pub(super) fn scan_weights(
        &self,
        range: std::ops::Range<usize>,
        times: &[f64],
        weights: &mut ScanWeights,
    ) {
        let xs = &self.t[range];
        let m = xs.len();
        let scale = xs[m - 1] - xs[0];
        weights.places.clear();
        weights
            .places
            .extend(xs.iter().chain(times).map(|&x| (x - xs[0]) / scale));
        weights.w.clear();
        weights.w.resize(2 * m * times.len(), 0.0);
        // The basis data, one unit value or slope at a time (a scan reads at most three
        // points).
        let (mut y, mut dy) = ([0.0; 3], [0.0; 3]);
        for q in 0..2 * m {
            y.fill(0.0);
            dy.fill(0.0);
            if q % 2 == 0 {
                y[q / 2] = 1.0;
            } else {
                dy[q / 2] = 1.0;
            }
            let newton = Newton::new(xs, &y[..m], &dy[..m], 1, 0, scale);
            for (j, &t) in times.iter().enumerate() {
                weights.w[j * 2 * m + q] = newton.at(t);
            }
        }
    }

    /// The answer's Hermite interpolant on the grid points `range` at the times `weights`
    /// holds for ([`scan_weights`](Self::scan_weights)), state after state into `out`, with
    /// the answer's slopes `slopes` at those points (`d` numbers per point): where an event
    /// function is sampled inside a step.
    pub(super) fn answer_on(
        &self,
        range: std::ops::Range<usize>,
        slopes: &[f64],
        weights: &ScanWeights,
        out: &mut [f64],
    ) {
        let d = self.d;
        let m = range.len();
        let y = &self.answer[range.start * d..range.end * d];
        for (j, w) in weights.w.chunks_exact(2 * m).enumerate() {
            let o = &mut out[j * d..(j + 1) * d];
            o.fill(0.0);
            for p in 0..m {
                let (wy, ws) = (w[2 * p], w[2 * p + 1]);
                let (yp, sp) = (&y[p * d..(p + 1) * d], &slopes[p * d..(p + 1) * d]);
                for ((o, y), s) in o.iter_mut().zip(yp).zip(sp) {
                    *o += wy * y + ws * s;
                }
            }
        }
    }

    /// The answer's interpolant at `t` on `stencil` into `out` and its estimate in units of
    /// the tolerance `(rtol, atol)` (with the round-off of `steps` steps at rounding unit
    /// `unit`). `slope_answer` and `slope_check` hold the slopes at the stencil's
    /// [`range`](Stencil::range) (`d` numbers per point).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn value(
        &self,
        t: f64,
        stencil: Stencil,
        slope_answer: &[f64],
        slope_check: &[f64],
        tolerance: (f64, f64),
        unit: f64,
        steps: usize,
        out: &mut [f64],
    ) -> f64 {
        let d = self.d;
        let Stencil { first, first_x } = stencil;
        let more = POINTS + 1;
        let xs = &self.t[first..first + POINTS];
        let xx = &self.t[first_x..first_x + more];
        let scale = xx[more - 1] - xx[0];
        let (ya, yc) = (&self.answer[first * d..], &self.check[first * d..]);
        let shift = (first - first_x) * d;
        let (sa, sc) = (&slope_answer[shift..], &slope_check[shift..]);
        let yx = &self.answer[first_x * d..];
        // The slopes' rounding: a grid state known to `NOISE` units of its largest component,
        // magnified by the linear part, carried over the interval holding t (in a stiff
        // problem both runs' slopes share it, and their difference does not show it).
        let size = yx[..more * d].iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        let k = xx.partition_point(|&x| x <= t).clamp(1, more - 1);
        let width = xx[k] - xx[k - 1];
        let shaky = 2.0 * super::runs::NOISE * unit * size * width;
        let mut check = [0.0; 1];
        let mut worst = 0.0_f64;
        for (i, o) in out.iter_mut().enumerate() {
            let a = hermite(xs, ya, sa, d, i, t, scale);
            let c = hermite(xs, yc, sc, d, i, t, scale);
            let x = hermite(xx, yx, slope_answer, d, i, t, scale);
            *o = a;
            // Per component: the two differences add, the weight is the answer's.
            check[0] = a - ((a - c).abs() + SAFETY * (a - x).abs() + shaky * self.stiffness[i]);
            let e = estimate(tolerance, 0.0, &[a], &check, 0);
            worst = if e > worst || e.is_nan() { e } else { worst };
        }
        // The round-off model, over the whole state (it mixes the components).
        let noise = estimate(tolerance, unit, out, out, steps);
        worst + noise
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(grid: &Grid<'_>, f: &dyn Fn(f64) -> f64, x: f64, tol: f64) -> Option<(f64, f64)> {
        let stencil = grid.stencil(x)?;
        let slopes: Vec<f64> = grid.t[stencil.range()].iter().map(|&t| f(t)).collect();
        let mut out = [0.0];
        let e = grid.value(
            x,
            stencil,
            &slopes,
            &slopes,
            (tol, tol),
            f64::EPSILON,
            10,
            &mut out,
        );
        Some((out[0], e))
    }

    /// A polynomial of degree < 2 POINTS is reproduced to rounding, with a tiny estimate; a
    /// smooth function the grid resolves is within its estimate; one it does not resolve gets
    /// an estimate above its true error.
    #[test]
    fn polynomials_are_exact_and_unresolved_functions_are_flagged() {
        let t: Vec<f64> = (0..20)
            .map(|k| 0.3 * k as f64 + 0.01 * (k * k) as f64)
            .collect();
        let poly = |x: f64| 1.0 + x - 0.5 * x * x + 0.1 * x.powi(3) - 0.01 * x.powi(9);
        let dpoly = |x: f64| 1.0 - x + 0.3 * x * x - 0.09 * x.powi(8);
        let answer: Vec<f64> = t.iter().map(|&x| poly(x)).collect();
        let grid = Grid {
            t: &t,
            answer: &answer,
            check: &answer,
            d: 1,
            stiffness: &[0.0],
        };
        for x in [0.05, 2.345, t[19] - 0.01] {
            let (v, e) = at(&grid, &dpoly, x, 1e-10).unwrap();
            assert!(
                (v - poly(x)).abs() <= 1e-11 * poly(x).abs().max(1.0),
                "{x}: {v}"
            );
            assert!(e < 1e-2, "{e}");
        }
        // sin(2x): resolved at 1e-6; the estimate is above the error.
        let slow: Vec<f64> = t.iter().map(|&x| (2.0 * x).sin()).collect();
        let grid = Grid {
            t: &t,
            answer: &slow,
            check: &slow,
            d: 1,
            stiffness: &[0.0],
        };
        for x in [1.111, 2.345, 3.7, t[19] - 0.01] {
            let (v, e) = at(&grid, &|x| 2.0 * (2.0 * x).cos(), x, 1e-6).unwrap();
            let err = (v - (2.0 * x).sin()).abs() / (1e-6 * (1.0 + v.abs()));
            assert!(e >= err && e < 1.0, "t = {x}: estimate {e}, error {err}");
        }
        // sin(20 t) on this grid: far from resolved; the estimate says so.
        let fast: Vec<f64> = t.iter().map(|&x| (20.0 * x).sin()).collect();
        let grid = Grid {
            t: &t,
            answer: &fast,
            check: &fast,
            d: 1,
            stiffness: &[0.0],
        };
        for x in [1.111, 2.345, 3.7] {
            let (v, e) = at(&grid, &|x| 20.0 * (20.0 * x).cos(), x, 1e-6).unwrap();
            let err = (v - (20.0 * x).sin()).abs() / (1e-6 * (1.0 + v.abs()));
            assert!(e > 1.0, "t = {x}: estimate {e}, error {err}");
        }
        // Outside the grid or on too short a grid: no stencil.
        assert!(grid.stencil(-1.0).is_none());
        let short = Grid {
            t: &t[..POINTS],
            answer: &fast[..POINTS],
            check: &fast[..POINTS],
            d: 1,
            stiffness: &[0.0],
        };
        assert!(short.stencil(1.0).is_none());
    }
}
