//! Dense operators of general matrices, of dynamic and static size (symmetric ones:
//! [`Symmetric`](super::Symmetric)).

use std::ops::Range;
use std::sync::{Arc, OnceLock};

use nalgebra::{DMatrix, DMatrixView, SMatrix, SVector};

use super::checks::{apply_shape, check_bank_scale, combine_shape};
use super::entries::NodeFunctions;
use super::matvec::{gemv, matvec_dd, matvec_dd_slices};
use super::normal::{DenseForm, NodeScratch};
use super::traits::{BankArithmetic, LinearOperator, PhiBank};
use crate::error::{Error, Result};
use crate::phi::validate_matrix;
use crate::storage::ensure_allocatable_for;

/// A general dense matrix `A` (non-normal allowed); φ by scaling and modified squaring
/// ([`phi_dense`](crate::phi::phi_dense)); under [`BankArithmetic::F64`] through its
/// eigenvectors where it is normal after balancing (computed on first use, once per operator).
#[derive(Debug, Clone)]
pub struct Dense {
    a: DMatrix<f64>,
    form: OnceLock<Arc<DenseForm>>,
}

impl PartialEq for Dense {
    fn eq(&self, other: &Self) -> bool {
        self.a == other.a
    }
}

impl Dense {
    /// Wraps a square matrix.
    ///
    /// # Errors
    /// [`Error::NotSquare`], [`Error::NonFinite`].
    pub fn new(a: DMatrix<f64>) -> Result<Self> {
        validate_matrix(&a, "dense operator")?;
        Ok(Dense {
            a,
            form: OnceLock::new(),
        })
    }

    /// The `d × d` matrix with the given entries in row-major order.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] if `data.len() ≠ d²`, [`Error::NonFinite`].
    pub fn from_row_slice(d: usize, data: &[f64]) -> Result<Self> {
        Self::new(matrix_from_rows(d, data)?)
    }

    /// The matrix.
    pub fn matrix(&self) -> &DMatrix<f64> {
        &self.a
    }

    /// `true` if the f64 banks ([`BankArithmetic::F64`]) take the normal route: the matrix is
    /// normal to working precision after balancing (computed once, on first use).
    pub fn is_normal_after_balancing(&self) -> bool {
        self.form().is_normal()
    }

    /// The stated error of the f64 banks ([`BankArithmetic::F64`]) for steps up to `h`,
    /// relative to the largest function value: `8 d ε (1 + ρh)` on the normal route (ρ the
    /// largest |λ|), `16 ε (1 + ‖hA‖₁)` on scaling and squaring, whichever serves, or `None`
    /// where neither is within 1e−12: those banks take the default route.
    pub fn f64_bank_bound(&self, h: f64) -> Option<f64> {
        self.form().route(h).map(|(_, b)| b)
    }

    fn form(&self) -> &DenseForm {
        self.form.get_or_init(|| Arc::new(DenseForm::of(&self.a)))
    }
}

/// `DMatrix` from `d²` row-major entries.
pub(super) fn matrix_from_rows(d: usize, data: &[f64]) -> Result<DMatrix<f64>> {
    if data.len() != d * d {
        return Err(Error::DimensionMismatch {
            what: "matrix entries (dim^2)",
            expected: d * d,
            found: data.len(),
        });
    }
    Ok(DMatrix::from_row_slice(d, d, data))
}

/// φ-bank of [`Dense`]: the matrices `φ_k(τ_i h A)`.
#[derive(Debug, Clone, PartialEq)]
pub struct DenseBank {
    dim: usize,
    len: usize,
    p: usize,
    /// The matrices in one allocation, column-major, one after the other: `φ_k(τ_i h A)` is
    /// the `d²` numbers from `(i (p+1) + k) d²` on (a bank is built for every length a value
    /// between grid points asks for: one allocation, not one per matrix).
    phis: Vec<f64>,
    /// Low parts of the propagators carried in double-double (`e^{τ_i hA} = φ_0(τ_i hA) +
    /// lo[i]`), see [`PhiBank::propagate_dd`].
    lo: Vec<Option<DMatrix<f64>>>,
}

