//! Baseline methods the paper compares with (`docs/architecture.md#baselines`), sharing the
//! system and operator types, each an [`ecr_runtime::integrate::Integrator`].
//!
//! The paper's peers: [`collocation`] (RKEPC2, HBVM, Gauss, AVF, exponential AVF),
//! [`exponential`] (EEI3s4 = exprb43, Hochbruck–Ostermann), [`krylov`], [`dop853`]. What users
//! of each problem class pick instead: [`splitting`] (kick–rotate–kick with the exact linear
//! flow and Störmer–Verlet, composed to orders 2–8), [`split_step`] (split-step Fourier for
//! NLS-type systems) and [`etdrk4`] (Cox–Matthews).

pub mod collocation;
pub mod dop853;
pub mod etdrk4;
pub mod exponential;
pub mod krylov;
pub mod split_step;
pub mod splitting;

use ecr_runtime::stepper::StepReport;

/// The report of an explicit step that made `g_evals` evaluations of g (no stage iteration).
pub(crate) fn explicit_step(g_evals: usize) -> StepReport {
    StepReport {
        sweeps: 0,
        residual: 0.0,
        g_evals,
        converged: true,
        jacobian_evals: 0,
        newton_refreshes: 0,
    }
}
