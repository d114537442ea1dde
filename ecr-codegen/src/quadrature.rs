//! Gauss–Legendre and Gauss–Lobatto rules on [0, 1], certified.
//!
//! Nodes are the roots of exact integer polynomials. They are isolated by exact sign
//! evaluation on a dyadic grid (a degree-n polynomial with n sign changes has all its roots
//! bracketed, one per bracket; done once per polynomial and process), then narrowed to the
//! dyadic bracket of width 2^−bits that holds the root: Newton's method in fixed point proposes
//! it and exact signs at its ends confirm it (bisection with exact signs where they do not,
//! which gives the same bracket, only slower). Weights are enclosed by interval arithmetic over those brackets. Every
//! `f64` is read off an enclosure whose endpoints round alike, so it is the correctly
//! rounded value of the true quantity.

use crate::interval::Interval;
use crate::legendre::shifted_legendre;
use crate::poly::Poly;
use crate::rat::Rat;
use num_bigint::BigInt;
use num_integer::Integer;
use num_traits::{One, Signed, Zero};
use std::cmp::Ordering;

/// Which quadrature family.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum QuadratureKind {
    /// s-point Gauss–Legendre: roots of P̃ₛ, exact for degree 2s − 1.
    GaussLegendre,
    /// s-point Gauss–Lobatto: 0, 1 and the roots of P̃'_{s−1}, exact for degree 2s − 3.
    GaussLobatto,
}

/// A quadrature rule on [0, 1] with rigorous enclosures of its nodes and weights.
#[derive(Clone, Debug)]
pub struct Quadrature {
    /// Family of the rule.
    pub kind: QuadratureKind,
    /// Number of points.
    pub s: usize,
    /// Node enclosures, increasing.
    pub nodes: Vec<Interval>,
    /// Weight enclosures, in node order.
    pub weights: Vec<Interval>,
    /// The polynomial whose roots are the (interior) nodes.
    pub node_polynomial: Poly,
    /// Bisection depth: interior node brackets have width ≤ 2^−bits.
    pub bits: u32,
}

impl Quadrature {
    /// The s-point Gauss–Legendre rule with node brackets of width ≤ 2^−bits (s ≥ 1).
    pub fn gauss_legendre(s: usize, bits: u32) -> Quadrature {
        assert!(s >= 1, "a Gauss–Legendre rule needs s >= 1");
        let p = shifted_legendre(s);
        let dp = p.derivative();
        let nodes = real_roots_in_unit(&p, s, bits);
        let work = working_bits(bits);
        // bⱼ = 1 / (c (1 − c) P̃ₛ'(c)²)
        let weights = nodes
            .iter()
            .map(|c| {
                let one = Interval::point(Rat::one());
                let d = dp.eval_interval(c, work);
                let den = c.mul(&one.sub(c)).mul(&d.mul(&d));
                one.div(&den)
                    .expect("P̃ₛ' has no root at a Gauss node")
                    .rounded(work)
            })
            .collect();
        Quadrature {
            kind: QuadratureKind::GaussLegendre,
            s,
            nodes,
            weights,
            node_polynomial: p,
            bits,
        }
    }

    /// The s-point Gauss–Lobatto rule (s ≥ 2) with interior brackets of width ≤ 2^−bits.
    pub fn gauss_lobatto(s: usize, bits: u32) -> Quadrature {
        assert!(s >= 2, "a Gauss–Lobatto rule needs s >= 2");
        let p = shifted_legendre(s - 1);
        let dp = p.derivative();
        let work = working_bits(bits);
        let mut nodes = vec![Interval::point(Rat::zero())];
        nodes.extend(real_roots_in_unit(&dp, s - 2, bits));
        nodes.push(Interval::point(Rat::one()));
        // bⱼ = 1 / (s (s − 1) P̃_{s−1}(c)²)
        let ss = Interval::point(Rat::from_integer(BigInt::from(s * (s - 1))));
        let weights = nodes
            .iter()
            .map(|c| {
                let v = p.eval_interval(c, work);
                Interval::point(Rat::one())
                    .div(&ss.mul(&v.mul(&v)))
                    .expect("P̃_{s−1} has no root at a Lobatto node")
                    .rounded(work)
            })
            .collect();
        Quadrature {
            kind: QuadratureKind::GaussLobatto,
            s,
            nodes,
            weights,
            node_polynomial: dp,
            bits,
        }
    }

    /// Σⱼ bⱼ f(cⱼ) enclosed, for a polynomial f.
    pub fn apply_poly(&self, f: &Poly) -> Interval {
        let work = working_bits(self.bits);
        self.nodes
            .iter()
            .zip(&self.weights)
            .fold(Interval::point(Rat::zero()), |acc, (c, b)| {
                acc.add(&b.mul(&f.eval_interval(c, work)).rounded(work))
            })
    }
}

