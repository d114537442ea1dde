//! The Legendre kernels `Ψ_j(τ, x) = ∫₀¹ e^{(1−ξ)τx} P̃_j(τξ) dξ` of the ECrP stepper against
//! 256-bit references computed here from their defining sum `Σ_{k≤j} c_jk τ^k φ_{k+1}(τx)`
//! (exact integer c_jk, high-precision φ: the cancellation that the f64 stepper avoids is
//! harmless at 256 bits), over the whole argument range, for n = 16 kernels (r ≤ 16) and
//! the Gauss nodes of s = 16 together with τ = 1.
//!
//! Error measure: `|computed − exact| / φ₁(Re τx)`, where `φ₁(Re τx) = ∫₀¹ |e^{(1−ξ)τx}| dξ`
//! bounds every kernel (`|P̃_j| ≤ 1`): what a stage needs is `Ψ_j L_j` to a few units of
//! roundoff of `h |g|`, i.e. absolute accuracy on this scale. Run with `--nocapture` for the
//! table per region.

use crate::common_phi;

use common_phi::{Hc, Hp, Rng, log_grid};
use ecr_runtime::phi::{LegendreKernels, phi_dense, phi_real};
use ecr_runtime::tables::coefficients;
use nalgebra::DMatrix;
use num_complex::Complex64;

const N: usize = 16;
const PREC: usize = 256;
/// Bound on the scaled error (the φ accuracy target).
const TOL: f64 = 1e-14;

/// c_jk = (−1)^{j+k} (j+k)!/(k!(j−k)!) exactly, in high precision.
fn c_jk_hp(hp: &Hp, j: usize, k: usize) -> common_phi::BigFloat {
    let mut v = hp.f(1.0);
    for t in (j - k + 1)..=(j + k) {
        v = hp.mul(&v, &hp.int(t as i64));
    }
    for t in 2..=k {
        v = hp.div(&v, &hp.int(t as i64));
    }
    if (j + k) % 2 == 0 {
        v
    } else {
        hp.sub(&hp.f(0.0), &v)
    }
}

/// c_jk as f64 (for the small j of the dense check, where it is exact).
fn c_jk(j: usize, k: usize) -> f64 {
    let mut v = 1.0f64;
    for t in (j - k + 1)..=(j + k) {
        v *= t as f64;
    }
    for t in 2..=k {
        v /= t as f64;
    }
    if (j + k) % 2 == 0 { v } else { -v }
}

/// The reference kernels Ψ_0..Ψ_{N−1} at (τ, x) where x = τhλ is the argument the bank uses.
fn reference(hp: &mut Hp, tau: f64, x: Complex64) -> Vec<Hc> {
    let phis = hp.phi(x, N);
    let t = hp.f(tau);
    (0..N)
        .map(|j| {
            let mut acc = hp.creal(&hp.f(0.0));
            let mut tk = hp.f(1.0);
            for k in 0..=j {
                let c = hp.mul(&c_jk_hp(hp, j, k), &tk);
                acc = hp.cadd(&acc, &hp.cscale(&phis[k + 1], &c));
                tk = hp.mul(&tk, &t);
            }
            acc
        })
        .collect()
}

fn taus() -> Vec<f64> {
    let c = coefficients(N, N).expect("s = 16 table");
    let mut t: Vec<f64> = c.nodes.iter().copied().step_by(3).collect();
    t.push(1.0);
    t
}

/// Max scaled error over the points, for every τ.
fn sweep(label: &str, hp: &mut Hp, pts: &[Complex64]) -> f64 {
    let k = LegendreKernels::new(N);
    let mut worst = 0.0f64;
    let mut per_j = [0.0f64; N];
    for tau in taus() {
        let map = k.node_map(tau);
        for &z in pts {
            let x = z * tau;
            let mut row = [Complex64::new(0.0, 0.0); N + 1];
            k.row_complex(&map, x, &mut row);
            let mut scale = [0.0; 2];
            phi_real(x.re, &mut scale);
            let r = reference(hp, tau, x);
            for (j, rj) in r.iter().enumerate() {
                let e = hp.abs_err(row[j + 1], rj) / scale[1];
                assert!(
                    e.is_finite(),
                    "{label}: τ={tau} x={x} j={j}: {:?}",
                    row[j + 1]
                );
                if e > per_j[j] {
                    per_j[j] = e;
                    if e > TOL {
                        println!("  {label}: τ={tau} x={x} j={j}: {e:.2e}");
                    }
                }
                worst = worst.max(e);
            }
            if z.im == 0.0 {
                // The real path agrees with the complex one to the bit pattern's rounding.
                let mut real = [0.0; N + 1];
                k.row_real(&map, x.re, &mut real);
                for (a, b) in real.iter().zip(&row) {
                    assert!((a - b.re).abs() <= 4.0 * f64::EPSILON * scale[1].max(a.abs()));
                }
            }
        }
    }
    println!(
        "| {label} | {} points × {} nodes | {worst:.2e} |",
        pts.len(),
        taus().len()
    );
    worst
}

