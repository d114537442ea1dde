//! What the controller reads off the windows it keeps: a feature inside one step (a jump or
//! kink of g, a close passage) that carries most of a window's growth, and the growth of the
//! recent windows from which the run's level is projected.

use super::window::GridPoint;

/// The growth of the estimate over the recent windows, (time, growth) in time order. The last
/// sixteenth of the span (`RECENT` in the controller) holds up to as many windows as the span
/// has stops, so its sum and largest entry are kept as windows come and go (a running sum and
/// a queue of decreasing maxima) rather than recomputed: O(1) per window. Up to `EXACT`
/// windows the sum is added afresh, front to back.
#[derive(Default)]
pub(super) struct Recent {
    windows: std::collections::VecDeque<(f64, f64)>,
    sum: f64,
    maxima: std::collections::VecDeque<(f64, f64)>,
}

impl Recent {
    const EXACT: usize = 256;

    pub(super) fn push(&mut self, t: f64, growth: f64) {
        self.windows.push_back((t, growth));
        self.sum += growth;
        while self.maxima.back().is_some_and(|&(_, g)| g <= growth) {
            self.maxima.pop_back();
        }
        self.maxima.push_back((t, growth));
    }

    /// Drops the windows that end at or before `since`.
    pub(super) fn expire(&mut self, since: f64) {
        while let Some(&(t, g)) = self.windows.front() {
            if t > since {
                break;
            }
            self.windows.pop_front();
            self.sum -= g;
        }
        while self.maxima.front().is_some_and(|&(t, _)| t <= since) {
            self.maxima.pop_front();
        }
    }

    pub(super) fn len(&self) -> usize {
        self.windows.len()
    }

    pub(super) fn clear(&mut self) {
        *self = Recent::default();
    }

    /// The sum of the growths and the largest.
    pub(super) fn sum_and_top(&self) -> (f64, f64) {
        let top = self.maxima.front().map_or(0.0, |&(_, g)| g.max(0.0));
        if self.windows.len() <= Self::EXACT {
            let sum = self.windows.iter().fold(0.0, |s, w| s + w.1);
            (sum, top)
        } else {
            (self.sum, top)
        }
    }
}

/// A feature inside one step of a window (see [`local_step`]) being passed with smaller steps:
/// what its step added to the estimate, with which step size, and the end of that step.
#[derive(Clone, Copy, Debug)]
pub(super) struct Feature {
    pub(super) delta: f64,
    pub(super) h: f64,
    pub(super) until: f64,
}

/// The step of a window that carries more than half of the growth of its estimate (the
/// largest estimate so far, from `worst` before the window), and what it adds; `None` where
/// the growth is spread over the steps (an error carried by the flow grows step by step).
pub(super) fn local_step(points: &[GridPoint], worst: f64) -> Option<(usize, f64)> {
    let (mut top, mut best) = (worst, None::<(usize, f64)>);
    for (j, q) in points.iter().enumerate() {
        if q.est > top {
            let delta = q.est - top;
            top = q.est;
            if best.is_none_or(|(_, d)| delta > d) {
                best = Some((j, delta));
            }
        }
    }
    let growth = top - worst;
    best.filter(|&(_, d)| growth > 0.0 && d > 0.5 * growth)
}
