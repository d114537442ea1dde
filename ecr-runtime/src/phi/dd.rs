//! Scalar exponentials in double-double (`hi + lo`, about 106 significant bits), for the
//! propagators of diagonal and spectral operators carried beyond f64 in long runs.
//!
//! The argument is an f64 taken as exact (e.g. `h λ` already rounded): what matters for the
//! long-run drift is that the map applied every step is the exponential of a fixed operator to
//! about ε², not which nearby operator it is.
//!
//! Both functions reduce the argument by a multiple of `ln 2` (resp. `π/2`) held to three
//! doubles, so the reduced argument is accurate to ~ε² for `|k| ≲ 2⁴⁰`, and then evaluate
//! Taylor polynomials in double-double arithmetic.

pub(crate) use crate::double_double::DoubleDouble as Dd;
use crate::double_double::two_prod;

/// `ln 2` as the sum of three doubles (generated with 300-bit mpmath).
const LN2: [f64; 3] = [
    std::f64::consts::LN_2,
    2.3190468138462996e-17,
    5.707708438416212e-34,
];

/// `π/2` as the sum of three doubles (generated with 300-bit mpmath).
const PI_2: [f64; 3] = [
    std::f64::consts::FRAC_PI_2,
    6.123233995736766e-17,
    -1.4973849048591698e-33,
];

/// `x − k c` for the triple-double constant `c`, in double-double; `k` an integer-valued f64 with
/// `|x − k c₀| ≤ |x|` (Sterbenz applies to `x − k c₀` in the callers' ranges).
fn reduce(x: f64, k: f64, c: &[f64; 3]) -> Dd {
    if k == 0.0 {
        return Dd::new(x);
    }
    let (p0, e0) = two_prod(k, c[0]);
    let (p1, e1) = two_prod(k, c[1]);
    Dd::new(x - p0)
        .sub(Dd::new(e0))
        .sub(Dd { hi: p1, lo: e1 })
        .sub(Dd::new(k * c[2]))
}

/// `e^x` in double-double: relative error below 2e−31 where the low part is a normal number
/// (`e^x ≥ 2^−969`, x ≳ −671), absolute error about 2⁻¹⁰⁷⁴ below; `(∞, 0)` above
/// `ln(f64::MAX)`, `(0, 0)` below the subnormal range.
pub(crate) fn exp_dd(x: f64) -> Dd {
    if x == 0.0 {
        // What the reduction and the series give for ±0 (tested), without running them: the
        // real part of every skew-pair mode's exponent, and every zero eigenvalue.
        return Dd::new(1.0);
    }
    exp_dd_series(x)
}

/// [`exp_dd`] by the reduction and the series (also correct, and the same, for ±0).
fn exp_dd_series(x: f64) -> Dd {
    if x.is_nan() {
        return Dd::new(f64::NAN);
    }
    if x > 709.782712893384 {
        return Dd::new(f64::INFINITY);
    }
    if x < -745.2 {
        return Dd::new(0.0);
    }
    // x = k ln 2 + r, |r| ≤ ln2/2; r = 16 t; e^r − 1 = m from t by four doublings
    // m ← m (m + 2), which keep the relative error of m (no "1 +" to lose it in).
    let k = (x / LN2[0]).round();
    let t = {
        let r = reduce(x, k, &LN2);
        Dd {
            hi: r.hi / 16.0,
            lo: r.lo / 16.0,
        }
    };
    // e^t − 1 = t (1 + t/2 (1 + t/3 (… (1 + t/16)))): |t| ≤ 0.0217, the first term left out is
    // below 1e−36 relative.
    let mut s = Dd::new(1.0);
    for j in (2..=17).rev() {
        s = Dd::new(1.0).add(t.mul(s).div_f64(f64::from(j)));
    }
    let mut m = t.mul(s);
    for _ in 0..4 {
        m = m.mul(m.add(Dd::new(2.0)));
    }
    Dd::new(1.0).add(m).ldexp(k as i32)
}