fn moduli() -> Vec<f64> {
    let mut m = log_grid(-16, 12, 2);
    m.extend([
        0.49, 0.51, 0.999, 1.001, 7.9, 8.1, 1023.0, 1025.0, 2047.0, 2049.0,
    ]);
    m
}

#[test]
fn kernels_against_reference_real_axis() {
    let mut hp = Hp::new(PREC);
    let neg: Vec<Complex64> = moduli().iter().map(|&r| Complex64::new(-r, 0.0)).collect();
    // Positive reals up to where ψ fits in f64 comfortably (e^x overflows at 709.8).
    let pos: Vec<Complex64> = moduli()
        .iter()
        .filter(|&&r| r <= 600.0)
        .map(|&r| Complex64::new(r, 0.0))
        .collect();
    let a = sweep("real, x < 0", &mut hp, &neg);
    let b = sweep("real, x > 0", &mut hp, &pos);
    assert!(a <= TOL && b <= TOL, "{a:e} {b:e}");
}

#[test]
fn kernels_against_reference_imaginary_axis() {
    let mut hp = Hp::new(PREC);
    let pts: Vec<Complex64> = moduli()
        .iter()
        .flat_map(|&r| [Complex64::new(0.0, r), Complex64::new(0.0, -r)])
        .collect();
    let e = sweep("imaginary axis", &mut hp, &pts);
    assert!(e <= TOL, "{e:e}");
}

#[test]
fn kernels_against_reference_complex_plane() {
    let mut hp = Hp::new(PREC);
    let mut rng = Rng::new(0x5eed_1e9e);
    let pts: Vec<Complex64> = (0..60)
        .map(|_| {
            let r = 10f64.powf(rng.range(-8.0, 6.0));
            let a = rng.range(0.0, std::f64::consts::TAU);
            Complex64::from_polar(r, a)
        })
        .filter(|z| z.re <= 600.0)
        .collect();
    let e = sweep("complex plane", &mut hp, &pts);
    assert!(e <= TOL, "{e:e}");
}

/// Fewer kernels (n = 1 … 15) give the first n of the n = 16 values checked above, to a few
/// units of roundoff of φ₁(Re x): ψ at |x| ≤ 4 comes from the Taylor series of the last two
/// and the recurrence downwards, so n decides where the recurrence starts.
#[test]
fn fewer_kernels_agree_with_sixteen() {
    let all = LegendreKernels::new(N);
    let mut rng = Rng::new(0x5eed_1e6e_0d2e_0001);
    let mut worst = 0.0f64;
    for &r in &[
        1e-4,
        1.0 / 1024.0,
        0.01,
        0.3,
        0.5,
        0.51,
        1.0,
        2.0,
        3.9,
        4.0,
        4.1,
        7.9,
    ] {
        for _ in 0..24 {
            let th = std::f64::consts::TAU * rng.uniform();
            let x = Complex64::from_polar(r, th);
            let mut full = [Complex64::new(0.0, 0.0); N];
            all.psi_complex(x, &mut full);
            let mut scale = [0.0; 2];
            phi_real(x.re, &mut scale);
            for n in 1..N {
                let k = LegendreKernels::new(n);
                let mut out = vec![Complex64::new(0.0, 0.0); n];
                k.psi_complex(x, &mut out);
                for (m, (a, b)) in out.iter().zip(&full).enumerate() {
                    let e = (a - b).norm() / scale[1];
                    assert!(e <= TOL, "n = {n}, x = {x}, m = {m}: {e:e}");
                    worst = worst.max(e);
                }
            }
        }
    }
    println!("fewer kernels against 16: {worst:.2e}");
}

