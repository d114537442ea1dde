//! Operators with O(d) φ-banks: zero, scalar multiple of the identity, diagonal.

use std::ops::Range;

use nalgebra::DVector;

use super::checks::{
    apply_shape, check_bank_args, check_bank_scale, check_bank_values, combine_shape,
};
use super::entries::{Distinct, NodeFunctions};
use super::traits::{LinearOperator, PhiBank};
use crate::error::{Error, Result};
use crate::phi::{exp_dd, two_prod, two_sum};

/// `hi + lo = (eh + el) y` for one entry: the product in double-double.
#[inline]
fn mul_dd(eh: f64, el: f64, y: f64) -> (f64, f64) {
    let (p, e) = two_prod(eh, y);
    two_sum(p, e + el * y)
}

/// `A = 0` in dimension `dim`: `φ_k(τhA) = I/k!` (the method reduces to HBVM,
/// `docs/method.md#hbvm`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Zero {
    dim: usize,
}

impl Zero {
    /// The zero operator on `ℝ^dim` (cannot fail).
    pub fn new(dim: usize) -> Self {
        Zero { dim }
    }
}

/// The φ-bank of [`Zero`]: `φ_k = I/k!` for every node (a Legendre-kernel bank holds the
/// numbers `Ψ_j(τ_i, 0) = ∫₀¹ P̃_j(τ_i ξ) dξ`).
#[derive(Debug, Clone, PartialEq)]
pub struct ZeroBank {
    dim: usize,
    len: usize,
    p: usize,
    /// `values[i (p+1) + k]`: the multiple of the identity in slot k at node i.
    values: Vec<f64>,
    /// Nodes whose propagator (the identity) [`PhiBank::propagate_dd`] reports.
    carries: Vec<bool>,
}

impl LinearOperator for Zero {
    type Bank = ZeroBank;

    fn dim(&self) -> usize {
        self.dim
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        debug_assert_eq!(x.len(), self.dim);
        y.fill(0.0);
    }

    fn phi_bank(&self, h: f64, taus: &[f64], p: usize) -> Result<ZeroBank> {
        self.bank(h, taus, p, NodeFunctions::phi())
    }

    fn kernel_bank(&self, h: f64, taus: &[f64], n: usize) -> Result<ZeroBank> {
        self.bank(h, taus, n, NodeFunctions::legendre(taus, n))
    }
}

impl Zero {
    fn bank(&self, h: f64, taus: &[f64], p: usize, f: NodeFunctions) -> Result<ZeroBank> {
        check_bank_args(h, taus)?;
        let mut values = vec![0.0; taus.len() * (p + 1)];
        for (i, row) in values.chunks_exact_mut(p + 1).enumerate() {
            f.real(i, 0.0, row);
        }
        Ok(ZeroBank {
            dim: self.dim,
            len: taus.len(),
            p,
            values,
            carries: (0..taus.len()).map(|i| f.carries_dd(i)).collect(),
        })
    }
}

impl PhiBank for ZeroBank {
    type Workspace = ();

    fn dim(&self) -> usize {
        self.dim
    }
    fn len(&self) -> usize {
        self.len
    }
    fn p(&self) -> usize {
        self.p
    }
    fn workspace(&self) {}

    /// `out_j = y0 + Σ_k coef[j·m + k] v_{i,k+1} · g_k` (`v_{i,k} = 1/k!` in a φ-bank).
    fn combine(
        &self,
        indices: Range<usize>,
        y0: &[f64],
        g: &[f64],
        coef: &[f64],
        out: &mut [f64],
        _ws: &mut (),
    ) {
        let d = self.dim;
        let m = combine_shape(d, self.len, self.p, &indices, y0, g, coef, out);
        if d == 0 {
            return;
        }
        for ((j, i), o) in indices.enumerate().zip(out.chunks_exact_mut(d)) {
            let v = &self.values[i * (self.p + 1)..(i + 1) * (self.p + 1)];
            o.copy_from_slice(y0);
            for (k, gk) in g.chunks_exact(d).enumerate() {
                let c = coef[j * m + k] * v[k + 1];
                for (ot, gt) in o.iter_mut().zip(gk) {
                    *ot += c * gt;
                }
            }
        }
    }

    /// `e^{0} y0 = y0` exactly: `hi = y0`, `lo = 0`.
    fn propagate_dd(
        &self,
        i: usize,
        y0: &[f64],
        hi: &mut [f64],
        lo: &mut [f64],
        _ws: &mut (),
    ) -> bool {
        if !self.carries[i] {
            return false;
        }
        hi.copy_from_slice(y0);
        lo.fill(0.0);
        true
    }

