//! Linear operators and their φ-banks: every structured operator against `Dense` for the same
//! matrix, exact propagation of y' = Ay, argument validation, and allocation-free `combine`.

use crate::common_phi;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::ops::Range;

use common_phi::Rng;
use ecr_runtime::Error;
use ecr_runtime::operator::{
    Circulant, Dense, DenseStatic, Diagonal, LinearOperator, PhiBank, Scalar, SkewPair, Symmetric,
    Zero,
};
use nalgebra::{DMatrix, SMatrix};
use num_complex::Complex64;
use proptest::prelude::*;
use proptest::test_runner::{Config as ProptestConfig, RngSeed};

// ---------------------------------------------------------------------------------------
// Allocation counting (per thread, so parallel tests do not interfere)
// ---------------------------------------------------------------------------------------

struct CountingAlloc;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

fn count_one() {
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
}

// SAFETY: forwards to the system allocator; the thread-local counter is const-initialised
// and has no destructor, so touching it cannot allocate or recurse.
unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count_one();
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count_one();
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count_one();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: CountingAlloc = CountingAlloc;

/// Number of heap allocations made by `f` on this thread.
fn allocations_in(f: impl FnOnce()) -> usize {
    let before = ALLOCATIONS.with(|c| c.get());
    f();
    ALLOCATIONS.with(|c| c.get()) - before
}

// ---------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------

/// Gauss–Legendre nodes of order 3 on [0, 1] plus the end points: the taus a stepper uses.
const TAUS: [f64; 5] = [0.0, 0.1127016653792583, 0.5, 0.8872983346207417, 1.0];
const P: usize = 4;
const M: usize = 3;

/// Agreement required between two operator kinds for the same A: both sides are within a few
/// hundred units of roundoff of the exact result relative to its size (φ by scaling and
/// squaring with ≤ 8 doublings here, or exact-to-a-few-ulps scalar φ after an FFT or an
/// orthogonal transform with O(u log n) / O(u n) error), so 1e−13 ≈ 450u.
const AGREE: f64 = 1e-13;

/// Test data for a combine call of dimension d: y0, g (M blocks), coef (M per node).
struct CombineData {
    y0: Vec<f64>,
    g: Vec<f64>,
    coef: Vec<f64>,
}

fn combine_data(d: usize, rng: &mut Rng) -> CombineData {
    let h = 0.3;
    CombineData {
        y0: (0..d).map(|_| rng.range(-1.0, 1.0)).collect(),
        g: (0..d * M).map(|_| rng.range(-1.0, 1.0)).collect(),
        // coef[j·m + k] = h c_j^{k+1}, as in the ECrP stage formula
        coef: TAUS
            .iter()
            .flat_map(|c| (0..M).map(move |k| h * c.powi(k as i32 + 1)))
            .collect(),
    }
}

/// Runs `combine` over `indices` (with an output buffer pre-filled with NaN, so that a bank that
/// reads its output would be caught).
fn run_combine<B: PhiBank>(bank: &B, data: &CombineData, indices: Range<usize>) -> Vec<f64> {
    let d = bank.dim();
    let nb = indices.len();
    let mut out = vec![f64::NAN; d * nb];
    let mut ws = bank.workspace();
    let m = data.g.len().checked_div(d).unwrap_or(M);
    let coef = &data.coef[indices.start * m..indices.end * m];
    bank.combine(indices, &data.y0, &data.g, coef, &mut out, &mut ws);
    out
}

fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let num = a
        .iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    let den = b.iter().fold(0.0f64, |m, y| m.max(y.abs()));
    if den == 0.0 { num } else { num / den }
}