#[test]
fn extremes_and_special_values() {
    let k = LegendreKernels::new(12);
    let mut out = [0.0; 12];
    k.psi_real(f64::NEG_INFINITY, &mut out);
    assert!(out.iter().all(|&v| v == 0.0));
    k.psi_real(f64::NAN, &mut out);
    assert!(out.iter().all(|v| v.is_nan()));
    k.psi_real(0.0, &mut out);
    assert_eq!(out[0], 1.0);
    assert!(out[1..].iter().all(|&v| v == 0.0));
    // ψ overflows to ±∞ (never NaN) far in the right half-plane.
    k.psi_real(800.0, &mut out);
    assert!(out.iter().all(|v| v.is_infinite()), "{out:?}");
    let mut outc = [Complex64::new(0.0, 0.0); 12];
    k.psi_complex(Complex64::new(f64::NEG_INFINITY, 3.0), &mut outc);
    assert!(outc.iter().all(|v| v.norm() == 0.0));
    // τ = 0 and τ = 1 maps are exact.
    let map1 = k.node_map(1.0);
    let map0 = k.node_map(0.0);
    for j in 0..12 {
        for m in 0..12 {
            assert_eq!(map1[j * 12 + m], if j == m { 1.0 } else { 0.0 });
            let v0 = if m == 0 { [1.0, -1.0][j % 2] } else { 0.0 };
            assert_eq!(map0[j * 12 + m], v0);
        }
    }
}

/// Dense matrices: a non-normal 6 × 6 (Jordan-like block plus a skew part) with ‖X‖ from 1e−3
/// to 1e12; reference: the kernels of the diagonal similar matrix are not available for a
/// Jordan block, so the check is the defining sum Σ c_jk τ^k φ_{k+1}(τX) with the dense φ in
/// f64, which is accurate where the sum does not cancel (‖X‖ ≥ 10 and j ≤ 3), and the scalar
/// kernels on a diagonal matrix everywhere.
#[test]
fn dense_kernels() {
    let n = 8;
    let k = LegendreKernels::new(n);
    // Diagonal: must equal the scalar path to a few ulps of the kernel scale.
    for &s in &[1e-3f64, 0.7, 13.0, 400.0, 1e5] {
        let diag = [-s, -0.3 * s, 0.1 * s.min(50.0), -2.0 * s];
        let x = DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(&diag));
        let psi = k.psi_dense(&x).unwrap();
        for (t, &lam) in diag.iter().enumerate() {
            let mut row = vec![0.0; n];
            k.psi_real(lam, &mut row);
            let mut scale = [0.0; 2];
            phi_real(lam, &mut scale);
            for m in 0..n {
                let e = (psi[m][(t, t)] - row[m]).abs() / scale[1];
                assert!(e < 1e-13, "s={s} λ={lam} m={m}: {e:e}");
            }
        }
    }
    // Non-normal: Jordan-like block with a large off-diagonal part and a rotation.
    for &s in &[10.0, 100.0, 1000.0, 1e6, 1e12] {
        let mut x = DMatrix::<f64>::zeros(6, 6);
        for i in 0..6 {
            x[(i, i)] = -s * (1.0 + i as f64 / 6.0);
            if i + 1 < 6 {
                x[(i, i + 1)] = s;
            }
        }
        x[(0, 5)] = 0.5 * s;
        x[(5, 0)] = -0.5 * s;
        let tau = 0.7;
        let map = k.node_map(tau);
        let got = k.rows_dense(&map, &(&x * tau)).unwrap();
        let phis = phi_dense(&(&x * tau), n).unwrap();
        for (j, gj) in got.iter().enumerate().take(4) {
            let mut want = DMatrix::<f64>::zeros(6, 6);
            for kk in 0..=j {
                want += &phis[kk + 1] * (c_jk(j, kk) * tau.powi(kk as i32));
            }
            let e = (gj - &want).abs().max() / phis[1].abs().max();
            assert!(e < 1e-12, "s={s} j={j}: {e:e}");
        }
    }
}
