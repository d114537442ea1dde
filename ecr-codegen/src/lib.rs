//! Exact coefficient generator for exponential collocation methods (ECr, TCr, RKNCr).
//!
//! Everything is computed in exact rational arithmetic (`num-rational`) or, for the
//! irrational Gauss nodes and weights, as rigorous rational enclosures narrower than 10⁻⁶⁰
//! relative, and rounded to `f64` once, correctly. The library is pure and deterministic
//! (no I/O); `ecr-runtime/build.rs`, `ecr-macros` and the `ecr tables` command render its
//! tables.
//!
//! ```
//! use ecr_codegen::{Family, MethodTable};
//! let t = MethodTable::generate(Family::Ec, 2, 2).unwrap();
//! // Gauss–Legendre nodes 1/2 ∓ √3/6, correctly rounded:
//! assert_eq!(t.nodes_f64(), [0.2113248654051871, 0.7886751345948129]);
//! assert_eq!(t.weights_f64(), [0.5, 0.5]);
//! ```
#![deny(missing_docs)]

pub mod interval;
pub mod kernels;
pub mod legendre;
pub mod poly;
pub mod quadrature;
pub mod rat;
pub mod render;
pub mod table;

pub use interval::Interval;
pub use poly::Poly;
pub use quadrature::{Quadrature, QuadratureKind};
pub use rat::Rat;
pub use table::{Certified, Family, MethodTable};

use std::fmt;

/// Largest order parameter r the generator accepts.
pub const MAX_R: usize = 32;
/// Largest number of quadrature points s the generator accepts.
pub const MAX_S: usize = 64;

/// Invalid requests to the generator.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum CodegenError {
    /// r outside 1..=MAX_R.
    ROutOfRange {
        /// The requested r.
        r: usize,
    },
    /// s outside r..=MAX_S.
    SOutOfRange {
        /// The requested r.
        r: usize,
        /// The requested s.
        s: usize,
    },
    /// A family name other than `ec`, `tc`, `rknc`.
    UnknownFamily(String),
    /// The enclosures could not be made tight enough to round (never observed; reported
    /// rather than guessed).
    Certification {
        /// The requested r.
        r: usize,
        /// The requested s.
        s: usize,
    },
}

impl fmt::Display for CodegenError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CodegenError::ROutOfRange { r } => {
                write!(
                    f,
                    "r = {r} is out of range: the generator supports 1 <= r <= {MAX_R}"
                )
            }
            CodegenError::SOutOfRange { r, s } => write!(
                f,
                "s = {s} is out of range: it must satisfy r <= s <= {MAX_S} (here r = {r})"
            ),
            CodegenError::UnknownFamily(name) => {
                write!(
                    f,
                    "unknown method family '{name}' (expected ec, tc or rknc)"
                )
            }
            CodegenError::Certification { r, s } => write!(
                f,
                "could not certify the correct rounding of the r = {r}, s = {s} tables"
            ),
        }
    }
}

impl std::error::Error for CodegenError {}
