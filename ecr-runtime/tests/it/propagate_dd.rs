//! `PhiBank::propagate_dd` of every operator kind against 256-bit references of `e^{hA} y0`.
//!
//! * Scalar, diagonal, dense (dynamic and static) and symmetric operators carry the propagator
//!   in double-double: `hi + lo` must agree with the reference to 1e−30 relative (normwise);
//!   for the dense kinds up to `‖hA‖ ≈ 30`, beyond which each squaring of the double-double
//!   scaling and squaring doubles the error (5.7e−29 at `‖hA‖ ≈ 1e4`).
//!   The dense and symmetric test matrices are `A = H D H` with H the 4 × 4 Hadamard matrix
//!   divided by 2 (orthogonal and symmetric, entries ±1/2) and D diagonal with dyadic entries,
//!   so A and hA are exact in f64 and `e^{hA} = H e^{hD} H` is an exact reference.
//! * Spectral operators (circulant, 2D circulant, skew pair) carry `y0 + V (e^{hΛ} − I) V⁻¹ y0`
//!   with f64 transforms: the error is bounded by the transform rounding times `max |e^{hλ} −
//!   1|`, so it falls below f64 resolution when `‖hA‖` is small, and a mode with `e^{hλ} = 1`
//!   (the constant vector of a difference Laplacian) is reproduced exactly. The references are
//!   256-bit DFTs of the operators as given (their first columns).

use crate::common_phi;

use astro_float::{BigFloat, Consts, RoundingMode};
use common_phi::{Hc, Hp, to_f64};
use ecr_runtime::operator::{
    Circulant, Circulant2d, Dense, DenseStatic, Diagonal, LinearOperator, PhiBank, Scalar,
    SkewPair, Symmetric, Zero,
};
use nalgebra::DMatrix;

const PREC: usize = 256;
const RM: RoundingMode = RoundingMode::ToEven;

/// The kernel bank's nodes: τ = 1 (index 1) carries the propagator, τ = 0.5 does not.
const TAUS: [f64; 2] = [0.5, 1.0];

/// `(hi, lo)` from `propagate_dd` at τ = 1, after checking that τ = 0.5 declines.
fn propagate<A: LinearOperator>(op: &A, h: f64, y0: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let bank = op.kernel_bank(h, &TAUS, 2).unwrap();
    let mut ws = bank.workspace();
    let d = y0.len();
    let (mut hi, mut lo) = (vec![7.0; d], vec![7.0; d]);
    assert!(!bank.propagate_dd(0, y0, &mut hi, &mut lo, &mut ws));
    assert!(hi.iter().chain(&lo).all(|v| *v == 7.0), "outputs touched");
    assert!(bank.propagate_dd(1, y0, &mut hi, &mut lo, &mut ws));
    (hi, lo)
}

/// `max_i |hi_i + lo_i − r_i| / max_i |r_i|` (normwise relative error).
fn rel_err(hp: &Hp, hi: &[f64], lo: &[f64], r: &[BigFloat]) -> f64 {
    let mut err = 0.0f64;
    let mut mag = 0.0f64;
    for ((h, l), rv) in hi.iter().zip(lo).zip(r) {
        let v = hp.add(&hp.f(*h), &hp.f(*l));
        err = err.max(to_f64(&hp.sub(&v, rv)).abs());
        mag = mag.max(to_f64(rv).abs());
    }
    err / mag
}

