//! Polynomials with exact rational coefficients.

use crate::interval::Interval;
use crate::rat::{Rat, int, pow};
use num_bigint::BigInt;
use num_integer::Integer;
use num_traits::{One, Zero};
use std::fmt;

/// A polynomial Σ aₖ xᵏ with rational coefficients, stored in ascending powers.
///
/// The coefficient vector has no trailing zeros (the zero polynomial is empty).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Poly {
    coeffs: Vec<Rat>,
}

impl Poly {
    /// The polynomial with the given ascending coefficients.
    pub fn new(mut coeffs: Vec<Rat>) -> Self {
        while coeffs.last().is_some_and(Zero::is_zero) {
            coeffs.pop();
        }
        Poly { coeffs }
    }

    /// The zero polynomial.
    pub fn zero() -> Self {
        Poly { coeffs: Vec::new() }
    }

    /// The constant polynomial `c`.
    pub fn constant(c: Rat) -> Self {
        Poly::new(vec![c])
    }

    /// The monomial `x^k`.
    pub fn monomial(k: usize) -> Self {
        let mut c = vec![Rat::zero(); k + 1];
        c[k] = Rat::one();
        Poly { coeffs: c }
    }

    /// Ascending coefficients.
    pub fn coeffs(&self) -> &[Rat] {
        &self.coeffs
    }

    /// Coefficient of `x^k` (zero past the degree).
    pub fn coeff(&self, k: usize) -> Rat {
        self.coeffs.get(k).cloned().unwrap_or_else(Rat::zero)
    }

    /// Degree (`None` for the zero polynomial).
    pub fn degree(&self) -> Option<usize> {
        self.coeffs.len().checked_sub(1)
    }

    /// Exact value at a rational point (Horner).
    pub fn eval(&self, x: &Rat) -> Rat {
        self.coeffs
            .iter()
            .rev()
            .fold(Rat::zero(), |acc, a| acc * x + a)
    }

    /// An enclosure of the range over an interval (Horner in interval arithmetic), each step
    /// rounded outward to `bits` fractional bits (see [`Interval::rounded`]).
    ///
    /// Integer coefficients at an interval with dyadic endpoints (Gauss nodes, weights and
    /// everything rounded by [`Interval::rounded`]) take a fast path in integers scaled by
    /// 2^bits: the same exact operations on the same values, so the same result, without the
    /// gcd reductions of rational arithmetic (what made the generator slow unoptimised).
    pub fn eval_interval(&self, x: &Interval, bits: u32) -> Interval {
        if let Some(iv) = self.eval_interval_dyadic(x, bits) {
            return iv;
        }
        self.coeffs
            .iter()
            .rev()
            .fold(Interval::point(Rat::zero()), |acc, a| {
                acc.mul(x).add(&Interval::point(a.clone())).rounded(bits)
            })
    }

    /// [`eval_interval`](Self::eval_interval) in integers, for integer coefficients and
    /// endpoints m/2^e with e ≤ bits (`None` otherwise). Every value is held as its numerator
    /// over 2^bits (products over 2^(2·bits)); floor and ceiling by 2^bits are the outward
    /// rounding of [`Interval::rounded`], applied to the same exact values.
    fn eval_interval_dyadic(&self, x: &Interval, bits: u32) -> Option<Interval> {
        if !self.coeffs.iter().all(|a| a.denom().is_one()) {
            return None;
        }
        let (xl, xh) = (
            dyadic_numerator(&x.lo, bits)?,
            dyadic_numerator(&x.hi, bits)?,
        );
        let w = bits as usize;
        let scale = BigInt::one() << w;
        let (mut l, mut h) = (BigInt::zero(), BigInt::zero());
        for a in self.coeffs.iter().rev() {
            let p = [&l * &xl, &l * &xh, &h * &xl, &h * &xh];
            let a2 = a.numer() << (2 * w);
            let lo = p.iter().min().expect("four products") + &a2;
            let hi = p.iter().max().expect("four products") + &a2;
            l = lo.div_floor(&scale);
            h = hi.div_ceil(&scale);
        }
        Some(Interval {
            lo: Rat::new(l, scale.clone()),
            hi: Rat::new(h, scale),
        })
    }

