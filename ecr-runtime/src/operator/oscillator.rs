//! The linear part of a second-order system `q'' + Ωq = −∇U(q)` in first-order form:
//! `y = (q, p)`, `A = [[0, I], [−Ω, 0]]` (Ω symmetric positive semidefinite), and of its damped
//! form `q'' − Nq' + Ωq = −∇U(q)`, `A = [[0, I], [−Ω, N]]`, for N with the eigenvectors of Ω.
//!
//! The trigonometric and RKN collocation methods (TCrP, RKNCrP for Ω = 0) are ECrP applied to
//! this system, so they run on the one ECrP stepper; this operator supplies the φ- and
//! Legendre-kernel banks of `A` without forming the `2n × 2n` matrix.
//!
//! # The banks in trigonometric form
//!
//! In the eigenbasis of Ω (the standard basis for zero, scalar and diagonal Ω; the
//! eigenvectors V for a dense one) `A` splits into 2 × 2 blocks `A_l = [[0, 1], [−λ_l, 0]]`, one
//! per mode. Every function f of `t A_l` that is a power series has the same shape,
//!
//! ```text
//! f(t A_l) = [[ a,  b ],          a = Re f(iθ),   b = t · Im f(iθ)/θ,   c = −λ_l b,
//!             [ c,  a ]],         θ = t √λ_l,
//! ```
//!
//! because `(tA_l)² = −θ² I`: the even powers give `a`, the odd ones `t A_l` times a series in
//! θ². So a node of the bank is three distinct numbers per mode and per function (stored as the
//! block's four entries), from the scalar functions at the imaginary argument `iθ`:
//!
//! * φ-banks: `a = φᵗ_k(θ²)`, `b = t φᵗ_{k+1}(θ²)` ([`phi_trig`](crate::phi::phi_trig));
//! * Legendre-kernel banks: `e^{iθ}` and `Ψ_j(τ, iθ/τ)` from the complex Legendre kernels
//!   ([`LegendreKernels::row_complex`](crate::phi::LegendreKernels::row_complex)), with
//!   `Im Ψ/θ` taken directly (its Taylor series in `iθ` keeps real and imaginary parts apart,
//!   so the quotient is accurate as θ → 0), and at θ = 0 (RKNC, or a zero mode) the limit
//!   `∫₀¹ (1 − ξ) P̃_j(τξ) dξ`.
//!
//! The damped form `q'' − Nq' + Ωq = …` with N sharing Ω's eigenvectors (modal damping ν_l,
//! [`Oscillator::damped`]) has the blocks `[[0, 1], [−λ_l, ν_l]]`; their functions are general
//! 2 × 2 matrices, computed per mode by the dense algorithms on the balanced block, four
//! numbers per mode and function.
//!
//! `combine` then costs 4(m + 1) multiply-adds per mode and node (plus, for a dense Ω, the
//! transforms `Vᵀ` of y₀ and the m moments, shared by all nodes, and one `V` per node).
//!
//! # Long runs
//!
//! The step's propagator `e^{hA}` is carried in double-double: per mode, the 2 × 2 block
//! (scaling and squaring in double-double); for a dense Ω with `2n ≤`
//! [`DD_PROPAGATOR_MAX_DIM`](super::DD_PROPAGATOR_MAX_DIM), the `2n × 2n` matrix, formed once
//! per step size for this purpose only (the eigenvectors are orthogonal only to rounding, and a
//! propagator through them would not conserve energy to more than that per step).

use std::ops::Range;
use std::sync::Arc;

use nalgebra::{DMatrix, Matrix2};
use num_complex::Complex64;

use super::checks::{apply_shape, check_bank_scale, check_bank_values, combine_shape};
use super::entries::{DD_PROPAGATOR_MAX_DIM, NodeFunctions};
use super::matvec::{gemv, gemv_tr, matvec_dd};
use super::omega::Omega;
use super::traits::{LinearOperator, PhiBank};
use crate::error::{Error, Result};
use crate::phi::{expm_dd, phi_trig};