impl DenseBank {
    /// The matrix `φ_k(τ_i h A)`.
    ///
    /// # Panics
    /// If `i ≥ len()` or `k > p()`.
    pub fn matrix(&self, i: usize, k: usize) -> DMatrixView<'_, f64> {
        assert!(
            i < self.len && k <= self.p,
            "DenseBank::matrix: index out of range"
        );
        DMatrixView::from_slice(self.slot(i * (self.p + 1) + k), self.dim, self.dim)
    }

    /// The `d²` numbers of matrix `m` (= i (p + 1) + k).
    fn slot(&self, m: usize) -> &[f64] {
        let dd = self.dim * self.dim;
        &self.phis[m * dd..(m + 1) * dd]
    }

    /// A bank of the nodes `taus` whose matrices `fill(i, out)` writes node by node (`out` the
    /// `(p + 1) d²` numbers of node i), returning the low part of its propagator if carried.
    fn build(
        dim: usize,
        taus: &[f64],
        p: usize,
        mut fill: impl FnMut(usize, &mut [f64]) -> Result<Option<DMatrix<f64>>>,
    ) -> Result<DenseBank> {
        let len = taus.len();
        let per = (p + 1) * dim * dim;
        let mut phis = vec![0.0; len * per];
        let mut lo: Vec<Option<DMatrix<f64>>> = Vec::with_capacity(len);
        for i in 0..len {
            // A node met again (the step's end τ = 1 after a Lobatto rule's last node) is the
            // same computation: copied, not repeated.
            if let Some(j) = taus[..i]
                .iter()
                .rposition(|&t| t.to_bits() == taus[i].to_bits())
            {
                phis.copy_within(j * per..(j + 1) * per, i * per);
                lo.push(lo[j].clone());
                continue;
            }
            lo.push(fill(i, &mut phis[i * per..(i + 1) * per])?);
        }
        Ok(DenseBank {
            dim,
            len,
            p,
            phis,
            lo,
        })
    }
}

impl DenseBank {
    /// [`PhiBank::combine`]'s loops for `d` rows. Inlined into each arm of the dispatch on d,
    /// so that for small d (a constant there) the loops unroll: the same operations in the
    /// same order for every d.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn combine_rows(
        &self,
        d: usize,
        indices: Range<usize>,
        y0: &[f64],
        g: &[f64],
        coef: &[f64],
        m: usize,
        out: &mut [f64],
    ) {
        for ((j, i), o) in indices.enumerate().zip(out.chunks_exact_mut(d)) {
            let base = i * (self.p + 1);
            gemv_scaled(o, 1.0, self.slot(base), y0, false);
            for (k, gk) in g.chunks_exact(d).enumerate() {
                gemv_scaled(o, coef[j * m + k], self.slot(base + k + 1), gk, true);
            }
        }
    }
}

/// `out` = the matrices `ms`, one after the other.
fn copy_matrices(ms: &[DMatrix<f64>], out: &mut [f64]) {
    let mut at = 0;
    for m in ms {
        out[at..at + m.len()].copy_from_slice(m.as_slice());
        at += m.len();
    }
    debug_assert_eq!(at, out.len(), "copy_matrices: p + 1 matrices fill a node");
}

/// `y = α M x + β y` for the column-major `rows × x.len()` matrix `m`, β 0 or 1, with
/// nalgebra's `gemv` rounding (each column's `(α m_rc) x_c` added in column order): the same
/// bits as the bank's matrices had when they were `DMatrix` values, without its set-up per
/// call (a bank of a 2 × 2 operator applies ~50 of them per sweep). The fused step's
/// [`gemv_cm`](crate::stepper::gemv_cm) has no α: `α (m x)` rounds otherwise than `(α m) x`,
/// and the fixed path's golden files record the latter.
#[inline(always)]
fn gemv_scaled(y: &mut [f64], alpha: f64, m: &[f64], x: &[f64], beta_one: bool) {
    let rows = y.len();
    for (c, (&xc, col)) in x.iter().zip(m.chunks_exact(rows)).enumerate() {
        if c == 0 && !beta_one {
            for (yr, &a) in y.iter_mut().zip(col) {
                *yr = alpha * a * xc;
            }
        } else {
            for (yr, &a) in y.iter_mut().zip(col) {
                *yr += alpha * a * xc;
            }
        }
    }
}

impl LinearOperator for Dense {
    type Bank = DenseBank;

    fn dim(&self) -> usize {
        self.a.nrows()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        debug_assert_eq!(x.len(), self.a.ncols());
        debug_assert_eq!(y.len(), self.a.nrows());
        gemv(y, 1.0, &self.a, x, 0.0);
    }

