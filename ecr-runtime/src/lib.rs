//! Runtime of the ecr exponential collocation methods.
#![deny(missing_docs)]

pub mod baselines;
mod concurrent;
pub mod error;
pub mod integrate;
pub mod operator;
pub mod phi;
pub mod problems;
pub mod second_order;
pub mod solve;
pub mod special;
pub mod stepper;
mod storage;
pub mod system;
pub mod tables;

pub use error::{Error, Result};
/// The linear-algebra crate of the public signatures (`DMatrix`, `SMatrix`), re-exported so
/// that users need not pin a matching version.
pub use nalgebra;

/// What a program that solves a problem needs, in one import: `use ecr_runtime::prelude::*;`.
pub mod prelude {
    pub use crate::ecr_method;
    pub use crate::nalgebra::{DMatrix, DVector, SMatrix};
    pub use crate::operator::{Dense, DenseStatic, Diagonal, LinearOperator, Scalar, Symmetric};
    pub use crate::second_order::{Omega, SecondOrder, SecondOrderForm, SecondOrderSystem};
    pub use crate::solve::{
        Direction, Event, Method, Options, Problem, Solution, Status, linspace,
    };
    pub use crate::stepper::{EcStepper, SolverSettings};
    pub use crate::system::{GradientFlow, Hamiltonian, Semilinear, System};
    pub use crate::{Error, Result};
}

// Lets code emitted by `ecr_method!` name this crate `::ecr_runtime` from inside it too.
extern crate self as ecr_runtime;

/// Emits a fixed-order ECrP stepper with exact compile-time coefficients and unrolled loops.
///
/// `ecr_method!(r = 3)` defines, in the calling module:
/// - `Ec3Kernel`: a unit type with the method's constants (`R`, `S`, `NODES`, `WEIGHTS`,
///   `LW`, each the correctly rounded value of an exactly generated quantity, provenance in its
///   doc) implementing [`stepper::Kernel`] with the Legendre moment sum L = ℓ g and the stage
///   loop unrolled;
/// - `Ec3<Sys, const D: usize>`: the stepper for dimension `D` known at compile time, stage
///   state in fixed-size arrays ([`stepper::StaticBuffers`]);
/// - `Ec3Dyn<Sys>`: the stepper for a dimension known at run time, stage state allocated once
///   ([`stepper::VecBuffers`]).
///
/// Both are [`stepper::Stepper`]s: the same [`system::System`] works with them and with the
/// run-time-r [`stepper::EcStepper`], and they compute bit for bit the same steps.
///
/// With `family = tc` (TCrP, for `q'' + Ωq = −∇U(q)`) or `family = rknc` (RKNCrP, Ω = 0) the
/// kernel is the same and the steppers are [`second_order::TcStepper`]s, i.e. the same ECrP
/// stepper on the first-order form of a [`second_order::SecondOrderSystem`]: `Tc3<Sys, const
/// N: usize>` for `N` positions known at compile time (state (q, p) in fixed-size arrays) and
/// `Tc3Dyn<Sys>`, bit for bit equal to the run-time [`second_order::TcStepper`].
///
/// Options (comma-separated, any order): `s = S` (Gauss–Legendre points, default r),
/// `name = MyStepper` (default `Ec{r}`, `Tc{r}` or `Rknc{r}`, with `S{s}` appended when s ≠
/// r; the kernel and dynamic types are `MyStepperKernel`, `MyStepperDyn`), `family = ec | tc
/// | rknc`, `runtime = path` (where `ecr_runtime` is, if neither it nor `ecr` is a direct
/// dependency), and a leading visibility (`pub`, `pub(crate)`). Every misuse is a compile
/// error at the offending token.
///
/// ```
/// use ecr_runtime::ecr_method;
/// use ecr_runtime::operator::DenseStatic;
/// use ecr_runtime::system::Semilinear;
/// use nalgebra::SMatrix;
///
/// ecr_method!(r = 3);
///
/// // Duffing: q'' = −(ω² + k²) q + 2k² q³ as y' = Ay + g(y), y = (q, p).
/// let (omega, k) = (5.0_f64, 0.07_f64);
/// let a = SMatrix::<f64, 2, 2>::new(0.0, 1.0, -(omega * omega + k * k), 0.0);
/// let g = move |y: &[f64], out: &mut [f64]| {
///     out[0] = 0.0;
///     out[1] = 2.0 * k * k * y[0].powi(3);
/// };
/// let system = Semilinear::new(DenseStatic::new(a).unwrap(), g);
/// let mut stepper: Ec3<_, 2> = Ec3::fixed(system, 0.01).unwrap();
/// let mut y = [0.0, omega];
/// for _ in 0..100 {
///     stepper.step(&mut y).unwrap();
/// }
/// // Order 6: at t = 1 the error against the exact q = sn(ωt; m = (k/ω)²) is ~1e-13.
/// let exact = ecr_runtime::problems::Duffing::new(omega, k).unwrap().exact(1.0).unwrap();
/// assert!((y[0] - exact[0]).abs() < 1e-11 && (y[1] - exact[1]).abs() < 1e-10);
/// assert_eq!(Ec3Kernel::R, 3);
/// ```
///
/// Misuse does not compile:
///
/// ```compile_fail
/// ecr_runtime::ecr_method!(r = 3, s = 2); // s must be >= r
/// ```
pub use ecr_macros::ecr_method;