/// `A = [[0, I], [−Ω, N]]` on `y = (q, p) ∈ ℝ^{2n}` (see the module docs); `N = 0` unless
/// built with [`damped`](Self::damped).
#[derive(Clone, Debug)]
pub struct Oscillator {
    omega: Arc<Omega>,
    /// The modal damping ν_l (N = V diag(ν) Vᵀ), if any.
    damping: Option<Vec<f64>>,
    /// N as a matrix, for a dense Ω with damping.
    damping_matrix: Option<DMatrix<f64>>,
}

impl Oscillator {
    /// The operator of `q'' + Ωq = …` (Ω = 0: `q'' = …`, the RKN case).
    pub fn new(omega: Omega) -> Self {
        Oscillator {
            omega: Arc::new(omega),
            damping: None,
            damping_matrix: None,
        }
    }

    /// The operator of the damped system `q'' − Nq' + Ωq = …` with modal damping: N has the
    /// eigenvectors of Ω and the eigenvalues `nu` (one per mode, in the order of
    /// [`Omega::eigenvalues`]; `N = diag(nu)` for zero, scalar and diagonal Ω). Each mode is
    /// then the block `[[0, 1], [−λ_l, ν_l]]`, whose functions the banks compute as 2 × 2
    /// matrices (four numbers per mode).
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] if `nu` does not have one entry per mode,
    /// [`Error::InvalidInput`] for a positive (energy-increasing) or non-finite entry.
    pub fn damped(omega: Omega, nu: Vec<f64>) -> Result<Self> {
        if nu.len() != omega.dim() {
            return Err(Error::DimensionMismatch {
                what: "modal damping ν (one per mode of Ω)",
                expected: omega.dim(),
                found: nu.len(),
            });
        }
        if let Some(v) = nu.iter().find(|v| !(v.is_finite() && **v <= 0.0)) {
            return Err(Error::InvalidInput(format!(
                "modal damping must be finite and <= 0 (N negative semidefinite), got {v:?}"
            )));
        }
        let damping_matrix = omega.basis().map(|v| {
            let scaled = v * DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(&nu));
            scaled * v.transpose()
        });
        Ok(Oscillator {
            omega: Arc::new(omega),
            damping: Some(nu),
            damping_matrix,
        })
    }

    /// Ω.
    pub fn omega(&self) -> &Omega {
        &self.omega
    }

    /// The modal damping ν (eigenvalues of N), if damped.
    pub fn damping(&self) -> Option<&[f64]> {
        self.damping.as_deref()
    }

    /// The number of modes n (`dim() = 2n`).
    pub fn modes(&self) -> usize {
        self.omega.dim()
    }
}

/// `out[k] = (a_k, s_k)` for slot k at node i of the functions `f`, with `t = τ_i h` and
/// `θ = t√λ`: the block `[[a, t s], [−λ t s, a]]` (see the module docs).
fn trig_block_parts(
    f: &NodeFunctions,
    i: usize,
    t: f64,
    lambda: f64,
    out: &mut [(f64, f64)],
    buf: &mut Buf,
) {
    let p = out.len() - 1;
    let theta = t * lambda.sqrt();
    match f.legendre_map(i) {
        None => {
            // a = φᵗ_k(θ²), s = φᵗ_{k+1}(θ²).
            buf.real.resize(p + 2, 0.0);
            phi_trig(theta * theta, &mut buf.real);
            for (k, o) in out.iter_mut().enumerate() {
                *o = (buf.real[k], buf.real[k + 1]);
            }
        }
        Some((k, map)) => {
            buf.complex.resize(p + 1, Complex64::new(0.0, 0.0));
            f.complex(i, Complex64::new(0.0, theta), &mut buf.complex);
            if theta == 0.0 {
                // e^0 = 1 with Im e^{iθ}/θ → 1; Ψ_j(τ, 0) with Im Ψ_j/θ → ∫(1 − ξ) P̃_j(τξ)
                // dξ = ½ K_j0 − K_j1/6 (1 − ξ = (P̃_0 − P̃_1)/2, orthogonal to P̃_m, m ≥ 2).
                let n = k.n();
                out[0] = (1.0, 1.0);
                for (j, o) in out.iter_mut().enumerate().skip(1) {
                    let row = &map[(j - 1) * n..j * n];
                    let k1 = if j >= 2 { row[1] } else { 0.0 };
                    *o = (buf.complex[j].re, 0.5 * row[0] - k1 / 6.0);
                }
            } else {
                for (o, v) in out.iter_mut().zip(&buf.complex) {
                    *o = (v.re, v.im / theta);
                }
            }
        }
    }
}

