//! Linear operators `A` of `y' = Ay + g(y)` and their banks of φ-functions.
//!
//! A [`LinearOperator`] applies `A` and, once per step size, precomputes a [`PhiBank`]: the
//! operators `φ_k(τ_i h A)` (paper eq. `phi`) for the nodes `τ_i` and `k = 0..=p`. The ECrP
//! stepper (paper eq. `EEPCr` with Gauss nodes; `docs/method.md#moment-form`) needs exactly
//!
//! ```text
//! Y_i = φ₀(c_i hA) y₀ + h Σ_k c_i^{k+1} φ_{k+1}(c_i hA) G_k
//! ```
//!
//! which is one [`PhiBank::combine`] call with `coef[j·m + k] = h c_i^{k+1}`.
//!
//! Each operator pays only for its structure ("model only what the problem requires"):
//!
//! | operator | `A` | bank | `combine` per output block |
//! |---|---|---|---|
//! | [`Zero`] | 0 | nothing (`φ_k = I/k!`) | O(m d) |
//! | [`Scalar`] | `aI` | `(p+1)` numbers per τ | O(m d) |
//! | [`Diagonal`] | `diag(d)` | `(p+1) d` numbers per τ | O(m d) |
//! | [`Dense`], [`DenseStatic`] | general | `(p+1)` matrices per τ ([`phi_dense`](crate::phi::phi_dense)) | O(m d²) |
//! | [`Symmetric`] | `QΛQᵀ` | `(p+1) d` numbers per τ | O(d²) (+ O(m d²) shared) |
//! | [`Circulant`] | `c ⊛ ·` | `(p+1) d` complex numbers per τ | O(d log d) (+ O(m d log d) shared) |
//! | [`SkewPair`] | `[[0, −C], [C, 0]]` | `(p+1) n` complex numbers per τ | as its generator `C` |
//!
//! ```
//! use ecr_runtime::operator::{Diagonal, LinearOperator, PhiBank};
//! # fn main() -> ecr_runtime::Result<()> {
//! let a = Diagonal::new(vec![-1.0, -100.0])?;
//! let bank = a.phi_bank(0.1, &[0.5, 1.0], 1)?;
//! let mut ws = bank.workspace();
//! let y0 = [1.0, 1.0];
//! let mut y1 = [0.0; 2];
//! // y1 = φ₀(hA) y0  (m = 0: no G terms), the exact flow of y' = Ay over one step.
//! bank.combine(1..2, &y0, &[], &[], &mut y1, &mut ws);
//! assert!((y1[0] - (-0.1f64).exp()).abs() < 1e-15);
//! # Ok(()) }
//! ```

mod circulant;
mod circulant2d;
mod dense;
mod oscillator;
mod simple;
mod skew;

pub use circulant::{
    Circulant, CirculantBank, CirculantWorkspace, FourierBasis, SpectralBank, SpectralWorkspace,
};
pub use circulant2d::{
    Circulant2d, Circulant2dBank, Circulant2dWorkspace, Fourier2dBasis, Fourier2dScratch,
};
pub use dense::{
    Dense, DenseBank, DenseStatic, DenseStaticBank, EigenBasis, Symmetric, SymmetricBank,
    SymmetricWorkspace,
};
pub use oscillator::{Oscillator, OscillatorBank, OscillatorWorkspace};
pub use simple::{Diagonal, DiagonalBank, Scalar, ScalarBank, Zero, ZeroBank};
pub use skew::{SkewGenerator, SkewPair, SkewPairBank, SkewPairWorkspace, SpectralBasis};

use std::ops::Range;
use std::sync::Arc;

use crate::{Error, Result};

/// A linear operator `A: ℝᵈ → ℝᵈ` that can precompute its φ-functions.
pub trait LinearOperator {
    /// The precomputed φ-functions for one step size (see [`PhiBank`]).
    type Bank: PhiBank;

    /// The dimension `d`.
    fn dim(&self) -> usize;

    /// `y = A x`. Does not allocate.
    ///
    /// # Panics
    /// May panic (debug builds check) if `x.len()` or `y.len()` is not [`dim`](Self::dim);
    /// the steppers check lengths before calling.
    fn apply(&self, x: &[f64], y: &mut [f64]);