/// Fractional bits kept in interval computations on top of node brackets of width 2^−bits:
/// enough headroom that outward rounding never dominates the enclosure width.
pub fn working_bits(bits: u32) -> u32 {
    bits + 64
}

/// The polynomial scaled to integer coefficients (same roots, same signs).
fn integer_coefficients(p: &Poly) -> Vec<BigInt> {
    let l = p
        .coeffs()
        .iter()
        .fold(BigInt::one(), |acc, a| acc.lcm(a.denom()));
    p.coeffs()
        .iter()
        .map(|a| a.numer() * (&l / a.denom()))
        .collect()
}

/// Sign of p(m / 2^e), computed exactly: Σ aₖ mᵏ 2^{e(n−k)} (Horner in integers).
fn sign_at_dyadic(a: &[BigInt], m: &BigInt, e: u32) -> Ordering {
    let n = a.len() - 1;
    let mut v = a[n].clone();
    for k in (0..n).rev() {
        v = v * m + (&a[k] << (e as usize * (n - k)));
    }
    v.sign_cmp()
}

trait SignCmp {
    fn sign_cmp(&self) -> Ordering;
}

impl SignCmp for BigInt {
    fn sign_cmp(&self) -> Ordering {
        if self.is_zero() {
            Ordering::Equal
        } else if self.is_positive() {
            Ordering::Greater
        } else {
            Ordering::Less
        }
    }
}

fn dyadic(m: &BigInt, e: u32) -> Rat {
    Rat::new(m.clone(), BigInt::one() << e as usize)
}

/// Brackets of width ≤ 2^−bits around the `count` roots of p in (0, 1), increasing.
///
/// The caller guarantees that p has exactly `count` simple roots in (0, 1) (true for Legendre
/// polynomials and their derivatives); see [`isolate`] and [`newton_cell`].
fn real_roots_in_unit(p: &Poly, count: usize, bits: u32) -> Vec<Interval> {
    if count == 0 {
        return Vec::new();
    }
    let a = integer_coefficients(p);
    let iso = isolate(&a, count);
    let g = iso.level;
    let mut roots: Vec<Interval> = iso
        .exact
        .iter()
        .map(|m| Interval::point(dyadic(m, g)))
        .collect();
    let da = derivative_coefficients(&a);
    for (m, sign_lo) in &iso.brackets {
        roots.push(
            newton_cell(&a, &da, m, g, *sign_lo, bits)
                .unwrap_or_else(|| bisect(&a, m.clone(), g, *sign_lo, bits)),
        );
    }
    roots.sort_by(|x, y| x.lo.cmp(&y.lo));
    roots
}

/// The roots of a polynomial in (0, 1) isolated on the dyadic grid of level `level`.
#[derive(Clone)]
struct Isolation {
    level: u32,
    /// (grid index of the left end, sign at the left end) per bracket.
    brackets: Vec<(BigInt, Ordering)>,
    /// Grid indices of exact zeros.
    exact: Vec<BigInt>,
}

/// [`Isolation`] of the `count` roots of the integer polynomial `a` in (0, 1), computed once
/// per polynomial and process: the grid scan is the same for every bisection depth and every
/// table that uses the same rule (a table that needs a second, deeper attempt, or the tables
/// of several r with the same s).
fn isolate(a: &[BigInt], count: usize) -> Isolation {
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};
    static CACHE: OnceLock<Mutex<HashMap<Vec<BigInt>, Isolation>>> = OnceLock::new();
    let cache = CACHE.get_or_init(Default::default);
    if let Some(iso) = cache.lock().ok().and_then(|c| c.get(a).cloned()) {
        return iso;
    }
    let iso = isolate_on_grid(a, count);
    if let Ok(mut c) = cache.lock() {
        c.insert(a.to_vec(), iso.clone());
    }
    iso
}

