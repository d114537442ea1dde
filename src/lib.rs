//! ecr: exponential collocation methods — energy-preserving exponential integrators of any
//! order 2r for y' = Q∇H(y) (facade over `ecr-codegen`, `ecr-runtime` and `ecr-macros`).
//!
//! # Quick start: to a tolerance
//!
//! A problem (system, y₀, time span), solved to a tolerance; the solution owns its data
//! ([`guide::solve`] says how the order and the step are chosen):
//!
//! ```
//! use ecr::prelude::*;
//!
//! // H(q, p) = ½p² + ½q² + ¼q⁴, y = (q, p); ∇V is written into zeros.
//! let grad_v = |y: &[f64], g: &mut [f64]| g[0] = y[0].powi(3);
//! let system = Hamiltonian::canonical(DMatrix::identity(2, 2), grad_v)?
//!     .potential(|y| 0.25 * y[0].powi(4));
//! let options = Options::tolerance(1e-8).t_eval(linspace(0.0, 20.0, 5));
//! let sol = Problem::new(system, [1.0, 0.0], (0.0, 20.0))?.solve(&options)?;
//! assert_eq!(sol.t, [0.0, 5.0, 10.0, 15.0, 20.0]);
//! println!("y(20) = {:?}, order {}, h = {}", sol.y[4], 2 * sol.r, sol.h);
//! assert!(sol.energy_error().unwrap() < 1e-8);
//! # Ok::<(), ecr::runtime::Error>(())
//! ```
//!
//! Pick the linear part's structure: the prelude has every operator (`Zero`, `Scalar`,
//! `Diagonal`, `Dense`, `Symmetric`, `Circulant`, `Circulant2d`, `SkewPair`, `Oscillator`),
//! and each pays only for its structure: a periodic Laplacian as a `Circulant` costs
//! O(d log d) per application where a dense `Symmetric` costs O(d²). The repository's
//! `examples/` show which tool fits which problem (`kepler.rs`: a tolerance instead of a
//! fixed step at e = 0.99; `allen_cahn.rs`: `Circulant` against a dense operator).
//!
//! # Quick start: a fixed-order stepper in your own loop
//!
//! [`ecr_method!`] emits a stepper with exact compile-time coefficients and sizes, bit for
//! bit the steps of the run-time `EcStepper`:
//!
//! ```
//! use ecr::prelude::*;
//!
//! ecr_method!(r = 3); // EC3P (order 6): Ec3<Sys, D>, Ec3Dyn<Sys>
//!
//! // Duffing: q'' = −(ω² + k²)q + 2k²q³ as y' = Ay + g(y), y = (q, p), with the energy
//! // H = ½p² + ½(ω² + k²)q² − ½k²q⁴.
//! let (omega, k) = (5.0_f64, 0.07_f64);
//! let w2 = omega * omega + k * k;
//! let a = DenseStatic::new(SMatrix::<f64, 2, 2>::new(0.0, 1.0, -w2, 0.0))?;
//! let g = move |y: &[f64], out: &mut [f64]| (out[0], out[1]) = (0.0, 2.0 * k * k * y[0].powi(3));
//! let energy = |y: &[f64]| 0.5 * y[1] * y[1] + 0.5 * w2 * y[0] * y[0] - 0.5 * k * k * y[0].powi(4);
//! let mut stepper: Ec3<_, 2> = Ec3::fixed(Semilinear::new(a, g), 0.01)?;
//! let mut y = [0.0, omega];
//! for _ in 0..100 {
//!     stepper.step(&mut y)?; // in place, no allocation
//! }
//! // H = 12.5 kept to a few ulps (5e-15 here); 1e-12 leaves room for other platforms' libm.
//! assert!((energy(&y) - energy(&[0.0, omega])).abs() < 1e-12);
//! # Ok::<(), ecr::runtime::Error>(())
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
//! - `cli` (default): the `ecr` command (`reproduce`, `run`, `bench`, `tables`, `ensemble`);
//!   implies `baselines`.
//! - `mpi`: ensembles over the ranks of MPI (`ecr::mpi`), with an MPI library installed.
#![deny(missing_docs)]

pub use ecr_codegen as codegen;
pub use ecr_runtime as runtime;
pub use ecr_runtime::ecr_method;
/// The linear-algebra crate of the public signatures, so that users need not pin a version.
pub use ecr_runtime::nalgebra;
/// Everything a program that solves a problem needs: `use ecr::prelude::*;`.
pub use ecr_runtime::prelude;
pub use ecr_runtime::solve::{Options, Problem, Solution};

#[cfg(feature = "mpi")]
pub mod mpi;

/// The repository's guides (`docs/*.md`) as pages of this documentation: the same text.
///
/// Their Rust blocks, and the README's, are whole programs: the `downstream` crate's tests
/// compile them verbatim as a user's crate that depends on `ecr` without default features, and
/// run them; the programs the guides describe are written out and checked there too.
#[cfg(not(doctest))]
#[allow(clippy::doc_lazy_continuation, clippy::doc_overindented_list_items)]
#[allow(
    rustdoc::broken_intra_doc_links,
    rustdoc::invalid_html_tags,
    rustdoc::bare_urls,
    rustdoc::invalid_rust_codeblocks
)]
pub mod guide {
    #[doc = include_str!("../docs/method.md")]
    pub mod method {}
    #[doc = include_str!("../docs/solve.md")]
    pub mod solve {}
    #[doc = include_str!("../docs/ensembles.md")]
    pub mod ensembles {}
    #[doc = include_str!("../docs/errata.md")]
    pub mod errata {}
    #[doc = include_str!("../docs/architecture.md")]
    pub mod architecture {}
    #[doc = include_str!("../docs/cli.md")]
    pub mod cli {}
    #[doc = include_str!("../docs/performance.md")]
    pub mod performance {}
}

#[cfg(feature = "baselines")]
pub mod baselines;
#[cfg(feature = "problems")]
pub mod exact;
#[cfg(feature = "problems")]
pub mod problems;
#[cfg(feature = "problems")]
pub mod special;
