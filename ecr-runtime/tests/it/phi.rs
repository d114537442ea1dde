//! φ-functions against high-precision references (astro-float), identities (proptest), and
//! dense-matrix φ against exact eigen/Jordan forms.
//!
//! Run with `--nocapture` to see the measured maximum errors per region.

// Index loops mirror the formulas (k, j, m as in the paper) in these comparisons.
#![allow(clippy::needless_range_loop)]

use crate::common_phi;

use common_phi::{Hc, Hp, Rng, log_grid, to_f64};
use ecr_runtime::Error;
use ecr_runtime::phi::{
    INV_FACTORIAL, inv_factorial, phi_complex, phi_dense, phi_dense_static, phi_diagonal, phi_real,
    phi_symmetric, phi_trig,
};
use nalgebra::{DMatrix, SMatrix};
use num_complex::Complex64;
use proptest::prelude::*;
use proptest::test_runner::{Config as ProptestConfig, RngSeed};
use std::f64::consts::PI;

/// Highest φ index checked against references (the requirement covers k = 0..12).
const P: usize = 12;
/// The accuracy requirement for scalar φ: relative error (in modulus for complex values) at
/// most 1e−14, i.e. about 45 units of roundoff; the algorithm's a-priori bound is a few units.
const TOL: f64 = 1e-14;
/// Working precision of the references: 384 bits covers the ≤ 100 bits that the Taylor +
/// downward-recurrence reference can lose for |z| ≤ 24, with 280 bits to spare.
const PREC: usize = 384;

/// Maximum error of one region, with where it occurred.
struct RegionStats {
    name: String,
    max_err: f64,
    at: (Complex64, usize),
    points: usize,
}

impl RegionStats {
    fn new(name: &str) -> Self {
        RegionStats {
            name: name.to_string(),
            max_err: 0.0,
            at: (Complex64::new(0.0, 0.0), 0),
            points: 0,
        }
    }
    fn update(&mut self, err: f64, z: Complex64, k: usize) {
        if err > self.max_err || err.is_nan() {
            self.max_err = if err.is_nan() { f64::INFINITY } else { err };
            self.at = (z, k);
        }
    }
}

/// The error measure of one value against its reference:
/// * relative error in modulus where the reference is a normal f64;
/// * where the reference underflows (|r| < f64::MIN_POSITIVE, e.g. e^{−1000}), f64 cannot hold
///   relative accuracy: the absolute error divided by MIN_POSITIVE;
/// * where the reference overflows f64, the computed value must be infinite (0 if so, ∞ if not)
///   (the same when e^z overflows astro-float itself, far beyond f64).
///
/// NaN is never acceptable and returns ∞.
fn error_measure(hp: &Hp, z: Complex64, c: Complex64, r: &Hc) -> f64 {
    if c.re.is_nan() || c.im.is_nan() {
        return f64::INFINITY;
    }
    let mut rmag = hp.abs_f64(r);
    if rmag.is_nan() {
        // e^z beyond even astro-float's exponent range (Re z ≳ 1.5e9): then
        // |φ_k(z)| ≥ e^{Re z}/|z|^k − e^{|z|}… is astronomically beyond f64::MAX.
        assert!(
            z.re > 1e6 && z.re - (P as f64) * z.norm().ln() > 1000.0,
            "reference NaN at {z}"
        );
        rmag = f64::INFINITY;
    }
    if rmag >= f64::MAX {
        return if c.norm().is_infinite() {
            0.0
        } else {
            f64::INFINITY
        };
    }
    if rmag < f64::MIN_POSITIVE {
        return hp.abs_err(c, r) / f64::MIN_POSITIVE;
    }
    hp.rel_err(c, r)
}

fn region_of(r: f64) -> &'static str {
    if r < 1e-4 {
        "|z| in [1e-16, 1e-4)"
    } else if r < 0.25 {
        "|z| in [1e-4, 0.25)"
    } else if r <= 64.0 {
        "|z| in [0.25, 64]"
    } else if r <= 700.0 {
        "|z| in (64, 700]"
    } else {
        "|z| in (700, 1e12]"
    }
}

const REGIONS: [&str; 5] = [
    "|z| in [1e-16, 1e-4)",
    "|z| in [1e-4, 0.25)",
    "|z| in [0.25, 64]",
    "|z| in (64, 700]",
    "|z| in (700, 1e12]",
];

/// Moduli swept: a log grid over 1e−16..1e12 plus a denser grid where the method changes
/// (0.25, the upward/downward crossover up to 4p + 16 = 64, and the scaled range 600..800).
fn moduli() -> Vec<f64> {
    let mut v = log_grid(-16, 12, 12);
    v.extend(log_grid(-1, 2, 40));
    v.extend((0..=40).map(|i| 600.0 + 5.0 * i as f64));
    v
}

/// Sweeps `points` through `eval` and returns per-region statistics (printed).
fn sweep(
    label: &str,
    points: &[Complex64],
    mut eval: impl FnMut(Complex64, &mut [Complex64]),
) -> Vec<RegionStats> {
    let mut hp = Hp::new(PREC);
    let mut stats: Vec<RegionStats> = REGIONS.iter().map(|n| RegionStats::new(n)).collect();
    let mut out = vec![Complex64::new(0.0, 0.0); P + 1];
    for &z in points {
        eval(z, &mut out);
        let refs = hp.phi(z, P);
        let reg = region_of(z.norm());
        let s = stats.iter_mut().find(|s| s.name == reg).unwrap();
        s.points += 1;
        for k in 0..=P {
            let err = error_measure(&hp, z, out[k], &refs[k]);
            s.update(err, z, k);
        }
    }
    for s in &stats {
        if s.points > 0 {
            println!(
                "{label:<28} {:<22} points {:>4}  max rel err {:.2e}  (at z = {:.6e}{:+.6e}i, k = {})",
                s.name, s.points, s.max_err, s.at.0.re, s.at.0.im, s.at.1
            );
        }
    }
    stats
}

