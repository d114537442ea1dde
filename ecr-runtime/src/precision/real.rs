//! The scalar the extended-precision path is generic over.

use crate::double_double::DoubleDouble;
use crate::phi::cos_sin_dd;
use std::fmt::{Debug, Display};
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// A real scalar of the generic stepper: `f64` or [`DoubleDouble`].
///
/// Constants enter through [`Real::from_dd`], the correctly rounded double-double pair of an
/// exact value (what `ecr-codegen` certifies for every coefficient): `f64` keeps the high
/// part, which is then the correctly rounded `f64`, and `DoubleDouble` keeps both.
pub trait Real:
    Copy
    + Debug
    + Display
    + PartialOrd
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
{
    /// The name used in reports and on the command line: `double` or `double-double`.
    const NAME: &'static str;
    /// The unit round-off (2⁻⁵³ for `f64`, 2⁻¹⁰⁶ for `DoubleDouble`).
    const EPSILON: f64;
    /// Significant decimal digits that identify every value (17 and 34).
    const DIGITS: usize;

    /// The `f64` `x`, exactly.
    fn from_f64(x: f64) -> Self;
    /// The value `hi + lo` of a correctly rounded double-double pair, in this precision.
    fn from_dd(hi: f64, lo: f64) -> Self;
    /// The value rounded to `f64`.
    fn to_f64(self) -> f64;
    /// The absolute value.
    fn abs(self) -> Self;
    /// The square root.
    fn sqrt(self) -> Self;
    /// `(cos θ, sin θ)` of the `f64` `θ` (taken as exact), to this precision.
    fn cos_sin(theta: f64) -> (Self, Self);
    /// Whether the value is finite.
    fn is_finite(self) -> bool;
    /// The value with [`Real::DIGITS`] significant digits, as a JSON number.
    fn to_decimal(self) -> String;

    /// Zero.
    fn zero() -> Self {
        Self::from_f64(0.0)
    }
    /// One.
    fn one() -> Self {
        Self::from_f64(1.0)
    }
}

impl Real for f64 {
    const NAME: &'static str = "double";
    const EPSILON: f64 = f64::EPSILON / 2.0;
    const DIGITS: usize = 17;

    fn from_f64(x: f64) -> Self {
        x
    }
    fn from_dd(hi: f64, _lo: f64) -> Self {
        hi
    }
    fn to_f64(self) -> f64 {
        self
    }
    fn abs(self) -> Self {
        f64::abs(self)
    }
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    fn cos_sin(theta: f64) -> (Self, Self) {
        (theta.cos(), theta.sin())
    }
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
    fn to_decimal(self) -> String {
        // The shortest representation that reads back as the same f64.
        format!("{self:?}")
    }
}

impl Real for DoubleDouble {
    const NAME: &'static str = "double-double";
    const EPSILON: f64 = f64::EPSILON * f64::EPSILON / 4.0;
    const DIGITS: usize = 34;

    fn from_f64(x: f64) -> Self {
        DoubleDouble::new(x)
    }
    fn from_dd(hi: f64, lo: f64) -> Self {
        DoubleDouble::from_parts(hi, lo)
    }
    fn to_f64(self) -> f64 {
        self.hi
    }
    fn abs(self) -> Self {
        DoubleDouble::abs(self)
    }
    fn sqrt(self) -> Self {
        DoubleDouble::sqrt(self)
    }
    fn cos_sin(theta: f64) -> (Self, Self) {
        cos_sin_dd(theta)
    }
    fn is_finite(self) -> bool {
        DoubleDouble::is_finite(self)
    }
    fn to_decimal(self) -> String {
        DoubleDouble::to_decimal(self, Self::DIGITS)
    }
}