/// The `p + 1` functions of slot k = 0..=p at node i of the damped mode block
/// `t [[0, 1], [−λ, ν]]`, as 2 × 2 matrices `[a, b, c, e]` (row-major), by the dense
/// algorithms (`NodeFunctions::dense`) on the balanced block: with `D = diag(√λ, 1)` (λ > 1)
/// the block is `D⁻¹ t[[0, √λ], [−√λ, ν]] D`, whose entries are of one size, and
/// `f(X) = D⁻¹ f(DXD⁻¹) D`.
fn damped_blocks(
    f: &NodeFunctions,
    i: usize,
    t: f64,
    lambda: f64,
    nu: f64,
    p: usize,
) -> Result<Vec<[f64; 4]>> {
    let w = if lambda > 1.0 { lambda.sqrt() } else { 1.0 };
    // D X D⁻¹ = [[0, t w], [−t λ/w, t ν]].
    let x = DMatrix::from_row_slice(2, 2, &[0.0, t * w, -t * lambda / w, t * nu]);
    let (mats, _) = f.dense(i, &x, None, p)?;
    // Undo the balancing: f(X)_01 = f̃_01 / w, f(X)_10 = f̃_10 · w.
    Ok(mats
        .iter()
        .map(|m| [m[(0, 0)], m[(0, 1)] / w, m[(1, 0)] * w, m[(1, 1)]])
        .collect())
}

/// Scratch for building a bank.
#[derive(Default)]
struct Buf {
    real: Vec<f64>,
    complex: Vec<Complex64>,
}

/// The double-double propagator of an [`OscillatorBank`] at its node τ = 1.
#[derive(Clone, Debug, PartialEq)]
enum DdPropagator {
    /// Per mode, the 2 × 2 block, high and low parts.
    Modal {
        node: usize,
        hi: Vec<Matrix2<f64>>,
        lo: Vec<Matrix2<f64>>,
    },
    /// The `2n × 2n` matrix (dense Ω).
    Dense {
        node: usize,
        hi: DMatrix<f64>,
        lo: DMatrix<f64>,
    },
}

/// The φ- or Legendre-kernel bank of an [`Oscillator`]: per node, slot and mode the four
/// entries of the 2 × 2 modal block (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct OscillatorBank {
    n: usize,
    len: usize,
    p: usize,
    /// The eigenvectors of a dense Ω (`None`: the modes are the coordinates).
    basis: Option<Arc<DMatrix<f64>>>,
    /// `vals[((i (p+1) + k) 4 + part) n + l]`, part 0..4 = a, b, c, e of the block
    /// `[[a, b], [c, e]]`.
    vals: Vec<f64>,
    dd: Option<DdPropagator>,
}

/// Scratch of [`OscillatorBank`] (used for a dense Ω): y₀ and the moments in the modal basis,
/// and one modal output block.
#[derive(Clone, Debug)]
pub struct OscillatorWorkspace {
    yhat: Vec<f64>,
    ghat: Vec<f64>,
    w: Vec<f64>,
}

impl LinearOperator for Oscillator {
    type Bank = OscillatorBank;

    fn dim(&self) -> usize {
        2 * self.omega.dim()
    }

    /// Four numbers per mode, slot and node; for a dense Ω (or one with a dense damping) the
    /// double-double propagator of the full 2n × 2n matrix and its scaling and squaring's few
    /// working matrices (16 n² numbers at most), otherwise 16 numbers per mode; a workspace of
    /// `(n + 2)·2m` numbers when Ω has a dense basis.
    fn bank_bytes(&self, len: usize, n: usize) -> Option<(usize, usize)> {
        let m = self.omega.dim();
        let dense = self.omega.basis().is_some() || self.damping_matrix.is_some();
        let vals = len.checked_mul(n.checked_add(1)?)?.checked_mul(4 * m)?;
        let dd = if dense {
            m.checked_mul(m)?.checked_mul(16)?
        } else {
            m.checked_mul(16)?
        };
        let bank = vals.checked_add(dd)?.checked_mul(8)?;
        let workspace = if self.omega.basis().is_some() {
            n.checked_add(2)?.checked_mul(2 * m)?.checked_mul(8)?
        } else {
            0
        };
        Some((bank, workspace))
    }