    /// `φ_k(τ_i h A)` for every `τ_i` in `taus` and `k = 0..=p`; called once per step size.
    ///
    /// `τ = 0` is allowed (`φ_k(0) = I/k!`). The nodes are usually in `[0, 1]`; any finite τ is
    /// accepted (τ > 1 extrapolates the continuous solution).
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`] if `h` is not finite and positive, [`Error::NonFinite`] if a
    /// τ is NaN or infinite, [`Error::Numerical`] if a φ-function overflows (eigenvalues far
    /// in the right half-plane).
    fn phi_bank(&self, h: f64, taus: &[f64], p: usize) -> Result<Self::Bank>;

    /// The Legendre kernels of ECrP in the same bank type: slot 0 holds `e^{τ_i hA}` and slot
    /// `j + 1` holds `Ψ_j(τ_i, hA) = ∫₀¹ e^{(1−ξ)τ_i hA} P̃_j(τ_i ξ) dξ`, `j < n` (see
    /// [`LegendreKernels`](crate::phi::LegendreKernels)). With the Legendre moments `L_j` the
    /// stage is `Y_i = e^{τ_i hA} y₀ + h τ_i Σ_j (2j+1) Ψ_j(τ_i, hA) L_j`: one
    /// [`PhiBank::combine`] with `coef[j] = h τ_i (2j+1)`, and no cancellation for any r.
    /// [`PhiBank::apply`] on such a bank applies these kernels, and [`PhiBank::p`] is n.
    ///
    /// # Errors
    /// As [`phi_bank`](Self::phi_bank).
    fn kernel_bank(&self, h: f64, taus: &[f64], n: usize) -> Result<Self::Bank>;
}

/// The functions a bank holds at each node: φ₀..φ_p, or `e^x` and the Legendre kernels.
pub(crate) struct NodeFunctions {
    legendre: Option<(Arc<crate::phi::LegendreKernels>, Vec<Vec<f64>>)>,
    /// The nodes (Legendre banks only).
    taus: Vec<f64>,
}

/// Dense operators up to this dimension carry the step's propagator `e^{hA}` in double-double
/// (high and low part) in their kernel banks: O(d³) more set-up, O(d²) per step
/// ([`PhiBank::propagate_dd`]).
pub const DD_PROPAGATOR_MAX_DIM: usize = 256;

/// Dense kernel banks up to this dimension also take the stage propagators `e^{τ_i hA}` (τ ≠ 1)
/// from the double-double exponential, rounded to f64: the f64 scaling and squaring leaves
/// their row sums off by up to 5e−13 at `‖hA‖ = 1e4` (a stage value that does not keep a
/// conserved mean), the rounded double-double by an ulp. The set-up costs about (d/64)³·0.05 s
/// per node more, so larger operators keep the f64 algorithm for the stages.
pub const DD_STAGE_PROPAGATOR_MAX_DIM: usize = 64;

impl NodeFunctions {
    /// φ₀..φ_p.
    pub(crate) fn phi() -> Self {
        NodeFunctions {
            legendre: None,
            taus: Vec::new(),
        }
    }

    /// `true` if the propagator at node i is carried beyond f64 (see
    /// [`PhiBank::propagate_dd`]): τ = 1 in a Legendre bank.
    pub(crate) fn carries_dd(&self, i: usize) -> bool {
        self.legendre.is_some() && self.taus[i] == 1.0
    }

    /// The Legendre kernels and the node map `K(τ_i)` of node i (Legendre banks only).
    pub(crate) fn legendre_map(&self, i: usize) -> Option<(&crate::phi::LegendreKernels, &[f64])> {
        self.legendre
            .as_ref()
            .map(|(k, maps)| (&**k, maps[i].as_slice()))
    }

    /// `e^x`, `Ψ_0(τ_i, ·) … Ψ_{n−1}(τ_i, ·)` for the nodes `taus`.
    pub(crate) fn legendre(taus: &[f64], n: usize) -> Self {
        let k = crate::phi::LegendreKernels::shared(n);
        let maps = taus.iter().map(|&t| k.node_map(t)).collect();
        NodeFunctions {
            legendre: Some((k, maps)),
            taus: taus.to_vec(),
        }
    }

    /// `out` = the functions at `x = τ_i h λ` (`out.len() = p + 1`).
    pub(crate) fn real(&self, i: usize, x: f64, out: &mut [f64]) {
        match &self.legendre {
            None => crate::phi::phi_real(x, out),
            Some((k, maps)) => k.row_real(&maps[i], x, out),
        }
    }

    /// As [`real`](Self::real) for complex `z = τ_i h λ`.
    pub(crate) fn complex(
        &self,
        i: usize,
        z: num_complex::Complex64,
        out: &mut [num_complex::Complex64],
    ) {
        match &self.legendre {
            None => crate::phi::phi_complex(z, out),
            Some((k, maps)) => k.row_complex(&maps[i], z, out),
        }
    }

    /// The `p + 1` matrix functions at `X = τ_i h A`, and the low part of the propagator
    /// `e^X = out[0] + lo` where it is carried in double-double: at τ = 1 in a Legendre bank,
    /// for `d ≤ DD_PROPAGATOR_MAX_DIM`. The other nodes of a Legendre bank take `out[0]` from
    /// the double-double exponential too for `d ≤ DD_STAGE_PROPAGATOR_MAX_DIM`.
    #[allow(clippy::type_complexity)]
    pub(crate) fn dense(
        &self,
        i: usize,
        x: &nalgebra::DMatrix<f64>,
        p: usize,
    ) -> Result<(Vec<nalgebra::DMatrix<f64>>, Option<nalgebra::DMatrix<f64>>)> {
        match &self.legendre {
            None => Ok((crate::phi::phi_dense(x, p)?, None)),
            Some((k, maps)) => {
                let d = x.nrows();
                let (mut out, lo) = if self.carries_dd(i) && d <= DD_PROPAGATOR_MAX_DIM {
                    let (hi, lo) = crate::phi::expm_dd(x)?;
                    (vec![hi], Some(lo))
                } else if d <= DD_STAGE_PROPAGATOR_MAX_DIM {
                    (vec![crate::phi::expm_dd(x)?.0], None)
                } else {
                    (crate::phi::phi_dense(x, 0)?, None)
                };
                out.extend(k.rows_dense(&maps[i], x)?);
                Ok((out, lo))
            }
        }
    }
}

/// The distinct values of a spectrum (eigenvalues or diagonal entries), so that a bank
/// evaluates its scalar functions once per distinct value and copies them to every mode that
/// shares it. Values are the same when their bits are: the copies are bit for bit what a
/// separate evaluation would give (`-0.0` and `0.0`, or NaNs with different payloads, count as
/// different; a symmetric spectrum whose mirrored values differ in the last bit is not merged).
pub(crate) struct Distinct<T> {
    /// The distinct values (in the order of their bits).
    values: Vec<T>,
    /// `index[mode]`: the position of the mode's value in `values`.
    index: Vec<usize>,
}

impl<T: Copy> Distinct<T> {
    /// The distinct values of `spectrum`, told apart by `key` (the value's bits): O(n log n).
    pub(crate) fn new<K: Ord + Copy>(spectrum: &[T], key: impl Fn(&T) -> K) -> Self {
        let mut order: Vec<(K, usize)> = spectrum
            .iter()
            .enumerate()
            .map(|(mode, v)| (key(v), mode))
            .collect();
        order.sort_unstable();
        let mut values = Vec::new();
        let mut index = vec![0; spectrum.len()];
        let mut last = None;
        for (k, mode) in order {
            if last != Some(k) {
                values.push(spectrum[mode]);
                last = Some(k);
            }
            index[mode] = values.len() - 1;
        }
        Distinct { values, index }
    }

    /// The entries of a bank with `len` nodes and the slots `0..=p`, evaluated once per node and
    /// distinct value: `eval(i, v, row)` fills `row` (the p + 1 slots at node i and value v) and
    /// returns a number carried at the nodes where `carries(i)` (the propagator's low part or
    /// increment; ignored elsewhere). Returns `entries[(i (p+1) + k) n + mode]` for the n modes
    /// and, per node, the carried numbers per mode where `carries(i)`.
    #[allow(clippy::type_complexity)]
    pub(crate) fn bank_entries<F: Copy, E: Copy>(
        &self,
        len: usize,
        p: usize,
        zero: F,
        carries: impl Fn(usize) -> bool,
        mut eval: impl FnMut(usize, T, &mut [F]) -> E,
    ) -> (Vec<F>, Vec<Option<Vec<E>>>) {
        let (n, nu) = (self.index.len(), self.values.len());
        let mut entries = Vec::with_capacity(len * (p + 1) * n);
        let mut carried = Vec::with_capacity(len);
        // rows[k·nu + u]: slot k at the distinct value u; extra[u]: its carried number.
        let mut rows = vec![zero; (p + 1) * nu];
        let mut extra = Vec::with_capacity(nu);
        let mut row = vec![zero; p + 1];
        for i in 0..len {
            extra.clear();
            for (u, v) in self.values.iter().enumerate() {
                extra.push(eval(i, *v, &mut row));
                for (k, r) in row.iter().enumerate() {
                    rows[k * nu + u] = *r;
                }
            }
            for slot in rows.chunks_exact(nu.max(1)).take(p + 1) {
                entries.extend(self.index.iter().map(|&u| slot[u]));
            }
            carried.push(carries(i).then(|| self.index.iter().map(|&u| extra[u]).collect()));
        }
        (entries, carried)
    }
}

impl Distinct<f64> {
    /// The distinct real values of `spectrum`.
    pub(crate) fn real(spectrum: &[f64]) -> Self {
        Self::new(spectrum, |v| v.to_bits())
    }
}

impl Distinct<num_complex::Complex64> {
    /// The distinct complex values of `spectrum`.
    pub(crate) fn complex(spectrum: &[num_complex::Complex64]) -> Self {
        Self::new(spectrum, |v| (v.re.to_bits(), v.im.to_bits()))
    }
}

/// The operators `φ_k(τ_i h A)`, `i < len()`, `k ≤ p()`, for one step size `h`.
pub trait PhiBank {
    /// Scratch memory (FFT buffers, transformed vectors, ...), allocated once by
    /// [`workspace`](Self::workspace) and reused by every call.
    type Workspace;

    /// The dimension `d`.
    fn dim(&self) -> usize;

    /// The number of nodes τ.
    fn len(&self) -> usize;

    /// `true` if the bank has no nodes.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The highest φ index available.
    fn p(&self) -> usize;

    /// Fresh scratch memory for [`combine`](Self::combine) and [`apply`](Self::apply).
    fn workspace(&self) -> Self::Workspace;

    /// For each `i` in `indices` (output block `j = i − indices.start`, `out.len() = d ·
    /// indices.len()`):
    ///
    /// ```text
    /// out_j = φ₀(τ_i hA) y0 + Σ_{k=0}^{m−1} coef[j·m + k] · φ_{k+1}(τ_i hA) g[k·d..(k+1)·d]
    /// ```
    ///
    /// where `m = g.len()/d ≤ p` (the stage and step formulas of ECrP:
    /// `docs/method.md#stage-equations`, `#step-formula`). Does not
    /// allocate.
    ///
    /// # Panics
    /// If the lengths are inconsistent (`indices` beyond `len()`, `y0.len() ≠ d`, `g.len()` not
    /// a multiple of `d` or `m > p`, `coef.len() ≠ m · indices.len()`, `out.len() ≠ d ·
    /// indices.len()`); [`validate_combine`](Self::validate_combine) reports the same
    /// conditions as errors. The check is O(1).
    fn combine(
        &self,
        indices: Range<usize>,
        y0: &[f64],
        g: &[f64],
        coef: &[f64],
        out: &mut [f64],
        ws: &mut Self::Workspace,
    );

