//! The f64 routes of a dense operator's banks: a matrix that is normal after a diagonal
//! similarity (balancing) takes its functions from its eigenvectors, computed once per
//! operator; any other matrix keeps scaling and squaring, in f64.
//!
//! # The normal route
//!
//! `B = D⁻¹AD` with D from Osborne's balancing (row and column 2-norms equalised; the factors
//! are not rounded to powers of 2, so that `[[0, 1], [−ω², 0]]` becomes the skew
//! `[[0, ω], [−ω, 0]]`). A normal B is diagonalised by a unitary U, and so are its symmetric
//! part S and its skew part K (they commute); U is found as the eigenvectors of the Hermitian
//! `H = S + iγK` (γ an irrational constant, so that distinct eigenvalues of B stay distinct in
//! H), by a Hermitian eigensolver, which converges on every matrix (the Francis QR of the real
//! Schur form stalls on circulants such as the periodic first difference). Then for every bank
//! function f (φ_k, `e^x`, the Legendre kernels), with `λ_k = (UᴴBU)_kk`,
//!
//! ```text
//! f(τhA) = D Re(U f(τhΛ) Uᴴ) D⁻¹
//! ```
//!
//! with the scalar functions at the eigenvalues: O(d) scalar evaluations and two real d × d
//! products per matrix, against the O(d³ log ‖hA‖) products of scaling and squaring (and the
//! double-double exponential of the default route). U is computed once per operator and serves
//! every step size.
//!
//! "Normal to working precision" is measured, not assumed: the off-diagonal part of `UᴴBU`
//! (what the route drops) must be at most `NORMAL_C · d · ε · ‖B‖_F` in Frobenius norm. The
//! route's error is then the rounding of U and of the products and the eigenvalues' own error
//! (absolute, ε‖B‖): [`DenseForm::route`] states it, and tests/it/f64_banks.rs measures it
//! against the double-double banks.
//!
//! # The general route
//!
//! Scaling and modified squaring in f64 ([`phi_dense`](crate::phi::phi_dense) and the kernels'
//! doubling, [`LegendreKernels::psi_dense`](crate::phi::LegendreKernels::psi_dense)), applied
//! to the balanced matrix where balancing halves its 1-norm.

use nalgebra::DMatrix;
use num_complex::Complex64;

use super::entries::NodeFunctions;
use crate::error::Result;

/// The off-diagonal part of `UᴴBU` (what the normal route drops) may be this many `d ε ‖B‖_F`.
const NORMAL_C: f64 = 16.0;

/// An f64 route serves a bank when its stated error is at most this
/// ([`DenseForm::route`]); otherwise the bank takes the default route.
pub(crate) const F64_BOUND_MAX: f64 = 1e-12;

/// Balancing stops when no factor moves by more than this (relative).
const BALANCE_STOP: f64 = 1e-3;

/// At most this many balancing sweeps.
const BALANCE_SWEEPS: usize = 40;

/// How the f64 banks of one dense matrix are computed.
#[derive(Clone, Debug)]
pub(crate) struct DenseForm {
    /// The diagonal of D (balancing).
    scale: Vec<f64>,
    /// Whether scaling and squaring runs on `D⁻¹AD` (where that halves the 1-norm).
    balanced: bool,
    /// The 1-norm of the matrix scaling and squaring runs on.
    norm1: f64,
    /// `D⁻¹AD = U Λ Uᴴ` with U unitary, where the matrix is normal after balancing.
    spectrum: Option<Spectrum>,
}

/// The eigendecomposition of a normal `D⁻¹AD`.
#[derive(Clone, Debug)]
struct Spectrum {
    /// The real and imaginary parts of U.
    ur: DMatrix<f64>,
    ui: DMatrix<f64>,
    /// The eigenvalues.
    lambda: Vec<Complex64>,
    /// For each eigenvalue, an earlier one whose conjugate it is to the eigenvalues' own
    /// error (4 ε ρ): it takes the conjugate of that one's function values.
    partner: Vec<Option<usize>>,
    /// The largest |λ| (the 2-norm of the balanced matrix).
    radius: f64,
    /// `D_r / D_c` at (r, c), column-major: the balancing undone entry by entry.
    ratio: Vec<f64>,
}

