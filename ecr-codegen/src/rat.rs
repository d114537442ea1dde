//! Exact rational helpers: the one numeric type of the generator is [`Rat`] (`BigRational`).

use num_bigint::BigInt;
use num_rational::BigRational;
use num_traits::{One, Signed, ToPrimitive, Zero};

/// Exact rational number.
pub type Rat = BigRational;

/// The integer `n` as a rational.
pub fn int(n: i64) -> Rat {
    Rat::from_integer(BigInt::from(n))
}

/// The fraction `n / d` (reduced). `d` must not be zero.
pub fn frac(n: i64, d: i64) -> Rat {
    Rat::new(BigInt::from(n), BigInt::from(d))
}

/// `n!` as a big integer.
pub fn factorial(n: u64) -> BigInt {
    (1..=n).fold(BigInt::one(), |acc, k| acc * BigInt::from(k))
}

/// Binomial coefficient `C(n, k)` (zero for `k > n`).
pub fn binomial(n: u64, k: u64) -> BigInt {
    if k > n {
        return BigInt::zero();
    }
    let k = k.min(n - k);
    let mut acc = BigInt::one();
    for i in 0..k {
        acc = acc * BigInt::from(n - i) / BigInt::from(i + 1);
    }
    acc
}

/// `1 / n!` as a rational.
pub fn inv_factorial(n: u64) -> Rat {
    Rat::new(BigInt::one(), factorial(n))
}

/// Correctly rounded (round-half-to-even) conversion to `f64`.
///
/// `num-rational`'s conversion of `Ratio<BigInt>` divides the big integers with enough guard
/// bits and rounds once, so the result is the nearest `f64`; the test suite checks this
/// independently against the neighbouring floats.
pub fn to_f64(x: &Rat) -> f64 {
    x.to_f64().expect("BigRational::to_f64 never fails")
}

/// The exact rational value of a finite `f64`.
pub fn from_f64(x: f64) -> Option<Rat> {
    Rat::from_float(x)
}

/// `base ^ e` for a rational base.
pub fn pow(base: &Rat, e: usize) -> Rat {
    let mut acc = Rat::one();
    for _ in 0..e {
        acc *= base;
    }
    acc
}

/// Decimal expansion of `x` with `digits` digits after the point (rounded to nearest, ties
/// away from zero), for provenance comments and human-readable tables.
pub fn to_decimal(x: &Rat, digits: usize) -> String {
    let neg = x.is_negative();
    let a = x.abs();
    let scale = BigInt::from(10u32).pow(digits as u32);
    let scaled = (a.numer() * &scale * BigInt::from(2) + a.denom()) / (a.denom() * BigInt::from(2));
    let s = scaled.to_string();
    let s = if s.len() <= digits {
        format!("{}{}", "0".repeat(digits + 1 - s.len()), s)
    } else {
        s
    };
    let (ip, fp) = s.split_at(s.len() - digits);
    let sign = if neg { "-" } else { "" };
    if digits == 0 {
        format!("{sign}{ip}")
    } else {
        format!("{sign}{ip}.{fp}")
    }
}

/// `"p/q"` (or `"p"` for integers), the exact text form used in JSON and Markdown.
pub fn to_text(x: &Rat) -> String {
    if x.denom().is_one() {
        x.numer().to_string()
    } else {
        format!("{}/{}", x.numer(), x.denom())
    }
}
