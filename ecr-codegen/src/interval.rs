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
        if let (Some(a), Some(b)) = (Dyadic2::of(self), Dyadic2::of(o)) {
            return Interval {
                lo: Dyadic::sum(&a.lo, &b.lo),
                hi: Dyadic::sum(&a.hi, &b.hi),
            };
        }
        Interval {
            lo: &self.lo + &o.lo,
            hi: &self.hi + &o.hi,
        }
    }

    /// Interval difference.
    pub fn sub(&self, o: &Interval) -> Interval {
        if let (Some(a), Some(b)) = (Dyadic2::of(self), Dyadic2::of(o)) {
            return Interval {
                lo: Dyadic::sum(&a.lo, &b.hi.neg()),
                hi: Dyadic::sum(&a.hi, &b.lo.neg()),
            };
        }
        Interval {
            lo: &self.lo - &o.hi,
            hi: &self.hi - &o.lo,
        }
    }

    /// Interval product.
    ///
    /// Dyadic endpoints (m/2^e: everything [`rounded`](Self::rounded), the Gauss node
    /// brackets) are multiplied in integers, without the gcd reductions of rational arithmetic;
    /// the values are the same.
    pub fn mul(&self, o: &Interval) -> Interval {
        if let (Some(a), Some(b)) = (Dyadic2::of(self), Dyadic2::of(o)) {
            let p = [
                a.lo.times(&b.lo),
                a.lo.times(&b.hi),
                a.hi.times(&b.lo),
                a.hi.times(&b.hi),
            ];
            let e = p.iter().map(|d| d.e).max().unwrap_or(0);
            let at = |d: &Dyadic| &d.m << (e - d.e) as usize;
            let lo = p.iter().map(at).min().unwrap_or_default();
            let hi = p.iter().map(at).max().unwrap_or_default();
            return Interval {
                lo: Dyadic { m: lo, e }.to_rat(),
                hi: Dyadic { m: hi, e }.to_rat(),
            };
        }
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
        if let Some(d) = Dyadic2::of(self) {
            // Exact below 2^−bits; otherwise floor / ceil of m / 2^(e − bits).
            let b = u64::from(bits);
            let round = |x: &Dyadic, up: bool| {
                if x.e <= b {
                    x.to_rat()
                } else {
                    let q = BigInt::one() << (x.e - b) as usize;
                    let m = if up {
                        x.m.div_ceil(&q)
                    } else {
                        x.m.div_floor(&q)
                    };
                    Dyadic { m, e: b }.to_rat()
                }
            };
            return Interval {
                lo: round(&d.lo, false),
                hi: round(&d.hi, true),
            };
        }
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
        if let Some(d) = Dyadic2::of(self) {
            // width·q ≤ p·mag with tol = p/q, in integers over 2^e.
            let e = d.lo.e.max(d.hi.e);
            let (lo, hi) = (
                &d.lo.m << (e - d.lo.e) as usize,
                &d.hi.m << (e - d.hi.e) as usize,
            );
            let mag = lo.abs().max(hi.abs());
            return (hi - lo) * tol.denom() <= mag * tol.numer();
        }
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

    /// The correctly rounded double-double `(hi, lo)` of every number in the interval, if they
    /// all round alike: `hi` is the correctly rounded `f64` of the quantity `x` and `lo` the
    /// correctly rounded `f64` of `x − hi`, so `|x − (hi + lo)| ≤ ulp(lo)/2` (about `2⁻¹⁰⁷ |x|`).
    /// When the enclosure holds `hi` itself and is narrower than `2⁻¹⁶⁰ |hi|` (an exact `f64`
    /// such as a weight ½, enclosed but not as a point), `lo = 0`: `hi` is then `x` to far
    /// more than double-double precision. `None` if a rounding is not decided by the enclosure
    /// (refine it).
    pub fn round_dd(&self) -> Option<(f64, f64)> {
        let hi = self.round_f64()?;
        if !hi.is_finite() {
            return None;
        }
        let h = Rat::from_float(hi).expect("finite f64");
        let rest = Interval {
            lo: &self.lo - &h,
            hi: &self.hi - &h,
        };
        if let Some(lo) = rest.round_f64() {
            return Some((hi, lo));
        }
        let bound = h.abs() / Rat::from_integer(BigInt::one() << 160usize);
        (rest.contains(&Rat::zero()) && rest.width() <= bound).then_some((hi, 0.0))
    }
}