    /// Derivative.
    pub fn derivative(&self) -> Poly {
        Poly::new(
            self.coeffs
                .iter()
                .enumerate()
                .skip(1)
                .map(|(k, a)| a * int(k as i64))
                .collect(),
        )
    }

    /// ∫₀¹ p(x) dx, exactly.
    pub fn integral_01(&self) -> Rat {
        self.coeffs
            .iter()
            .enumerate()
            .map(|(k, a)| a / int(k as i64 + 1))
            .fold(Rat::zero(), |acc, t| acc + t)
    }

    /// Product of two polynomials.
    pub fn mul(&self, other: &Poly) -> Poly {
        if self.coeffs.is_empty() || other.coeffs.is_empty() {
            return Poly::zero();
        }
        let mut c = vec![Rat::zero(); self.coeffs.len() + other.coeffs.len() - 1];
        for (i, a) in self.coeffs.iter().enumerate() {
            for (j, b) in other.coeffs.iter().enumerate() {
                c[i + j] += a * b;
            }
        }
        Poly::new(c)
    }

    /// Sum of two polynomials.
    pub fn add(&self, other: &Poly) -> Poly {
        let n = self.coeffs.len().max(other.coeffs.len());
        Poly::new((0..n).map(|k| self.coeff(k) + other.coeff(k)).collect())
    }

    /// The polynomial times a rational constant.
    pub fn scale(&self, c: &Rat) -> Poly {
        Poly::new(self.coeffs.iter().map(|a| a * c).collect())
    }

    /// p(t·x) for a rational t: the coefficient of xᵏ is multiplied by tᵏ.
    pub fn dilate(&self, t: &Rat) -> Poly {
        Poly::new(
            self.coeffs
                .iter()
                .enumerate()
                .map(|(k, a)| a * pow(t, k))
                .collect(),
        )
    }

    /// (1 − x)^n.
    pub fn one_minus_x_pow(n: usize) -> Poly {
        let base = Poly::new(vec![Rat::one(), -Rat::one()]);
        (0..n).fold(Poly::constant(Rat::one()), |acc, _| acc.mul(&base))
    }
}

impl fmt::Display for Poly {
    /// Human-readable form in descending powers, e.g. `6x^2 - 6x + 1`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.coeffs.is_empty() {
            return write!(f, "0");
        }
        let mut first = true;
        for (k, a) in self.coeffs.iter().enumerate().rev() {
            if a.is_zero() {
                continue;
            }
            let neg = a < &Rat::zero();
            let mag = if neg { -a.clone() } else { a.clone() };
            if first {
                if neg {
                    write!(f, "-")?;
                }
            } else {
                write!(f, " {} ", if neg { '-' } else { '+' })?;
            }
            first = false;
            let coeff = crate::rat::to_text(&mag);
            match k {
                0 => write!(f, "{coeff}")?,
                _ => {
                    if !mag.is_one() {
                        write!(f, "{coeff}")?;
                    }
                    if k == 1 {
                        write!(f, "x")?;
                    } else {
                        write!(f, "x^{k}")?;
                    }
                }
            }
        }
        Ok(())
    }
}

/// The numerator of `v` over 2^bits, if v = m/2^e with e ≤ bits.
pub(crate) fn dyadic_numerator(v: &Rat, bits: u32) -> Option<BigInt> {
    let d = v.denom();
    let e = d.trailing_zeros().unwrap_or(0);
    if d.bits() != e + 1 || e > u64::from(bits) {
        return None;
    }
    Some(v.numer() << (u64::from(bits) - e) as usize)
}
