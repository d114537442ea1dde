//! The error-free transformations `two_sum` and `two_prod` (fused multiply-add), and on them the
//! double-double number `hi + lo` (about 106 significant bits). A module of the lowest floor:
//! the φ-functions, the operators' long-run propagators and `precision` build on it.
//!
//! Addition is the accurate ("IEEE") form with both parts summed exactly, relative error about
//! 2⁻¹⁰⁶; multiplication and division have relative errors below 2⁻¹⁰⁴ (division: three
//! quotient digits, each corrected with the exact remainder). The elementary functions the
//! runtime needs in this precision are `e^x` and `(cos θ, sin θ)` of an `f64` argument
//! (`phi`, relative error below 2e−31, tested against 320-bit references) and the square
//! root (one Newton step on the f64 root, relative error below 2⁻¹⁰⁴).

use num_bigint::BigInt;
use num_rational::BigRational;
use num_traits::{Signed, Zero};
use std::cmp::Ordering;
use std::fmt;
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// `a + b = s + e` exactly.
#[inline]
pub(crate) fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// `a b = p + e` exactly (fused multiply-add).
#[inline]
pub(crate) fn two_prod(a: f64, b: f64) -> (f64, f64) {
    let p = a * b;
    (p, a.mul_add(b, -p))
}

/// A double-double number: the unevaluated sum `hi + lo` of two `f64` with
/// `|lo| ≤ ulp(hi)/2`, about 32 significant decimal digits.
///
/// Built from an `f64` ([`DoubleDouble::from`]), from two parts
/// ([`DoubleDouble::from_parts`]), or from the exact rationals of the coefficient tables
/// (correctly rounded, [`crate::precision::Real::from_dd`]). `Display` prints 34 significant
/// digits, enough to identify the value.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DoubleDouble {
    pub(crate) hi: f64,
    pub(crate) lo: f64,
}

impl DoubleDouble {
    /// The double-double equal to the `f64` `hi`.
    pub const fn new(hi: f64) -> Self {
        DoubleDouble { hi, lo: 0.0 }
    }

    /// `hi + lo` exactly, normalised (the parts may be in either order of magnitude).
    pub fn from_parts(hi: f64, lo: f64) -> Self {
        let (s, e) = two_sum(hi, lo);
        DoubleDouble { hi: s, lo: e }
    }

    /// The high part: the value rounded to `f64`.
    pub fn hi(self) -> f64 {
        self.hi
    }

    /// The low part: `self − hi` rounded to `f64`.
    pub fn lo(self) -> f64 {
        self.lo
    }

    /// Normalises `a + b` with `|a| ≥ |b|` (or `a = 0`).
    #[inline]
    pub(crate) fn fast(a: f64, b: f64) -> Self {
        let s = a + b;
        DoubleDouble {
            hi: s,
            lo: b - (s - a),
        }
    }

    #[inline]
    pub(crate) fn add(self, o: DoubleDouble) -> DoubleDouble {
        let (s, e) = two_sum(self.hi, o.hi);
        let (t, f) = two_sum(self.lo, o.lo);
        let r = DoubleDouble::fast(s, e + t);
        DoubleDouble::fast(r.hi, r.lo + f)
    }

    #[inline]
    pub(crate) fn neg(self) -> DoubleDouble {
        DoubleDouble {
            hi: -self.hi,
            lo: -self.lo,
        }
    }

    #[inline]
    pub(crate) fn sub(self, o: DoubleDouble) -> DoubleDouble {
        self.add(o.neg())
    }

    #[inline]
    pub(crate) fn mul(self, o: DoubleDouble) -> DoubleDouble {
        let (p, e) = two_prod(self.hi, o.hi);
        DoubleDouble::fast(p, e + (self.hi * o.lo + self.lo * o.hi))
    }

    /// `self · k` for an `f64` `k`.
    #[inline]
    fn mul_f64(self, k: f64) -> DoubleDouble {
        let (p, e) = two_prod(self.hi, k);
        DoubleDouble::fast(p, e + self.lo * k)
    }