/// Compares `op` with `Dense` of the same matrix: combine over all nodes and a sub-range,
/// `PhiBank::apply` for every (i, k), and `LinearOperator::apply`.
fn compare_with_dense<L: LinearOperator>(
    label: &str,
    op: &L,
    a: &DMatrix<f64>,
    h: f64,
    rng: &mut Rng,
) -> f64 {
    let dense = Dense::new(a.clone()).unwrap();
    let d = a.nrows();
    assert_eq!(op.dim(), d);
    let bank = op.phi_bank(h, &TAUS, P).unwrap();
    let dbank = dense.phi_bank(h, &TAUS, P).unwrap();
    assert_eq!((bank.dim(), bank.len(), bank.p()), (d, TAUS.len(), P));
    let data = combine_data(d, rng);
    let mut worst = 0.0f64;
    for range in [0..TAUS.len(), 1..4, 2..2] {
        let x = run_combine(&bank, &data, range.clone());
        let y = run_combine(&dbank, &data, range.clone());
        let e = rel_diff(&x, &y);
        worst = worst.max(e);
        assert!(
            e <= AGREE,
            "{label}: combine over {range:?} differs from Dense by {e:e}"
        );
    }
    // φ_k(τ_i hA) x one at a time
    let mut ws = bank.workspace();
    #[allow(clippy::let_unit_value)] // Dense banks need no workspace
    let mut dws = dbank.workspace();
    let mut out = vec![f64::NAN; d];
    let mut dout = vec![0.0; d];
    for i in 0..TAUS.len() {
        for k in 0..=P {
            bank.apply(i, k, &data.y0, &mut out, &mut ws);
            dbank.apply(i, k, &data.y0, &mut dout, &mut dws);
            let e = rel_diff(&out, &dout);
            worst = worst.max(e);
            assert!(
                e <= AGREE,
                "{label}: apply(i = {i}, k = {k}) differs from Dense by {e:e}"
            );
        }
    }
    // y = A x
    let mut y = vec![f64::NAN; d];
    op.apply(&data.y0, &mut y);
    let yd = a * nalgebra::DVector::from_column_slice(&data.y0);
    let e = rel_diff(&y, yd.as_slice());
    // O(u log n) (FFT) or O(u n) (dense) relative to ‖A‖‖x‖ — 1e−13 as above.
    assert!(e <= AGREE, "{label}: A x differs by {e:e}");
    println!("{label:<40} max relative difference from Dense: {worst:.2e}");
    worst
}

/// The dense circulant matrix `C_{jk} = c[(j − k) mod n]`.
fn circulant_matrix(c: &[f64]) -> DMatrix<f64> {
    let n = c.len();
    DMatrix::from_fn(n, n, |j, k| c[(j + n - k) % n])
}

/// A random symmetric first column (`c[j] = c[n − j]`) with spectrum roughly in [−2n, 0].
fn symmetric_column(n: usize, rng: &mut Rng) -> Vec<f64> {
    let mut c = vec![0.0; n];
    for j in 1..=n / 2 {
        let v = rng.range(-1.0, 1.0);
        c[j] = v;
        c[n - j] = v;
    }
    c[0] = -(n as f64);
    c
}

/// `[[0, −C], [C, 0]]`.
fn skew_matrix(c: &DMatrix<f64>) -> DMatrix<f64> {
    let n = c.nrows();
    let mut a = DMatrix::zeros(2 * n, 2 * n);
    a.view_mut((0, n), (n, n)).copy_from(&(-c));
    a.view_mut((n, 0), (n, n)).copy_from(c);
    a
}

/// First column of the Fourier pseudospectral second-derivative matrix D₂ on [0, 2π) with n
/// points: eigenvalues −m² (m = wavenumber, the Nyquist mode −(n/2)²), real and symmetric.
fn d2_column(n: usize) -> Vec<f64> {
    let mut col = vec![0.0; n];
    for (j, cj) in col.iter_mut().enumerate() {
        let mut s = 0.0;
        for m in 0..n {
            let wave = if m <= n / 2 {
                m as f64
            } else {
                m as f64 - n as f64
            };
            s -= wave * wave * (2.0 * std::f64::consts::PI * (j * m) as f64 / n as f64).cos();
        }
        *cj = s / n as f64;
    }
    col
}

// ---------------------------------------------------------------------------------------
// Every operator kind against Dense
// ---------------------------------------------------------------------------------------

