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

/// The shape of a bank, written once for all of them: [`PhiBank::dim`] from the bank `$b`
/// (`bank_shape!(|b| 2 * b.n)`), [`PhiBank::len`] and [`PhiBank::p`] from its `len` and `p`
/// fields; with `, unit` also the workspace of a bank that needs none.
macro_rules! bank_shape {
    (|$b:ident| $dim:expr) => {
        fn dim(&self) -> usize {
            let $b = self;
            $dim
        }
        fn len(&self) -> usize {
            self.len
        }
        fn p(&self) -> usize {
            self.p
        }
    };
    (|$b:ident| $dim:expr, unit) => {
        bank_shape!(|$b| $dim);
        fn workspace(&self) {}
    };
}

/// [`PhiBank::join`] concurrently (rayon's `join`), for the banks whose operations are costly
/// enough (the FFT banks).
macro_rules! concurrent_join {
    () => {
        fn join<RA, RB, A, B2>(
            &self,
            wa: &mut Self::Workspace,
            wb: &mut Self::Workspace,
            a: A,
            b: B2,
        ) -> (RA, RB)
        where
            RA: Send,
            RB: Send,
            A: FnOnce(&Self, &mut Self::Workspace) -> RA + Send,
            B2: FnOnce(&Self, &mut Self::Workspace) -> RB + Send,
        {
            rayon::join(|| a(self, wa), || b(self, wb))
        }
    };
}

mod checks;
mod circulant;
mod circulant2d;
mod dense;
mod diagonal;
mod entries;
mod matvec;
mod normal;
pub(crate) mod omega;
mod oscillator;
mod simple;
mod skew;
mod spectral;
mod symmetric;
mod traits;

pub use circulant::{Circulant, CirculantBank, CirculantWorkspace, FourierBasis};
pub use circulant2d::{
    Circulant2d, Circulant2dBank, Circulant2dWorkspace, Fourier2dBasis, Fourier2dScratch,
};
pub use dense::{Dense, DenseBank, DenseStatic, DenseStaticBank};
pub use diagonal::{Diagonal, DiagonalBank};
pub use entries::{DD_PROPAGATOR_MAX_DIM, DD_STAGE_PROPAGATOR_MAX_DIM};
pub use oscillator::{Oscillator, OscillatorBank, OscillatorWorkspace};
pub use simple::{Scalar, ScalarBank, Zero, ZeroBank};
pub use skew::{SkewPair, SkewPairBank, SkewPairWorkspace};
pub use spectral::{SkewGenerator, SpectralBank, SpectralBasis, SpectralWorkspace};
pub use symmetric::{EigenBasis, Symmetric, SymmetricBank, SymmetricWorkspace};
pub use traits::{BankArithmetic, LinearOperator, PhiBank};
