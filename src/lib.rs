//! ecr: exponential collocation methods — energy-preserving exponential integrators of any
//! order 2r for y' = Q∇H(y) (facade over `ecr-codegen`, `ecr-runtime` and `ecr-macros`).
//!
//! ```
//! use ecr::runtime::problems::Duffing;
//! use ecr::runtime::stepper::EcStepper;
//!
//! let p = Duffing::default();
//! let mut stepper = EcStepper::new(p.system().unwrap(), 2, 0.01).unwrap();
//! let mut y = p.initial_value();
//! for _ in 0..100 {
//!     stepper.step(&mut y).unwrap();
//! }
//! let exact = p.exact(1.0).unwrap();
//! assert!((y[0] - exact[0]).abs() < 1e-9);
//! ```
#![deny(missing_docs)]

pub use ecr_codegen as codegen;
pub use ecr_runtime as runtime;
pub use ecr_runtime::ecr_method;
/// The linear-algebra crate of the public signatures, so that users need not pin a version.
pub use ecr_runtime::nalgebra;
/// Everything a program that solves a problem needs: `use ecr::prelude::*;`.
pub use ecr_runtime::prelude;
pub use ecr_runtime::solve::{Options, Problem, Solution};

// The README's examples run as doctests.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;