    /// `self / o`: three quotient digits, each from the exact remainder.
    #[inline]
    pub(crate) fn div(self, o: DoubleDouble) -> DoubleDouble {
        let q1 = self.hi / o.hi;
        if !q1.is_finite() || q1 == 0.0 {
            return DoubleDouble::new(q1);
        }
        let r = self.sub(o.mul_f64(q1));
        let q2 = r.hi / o.hi;
        let r = r.sub(o.mul_f64(q2));
        let q3 = r.hi / o.hi;
        DoubleDouble::fast(q1, q2).add(DoubleDouble::new(q3))
    }

    /// `self / k` for an f64 `k` (exact-remainder division of the high part).
    #[inline]
    pub(crate) fn div_f64(self, k: f64) -> DoubleDouble {
        let q = self.hi / k;
        let rem = (-q).mul_add(k, self.hi);
        DoubleDouble::fast(q, (rem + self.lo) / k)
    }

    /// `self · 2^e` (exact unless the result leaves the normal range).
    pub(crate) fn ldexp(self, e: i32) -> DoubleDouble {
        // Two factors so that 2^e itself stays finite for e up to ±2046.
        let a = (e / 2) as f64;
        let b = (e - e / 2) as f64;
        let (fa, fb) = (a.exp2(), b.exp2());
        DoubleDouble {
            hi: self.hi * fa * fb,
            lo: self.lo * fa * fb,
        }
    }

    /// The absolute value.
    pub fn abs(self) -> DoubleDouble {
        if self.hi < 0.0 || (self.hi == 0.0 && self.lo < 0.0) {
            self.neg()
        } else {
            self
        }
    }

    /// The square root: one Newton step on the `f64` root, with the residual in
    /// double-double. NaN for negative numbers, `0` for `0`.
    pub fn sqrt(self) -> DoubleDouble {
        if self.hi <= 0.0 || !self.hi.is_finite() {
            return DoubleDouble::new(self.hi.sqrt());
        }
        let y = self.hi.sqrt();
        let (p, e) = two_prod(y, y);
        let residual = self.sub(DoubleDouble::fast(p, e));
        DoubleDouble::fast(y, residual.hi / (2.0 * y))
    }

    /// Whether both parts are finite.
    pub fn is_finite(self) -> bool {
        self.hi.is_finite() && self.lo.is_finite()
    }

    /// The exact value `hi + lo` as a rational (`None` if not finite).
    pub fn to_rational(self) -> Option<BigRational> {
        Some(BigRational::from_float(self.hi)? + BigRational::from_float(self.lo)?)
    }

    /// The value to `digits` significant decimal digits (rounded to nearest, ties to even),
    /// as `d.ddd…e±x`: a JSON number.
    pub fn to_decimal(self, digits: usize) -> String {
        match self.to_rational() {
            None => format!("{}", self.hi),
            Some(x) => rational_to_decimal(&x, digits.max(1)),
        }
    }
}

/// `x` to `digits` significant decimal digits in scientific notation, correctly rounded.
fn rational_to_decimal(x: &BigRational, digits: usize) -> String {
    if x.is_zero() {
        return "0.0".to_string();
    }
    let sign = if x.is_negative() { "-" } else { "" };
    let a = x.abs();
    // e10 with 10^e10 ≤ a < 10^(e10+1): start from the binary exponent, then correct.
    let bits = a.numer().bits() as i64 - a.denom().bits() as i64;
    let mut e10 = ((bits as f64) * std::f64::consts::LOG10_2).floor() as i64;
    let pow = |e: i64| -> BigRational {
        let p = BigRational::from_integer(BigInt::from(10).pow(e.unsigned_abs() as u32));
        if e >= 0 { p } else { p.recip() }
    };
    while pow(e10) > a {
        e10 -= 1;
    }
    while pow(e10 + 1) <= a {
        e10 += 1;
    }
    // m = round(a · 10^(digits − 1 − e10)), an integer with `digits` digits (or one more).
    let scaled = &a * pow(digits as i64 - 1 - e10);
    let floor = scaled.floor();
    let frac = &scaled - &floor;
    let half = BigRational::new(BigInt::from(1), BigInt::from(2));
    let mut m = floor.to_integer();
    let odd = (&m % BigInt::from(2)) != BigInt::zero();
    if frac > half || (frac == half && odd) {
        m += 1;
    }
    let mut s = m.to_string();
    if s.len() > digits {
        // Rounded up to a power of ten.
        s.truncate(digits);
        e10 += 1;
    }
    let (head, tail) = s.split_at(1);
    let tail = if tail.is_empty() { "0" } else { tail };
    format!("{sign}{head}.{tail}e{e10}")
}

