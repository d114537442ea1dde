//! The answer's recent grid points, for its values between them: Hermite interpolation of the
//! grid states and their derivatives f = Ay + g(y) on a stencil of consecutive points around
//! the time asked for ([`hermite`](super::hermite)), with an estimate of the interpolation's
//! own error from a second stencil shifted by one point.

use std::collections::VecDeque;

use super::hermite::weights;
use crate::operator::LinearOperator;
use crate::system::System;

/// What the check knows at a meeting point of the answer and its 2h run.
#[derive(Clone, Debug)]
pub(super) struct MeetData {
    /// The scaled difference to the 2h run.
    pub(super) diff: f64,
    /// The round-off model there.
    pub(super) noise: f64,
    /// The 2h run's state.
    pub(super) check: Vec<f64>,
}

/// A grid point of the answer.
#[derive(Clone, Debug)]
pub(super) struct GridPoint {
    pub(super) t: f64,
    pub(super) y: Vec<f64>,
    /// f = Ay + g(y), computed when a stencil first needs it.
    pub(super) f: Option<Vec<f64>>,
    /// At a meeting point with the 2h run: what the check knows there.
    pub(super) meet: Option<MeetData>,
}

/// The stencil width (points) for order 2r: Hermite interpolation of degree 2W − 1, at least
/// the method's order, with points enough that its error constant stays small.
pub(super) fn stencil_width(r: usize) -> usize {
    (r + 1).max(8)
}

/// The last grid points of the answer (a sliding window of `keep` points).
#[derive(Clone, Debug)]
pub(super) struct Trail {
    pub(super) points: VecDeque<GridPoint>,
    keep: usize,
    /// Buffers of points that left the window, for reuse.
    spare: Vec<Vec<f64>>,
    /// Scratch for a second interpolant.
    other: Vec<f64>,
}

/// The widest stencil.
const MAX_WIDTH: usize = 16;

/// A value between grid points: the interpolated state and the scaled size of the
/// interpolation's estimated error (in tolerance units), with the check's data of the meeting
/// points the stencil holds (the largest difference and round-off model).
pub(super) struct Interpolated {
    pub(super) interp: f64,
    pub(super) diff: f64,
    pub(super) noise: f64,
}

impl Trail {
    pub(super) fn new(keep: usize) -> Self {
        Trail {
            points: VecDeque::with_capacity(keep + 1),
            keep,
            spare: Vec::new(),
            other: Vec::new(),
        }
    }

    fn recycle(&mut self, p: GridPoint) {
        self.spare.push(p.y);
        if let Some(f) = p.f {
            self.spare.push(f);
        }
        if let Some(m) = p.meet {
            self.spare.push(m.check);
        }
    }

    /// A buffer holding `v`.
    pub(super) fn copy_of(&mut self, v: &[f64]) -> Vec<f64> {
        match self.spare.pop() {
            Some(mut b) => {
                b.clear();
                b.extend_from_slice(v);
                b
            }
            None => v.to_vec(),
        }
    }

    /// Adds the answer's state at t (the window drops its oldest point when full).
    pub(super) fn push(&mut self, t: f64, y: &[f64]) {
        if self.points.len() >= self.keep {
            if let Some(p) = self.points.pop_front() {
                self.recycle(p);
            }
        }
        let y = self.copy_of(y);
        self.points.push_back(GridPoint {
            t,
            y,
            f: None,
            meet: None,
        });
    }

    /// Marks the newest point as a meeting point with the check's data.
    pub(super) fn mark_meet(&mut self, diff: f64, noise: f64, check: &[f64]) {
        let check = self.copy_of(check);
        if let Some(p) = self.points.back_mut() {
            p.meet = Some(MeetData { diff, noise, check });
        }
    }

    /// The index of the interval [t_k, t_{k+1}] holding t (the last one for t beyond).
    fn interval(&self, t: f64) -> usize {
        let n = self.points.len();
        let k = self.points.partition_point(|p| p.t <= t);
        k.saturating_sub(1).min(n.saturating_sub(2))
    }

    /// Whether the window holds `width` points around t and one more on each side (for the
    /// shifted stencil): the value at t will not improve with more points.
    pub(super) fn centred(&self, t: f64, width: usize) -> bool {
        let n = self.points.len();
        if n < 2 {
            return false;
        }
        let k = self.interval(t);
        let right = width / 2 + 1;
        k + right < n
    }

    /// The meeting point at or before t (for a step of the method from it).
    pub(super) fn meet_before(&self, t: f64) -> Option<&GridPoint> {
        self.points
            .iter()
            .rev()
            .find(|p| p.t <= t && p.meet.is_some())
    }

