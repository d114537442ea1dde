//! The method's kernel: the coefficient-dependent part of ECrP ([`Kernel`]: r, s, the nodes and
//! the Legendre moments L = ℓ g), from tables at run time ([`RuntimeKernel`]) or as the
//! constants that `ecr_method!` emits ([`FixedKernel`]), and the combine coefficients of a
//! kernel bank.

use std::sync::Arc;

use crate::error::Result;
use crate::tables::{Coefficients, QuadratureKind, coefficients, coefficients_with};

/// The coefficient-dependent part of an ECrP method.
pub trait Kernel {
    /// r: the method has order 2r and r moments.
    fn r(&self) -> usize;
    /// s: number of Gauss–Legendre points (s ≥ r).
    fn s(&self) -> usize;
    /// The nodes c₁..c_s.
    fn nodes(&self) -> &[f64];
    /// The Legendre moments m[k·d..(k+1)·d] = Σ_j ℓ_kj g[j·d..(j+1)·d], ℓ_kj = b_j P̃_k(c_j),
    /// k < r, each sum accumulated from 0.0 in the order j = 0, 1, … (so that every kernel
    /// rounds identically).
    fn legendre_moments(&self, g: &[f64], m: &mut [f64], d: usize);
    /// [`legendre_moments`](Self::legendre_moments) with the sizes (r, s, d) the stepper
    /// knows: compile-time constants where its buffers are fixed-size, so that a run-time
    /// kernel's loops unroll as a fixed kernel's do (the same sums in the same order). The
    /// default ignores r and s.
    #[inline(always)]
    fn legendre_moments_sized(&self, g: &[f64], m: &mut [f64], sizes: (usize, usize, usize)) {
        self.legendre_moments(g, m, sizes.2);
    }
    /// Calls `f(j)` for j = 0..s in order, stopping at the first error.
    fn each_stage<F: FnMut(usize) -> Result<()>>(&self, mut f: F) -> Result<()> {
        (0..self.s()).try_for_each(&mut f)
    }
    /// [`each_stage`](Self::each_stage) with the s the stepper knows (a compile-time constant
    /// for fixed-size buffers). The default ignores it.
    #[inline(always)]
    fn each_stage_sized<F: FnMut(usize) -> Result<()>>(&self, s: usize, f: F) -> Result<()> {
        let _ = s;
        self.each_stage(f)
    }
}

/// A kernel with compile-time coefficients (what `ecr_method!` emits): constructible
/// without arguments, so that `Stepper::new(system, h)` can build it.
pub trait FixedKernel: Kernel + Default {}

/// The run-time kernel: coefficients from the built-in tables or generated once and cached.
#[derive(Clone, Debug)]
pub struct RuntimeKernel(Arc<Coefficients>);

impl RuntimeKernel {
    /// The kernel of ECrP with r moments and s points.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`](crate::Error::InvalidParameter) for r, s out of range.
    pub fn new(r: usize, s: usize) -> Result<Self> {
        coefficients(r, s).map(RuntimeKernel)
    }

    /// The kernel with r moments on an s-point quadrature of the given kind (Gauss–Lobatto:
    /// the HBVM baselines).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`](crate::Error::InvalidParameter) for r, s out of range.
    pub fn with_quadrature(kind: QuadratureKind, r: usize, s: usize) -> Result<Self> {
        coefficients_with(kind, r, s).map(RuntimeKernel)
    }

    /// The coefficients.
    pub fn coefficients(&self) -> &Coefficients {
        &self.0
    }
}

impl Kernel for RuntimeKernel {
    fn r(&self) -> usize {
        self.0.r
    }
    fn s(&self) -> usize {
        self.0.s
    }
    fn nodes(&self) -> &[f64] {
        &self.0.nodes
    }
    fn legendre_moments(&self, g: &[f64], m: &mut [f64], d: usize) {
        accumulate(&self.0.lw, self.0.r, self.0.s, g, m, d);
    }
    #[inline(always)]
    fn legendre_moments_sized(&self, g: &[f64], m: &mut [f64], (r, s, d): (usize, usize, usize)) {
        // The stepper's buffers were checked against this kernel's r and s when it was built.
        debug_assert_eq!((r, s), (self.0.r, self.0.s));
        accumulate(&self.0.lw, r, s, g, m, d);
    }
    #[inline(always)]
    fn each_stage_sized<F: FnMut(usize) -> Result<()>>(&self, s: usize, mut f: F) -> Result<()> {
        debug_assert_eq!(s, self.0.s);
        for j in 0..s {
            f(j)?;
        }
        Ok(())
    }
}

/// `m_k = Σ_j w[k·s + j] g_j`, k < r, each sum from 0.0 in the order j = 0, 1, …. Components
/// go in blocks of 8, 4, 2 and 1 whose sums stay in registers (at small d a sum through memory
/// costs a store-to-load round trip per term).
#[inline(always)]
fn accumulate(w: &[f64], r: usize, s: usize, g: &[f64], m: &mut [f64], d: usize) {
    let g = &g[..s * d];
    for (k, mk) in m[..r * d].chunks_exact_mut(d).enumerate() {
        let wk = &w[k * s..(k + 1) * s];
        let mut a0 = 0;
        while a0 < d {
            a0 += match d - a0 {
                8.. => accumulate_rows::<8>(wk, g, mk, a0, d),
                4.. => accumulate_rows::<4>(wk, g, mk, a0, d),
                2.. => accumulate_rows::<2>(wk, g, mk, a0, d),
                _ => accumulate_rows::<1>(wk, g, mk, a0, d),
            };
        }
    }
}

/// Components `a0..a0 + N` of one moment of [`accumulate`]; returns N.
#[inline(always)]
fn accumulate_rows<const N: usize>(
    wk: &[f64],
    g: &[f64],
    mk: &mut [f64],
    a0: usize,
    d: usize,
) -> usize {
    let mut acc = [0.0_f64; N];
    for (j, &wkj) in wk.iter().enumerate() {
        let gj: &[f64; N] = g[j * d + a0..j * d + a0 + N]
            .try_into()
            .expect("N components");
        for (x, gv) in acc.iter_mut().zip(gj) {
            *x += wkj * gv;
        }
    }
    mk[a0..a0 + N].copy_from_slice(&acc);
    N
}

/// The combine coefficients of a kernel bank: `h τ (2j+1)` for each node τ and j < r.
pub(super) fn kernel_coefficients(h: f64, taus: &[f64], r: usize) -> Vec<f64> {
    // Sized once (a flat_map's collect grows its vector step by step).
    let mut coef = Vec::with_capacity(taus.len() * r);
    for &t in taus {
        coef.extend((0..r).map(|j| h * t * (2 * j + 1) as f64));
    }
    coef
}
