//! Procedural macros of ecr: `ecr_method!` emits a fixed-order exponential collocation stepper
//! (ECrP, or TCrP/RKNCrP with `family = tc | rknc`) whose coefficients were generated exactly
//! while the calling crate compiles (by `ecr-codegen`, correctly rounded to `f64`) and whose
//! moment and stage loops are unrolled.
//!
//! Use it through `ecr_runtime::ecr_method` (or `ecr::ecr_method`), where it is documented in
//! full with examples: that path is the one a program writes, and the emitted code calls into
//! `ecr-runtime`, which this crate does not depend on. The method itself is described in the
//! repository's `docs/method.md`; the data flow from the generator to the stepper in
//! `docs/architecture.md`.
//!
//! # Quick start
//!
//! (Not compiled here: the emitted code calls `ecr-runtime`, which depends on this crate, so
//! this crate cannot have it as a dev-dependency. The same program is compiled and run by
//! `tests/it/macro_quick_start.rs` at the top of the workspace.)
//!
//! ```ignore
//! use ecr_runtime::ecr_method;
//! use ecr_runtime::nalgebra::SMatrix;
//! use ecr_runtime::operator::DenseStatic;
//! use ecr_runtime::system::Semilinear;
//!
//! // EC2P: order 4, two Gauss–Legendre nodes. Emits `Ec2Kernel`, `Ec2<Sys, D>`, `Ec2Dyn<Sys>`.
//! ecr_method!(r = 2);
//!
//! // The harmonic oscillator y' = Ay, A = [[0, 1], [−1, 0]], and g = 0: ECrP integrates
//! // y' = Ay exactly, so after one period (2π) the state is back at y₀ up to round-off.
//! let a = SMatrix::<f64, 2, 2>::new(0.0, 1.0, -1.0, 0.0);
//! let system = Semilinear::new(DenseStatic::new(a).unwrap(), |_: &[f64], g: &mut [f64]| {
//!     g.fill(0.0)
//! });
//! let n = 64;
//! let mut stepper: Ec2<_, 2> = Ec2::fixed(system, std::f64::consts::TAU / n as f64).unwrap();
//! let mut y = [1.0, 0.0];
//! for _ in 0..n {
//!     stepper.step(&mut y).unwrap();
//! }
//! assert!((y[0] - 1.0).abs() < 1e-13 && y[1].abs() < 1e-13);
//! // The constants are the correctly rounded Gauss–Legendre nodes 1/2 ∓ √3/6.
//! assert_eq!(Ec2Kernel::NODES, [0.2113248654051871, 0.7886751345948129]);
//! ```
//!
//! Every misuse (a missing or bad `r`, `s < r`, an unknown key or family, a duplicate key) is
//! a compile error on the offending token; the cases are the trybuild tests of the workspace's
//! `downstream` crate (`downstream/tests/ui`).
#![deny(missing_docs)]

mod args;
mod expand;

use proc_macro::TokenStream;

/// Emits a fixed-order stepper: `ecr_method!(r = 3)` defines `Ec3Kernel` (the constants and
/// unrolled loops), `Ec3<Sys, const D: usize>` (static dimension) and `Ec3Dyn<Sys>` (dimension
/// at run time), the latter two newtypes around the runtime's `Stepper` (constructors `fixed`
/// and `with_settings`, `Deref` to the stepper, `Integrator`). Options: `s = S` (Gauss points,
/// default r), `name = Ident`, `family = ec | tc | rknc` (TCrP/RKNCrP: `Tc3<Sys, const N:
/// usize>`, `Tc3Dyn<Sys>` around `TcStepper`, for q'' + Ωq = −∇U(q); both families work),
/// `runtime = path`, and a leading visibility (`pub`, `pub(crate)`). See
/// `ecr_runtime::ecr_method` for the full documentation and examples.
#[proc_macro]
pub fn ecr_method(input: TokenStream) -> TokenStream {
    let args = syn::parse_macro_input!(input as args::MethodArgs);
    expand::expand(&args)
        .unwrap_or_else(syn::Error::into_compile_error)
        .into()
}
