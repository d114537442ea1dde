//! Dense symmetric operators: φ through the eigendecomposition, and the eigenbasis as the
//! spectral basis of skew pairs.

use std::ops::Range;
use std::sync::Arc;

use nalgebra::DMatrix;
use num_complex::Complex64;

use super::checks::{
    apply_shape, check_bank_scale, check_bank_values, combine_shape, real_overflow_cause,
};
use super::dense::matrix_from_rows;
use super::diagonal::diagonal_block;
use super::entries::{DD_PROPAGATOR_MAX_DIM, NodeFunctions};
use super::matvec::{gemv, gemv_tr, matvec_dd};
use super::spectral::{SkewGenerator, SpectralBasis};
use super::traits::{LinearOperator, PhiBank};
use crate::error::Result;
use crate::phi::{check_symmetric, expm_dd_split, symmetric_eigen, validate_matrix};

/// A real symmetric matrix `A = QΛQᵀ`: φ through the eigendecomposition.
///
/// Banks store `φ_k(τ_i h λ_t)` per eigenvalue; `combine` transforms `y0` and the `g_k` once
/// (`Qᵀ·`, shared by all output blocks) and pays one `Q·` product per output block.
#[derive(Debug, Clone, PartialEq)]
pub struct Symmetric {
    a: DMatrix<f64>,
    q: Arc<DMatrix<f64>>,
    lambda: Vec<f64>,
}

impl Symmetric {
    /// Decomposes a symmetric matrix (it is symmetrised, `(A + Aᵀ)/2`, first).
    ///
    /// # Errors
    /// [`Error::NotSquare`](crate::Error::NotSquare), [`Error::NonFinite`](crate::Error::NonFinite), [`Error::InvalidInput`](crate::Error::InvalidInput) if
    /// `max |a_ij − a_ji| > 1e−12 · max |a_ij|`, [`Error::Numerical`](crate::Error::Numerical) if the eigensolver fails.
    pub fn new(a: DMatrix<f64>) -> Result<Self> {
        validate_matrix(&a, "symmetric operator")?;
        check_symmetric(&a, "symmetric operator")?;
        let (lambda, q) = symmetric_eigen(&a)?;
        Ok(Symmetric {
            a,
            q: Arc::new(q),
            lambda,
        })
    }

    /// The `d × d` symmetric matrix with the given entries in row-major order.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`](crate::Error::DimensionMismatch) if `data.len() ≠ d²`, otherwise as [`Symmetric::new`].
    pub fn from_row_slice(d: usize, data: &[f64]) -> Result<Self> {
        Self::new(matrix_from_rows(d, data)?)
    }

    /// The matrix.
    pub fn matrix(&self) -> &DMatrix<f64> {
        &self.a
    }

    /// The eigenvalues λ (in the order of the columns of Q).
    pub fn eigenvalues(&self) -> &[f64] {
        &self.lambda
    }

    /// The orthogonal matrix of eigenvectors Q.
    pub fn eigenvectors(&self) -> &DMatrix<f64> {
        &self.q
    }
}

/// φ-bank of [`Symmetric`].
#[derive(Debug, Clone, PartialEq)]
pub struct SymmetricBank {
    dim: usize,
    len: usize,
    p: usize,
    q: Arc<DMatrix<f64>>,
    /// `phis[((i (p+1) + k) d + t] = φ_k(τ_i h λ_t)`.
    phis: Vec<f64>,
    /// Propagators carried in double-double (`e^{τ_i hA} = hi + lo`, formed from A, not from
    /// Q, which is orthogonal only to ε), see [`PhiBank::propagate_dd`].
    props: Vec<Option<(DMatrix<f64>, DMatrix<f64>)>>,
}

/// Scratch of [`SymmetricBank`]: the transformed vectors.
#[derive(Debug, Clone)]
pub struct SymmetricWorkspace {
    /// `Qᵀ y0`
    yhat: Vec<f64>,
    /// `Qᵀ g_k`, `k < p`
    ghat: Vec<f64>,
    /// one block in the eigenbasis
    w: Vec<f64>,
}

impl LinearOperator for Symmetric {
    type Bank = SymmetricBank;

    fn dim(&self) -> usize {
        self.a.nrows()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        debug_assert_eq!(x.len(), self.a.ncols());
        debug_assert_eq!(y.len(), self.a.nrows());
        gemv(y, 1.0, &self.a, x, 0.0);
    }

    fn phi_bank(&self, h: f64, taus: &[f64], p: usize) -> Result<SymmetricBank> {
        self.bank(h, taus, p, NodeFunctions::phi())
    }

    fn kernel_bank(&self, h: f64, taus: &[f64], n: usize) -> Result<SymmetricBank> {
        self.bank(h, taus, n, NodeFunctions::legendre(taus, n))
    }
}