impl From<f64> for DoubleDouble {
    fn from(x: f64) -> Self {
        DoubleDouble::new(x)
    }
}

impl PartialOrd for DoubleDouble {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        match self.hi.partial_cmp(&o.hi)? {
            Ordering::Equal => self.lo.partial_cmp(&o.lo),
            other => Some(other),
        }
    }
}

impl fmt::Display for DoubleDouble {
    /// 34 significant digits (the precision, if given, is the number of digits).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.to_decimal(f.precision().unwrap_or(34)))
    }
}

impl Add for DoubleDouble {
    type Output = DoubleDouble;
    #[inline]
    fn add(self, o: DoubleDouble) -> DoubleDouble {
        DoubleDouble::add(self, o)
    }
}

impl Sub for DoubleDouble {
    type Output = DoubleDouble;
    #[inline]
    fn sub(self, o: DoubleDouble) -> DoubleDouble {
        DoubleDouble::sub(self, o)
    }
}

impl Mul for DoubleDouble {
    type Output = DoubleDouble;
    #[inline]
    fn mul(self, o: DoubleDouble) -> DoubleDouble {
        DoubleDouble::mul(self, o)
    }
}

impl Div for DoubleDouble {
    type Output = DoubleDouble;
    #[inline]
    fn div(self, o: DoubleDouble) -> DoubleDouble {
        DoubleDouble::div(self, o)
    }
}

impl Neg for DoubleDouble {
    type Output = DoubleDouble;
    #[inline]
    fn neg(self) -> DoubleDouble {
        DoubleDouble::neg(self)
    }
}

impl AddAssign for DoubleDouble {
    #[inline]
    fn add_assign(&mut self, o: DoubleDouble) {
        *self = DoubleDouble::add(*self, o);
    }
}

impl SubAssign for DoubleDouble {
    #[inline]
    fn sub_assign(&mut self, o: DoubleDouble) {
        *self = DoubleDouble::sub(*self, o);
    }
}

