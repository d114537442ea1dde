//! The method in a chosen precision: [`GenericStepper`] runs ECrP in any [`Real`] scalar, `f64`
//! or [`DoubleDouble`] (about 106 significant bits, 32 decimal digits).
//!
//! In `f64` the method's order 2r cannot be seen beyond r ≈ 4: the error reaches the `f64` floor
//! (≈ 1e−15) before the step is small enough for the asymptotic rate. In double-double the floor
//! is about 1e−30, and the orders of r = 1..8 are measured (`docs/method.md#measured-orders`).
//! Users who need reference solutions, or energy-drift studies below 1e−16 per step, run the
//! same system here:
//!
//! ```
//! use ecr_runtime::precision::{DoubleDouble, GenericStepper, GenericSystem, LinearPart, Real};
//!
//! /// q'' = −q − q³ as y = (q, p): A = [[0, 1], [−1, 0]], g = (0, −q³).
//! struct Cubic;
//! impl<S: Real> GenericSystem<S> for Cubic {
//!     fn dim(&self) -> usize { 2 }
//!     fn linear_part(&self) -> LinearPart<S> {
//!         let (o, z) = (S::one(), S::zero());
//!         LinearPart::Dense { dim: 2, entries: vec![z, o, -o, z] }
//!     }
//!     fn nonlinear(&self, y: &[S], out: &mut [S]) {
//!         out[0] = S::zero();
//!         out[1] = -(y[0] * y[0] * y[0]);
//!     }
//!     fn energy(&self, y: &[S]) -> Option<S> {
//!         let half = S::from_f64(0.5);
//!         let q2 = y[0] * y[0];
//!         Some(half * (y[1] * y[1] + q2) + S::from_f64(0.25) * q2 * q2)
//!     }
//! }
//!
//! let h = DoubleDouble::from(1.0) / DoubleDouble::from(10.0);
//! let mut stepper = GenericStepper::new(Cubic, 8, h)?;
//! let mut y = [DoubleDouble::from(1.0), DoubleDouble::from(0.0)];
//! let report = stepper.integrate(0.0.into(), 10.0.into(), &mut y, |_, _, _| {})?;
//! assert_eq!(report.steps, 100);
//! // ECrP nearly preserves H: here to 2.2e−26 relative (EC8P, h = 0.1), below f64's reach.
//! assert!(report.max_energy_error.unwrap() < 1e-25);
//! println!("q(10) = {}", y[0]); // 34 significant digits
//! # Ok::<(), ecr_runtime::Error>(())
//! ```
//!
//! The coefficients are the correctly rounded double-doubles of the exact values `ecr-codegen`
//! certifies ([`GenericTables`]); the φ-functions are computed in `S` by scaling and squaring
//! for a multiple of the identity, a diagonal or a dense linear part ([`LinearPart`]).
//!
//! Why a hand-written double-double and not a crate: the crate `twofloat` 0.8.4 (the
//! maintained double-double crate) measured, on 2000 random operands in [−2, 2] against
//! 320-bit references, relative errors of 1.1e−16 for division, 1.6e−11 for `exp`, 2e−14 for
//! `ln` and absolute 1.6e−21 for `sin`, where this one has 1.3e−32 (division), 2e−31 (`exp`)
//! and 1e−31 (`cos`, `sin`); their multiply–add costs the same within 10 %
//! (`cargo test --release -p ecr-runtime --test it double_double_crates:: -- --ignored --nocapture`).

mod kernels;
mod real;
mod stepper;
mod system;
mod tables;

pub use crate::double_double::DoubleDouble;
pub use real::Real;
pub use stepper::{GENERIC_MAX_SWEEPS, GenericReport, GenericStepper};
pub use system::{GenericSystem, LinearPart};
pub use tables::GenericTables;
