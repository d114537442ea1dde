//! The two traits of every operator: [`LinearOperator`] (A) and [`PhiBank`] (its functions
//! for one step size).

use std::ops::Range;

use super::checks::combine_shape_checked;
use crate::error::Result;

/// The arithmetic a bank is built in ([`LinearOperator::kernel_bank_in`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum BankArithmetic {
    /// Each operator's most accurate route, as [`LinearOperator::kernel_bank`]: the step's
    /// propagator carried in double-double where the operator can
    /// ([`PhiBank::propagate_dd`]), dense stage propagators from the double-double exponential
    /// up to [`DD_STAGE_PROPAGATOR_MAX_DIM`](super::DD_STAGE_PROPAGATOR_MAX_DIM). What the
    /// fixed-step methods' bit-level and round-off claims rest on.
    #[default]
    Extended,
    /// f64 throughout, for a bank whose error (a few ε relative; docs/banks.md gives each
    /// route's bound and its measurement) is far below what it is used for: one partial step
    /// to a value between grid points, a step size only tried.
    F64,
    /// The step's propagator `e^{hA}` (τ = 1) and its kernels exactly as under `Extended`, every
    /// other node in f64 as under `F64`: what a run checked by a second run needs. An error
    /// of the propagator at τ = 1 is common to every method on the same steps (a check cannot
    /// see it), while the stage nodes differ from method to method, so that their f64 errors
    /// show in the difference of the two; the predictor's nodes only start an iteration.
    /// Operators without an f64 route of their own build the `Extended` bank. `solve`'s runs
    /// use it.
    StepExtended,
}

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
    /// [`Error::InvalidStepSize`](crate::Error::InvalidStepSize) if `h` is not finite and positive,
    /// [`Error::NonFinite`](crate::Error::NonFinite) if a τ is NaN or infinite,
    /// [`Error::Numerical`](crate::Error::Numerical) if a φ-function overflows f64 (the error
    /// gives the numbers of τhA that make it: its norm, or its largest eigenvalue's real part).
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

    /// [`kernel_bank`](Self::kernel_bank) in the given arithmetic. Under
    /// [`BankArithmetic::F64`] an operator may skip what its default route carries beyond f64
    /// (the double-double propagators: [`PhiBank::propagate_dd`] then returns `false`) and take
    /// a cheaper route where its structure allows one ([`Dense`](super::Dense): the real Schur
    /// form of a matrix normal after balancing, computed once per operator). The default, for
    /// operators whose banks are f64 already or that have no cheaper route, is `kernel_bank`.
    ///
    /// # Errors
    /// As [`phi_bank`](Self::phi_bank).
    fn kernel_bank_in(
        &self,
        h: f64,
        taus: &[f64],
        n: usize,
        arithmetic: BankArithmetic,
    ) -> Result<Self::Bank> {
        let _ = arithmetic;
        self.kernel_bank(h, taus, n)
    }

    /// The bytes of a [`kernel_bank`](Self::kernel_bank) of `len` nodes and `n` kernels
    /// (slots `0..=n`) and of one of its workspaces ([`PhiBank::workspace`]), as this operator
    /// allocates them: `(bank, workspace)`, or `None` if the count overflows a `usize`. For
    /// checking the memory of a run before it starts (see
    /// [`ec_stepper_bytes`](crate::stepper::ec_stepper_bytes)); a φ-bank takes at most as much.
    ///
    /// The default, for operators that do not say, counts a dense bank: `(len (n + 2) + 8) d²`
    /// numbers and a workspace of `(n + 3) d`.
    fn bank_bytes(&self, len: usize, n: usize) -> Option<(usize, usize)> {
        let d = self.dim();
        let bank = len
            .checked_mul(n.checked_add(2)?)?
            .checked_add(8)?
            .checked_mul(d.checked_mul(d)?)?
            .checked_mul(8)?;
        let workspace = n.checked_add(3)?.checked_mul(d)?.checked_mul(8)?;
        Some((bank, workspace))
    }
}

/// `Σ count·size` over `(count, size)` in bytes, `None` on overflow.
pub(crate) fn byte_sum(parts: &[(usize, usize)]) -> Option<usize> {
    parts.iter().try_fold(0usize, |acc, &(count, size)| {
        acc.checked_add(count.checked_mul(size)?)
    })
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
    /// [`Error::InvalidInput`](crate::Error::InvalidInput) for `indices` beyond `len()` or
    /// `g.len()` not a multiple of `d`,
    /// [`Error::DimensionMismatch`](crate::Error::DimensionMismatch) for `y0`, `out` or `coef` of
    /// the wrong length, [`Error::InvalidParameter`](crate::Error::InvalidParameter) if `m > p()`.
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

    /// `hi + lo = e^{τ_i hA} y0` with the propagator and the product carried beyond f64, if this
    /// bank carries the propagator at node i that way; otherwise `false`, outputs untouched. Kernel
    /// banks carry it at τ = 1 (the step's propagator): dense and symmetric operators up to
    /// [`DD_PROPAGATOR_MAX_DIM`](super::DD_PROPAGATOR_MAX_DIM) as a double-double matrix (error ~ε²
    /// ‖y0‖), scalar and diagonal operators as double-double numbers (error ~ε² |y0|), the zero
    /// operator's identity exactly, the spectral operators (circulants, skew pairs) as `y0 + V
    /// (e^{hΛ} − I) V⁻¹ y0` with `e^{hΛ} − I` rounded from double-double and f64 transforms (error
    /// ~ε ‖(e^{hA} − I) y0‖, plus the forward transform's rounding of y0 times `e^{hΛ} − I`; `y0`
    /// itself enters exactly, and a mode with `e^{hλ} = 1` is kept exactly). Does not allocate.
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

    /// About how many numbers the bank stores: what a cache of banks counts against its
    /// budget. The default, `len() · (p() + 1) · dim()`, is one number per mode, node and
    /// function; banks that store d × d matrices say so.
    fn stored(&self) -> usize {
        self.len()
            .saturating_mul(self.p() + 1)
            .saturating_mul(self.dim())
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