    /// [`combine`](Self::combine) with its independent parts run concurrently on rayon's thread
    /// pool where the bank can (the FFT banks: the transforms of the inputs, then the output
    /// blocks, each group on a workspace of `helpers`), bit for bit the same numbers: each part
    /// is computed by the same code as in `combine`, only the schedule differs. `ws` is the
    /// workspace `combine` would use (the FFT banks keep the inputs' spectra in it), `helpers`
    /// one workspace per concurrent task. The default, for banks whose `combine` is cheap or
    /// that cannot be shared between threads, is `combine` with `ws`. Does not allocate (once
    /// rayon's pool has started).
    ///
    /// # Panics
    /// As [`combine`](Self::combine).
    #[allow(clippy::too_many_arguments)]
    fn combine_concurrent(
        &self,
        indices: Range<usize>,
        y0: &[f64],
        g: &[f64],
        coef: &[f64],
        out: &mut [f64],
        ws: &mut Self::Workspace,
        helpers: &mut [Self::Workspace],
    ) {
        let _ = helpers;
        self.combine(indices, y0, g, coef, out, ws);
    }

    /// Calls `a(self, wa)` and `b(self, wb)` and returns both results: concurrently (rayon's
    /// `join`) where the bank may be shared between threads and its operations are costly (the
    /// FFT banks), otherwise (the default) one after the other. The ECrP stepper runs
    /// independent bank operations of a large system's step through it (see
    /// [`SolverSettings::parallel_min_dim`](crate::stepper::SolverSettings::parallel_min_dim)).
    fn join<RA, RB, A, B>(
        &self,
        wa: &mut Self::Workspace,
        wb: &mut Self::Workspace,
        a: A,
        b: B,
    ) -> (RA, RB)
    where
        Self: Sized,
        RA: Send,
        RB: Send,
        A: FnOnce(&Self, &mut Self::Workspace) -> RA + Send,
        B: FnOnce(&Self, &mut Self::Workspace) -> RB + Send,
    {
        (a(self, wa), b(self, wb))
    }

