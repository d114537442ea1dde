//! Runtime of the ecr exponential collocation methods.
#![deny(missing_docs)]

mod concurrent;
pub mod error;
pub mod integrate;
pub mod operator;
pub mod phi;
pub mod second_order;
pub mod stepper;
mod storage;
pub mod system;
pub mod tables;

pub use error::{Error, Result};
/// The linear-algebra crate of the public signatures (`DMatrix`, `SMatrix`), re-exported so
/// that users need not pin a matching version.
pub use nalgebra;

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
/// Misuse does not compile:
///
/// ```compile_fail
/// ecr_runtime::ecr_method!(r = 3, s = 2); // s must be >= r
/// ```
pub use ecr_macros::ecr_method;