impl MulAssign for DoubleDouble {
    #[inline]
    fn mul_assign(&mut self, o: DoubleDouble) {
        *self = DoubleDouble::mul(*self, o);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use astro_float::{BigFloat, RoundingMode};

    const PREC: usize = 320;
    const RM: RoundingMode = RoundingMode::ToEven;

    fn big(x: DoubleDouble) -> BigFloat {
        BigFloat::from_f64(x.hi, PREC).add(&BigFloat::from_f64(x.lo, PREC), PREC, RM)
    }
    fn rel(a: &BigFloat, b: &BigFloat) -> f64 {
        let d = a.sub(b, PREC, RM);
        let m = |x: &BigFloat| -> f64 {
            if x.is_zero() {
                return 0.0;
            }
            let (w, _, _, e, _) = x.as_raw_parts().unwrap();
            *w.last().unwrap() as f64 / 18446744073709551616.0 * 2f64.powi(e)
        };
        m(&d) / m(b)
    }

    /// Deterministic operands: a normalised pair with a random low part, in [−4, 4].
    fn operands(n: usize) -> Vec<DoubleDouble> {
        let mut rng = crate::test_rng::XorShift(0x2545_F491_4F6C_DD1D);
        let mut next = move || rng.unit();
        (0..n)
            .map(|_| {
                let hi = 8.0 * next() - 4.0;
                DoubleDouble::from_parts(hi, hi * f64::EPSILON * (next() - 0.5))
            })
            .collect()
    }

    #[test]
    fn arithmetic_against_320_bits() {
        let xs = operands(400);
        let mut worst = [0.0f64; 5];
        for pair in xs.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            let (ba, bb) = (big(a), big(b));
            let checks = [
                rel(&big(a + b), &ba.add(&bb, PREC, RM)),
                rel(&big(a - b), &ba.sub(&bb, PREC, RM)),
                rel(&big(a * b), &ba.mul(&bb, PREC, RM)),
                rel(&big(a / b), &ba.div(&bb, PREC, RM)),
                rel(&big(a.abs().sqrt()), &ba.abs().sqrt(PREC, RM)),
            ];
            for (w, c) in worst.iter_mut().zip(checks) {
                *w = w.max(c);
            }
        }
        println!("add, sub, mul, div, sqrt: worst relative errors {worst:?}");
        // add/sub: 2 ε² (accurate addition, away from cancellation: operands are random);
        // mul, div, sqrt: a few ε².
        let eps2 = f64::EPSILON * f64::EPSILON;
        for (what, w) in ["add", "sub", "mul", "div", "sqrt"].iter().zip(worst) {
            assert!(w <= 8.0 * eps2, "{what}: {w:e}");
        }
    }

    #[test]
    fn decimal_output_is_correctly_rounded() {
        let tenth = DoubleDouble::new(1.0) / DoubleDouble::new(10.0);
        // 1/10 to the division's accuracy (a few units of 2⁻¹⁰⁶), 31 digits.
        assert_eq!(tenth.to_decimal(31), "1.000000000000000000000000000000e-1");
        // An exact binary value, rounded to 34 digits: 1 + 2⁻⁶⁰ =
        // 1.000000000000000000867361737988403547205962240695953369140625.
        let x = DoubleDouble::from_parts(1.0, 2f64.powi(-60));
        assert_eq!(x.to_decimal(34), "1.000000000000000000867361737988404e0");
        assert_eq!(x.to_decimal(28), "1.000000000000000000867361738e0");
        assert_eq!(
            DoubleDouble::new(0.1).to_decimal(20),
            "1.0000000000000000555e-1"
        );
        assert_eq!(DoubleDouble::new(-2.5).to_decimal(1), "-2.0e0");
        assert_eq!(DoubleDouble::new(9.96).to_decimal(2), "1.0e1");
        assert_eq!(DoubleDouble::new(0.0).to_decimal(34), "0.0");
        assert_eq!(DoubleDouble::new(1e300).to_decimal(5), "1.0000e300");
        let third = DoubleDouble::new(1.0) / DoubleDouble::new(3.0);
        assert!(format!("{third}").starts_with("3.33333333333333333333333333333"));
        assert_eq!(format!("{third}").len(), "3.".len() + 33 + "e-1".len());
        // A JSON number that reads back (to f64) as the high part.
        let x = DoubleDouble::from_parts(std::f64::consts::PI, 1.2246467991473532e-16);
        assert_eq!(x.to_decimal(34).parse::<f64>().unwrap(), x.hi());
    }

    #[test]
    fn order_and_parts() {
        let a = DoubleDouble::from_parts(1.0, 1e-20);
        let b = DoubleDouble::new(1.0);
        assert!(a > b);
        assert!(-a < -b);
        assert_eq!(b.partial_cmp(&a), Some(Ordering::Less));
        assert_eq!((a - b).hi(), 1e-20);
        assert_eq!(DoubleDouble::from_parts(1e-20, 1.0), a);
        assert!(DoubleDouble::new(-4.0).sqrt().hi().is_nan());
        assert_eq!(DoubleDouble::new(0.0).sqrt().hi(), 0.0);
        assert!(!(DoubleDouble::new(1.0) / DoubleDouble::new(0.0)).is_finite());
    }
}