#[test]
fn symmetric_circulant_circulant_vs_symmetric_vs_dense() {
    let mut rng = Rng::new(11);
    for n in [1usize, 2, 7, 16] {
        let c = symmetric_column(n, &mut rng);
        let a = circulant_matrix(&c);
        let h = 0.4;
        compare_with_dense(
            &format!("Circulant (symmetric, n = {n})"),
            &Circulant::new(c).unwrap(),
            &a,
            h,
            &mut rng,
        );
        compare_with_dense(
            &format!("Symmetric (circulant, n = {n})"),
            &Symmetric::new(a.clone()).unwrap(),
            &a,
            h,
            &mut rng,
        );
    }
}

#[test]
fn general_circulant_vs_dense() {
    // Non-symmetric first column: complex eigenvalues.
    let mut rng = Rng::new(12);
    for n in [3usize, 8, 15] {
        let mut c: Vec<f64> = (0..n).map(|_| rng.range(-1.0, 1.0)).collect();
        c[0] -= 2.0;
        let a = circulant_matrix(&c);
        compare_with_dense(
            &format!("Circulant (general, n = {n})"),
            &Circulant::new(c).unwrap(),
            &a,
            0.8,
            &mut rng,
        );
    }
}

#[test]
fn skew_pair_vs_dense() {
    let mut rng = Rng::new(13);
    let n = 12;
    let c = symmetric_column(n, &mut rng);
    let cm = circulant_matrix(&c);
    let a = skew_matrix(&cm);
    let h = 0.25;
    compare_with_dense(
        "SkewPair<Circulant> (n = 12)",
        &SkewPair::new(Circulant::new(c).unwrap()).unwrap(),
        &a,
        h,
        &mut rng,
    );
    // A dense symmetric (non-circulant) generator.
    let b = DMatrix::from_fn(n, n, |_, _| rng.range(-1.0, 1.0));
    let s = (&b + b.transpose()) * 0.5;
    let a = skew_matrix(&s);
    compare_with_dense(
        "SkewPair<Symmetric> (n = 12)",
        &SkewPair::new(Symmetric::new(s).unwrap()).unwrap(),
        &a,
        0.7,
        &mut rng,
    );
}

#[test]
fn skew_pair_nls_second_derivative_vs_dense() {
    // The cubic NLS linear part: C = D₂ (n = 32, eigenvalues down to −256), h = 0.02 so that
    // |hλ| reaches 5.
    let mut rng = Rng::new(14);
    let n = 32;
    let col = d2_column(n);
    let op = Circulant::new(col.clone()).unwrap();
    for (m, l) in op.eigenvalues().iter().enumerate() {
        let wave = if m <= n / 2 {
            m as f64
        } else {
            m as f64 - n as f64
        };
        // FFT of the column reproduces −m² to rounding (O(u n²) absolute).
        assert!(
            (l.re + wave * wave).abs() < 1e-11 && l.im.abs() < 1e-11,
            "mode {m}: {l}"
        );
    }
    let a = skew_matrix(&circulant_matrix(&col));
    compare_with_dense(
        "SkewPair<Circulant D2> (n = 32)",
        &SkewPair::new(op).unwrap(),
        &a,
        0.02,
        &mut rng,
    );
}

#[test]
fn diagonal_scalar_zero_vs_dense() {
    let mut rng = Rng::new(15);
    let d = 9;
    let diag: Vec<f64> = (0..d).map(|_| rng.range(-30.0, 3.0)).collect();
    let a = DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(&diag));
    compare_with_dense(
        "Diagonal (d = 9)",
        &Diagonal::new(diag.clone()).unwrap(),
        &a,
        0.5,
        &mut rng,
    );
    let dv = nalgebra::DVector::from_column_slice(&diag);
    compare_with_dense(
        "Diagonal::from_dvector",
        &Diagonal::from_dvector(&dv).unwrap(),
        &a,
        0.5,
        &mut rng,
    );
    let a = DMatrix::identity(d, d) * -2.5;
    compare_with_dense(
        "Scalar (a = -2.5)",
        &Scalar::new(-2.5, d).unwrap(),
        &a,
        0.5,
        &mut rng,
    );
    compare_with_dense("Zero", &Zero::new(d), &DMatrix::zeros(d, d), 0.5, &mut rng);
}

