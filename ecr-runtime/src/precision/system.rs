//! Systems `y' = Ay + g(y)` written once for every [`Real`] scalar.

use super::Real;
use crate::error::{Error, Result};

/// The linear part `A` of a [`GenericSystem`], in the structure it has (a user pays only for
/// that structure: a multiple of the identity costs one number per φ-function, a diagonal one
/// per component, a dense matrix `d²`).
#[derive(Clone, Debug, PartialEq)]
pub enum LinearPart<S> {
    /// `λ I` (`λ = 0`: no linear part; the method is then a collocation method).
    Scalar(S),
    /// `diag(λ₁, …, λ_d)`.
    Diagonal(Vec<S>),
    /// A dense `dim × dim` matrix, row-major.
    Dense {
        /// The dimension d.
        dim: usize,
        /// The `d²` entries, row by row.
        entries: Vec<S>,
    },
}

impl<S: Real> LinearPart<S> {
    /// Checks the shape against `d` and that every entry is finite.
    pub(crate) fn check(&self, d: usize) -> Result<()> {
        let (entries, expected): (&[S], usize) = match self {
            LinearPart::Scalar(l) => (std::slice::from_ref(l), 1),
            LinearPart::Diagonal(v) => (v, d),
            LinearPart::Dense { dim, entries } => {
                if *dim != d {
                    return Err(Error::DimensionMismatch {
                        what: "linear part",
                        expected: d,
                        found: *dim,
                    });
                }
                (entries, d * d)
            }
        };
        if entries.len() != expected {
            return Err(Error::DimensionMismatch {
                what: "linear part entries",
                expected,
                found: entries.len(),
            });
        }
        if entries.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("linear part"));
        }
        Ok(())
    }
}

/// A system `y' = Ay + g(y)` (for the structure `y' = Q∇H(y)`: `A = QM`, `g = Q∇V`) whose
/// arithmetic is written for any [`Real`] scalar `S`, so that one definition runs in `f64`
/// and in [`super::DoubleDouble`].
pub trait GenericSystem<S: Real> {
    /// The dimension d.
    fn dim(&self) -> usize;
    /// The linear part A.
    fn linear_part(&self) -> LinearPart<S>;
    /// The nonlinear part `g(y)`, written into `out`.
    fn nonlinear(&self, y: &[S], out: &mut [S]);
    /// The energy (first integral or Lyapunov function) `H(y)`, if the system has one.
    fn energy(&self, _y: &[S]) -> Option<S> {
        None
    }
}

impl<S: Real, T: GenericSystem<S> + ?Sized> GenericSystem<S> for &T {
    fn dim(&self) -> usize {
        (**self).dim()
    }
    fn linear_part(&self) -> LinearPart<S> {
        (**self).linear_part()
    }
    fn nonlinear(&self, y: &[S], out: &mut [S]) {
        (**self).nonlinear(y, out)
    }
    fn energy(&self, y: &[S]) -> Option<S> {
        (**self).energy(y)
    }
}
