//! Events: the user's functions e(t, y) whose zeros are located on the continuous solution
//! (where: [`super::hits`]), and the root finding on a bracket they share.

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

    /// `f(t, y)` as it is, NaN included (a scan's sample off the solution may be NaN).
    pub(super) fn raw(&self, t: f64, y: &[f64]) -> f64 {
        (self.f)(t, y)
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
