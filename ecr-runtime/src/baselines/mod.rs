//! Baseline methods the paper compares with (DESIGN.md §5), sharing the system and operator
//! types, each an [`crate::integrate::Integrator`].
//!
//! The paper's peers: [`collocation`] (RKEPC2, HBVM, Gauss, AVF, exponential AVF),
//! [`exponential`] (EEI3s4 = exprb43, Hochbruck–Ostermann), [`krylov`], [`dop853`]. What users
//! of oscillatory Hamiltonians pick instead: [`splitting`] (kick–rotate–kick with the exact
//! linear flow and Störmer–Verlet, composed to orders 2–8) and, for NLS-type systems,
//! [`split_step`] (split-step Fourier).

pub mod collocation;
pub mod dop853;
pub mod exponential;
pub mod krylov;
pub mod split_step;
pub mod splitting;