#[test]
fn dense_static_vs_dense() {
    let mut rng = Rng::new(16);
    let a = SMatrix::<f64, 6, 6>::from_fn(|i, j| if i == j { -3.0 } else { rng.range(-1.0, 1.0) });
    let dyn_a = DMatrix::from_column_slice(6, 6, a.as_slice());
    compare_with_dense(
        "DenseStatic<6>",
        &DenseStatic::new(a).unwrap(),
        &dyn_a,
        0.6,
        &mut rng,
    );
    let rows: Vec<f64> = (0..36).map(|i| dyn_a[(i / 6, i % 6)]).collect();
    let b = DenseStatic::<6>::from_row_slice(&rows).unwrap();
    assert_eq!(b.matrix(), &a);
    let c = Dense::from_row_slice(6, &rows).unwrap();
    assert_eq!(c.matrix(), &dyn_a);
}

#[test]
fn zero_dimension_operators() {
    let data = CombineData {
        y0: vec![],
        g: vec![],
        coef: vec![0.0; TAUS.len() * M],
    };
    let bank = Zero::new(0).phi_bank(1.0, &TAUS, P).unwrap();
    assert!(run_combine(&bank, &data, 0..5).is_empty());
    let bank = Dense::new(DMatrix::zeros(0, 0))
        .unwrap()
        .phi_bank(1.0, &TAUS, P)
        .unwrap();
    assert!(run_combine(&bank, &data, 0..5).is_empty());
    let bank = Diagonal::new(vec![])
        .unwrap()
        .phi_bank(1.0, &TAUS, P)
        .unwrap();
    assert!(run_combine(&bank, &data, 0..5).is_empty());
}

// ---------------------------------------------------------------------------------------
// y' = Ay is propagated exactly
// ---------------------------------------------------------------------------------------

#[test]
fn m_zero_propagates_linear_flow_exactly() {
    // A = [[a, b], [−b, a]]: e^{tA} = e^{ta} [[cos tb, sin tb], [−sin tb, cos tb]], here with
    // every τ_i of the bank (the continuous output at τ_i h). Tolerance 4e−15: the exact
    // values are computed from f64 exp/sin/cos (≤ 1 ulp each) and φ₀ by scaling and squaring
    // (‖hA‖ = 3.2: 2 doublings), i.e. within ~16u of each other.
    let (a, b) = (-0.7, 2.5);
    let h = 1.1;
    let m = DMatrix::from_row_slice(2, 2, &[a, b, -b, a]);
    let y0 = [0.3, -1.2];
    let data = CombineData {
        y0: y0.to_vec(),
        g: vec![],
        coef: vec![],
    };
    let check = |label: &str, out: &[f64]| {
        for (i, tau) in TAUS.iter().enumerate() {
            let t = tau * h;
            let (s, c) = (t * b).sin_cos();
            let e = (t * a).exp();
            let exact = [e * (c * y0[0] + s * y0[1]), e * (-s * y0[0] + c * y0[1])];
            let got = &out[2 * i..2 * i + 2];
            let err = rel_diff(got, &exact);
            assert!(
                err <= 4e-15,
                "{label}: tau = {tau}: {got:?} vs {exact:?} ({err:e})"
            );
        }
    };
    let bank = Dense::new(m.clone())
        .unwrap()
        .phi_bank(h, &TAUS, 0)
        .unwrap();
    check("Dense", &run_combine(&bank, &data, 0..5));
    let s = SMatrix::<f64, 2, 2>::new(a, b, -b, a);
    let bank = DenseStatic::new(s).unwrap().phi_bank(h, &TAUS, 0).unwrap();
    check("DenseStatic", &run_combine(&bank, &data, 0..5));

    // The same flow as a skew pair: A = [[0, −C], [C, 0]] with C = −b (1×1) is the rotation
    // part (a = 0); each mode rotates by e^{iτhλ}.
    let data0 = CombineData {
        y0: y0.to_vec(),
        g: vec![],
        coef: vec![],
    };
    let op = SkewPair::new(Symmetric::new(DMatrix::from_element(1, 1, -b)).unwrap()).unwrap();
    let out = run_combine(&op.phi_bank(h, &TAUS, 0).unwrap(), &data0, 0..5);
    for (i, tau) in TAUS.iter().enumerate() {
        // y' = (−C q, C p) ↔ u' = iCu, u(t) = e^{−ibt} u0 (the angle rounded as the bank
        // rounds it, (τh)·λ). Tolerance: sin/cos ≤ 1 ulp, the eigenbasis ±1 exact, one complex
        // product: 4 ulps of |u|.
        let u = Complex64::new(y0[0], y0[1]) * Complex64::new(0.0, tau * h * -b).exp();
        let tol = 4.0 * f64::EPSILON * u.norm();
        assert!(
            (out[2 * i] - u.re).abs() <= tol && (out[2 * i + 1] - u.im).abs() <= tol,
            "tau = {tau}: ({}, {}) vs {u}",
            out[2 * i],
            out[2 * i + 1]
        );
    }

    // Diagonal and Scalar: φ₀(τ h d) y0 = e^{τ h d} y0 to the ulp.
    let diag = vec![-1e6, -3.0, 0.0, 2.0];
    let yd = vec![1.0, 2.0, 3.0, 4.0];
    let data = CombineData {
        y0: yd.clone(),
        g: vec![],
        coef: vec![],
    };
    let out = run_combine(
        &Diagonal::new(diag.clone())
            .unwrap()
            .phi_bank(h, &TAUS, 0)
            .unwrap(),
        &data,
        0..5,
    );
    for (i, tau) in TAUS.iter().enumerate() {
        for (t, dv) in diag.iter().enumerate() {
            let exact = (tau * h * dv).exp() * yd[t];
            assert!((out[4 * i + t] - exact).abs() <= 2.0 * f64::EPSILON * exact.abs());
        }
    }
    let out = run_combine(
        &Scalar::new(-3.0, 4).unwrap().phi_bank(h, &TAUS, 0).unwrap(),
        &data,
        0..5,
    );
    for (i, tau) in TAUS.iter().enumerate() {
        for t in 0..4 {
            let exact = (tau * h * -3.0).exp() * yd[t];
            assert!((out[4 * i + t] - exact).abs() <= 2.0 * f64::EPSILON * exact.abs());
        }
    }
}