    fn apply(&self, i: usize, k: usize, x: &[f64], out: &mut [f64], _ws: &mut ()) {
        apply_shape(self.dim, self.len, self.p, i, k, x, out);
        let c = self.values[i * (self.p + 1) + k];
        for (o, xv) in out.iter_mut().zip(x) {
            *o = c * xv;
        }
    }
}

/// `A = a I` in dimension `dim`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scalar {
    a: f64,
    dim: usize,
}

impl Scalar {
    /// `A = a I` on `ℝ^dim`.
    ///
    /// # Errors
    /// [`Error::NonFinite`] if `a` is NaN or infinite.
    pub fn new(a: f64, dim: usize) -> Result<Self> {
        if !a.is_finite() {
            return Err(Error::NonFinite("scalar operator a"));
        }
        Ok(Scalar { a, dim })
    }

    /// The scalar `a`.
    pub fn value(&self) -> f64 {
        self.a
    }
}

/// φ-bank of [`Scalar`]: the numbers `φ_k(τ_i h a)`.
#[derive(Debug, Clone, PartialEq)]
pub struct ScalarBank {
    dim: usize,
    len: usize,
    p: usize,
    /// `phis[i (p+1) + k] = φ_k(τ_i h a)`.
    phis: Vec<f64>,
    /// The low parts of the propagators carried in double-double (`e^{τ_i h a} = phis[i (p+1)]
    /// + lo[i]`), see [`PhiBank::propagate_dd`].
    lo: Vec<Option<f64>>,
}

impl LinearOperator for Scalar {
    type Bank = ScalarBank;

    fn dim(&self) -> usize {
        self.dim
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        debug_assert_eq!(x.len(), self.dim);
        debug_assert_eq!(y.len(), self.dim);
        for (yv, xv) in y.iter_mut().zip(x) {
            *yv = self.a * xv;
        }
    }

    fn phi_bank(&self, h: f64, taus: &[f64], p: usize) -> Result<ScalarBank> {
        self.bank(h, taus, p, NodeFunctions::phi())
    }

    fn kernel_bank(&self, h: f64, taus: &[f64], n: usize) -> Result<ScalarBank> {
        self.bank(h, taus, n, NodeFunctions::legendre(taus, n))
    }
}

impl Scalar {
    fn bank(&self, h: f64, taus: &[f64], p: usize, f: NodeFunctions) -> Result<ScalarBank> {
        check_bank_scale(h, taus, self.a.abs())?;
        let mut phis = vec![0.0; taus.len() * (p + 1)];
        let mut lo = vec![None; taus.len()];
        for (i, (tau, row)) in taus.iter().zip(phis.chunks_exact_mut(p + 1)).enumerate() {
            let x = tau * h * self.a;
            f.real(i, x, row);
            if f.carries_dd(i) {
                let e = exp_dd(x);
                row[0] = e.hi;
                lo[i] = Some(e.lo);
            }
        }
        check_bank_values(phis.iter().copied())?;
        Ok(ScalarBank {
            dim: self.dim,
            len: taus.len(),
            p,
            phis,
            lo,
        })
    }
}

impl PhiBank for ScalarBank {
    type Workspace = ();

    fn dim(&self) -> usize {
        self.dim
    }
    fn len(&self) -> usize {
        self.len
    }
    fn p(&self) -> usize {
        self.p
    }
    fn workspace(&self) {}

    fn combine(
        &self,
        indices: Range<usize>,
        y0: &[f64],
        g: &[f64],
        coef: &[f64],
        out: &mut [f64],
        _ws: &mut (),
    ) {
        let d = self.dim;
        let m = combine_shape(d, self.len, self.p, &indices, y0, g, coef, out);
        if d == 0 {
            return;
        }
        for ((j, i), o) in indices.enumerate().zip(out.chunks_exact_mut(d)) {
            let f = &self.phis[i * (self.p + 1)..(i + 1) * (self.p + 1)];
            for (ot, yt) in o.iter_mut().zip(y0) {
                *ot = f[0] * yt;
            }
            for (k, gk) in g.chunks_exact(d).enumerate() {
                let c = coef[j * m + k] * f[k + 1];
                for (ot, gt) in o.iter_mut().zip(gk) {
                    *ot += c * gt;
                }
            }
        }
    }