impl Symmetric {
    fn bank(&self, h: f64, taus: &[f64], p: usize, f: NodeFunctions) -> Result<SymmetricBank> {
        check_bank_scale(h, taus, self.a.amax())?;
        let d = self.lambda.len();
        let mut phis = vec![0.0; taus.len() * (p + 1) * d];
        let mut buf = vec![0.0; p + 1];
        for (i, tau) in taus.iter().enumerate() {
            let th = tau * h;
            for (t, l) in self.lambda.iter().enumerate() {
                f.real(i, th * l, &mut buf);
                for (k, v) in buf.iter().enumerate() {
                    phis[(i * (p + 1) + k) * d + t] = *v;
                }
            }
        }
        check_bank_values(phis.iter().copied(), || {
            real_overflow_cause(self.lambda.as_slice(), h, taus)
        })?;
        // A matrix symmetric to the bit has symmetric powers: the double-double exponential
        // then computes half of each product's entries.
        let exact = self.a == self.a.transpose();
        let props = taus
            .iter()
            .enumerate()
            .map(|(i, tau)| {
                if f.carries_dd(i) && d <= DD_PROPAGATOR_MAX_DIM {
                    expm_dd_split(&(&self.a * (tau * h)), None, exact).map(Some)
                } else {
                    Ok(None)
                }
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(SymmetricBank {
            dim: d,
            len: taus.len(),
            p,
            q: Arc::clone(&self.q),
            phis,
            props,
        })
    }
}

impl PhiBank for SymmetricBank {
    type Workspace = SymmetricWorkspace;

    bank_shape!(|b| b.dim);
    fn workspace(&self) -> SymmetricWorkspace {
        SymmetricWorkspace {
            yhat: vec![0.0; self.dim],
            ghat: vec![0.0; self.dim * self.p],
            w: vec![0.0; self.dim],
        }
    }

    fn combine(
        &self,
        indices: Range<usize>,
        y0: &[f64],
        g: &[f64],
        coef: &[f64],
        out: &mut [f64],
        ws: &mut SymmetricWorkspace,
    ) {
        let d = self.dim;
        let m = combine_shape(d, self.len, self.p, &indices, y0, g, coef, out);
        if d == 0 || indices.is_empty() {
            return;
        }
        gemv_tr(&mut ws.yhat, &self.q, y0);
        for (gk, gh) in g.chunks_exact(d).zip(ws.ghat.chunks_exact_mut(d)) {
            gemv_tr(gh, &self.q, gk);
        }
        let stride = (self.p + 1) * d;
        for ((j, i), o) in indices.enumerate().zip(out.chunks_exact_mut(d)) {
            let f = &self.phis[i * stride..(i + 1) * stride];
            diagonal_block(
                &mut ws.w,
                f,
                d,
                &ws.yhat,
                &ws.ghat[..m * d],
                &coef[j * m..(j + 1) * m],
            );
            gemv(o, 1.0, &self.q, &ws.w, 0.0);
        }
    }

    fn propagate_dd(
        &self,
        i: usize,
        y0: &[f64],
        hi: &mut [f64],
        lo: &mut [f64],
        _ws: &mut SymmetricWorkspace,
    ) -> bool {
        match &self.props[i] {
            Some((mh, ml)) => {
                matvec_dd(mh, ml, y0, hi, lo);
                true
            }
            None => false,
        }
    }

    fn apply(&self, i: usize, k: usize, x: &[f64], out: &mut [f64], ws: &mut SymmetricWorkspace) {
        apply_shape(self.dim, self.len, self.p, i, k, x, out);
        let d = self.dim;
        if d == 0 {
            return;
        }
        gemv_tr(&mut ws.yhat, &self.q, x);
        let f = &self.phis[(i * (self.p + 1) + k) * d..(i * (self.p + 1) + k + 1) * d];
        for ((w, yh), fv) in ws.w.iter_mut().zip(&ws.yhat).zip(f) {
            *w = fv * yh;
        }
        gemv(out, 1.0, &self.q, &ws.w, 0.0);
    }
}

/// The orthonormal eigenbasis Q of a symmetric matrix, acting on complex vectors
/// (`û = Qᵀu`, `u = Qû`, real and imaginary parts separately).
#[derive(Debug, Clone, PartialEq)]
pub struct EigenBasis {
    q: Arc<DMatrix<f64>>,
}

impl SpectralBasis for EigenBasis {
    /// Real buffers for the parts of one vector.
    type Scratch = (Vec<f64>, Vec<f64>);

    fn dim(&self) -> usize {
        self.q.nrows()
    }

    fn scratch(&self) -> Self::Scratch {
        (vec![0.0; self.q.nrows()], vec![0.0; self.q.nrows()])
    }

    fn forward(&self, u: &mut [Complex64], s: &mut Self::Scratch) {
        transform(u, s, |y, x| gemv_tr(y, &self.q, x));
    }

    fn inverse(&self, u: &mut [Complex64], s: &mut Self::Scratch) {
        transform(u, s, |y, x| gemv(y, 1.0, &self.q, x, 0.0));
    }
}

/// Applies the real map `f` to the real and imaginary parts of `u`.
fn transform(
    u: &mut [Complex64],
    (a, b): &mut (Vec<f64>, Vec<f64>),
    f: impl Fn(&mut [f64], &[f64]),
) {
    for (av, uv) in a.iter_mut().zip(u.iter()) {
        *av = uv.re;
    }
    f(b, a);
    for (uv, bv) in u.iter_mut().zip(b.iter()) {
        uv.re = *bv;
    }
    for (av, uv) in a.iter_mut().zip(u.iter()) {
        *av = uv.im;
    }
    f(b, a);
    for (uv, bv) in u.iter_mut().zip(b.iter()) {
        uv.im = *bv;
    }
}

impl SkewGenerator for Symmetric {
    type Basis = EigenBasis;

    fn real_spectrum(&self) -> Result<(Vec<f64>, EigenBasis)> {
        Ok((
            self.lambda.clone(),
            EigenBasis {
                q: Arc::clone(&self.q),
            },
        ))
    }
}