#[test]
fn zero_scalar_and_diagonal_to_1e_30() {
    let mut hp = Hp::new(PREC);
    let h = 0.37;
    let entries = [0.0, -1.0, 2.5, -37.0, 1e-9, -1e4, 0.3, -0.7, 5.0];
    let y0: Vec<f64> = (0..entries.len()).map(|i| 1.0 + 0.1 * i as f64).collect();
    // The bank's argument is (τ h) λ rounded, with τ = 1.
    let x = |l: f64| (1.0 * h) * l;
    let r: Vec<BigFloat> = entries
        .iter()
        .zip(&y0)
        .map(|(l, y)| {
            let e = hp.exp(&hp.f(x(*l)));
            hp.mul(&e, &hp.f(*y))
        })
        .collect();
    let (hi, lo) = propagate(&Diagonal::new(entries.to_vec()).unwrap(), h, &y0);
    // Entrywise, every entry whose reference is a normal f64 number.
    for (t, rv) in r.iter().enumerate() {
        if to_f64(rv).abs() > 1e-290 {
            let e = rel_err(&hp, &hi[t..=t], &lo[t..=t], std::slice::from_ref(rv));
            assert!(
                e < 1e-30,
                "diagonal entry {}: relative error {e:e}",
                entries[t]
            );
        }
    }
    println!(
        "Diagonal: normwise relative error {:.1e}",
        rel_err(&hp, &hi, &lo, &r)
    );
    let (hi, lo) = propagate(&Zero::new(4), h, &y0[..4]);
    assert_eq!((hi.as_slice(), lo.as_slice()), (&y0[..4], &[0.0; 4][..]));
    for a in [0.0, -2.3, 4.1, -1e3] {
        let (hi, lo) = propagate(&Scalar::new(a, 3).unwrap(), h, &y0[..3]);
        let e = hp.exp(&hp.f(x(a)));
        let r: Vec<BigFloat> = y0[..3].iter().map(|y| hp.mul(&e, &hp.f(*y))).collect();
        let err = rel_err(&hp, &hi, &lo, &r);
        println!("Scalar a = {a}: relative error {err:.1e}");
        assert!(err < 1e-30, "scalar a = {a}: {err:e}");
    }
}

/// `A = H diag(dg) H`, exact in f64 for dyadic `dg` (H the Hadamard matrix / 2).
fn hadamard(dg: [f64; 4]) -> (DMatrix<f64>, DMatrix<f64>) {
    #[rustfmt::skip]
    let hm = DMatrix::from_row_slice(4, 4, &[
        0.5, 0.5, 0.5, 0.5,
        0.5, -0.5, 0.5, -0.5,
        0.5, 0.5, -0.5, -0.5,
        0.5, -0.5, -0.5, 0.5,
    ]);
    let a = &hm * DMatrix::from_diagonal(&nalgebra::DVector::from_row_slice(&dg)) * &hm;
    (a, hm)
}

#[test]
fn dense_static_and_symmetric_to_1e_30_below_stiff_norms() {
    let mut hp = Hp::new(PREC);
    let y0 = [1.0, -0.25, 0.75, 2.0];
    // ‖hA‖ from ≈ 1 to ≈ 1e4 (h = 0.375), most with a null vector (dg[0] = 0), and the bound:
    // 1e−30 up to ‖hA‖ ≈ 30. At ‖hA‖ ≈ 1e4 the scaling and squaring of `expm_dd` takes 15
    // double-double squarings, each of which doubles the relative error: measured 5.7e−29.
    let cases = [
        ([0.0, -3.25, -0.5, 1.75], 1e-30),
        ([-1.5, 0.25, -3.0, 2.0], 1e-30),
        ([0.0, -64.0, -8.5, 12.0], 1e-30),
        ([0.0, -26624.0, -1024.0, -0.5], 1e-28),
    ];
    let h = 0.375;
    for (dg, tol) in cases {
        let (a, hm) = hadamard(dg);
        // Reference H e^{h D} H y0, in 256 bits.
        let mut hy = Vec::new();
        for i in 0..4 {
            let mut s = hp.f(0.0);
            for (j, y) in y0.iter().enumerate() {
                s = hp.add(&s, &hp.mul(&hp.f(hm[(i, j)]), &hp.f(*y)));
            }
            let e = hp.exp(&hp.f(h * dg[i]));
            hy.push(hp.mul(&e, &s));
        }
        let r: Vec<BigFloat> = (0..4)
            .map(|i| {
                let mut s = hp.f(0.0);
                for (j, v) in hy.iter().enumerate() {
                    s = hp.add(&s, &hp.mul(&hp.f(hm[(i, j)]), v));
                }
                s
            })
            .collect();
        let runs = [
            ("Dense", propagate(&Dense::new(a.clone()).unwrap(), h, &y0)),
            (
                "DenseStatic<4>",
                propagate(
                    &DenseStatic::<4>::new(nalgebra::SMatrix::<f64, 4, 4>::from_column_slice(
                        a.as_slice(),
                    ))
                    .unwrap(),
                    h,
                    &y0,
                ),
            ),
            (
                "Symmetric",
                propagate(&Symmetric::new(a.clone()).unwrap(), h, &y0),
            ),
        ];
        for (label, (hi, lo)) in runs {
            let err = rel_err(&hp, &hi, &lo, &r);
            println!(
                "{label}, hD = {:?}: relative error {err:.1e}",
                dg.map(|v| v * h)
            );
            assert!(err < tol, "{label}, D = {dg:?}: {err:e}");
        }
    }
}