fn assert_within(stats: &[RegionStats], label: &str, tol: f64) {
    for s in stats {
        assert!(
            s.max_err <= tol,
            "{label} {}: max error {:.3e} > {tol:e} at z = {}, k = {}",
            s.name,
            s.max_err,
            s.at.0,
            s.at.1
        );
    }
}

#[test]
fn inv_factorial_table_is_correctly_rounded() {
    use num_bigint::BigInt;
    use num_rational::BigRational;
    use num_traits::ToPrimitive;
    let mut fact = BigInt::from(1);
    for (k, &v) in INV_FACTORIAL.iter().enumerate() {
        if k > 0 {
            fact *= k;
        }
        let exact = BigRational::new(BigInt::from(1), fact.clone())
            .to_f64()
            .unwrap();
        // Exact equality: the table is documented as correctly rounded.
        assert_eq!(v.to_bits(), exact.to_bits(), "1/{k}!");
        assert_eq!(inv_factorial(k), v);
    }
    // Beyond the table: recurrence from 1/32!, relative error ≤ (k − 32 + 1) u.
    let mut fact40 = BigInt::from(1);
    for j in 2..=40 {
        fact40 *= j;
    }
    let exact40 = BigRational::new(BigInt::from(1), fact40).to_f64().unwrap();
    assert!((inv_factorial(40) - exact40).abs() <= 9.0 * f64::EPSILON * exact40);
}

#[test]
fn reference_self_check() {
    // The two reference formulas agree where both are accurate (|z| = 24 is Taylor, 24.000001
    // the closed form), and to_f64 round-trips.
    let mut hp = Hp::new(PREC);
    for &z in &[
        Complex64::new(-24.0, 0.0),
        Complex64::new(0.0, 24.0),
        Complex64::new(17.0, -16.9),
    ] {
        let a = hp.phi(z, P);
        let b = hp.phi(z * (1.0 + 1e-15), P);
        for k in 0..=P {
            // The two arguments differ by 1e−15 relative; φ_k changes by at most ~|z|·1e−15.
            let e = hp.rel_err(common_phi::to_c64(&a[k]), &b[k]);
            assert!(e < 1e-13, "z = {z}, k = {k}: {e:e}");
        }
    }
    for &x in &[
        1.0,
        -3.5e-300,
        1.7e308,
        5e-324,
        0.1,
        -2.0f64.powi(-1000),
        -2.96e-316,
    ] {
        assert_eq!(to_f64(&hp.f(x)), x);
    }
    // Subnormals convert exactly (2^-1050 · 3 = 3·2^-1050).
    let x = 3.0 * 2f64.powi(-1050);
    let back = hp.mul(&hp.f(x), &hp.f(2f64.powi(1000)));
    assert_eq!(to_f64(&back), 3.0 * 2f64.powi(-50));
}

#[test]
fn phi_real_against_reference_real_axis() {
    let radii = moduli();
    for (label, sign) in [("phi_real, z > 0", 1.0), ("phi_real, z < 0", -1.0)] {
        let pts: Vec<Complex64> = radii
            .iter()
            .map(|&r| Complex64::new(sign * r, 0.0))
            .collect();
        let stats = sweep(label, &pts, |z, out| {
            let mut buf = [0.0; P + 1];
            phi_real(z.re, &mut buf);
            for (o, b) in out.iter_mut().zip(buf) {
                *o = Complex64::new(b, 0.0);
            }
        });
        assert_within(&stats, label, TOL);
    }
}

#[test]
fn phi_real_extremes() {
    let mut out = [0.0; P + 1];
    // Large negative: e^z underflows to 0, φ_k ≈ 1/((k−1)!|z|), no NaN.
    phi_real(-1e300, &mut out);
    assert_eq!(out[0], 0.0);
    for k in 1..=P {
        let expect = inv_factorial(k - 1) / 1e300;
        assert!((out[k] - expect).abs() <= 1e-15 * expect, "k = {k}");
    }
    // Large positive: +∞, never NaN.
    phi_real(1e12, &mut out);
    assert!(out.iter().all(|v| *v == f64::INFINITY));
    // φ_12(750) = e^750/750^12 (1 − …) fits in f64 although e^750 does not.
    phi_real(750.0, &mut out);
    assert!(out[0].is_infinite() && out[12].is_finite() && out[12] > 1e250);
    // NaN in, NaN out; infinities give the limits.
    phi_real(f64::NAN, &mut out);
    assert!(out.iter().all(|v| v.is_nan()));
    phi_real(f64::NEG_INFINITY, &mut out);
    assert!(out.iter().all(|v| *v == 0.0));
    phi_real(f64::INFINITY, &mut out);
    assert!(out.iter().all(|v| *v == f64::INFINITY));
    // Exact zero and empty output.
    phi_real(0.0, &mut out);
    for (k, v) in out.iter().enumerate() {
        assert_eq!(*v, inv_factorial(k));
    }
    phi_real(1.0, &mut []);
    // Long outputs (heap scratch) agree with short ones on the common part.
    let mut long = vec![0.0; 60];
    for &z in &[-30.0, -3.0, 0.1, 5.0, 80.0] {
        phi_real(z, &mut long);
        phi_real(z, &mut out);
        for k in 0..=P {
            // Different orders P of the downward run: both within the 1e−14 requirement.
            assert!(
                (long[k] - out[k]).abs() <= 2.0 * TOL * out[k].abs(),
                "z = {z}, k = {k}"
            );
        }
    }
}

