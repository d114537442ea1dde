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
pub mod special;
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