    /// `(q, p) ↦ (p, −Ωq)`.
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let n = self.omega.dim();
        debug_assert!(x.len() == 2 * n && y.len() == 2 * n);
        let (yq, yp) = y.split_at_mut(n);
        yq.copy_from_slice(&x[n..]);
        self.omega.apply(&x[..n], yp);
        yp.iter_mut().for_each(|v| *v = -*v);
        match (&self.damping, &self.damping_matrix) {
            (_, Some(nm)) => gemv(yp, 1.0, nm, &x[n..], 1.0),
            (Some(nu), None) => {
                for ((o, v), pv) in yp.iter_mut().zip(nu).zip(&x[n..]) {
                    *o += v * pv;
                }
            }
            (None, None) => {}
        }
    }

    fn phi_bank(&self, h: f64, taus: &[f64], p: usize) -> Result<OscillatorBank> {
        self.bank(h, taus, p, NodeFunctions::phi())
    }

    fn kernel_bank(&self, h: f64, taus: &[f64], n: usize) -> Result<OscillatorBank> {
        self.bank(h, taus, n, NodeFunctions::legendre(taus, n))
    }
}

impl Oscillator {
    fn bank(&self, h: f64, taus: &[f64], p: usize, f: NodeFunctions) -> Result<OscillatorBank> {
        let lambda = self.omega.eigenvalues();
        let numax = self
            .damping
            .iter()
            .flatten()
            .fold(0.0_f64, |m, v| m.max(v.abs()));
        let lmax = lambda.iter().fold(1.0_f64, |m, l| m.max(*l)).max(numax);
        check_bank_scale(h, taus, lmax)?;
        let n = lambda.len();
        let mut vals = vec![0.0; taus.len() * (p + 1) * 4 * n];
        let mut parts = vec![(0.0, 0.0); p + 1];
        let mut buf = Buf::default();
        for (i, tau) in taus.iter().enumerate() {
            let t = tau * h;
            for (l, &lam) in lambda.iter().enumerate() {
                let nu = self.damping.as_ref().map_or(0.0, |d| d[l]);
                if nu == 0.0 {
                    trig_block_parts(&f, i, t, lam, &mut parts, &mut buf);
                    for (k, &(a, s)) in parts.iter().enumerate() {
                        let base = (i * (p + 1) + k) * 4 * n + l;
                        let b = t * s;
                        vals[base] = a;
                        vals[base + n] = b;
                        vals[base + 2 * n] = -lam * b;
                        vals[base + 3 * n] = a;
                    }
                } else {
                    let blocks = damped_blocks(&f, i, t, lam, nu, p)?;
                    for (k, m) in blocks.iter().enumerate() {
                        let base = (i * (p + 1) + k) * 4 * n + l;
                        vals[base] = m[0];
                        vals[base + n] = m[1];
                        vals[base + 2 * n] = m[2];
                        vals[base + 3 * n] = m[3];
                    }
                }
            }
        }
        check_bank_values(vals.iter().copied(), || {
            let top = lambda.iter().fold(f64::INFINITY, |m, &l| m.min(l));
            let nu = self
                .damping
                .iter()
                .flatten()
                .fold(f64::NEG_INFINITY, |m, &v| m.max(v));
            let tmax = taus.iter().fold(0.0_f64, |m, t| m.max(t.abs()));
            format!(
                "the blocks [[0, 1], [-λ, ν]] grow like e^(τ·h·√(-λ)) for a negative \
                 eigenvalue λ of Ω and like e^(τ·h·ν) for a damping ν > 0: here the smallest λ \
                 is {top:.3e}, the largest ν {nu:.3e}, and τ·h up to {:.3e}",
                tmax * h
            )
        })?;
        let dd = match (0..taus.len()).find(|&i| f.carries_dd(i)) {
            Some(node) => self.dd_propagator(h, node)?,
            None => None,
        };
        Ok(OscillatorBank {
            n,
            len: taus.len(),
            p,
            basis: self.omega.basis().map(|v| Arc::new(v.clone())),
            vals,
            dd,
        })
    }

