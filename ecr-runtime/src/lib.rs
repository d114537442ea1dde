//! Runtime of the ecr exponential collocation methods: energy-preserving exponential
//! integrators of any order 2r for `y' = Q∇H(y)`, `H(y) = ½yᵀMy + V(y)`, after B. Wang and
//! X. Wu, *Exponential collocation methods for conservative or dissipative systems*.
//!
//! A program states its system as `y' = Ay + g(y)` — the linear part A as a structured
//! operator (zero, scalar, diagonal, dense, symmetric, circulant by FFT, …), g as a function —
//! and steps it with ECrP: the linear part is integrated exactly, g through r Legendre moments
//! at s ≥ r Gauss–Legendre nodes, and H is preserved up to O(h^{2r}) (or decreases, for a
//! dissipative Q) without drift over long runs. Second-order systems `q'' + Ωq = −∇U(q)` use
//! the same stepper as TCrP (RKNCrP for Ω = 0).
//!
//! # Quick start: to a tolerance
//!
//! [`solve`] chooses the order and the step size for a tolerance and returns the solution at
//! the times asked for (`use ecr_runtime::prelude::*` brings what it needs into scope):
//!
//! ```
//! use ecr_runtime::prelude::*;
//!
//! // H(q, p) = ½p² + ½q² + ¼q⁴, y = (q, p); ∇V is written into zeros.
//! let grad_v = |y: &[f64], g: &mut [f64]| g[0] = y[0].powi(3);
//! let system = Hamiltonian::canonical(DMatrix::identity(2, 2), grad_v)?
//!     .potential(|y| 0.25 * y[0].powi(4));
//! let problem = Problem::new(system, [1.0, 0.0], (0.0, 20.0))?;
//! let sol = problem.solve(&Options::tolerance(1e-10).t_eval(linspace(0.0, 20.0, 5)))?;
//! assert_eq!(sol.t, [0.0, 5.0, 10.0, 15.0, 20.0]);
//! assert!(sol.energy_error().unwrap() < 1e-10);
//! # Ok::<(), ecr_runtime::Error>(())
//! ```
//!
//! # Quick start: a fixed-order stepper
//!
//! [`ecr_method!`](crate::ecr_method) emits a stepper with exact compile-time coefficients
//! and sizes (`ecr_method!(r = 3)`: `Ec3<Sys, D>`, EC3P of order 6), bit for bit the steps of
//! the run-time [`stepper::EcStepper`]:
//!
//! ```
//! use ecr_runtime::prelude::*;
//!
//! ecr_method!(r = 3);
//!
//! // q'' = −100q − q³ as y' = Ay + g(y), y = (q, p), H = ½p² + 50q² + ¼q⁴.
//! let a = DenseStatic::new(SMatrix::<f64, 2, 2>::new(0.0, 1.0, -100.0, 0.0))?;
//! let g = |y: &[f64], out: &mut [f64]| (out[0], out[1]) = (0.0, -y[0].powi(3));
//! let energy = |y: &[f64]| 0.5 * y[1] * y[1] + 50.0 * y[0] * y[0] + 0.25 * y[0].powi(4);
//! let mut stepper: Ec3<_, 2> = Ec3::fixed(Semilinear::new(a, g), 0.01)?;
//! let mut y = [1.0, 0.0];
//! for _ in 0..1000 {
//!     stepper.step(&mut y)?; // in place, no allocation
//! }
//! // H = 50.25 kept over 1000 steps of hω = 0.1: relative error 2.5e−13 here; 1e−12 leaves
//! // room for other platforms' libm.
//! assert!((energy(&y) - 50.25).abs() < 1e-12 * 50.25);
//! # Ok::<(), ecr_runtime::Error>(())
//! ```
//!
//! # Your own system in your own loop
//!
//! A system of your own, `q'' + ω²q = −q³` with `y = (q, p)`, `A = [[0, 1], [−ω², 0]]`,
//! `g(y) = (0, −q³)` and the energy `H = p²/2 + ω²q²/2 + q⁴/4`, stepped with EC3P (order 6):
//!
//! ```
//! use ecr_runtime::nalgebra::SMatrix;
//! use ecr_runtime::operator::DenseStatic;
//! use ecr_runtime::stepper::EcStepper;
//! use ecr_runtime::system::System;
//!
//! struct Cubic {
//!     a: DenseStatic<2>,
//!     omega: f64,
//! }
//!
//! impl System for Cubic {
//!     type Op = DenseStatic<2>;
//!     fn linear(&self) -> &DenseStatic<2> {
//!         &self.a
//!     }
//!     fn nonlinear(&self, y: &[f64], g: &mut [f64], _scratch: &mut [f64]) {
//!         g[0] = 0.0;
//!         g[1] = -y[0].powi(3);
//!     }
//!     fn energy(&self, y: &[f64]) -> Option<f64> {
//!         let (q, p) = (y[0], y[1]);
//!         Some(0.5 * p * p + 0.5 * self.omega * self.omega * q * q + 0.25 * q.powi(4))
//!     }
//! }
//!
//! # fn main() -> ecr_runtime::Result<()> {
//! let omega = 10.0;
//! let a = SMatrix::<f64, 2, 2>::new(0.0, 1.0, -omega * omega, 0.0);
//! let run = |h: f64, steps: usize| -> ecr_runtime::Result<([f64; 2], f64)> {
//!     let system = Cubic { a: DenseStatic::new(a)?, omega };
//!     let mut stepper = EcStepper::new(system, 3, h)?; // r = 3: EC3P, s = 3 Gauss nodes
//!     let mut y = [1.0, 0.0];
//!     let h0 = stepper.system().energy(&y).unwrap();
//!     let mut max_energy_error = 0.0_f64;
//!     for _ in 0..steps {
//!         let report = stepper.step(&mut y)?; // y ← y₁, in place, no allocation
//!         assert!(report.converged);
//!         let e = stepper.system().energy(&y).unwrap();
//!         max_energy_error = max_energy_error.max((e - h0).abs() / h0);
//!     }
//!     Ok((y, max_energy_error))
//! };
//! // Up to t = 10 with hω = 0.5 and 0.25, against a run with h four times smaller again.
//! let (coarse, energy_coarse) = run(0.05, 200)?;
//! let (fine, energy_fine) = run(0.025, 400)?;
//! let (reference, _) = run(0.00625, 1600)?;
//! let error = |y: [f64; 2]| (y[0] - reference[0]).abs().max((y[1] - reference[1]).abs() / omega);
//! // Order 6: halving h divides the error by about 2⁶ (measured: 3.1e−8 → 4.9e−10, 62.9×).
//! let ratio = error(coarse) / error(fine);
//! assert!((48.0..80.0).contains(&ratio), "{ratio}");
//! // H is nearly preserved: relative error 4.7e−8 at hω = 0.5, 6.6e−10 at hω = 0.25.
//! assert!(energy_coarse < 1e-7 && energy_fine < 1e-9);
//! # Ok(())
//! # }
//! ```
//!
//! Fixed-order steppers with compile-time coefficients and sizes come from
//! [`ecr_method!`](crate::ecr_method) (`ecr_method!(r = 3)` emits `Ec3<Sys, D>`), bit for bit
//! the steps of [`stepper::EcStepper`]; [`integrate::integrate`] drives any stepper over
//! [t₀, T] with an observer and a report.
//!
//! # Modules
//!
//! - [`system`]: the [`System`](system::System) trait (`y' = Ay + g(y)`, optionally H and the
//!   Jacobian of g) and ready-made systems: [`Semilinear`](system::Semilinear) (an operator
//!   and closures), [`Hamiltonian`](system::Hamiltonian) (A = QM, g = Q∇V),
//!   [`GradientFlow`](system::GradientFlow) (A = −M, g = −∇V).
//! - [`operator`]: linear operators A and their banks of φ-functions and Legendre kernels,
//!   built once per step size: `Zero`, `Scalar`, `Diagonal`, `Dense`, `DenseStatic`,
//!   `Symmetric`, `Circulant`, `Circulant2d`, `SkewPair`, `Oscillator`; each pays only for its
//!   structure.
//! - [`stepper`]: the ECrP stepper [`Stepper`](stepper::Stepper) for any r and s ≥ r
//!   ([`EcStepper`](stepper::EcStepper) with r and s chosen at run time;
//!   [`SizedEcStepper`](stepper::SizedEcStepper), the same on fixed-size buffers for planar
//!   systems with s = r ≤ 8), its
//!   [`SolverSettings`](stepper::SolverSettings) (tolerance, predictor, fixed point or Newton,
//!   compensated update) and [`StepReport`](stepper::StepReport).
//! - [`second_order`]: `q'' + Ωq = −∇U(q)` ([`SecondOrder`](second_order::SecondOrder),
//!   [`Omega`](second_order::Omega)) and TCrP/RKNCrP as
//!   [`TcStepper`](second_order::TcStepper).
//! - [`integrate`]: the fixed-step driver [`integrate`](integrate::integrate) and the
//!   [`Integrator`](integrate::Integrator) trait that every stepper implements.
//! - [`phi`]: φ-functions of scalars and matrices, the trigonometric φᵗ, the Legendre kernels.
//! - [`tables`]: the coefficient tables (built in by `build.rs` for r up to `ECR_MAX_R`,
//!   default 8; generated and cached for other r ≤ 32).
//! - [`error`]: [`Error`] and [`Result`]; [`storage`]: large allocations checked before they
//!   are made (an error naming the size, not an abort).
//! - [`solve`]: [`Problem`](solve::Problem) → [`solve`](solve::Problem::solve) →
//!   [`Solution`](solve::Solution): a tolerance (or a fixed r and h), output times, events,
//!   observers, the continuous solution.
//! - [`ensemble`]: many trajectories, an [`Ensemble`](ensemble::Ensemble) of problems made
//!   from a template and solved on every core, each member's result as the user's output
//!   function maps it, or its own error; in member order, bit for bit the same with any
//!   number of threads.
//! - [`prelude`]: the names a program that solves a problem uses.
//!
//! The paper's test problems, the methods it compares with and the elliptic functions of the
//! exact Duffing solution are in the `ecr` crate (`ecr::problems`, `ecr::baselines`,
//! `ecr::special`, behind its features), not here.
//!
//! The method is written out in the repository's `docs/method.md` (stage equations, step
//! formula, stopping rule, compensated update), the paper's errata in `docs/errata.md`, and
//! the crates and data flow in `docs/architecture.md`.
#![deny(missing_docs)]

