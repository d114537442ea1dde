//! Polynomials with exact rational coefficients.

use crate::interval::Interval;
use crate::rat::{Rat, int, pow};
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
    pub fn eval_interval(&self, x: &Interval, bits: u32) -> Interval {
        self.coeffs
            .iter()
            .rev()
            .fold(Interval::point(Rat::zero()), |acc, a| {
                acc.mul(x).add(&Interval::point(a.clone())).rounded(bits)
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
