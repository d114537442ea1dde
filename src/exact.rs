//! Exact solutions beyond `f64`: the Duffing equation's `q(t) = sn(ωt | m)`,
//! `p(t) = ω cn(ωt | m) dn(ωt | m)` (`m = (k/ω)²`) at 256 bits, the reference of double-double
//! runs.
//!
//! The Jacobi functions by the descending Landen (AGM) transformation, as [`crate::special`]
//! does in `f64` (DLMF §22.20(ii)): `a₀ = 1`, `b₀ = √(1 − m)`, `c₀ = √m`, `aₙ = (aₙ₋₁ + bₙ₋₁)/2`,
//! `bₙ = √(aₙ₋₁ bₙ₋₁)`, `cₙ = (aₙ₋₁ − bₙ₋₁)/2` until `cₙ < 2⁻²⁵⁶`; `φ_N = 2ᴺ a_N u`,
//! `φₙ₋₁ = (φₙ + arcsin((cₙ/aₙ) sin φₙ))/2`; `sn = sin φ₀`, `cn = cos φ₀`,
//! `dn = √(1 − m sn²)`. Every operation at 256 bits (astro-float); the parameters and the time
//! are exact binary numbers, so the result is the exact solution of the problem the run
//! integrates, to about 1e−70.

use crate::problems::Duffing;
use astro_float::{BigFloat, Consts, RoundingMode, Sign};
use ecr_runtime::precision::DoubleDouble;

/// Working precision in bits.
const PREC: usize = 256;
const RM: RoundingMode = RoundingMode::ToEven;

fn big(x: f64) -> BigFloat {
    BigFloat::from_f64(x, PREC)
}

/// A double-double as the exact sum of its parts.
fn big_dd(x: DoubleDouble) -> BigFloat {
    big(x.hi()).add(&big(x.lo()), PREC, RM)
}

/// The nearest `f64` from the top 64 bits of the mantissa (exact for zero).
fn top_f64(x: &BigFloat) -> f64 {
    if x.is_zero() {
        return 0.0;
    }
    let Some((m, _, s, e, _)) = x.as_raw_parts() else {
        return f64::NAN;
    };
    let top = m.last().copied().unwrap_or(0) as f64 / 18446744073709551616.0;
    let e1 = e / 2;
    let v = top * 2f64.powi(e1) * 2f64.powi(e - e1);
    if s == Sign::Neg { -v } else { v }
}

/// `x` rounded to a double-double (`hi` within an ulp, `lo` from the exact remainder).
fn to_dd(x: &BigFloat) -> DoubleDouble {
    let hi = top_f64(x);
    let lo = top_f64(&x.sub(&big(hi), PREC, RM));
    DoubleDouble::from_parts(hi, lo)
}

/// `(q(t), p(t))` of the Duffing problem at the time `t` (a double-double taken as exact), at
/// 256 bits, rounded to double-double.
pub fn duffing_exact_dd(problem: &Duffing, t: DoubleDouble) -> [DoubleDouble; 2] {
    let [q, p] = duffing_exact_big(problem, &big_dd(t));
    [to_dd(&q), to_dd(&p)]
}

/// The max-norm distance `max(|y₀ − q(t)|, |y₁ − p(t)|)` of the double-doubles `y` from the
/// exact solution, computed at 256 bits (no rounding to double-double of the reference).
pub fn duffing_error_dd(problem: &Duffing, t: DoubleDouble, y: &[DoubleDouble; 2]) -> f64 {
    let exact = duffing_exact_big(problem, &big_dd(t));
    exact
        .iter()
        .zip(y)
        .map(|(e, v)| top_f64(&big_dd(*v).sub(e, PREC, RM)).abs())
        .fold(0.0, f64::max)
}

fn duffing_exact_big(problem: &Duffing, t: &BigFloat) -> [BigFloat; 2] {
    let mut cc = Consts::new().expect("astro-float constants");
    let omega = big(problem.omega());
    let ratio = big(problem.k()).div(&omega, PREC, RM);
    let m = ratio.mul(&ratio, PREC, RM);
    let u = omega.mul(t, PREC, RM);
    let one = big(1.0);
    let half = big(0.5);
    let mut a = one.clone();
    let mut b = one.sub(&m, PREC, RM).sqrt(PREC, RM);
    let mut c = m.sqrt(PREC, RM);
    let tiny = big(2f64.powi(-(PREC as i32)));
    let mut ratios = Vec::new();
    let mut n = 0;
    while c.abs() > tiny && n < 64 {
        let a1 = a.add(&b, PREC, RM).mul(&half, PREC, RM);
        let b1 = a.mul(&b, PREC, RM).sqrt(PREC, RM);
        c = a.sub(&b, PREC, RM).mul(&half, PREC, RM);
        a = a1;
        b = b1;
        ratios.push(c.div(&a, PREC, RM));
        n += 1;
    }
    let mut phi = a.mul(&u, PREC, RM).mul(&big(2f64.powi(n)), PREC, RM);
    for cn_an in ratios.iter().rev() {
        let s = cn_an.mul(&phi.sin(PREC, RM, &mut cc), PREC, RM);
        phi = phi
            .add(&s.asin(PREC, RM, &mut cc), PREC, RM)
            .mul(&half, PREC, RM);
    }
    let sn = phi.sin(PREC, RM, &mut cc);
    let cn = phi.cos(PREC, RM, &mut cc);
    let dn = one
        .sub(&m.mul(&sn, PREC, RM).mul(&sn, PREC, RM), PREC, RM)
        .sqrt(PREC, RM);
    [sn, omega.mul(&cn, PREC, RM).mul(&dn, PREC, RM)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn agrees_with_the_f64_solution() {
        for (omega, k) in [(5.0, 0.07), (20.0, 0.07), (1.0, 0.9)] {
            let p = Duffing::new(omega, k).unwrap();
            for t in [0.0, 0.3, 1.0, 10.0, 77.7] {
                let e = p.exact(t).unwrap();
                let d = duffing_exact_dd(&p, DoubleDouble::from(t));
                for i in 0..2 {
                    let tol = 4e-15 * omega * (1.0 + t * omega);
                    assert!(
                        (e[i] - d[i].hi()).abs() <= tol,
                        "ω = {omega}, k = {k}, t = {t}: {} vs {}",
                        e[i],
                        d[i]
                    );
                }
            }
        }
    }

    #[test]
    fn conserves_the_energy_to_double_double() {
        let p = Duffing::default();
        let y0 = p.initial_value();
        let h0 = 0.5 * y0[1] * y0[1];
        for t in [0.5, 3.0, 10.0] {
            let [q, v] = duffing_exact_dd(&p, DoubleDouble::from(t));
            use ecr_runtime::precision::GenericSystem;
            let h = GenericSystem::<DoubleDouble>::energy(&p, &[q, v]).unwrap();
            let err = (h - DoubleDouble::from(h0)).abs().hi();
            assert!(err < 1e-29 * h0, "t = {t}: H error {err:e}");
        }
    }
}