mod concurrent;
mod double_double;
pub mod ensemble;
pub mod error;
pub mod integrate;
pub mod operator;
pub mod phi;
pub mod precision;
pub mod second_order;
pub mod solve;
pub mod stepper;
pub mod storage;
pub mod system;
pub mod tables;
#[cfg(test)]
mod test_rng;

pub use error::{Error, Result};
/// The linear-algebra crate of the public signatures (`DMatrix`, `SMatrix`), re-exported so
/// that users need not pin a matching version.
pub use nalgebra;

/// What a program that solves a problem needs, in one import: `use ecr_runtime::prelude::*;`.
pub mod prelude {
    pub use crate::ecr_method;
    pub use crate::ensemble::{Control, Ensemble, EnsembleSolution, MemberError, MemberResult};
    pub use crate::nalgebra::{DMatrix, DVector, SMatrix};
    pub use crate::operator::{
        Circulant, Circulant2d, Dense, DenseStatic, Diagonal, LinearOperator, Oscillator, Scalar,
        SkewPair, Symmetric, Zero,
    };
    pub use crate::second_order::{Omega, SecondOrder, SecondOrderForm, SecondOrderSystem};
    pub use crate::solve::{
        Direction, Event, EventHit, Method, Options, Problem, Solution, SolveError, Stats, Status,
        StepView, linspace,
    };
    pub use crate::stepper::{EcStepper, SolverSettings};
    pub use crate::system::{GradientFlow, Hamiltonian, Semilinear, System};
    pub use crate::{Error, Result};
}

