//! ecr: exponential collocation methods — energy-preserving exponential integrators of any
//! order 2r for y' = Q∇H(y) (facade over `ecr-codegen`, `ecr-runtime` and `ecr-macros`).
//!
//! ```
//! use ecr::runtime::nalgebra::DMatrix;
//! use ecr::runtime::operator::Dense;
//! use ecr::runtime::stepper::EcStepper;
//! use ecr::runtime::system::Semilinear;
//!
//! // The Duffing equation q'' = −(ω² + k²)q + 2k²q³ as y' = Ay + g(y), y = (q, p); its energy
//! // H = ½p² + ½(ω² + k²)q² − ½k²q⁴ is a first integral.
//! let (omega, k) = (5.0_f64, 0.07_f64);
//! let w2 = omega * omega + k * k;
//! let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -w2, 0.0]);
//! let g = move |y: &[f64], out: &mut [f64]| {
//!     out[0] = 0.0;
//!     out[1] = 2.0 * k * k * y[0].powi(3);
//! };
//! let energy = |y: &[f64]| {
//!     0.5 * y[1] * y[1] + 0.5 * w2 * y[0] * y[0] - 0.5 * k * k * y[0].powi(4)
//! };
//! // EC3P: order 6, step size 0.01.
//! let system = Semilinear::new(Dense::new(a).unwrap(), g);
//! let mut stepper = EcStepper::new(system, 3, 0.01).unwrap();
//! let mut y = vec![0.0, omega];
//! for _ in 0..100 {
//!     stepper.step(&mut y).unwrap();
//! }
//! // H = 12.5 kept to a few ulps (5e-15 here); 1e-12 leaves room for other platforms' libm.
//! assert!((energy(&y) - energy(&[0.0, omega])).abs() < 1e-12);
//! ```
//!
//! # Features
//!
//! Without features this crate is the library alone: the re-exports below.
//!
//! - `problems`: the paper's test problems (`ecr::problems`: Duffing, wind-induced oscillation,
//!   NLS in 1D and 2D, FPU) and the Jacobi elliptic functions of Duffing's exact solution
//!   (`ecr::special`).
//! - `baselines`: the peer methods of the comparisons (`ecr::baselines`; DOP853 through
//!   `ode_solvers`); implies `problems`.
//! - `cli` (default): the `ecr` command (`reproduce`, `run`, `bench`, `tables`); implies
//!   `baselines`.
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

#[cfg(feature = "baselines")]
pub mod baselines;
#[cfg(feature = "problems")]
pub mod problems;
#[cfg(feature = "problems")]
pub mod special;