#[test]
fn stiff_dense_bank_damps_to_zero() {
    // ‖hA‖ = 1e8 with spectrum in the left half-plane: φ₀(hA) y0 ≈ 0, the φ_k G terms ≈
    // (−hA)^{-1}·G/(k−1)!, nothing NaN.
    let a = DMatrix::from_row_slice(3, 3, &[-1e8, 5e7, 0.0, 0.0, -2e8, 1e8, 0.0, 0.0, -3e8]);
    let bank = Dense::new(a).unwrap().phi_bank(1.0, &[1.0], 2).unwrap();
    let y0 = [1.0, 1.0, 1.0];
    let g = [1.0, 2.0, 3.0];
    let mut out = [f64::NAN; 3];
    bank.combine(0..1, &y0, &g, &[1.0], &mut out, &mut ());
    assert!(
        out.iter().all(|v| v.is_finite() && v.abs() < 1e-7),
        "{out:?}"
    );
    bank.combine(0..1, &y0, &[], &[], &mut out, &mut ());
    assert!(out.iter().all(|v| *v == 0.0 || v.abs() < 1e-300), "{out:?}");
}

// ---------------------------------------------------------------------------------------
// Errors
// ---------------------------------------------------------------------------------------

#[test]
fn invalid_step_sizes_and_taus() {
    let op = Diagonal::new(vec![-1.0, -2.0]).unwrap();
    for h in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        match op.phi_bank(h, &TAUS, 2) {
            Err(Error::InvalidStepSize(x)) => assert!(x.is_nan() || x == h),
            other => panic!("h = {h}: {other:?}"),
        }
    }
    assert!(matches!(
        op.phi_bank(0.1, &[0.5, f64::NAN], 2),
        Err(Error::NonFinite(_))
    ));
    assert!(matches!(
        Zero::new(3).phi_bank(0.0, &TAUS, 2),
        Err(Error::InvalidStepSize(_))
    ));
    assert!(matches!(
        Scalar::new(1.0, 3).unwrap().phi_bank(f64::NAN, &TAUS, 2),
        Err(Error::InvalidStepSize(_))
    ));
    let c = Circulant::new(vec![-2.0, 1.0, 0.0, 1.0]).unwrap();
    assert!(matches!(
        c.phi_bank(-0.5, &TAUS, 2),
        Err(Error::InvalidStepSize(_))
    ));
    let d = Dense::new(DMatrix::identity(2, 2)).unwrap();
    assert!(matches!(
        d.phi_bank(f64::NEG_INFINITY, &TAUS, 2),
        Err(Error::InvalidStepSize(_))
    ));
    assert!(matches!(
        d.phi_bank(1.0, &[f64::INFINITY], 2),
        Err(Error::NonFinite(_))
    ));
    let s = Symmetric::new(DMatrix::identity(2, 2)).unwrap();
    assert!(matches!(
        s.phi_bank(0.0, &TAUS, 2),
        Err(Error::InvalidStepSize(_))
    ));
    let sp = SkewPair::new(c).unwrap();
    assert!(matches!(
        sp.phi_bank(0.0, &TAUS, 2),
        Err(Error::InvalidStepSize(_))
    ));
    // Overflow is an error, not ∞ in the bank.
    assert!(matches!(
        Scalar::new(1e3, 2).unwrap().phi_bank(1.0, &TAUS, 2),
        Err(Error::Numerical(_))
    ));
    assert!(matches!(
        d.phi_bank(1e3, &TAUS, 2),
        Err(Error::Numerical(_))
    ));
}