    /// Checks the arguments of [`combine`](Self::combine) without computing anything and
    /// returns `m = g.len()/d`. Does not allocate unless it returns an error.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] for `indices` beyond `len()` or `g.len()` not a multiple of `d`,
    /// [`Error::DimensionMismatch`] for `y0`, `out` or `coef` of the wrong length,
    /// [`Error::InvalidParameter`] if `m > p()`.
    fn validate_combine(
        &self,
        indices: &Range<usize>,
        y0: &[f64],
        g: &[f64],
        coef: &[f64],
        out: &[f64],
    ) -> Result<usize> {
        combine_shape_checked(self.dim(), self.len(), self.p(), indices, y0, g, coef, out)
    }

    /// `hi + lo = e^{τ_i hA} y0` with the propagator and the product carried beyond f64, if
    /// this bank carries the propagator at node i that way; otherwise `false`, outputs
    /// untouched. Kernel banks carry it at τ = 1 (the step's propagator): dense and symmetric
    /// operators up to [`DD_PROPAGATOR_MAX_DIM`] as a double-double matrix (error ~ε² ‖y0‖),
    /// scalar and diagonal operators as double-double numbers (error ~ε² |y0|), the zero
    /// operator's identity exactly, the spectral operators (circulants, skew pairs) as
    /// `y0 + V (e^{hΛ} − I) V⁻¹ y0` with `e^{hΛ} − I` rounded from double-double and f64
    /// transforms (error ~ε ‖(e^{hA} − I) y0‖, plus the forward transform's rounding of y0
    /// times `e^{hΛ} − I`; `y0` itself enters exactly, and a mode with `e^{hλ} = 1` is kept
    /// exactly). Does not allocate.
    ///
    /// # Panics
    /// If `i ≥ len()` or a slice length differs from `d`.
    fn propagate_dd(
        &self,
        i: usize,
        y0: &[f64],
        hi: &mut [f64],
        lo: &mut [f64],
        ws: &mut Self::Workspace,
    ) -> bool {
        let _ = (i, y0, hi, lo, ws);
        false
    }