    fn propagate_dd(
        &self,
        i: usize,
        y0: &[f64],
        hi: &mut [f64],
        lo: &mut [f64],
        _ws: &mut (),
    ) -> bool {
        let Some(el) = self.lo[i] else {
            return false;
        };
        assert!(y0.len() == self.dim && hi.len() == self.dim && lo.len() == self.dim);
        let eh = self.phis[i * (self.p + 1)];
        for ((h, l), y) in hi.iter_mut().zip(lo.iter_mut()).zip(y0) {
            (*h, *l) = mul_dd(eh, el, *y);
        }
        true
    }

    fn apply(&self, i: usize, k: usize, x: &[f64], out: &mut [f64], _ws: &mut ()) {
        apply_shape(self.dim, self.len, self.p, i, k, x, out);
        let c = self.phis[i * (self.p + 1) + k];
        for (o, xv) in out.iter_mut().zip(x) {
            *o = c * xv;
        }
    }
}

/// `A = diag(d)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Diagonal {
    diag: Vec<f64>,
}

impl Diagonal {
    /// `A = diag(diag)`.
    ///
    /// # Errors
    /// [`Error::NonFinite`] if an entry is NaN or infinite.
    pub fn new(diag: Vec<f64>) -> Result<Self> {
        if diag.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("diagonal"));
        }
        Ok(Diagonal { diag })
    }

    /// `A = diag(v)` from an nalgebra vector.
    ///
    /// # Errors
    /// As [`Diagonal::new`].
    pub fn from_dvector(v: &DVector<f64>) -> Result<Self> {
        Self::new(v.iter().copied().collect())
    }

    /// The diagonal entries.
    pub fn entries(&self) -> &[f64] {
        &self.diag
    }
}

/// φ-bank of [`Diagonal`]: the numbers `φ_k(τ_i h d_t)`.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagonalBank {
    dim: usize,
    len: usize,
    p: usize,
    /// `phis[((i (p+1) + k) d + t] = φ_k(τ_i h d_t)`.
    phis: Vec<f64>,
    /// The low parts of the propagators carried in double-double (`e^{τ_i h d_t} =
    /// phis[i (p+1) d + t] + lo[i][t]`), see [`PhiBank::propagate_dd`].
    lo: Vec<Option<Vec<f64>>>,
}

impl LinearOperator for Diagonal {
    type Bank = DiagonalBank;

    fn dim(&self) -> usize {
        self.diag.len()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        debug_assert_eq!(x.len(), self.diag.len());
        debug_assert_eq!(y.len(), self.diag.len());
        for ((yv, xv), dv) in y.iter_mut().zip(x).zip(&self.diag) {
            *yv = dv * xv;
        }
    }

    fn phi_bank(&self, h: f64, taus: &[f64], p: usize) -> Result<DiagonalBank> {
        self.bank(h, taus, p, NodeFunctions::phi())
    }

    fn kernel_bank(&self, h: f64, taus: &[f64], n: usize) -> Result<DiagonalBank> {
        self.bank(h, taus, n, NodeFunctions::legendre(taus, n))
    }
}

impl Diagonal {
    fn bank(&self, h: f64, taus: &[f64], p: usize, f: NodeFunctions) -> Result<DiagonalBank> {
        check_bank_scale(
            h,
            taus,
            self.diag.iter().fold(0.0_f64, |m, x| m.max(x.abs())),
        )?;
        let d = self.diag.len();
        // Evaluated once per distinct entry (a diagonal often repeats its entries).
        let entries = Distinct::real(&self.diag);
        let carries = |i| f.carries_dd(i);
        let (phis, lo) = entries.bank_entries(taus.len(), p, 0.0, carries, |i, dv, row| {
            let x = taus[i] * h * dv;
            f.real(i, x, row);
            if f.carries_dd(i) {
                let e = exp_dd(x);
                row[0] = e.hi;
                e.lo
            } else {
                0.0
            }
        });
        check_bank_values(phis.iter().copied())?;
        Ok(DiagonalBank {
            dim: d,
            len: taus.len(),
            p,
            phis,
            lo,
        })
    }
}