#[test]
fn phi_complex_against_reference_imaginary_axis() {
    let radii = moduli();
    for (label, dir) in [
        ("phi_complex, z = +iy", Complex64::new(0.0, 1.0)),
        ("phi_complex, z = -iy", Complex64::new(0.0, -1.0)),
    ] {
        let pts: Vec<Complex64> = radii.iter().map(|&r| dir * r).collect();
        let stats = sweep(label, &pts, phi_complex);
        assert_within(&stats, label, TOL);
    }
}

#[test]
fn phi_complex_against_reference_left_half_plane() {
    let radii = moduli();
    for frac in [0.55, 0.75, 0.95, -0.6, -0.9] {
        let dir = Complex64::from_polar(1.0, frac * PI);
        let label = format!("phi_complex, arg = {frac}pi");
        let pts: Vec<Complex64> = radii.iter().map(|&r| dir * r).collect();
        let stats = sweep(&label, &pts, phi_complex);
        assert_within(&stats, &label, TOL);
    }
}

#[test]
fn phi_complex_against_reference_right_half_plane() {
    // Right half-plane rays. φ_k (k ≥ 2) has zeros near the curve |e^z| ≈ |z|^{k−1}/(k−1)!,
    // which these rays cross; a point of the grid that falls very close to a zero would be
    // ill-conditioned for any f64 method, but none of these does (the measured maxima are
    // printed).
    let radii = moduli();
    for frac in [0.0, 0.25, 0.45, -0.3] {
        let dir = Complex64::from_polar(1.0, frac * PI);
        let label = format!("phi_complex, arg = {frac}pi");
        let pts: Vec<Complex64> = radii.iter().map(|&r| dir * r).collect();
        let stats = sweep(&label, &pts, phi_complex);
        assert_within(&stats, &label, TOL);
    }
}

#[test]
fn phi_complex_against_reference_random_points() {
    // Fixed-seed random points, log-uniform modulus in [1e−16, 1e12], uniform argument in the
    // closed left half-plane (the right half-plane is covered by the rays above).
    let mut rng = Rng::new(0x005E_EDF1);
    let pts: Vec<Complex64> = (0..400)
        .map(|_| {
            let r = 10f64.powf(rng.range(-16.0, 12.0));
            Complex64::from_polar(r, rng.range(0.5 * PI, 1.5 * PI))
        })
        .collect();
    let stats = sweep("phi_complex, random LHP", &pts, |z, out| {
        phi_complex(z, out)
    });
    assert_within(&stats, "random", TOL);
}

#[test]
fn phi_complex_extremes() {
    let mut out = [Complex64::new(0.0, 0.0); P + 1];
    for z in [
        Complex64::new(1e12, 1e12),
        Complex64::new(800.0, 0.0),
        Complex64::new(1e5, -3.0),
        Complex64::new(-1e300, 1e300),
        Complex64::new(0.0, 1e300),
        Complex64::new(-745.0, 1e-300),
    ] {
        phi_complex(z, &mut out);
        assert!(
            out.iter().all(|v| !v.re.is_nan() && !v.im.is_nan()),
            "NaN at z = {z}"
        );
    }
    phi_complex(Complex64::new(f64::NAN, 0.0), &mut out);
    assert!(out.iter().all(|v| v.re.is_nan()));
    phi_complex(Complex64::new(f64::NEG_INFINITY, 1.0), &mut out);
    assert!(out.iter().all(|v| v.re == 0.0 && v.im == 0.0));
    // The real path and the complex path agree on the real axis (bit-for-bit is not promised).
    let mut re = [0.0; P + 1];
    for x in [-50.0, -1.0, 1e-10, 2.5, 40.0, 650.0] {
        phi_real(x, &mut re);
        phi_complex(Complex64::new(x, 0.0), &mut out);
        for k in 0..=P {
            assert!((out[k].re - re[k]).abs() <= 2.0 * TOL * re[k].abs() && out[k].im == 0.0);
        }
    }
}

/// `θ` with a 26-bit mantissa, so that `K = θ²` is exact in f64 and `√K = θ` exactly: the
/// trigonometric functions are then compared at exactly the argument the reference uses.
fn exact_square_root(t: f64) -> f64 {
    let e = t.abs().log2().floor();
    let scale = 2f64.powf(25.0 - e);
    (t * scale).round() / scale
}