#[test]
fn invalid_constructors() {
    assert!(matches!(
        Dense::new(DMatrix::zeros(2, 3)),
        Err(Error::NotSquare {
            rows: 2,
            cols: 3,
            ..
        })
    ));
    assert!(matches!(
        Symmetric::new(DMatrix::zeros(3, 2)),
        Err(Error::NotSquare { .. })
    ));
    assert!(matches!(
        Dense::from_row_slice(3, &[1.0; 8]),
        Err(Error::DimensionMismatch {
            expected: 9,
            found: 8,
            ..
        })
    ));
    assert!(matches!(
        Symmetric::from_row_slice(2, &[1.0; 3]),
        Err(Error::DimensionMismatch { .. })
    ));
    assert!(matches!(
        DenseStatic::<2>::from_row_slice(&[1.0; 5]),
        Err(Error::DimensionMismatch { .. })
    ));
    let mut nan = DMatrix::identity(2, 2);
    nan[(1, 0)] = f64::NAN;
    assert!(matches!(Dense::new(nan.clone()), Err(Error::NonFinite(_))));
    assert!(matches!(Symmetric::new(nan), Err(Error::NonFinite(_))));
    assert!(matches!(
        DenseStatic::new(SMatrix::<f64, 2, 2>::new(1.0, f64::INFINITY, 0.0, 1.0)),
        Err(Error::NonFinite(_))
    ));
    assert!(matches!(
        Diagonal::new(vec![1.0, f64::NAN]),
        Err(Error::NonFinite(_))
    ));
    assert!(matches!(
        Scalar::new(f64::INFINITY, 2),
        Err(Error::NonFinite(_))
    ));
    assert!(matches!(
        Circulant::new(vec![]),
        Err(Error::InvalidInput(_))
    ));
    assert!(matches!(
        Circulant::new(vec![1.0, f64::NAN]),
        Err(Error::NonFinite(_))
    ));
    // Non-symmetric input where symmetry is required.
    let ns = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0 + 1e-9, 1.0]);
    assert!(matches!(
        Symmetric::new(ns.clone()),
        Err(Error::InvalidInput(_))
    ));
    // ... but asymmetry at the 1e−13 relative level is accepted (and symmetrised).
    let almost = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0 + 2e-13, 1.0]);
    assert!(Symmetric::new(almost).is_ok());
    let nc = Circulant::new(vec![-2.0, 1.0, 0.5, 0.0]).unwrap();
    assert!(!nc.is_symmetric());
    assert!(matches!(SkewPair::new(nc), Err(Error::InvalidInput(_))));
}