/// `(cos θ, sin θ)` in double-double, absolute error about 1e−32 for `|θ| ≲ 2⁴⁰` (θ taken as
/// exact).
pub(crate) fn cos_sin_dd(theta: f64) -> (Dd, Dd) {
    if !theta.is_finite() {
        return (Dd::new(f64::NAN), Dd::new(f64::NAN));
    }
    let k = (theta / PI_2[0]).round();
    let r = reduce(theta, k, &PI_2);
    // |r| ≤ π/4: Taylor to r³⁵ (the first term left out is below 1e−38).
    let r2 = r.mul(r);
    let (mut c, mut s) = (Dd::new(1.0), Dd::new(1.0));
    for j in (1..=17).rev() {
        let jf = f64::from(j);
        // cos: 1 − r²/((2j−1)(2j)) (…), sin: 1 − r²/((2j)(2j+1)) (…)
        c = Dd::new(1.0).sub(r2.mul(c).div_f64((2.0 * jf - 1.0) * (2.0 * jf)));
        s = Dd::new(1.0).sub(r2.mul(s).div_f64((2.0 * jf) * (2.0 * jf + 1.0)));
    }
    let s = r.mul(s);
    match (k.rem_euclid(4.0)) as i32 {
        0 => (c, s),
        1 => (s.neg(), c),
        2 => (c.neg(), s.neg()),
        _ => (s, c.neg()),
    }
}

/// `e^z` for complex `z = x + iy` in double-double: `(re, im)`.
pub(crate) fn cexp_dd(x: f64, y: f64) -> (Dd, Dd) {
    let e = exp_dd(x);
    if y == 0.0 {
        return (e, Dd::new(0.0));
    }
    let (c, s) = cos_sin_dd(y);
    (e.mul(c), e.mul(s))
}

#[cfg(test)]
mod tests {
    use super::*;
    use astro_float::{BigFloat, Consts, RoundingMode};

    const PREC: usize = 320;
    const RM: RoundingMode = RoundingMode::ToEven;

    /// Exact conversion (astro-float 0.9 converts subnormal f64 off by a factor 2, so those are
    /// scaled into the normal range first; the scaling by 2^100 is exact).
    fn big(x: f64) -> BigFloat {
        if x != 0.0 && x.abs() < f64::MIN_POSITIVE {
            let s = BigFloat::from_f64(2f64.powi(100), PREC);
            BigFloat::from_f64(x * 2f64.powi(100), PREC).div(&s, PREC, RM)
        } else {
            BigFloat::from_f64(x, PREC)
        }
    }

    fn dd_big(d: Dd) -> BigFloat {
        big(d.hi).add(&big(d.lo), PREC, RM)
    }

    /// The nearest f64 (from the top 64 mantissa bits), enough for errors of ~1e−30.
    fn to_f64(x: &BigFloat) -> f64 {
        if x.is_zero() {
            return 0.0;
        }
        let (m, _, s, e, _) = x.as_raw_parts().expect("finite value");
        let top = *m.last().expect("mantissa") as f64 / 18446744073709551616.0;
        let e1 = e / 2;
        let v = top * 2f64.powi(e1) * 2f64.powi(e - e1);
        if s == astro_float::Sign::Neg { -v } else { v }
    }

    /// |a − b| / |b| (or |a − b| if b = 0) as f64.
    fn rel(a: &BigFloat, b: &BigFloat) -> f64 {
        let d = to_f64(&a.sub(b, PREC, RM)).abs();
        let m = to_f64(b).abs();
        if m == 0.0 { d } else { d / m }
    }

    fn grid() -> Vec<f64> {
        let mut xs = vec![
            0.0,
            1e-300,
            1e-20,
            1e-9,
            0.1,
            0.34,
            0.35,
            0.5,
            std::f64::consts::LN_2,
        ];
        xs.extend([1.0, 2.5, 3.0, 10.0, 33.3, 100.0, 300.7, 700.0, 709.0]);
        let mut x = 1e-6;
        while x < 700.0 {
            xs.push(x);
            x *= 1.37;
        }
        let neg: Vec<f64> = xs.iter().map(|v| -v).collect();
        xs.extend(neg);
        xs
    }