/// Osborne's balancing in the 2-norm: `(D, D⁻¹AD)`, D's entries unrounded.
fn balance(a: &DMatrix<f64>) -> (Vec<f64>, DMatrix<f64>) {
    let d = a.nrows();
    let mut b = a.clone();
    let mut scale = vec![1.0; d];
    for _ in 0..BALANCE_SWEEPS {
        let mut moved = false;
        for i in 0..d {
            let (mut c, mut r) = (0.0f64, 0.0f64);
            for j in 0..d {
                if j != i {
                    c = c.hypot(b[(j, i)]);
                    r = r.hypot(b[(i, j)]);
                }
            }
            if c == 0.0 || r == 0.0 || !(c.is_finite() && r.is_finite()) {
                continue;
            }
            let f = (r / c).sqrt();
            if (f - 1.0).abs() > BALANCE_STOP {
                moved = true;
            }
            if f != 1.0 {
                scale[i] *= f;
                for j in 0..d {
                    if j != i {
                        b[(j, i)] *= f;
                        b[(i, j)] /= f;
                    }
                }
            }
        }
        if !moved {
            break;
        }
    }
    // B from A and D in one rounding per entry.
    for j in 0..d {
        for i in 0..d {
            b[(i, j)] = a[(i, j)] * (scale[j] / scale[i]);
        }
    }
    (scale, b)
}

/// The 1-norm (largest absolute column sum).
fn norm1(a: &DMatrix<f64>) -> f64 {
    a.column_iter()
        .map(|c| c.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max)
}

/// γ of `H = S + iγK`: irrational, so that eigenvalues of B that differ stay apart in H.
const GAMMA: f64 = 0.618_033_988_749_894_9;

impl Spectrum {
    /// The eigendecomposition of `b` if it is normal to working precision, else `None`.
    fn of(b: &DMatrix<f64>) -> Option<Self> {
        let d = b.nrows();
        let norm = b.norm();
        if d == 0 || norm == 0.0 || !norm.is_finite() {
            return None;
        }
        let limit = NORMAL_C * d as f64 * f64::EPSILON * norm;
        // A quick test first: the commutator of a normal matrix vanishes.
        let bt = b.transpose();
        let comm = (&bt * b - b * &bt).norm();
        if comm > 64.0 * limit * norm {
            return None;
        }
        let h = DMatrix::from_fn(d, d, |r, c| {
            Complex64::new(
                0.5 * (b[(r, c)] + b[(c, r)]),
                0.5 * GAMMA * (b[(r, c)] - b[(c, r)]),
            )
        });
        let u = nalgebra::linalg::SymmetricEigen::try_new(h, f64::EPSILON, 0)?.eigenvectors;
        let t = u.adjoint() * b.map(|v| Complex64::new(v, 0.0)) * &u;
        let mut dropped = 0.0f64;
        for c in 0..d {
            for r in 0..d {
                if r != c {
                    dropped = dropped.hypot(t[(r, c)].norm());
                }
            }
        }
        if dropped.is_nan() || dropped > limit {
            return None;
        }
        let lambda: Vec<Complex64> = (0..d).map(|k| t[(k, k)]).collect();
        let radius = lambda.iter().fold(0.0f64, |m, l| m.max(l.norm()));
        let near = 4.0 * f64::EPSILON * radius;
        let partner = (0..d)
            .map(|k| {
                let l = lambda[k];
                (l.im != 0.0)
                    .then(|| (0..k).find(|&j| (lambda[j].conj() - l).norm() <= near))
                    .flatten()
            })
            .collect();
        Some(Spectrum {
            ratio: Vec::new(),
            ur: u.map(|z| z.re),
            ui: u.map(|z| z.im),
            lambda,
            partner,
            radius,
        })
    }
}

impl DenseForm {
    /// The form of `a` (square, finite): its balancing, and its eigendecomposition where it
    /// is normal after balancing.
    pub(crate) fn of(a: &DMatrix<f64>) -> Self {
        let (scale, b) = balance(a);
        let (na, nb) = (norm1(a), norm1(&b));
        // Scaling and squaring balances where that halves the 1-norm.
        let balanced = nb < 0.5 * na;
        let d = a.nrows();
        let spectrum = Spectrum::of(&b).map(|mut sp| {
            sp.ratio = (0..d * d).map(|i| scale[i % d] / scale[i / d]).collect();
            sp
        });
        DenseForm {
            spectrum,
            scale,
            balanced,
            norm1: if balanced { nb } else { na },
        }
    }

    /// `true` if the matrix is normal after balancing.
    pub(crate) fn is_normal(&self) -> bool {
        self.spectrum.is_some()
    }