/// The grid scan of [`isolate`]. The grid is refined until `count` sign changes (or exact
/// zeros) are seen; a polynomial with exactly `count` roots in (0, 1) has no others, so the
/// brackets are a proof of isolation.
fn isolate_on_grid(a: &[BigInt], count: usize) -> Isolation {
    let mut g: u32 = 3 + 2 * count.next_power_of_two().trailing_zeros();
    loop {
        let mut brackets: Vec<(BigInt, Ordering)> = Vec::new();
        let mut exact: Vec<BigInt> = Vec::new();
        let mut last: Option<(BigInt, Ordering)> = None;
        for i in 1..(1u64 << g) {
            let m = BigInt::from(i);
            let sg = sign_at_dyadic(a, &m, g);
            match sg {
                Ordering::Equal => {
                    exact.push(m);
                    last = None;
                }
                _ => {
                    if let Some((lm, ls)) = &last {
                        if *ls != sg && (&m - lm) == BigInt::one() {
                            brackets.push((lm.clone(), *ls));
                        }
                    }
                    last = Some((m, sg));
                }
            }
        }
        // Roots in (0, 2^−g) or (1 − 2^−g, 1) are not bracketed by interior grid points; the
        // count check refines the grid until every root is.
        if brackets.len() + exact.len() == count {
            return Isolation {
                level: g,
                brackets,
                exact,
            };
        }
        g += 2;
        assert!(
            g <= 24,
            "root isolation failed: polynomial does not have {count} roots in (0,1)"
        );
    }
}

/// The coefficients of p' from those of p (integers).
fn derivative_coefficients(a: &[BigInt]) -> Vec<BigInt> {
    a.iter()
        .enumerate()
        .skip(1)
        .map(|(k, c)| c * BigInt::from(k))
        .collect()
}

/// p(X / 2^prec) · 2^prec, approximately (Horner in fixed point, truncating).
fn eval_fixed(a: &[BigInt], x: &BigInt, prec: usize) -> BigInt {
    let mut v = BigInt::zero();
    for c in a.iter().rev() {
        v = ((v * x) >> prec) + (c << prec);
    }
    v
}

/// What [`bisect`] returns for the root isolated in [m/2^e, (m+1)/2^e], found by Newton's
/// method instead (a few iterations in fixed point rather than `bits − e` exact signs), or
/// `None` (the caller then bisects).
///
/// Newton only proposes: the result is the dyadic cell [M/2^bits, (M+1)/2^bits] inside the
/// bracket at whose ends p has opposite signs, checked with exact signs, or the point M/2^bits
/// where p is exactly zero. The bracket holds exactly one root, so that cell is the one
/// bisection reaches (it halves down to the unique cell of width 2^−bits holding the root, or
/// stops at the root where a midpoint hits it): the enclosures, and every value certified from
/// them, are the same.
fn newton_cell(
    a: &[BigInt],
    da: &[BigInt],
    m: &BigInt,
    e: u32,
    sign_lo: Ordering,
    bits: u32,
) -> Option<Interval> {
    if e >= bits {
        return None;
    }
    // Fixed point with `prec` fractional bits, well below the target cell.
    let prec = bits as usize + 32;
    let unit = BigInt::one() << (prec - e as usize);
    let (lo, hi) = (m * &unit, (m + BigInt::one()) * &unit);
    let mut x = (&lo + &hi) >> 1usize;
    let mut converged = false;
    for _ in 0..64 {
        let d = eval_fixed(da, &x, prec);
        if d.is_zero() {
            return None;
        }
        let step = (eval_fixed(a, &x, prec) << prec) / d;
        x -= &step;
        if x < lo || x > hi {
            return None;
        }
        if step.magnitude().bits() <= 2 {
            converged = true;
            break;
        }
    }
    if !converged {
        return None;
    }
    let cell = x >> (prec - bits as usize);
    let shift = (bits - e) as usize;
    let (first, last) = (m << shift, ((m + BigInt::one()) << shift) - BigInt::one());
    if cell < first || cell > last {
        return None;
    }
    let next = &cell + BigInt::one();
    let (s0, s1) = (
        sign_at_dyadic(a, &cell, bits),
        sign_at_dyadic(a, &next, bits),
    );
    match (s0, s1) {
        (Ordering::Equal, _) if cell > first => Some(Interval::point(dyadic(&cell, bits))),
        (_, Ordering::Equal) if cell < last => Some(Interval::point(dyadic(&next, bits))),
        (Ordering::Equal, _) | (_, Ordering::Equal) => None,
        (s0, s1) if s0 == sign_lo && s1 != s0 => {
            Some(Interval::new(dyadic(&cell, bits), dyadic(&next, bits)))
        }
        _ => None,
    }
}

/// Bisection of [m/2^e, (m+1)/2^e] (sign `sign_lo` at the left end) to width ≤ 2^−bits.
fn bisect(a: &[BigInt], mut m: BigInt, mut e: u32, sign_lo: Ordering, bits: u32) -> Interval {
    while e < bits {
        m <<= 1usize;
        e += 1;
        let mid = &m + BigInt::one();
        match sign_at_dyadic(a, &mid, e) {
            Ordering::Equal => return Interval::point(dyadic(&mid, e)),
            s if s == sign_lo => m = mid,
            _ => {}
        }
    }
    Interval::new(dyadic(&m, e), dyadic(&(&m + BigInt::one()), e))
}