/// The 256-bit reference of `V e^{μ h Λ} V⁻¹ u` for the doubly periodic convolution with kernel
/// c on an nx × ny grid (1D: ny = 1), for complex u, with μ = 1 (circulant) or μ = i (skew
/// pair, whose generator is symmetric so Λ is real).
struct SpectralRef {
    hp: Hp,
    pi: BigFloat,
}

impl SpectralRef {
    fn new() -> Self {
        let mut cc = Consts::new().unwrap();
        SpectralRef {
            hp: Hp::new(PREC),
            pi: cc.pi(PREC, RM),
        }
    }

    /// `e^{−2πi (jx mx / nx + jy my / ny)}`.
    fn twiddle(&mut self, nx: usize, ny: usize, j: usize, m: usize, sign: f64) -> Hc {
        let hp = &mut self.hp;
        let (jx, jy, mx, my) = (j / ny, j % ny, m / ny, m % ny);
        // 2π (jx mx ny + jy my nx) / (nx ny), reduced mod nx ny.
        let k = ((jx * mx * ny + jy * my * nx) % (nx * ny)) as i64;
        let ang = hp.div(
            &hp.mul(&hp.mul(&self.pi, &hp.int(2 * k)), &hp.f(sign)),
            &hp.int((nx * ny) as i64),
        );
        let ang = hp.mul(&ang, &hp.f(-1.0));
        Hc {
            re: hp.cos(&ang),
            im: hp.sin(&ang),
        }
    }

    fn dft(&mut self, nx: usize, ny: usize, x: &[Hc], sign: f64) -> Vec<Hc> {
        let n = nx * ny;
        (0..n)
            .map(|m| {
                let mut s = self.hp.creal(&self.hp.f(0.0));
                for (j, xv) in x.iter().enumerate() {
                    let w = self.twiddle(nx, ny, j, m, sign);
                    s = self.hp.cadd(&s, &self.hp.cmul(&w, xv));
                }
                s
            })
            .collect()
    }

    /// The reference output and `max_m |e^{μ h λ_m} − 1|`.
    fn propagate(
        &mut self,
        (nx, ny): (usize, usize),
        c: &[f64],
        h: f64,
        imaginary: bool,
        u: &[(f64, f64)],
    ) -> (Vec<Hc>, f64) {
        let n = nx * ny;
        let cc: Vec<Hc> = c.iter().map(|v| self.hp.creal(&self.hp.f(*v))).collect();
        let lambda = self.dft(nx, ny, &cc, 1.0);
        let uu: Vec<Hc> = u
            .iter()
            .map(|(a, b)| Hc {
                re: self.hp.f(*a),
                im: self.hp.f(*b),
            })
            .collect();
        let uh = self.dft(nx, ny, &uu, 1.0);
        let mut dmax = 0.0f64;
        let scaled: Vec<Hc> = lambda
            .iter()
            .zip(&uh)
            .map(|(l, x)| {
                let hl = self.hp.cscale(l, &self.hp.f(h));
                let z = if imaginary {
                    Hc {
                        re: self.hp.f(0.0),
                        im: hl.re.clone(),
                    }
                } else {
                    hl
                };
                let e = self.hp.cexp(&z);
                let d = self.hp.csub(&e, &self.hp.creal(&self.hp.f(1.0)));
                dmax = dmax.max(self.hp.abs_f64(&d));
                self.hp.cmul(&e, x)
            })
            .collect();
        let out = self.dft(nx, ny, &scaled, -1.0);
        let inv_n = self.hp.div(&self.hp.f(1.0), &self.hp.int(n as i64));
        (
            out.iter().map(|v| self.hp.cscale(v, &inv_n)).collect(),
            dmax,
        )
    }

