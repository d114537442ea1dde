//! Closed intervals with rational endpoints: rigorous enclosures of irrational quantities
//! (Gauss nodes, weights, moment weights) from which correctly rounded `f64`s are read off.

use crate::rat::{Rat, to_f64};
use num_bigint::BigInt;
use num_integer::Integer;
use num_traits::{One, Signed, Zero};

/// The closed interval `[lo, hi]`, `lo <= hi`, rational endpoints.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Interval {
    /// Lower endpoint.
    pub lo: Rat,
    /// Upper endpoint.
    pub hi: Rat,
}

impl Interval {
    /// `[lo, hi]`; the endpoints are swapped if given in the wrong order.
    pub fn new(lo: Rat, hi: Rat) -> Self {
        if lo <= hi {
            Interval { lo, hi }
        } else {
            Interval { lo: hi, hi: lo }
        }
    }

    /// The degenerate interval `[x, x]`.
    pub fn point(x: Rat) -> Self {
        Interval {
            lo: x.clone(),
            hi: x,
        }
    }

    /// Width `hi - lo`.
    pub fn width(&self) -> Rat {
        &self.hi - &self.lo
    }

    /// Midpoint.
    pub fn mid(&self) -> Rat {
        (&self.lo + &self.hi) / Rat::from_integer(2.into())
    }

    /// Whether `x` lies in the interval.
    pub fn contains(&self, x: &Rat) -> bool {
        &self.lo <= x && x <= &self.hi
    }

    /// Interval sum.
    pub fn add(&self, o: &Interval) -> Interval {
        Interval {
            lo: &self.lo + &o.lo,
            hi: &self.hi + &o.hi,
        }
    }

    /// Interval difference.
    pub fn sub(&self, o: &Interval) -> Interval {
        Interval {
            lo: &self.lo - &o.hi,
            hi: &self.hi - &o.lo,
        }
    }

    /// Interval product.
    pub fn mul(&self, o: &Interval) -> Interval {
        let p = [
            &self.lo * &o.lo,
            &self.lo * &o.hi,
            &self.hi * &o.lo,
            &self.hi * &o.hi,
        ];
        let lo = p.iter().min().cloned().unwrap_or_default();
        let hi = p.iter().max().cloned().unwrap_or_default();
        Interval { lo, hi }
    }

    /// Interval quotient; `None` if `o` contains zero.
    pub fn div(&self, o: &Interval) -> Option<Interval> {
        if o.contains(&Rat::zero()) {
            return None;
        }
        let inv = Interval::new(o.hi.recip(), o.lo.recip());
        Some(self.mul(&inv))
    }

    /// The interval widened outward to dyadic endpoints with `bits` fractional bits.
    ///
    /// Keeps the sizes of numerators and denominators bounded in long interval computations
    /// while the result stays a rigorous enclosure (the error is at most 2^−bits per endpoint).
    pub fn rounded(&self, bits: u32) -> Interval {
        let scale = BigInt::one() << bits as usize;
        let lo = (self.lo.numer() * &scale).div_floor(self.lo.denom());
        let hi = (self.hi.numer() * &scale).div_ceil(self.hi.denom());
        Interval {
            lo: Rat::new(lo, scale.clone()),
            hi: Rat::new(hi, scale),
        }
    }

    /// Whether the width is at most `tol · max(|lo|, |hi|)` (or the interval is a point).
    pub fn relative_width_at_most(&self, tol: &Rat) -> bool {
        let mag = self.lo.abs().max(self.hi.abs());
        self.width() <= tol * mag
    }

    /// The correctly rounded `f64` of every number in the interval, if they all round alike.
    ///
    /// Rounding to nearest is monotone, so if both endpoints round to the same float, every
    /// point between them does: the result is the correctly rounded value of the enclosed
    /// quantity. `None` means the interval straddles a rounding boundary (refine it).
    pub fn round_f64(&self) -> Option<f64> {
        let a = to_f64(&self.lo);
        let b = to_f64(&self.hi);
        (a.to_bits() == b.to_bits() || (a == 0.0 && b == 0.0)).then_some(a)
    }
}