// The README's example runs as a doctest.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;

// Lets code emitted by `ecr_method!` name this crate `::ecr_runtime` from inside it too.
extern crate self as ecr_runtime;

/// Emits a fixed-order ECrP, TCrP or RKNCrP stepper with exact compile-time coefficients and
/// unrolled loops.
///
/// `ecr_method!(r = 3)` defines, in the calling module:
/// - `Ec3Kernel`: a unit type with the method's constants (`R`, `S`, `NODES`, `WEIGHTS`, `W`,
///   `LW`, each the correctly rounded value of an exactly generated quantity, provenance in its
///   doc) implementing [`stepper::Kernel`] with the Legendre moment sum L = ℓ g and the stage
///   loop unrolled;
/// - `Ec3<Sys, const D: usize>`: the stepper for dimension `D` known at compile time, stage
///   state in fixed-size arrays ([`stepper::StaticBuffers`]), no heap use per step;
/// - `Ec3Dyn<Sys>`: the stepper for a dimension known at run time, stage state allocated once
///   ([`stepper::VecBuffers`]).
///
/// `Ec3` and `Ec3Dyn` are newtypes around a [`stepper::Stepper`] with that kernel, not
/// aliases of it, so that a type error names them (`Ec3<_, _>`) rather than the `Stepper`
/// behind them. Each has `fixed(system, h)` (default [`stepper::SolverSettings`]),
/// `with_settings(system, h, settings)` and `into_inner()`, converts `From` the stepper,
/// dereferences to it (`step`, `step_size`, `set_step_size`, `dense_output`, … are the
/// stepper's) and implements [`integrate::Integrator`], so [`integrate::integrate`] drives it.
/// The same [`system::System`] works with them and with the run-time-r
/// [`stepper::EcStepper`], and they compute bit for bit the same steps (the wrappers are
/// inlined forwarding calls).
///
/// With `family = tc` (TCrP, for `q'' + Ωq = −∇U(q)`) or `family = rknc` (RKNCrP, Ω = 0) the
/// kernel is the same kind and the types wrap [`second_order::TcStepper`], i.e. the same ECrP
/// stepper on the first-order form of a [`second_order::SecondOrderSystem`]: `Tc3<Sys, const
/// N: usize>` (or `Rknc3`) for `N` positions known at compile time (state (q, p) in fixed-size
/// arrays) and `Tc3Dyn<Sys>`, with the same constructors and traits, whose `step(q, p)` is bit
/// for bit that of the run-time [`second_order::TcStepper`]. With `family = rknc` the kernel
/// also carries the RKN tableau of RKNCrP (`ABAR`, `BBAR`). The method is described in
/// `docs/method.md` (sections "ECrP" and "TCrP and RKNCrP").
///
/// Options (comma-separated, any order): `s = S` (Gauss–Legendre points, default r),
/// `name = MyStepper` (default `Ec{r}`, `Tc{r}` or `Rknc{r}`, with `S{s}` appended when s ≠
/// r; the kernel and dynamic types are `MyStepperKernel`, `MyStepperDyn`), `family = ec | tc
/// | rknc`, `runtime = path` (where `ecr_runtime` is, if neither it nor `ecr` is a direct
/// dependency), and a leading visibility (`pub`, `pub(crate)`) for every emitted item. Every
/// misuse is a compile error at the offending token.
///
/// ```
/// use ecr_runtime::ecr_method;
/// use ecr_runtime::operator::{Dense, DenseStatic};
/// use ecr_runtime::stepper::EcStepper;
/// use ecr_runtime::system::Semilinear;
/// use nalgebra::{DMatrix, SMatrix};
///
/// ecr_method!(r = 3);
///
/// // Duffing: q'' = −(ω² + k²) q + 2k² q³ as y' = Ay + g(y), y = (q, p), with the energy
/// // H = ½p² + ½(ω² + k²)q² − ½k²q⁴.
/// let (omega, k) = (5.0_f64, 0.07_f64);
/// let w2 = omega * omega + k * k;
/// let a = [0.0, 1.0, -w2, 0.0]; // row by row
/// let g = move |y: &[f64], out: &mut [f64]| {
///     out[0] = 0.0;
///     out[1] = 2.0 * k * k * y[0].powi(3);
/// };
/// let energy = |y: &[f64]| {
///     0.5 * y[1] * y[1] + 0.5 * w2 * y[0] * y[0] - 0.5 * k * k * y[0].powi(4)
/// };
/// let a_static = SMatrix::<f64, 2, 2>::from_row_slice(&a);
/// let system = Semilinear::new(DenseStatic::new(a_static).unwrap(), g);
/// let mut stepper: Ec3<_, 2> = Ec3::fixed(system, 0.01).unwrap();
/// // The run-time stepper of the same order and h, on the same problem.
/// let system = Semilinear::new(Dense::new(DMatrix::from_row_slice(2, 2, &a)).unwrap(), g);
/// let mut run_time = EcStepper::new(system, 3, 0.01).unwrap();
/// let (mut y, mut z) = ([0.0, omega], vec![0.0, omega]);
/// for _ in 0..100 {
///     stepper.step(&mut y).unwrap();
///     run_time.step(&mut z).unwrap();
/// }
/// // Bit for bit the same steps as the run-time stepper, and H = 12.5 kept to a few ulps
/// // (5e-15 here; 1e-12 leaves room for other platforms' libm).
/// assert_eq!(y.map(f64::to_bits), [z[0].to_bits(), z[1].to_bits()]);
/// assert!((energy(&y) - energy(&[0.0, omega])).abs() < 1e-12);
/// assert_eq!(Ec3Kernel::R, 3);
/// ```
///
/// TCrP for a second-order system, driven by [`integrate::integrate`] through the flat state
/// (q, p):
///
/// ```
/// use ecr_runtime::ecr_method;
/// use ecr_runtime::integrate::{IntegrateOptions, integrate};
/// use ecr_runtime::second_order::{Omega, SecondOrder};
///
/// ecr_method!(r = 2, family = tc);
///
/// // q'' + 100 q = −q³ (one stiff mode), H = p²/2 + 50 q² + q⁴/4.
/// let system = SecondOrder::with_potential(
///     Omega::scalar(100.0, 1).unwrap(),
///     |q: &[f64], f: &mut [f64]| f[0] = q[0].powi(3),
///     |q: &[f64]| q[0].powi(4) / 4.0,
/// );
/// let run = |h: f64| {
///     let mut stepper: Tc2<_, 1> = Tc2::fixed(&system, h).unwrap();
///     let mut y = [1.0, 0.0]; // (q, p)
///     let options = IntegrateOptions::default();
///     integrate(&mut stepper, 0.0, 10.0, &mut y, options, |_, _, _| {}).unwrap()
/// };
/// let (coarse, fine) = (run(0.05), run(0.025));
/// assert_eq!((coarse.steps, fine.steps), (200, 400));
/// // Order 4: halving h divides the relative energy error by about 2⁴ (measured: 5.2e−6 at
/// // h = 0.05, 2.9e−7 at h = 0.025, ratio 17.7).
/// let ratio = coarse.max_energy_error.unwrap() / fine.max_energy_error.unwrap();
/// assert!(coarse.max_energy_error.unwrap() < 1e-5 && (12.0..20.0).contains(&ratio));
/// ```
///
/// Misuse does not compile:
///
/// ```compile_fail
/// ecr_runtime::ecr_method!(r = 3, s = 2); // s must be >= r
/// ```
///
/// Neither does a fixed-size stepper whose dimension cannot be inferred; the error names the
/// type written (`type annotations needed for `Ec3<…, _>``) and suggests `Ec3<_, D>`:
///
/// ```compile_fail,E0284
/// use ecr_runtime::ecr_method;
/// use ecr_runtime::operator::Zero;
/// use ecr_runtime::system::Semilinear;
///
/// ecr_method!(r = 3);
///
/// let system = Semilinear::new(Zero::new(2), |_: &[f64], out: &mut [f64]| out.fill(0.0));
/// let mut stepper = Ec3::fixed(system, 0.01).unwrap(); // needs `Ec3<_, 2>`
/// stepper.step(&mut [1.0, 0.0]).unwrap();
/// ```
pub use ecr_macros::ecr_method;