/// The matrix of `Σ_k (a[i][k] · b[k][j]).rounded(bits)`, each summed from 0 in order: the
/// value of `fold(point(0), |acc, k| acc.add(&a[i][k].mul(&b[k][j]).rounded(bits)))` for
/// every i and j. Where every operand is dyadic it is computed on integers scaled by
/// `2^bits`, each operand converted once, a product with a nonnegative `a[i][k]` from two
/// endpoint products instead of four, and one conversion to a rational per result; the sums of
/// rounded products are exact either way, so the results are the same intervals.
pub fn matmul_rounded(a: &[Vec<Interval>], b: &[Vec<Interval>], bits: u32) -> Vec<Vec<Interval>> {
    let cols = b.first().map_or(0, Vec::len);
    let slow = || {
        a.iter()
            .map(|row| {
                (0..cols)
                    .map(|j| {
                        row.iter()
                            .zip(b)
                            .fold(Interval::point(Rat::zero()), |acc, (x, bk)| {
                                acc.add(&x.mul(&bk[j]).rounded(bits))
                            })
                    })
                    .collect()
            })
            .collect()
    };
    let dyadic = |m: &[Vec<Interval>]| -> Option<Vec<Vec<Dyadic2>>> {
        m.iter()
            .map(|row| row.iter().map(Dyadic2::of).collect())
            .collect()
    };
    let (Some(da), Some(db)) = (dyadic(a), dyadic(b)) else {
        return slow();
    };
    let bb = u64::from(bits);
    // An endpoint m / 2^e as an integer over 2^bits: exact if e ≤ bits, else floor or ceil
    // (`>>` on a BigInt rounds toward −∞; ceil(m/2^k) = −floor(−m/2^k)).
    let scaled = |m: BigInt, e: u64, up: bool| -> BigInt {
        if e <= bb {
            m << (bb - e) as usize
        } else {
            let k = (e - bb) as usize;
            if up { -((-m) >> k) } else { m >> k }
        }
    };
    da.iter()
        .map(|row| {
            (0..cols)
                .map(|j| {
                    let (mut lo, mut hi) = (BigInt::zero(), BigInt::zero());
                    for (x, bk) in row.iter().zip(&db) {
                        let y = &bk[j];
                        let (pl, ph) = if !x.lo.m.is_negative() {
                            // x ≥ 0: the smallest product is with y.lo, the largest with y.hi.
                            let l = if y.lo.m.is_negative() { &x.hi } else { &x.lo };
                            let h = if y.hi.m.is_negative() { &x.lo } else { &x.hi };
                            (l.times(&y.lo), h.times(&y.hi))
                        } else {
                            let p = [
                                x.lo.times(&y.lo),
                                x.lo.times(&y.hi),
                                x.hi.times(&y.lo),
                                x.hi.times(&y.hi),
                            ];
                            let e = p.iter().map(|d| d.e).max().unwrap_or(0);
                            let at = |d: &Dyadic| &d.m << (e - d.e) as usize;
                            let l = p.iter().map(at).min().unwrap_or_default();
                            let h = p.iter().map(at).max().unwrap_or_default();
                            (Dyadic { m: l, e }, Dyadic { m: h, e })
                        };
                        lo += scaled(pl.m, pl.e, false);
                        hi += scaled(ph.m, ph.e, true);
                    }
                    Interval {
                        lo: Dyadic { m: lo, e: bb }.to_rat(),
                        hi: Dyadic { m: hi, e: bb }.to_rat(),
                    }
                })
                .collect()
        })
        .collect()
}

/// A dyadic rational m / 2^e.
struct Dyadic {
    m: BigInt,
    e: u64,
}

impl Dyadic {
    /// `v` as m / 2^e, if its (reduced, positive) denominator is a power of two.
    fn of(v: &Rat) -> Option<Dyadic> {
        let d = v.denom();
        let e = d.trailing_zeros().unwrap_or(0);
        (d.bits() == e + 1).then(|| Dyadic {
            m: v.numer().clone(),
            e,
        })
    }

    fn neg(&self) -> Dyadic {
        Dyadic {
            m: -&self.m,
            e: self.e,
        }
    }

    fn times(&self, o: &Dyadic) -> Dyadic {
        Dyadic {
            m: &self.m * &o.m,
            e: self.e + o.e,
        }
    }

    /// The exact sum, as a reduced rational.
    fn sum(a: &Dyadic, b: &Dyadic) -> Rat {
        let e = a.e.max(b.e);
        let m = (&a.m << (e - a.e) as usize) + (&b.m << (e - b.e) as usize);
        Dyadic { m, e }.to_rat()
    }

    /// The reduced rational m / 2^e (what `Rat::new` would give, without a gcd).
    fn to_rat(&self) -> Rat {
        if self.m.is_zero() {
            return Rat::zero();
        }
        let t = self.m.trailing_zeros().unwrap_or(0).min(self.e);
        Rat::new_raw(
            &self.m >> t as usize,
            BigInt::one() << (self.e - t) as usize,
        )
    }
}

/// Both endpoints of an interval as dyadic rationals.
struct Dyadic2 {
    lo: Dyadic,
    hi: Dyadic,
}

impl Dyadic2 {
    fn of(iv: &Interval) -> Option<Dyadic2> {
        Some(Dyadic2 {
            lo: Dyadic::of(&iv.lo)?,
            hi: Dyadic::of(&iv.hi)?,
        })
    }
}