    /// The route of an f64 bank whose largest step length is `th`, and its stated error
    /// (relative to the largest function value, at an eigenvalue or in norm): the normal route
    /// where the matrix is normal after balancing and `8 d ε (1 + ρ th)` (ρ the largest |λ|:
    /// the rounding of U and of the products, and the eigenvalues' own error, absolute `~ε ρ`,
    /// which moves `f(τhλ)` by `~ε ρ th |f'|`; the φ-functions and kernels have `|f'| ≤ |f|`
    /// on the left half plane) is at most [`F64_BOUND_MAX`]; else scaling and squaring where
    /// `16 ε (1 + ‖thA‖₁)` (its measured error, tests/it/f64_banks.rs, with room) is; else
    /// `None`: the bank takes the default route.
    pub(crate) fn route(&self, th: f64) -> Option<(bool, f64)> {
        let th = th.abs();
        if let Some(sp) = &self.spectrum {
            let b = 8.0 * sp.ur.nrows() as f64 * f64::EPSILON * (1.0 + sp.radius * th);
            if b <= F64_BOUND_MAX {
                return Some((true, b));
            }
        }
        let b = 16.0 * f64::EPSILON * (1.0 + self.norm1 * th);
        (b <= F64_BOUND_MAX).then_some((false, b))
    }

    /// The `p + 1` matrices of node `i` at `τh` (`th`), through this form, into `out`
    /// (column-major, one after the other: `(p + 1) d²` numbers); `normal` says which route
    /// serves the bank ([`route`](Self::route) at its largest τh). `a` is the operator's
    /// matrix (general route); `scratch` serves all the nodes of a bank.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn node_into(
        &self,
        a: &DMatrix<f64>,
        f: &NodeFunctions,
        i: usize,
        th: f64,
        p: usize,
        normal: bool,
        out: &mut [f64],
        scratch: &mut NodeScratch,
    ) -> Result<()> {
        if a.is_empty() {
            return Ok(());
        }
        match &self.spectrum {
            Some(sp) if normal => spectral_node(sp, f, i, th, p, out, scratch),
            _ => {
                let ms = general_node(a, self.balanced.then_some(&self.scale[..]), f, i, th, p)?;
                for (o, m) in out.chunks_exact_mut(a.len()).zip(&ms) {
                    o.copy_from_slice(m.as_slice());
                }
                Ok(())
            }
        }
    }
}

/// The general route at one node: scaling and squaring in f64 on `D⁻¹(τhA)D`.
fn general_node(
    a: &DMatrix<f64>,
    scale: Option<&[f64]>,
    f: &NodeFunctions,
    i: usize,
    th: f64,
    p: usize,
) -> Result<Vec<DMatrix<f64>>> {
    let x = match scale {
        Some(s) => DMatrix::from_fn(a.nrows(), a.ncols(), |r, c| a[(r, c)] * (s[c] / s[r]) * th),
        None => a * th,
    };
    let mut out = f.dense_f64(i, &x, p)?;
    if let Some(s) = scale {
        for m in &mut out {
            for c in 0..m.ncols() {
                for r in 0..m.nrows() {
                    m[(r, c)] *= s[r] / s[c];
                }
            }
        }
    }
    Ok(out)
}

/// The normal route at one node: `D Re(U f(τhΛ) Uᴴ) D⁻¹` for the p + 1 functions, into `out`
/// (`(p + 1) d²` numbers, column-major matrices one after the other).
fn spectral_node(
    sp: &Spectrum,
    f: &NodeFunctions,
    i: usize,
    th: f64,
    p: usize,
    out: &mut [f64],
    scratch: &mut NodeScratch,
) -> Result<()> {
    let Spectrum {
        ur,
        ui,
        lambda,
        partner,
        radius,
        ..
    } = sp;
    let d = ur.nrows();
    // fl[k (p + 1) + j] = f_j(τhλ_k), in the bank's scratch (a value between grid points
    // builds a bank of a 2 × 2 operator per call: no allocation or clearing per node).
    let NodeScratch { fl, rbuf, w } = scratch;
    fl.resize(d * (p + 1), Complex64::new(0.0, 0.0));
    rbuf.resize(p + 1, 0.0);
    w.resize(d, (0.0, 0.0));
    for k in 0..d {
        let l = lambda[k];
        let (done, row) = fl.split_at_mut(k * (p + 1));
        let row = &mut row[..p + 1];
        if let Some(j) = partner[k] {
            for (o, v) in row.iter_mut().zip(&done[j * (p + 1)..(j + 1) * (p + 1)]) {
                *o = v.conj();
            }
        } else if l.im == 0.0 {
            f.real(i, th * l.re, rbuf);
            for (o, v) in row.iter_mut().zip(rbuf.iter()) {
                *o = Complex64::new(*v, 0.0);
            }
        } else {
            f.complex(i, l * th, row);
        }
    }
    if fl.iter().any(|v| !(v.re.is_finite() && v.im.is_finite())) {
        return Err(crate::error::Error::Numerical(format!(
            "phi-function overflow in the bank (an entry beyond {:.1e}): the eigenvalues of A \
             reach |λ| = {radius:.3e} at τh = {th:.3e}; a smaller step size h keeps it finite",
            f64::MAX
        )));
    }
    assert_eq!(
        out.len(),
        (p + 1) * d * d,
        "spectral_node: room for p + 1 matrices"
    );
    let (ur, ui) = (ur.as_slice(), ui.as_slice());
    match d {
        1 => assemble_small::<1>(fl, (ur, ui), &sp.ratio, out),
        2 => assemble_small::<2>(fl, (ur, ui), &sp.ratio, out),
        3 => assemble_small::<3>(fl, (ur, ui), &sp.ratio, out),
        4 => assemble_small::<4>(fl, (ur, ui), &sp.ratio, out),
        _ => assemble(d, fl, (ur, ui), &sp.ratio, w, out),
    }
    Ok(())
}