#[test]
fn phi_trig_against_reference() {
    // φᵗ_m(θ²) = Re φ_m(iθ), reference in high precision. Componentwise relative error: the
    // closed forms for m ≤ 2 keep it even next to the zeros of cos θ, sin θ/θ, (1 − cos θ)/θ²,
    // and φᵗ_m > 0 for m ≥ 3.
    let mut hp = Hp::new(PREC);
    let mut thetas: Vec<f64> = log_grid(-8, 12, 12);
    thetas.extend(log_grid(-1, 2, 40));
    // points next to zeros of cos, sin and 1 − cos
    for n in 1..40 {
        thetas.push(n as f64 * 0.5 * PI);
    }
    let mut max_err = [0.0f64; 3];
    let mut out = [0.0; P + 1];
    for &t in &thetas {
        let theta = exact_square_root(t);
        let kk = theta * theta;
        assert_eq!(kk.sqrt(), theta);
        phi_trig(kk, &mut out);
        let refs = hp.phi(Complex64::new(0.0, theta), P);
        for m in 0..=P {
            let r = &refs[m].re;
            let e = to_f64(&hp.div(&hp.sub(&hp.f(out[m]), r), r).abs());
            let bucket = if theta < 0.25 {
                0
            } else if theta <= 64.0 {
                1
            } else {
                2
            };
            max_err[bucket] = max_err[bucket].max(e);
            assert!(
                e <= TOL,
                "phi_trig: theta = {theta:e}, m = {m}: rel err {e:e}"
            );
        }
    }
    println!(
        "phi_trig K = theta^2 >= 0: max rel err {:.2e} (theta < 0.25), {:.2e} (0.25..64), {:.2e} (64..1e12)",
        max_err[0], max_err[1], max_err[2]
    );
    // K < 0: φᵗ_m(−θ²) = (φ_m(θ) + φ_m(−θ))/2, a sum of positive terms.
    let mut max_neg = 0.0f64;
    for &t in &log_grid(-8, 2, 12) {
        let theta = exact_square_root(t);
        phi_trig(-theta * theta, &mut out);
        let a = hp.phi(Complex64::new(theta, 0.0), P);
        let b = hp.phi(Complex64::new(-theta, 0.0), P);
        for m in 0..=P {
            let r = hp.mul(&hp.add(&a[m].re, &b[m].re), &hp.f(0.5));
            let e = to_f64(&hp.div(&hp.sub(&hp.f(out[m]), &r), &r).abs());
            max_neg = max_neg.max(e);
            assert!(
                e <= TOL,
                "phi_trig: K = -{:e}, m = {m}: rel err {e:e}",
                theta * theta
            );
        }
    }
    println!("phi_trig K < 0 (theta <= 100): max rel err {max_neg:.2e}");
    phi_trig(f64::NAN, &mut out);
    assert!(out.iter().all(|v| v.is_nan()));
    phi_trig(0.0, &mut out);
    assert!(out.iter().enumerate().all(|(m, v)| *v == inv_factorial(m)));
}

#[test]
fn phi_diagonal_matches_phi_real() {
    let d = [-1e8, -3.0, 0.0, 1e-9, 2.0];
    let res = phi_diagonal(&d, 4);
    assert_eq!(res.len(), 5);
    let mut buf = [0.0; 5];
    for (j, &x) in d.iter().enumerate() {
        phi_real(x, &mut buf);
        for k in 0..5 {
            assert_eq!(res[k][j], buf[k]);
        }
    }
}

