//! `Circulant2d` (block-circulant with circulant blocks, by 2D FFT) against the dense matrix it
//! represents: application, φ-banks, the Kronecker-sum Laplacian and its skew pair.

use ecr::problems::Nls;
use ecr_runtime::Error;
use ecr_runtime::operator::{Circulant2d, Dense, LinearOperator, PhiBank, SkewPair};
use nalgebra::{DMatrix, DVector};

const NX: usize = 4;
const NY: usize = 6;

/// Deterministic numbers in [−1, 1) (64-bit LCG, top 53 bits).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        2.0 * ((self.0 >> 11) as f64 / (1u64 << 53) as f64) - 1.0
    }
    fn vec(&mut self, n: usize) -> Vec<f64> {
        (0..n).map(|_| self.next()).collect()
    }
}

/// The dense block-circulant matrix: `A[(ix,iy),(jx,jy)] = c((ix−jx) mod nx, (iy−jy) mod ny)`.
fn dense_of(nx: usize, ny: usize, c: &[f64]) -> DMatrix<f64> {
    let n = nx * ny;
    DMatrix::from_fn(n, n, |i, j| {
        let (ix, iy) = (i / ny, i % ny);
        let (jx, jy) = (j / ny, j % ny);
        c[((ix + nx - jx) % nx) * ny + (iy + ny - jy) % ny]
    })
}

fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).fold(0.0, |m, (x, y)| m.max((x - y).abs()))
}

#[test]
fn apply_equals_dense_matrix_on_4x6() {
    let mut rng = Lcg(1);
    let c = rng.vec(NX * NY);
    let op = Circulant2d::new(NX, NY, c.clone()).unwrap();
    let a = dense_of(NX, NY, &c);
    assert_eq!(op.dim(), NX * NY);
    assert_eq!(op.shape(), (NX, NY));
    for _ in 0..5 {
        let x = rng.vec(NX * NY);
        let mut y = vec![0.0; NX * NY];
        op.apply(&x, &mut y);
        let expect = &a * DVector::from_column_slice(&x);
        let err = max_diff(&y, expect.as_slice());
        assert!(err < 1e-13, "apply: {err:e}");
    }
    // The eigenvalues are those of the dense matrix: A v = λ v for the 2D Fourier modes.
    let lambda = op.eigenvalues();
    for kx in 0..NX {
        for ky in 0..NY {
            let v = DVector::from_fn(NX * NY, |i, _| {
                let (ix, iy) = (i / NY, i % NY);
                let t = 2.0
                    * std::f64::consts::PI
                    * ((kx * ix) as f64 / NX as f64 + (ky * iy) as f64 / NY as f64);
                num_complex::Complex64::new(t.cos(), t.sin())
            });
            let av = a.map(|x| num_complex::Complex64::new(x, 0.0)) * &v;
            let l = lambda[kx * NY + ky];
            let err = (av - v * l).iter().fold(0.0f64, |m, z| m.max(z.norm()));
            assert!(err < 1e-12, "mode ({kx},{ky}): {err:e}");
        }
    }
}

#[test]
fn bank_equals_dense_bank_on_4x6() {
    let mut rng = Lcg(2);
    let c = rng.vec(NX * NY);
    let op = Circulant2d::new(NX, NY, c.clone()).unwrap();
    let dense = Dense::new(dense_of(NX, NY, &c)).unwrap();
    let (h, taus, p) = (0.3, [0.0, 0.25, 0.7, 1.0], 3);
    let bank = op.phi_bank(h, &taus, p).unwrap();
    let dbank = dense.phi_bank(h, &taus, p).unwrap();
    assert_eq!((bank.dim(), bank.len(), bank.p()), (NX * NY, taus.len(), p));
    let (mut ws, mut dws) = (bank.workspace(), dbank.workspace());
    let d = NX * NY;
    let y0 = rng.vec(d);
    let g = rng.vec(p * d);
    let coef = rng.vec(p * taus.len());
    let (mut out, mut dout) = (vec![0.0; d * taus.len()], vec![0.0; d * taus.len()]);
    bank.combine(0..taus.len(), &y0, &g, &coef, &mut out, &mut ws);
    dbank.combine(0..taus.len(), &y0, &g, &coef, &mut dout, &mut dws);
    let err = max_diff(&out, &dout);
    assert!(err < 1e-12, "combine: {err:e}");
    // A sub-range and m < p.
    let (mut o2, mut d2) = (vec![0.0; 2 * d], vec![0.0; 2 * d]);
    bank.combine(1..3, &y0, &g[..d], &coef[..2], &mut o2, &mut ws);
    dbank.combine(1..3, &y0, &g[..d], &coef[..2], &mut d2, &mut dws);
    assert!(max_diff(&o2, &d2) < 1e-12);
    for i in 0..taus.len() {
        for k in 0..=p {
            let x = rng.vec(d);
            let (mut a, mut b) = (vec![0.0; d], vec![0.0; d]);
            bank.apply(i, k, &x, &mut a, &mut ws);
            dbank.apply(i, k, &x, &mut b, &mut dws);
            let err = max_diff(&a, &b);
            assert!(err < 1e-12, "apply φ_{k}(τ_{i}): {err:e}");
        }
    }
}

