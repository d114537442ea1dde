//! Values between grid points by interpolation, where it can be shown to hold: the Lagrange
//! polynomial of the answer's grid states around t, with an estimate that does not share the
//! error it estimates. It adds up
//!
//! - the difference of the same interpolant of the check's grid states: the two runs'
//!   difference carried to t (the grid's own estimate, interpolated);
//! - the difference to the interpolant with one more grid point: the interpolation error,
//!   measured (a polynomial that does not follow the solution differs from its neighbour of one
//!   degree more, where one that does agrees to the next term);
//! - the round-off model of the run.
//!
//! Values only, no derivatives: in a stiff problem y' = Ay + g(y) the derivative at a grid
//! point multiplies the grid value's error by ‖A‖ (a Hermite interpolant through them was off
//! by 179 tolerances at λ = −1e8 while its estimate said it was within one), and costs an
//! evaluation of g per grid point besides. Where the estimate exceeds the tolerance the value
//! is one step of each method from the grid point before t instead.

use super::runs::estimate;

/// Points of the interpolant (degree `POINTS − 1`); the estimate's interpolant has one more.
pub(super) const POINTS: usize = 8;

/// The grid the interpolant reads: times and the answer's and the check's states there (flat,
/// `d` numbers per point).
pub(super) struct Grid<'a> {
    pub(super) t: &'a [f64],
    pub(super) answer: &'a [f64],
    pub(super) check: &'a [f64],
    pub(super) d: usize,
}

/// The Lagrange weights at `t` of the nodes `xs` into `w`.
fn weights(xs: &[f64], t: f64, w: &mut [f64]) {
    for (j, wj) in w.iter_mut().enumerate().take(xs.len()) {
        let mut l = 1.0;
        for (k, &xk) in xs.iter().enumerate() {
            if k != j {
                l *= (t - xk) / (xs[j] - xk);
            }
        }
        *wj = l;
    }
}

impl Grid<'_> {
    /// The number of grid points.
    pub(super) fn len(&self) -> usize {
        self.t.len()
    }

    /// The answer's interpolant at `t` into `out` and its estimate in units of the tolerance
    /// `(rtol, atol)` (with the round-off of `steps` steps at rounding unit `unit`), or `None`
    /// where the grid is too short for an interpolant and its check (fewer than `POINTS + 1`
    /// points) or `t` lies outside it.
    pub(super) fn value(
        &self,
        t: f64,
        tolerance: (f64, f64),
        unit: f64,
        steps: usize,
        out: &mut [f64],
    ) -> Option<f64> {
        let n = self.len();
        let d = self.d;
        if n < POINTS + 1 || out.len() != d || !(self.t[0]..=self.t[n - 1]).contains(&t) {
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
        let (first_x, more) = if first == 0 {
            (0, POINTS + 1)
        } else if first + POINTS == n || t - self.t[first - 1] < self.t[first + POINTS] - t {
            (first - 1, POINTS + 1)
        } else {
            (first, POINTS + 1)
        };
        let mut w = [0.0; POINTS];
        let mut wx = [0.0; POINTS + 1];
        weights(&self.t[first..first + POINTS], t, &mut w);
        weights(&self.t[first_x..first_x + more], t, &mut wx);
        let mut check = [0.0; 1];
        let mut worst = 0.0_f64;
        for (i, o) in out.iter_mut().enumerate() {
            let (mut a, mut c, mut x) = (0.0, 0.0, 0.0);
            for (j, wj) in w.iter().enumerate() {
                a += wj * self.answer[(first + j) * d + i];
                c += wj * self.check[(first + j) * d + i];
            }
            for (j, wj) in wx.iter().enumerate() {
                x += wj * self.answer[(first_x + j) * d + i];
            }
            *o = a;
            // Per component: the two differences add, the weight is the answer's.
            check[0] = a - ((a - c).abs() + (a - x).abs());
            let e = estimate(tolerance, 0.0, &[a], &check, 0);
            worst = if e > worst || e.is_nan() { e } else { worst };
        }
        // The round-off model, over the whole state (it mixes the components).
        let noise = estimate(tolerance, unit, out, out, steps);
        Some(worst + noise)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A polynomial of degree < POINTS is reproduced to rounding, with a tiny estimate; a
    /// function the grid does not resolve gets an estimate above its true error.
    #[test]
    fn polynomials_are_exact_and_unresolved_functions_are_flagged() {
        let t: Vec<f64> = (0..20)
            .map(|k| 0.3 * k as f64 + 0.01 * (k * k) as f64)
            .collect();
        let cubic = |x: f64| 1.0 + x - 0.5 * x * x + 0.1 * x * x * x;
        let answer: Vec<f64> = t.iter().map(|&x| cubic(x)).collect();
        let grid = Grid {
            t: &t,
            answer: &answer,
            check: &answer,
            d: 1,
        };
        let mut out = [0.0];
        let e = grid
            .value(2.345, (1e-10, 1e-10), f64::EPSILON, 10, &mut out)
            .unwrap();
        assert!(
            (out[0] - cubic(2.345)).abs() <= 1e-12 * cubic(2.345).abs(),
            "{out:?}"
        );
        assert!(e < 1e-2, "{e}");
        // sin(20 t) on this grid: far from resolved; the estimate says so.
        let fast: Vec<f64> = t.iter().map(|&x| (20.0 * x).sin()).collect();
        let grid = Grid {
            t: &t,
            answer: &fast,
            check: &fast,
            d: 1,
        };
        for x in [1.111, 2.345, 3.7] {
            let e = grid
                .value(x, (1e-6, 1e-6), f64::EPSILON, 10, &mut out)
                .unwrap();
            let err = (out[0] - (20.0 * x).sin()).abs() / (1e-6 * (1.0 + out[0].abs()));
            assert!(e > 1.0, "t = {x}: estimate {e}, error {err}");
        }
        // Outside the grid or on too short a grid: no interpolant.
        assert!(
            grid.value(-1.0, (1e-6, 1e-6), f64::EPSILON, 10, &mut out)
                .is_none()
        );
        let short = Grid {
            t: &t[..POINTS],
            answer: &fast[..POINTS],
            check: &fast[..POINTS],
            d: 1,
        };
        assert!(
            short
                .value(1.0, (1e-6, 1e-6), f64::EPSILON, 10, &mut out)
                .is_none()
        );
    }
}