    #[test]
    fn exp_dd_against_320_bit_reference() {
        let mut cc = Consts::new().unwrap();
        let mut worst = 0.0f64;
        for x in grid() {
            let r = big(x).exp(PREC, RM, &mut cc);
            let d = dd_big(exp_dd(x));
            if x < -670.0 {
                // e^x < 2^−966: the low part is subnormal, the error is absolute.
                let e = to_f64(&d.sub(&r, PREC, RM)).abs();
                assert!(e <= 2f64.powi(-1074), "exp_dd({x:e}): error {e:e}");
                continue;
            }
            let e = rel(&d, &r);
            worst = worst.max(e);
            assert!(e < 2e-31, "exp_dd({x:e}): relative error {e:e}");
            // A normalised double-double.
            let d = exp_dd(x);
            assert!(d.lo.abs() <= 0.5 * f64::EPSILON * d.hi.abs());
        }
        println!("exp_dd: worst relative error {worst:e}");
        assert_eq!(exp_dd(0.0), Dd::new(1.0));
        // The shortcut for ±0 returns, bit for bit, what the series gives.
        for z in [0.0, -0.0] {
            let (a, b) = (exp_dd_series(z), Dd::new(1.0));
            assert_eq!(
                (a.hi.to_bits(), a.lo.to_bits()),
                (b.hi.to_bits(), b.lo.to_bits())
            );
        }
        assert_eq!(exp_dd(710.0).hi, f64::INFINITY);
        assert_eq!(exp_dd(-800.0).hi, 0.0);
    }

    #[test]
    fn cos_sin_dd_against_320_bit_reference() {
        let mut cc = Consts::new().unwrap();
        let mut worst = 0.0f64;
        let mut thetas = grid();
        thetas.retain(|t| t.abs() < 1e5);
        thetas.extend([
            1e5,
            -3.0e5,
            12345.678,
            std::f64::consts::FRAC_PI_2,
            std::f64::consts::PI,
        ]);
        for th in thetas {
            let (c, s) = cos_sin_dd(th);
            let rc = big(th).cos(PREC, RM, &mut cc);
            let rs = big(th).sin(PREC, RM, &mut cc);
            // Absolute errors (cos and sin are at most 1).
            let ec = to_f64(&dd_big(c).sub(&rc, PREC, RM)).abs();
            let es = to_f64(&dd_big(s).sub(&rs, PREC, RM)).abs();
            worst = worst.max(ec).max(es);
            assert!(
                ec < 1e-31 && es < 1e-31,
                "θ = {th:e}: errors {ec:e}, {es:e}"
            );
            // Relative accuracy of sin near 0.
            if th.abs() < 0.5 && th != 0.0 {
                assert!(rel(&dd_big(s), &rs) < 1e-31, "sin({th:e})");
            }
        }
        println!("cos_sin_dd: worst absolute error {worst:e}");
    }

    #[test]
    fn cexp_dd_is_the_product() {
        let mut cc = Consts::new().unwrap();
        for &(x, y) in &[
            (0.0, 2.56),
            (-3.0, 0.7),
            (1.5, -40.0),
            (-1e4, 3.0),
            (0.2, 0.0),
        ] {
            let (re, im) = cexp_dd(x, y);
            let ex = big(x).exp(PREC, RM, &mut cc);
            let rre = ex.mul(&big(y).cos(PREC, RM, &mut cc), PREC, RM);
            let rim = ex.mul(&big(y).sin(PREC, RM, &mut cc), PREC, RM);
            let scale = to_f64(&ex).max(f64::MIN_POSITIVE);
            let er = to_f64(&dd_big(re).sub(&rre, PREC, RM)).abs() / scale;
            let ei = to_f64(&dd_big(im).sub(&rim, PREC, RM)).abs() / scale;
            assert!(er < 2e-31 && ei < 2e-31, "({x}, {y}): {er:e} {ei:e}");
        }
    }
}