    /// The multiply-adds of one output block of [`combine`](Self::combine) with `m` g-blocks,
    /// for banks whose `combine` is simple enough that the ECrP stepper may replace its sweeps
    /// by fused stage matrices when those cost no more
    /// ([`fuses_stages`](crate::stepper::fuses_stages)); `None` (the default): never fuse.
    /// Dense banks: `(m + 1) d²`.
    fn combine_cost(&self, m: usize) -> Option<usize> {
        let _ = m;
        None
    }

    /// `out = φ_k(τ_i h A) x`. Does not allocate.
    ///
    /// # Panics
    /// If `i ≥ len()`, `k > p()` or `x.len()`, `out.len()` differ from `d`.
    fn apply(&self, i: usize, k: usize, x: &[f64], out: &mut [f64], ws: &mut Self::Workspace);
}

/// Validates the arguments of [`LinearOperator::phi_bank`].
pub(crate) fn check_bank_args(h: f64, taus: &[f64]) -> Result<()> {
    if !(h.is_finite() && h > 0.0) {
        return Err(Error::InvalidStepSize(h));
    }
    if taus.iter().any(|t| !t.is_finite()) {
        return Err(Error::NonFinite("taus"));
    }
    Ok(())
}

/// Validates [`check_bank_args`] and that τ·h·A stays in the f64 range for an operator whose
/// largest entry (or eigenvalue) in magnitude is `amax`: otherwise an overflow there would be
/// reported later as a non-finite matrix, without naming its cause (a step size far too large
/// for the operator).
pub(crate) fn check_bank_scale(h: f64, taus: &[f64], amax: f64) -> Result<()> {
    check_bank_args(h, taus)?;
    let tmax = taus.iter().fold(0.0_f64, |m, t| m.max(t.abs()));
    if !(tmax * h * amax).is_finite() {
        return Err(Error::InvalidInput(format!(
            "the step size h = {h:?} is too large for the linear part A (max |entry| {amax:?}): \
             τ·h·A overflows the f64 range"
        )));
    }
    Ok(())
}