    /// The interpolant of the window at t into `out`, with the stencil of `width` points as
    /// central as the window allows, and its error estimate: the largest scaled difference to
    /// the stencils shifted by one point either way (where the window has them). `scaled`
    /// measures a difference at a state in tolerance units. With `verified`, the check's data
    /// of the meeting points around t too, and `None` where t is not between two of them (or
    /// with fewer than two points).
    pub(super) fn interpolate<S: System>(
        &mut self,
        system: &S,
        t: f64,
        width: usize,
        verified: bool,
        scaled: impl Fn(&[f64], &[f64]) -> f64,
        out: &mut [f64],
    ) -> Option<Interpolated> {
        let n = self.points.len();
        if n < 2 {
            return None;
        }
        let width = width.min(n).min(MAX_WIDTH);
        let k = self.interval(t);
        let (mut diff, mut noise) = (0.0_f64, 0.0_f64);
        if verified {
            // The meeting points around t: the one at or before the interval and the one at
            // or after it (beyond them nothing of the check is known here).
            let before = (0..=k).rev().find(|&j| self.points[j].meet.is_some())?;
            let after = (k + 1..n).find(|&j| self.points[j].meet.is_some())?;
            for j in [before, after] {
                if let Some(m) = &self.points[j].meet {
                    diff = diff.max(m.diff);
                    noise = noise.max(m.noise);
                }
            }
        }
        let first = super::hermite::stencil(k, n - 1, width);
        // The shifted stencils: one point later and one earlier, where they exist.
        let later = (first + width < n).then_some(first + 1);
        let earlier = first.checked_sub(1);
        let lo = earlier.unwrap_or(first);
        let hi = later.unwrap_or(first) + width;
        self.ensure_derivatives(system, lo..hi);
        let h = self.points[k + 1].t - self.points[k].t;
        let h = if h > 0.0 { h } else { 1.0 };
        let tc = self.points[k].t;
        let x = (t - tc) / h;
        self.eval(first, width, tc, h, x, out);
        let mut interp = if later.is_none() && earlier.is_none() {
            // Nothing checks an interpolant without a second stencil.
            f64::INFINITY
        } else {
            0.0_f64
        };
        let mut other = std::mem::take(&mut self.other);
        other.resize(out.len(), 0.0);
        for f0 in later.into_iter().chain(earlier) {
            self.eval(f0, width, tc, h, x, &mut other);
            for (o, v) in other.iter_mut().zip(out.iter()) {
                *o -= v;
            }
            interp = interp.max(scaled(&other, out));
        }
        self.other = other;
        Some(Interpolated {
            interp,
            diff,
            noise,
        })
    }

    /// The Hermite interpolant on the `width` points from `first` at x (in units of h from
    /// tc) into `out`.
    fn eval(&self, first: usize, width: usize, tc: f64, h: f64, x: f64, out: &mut [f64]) {
        let mut xs = [0.0; MAX_WIDTH];
        for (j, xj) in xs[..width].iter_mut().enumerate() {
            *xj = (self.points[first + j].t - tc) / h;
        }
        let (mut a, mut b) = ([0.0; MAX_WIDTH], [0.0; MAX_WIDTH]);
        weights(&xs[..width], x, &mut a[..width], &mut b[..width]);
        out.fill(0.0);
        for j in 0..width {
            let p = &self.points[first + j];
            let (aj, bj) = (a[j], h * b[j]);
            let f = p.f.as_deref().unwrap_or(&[]);
            for ((o, yv), fv) in out.iter_mut().zip(&p.y).zip(f) {
                *o += aj * yv + bj * fv;
            }
        }
    }

    /// Computes f = Ay + g(y) at the points `range` that do not have it.
    fn ensure_derivatives<S: System>(&mut self, system: &S, range: std::ops::Range<usize>) {
        let d = system.dim();
        let mut g = vec![0.0; d];
        let mut scratch = vec![0.0; system.scratch_len()];
        for j in range {
            if self.points[j].f.is_some() {
                continue;
            }
            let mut f = match self.spare.pop() {
                Some(mut b) => {
                    b.clear();
                    b.resize(d, 0.0);
                    b
                }
                None => vec![0.0; d],
            };
            let y = &self.points[j].y;
            system.linear().apply(y, &mut f);
            system.nonlinear(y, &mut g, &mut scratch);
            for (a, b) in f.iter_mut().zip(&g) {
                *a += b;
            }
            self.points[j].f = Some(f);
        }
    }
}