#[test]
fn kron_sum_is_the_spectral_laplacian() {
    let (nx, ny) = (Nls::new(NX).unwrap(), Nls::new(NY).unwrap());
    let op = Circulant2d::kron_sum(&nx.d2_first_column(), &ny.d2_first_column()).unwrap();
    assert!(op.is_symmetric());
    let lap = nx.d2_matrix().kronecker(&DMatrix::identity(NY, NY))
        + DMatrix::identity(NX, NX).kronecker(&ny.d2_matrix());
    let dense = dense_of(NX, NY, op.first_column());
    assert!((&dense - &lap).amax() < 1e-14);
    // The symbol −(kx² + ky²) (μ = √2/4 in both directions), real.
    let (lx, ly) = (nx.d2_eigenvalues(), ny.d2_eigenvalues());
    for (m, l) in op.eigenvalues().iter().enumerate() {
        let expect = lx[m / NY] + ly[m % NY];
        assert!(
            (l.re - expect).abs() < 1e-13 && l.im.abs() < 1e-13,
            "mode {m}"
        );
    }
}

#[test]
fn skew_pair_of_laplacian_equals_dense() {
    let (nx, ny) = (Nls::new(NX).unwrap(), Nls::new(NY).unwrap());
    let c = Circulant2d::kron_sum(&nx.d2_first_column(), &ny.d2_first_column()).unwrap();
    let cm = dense_of(NX, NY, c.first_column());
    let n = NX * NY;
    let mut a = DMatrix::zeros(2 * n, 2 * n);
    a.view_mut((0, n), (n, n)).copy_from(&(-&cm));
    a.view_mut((n, 0), (n, n)).copy_from(&cm);
    let pair = SkewPair::new(c).unwrap();
    let dense = Dense::new(a.clone()).unwrap();
    let mut rng = Lcg(3);
    let x = rng.vec(2 * n);
    let mut y = vec![0.0; 2 * n];
    pair.apply(&x, &mut y);
    let expect = &a * DVector::from_column_slice(&x);
    assert!(max_diff(&y, expect.as_slice()) < 1e-12);

    let (h, taus, p) = (0.2, [0.2, 0.8, 1.0], 2);
    let bank = pair.phi_bank(h, &taus, p).unwrap();
    let dbank = dense.phi_bank(h, &taus, p).unwrap();
    let (mut ws, mut dws) = (bank.workspace(), dbank.workspace());
    let y0 = rng.vec(2 * n);
    let g = rng.vec(p * 2 * n);
    let coef = rng.vec(p * taus.len());
    let (mut out, mut dout) = (vec![0.0; 2 * n * 3], vec![0.0; 2 * n * 3]);
    bank.combine(0..3, &y0, &g, &coef, &mut out, &mut ws);
    dbank.combine(0..3, &y0, &g, &coef, &mut dout, &mut dws);
    let err = max_diff(&out, &dout);
    assert!(err < 1e-11, "skew pair combine: {err:e}");
}

#[test]
fn validation() {
    assert!(matches!(
        Circulant2d::new(0, 3, vec![]),
        Err(Error::InvalidInput(_))
    ));
    assert!(matches!(
        Circulant2d::new(2, 3, vec![0.0; 5]),
        Err(Error::DimensionMismatch { .. })
    ));
    assert!(matches!(
        Circulant2d::new(2, 2, vec![0.0, f64::NAN, 0.0, 0.0]),
        Err(Error::NonFinite(_))
    ));
    // Not symmetric: c(0, 1) ≠ c(0, −1).
    let mut c = vec![0.0; NX * NY];
    c[1] = 1.0;
    let op = Circulant2d::new(NX, NY, c).unwrap();
    assert!(!op.is_symmetric());
    assert!(matches!(SkewPair::new(op), Err(Error::InvalidInput(_))));
}