    fn phi_bank(&self, h: f64, taus: &[f64], p: usize) -> Result<DenseBank> {
        self.bank(h, taus, p, NodeFunctions::phi())
    }

    fn kernel_bank(&self, h: f64, taus: &[f64], n: usize) -> Result<DenseBank> {
        self.bank(h, taus, n, NodeFunctions::legendre(taus, n))
    }

    fn kernel_bank_in(
        &self,
        h: f64,
        taus: &[f64],
        n: usize,
        arithmetic: BankArithmetic,
    ) -> Result<DenseBank> {
        match arithmetic {
            BankArithmetic::Extended => self.kernel_bank(h, taus, n),
            BankArithmetic::F64 => self.bank_f64(h, taus, n, NodeFunctions::legendre(taus, n)),
            BankArithmetic::StepExtended => {
                self.bank_step_extended(h, taus, n, NodeFunctions::legendre(taus, n))
            }
        }
    }
}

/// The rounding error of `x = fl(a·t)` entry by entry (column-major `a`), exact by the fused
/// multiply-add: `a·t = x + error`. Taken into the double-double propagator, so that the
/// propagator is that of the step h·A, not of its f64 rounding (a relative ε/2 per entry,
/// the same every step: a systematic frequency error; issue 27).
fn product_error(a: &[f64], t: f64, x: &DMatrix<f64>) -> DMatrix<f64> {
    let mut lo = x.clone();
    for (l, (&a, &x)) in lo.iter_mut().zip(a.iter().zip(x.iter())) {
        *l = a.mul_add(t, -x);
    }
    lo
}

impl Dense {
    /// The step and nodes in range, and room for the bank: its (p + 1) matrices and a
    /// propagator tail per node, and the scaling and squaring's few d × d working matrices.
    fn check_bank(&self, h: f64, taus: &[f64], p: usize) -> Result<()> {
        check_bank_scale(h, taus, self.a.amax())?;
        let d = self.a.nrows();
        ensure_allocatable_for(
            || {
                format!(
                    "the φ-bank of a dense {d} × {d} operator ({} nodes, p = {p})",
                    taus.len()
                )
            },
            taus.len()
                .checked_mul(p + 2)
                .and_then(|m| m.checked_add(8))
                .and_then(|m| m.checked_mul(d.checked_mul(d)?)),
        )
    }

    /// The functions of node i at `τh = th` by the default route, with the stage propagators
    /// from the double-double exponential only if `dd_stages` (see
    /// [`NodeFunctions::dense_in`]), and the low part of a double-double propagator.
    #[allow(clippy::type_complexity)]
    fn default_node(
        &self,
        f: &NodeFunctions,
        i: usize,
        th: f64,
        p: usize,
        dd_stages: bool,
    ) -> Result<(Vec<DMatrix<f64>>, Option<DMatrix<f64>>)> {
        let x = &self.a * th;
        let x_lo = product_error(self.a.as_slice(), th, &x);
        f.dense_in(i, &x, Some(&x_lo), p, dd_stages)
    }

    fn bank(&self, h: f64, taus: &[f64], p: usize, f: NodeFunctions) -> Result<DenseBank> {
        self.check_bank(h, taus, p)?;
        DenseBank::build(self.a.nrows(), taus, p, |i, out| {
            let (m, l) = self.default_node(&f, i, taus[i] * h, p, true)?;
            copy_matrices(&m, out);
            Ok(l)
        })
    }
}

impl Dense {
    /// The bank with the step's node (τ = 1) as [`bank`](Self::bank) builds it and the other
    /// nodes in f64 through [`DenseForm`] where a route serves them, else as
    /// [`bank`](Self::bank) ([`BankArithmetic::StepExtended`]).
    fn bank_step_extended(
        &self,
        h: f64,
        taus: &[f64],
        p: usize,
        f: NodeFunctions,
    ) -> Result<DenseBank> {
        self.check_bank(h, taus, p)?;
        let form = self.form();
        let others = taus.iter().filter(|&&t| t != 1.0);
        let tmax = others.fold(0.0f64, |m, t| m.max(t.abs()));
        let route = form.route(tmax * h);
        let mut scratch = NodeScratch::default();
        DenseBank::build(self.a.nrows(), taus, p, |i, out| match route {
            Some((normal, _)) if taus[i] != 1.0 => {
                form.node_into(&self.a, &f, i, taus[i] * h, p, normal, out, &mut scratch)?;
                Ok(None)
            }
            _ => {
                let (m, l) = self.default_node(&f, i, taus[i] * h, p, false)?;
                copy_matrices(&m, out);
                Ok(l)
            }
        })
    }