/// `out` = `D Re(U f_j(Λ) Uᴴ) D⁻¹` for each function j, from `fl[k (p + 1) + j] = f_j(λ_k)`:
/// `Re(U f(Λ) Uᴴ)_rc = Σ_k Re(W_rk conj(U_ck))` with `W = U f(Λ)`, summed over k in order into
/// the column-major result, then scaled by D (`ratio`). Inlined into each arm of the dispatch
/// on d, so that for small d (a constant there) the loops unroll: the same operations in the
/// same order for every d.
#[inline(always)]
fn assemble(
    d: usize,
    fl: &[Complex64],
    (ur, ui): (&[f64], &[f64]),
    ratio: &[f64],
    w: &mut [(f64, f64)],
    out: &mut [f64],
) {
    let p1 = fl.len() / d;
    out.fill(0.0);
    for (j, ms) in out.chunks_exact_mut(d * d).enumerate() {
        for k in 0..d {
            let v = fl[k * p1 + j];
            let (uk_r, uk_i) = (&ur[k * d..(k + 1) * d], &ui[k * d..(k + 1) * d]);
            for ((wv, &a), &b) in w.iter_mut().zip(uk_r).zip(uk_i) {
                *wv = (a * v.re - b * v.im, a * v.im + b * v.re);
            }
            for (c, col) in ms.chunks_exact_mut(d).enumerate() {
                let (uc_r, uc_i) = (uk_r[c], uk_i[c]);
                for (acc, &(wr, wi)) in col.iter_mut().zip(w.iter()) {
                    *acc += wr * uc_r + wi * uc_i;
                }
            }
        }
        for (v, q) in ms.iter_mut().zip(ratio) {
            *v *= q;
        }
    }
}

/// [`assemble`] for a dimension `D` known at compile time: the same operations in the same
/// order (so the same bits), with the column of `U f(Λ)` and each matrix in arrays, so that
/// the loops unroll and nothing is bounds-checked (for d = 2 the matrices of a node took a
/// quarter of a value between grid points' instructions through the slices).
fn assemble_small<const D: usize>(
    fl: &[Complex64],
    (ur, ui): (&[f64], &[f64]),
    ratio: &[f64],
    out: &mut [f64],
) {
    let p1 = fl.len() / D;
    let ratio: &[f64] = &ratio[..D * D];
    let (ur, ui) = (&ur[..D * D], &ui[..D * D]);
    for (j, ms) in out.chunks_exact_mut(D * D).enumerate() {
        let mut m = [[0.0; D]; D];
        for k in 0..D {
            let v = fl[k * p1 + j];
            let mut w = [(0.0, 0.0); D];
            for (row, wv) in w.iter_mut().enumerate() {
                let (a, b) = (ur[k * D + row], ui[k * D + row]);
                *wv = (a * v.re - b * v.im, a * v.im + b * v.re);
            }
            for (c, col) in m.iter_mut().enumerate() {
                let (uc_r, uc_i) = (ur[k * D + c], ui[k * D + c]);
                for (acc, &(wr, wi)) in col.iter_mut().zip(w.iter()) {
                    *acc += wr * uc_r + wi * uc_i;
                }
            }
        }
        for (c, col) in m.iter().enumerate() {
            for (row, v) in col.iter().enumerate() {
                ms[c * D + row] = v * ratio[c * D + row];
            }
        }
    }
}

/// The scratch of the normal route's nodes, kept for all the nodes of a bank.
#[derive(Default)]
pub(crate) struct NodeScratch {
    /// The function values `f_j(τhλ_k)`.
    fl: Vec<Complex64>,
    /// One real eigenvalue's function values.
    rbuf: Vec<f64>,
    /// A column of `U f(Λ)`.
    w: Vec<(f64, f64)>,
}