    /// `e^{hA}` in double-double (see the module docs), or `None` for a dense Ω too large.
    fn dd_propagator(&self, h: f64, node: usize) -> Result<Option<DdPropagator>> {
        let n = self.omega.dim();
        if self.omega.basis().is_none() {
            let (mut hi, mut lo) = (Vec::with_capacity(n), Vec::with_capacity(n));
            for (l, &lam) in self.omega.eigenvalues().iter().enumerate() {
                let nu = self.damping.as_ref().map_or(0.0, |d| d[l]);
                let x = DMatrix::from_row_slice(2, 2, &[0.0, h, -h * lam, h * nu]);
                let (eh, el) = expm_dd(&x)?;
                hi.push(Matrix2::from_column_slice(eh.as_slice()));
                lo.push(Matrix2::from_column_slice(el.as_slice()));
            }
            return Ok(Some(DdPropagator::Modal { node, hi, lo }));
        }
        if 2 * n > DD_PROPAGATOR_MAX_DIM {
            return Ok(None);
        }
        let omega = self.omega.matrix().ok_or_else(|| {
            Error::Numerical("a dense Ω without its matrix (internal error)".into())
        })?;
        let mut x = DMatrix::zeros(2 * n, 2 * n);
        for i in 0..n {
            x[(i, n + i)] = h;
            for j in 0..n {
                x[(n + i, j)] = -h * omega[(i, j)];
                if let Some(nm) = &self.damping_matrix {
                    x[(n + i, n + j)] = h * nm[(i, j)];
                }
            }
        }
        let (hi, lo) = expm_dd(&x)?;
        Ok(Some(DdPropagator::Dense { node, hi, lo }))
    }
}

impl OscillatorBank {
    /// The blocks `[[a, b], [c, e]]` of slot k at node i: a, b, c, e, each of length n.
    #[inline]
    fn slot(&self, i: usize, k: usize) -> [&[f64]; 4] {
        let n = self.n;
        let base = (i * (self.p + 1) + k) * 4 * n;
        let v = &self.vals[base..base + 4 * n];
        [&v[..n], &v[n..2 * n], &v[2 * n..3 * n], &v[3 * n..]]
    }

    /// `out = Σ-form of one node in modal coordinates`: `out = F_0 y0 + Σ_k coef_k F_{k+1} g_k`
    /// with the blocks of node i (`y0`, `g_k`, `out` split as (q, p) halves of length n).
    #[inline]
    fn modal_block(&self, i: usize, y0: &[f64], g: &[f64], coef: &[f64], out: &mut [f64]) {
        let n = self.n;
        let [a0, b0, c0, e0] = self.slot(i, 0);
        let (oq, op) = out.split_at_mut(n);
        let (q0, p0) = y0.split_at(n);
        for l in 0..n {
            oq[l] = a0[l] * q0[l] + b0[l] * p0[l];
            op[l] = c0[l] * q0[l] + e0[l] * p0[l];
        }
        for (k, (gk, c)) in g.chunks_exact(2 * n).zip(coef).enumerate() {
            let [a, b, cc, e] = self.slot(i, k + 1);
            let (gq, gp) = gk.split_at(n);
            for l in 0..n {
                oq[l] += c * (a[l] * gq[l] + b[l] * gp[l]);
                op[l] += c * (cc[l] * gq[l] + e[l] * gp[l]);
            }
        }
    }
}

/// `out = Vᵀ x` for each half of `x = (q, p)`.
fn to_modal(v: &DMatrix<f64>, x: &[f64], out: &mut [f64]) {
    let n = v.nrows();
    gemv_tr(&mut out[..n], v, &x[..n]);
    gemv_tr(&mut out[n..], v, &x[n..]);
}