#[test]
fn validate_combine_reports_shapes() {
    let bank = Diagonal::new(vec![-1.0; 3])
        .unwrap()
        .phi_bank(0.1, &TAUS, 2)
        .unwrap();
    let y0 = [0.0; 3];
    let g = [0.0; 6];
    let coef = [0.0; 4];
    let out = [0.0; 6];
    assert_eq!(bank.validate_combine(&(1..3), &y0, &g, &coef, &out), Ok(2));
    assert!(matches!(
        bank.validate_combine(&(1..3), &y0[..2], &g, &coef, &out),
        Err(Error::DimensionMismatch {
            expected: 3,
            found: 2,
            ..
        })
    ));
    assert!(matches!(
        bank.validate_combine(&(1..3), &y0, &g, &coef, &out[..5]),
        Err(Error::DimensionMismatch {
            expected: 6,
            found: 5,
            ..
        })
    ));
    assert!(matches!(
        bank.validate_combine(&(1..3), &y0, &g, &coef[..3], &out),
        Err(Error::DimensionMismatch {
            expected: 4,
            found: 3,
            ..
        })
    ));
    assert!(matches!(
        bank.validate_combine(&(1..3), &y0, &g[..5], &coef, &out),
        Err(Error::InvalidInput(_))
    ));
    assert!(matches!(
        bank.validate_combine(&(4..6), &y0, &g, &coef, &out),
        Err(Error::InvalidInput(_))
    ));
    assert!(matches!(
        bank.validate_combine(&(1..3), &y0, &[0.0; 9], &[0.0; 6], &out),
        Err(Error::InvalidParameter(_))
    ));
}

#[test]
#[should_panic(expected = "combine: y0")]
fn combine_panics_on_wrong_length() {
    let bank = Diagonal::new(vec![-1.0; 3])
        .unwrap()
        .phi_bank(0.1, &TAUS, 2)
        .unwrap();
    let mut out = [0.0; 3];
    bank.combine(0..1, &[0.0; 2], &[], &[], &mut out, &mut ());
}

// ---------------------------------------------------------------------------------------
// No allocation in combine / apply
// ---------------------------------------------------------------------------------------

fn assert_no_alloc<L: LinearOperator>(label: &str, op: &L) {
    let d = op.dim();
    let mut rng = Rng::new(21);
    let data = combine_data(d, &mut rng);
    let bank = op.phi_bank(0.3, &TAUS, P).unwrap();
    let mut ws = bank.workspace();
    let mut out = vec![0.0; d * TAUS.len()];
    let mut single = vec![0.0; d];
    // warm-up (lazy statics, if any, are not counted)
    bank.combine(
        0..TAUS.len(),
        &data.y0,
        &data.g,
        &data.coef,
        &mut out,
        &mut ws,
    );
    op.apply(&data.y0, &mut single);
    let n = allocations_in(|| {
        bank.combine(
            0..TAUS.len(),
            &data.y0,
            &data.g,
            &data.coef,
            &mut out,
            &mut ws,
        );
        bank.combine(
            1..3,
            &data.y0,
            &data.g[..d],
            &data.coef[..2],
            &mut out[..2 * d],
            &mut ws,
        );
        bank.apply(2, 3, &data.y0, &mut single, &mut ws);
        op.apply(&data.y0, &mut single);
    });
    assert_eq!(n, 0, "{label}: {n} allocations in combine/apply");
}