    /// The bank in f64 ([`BankArithmetic::F64`]) through [`DenseForm`].
    fn bank_f64(&self, h: f64, taus: &[f64], p: usize, f: NodeFunctions) -> Result<DenseBank> {
        self.check_bank(h, taus, p)?;
        let d = self.a.nrows();
        let form = self.form();
        let tmax = taus.iter().fold(0.0f64, |m, t| m.max(t.abs()));
        let Some((normal, _)) = form.route(tmax * h) else {
            return self.bank(h, taus, p, f);
        };
        let mut scratch = NodeScratch::default();
        DenseBank::build(d, taus, p, |i, out| {
            form.node_into(&self.a, &f, i, taus[i] * h, p, normal, out, &mut scratch)?;
            Ok(None)
        })
    }
}

impl PhiBank for DenseBank {
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
        if d == 0 {
            return;
        }
        match d {
            1 => self.combine_rows(1, indices, y0, g, coef, m, out),
            2 => self.combine_rows(2, indices, y0, g, coef, m, out),
            3 => self.combine_rows(3, indices, y0, g, coef, m, out),
            4 => self.combine_rows(4, indices, y0, g, coef, m, out),
            _ => self.combine_rows(d, indices, y0, g, coef, m, out),
        }
    }

    fn combine_cost(&self, m: usize) -> Option<usize> {
        let d = self.dim();
        Some((m + 1) * d * d)
    }

    fn stored(&self) -> usize {
        let d = self.dim();
        (self.len * (self.p + 2)).saturating_mul(d.saturating_mul(d))
    }

    fn propagate_dd(
        &self,
        i: usize,
        y0: &[f64],
        hi: &mut [f64],
        lo: &mut [f64],
        _ws: &mut (),
    ) -> bool {
        match &self.lo[i] {
            Some(l) => {
                matvec_dd_slices(self.slot(i * (self.p + 1)), l.as_slice(), y0, hi, lo);
                true
            }
            None => false,
        }
    }

    fn apply(&self, i: usize, k: usize, x: &[f64], out: &mut [f64], _ws: &mut ()) {
        apply_shape(self.dim, self.len, self.p, i, k, x, out);
        if self.dim > 0 {
            gemv_scaled(out, 1.0, self.slot(i * (self.p + 1) + k), x, false);
        }
    }
}

/// A dense matrix of static size `D × D`: the bank stores `SMatrix` values and applies them
/// with static matrix–vector products (no heap in `combine`/`apply`).
#[derive(Debug, Clone, PartialEq)]
pub struct DenseStatic<const D: usize> {
    a: SMatrix<f64, D, D>,
}

impl<const D: usize> DenseStatic<D> {
    /// Wraps a static matrix.
    ///
    /// # Errors
    /// [`Error::NonFinite`].
    pub fn new(a: SMatrix<f64, D, D>) -> Result<Self> {
        if a.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("dense operator"));
        }
        Ok(DenseStatic { a })
    }

    /// The matrix with the given `D²` entries in row-major order.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] if `data.len() ≠ D²`, [`Error::NonFinite`].
    pub fn from_row_slice(data: &[f64]) -> Result<Self> {
        if data.len() != D * D {
            return Err(Error::DimensionMismatch {
                what: "matrix entries (D^2)",
                expected: D * D,
                found: data.len(),
            });
        }
        Self::new(SMatrix::from_row_slice(data))
    }

    /// The matrix.
    pub fn matrix(&self) -> &SMatrix<f64, D, D> {
        &self.a
    }
}

/// φ-bank of [`DenseStatic`].
#[derive(Debug, Clone, PartialEq)]
pub struct DenseStaticBank<const D: usize> {
    len: usize,
    p: usize,
    /// `phis[i (p+1) + k] = φ_k(τ_i h A)`.
    phis: Vec<SMatrix<f64, D, D>>,
    /// Low parts of the propagators carried in double-double, as in [`DenseBank`].
    lo: Vec<Option<SMatrix<f64, D, D>>>,
}