/// `out = V x` for each half.
fn from_modal(v: &DMatrix<f64>, x: &[f64], out: &mut [f64]) {
    let n = v.nrows();
    gemv(&mut out[..n], 1.0, v, &x[..n], 0.0);
    gemv(&mut out[n..], 1.0, v, &x[n..], 0.0);
}

impl PhiBank for OscillatorBank {
    type Workspace = OscillatorWorkspace;

    bank_shape!(|b| 2 * b.n);
    fn workspace(&self) -> OscillatorWorkspace {
        let d = if self.basis.is_some() { 2 * self.n } else { 0 };
        OscillatorWorkspace {
            yhat: vec![0.0; d],
            ghat: vec![0.0; d * self.p],
            w: vec![0.0; d],
        }
    }

    fn combine(
        &self,
        indices: Range<usize>,
        y0: &[f64],
        g: &[f64],
        coef: &[f64],
        out: &mut [f64],
        ws: &mut OscillatorWorkspace,
    ) {
        let d = 2 * self.n;
        let m = combine_shape(d, self.len, self.p, &indices, y0, g, coef, out);
        if d == 0 || indices.is_empty() {
            return;
        }
        match &self.basis {
            None => {
                for ((j, i), o) in indices.enumerate().zip(out.chunks_exact_mut(d)) {
                    self.modal_block(i, y0, g, &coef[j * m..(j + 1) * m], o);
                }
            }
            Some(v) => {
                to_modal(v, y0, &mut ws.yhat);
                for (gk, gh) in g.chunks_exact(d).zip(ws.ghat.chunks_exact_mut(d)) {
                    to_modal(v, gk, gh);
                }
                for ((j, i), o) in indices.enumerate().zip(out.chunks_exact_mut(d)) {
                    self.modal_block(
                        i,
                        &ws.yhat,
                        &ws.ghat[..m * d],
                        &coef[j * m..(j + 1) * m],
                        &mut ws.w,
                    );
                    from_modal(v, &ws.w, o);
                }
            }
        }
    }

    /// Fusing the sweeps pays for one mode (a 2 × 2 system: the scalar second-order problem).
    fn combine_cost(&self, m: usize) -> Option<usize> {
        (self.basis.is_none()).then_some(4 * (m + 1) * self.n)
    }

    fn propagate_dd(
        &self,
        i: usize,
        y0: &[f64],
        hi: &mut [f64],
        lo: &mut [f64],
        _ws: &mut OscillatorWorkspace,
    ) -> bool {
        match &self.dd {
            Some(DdPropagator::Modal {
                node,
                hi: mh,
                lo: ml,
            }) if *node == i => {
                let n = self.n;
                for l in 0..n {
                    let (mut h, mut w) = ([0.0; 2], [0.0; 2]);
                    matvec_dd(&mh[l], &ml[l], &[y0[l], y0[n + l]], &mut h, &mut w);
                    (hi[l], hi[n + l], lo[l], lo[n + l]) = (h[0], h[1], w[0], w[1]);
                }
                true
            }
            Some(DdPropagator::Dense {
                node,
                hi: mh,
                lo: ml,
            }) if *node == i => {
                matvec_dd(mh, ml, y0, hi, lo);
                true
            }
            _ => false,
        }
    }

    fn apply(&self, i: usize, k: usize, x: &[f64], out: &mut [f64], ws: &mut OscillatorWorkspace) {
        apply_shape(2 * self.n, self.len, self.p, i, k, x, out);
        let n = self.n;
        let apply_modal = |x: &[f64], out: &mut [f64]| {
            let [a, b, c, e] = self.slot(i, k);
            let (oq, op) = out.split_at_mut(n);
            for l in 0..n {
                oq[l] = a[l] * x[l] + b[l] * x[n + l];
                op[l] = c[l] * x[l] + e[l] * x[n + l];
            }
        };
        match &self.basis {
            None => apply_modal(x, out),
            Some(v) => {
                to_modal(v, x, &mut ws.yhat);
                apply_modal(&ws.yhat, &mut ws.w);
                from_modal(v, &ws.w, out);
            }
        }
    }
}
