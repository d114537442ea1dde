//! Exact coefficient generator for exponential collocation methods (ECrP, TCrP, RKNCrP).
//!
//! Given a family, the order parameter r (order 2r) and s ≥ r quadrature points,
//! [`MethodTable::generate`] computes everything a stepper needs: the Gauss–Legendre nodes cᵢ
//! and weights bᵢ on [0, 1], the Legendre moment weights ℓ_kj = bⱼ P̃_k(cⱼ) that the ECrP
//! stepper uses, the moment weights w_kj = bⱼ β_k(cⱼ) of the φ-form, and for RKNCrP the RKN
//! tableau ā, b̄. The mathematics is written out in the repository's `docs/method.md`
//! (sections "ECrP" and "The coefficients: exact until rounded once").
//!
//! What is exact:
//!
//! - **Rational data is kept as rationals** ([`Rat`], `num-rational`): the shifted Legendre
//!   polynomials P̃ⱼ, the coefficients c_jk, the moment polynomials β_k, the node polynomial
//!   P̃ₛ, and (in [`kernels`]) the Taylor and Padé coefficients of φ_k and the power series of
//!   the method's kernels, each also computed from the paper's closed form and from its
//!   defining integral so that the tests can compare them exactly.
//! - **Irrational data is enclosed**: each node is a root of an integer polynomial, isolated
//!   by exact sign evaluation and narrowed to a dyadic interval; weights and moment weights
//!   follow by interval arithmetic ([`Interval`]). Every enclosure is narrower than 10⁻⁶⁰
//!   relative.
//! - **Every `f64` is rounded once, correctly**: a value is only emitted when both ends of its
//!   enclosure round to the same double ([`Certified`]), so it is the correctly rounded exact
//!   value, with 40 exact digits beside it as provenance.
//!
//! The library is pure and deterministic (no I/O): the same request gives the same bits
//! everywhere. `ecr-runtime/build.rs` renders its tables as Rust source
//! ([`render::RustSource`]), `ecr_method!` as tokens (feature `tokens`), and the `ecr tables`
//! command as JSON (feature `json`) or Markdown ([`render::Markdown`]). r ≤ [`MAX_R`] = 32,
//! s ≤ [`MAX_S`] = 64.
//!
//! # Quick start
//!
//! ```
//! use ecr_codegen::render::RustSource;
//! use ecr_codegen::{Family, MethodTable, Rat};
//!
//! // EC3P: r = 3 (order 6), s = 3 Gauss–Legendre points.
//! let t = MethodTable::generate(Family::Ec, 3, 3).unwrap();
//!
//! // Exact: P̃₂(x) = 1 − 6x + 6x², and the nodes are the roots of P̃₃.
//! let int = |n: i64| Rat::from_integer(n.into());
//! assert_eq!(t.legendre[2].coeffs(), [int(1), int(-6), int(6)]);
//! assert_eq!(t.node_polynomial.eval(&Rat::new(1.into(), 2.into())), int(0)); // c₂ = 1/2
//!
//! // Certified: c₁ = 1/2 − √15/10, correctly rounded, its exact digits kept beside it.
//! assert_eq!(t.nodes[0].value, 0.11270166537925831);
//! assert!(t.nodes[0].decimal(40).starts_with("0.11270166537925831148207346002176"));
//! assert_eq!(t.weights_f64(), [5.0 / 18.0, 4.0 / 9.0, 5.0 / 18.0]);
//!
//! // Rendered for a build script: `const` arrays with provenance comments.
//! let source = RustSource(&t).to_string();
//! assert!(source.contains("0.11270166537925831_f64, // c_1 = 0.112701665379258311482073460021"));
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