impl<const D: usize> DenseStaticBank<D> {
    /// The matrix `φ_k(τ_i h A)`.
    ///
    /// # Panics
    /// If `i ≥ len()` or `k > p()`.
    pub fn matrix(&self, i: usize, k: usize) -> &SMatrix<f64, D, D> {
        assert!(
            i < self.len && k <= self.p,
            "DenseStaticBank::matrix: index out of range"
        );
        &self.phis[i * (self.p + 1) + k]
    }
}

impl<const D: usize> LinearOperator for DenseStatic<D> {
    type Bank = DenseStaticBank<D>;

    fn dim(&self) -> usize {
        D
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let v = SVector::<f64, D>::from_column_slice(x);
        y.copy_from_slice((self.a * v).as_slice());
    }

    fn phi_bank(&self, h: f64, taus: &[f64], p: usize) -> Result<DenseStaticBank<D>> {
        self.bank(h, taus, p, NodeFunctions::phi())
    }

    fn kernel_bank(&self, h: f64, taus: &[f64], n: usize) -> Result<DenseStaticBank<D>> {
        self.bank(h, taus, n, NodeFunctions::legendre(taus, n))
    }
}

impl<const D: usize> DenseStatic<D> {
    fn bank(&self, h: f64, taus: &[f64], p: usize, f: NodeFunctions) -> Result<DenseStaticBank<D>> {
        check_bank_scale(h, taus, self.a.amax())?;
        let mut phis = Vec::with_capacity(taus.len() * (p + 1));
        let mut lo = Vec::with_capacity(taus.len());
        let to_static = |m: &DMatrix<f64>| SMatrix::<f64, D, D>::from_column_slice(m.as_slice());
        for (i, tau) in taus.iter().enumerate() {
            let th = tau * h;
            let x = DMatrix::from_column_slice(D, D, (self.a * th).as_slice());
            let x_lo = product_error(self.a.as_slice(), th, &x);
            let (m, l) = f.dense(i, &x, Some(&x_lo), p)?;
            phis.extend(m.iter().map(to_static));
            lo.push(l.as_ref().map(to_static));
        }
        Ok(DenseStaticBank {
            len: taus.len(),
            p,
            phis,
            lo,
        })
    }
}

impl<const D: usize> PhiBank for DenseStaticBank<D> {
    type Workspace = ();

    bank_shape!(|_b| D, unit);

    fn combine(
        &self,
        indices: Range<usize>,
        y0: &[f64],
        g: &[f64],
        coef: &[f64],
        out: &mut [f64],
        _ws: &mut (),
    ) {
        let m = combine_shape(D, self.len, self.p, &indices, y0, g, coef, out);
        if D == 0 {
            return;
        }
        let y = SVector::<f64, D>::from_column_slice(y0);
        for ((j, i), o) in indices.enumerate().zip(out.chunks_exact_mut(D)) {
            let base = i * (self.p + 1);
            let mut acc = self.phis[base] * y;
            for (k, gk) in g.chunks_exact(D).enumerate() {
                let gv = SVector::<f64, D>::from_column_slice(gk);
                acc.gemv(coef[j * m + k], &self.phis[base + k + 1], &gv, 1.0);
            }
            o.copy_from_slice(acc.as_slice());
        }
    }

    fn combine_cost(&self, m: usize) -> Option<usize> {
        let d = self.dim();
        Some((m + 1) * d * d)
    }

    fn stored(&self) -> usize {
        let d = self.dim();
        (self.len * (self.p + 2)).saturating_mul(d.saturating_mul(d))
    }

    fn propagate_dd(
        &self,
        i: usize,
        y0: &[f64],
        hi: &mut [f64],
        lo: &mut [f64],
        _ws: &mut (),
    ) -> bool {
        match &self.lo[i] {
            Some(l) => {
                matvec_dd(&self.phis[i * (self.p + 1)], l, y0, hi, lo);
                true
            }
            None => false,
        }
    }

    fn apply(&self, i: usize, k: usize, x: &[f64], out: &mut [f64], _ws: &mut ()) {
        apply_shape(D, self.len, self.p, i, k, x, out);
        let v = SVector::<f64, D>::from_column_slice(x);
        out.copy_from_slice((self.phis[i * (self.p + 1) + k] * v).as_slice());
    }
}
