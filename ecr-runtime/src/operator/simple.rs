//! Operators with O(1) φ-banks: zero and a scalar multiple of the identity (the diagonal:
//! [`diagonal`](super::diagonal)).

use std::ops::Range;

use super::checks::{
    apply_shape, check_bank_args, check_bank_scale, check_bank_values, combine_shape,
    real_overflow_cause,
};
use super::entries::NodeFunctions;
use super::traits::{LinearOperator, PhiBank, byte_sum};
use crate::error::{Error, Result};
use crate::phi::{exp_dd, two_prod, two_sum};

/// `hi + lo = (eh + el) y` for one entry: the product in double-double.
#[inline]
pub(super) fn mul_dd(eh: f64, el: f64, y: f64) -> (f64, f64) {
    let (p, e) = two_prod(eh, y);
    two_sum(p, e + el * y)
}

/// A `combine` of a bank whose every slot is a multiple of the identity: `out_j = v_{i,0} y0
/// (y0 itself without `propagate`) + Σ_k coef[j·m + k] v_{i,k+1} · g_k` at the nodes i of
/// `indices`, `values[i (p+1) + k]` = v_{i,k}.
struct Rows<'a> {
    values: &'a [f64],
    p: usize,
    propagate: bool,
    coef: &'a [f64],
    m: usize,
}

impl Rows<'_> {
    /// For a state of dimension `d` (the shapes checked by the caller): the loops over a state
    /// get a known length for d ≤ 4 (a 2 × 2 Lotka–Volterra spent 42 % of a solve in the
    /// loop of unknown length, 31 % now); the same operations in the same order for every d.
    #[inline(always)]
    fn combine(&self, d: usize, indices: Range<usize>, y0: &[f64], g: &[f64], out: &mut [f64]) {
        match d {
            0 => {}
            1 => self.rows(1, indices, y0, g, out),
            2 => self.rows(2, indices, y0, g, out),
            3 => self.rows(3, indices, y0, g, out),
            4 => self.rows(4, indices, y0, g, out),
            _ => self.rows(d, indices, y0, g, out),
        }
    }

    #[inline(always)]
    fn rows(&self, d: usize, indices: Range<usize>, y0: &[f64], g: &[f64], out: &mut [f64]) {
        let (p, m) = (self.p, self.m);
        for ((j, i), o) in indices.enumerate().zip(out.chunks_exact_mut(d)) {
            let v = &self.values[i * (p + 1)..(i + 1) * (p + 1)];
            if self.propagate {
                for (ot, yt) in o.iter_mut().zip(y0) {
                    *ot = v[0] * yt;
                }
            } else {
                o.copy_from_slice(y0);
            }
            let row = &self.coef[j * m..(j + 1) * m];
            for ((gk, &ck), &vk) in g.chunks_exact(d).zip(row).zip(&v[1..]) {
                let c = ck * vk;
                for (ot, gt) in o.iter_mut().zip(gk) {
                    *ot += c * gt;
                }
            }
        }
    }
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

    fn bank_bytes(&self, len: usize, n: usize) -> Option<(usize, usize)> {
        Some((
            byte_sum(&[(len.checked_mul(n.checked_add(1)?)?, 8), (len, 1)])?,
            0,
        ))
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

    bank_shape!(|b| b.dim, unit);

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
        let rows = Rows {
            values: &self.values,
            p: self.p,
            propagate: false,
            coef,
            m,
        };
        rows.combine(d, indices, y0, g, out);
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

    fn bank_bytes(&self, len: usize, n: usize) -> Option<(usize, usize)> {
        Some((
            byte_sum(&[(len.checked_mul(n.checked_add(1)?)?, 8), (len, 16)])?,
            0,
        ))
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
        check_bank_values(phis.iter().copied(), || {
            real_overflow_cause(&[self.a], h, taus)
        })?;
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

    bank_shape!(|b| b.dim, unit);

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
        let rows = Rows {
            values: &self.phis,
            p: self.p,
            propagate: true,
            coef,
            m,
        };
        rows.combine(d, indices, y0, g, out);
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
