//! Baseline methods the paper compares with (DESIGN.md §5), sharing the system and operator
//! types, each an [`crate::integrate::Integrator`].

pub mod collocation;
pub mod dop853;
pub mod exponential;
pub mod krylov;