fn proptest_config() -> ProptestConfig {
    ProptestConfig {
        cases: 256,
        rng_seed: RngSeed::Fixed(0x0EC2_5EED),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

/// Log-uniform modulus in [1e−12, 1e6] with a random sign.
fn arb_real() -> impl Strategy<Value = f64> {
    (-12.0f64..6.0, any::<bool>())
        .prop_map(|(e, neg)| if neg { -(10f64.powf(e)) } else { 10f64.powf(e) })
}

/// Log-uniform modulus in [1e−12, 1e6], argument in the closed left half-plane or on the
/// imaginary axis.
fn arb_complex() -> impl Strategy<Value = Complex64> {
    (-12.0f64..6.0, 0.5f64..1.5).prop_map(|(e, a)| Complex64::from_polar(10f64.powf(e), a * PI))
}

proptest! {
    #![proptest_config(proptest_config())]

    /// z φ_{k+1}(z) = φ_k(z) − 1/k!, checked relative to |φ_k| + 1/k! (the scale of the two
    /// terms being subtracted): each side is within 1e−14 of its exact value relative to that
    /// scale, so 3e−14 allows for both plus the product's rounding.
    #[test]
    fn recurrence_real(z in arb_real()) {
        let mut out = [0.0; P + 2];
        phi_real(z, &mut out);
        // Overflow region (z ≳ 710 + k ln z): values are +∞ by design, nothing to check.
        prop_assume!(out.iter().all(|v| v.is_finite()));
        for k in 0..=P {
            let lhs = z * out[k + 1];
            let rhs = out[k] - inv_factorial(k);
            let scale = out[k].abs() + inv_factorial(k);
            prop_assert!((lhs - rhs).abs() <= 3e-14 * scale, "z = {}, k = {}: {} vs {}", z, k, lhs, rhs);
        }
    }

    #[test]
    fn recurrence_complex(z in arb_complex()) {
        let mut out = [Complex64::new(0.0, 0.0); P + 2];
        phi_complex(z, &mut out);
        for k in 0..=P {
            let lhs = z * out[k + 1];
            let rhs = out[k] - inv_factorial(k);
            let scale = out[k].norm() + inv_factorial(k);
            prop_assert!((lhs - rhs).norm() <= 3e-14 * scale, "z = {}, k = {}: {} vs {}", z, k, lhs, rhs);
        }
    }

    /// φ_k(conj z) = conj φ_k(z) (every step of the algorithm commutes with conjugation).
    #[test]
    fn conjugate_symmetry(z in arb_complex()) {
        let mut a = [Complex64::new(0.0, 0.0); P + 1];
        let mut b = [Complex64::new(0.0, 0.0); P + 1];
        phi_complex(z, &mut a);
        phi_complex(z.conj(), &mut b);
        for k in 0..=P {
            prop_assert!((a[k].conj() - b[k]).norm() <= 1e-15 * a[k].norm(), "z = {}, k = {}", z, k);
        }
    }

    /// The doubling formula φ_k(2x) = 2^{−k}[φ₀φ_k + Σ_{j=1}^k φ_j/(k−j)!](x) for real x: all
    /// terms are positive, so the right side is within 1e−14 (+ k roundings) of the exact value.
    #[test]
    fn doubling_real(x in arb_real()) {
        let mut a = [0.0; P + 1];
        let mut b = [0.0; P + 1];
        phi_real(x, &mut a);
        phi_real(2.0 * x, &mut b);
        for k in 0..=P {
            let mut rhs = a[0] * a[k];
            for j in 1..=k {
                rhs += a[j] * inv_factorial(k - j);
            }
            rhs *= 0.5f64.powi(k as i32);
            if b[k].is_finite() && rhs.is_finite() && rhs > f64::MIN_POSITIVE {
                prop_assert!((rhs - b[k]).abs() <= 3e-14 * b[k].abs(), "x = {}, k = {}: {} vs {}", x, k, rhs, b[k]);
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// Dense matrices
// ---------------------------------------------------------------------------------------

/// High-precision matrix `V diag(f) W` (`V`, `W` exact f64 data, `f` high precision).
fn hp_similarity(hp: &Hp, v: &DMatrix<f64>, f: &[Hc], w: &DMatrix<f64>) -> Vec<Vec<f64>> {
    let d = v.nrows();
    let mut res = vec![vec![0.0; d]; d];
    for i in 0..d {
        for j in 0..d {
            let mut acc = hp.f(0.0);
            for l in 0..d {
                let vw = hp.mul(&hp.f(v[(i, l)]), &hp.f(w[(l, j)]));
                acc = hp.add(&acc, &hp.mul(&vw, &f[l].re));
            }
            res[i][j] = to_f64(&acc);
        }
    }
    res
}

/// Normwise error `max|C − R| / max|R|`.
fn matrix_err(c: &DMatrix<f64>, r: &[Vec<f64>]) -> f64 {
    let d = c.nrows();
    let mut num = 0.0f64;
    let mut den = 0.0f64;
    for i in 0..d {
        for j in 0..d {
            num = num.max((c[(i, j)] - r[i][j]).abs());
            den = den.max(r[i][j].abs());
        }
    }
    if den == 0.0 { num } else { num / den }
}

/// The 4×4 Hadamard matrix / 2: exactly orthogonal in f64.
fn hadamard4() -> DMatrix<f64> {
    DMatrix::from_row_slice(
        4,
        4,
        &[
            0.5, 0.5, 0.5, 0.5, 0.5, -0.5, 0.5, -0.5, 0.5, 0.5, -0.5, -0.5, 0.5, -0.5, -0.5, 0.5,
        ],
    )
}

/// Unit upper-triangular integer V and its (integer) inverse: a non-orthogonal eigenbasis
/// known exactly (κ₁(V) = 4·8 = 32).
fn triangular_basis() -> (DMatrix<f64>, DMatrix<f64>) {
    let v = DMatrix::from_row_slice(
        4,
        4,
        &[
            1.0, 1.0, 0.0, 2.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0,
        ],
    );
    let vinv: DMatrix<f64> = v.clone().try_inverse().unwrap();
    // The inverse of a unit triangular integer matrix is an integer matrix: round, verify.
    let vinv = vinv.map(|x: f64| x.round());
    assert_eq!(&v * &vinv, DMatrix::identity(4, 4));
    (v, vinv)
}

#[test]
fn dense_diagonalizable_against_exact_eigenbasis() {
    let mut hp = Hp::new(PREC);
    let (tv, tvinv) = triangular_basis();
    let h = hadamard4();
    let bases = [
        ("hadamard", h.clone(), h.transpose()),
        ("triangular", tv, tvinv),
    ];
    // Eigenvalues (dyadic, so that A = VΛV⁻¹ is exact), scaled by 2^s to sweep ‖A‖ from 1e−6
    // to 1e8.
    let spectra: [(&str, [f64; 4]); 3] = [
        ("left half-plane", [-1.0, -0.25, -3.0, -0.5]),
        ("mixed signs", [-1.0, 0.5, 0.125, -0.75]),
        ("stiff spread", [-1.0, -1.0 / 1024.0, -0.5, -1.0 / 64.0]),
    ];
    for (bname, v, vinv) in &bases {
        for (sname, lam) in &spectra {
            let mut worst = 0.0f64;
            for s in [-20, -8, 0, 2, 5, 10, 16, 20, 26] {
                let sc = 2f64.powi(s);
                if *sname == "mixed signs" && s > 10 {
                    continue; // e^{0.5·2^s} overflows
                }
                let l: Vec<f64> = lam.iter().map(|x| x * sc).collect();
                let a =
                    v * DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(&l)) * vinv;
                let phis = phi_dense(&a, 4).unwrap();
                let refs: Vec<Vec<Hc>> = l
                    .iter()
                    .map(|&x| hp.phi(Complex64::new(x, 0.0), 4))
                    .collect();
                for k in 0..=4 {
                    let f: Vec<Hc> = refs.iter().map(|r| r[k].clone()).collect();
                    let r = hp_similarity(&hp, v, &f, vinv);
                    let e = matrix_err(&phis[k], &r);
                    worst = worst.max(e);
                    // Tolerance. φ_k, k ≥ 1: the doubling phase adds O(u) per doubling (s ≤ 28)
                    // for these decaying/moderate spectra, times the condition number of the
                    // basis (κ₁ = 1 for Hadamard, 32 for triangular): 64·(s+2)·κ·u.
                    // φ₀: scaling and squaring is backward stable with backward error ~u‖A‖,
                    // and the relative condition number of e^A is ‖A‖ for normal A (Van Loan
                    // 1977): when every component decays (e^{−64} next to e^{−65536}) the
                    // attainable normwise relative error is ~‖A‖u, so 64·κ·(1 + ‖A‖₁)·u.
                    let kappa = if *bname == "hadamard" { 1.0 } else { 32.0 };
                    let u = f64::EPSILON / 2.0;
                    let tol = if k == 0 {
                        64.0 * kappa
                            * (1.0 + a.column_iter().map(|c| c.abs().sum()).fold(0.0, f64::max))
                            * u
                    } else {
                        64.0 * (s.max(0) as f64 + 2.0) * kappa * u
                    };
                    assert!(
                        e <= tol,
                        "{bname}/{sname}, scale 2^{s}, k = {k}: err {e:e} > {tol:e}"
                    );
                }
            }
            println!("phi_dense {bname:<10} {sname:<16} max normwise rel err {worst:.2e}");
        }
    }
}

/// `φ_k^{(m)}(λ)/m!` in high precision: `e^λ/m!` for k = 0, else
/// `Σ_{i=0}^{m} (−1)^i C(m,i) (k−1+i)!/((k−1)! m!) φ_{k+i}(λ)` (differentiate under the integral
/// `φ_k(z) = ∫₀¹ e^{(1−θ)z} θ^{k−1}/(k−1)! dθ` and expand `(1−θ)^m`).
fn phi_derivative(hp: &mut Hp, lambda: f64, k: usize, m: usize) -> BigF {
    let phis = hp.phi(Complex64::new(lambda, 0.0), k + m);
    if k == 0 {
        return hp.mul(&phis[0].re, &hp.inv_fact(m));
    }
    let mut acc = hp.f(0.0);
    for i in 0..=m {
        // C(m,i) (k−1+i)! / ((k−1)! m!) = (k−1+i)! / (i! (m−i)! (k−1)!)
        let c = hp.div(
            &hp.mul(&hp.inv_fact(i), &hp.inv_fact(m - i)),
            &hp.mul(&hp.inv_fact(k - 1 + i), &hp.f(1.0)),
        );
        let c = hp.mul(&c, &hp.inv_fact(k - 1));
        let term = hp.mul(&c, &phis[k + i].re);
        acc = if i % 2 == 0 {
            hp.add(&acc, &term)
        } else {
            hp.sub(&acc, &term)
        };
    }
    acc
}

type BigF = astro_float::BigFloat;

/// The brief's closed form for Jordan blocks, `Σ_n C(n+m, m) λⁿ/(n+m+k)!`, for moderate λ.
fn phi_derivative_series(hp: &Hp, lambda: f64, k: usize, m: usize) -> BigF {
    // term_0 = 1/(m+k)!, term_{n+1}/term_n = λ (n+m+1)/((n+1)(n+m+k+1)).
    let lam = hp.f(lambda);
    let mut term = hp.inv_fact(m + k);
    let mut acc = term.clone();
    for n in 0..200usize {
        let num = hp.mul(&lam, &hp.int((n + m + 1) as i64));
        let den = hp.int(((n + 1) * (n + m + k + 1)) as i64);
        term = hp.mul(&term, &hp.div(&num, &den));
        acc = hp.add(&acc, &term);
    }
    acc
}

#[test]
fn jordan_reference_formulas_agree() {
    let mut hp = Hp::new(PREC);
    for &lambda in &[-3.0, 0.5, 2.0] {
        for k in 0..4 {
            for m in 0..4 {
                let a = phi_derivative(&mut hp, lambda, k, m);
                let b = phi_derivative_series(&hp, lambda, k, m);
                let e = to_f64(&hp.div(&hp.sub(&a, &b), &b).abs());
                assert!(e < 1e-60, "lambda {lambda}, k {k}, m {m}: {e:e}");
            }
        }
    }
}

#[test]
fn dense_jordan_blocks() {
    // A = λI + νJ (J the shift): φ_k(A)_{i,i+m} = ν^m φ_k^{(m)}(λ)/m!. Strongly non-normal for
    // ν = |λ|; ‖A‖ up to 2e8.
    let mut hp = Hp::new(PREC);
    let d = 5;
    let p = 3;
    for &(lambda, nu) in &[
        (-1.0, 1.0),
        (2.0, 1.0),
        (-10.0, 10.0),
        (-30.0, 1.0),
        (-1e4, 1e4),
        (-1e8, 1e8),
        (-1e8, 1.0),
        (-1e12, 1e12),
        (-1e12, 1.0),
        (0.0, 1e3),
    ] {
        let mut a = DMatrix::from_element(d, d, 0.0);
        for i in 0..d {
            a[(i, i)] = lambda;
            if i + 1 < d {
                a[(i, i + 1)] = nu;
            }
        }
        let phis = phi_dense(&a, p).unwrap();
        let mut worst = 0.0f64;
        for k in 0..=p {
            let mut r = vec![vec![0.0; d]; d];
            for m in 0..d {
                let c = phi_derivative(&mut hp, lambda, k, m);
                let c = hp.mul(
                    &c,
                    &hp.f(nu).powi(m, PREC, astro_float::RoundingMode::ToEven),
                );
                let v = to_f64(&c);
                for i in 0..d - m {
                    r[i][i + m] = v;
                }
            }
            let e = matrix_err(&phis[k], &r);
            worst = worst.max(e);
            assert!(phis[k].iter().all(|v| v.is_finite()));
            // Tolerance: normwise error O(s·u·‖|φ|‖/‖φ‖) with s ≤ 29 doublings, and the
            // non-normal transient of a Jordan block with ν = |λ| (‖N^m‖/m! up to 1e0·‖φ‖)
            // multiplies it by the block size: 1e−12 covers 29 · 5 · 64 u with room.
            let tol = 1e-12;
            if lambda == 0.0 && nu == 1e3 && k == 0 {
                // φ₀ = Σ N^m/m! has entries up to 1e12/24; normwise the same bound applies.
            }
            assert!(e <= tol, "lambda {lambda}, nu {nu}, k = {k}: err {e:e}");
        }
        if lambda <= -1e8 {
            // Strong damping: φ₀ ≈ 0 (here it underflows: e^{−1e8}, e^{−1e12}).
            assert!(
                phis[0].iter().all(|v| v.abs() <= 1e-300),
                "phi0 not ~0: {}",
                phis[0]
            );
        }
        println!(
            "phi_dense Jordan lambda = {lambda:e}, nu = {nu:e}: max normwise rel err {worst:.2e}"
        );
    }
}

#[test]
fn dense_large_skew_part() {
    // A = [[−1, ω], [−ω, −1]]: e^A = e^{−1} R(ω). The condition number of e^A is ~ω, so the
    // attainable normwise error is ~ω·u (the rounded angle alone is off by ω·u/2).
    let mut hp = Hp::new(PREC);
    for &omega in &[1.0, 1e3, 1e6, 1e8] {
        let a = DMatrix::from_row_slice(2, 2, &[-1.0, omega, -omega, -1.0]);
        let phis = phi_dense(&a, 3).unwrap();
        // φ_k(A) = [[Re φ_k(λ), Im φ_k(λ)], [−Im, Re]] with λ = −1 + iω.
        let r = hp.phi(Complex64::new(-1.0, omega), 3);
        let mut worst = 0.0f64;
        for k in 0..=3 {
            let c = common_phi::to_c64(&r[k]);
            let refm = vec![vec![c.re, c.im], vec![-c.im, c.re]];
            let e = matrix_err(&phis[k], &refm);
            worst = worst.max(e);
            assert!(phis[k].iter().all(|v| v.is_finite()));
            // Tolerance: the conditioning ~ω·u, with a factor 8 of room.
            let tol = 8.0 * (1.0 + omega) * f64::EPSILON;
            assert!(e <= tol, "omega {omega:e}, k = {k}: err {e:e} > {tol:e}");
        }
        println!("phi_dense skew omega = {omega:e}: max normwise rel err {worst:.2e}");
    }
}

#[test]
fn dense_strongly_damped_nonnormal_is_zero_not_garbage() {
    // ‖A‖ = 1e8 class, spectrum in the left half-plane, non-normal: φ₀ must be ≈ 0 and the
    // φ_k bounded (≈ ‖A⁻¹‖/(k−1)!), no NaN.
    let mut rng = Rng::new(7);
    let d = 6;
    let mut a = DMatrix::from_fn(d, d, |i, j| {
        if i == j {
            -1e8 * (1.0 + i as f64)
        } else if j > i {
            1e8 * rng.range(-1.0, 1.0)
        } else {
            0.0
        }
    });
    a[(d - 1, 0)] = 0.0;
    let phis = phi_dense(&a, 4).unwrap();
    let n0 = phis[0].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(n0 <= 1e-300, "phi0 max entry {n0:e}");
    for k in 1..=4 {
        assert!(phis[k].iter().all(|v| v.is_finite()));
        let nk = phis[k].iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(nk < 1e-6, "k = {k}: {nk:e}");
    }
    // Cross-check against the triangular structure: diagonal entries are φ_k(a_ii) exactly.
    let mut buf = [0.0; 5];
    for i in 0..d {
        phi_real(a[(i, i)], &mut buf);
        for k in 1..=4 {
            let e = (phis[k][(i, i)] - buf[k]).abs() / buf[k];
            // 28 doublings, each O(u) for these positive terms: 1e−13.
            assert!(e < 1e-13, "i = {i}, k = {k}: {e:e}");
        }
    }
}

#[test]
fn symmetric_path_against_exact_and_dense() {
    let mut hp = Hp::new(PREC);
    let q = hadamard4();
    let mut worst = 0.0f64;
    for lam in [[-3.0, -0.25, 1.5, -7.0], [-3.0, -0.25, 1.5, -1e6]] {
        let a = &q
            * DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(&lam))
            * q.transpose();
        let sym = phi_symmetric(&a, 5).unwrap();
        let refs: Vec<Vec<Hc>> = lam
            .iter()
            .map(|&x| hp.phi(Complex64::new(x, 0.0), 5))
            .collect();
        // Tolerance: a backward-stable eigensolver perturbs A by ~u‖A‖; the eigenvectors then
        // move by ~u‖A‖/gap (gap = 1.75 between 1.5 and −0.25), and φ_k(A) normwise by about
        // that much relative. 16·u·(1 + ‖A‖/gap) is 1.3e−14 for ‖A‖ = 7 and 1e−9 for the stiff
        // ‖A‖ = 1e6 (measured: printed below).
        let norm = lam.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let tol = 16.0 * (f64::EPSILON / 2.0) * (1.0 + norm / 1.75);
        let mut worst_here = 0.0f64;
        for k in 0..=5 {
            let f: Vec<Hc> = refs.iter().map(|r| r[k].clone()).collect();
            let r = hp_similarity(&hp, &q, &f, &q.transpose());
            let e = matrix_err(&sym[k], &r);
            worst = worst.max(e / tol);
            worst_here = worst_here.max(e);
            assert!(
                e <= tol,
                "symmetric vs exact, lambda {lam:?}, k = {k}: {e:e} > {tol:e}"
            );
        }
        println!("phi_symmetric vs exact, lambda = {lam:?}: max normwise rel err {worst_here:.2e}");
    }
    println!("phi_symmetric vs exact (Hadamard basis): max error / tolerance {worst:.2}");

    // Random symmetric matrices: symmetric path vs dense path.
    let mut rng = Rng::new(99);
    let mut worst = 0.0f64;
    for &(d, scale) in &[(1usize, 1.0), (7, 1.0), (12, 20.0), (20, 3.0)] {
        let b = DMatrix::from_fn(d, d, |_, _| rng.range(-1.0, 1.0));
        let a = (&b + b.transpose()) * (0.5 * scale);
        let s = phi_symmetric(&a, 4).unwrap();
        let dn = phi_dense(&a, 4).unwrap();
        for k in 0..=4 {
            let r: Vec<Vec<f64>> = (0..d)
                .map(|i| (0..d).map(|j| s[k][(i, j)]).collect())
                .collect();
            let e = matrix_err(&dn[k], &r);
            worst = worst.max(e);
            // Both paths are backward stable; ‖A‖ ≤ 20·d gives ≤ 9 doublings and an
            // eigen-decomposition error ~d·u: 1e−12 normwise.
            assert!(e <= 1e-12, "d = {d}, scale {scale}, k = {k}: {e:e}");
        }
    }
    println!("phi_symmetric vs phi_dense (random symmetric): max normwise rel diff {worst:.2e}");
}

#[test]
fn dense_edge_cases_and_errors() {
    // Zero-size and 1×1.
    let z = phi_dense(&DMatrix::zeros(0, 0), 3).unwrap();
    assert_eq!(z.len(), 4);
    assert!(z.iter().all(|m| m.shape() == (0, 0)));
    let one = phi_dense(&DMatrix::from_element(1, 1, -2.0), 3).unwrap();
    let mut buf = [0.0; 4];
    phi_real(-2.0, &mut buf);
    for k in 0..4 {
        assert_eq!(one[k][(0, 0)], buf[k]);
    }
    assert_eq!(phi_symmetric(&DMatrix::zeros(0, 0), 2).unwrap().len(), 3);
    // p = 0: only φ₀, the same as the φ₀ of a longer run.
    let a = DMatrix::from_row_slice(2, 2, &[-3.0, 10.0, 0.5, -1.0]);
    let only0 = phi_dense(&a, 0).unwrap();
    assert_eq!(only0.len(), 1);
    assert_eq!(only0[0], phi_dense(&a, 3).unwrap()[0]);
    // Zero matrix: I/k!.
    let z = phi_dense(&DMatrix::zeros(3, 3), 2).unwrap();
    assert_eq!(z[2], DMatrix::identity(3, 3) * 0.5);
    // Errors.
    assert!(matches!(
        phi_dense(&DMatrix::zeros(2, 3), 1),
        Err(Error::NotSquare {
            rows: 2,
            cols: 3,
            ..
        })
    ));
    let mut nan = DMatrix::zeros(2, 2);
    nan[(0, 1)] = f64::NAN;
    assert!(matches!(phi_dense(&nan, 1), Err(Error::NonFinite(_))));
    assert!(matches!(phi_symmetric(&nan, 1), Err(Error::NonFinite(_))));
    let nonsym = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.1, 1.0]);
    assert!(matches!(
        phi_symmetric(&nonsym, 1),
        Err(Error::InvalidInput(_))
    ));
    assert!(matches!(
        phi_symmetric(&DMatrix::zeros(3, 2), 1),
        Err(Error::NotSquare { .. })
    ));
    // Overflow is reported, not returned as NaN/∞.
    let big = DMatrix::from_row_slice(2, 2, &[1e8, 1.0, 0.0, 1e8]);
    assert!(matches!(phi_dense(&big, 2), Err(Error::Numerical(_))));
    // Static path equals the dynamic one.
    let s = SMatrix::<f64, 3, 3>::new(-1.0, 2.0, 0.0, 0.5, -3.0, 1.0, 0.0, 0.25, -0.5);
    let st = phi_dense_static(&s, 3).unwrap();
    let dy = phi_dense(&DMatrix::from_column_slice(3, 3, s.as_slice()), 3).unwrap();
    for k in 0..=3 {
        assert_eq!(st[k].as_slice(), dy[k].as_slice());
    }
}