#[test]
fn combine_and_apply_do_not_allocate() {
    let mut rng = Rng::new(22);
    let c = symmetric_column(16, &mut rng);
    let cm = circulant_matrix(&c);
    assert_no_alloc("Zero", &Zero::new(5));
    assert_no_alloc("Scalar", &Scalar::new(-1.0, 5).unwrap());
    assert_no_alloc("Diagonal", &Diagonal::new(vec![-1.0, -2.0, 0.5]).unwrap());
    assert_no_alloc("Dense", &Dense::new(cm.clone()).unwrap());
    assert_no_alloc(
        "DenseStatic",
        &DenseStatic::new(SMatrix::<f64, 3, 3>::identity() * -2.0).unwrap(),
    );
    assert_no_alloc("Symmetric", &Symmetric::new(cm.clone()).unwrap());
    assert_no_alloc("Circulant", &Circulant::new(c.clone()).unwrap());
    assert_no_alloc(
        "SkewPair<Circulant>",
        &SkewPair::new(Circulant::new(c).unwrap()).unwrap(),
    );
    assert_no_alloc(
        "SkewPair<Symmetric>",
        &SkewPair::new(Symmetric::new(cm).unwrap()).unwrap(),
    );
}

// ---------------------------------------------------------------------------------------
// Property tests (fixed seed)
// ---------------------------------------------------------------------------------------

fn proptest_config() -> ProptestConfig {
    ProptestConfig {
        cases: 48,
        rng_seed: RngSeed::Fixed(0x0EC2_0BE7),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

proptest! {
    #![proptest_config(proptest_config())]

    /// Random symmetric circulants and step sizes over four decades: Circulant, Symmetric and
    /// SkewPair agree with Dense (tolerance AGREE, see there).
    #[test]
    fn circulant_family_agrees_with_dense(
        half in proptest::collection::vec(-1.0f64..1.0, 4),
        diag in -8.0f64..0.0,
        log_h in -3.0f64..1.0,
    ) {
        let n = 8;
        let mut c = vec![0.0; n];
        c[0] = diag;
        for j in 1..=4 {
            c[j] = half[j - 1];
            c[n - j] = half[j - 1];
        }
        let h = 10f64.powf(log_h);
        let a = circulant_matrix(&c);
        let mut rng = Rng::new(5);
        let data = combine_data(n, &mut rng);
        let reference = run_combine(&Dense::new(a.clone()).unwrap().phi_bank(h, &TAUS, P).unwrap(), &data, 0..5);
        let circ = run_combine(&Circulant::new(c.clone()).unwrap().phi_bank(h, &TAUS, P).unwrap(), &data, 0..5);
        prop_assert!(rel_diff(&circ, &reference) <= AGREE);
        let sym = run_combine(&Symmetric::new(a.clone()).unwrap().phi_bank(h, &TAUS, P).unwrap(), &data, 0..5);
        prop_assert!(rel_diff(&sym, &reference) <= AGREE);

        let skew = skew_matrix(&a);
        let data2 = combine_data(2 * n, &mut rng);
        let reference = run_combine(&Dense::new(skew).unwrap().phi_bank(h, &TAUS, P).unwrap(), &data2, 0..5);
        let sp = run_combine(&SkewPair::new(Circulant::new(c).unwrap()).unwrap().phi_bank(h, &TAUS, P).unwrap(), &data2, 0..5);
        prop_assert!(rel_diff(&sp, &reference) <= AGREE);
    }

    /// combine is linear in (y0, g): combine(y0 + 2y0', g + 2g') = combine(y0, g) + 2 combine(y0', g'),
    /// to rounding (3 roundings of values of size ≤ max|out|: 1e−14).
    #[test]
    fn combine_is_linear(seed in 0u64..1000) {
        let mut rng = Rng::new(seed);
        let c = symmetric_column(6, &mut rng);
        let bank = Circulant::new(c).unwrap().phi_bank(0.5, &TAUS, P).unwrap();
        let a = combine_data(6, &mut rng);
        let b = combine_data(6, &mut rng);
        let sum = CombineData {
            y0: a.y0.iter().zip(&b.y0).map(|(x, y)| x + 2.0 * y).collect(),
            g: a.g.iter().zip(&b.g).map(|(x, y)| x + 2.0 * y).collect(),
            coef: a.coef.clone(),
        };
        let ra = run_combine(&bank, &a, 0..5);
        let rb = run_combine(&bank, &b, 0..5);
        let rs = run_combine(&bank, &sum, 0..5);
        let lin: Vec<f64> = ra.iter().zip(&rb).map(|(x, y)| x + 2.0 * y).collect();
        prop_assert!(rel_diff(&rs, &lin) <= 1e-14);
    }
}