/// `Err(Numerical)` if a bank entry overflowed.
pub(crate) fn check_bank_values(values: impl IntoIterator<Item = f64>) -> Result<()> {
    if values.into_iter().all(f64::is_finite) {
        Ok(())
    } else {
        Err(Error::Numerical(
            "phi-function overflow in the bank (eigenvalues of hA far in the right half-plane)"
                .into(),
        ))
    }
}

/// Validates the shapes of a [`PhiBank::combine`] call and returns `m` (see
/// [`PhiBank::validate_combine`]). Allocates only when returning an error.
#[allow(clippy::too_many_arguments)]
pub(crate) fn combine_shape_checked(
    d: usize,
    len: usize,
    p: usize,
    indices: &Range<usize>,
    y0: &[f64],
    g: &[f64],
    coef: &[f64],
    out: &[f64],
) -> Result<usize> {
    if indices.start > indices.end || indices.end > len {
        return Err(Error::InvalidInput(format!(
            "combine: node indices {indices:?} outside 0..{len}"
        )));
    }
    let nb = indices.len();
    if y0.len() != d {
        return Err(Error::DimensionMismatch {
            what: "combine: y0",
            expected: d,
            found: y0.len(),
        });
    }
    if out.len() != d * nb {
        return Err(Error::DimensionMismatch {
            what: "combine: out (dim * number of nodes)",
            expected: d * nb,
            found: out.len(),
        });
    }
    if d == 0 {
        return Ok(0);
    }
    if g.len() % d != 0 {
        return Err(Error::InvalidInput(format!(
            "combine: g has length {}, not a multiple of the dimension {d}",
            g.len()
        )));
    }
    let m = g.len() / d;
    if m > p {
        return Err(Error::InvalidParameter(format!(
            "combine: {m} g-blocks, but the bank holds phi_1..phi_{p} only"
        )));
    }
    if coef.len() != m * nb {
        return Err(Error::DimensionMismatch {
            what: "combine: coef (g-blocks * number of nodes)",
            expected: m * nb,
            found: coef.len(),
        });
    }
    Ok(m)
}

/// [`combine_shape_checked`], panicking on error (for [`PhiBank::combine`]).
#[inline]
#[allow(clippy::too_many_arguments)]
pub(crate) fn combine_shape(
    d: usize,
    len: usize,
    p: usize,
    indices: &Range<usize>,
    y0: &[f64],
    g: &[f64],
    coef: &[f64],
    out: &[f64],
) -> usize {
    match combine_shape_checked(d, len, p, indices, y0, g, coef, out) {
        Ok(m) => m,
        Err(e) => panic!("{e}"),
    }
}

/// Checks the arguments of [`PhiBank::apply`].
#[inline]
pub(crate) fn apply_shape(
    d: usize,
    len: usize,
    p: usize,
    i: usize,
    k: usize,
    x: &[f64],
    out: &[f64],
) {
    assert!(i < len, "apply: node index {i} outside 0..{len}");
    assert!(
        k <= p,
        "apply: phi_{k} requested, the bank holds phi_0..phi_{p}"
    );
    assert_eq!(x.len(), d, "apply: x has length {}, expected {d}", x.len());
    assert_eq!(
        out.len(),
        d,
        "apply: out has length {}, expected {d}",
        out.len()
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distinct_values_are_told_apart_by_their_bits() {
        let spectrum = [
            0.0,
            -2.0,
            -4.0,
            -2.0,
            0.0,
            -0.0,
            3.0,
            -3.0,
            f64::MIN_POSITIVE,
        ];
        let d = Distinct::real(&spectrum);
        // 0 and −0 are different values; each mode maps to a value with its bits.
        assert_eq!(d.values.len(), 7);
        for (mode, v) in spectrum.iter().enumerate() {
            assert_eq!(d.values[d.index[mode]].to_bits(), v.to_bits());
        }
        let d = Distinct::real(&[]);
        assert!(d.values.is_empty() && d.index.is_empty());
        let (entries, carried) = d.bank_entries(2, 1, 0.0, |_| true, |_, _, _| 0.0);
        assert!(entries.is_empty());
        assert_eq!(carried, vec![Some(vec![]), Some(vec![])]);
    }
}