    /// ‖(hi + lo) − r‖₂ (the real parts, or re and im for a skew pair).
    fn err2(&self, hi: &[f64], lo: &[f64], r: &[BigFloat]) -> f64 {
        let hp = &self.hp;
        hi.iter()
            .zip(lo)
            .zip(r)
            .map(|((h, l), rv)| {
                let e = to_f64(&hp.sub(&hp.add(&hp.f(*h), &hp.f(*l)), rv));
                e * e
            })
            .sum::<f64>()
            .sqrt()
    }
}

fn norm2(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// The error bound of the increment form: the forward transform's rounding (≤ log₂(n)·ε‖y0‖₂
/// with a margin of 2) times `max |e^{hλ} − 1|`, plus the same for the product and the inverse
/// transform of the increment.
fn spectral_bound(n: usize, dmax: f64, y0: &[f64]) -> f64 {
    2.0 * ((n as f64).log2() + 1.0) * f64::EPSILON * dmax * norm2(y0)
}

/// A smooth periodic vector plus a rough part.
fn wave(n: usize, phase: f64) -> Vec<f64> {
    (0..n)
        .map(|j| {
            let x = 2.0 * std::f64::consts::PI * j as f64 / n as f64;
            1.0 + 0.4 * (x + phase).sin() + 0.1 * (3.0 * x).cos() + 0.01 * ((j * 7 % 5) as f64)
        })
        .collect()
}

#[test]
fn circulants_and_skew_pair_increment_form() {
    let mut sr = SpectralRef::new();
    let n = 16;
    // Periodic second difference (Δx = 1/n) plus an upwind advection part: complex spectrum.
    let mut c = vec![0.0; n];
    let s = (n * n) as f64;
    c[0] = -2.0 * s - 3.0 * n as f64;
    c[1] = s + 3.0 * n as f64;
    c[n - 1] = s;
    let lap2d = {
        // 4 × 4 periodic Laplacian (Δx = 1/4) on the 2D grid.
        let col = |m: usize| {
            let mut v = vec![0.0; m];
            v[0] = -32.0;
            v[1] = 16.0;
            v[m - 1] = 16.0;
            v
        };
        Circulant2d::kron_sum(&col(4), &col(4)).unwrap()
    };
    let y0 = wave(n, 0.3);
    // ‖hA‖ ≈ 1e−3 (increment far below f64 resolution) and ≈ 1e1.
    for h in [1e-3 / (4.0 * s), 10.0 / (4.0 * s)] {
        let (hi, lo) = propagate(&Circulant::new(c.clone()).unwrap(), h, &y0);
        let u: Vec<(f64, f64)> = y0.iter().map(|v| (*v, 0.0)).collect();
        let (r, dmax) = sr.propagate((n, 1), &c, h, false, &u);
        let re: Vec<BigFloat> = r.iter().map(|v| v.re.clone()).collect();
        let err = sr.err2(&hi, &lo, &re);
        let bound = spectral_bound(n, dmax, &y0);
        println!(
            "Circulant n = {n}, max|e^(hλ) − 1| = {dmax:.1e}: ‖error‖₂/‖y0‖₂ = {:.1e} (bound {:.1e})",
            err / norm2(&y0),
            bound / norm2(&y0)
        );
        assert!(err <= bound, "circulant, h = {h:e}: {err:e} > {bound:e}");

        let y2 = wave(16, 1.1);
        let (hi, lo) = propagate(&lap2d, h * 4.0, &y2);
        let u: Vec<(f64, f64)> = y2.iter().map(|v| (*v, 0.0)).collect();
        let (r, dmax) = sr.propagate((4, 4), lap2d.first_column(), h * 4.0, false, &u);
        let re: Vec<BigFloat> = r.iter().map(|v| v.re.clone()).collect();
        let err = sr.err2(&hi, &lo, &re);
        let bound = spectral_bound(16, dmax, &y2);
        println!(
            "Circulant2d 4 × 4, max|e^(hλ) − 1| = {dmax:.1e}: ‖error‖₂/‖y0‖₂ = {:.1e} (bound {:.1e})",
            err / norm2(&y2),
            bound / norm2(&y2)
        );
        assert!(err <= bound, "2D circulant, h = {h:e}: {err:e} > {bound:e}");
    }

    // Skew pair of the symmetric Laplacian: A = [[0, −C], [C, 0]], unitary propagator.
    let mut sym = vec![0.0; n];
    sym[0] = -2.0 * s;
    sym[1] = s;
    sym[n - 1] = s;
    let pair = SkewPair::new(Circulant::new(sym.clone()).unwrap()).unwrap();
    let mut y0 = wave(n, 0.3);
    y0.extend(wave(n, 2.0).iter().map(|v| v - 1.0));
    for h in [1e-3 / (4.0 * s), 2.5 / (4.0 * s)] {
        let (hi, lo) = propagate(&pair, h, &y0);
        let u: Vec<(f64, f64)> = (0..n).map(|j| (y0[j], y0[n + j])).collect();
        let (r, dmax) = sr.propagate((n, 1), &sym, h, true, &u);
        let parts: Vec<BigFloat> = r
            .iter()
            .map(|v| v.re.clone())
            .chain(r.iter().map(|v| v.im.clone()))
            .collect();
        let err = sr.err2(&hi, &lo, &parts);
        let bound = spectral_bound(n, dmax, &y0);
        println!(
            "SkewPair n = {n}, max|e^(ihλ) − 1| = {dmax:.1e}: ‖error‖₂/‖y0‖₂ = {:.1e} (bound {:.1e})",
            err / norm2(&y0),
            bound / norm2(&y0)
        );
        assert!(err <= bound, "skew pair, h = {h:e}: {err:e} > {bound:e}");
    }
}

#[test]
fn spectral_null_mode_is_kept_exactly() {
    // A constant vector is the eigenvector of a difference Laplacian with λ = 0 (which the
    // circulants compute as the exact sum of the stencil): e^{hλ} − 1 = 0 there, so the
    // propagated vector is y0 itself, bit for bit, with a zero low part.
    let n = 32;
    let s = (n * n) as f64;
    let mut c = vec![0.0; n];
    c[0] = -2.0 * s;
    c[1] = s;
    c[n - 1] = s;
    let y0 = vec![1.0 / 3.0; n];
    let h = 10_000.0 / (4.0 * s);
    let (hi, lo) = propagate(&Circulant::new(c.clone()).unwrap(), h, &y0);
    assert_eq!(Circulant::new(c.clone()).unwrap().eigenvalues()[0].re, 0.0);
    assert_eq!(hi, y0);
    assert!(lo.iter().all(|v| *v == 0.0), "{lo:?}");
    let op2 = Circulant2d::kron_sum(&c, &c[..]).unwrap();
    let y2 = vec![1.0 / 3.0; n * n];
    let (hi, lo) = propagate(&op2, h / 2.0, &y2);
    assert_eq!(hi, y2);
    assert!(lo.iter().all(|v| *v == 0.0));
    // Skew pair: (p, q) = (const, const) is ψ = const·(1 + i), the λ = 0 mode.
    let pair = SkewPair::new(Circulant::new(c).unwrap()).unwrap();
    let y = vec![0.7; 2 * n];
    let (hi, lo) = propagate(&pair, h, &y);
    assert_eq!(hi, y);
    assert!(lo.iter().all(|v| *v == 0.0));
}