/// `o = f0 ⊙ y0 + Σ_k c_k f_{k+1} ⊙ g_k` for diagonal banks (shared with the symmetric bank).
#[inline]
pub(super) fn diagonal_block(
    o: &mut [f64],
    f: &[f64],
    d: usize,
    y0: &[f64],
    g: &[f64],
    coefs: &[f64],
) {
    for ((ot, ft), yt) in o.iter_mut().zip(&f[..d]).zip(y0) {
        *ot = ft * yt;
    }
    for (k, (gk, c)) in g.chunks_exact(d).zip(coefs).enumerate() {
        let fk = &f[(k + 1) * d..(k + 2) * d];
        for ((ot, ft), gt) in o.iter_mut().zip(fk).zip(gk) {
            *ot += c * ft * gt;
        }
    }
}

impl PhiBank for DiagonalBank {
    type Workspace = ();

    fn dim(&self) -> usize {
        self.dim
    }
    fn len(&self) -> usize {
        self.len
    }
    fn p(&self) -> usize {
        self.p
    }
    fn workspace(&self) {}

    fn combine(
        &self,
        indices: Range<usize>,
        y0: &[f64],
        g: &[f64],
        coef: &[f64],
        out: &mut [f64],
        _ws: &mut (),
    ) {
        let d = self.dim;
        let m = combine_shape(d, self.len, self.p, &indices, y0, g, coef, out);
        if d == 0 {
            return;
        }
        let stride = (self.p + 1) * d;
        for ((j, i), o) in indices.enumerate().zip(out.chunks_exact_mut(d)) {
            let f = &self.phis[i * stride..(i + 1) * stride];
            diagonal_block(o, f, d, y0, g, &coef[j * m..(j + 1) * m]);
        }
    }

    fn propagate_dd(
        &self,
        i: usize,
        y0: &[f64],
        hi: &mut [f64],
        lo: &mut [f64],
        _ws: &mut (),
    ) -> bool {
        let Some(el) = &self.lo[i] else {
            return false;
        };
        let d = self.dim;
        assert!(y0.len() == d && hi.len() == d && lo.len() == d);
        let eh = &self.phis[i * (self.p + 1) * d..(i * (self.p + 1) + 1) * d];
        for ((((h, l), y), a), b) in hi.iter_mut().zip(lo.iter_mut()).zip(y0).zip(eh).zip(el) {
            (*h, *l) = mul_dd(*a, *b, *y);
        }
        true
    }

    fn apply(&self, i: usize, k: usize, x: &[f64], out: &mut [f64], _ws: &mut ()) {
        apply_shape(self.dim, self.len, self.p, i, k, x, out);
        let d = self.dim;
        let f = &self.phis[(i * (self.p + 1) + k) * d..(i * (self.p + 1) + k + 1) * d];
        for ((o, xv), fv) in out.iter_mut().zip(x).zip(f) {
            *o = fv * xv;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A diagonal with repeated entries (0, −0, a repeated pair, ±d) gives, bit for bit, the bank
    /// evaluated entry by entry.
    #[test]
    fn diagonal_bank_per_distinct_entry_equals_bank_per_entry() {
        let diag = vec![
            0.0, -2.0, -4.0, -2.0, 0.0, -0.0, 3.25, -3.25, 1e-9, -2.0, -300.0,
        ];
        let op = Diagonal::new(diag.clone()).unwrap();
        let (h, taus) = (0.3, [0.0, 0.2, 0.5, 1.0, 1.4]);
        for p in [0, 1, 4] {
            for kernels in [false, true] {
                let (bank, f) = if kernels {
                    (
                        op.kernel_bank(h, &taus, p),
                        NodeFunctions::legendre(&taus, p),
                    )
                } else {
                    (op.phi_bank(h, &taus, p), NodeFunctions::phi())
                };
                let bank = bank.unwrap();
                let mut buf = vec![0.0; p + 1];
                for (i, tau) in taus.iter().enumerate() {
                    for (t, dv) in diag.iter().enumerate() {
                        f.real(i, tau * h * dv, &mut buf);
                        let lo = f.carries_dd(i).then(|| {
                            let e = exp_dd(tau * h * dv);
                            buf[0] = e.hi;
                            e.lo
                        });
                        for (k, v) in buf.iter().enumerate() {
                            let got = bank.phis[(i * (p + 1) + k) * diag.len() + t];
                            assert_eq!(got.to_bits(), v.to_bits(), "p={p} i={i} t={t} k={k}");
                        }
                        let got = bank.lo[i].as_ref().map(|l| l[t].to_bits());
                        assert_eq!(got, lo.map(f64::to_bits), "p={p} i={i} t={t}: low part");
                    }
                }
            }
        }
    }
}
