//! The ECrP stepper (paper eq. `PEEPCr`; `docs/method.md#ecrp`) for any r and s ≥ r.
//!
//! The moment form of the method (`docs/method.md#moment-form`) uses the moments
//! `G_k = Σ_j w_kj g(Y_j)` and the φ-functions.
//! The stepper evaluates the same method regrouped by Legendre degree, which is well-conditioned
//! for every r (the w-form loses `log₁₀ max|w_kj|` digits: 7 at r = 8, 13 at r = 12):
//!
//! ```text
//! L_j = Σ_i ℓ_ji g(Y_i),   ℓ_ji = b_i P̃_j(c_i),                         j = 0..r−1
//! Y_i = e^{cᵢhA} y₀ + h cᵢ Σ_j (2j+1) Ψ_j(cᵢ, hA) L_j,     i = 1..s   (fixed-point sweeps)
//! y₁  = e^{hA} y₀  + h Σ_j (2j+1) Ψ_j(1, hA) L_j
//! ```
//!
//! with the kernels `Ψ_j(τ, Z) = Σ_{k≤j} c_jk τ^k φ_{k+1}(τZ) = ∫₀¹ e^{(1−ξ)τZ} P̃_j(τξ) dξ`
//! computed directly ([`LegendreKernels`](crate::phi::LegendreKernels)): `G_k = Σ_j (2j+1) c_jk
//! L_j` turns one form into the other exactly.
//!
//! The kernel bank for the nodes and τ = 1 is built once per step size; a step allocates nothing.
//!
//! Small dense systems fuse each sweep: with the stage matrices `M_ik = h cᵢ Σ_j (2j+1)
//! ℓ_jk Ψ_j(cᵢ, hA)` ([`stage_matrices`], built with the bank) a sweep is `Y_i = e^{cᵢhA} y₀ +
//! Σ_k M_ik g(Y_k)`, `s²d²` multiply-adds with `e^{cᵢhA} y₀` formed once per step, instead of the
//! moments and a `combine` (`rsd + s(r+1)d²`); [`fuses_stages`] decides. The fused matrices
//! are bounded sums of bounded terms: no cancellation for any r. The rest of such a step is
//! dense maps too ([`FusedMaps`]: the propagated starts, the predictor, the end of the step),
//! each applied by one register-blocked matrix–vector product ([`gemv_cm`]) whose order of
//! operations does not depend on what the compiler knows of the sizes: the run-time stepper,
//! with its sizes known at run time only, rounds as the fixed-size one and costs about as much
//! (Duffing ω = 20, r = 6: 1.07–1.15×, `cargo bench --bench steppers`), where a `combine` of
//! the dense bank per node and generic loops made it 4× slower.
//!
//! The stage iteration stops by the rule of [`sweeps_converged`], or once the stage error
//! left cannot reach y₁ ([`y1_converged`]), starting from the previous step's continuous
//! solution extrapolated ([`Predictor::Extrapolate`], the default).
//!
//! Long runs: where the bank carries the propagator beyond f64
//! ([`PhiBank::propagate_dd`](crate::operator::PhiBank::propagate_dd): every operator kind, dense
//! and symmetric ones up to `DD_PROPAGATOR_MAX_DIM`), the new state is `e^{hA} y₀` in double-double
//! plus the nonlinear part plus `e^{hA} c`, where `c` is the rounding error of the previous state
//! (compensated summation; valid while the caller passes back the state the last step returned). An
//! f64 propagator and an f64 state rounded the same way every period of an oscillation make the
//! energy drift linearly (Duffing, r = 3, h = 0.01: 7.5e−17 per step); with both carried it is
//! 6e−23 per step over 1e7 steps.
//!
//! One algorithm, [`Stepper`], serves every form of the method. What varies is the
//! [`Kernel`] (r, s, the nodes, and the moment accumulation L = ℓ g: looped over run-time
//! coefficients in [`RuntimeKernel`], unrolled over `const` coefficients in the kernels that
//! `ecr_method!` emits) and the [`Buffers`] holding the stage state ([`VecBuffers`], allocated
//! once; [`StaticBuffers`], fixed-size arrays: what a step hands on inside the stepper, the
//! stage state local to each step, so that it stays in registers). [`EcStepper`] is the
//! run-time-r form; [`SizedEcStepper`] is that form on fixed-size buffers where d = 2 and
//! s = r ≤ 8, on heap buffers otherwise.
//!
//! The files of this folder, in the order of a step's data flow: the [`SolverSettings`] and
//! the [`StepReport`] (`settings.rs`); the method's kernel and the combine coefficients
//! (`kernel.rs`); the stage buffers (`buffers.rs`); the stopping rules and faults
//! (`stopping.rs`); the fused maps and their matrix–vector product (`fused.rs`, `gemv.rs`);
//! the concurrent path's state (`parallel.rs`); what a step works with (`context.rs`), where
//! the iteration starts (`predictor.rs`), the sweeps (`iteration.rs`) with Newton's update
//! (`newton.rs`) and the step formula (`finish.rs`); and the [`Stepper`] that calls them in
//! that order (`step.rs`); [`SizedEcStepper`], which picks the buffers (`sized.rs`).

mod buffers;
mod cache;
mod context;
mod finish;
mod fused;
mod gemv;
mod iteration;
mod kernel;
mod memory;
mod newton;
mod parallel;
mod predictor;
mod settings;
mod sized;
mod step;
mod stopping;

pub use buffers::{BufferParts, Buffers, StaticBuffers, VecBuffers};
pub(crate) use cache::{BankCache, CACHE_BUDGET};
pub use fused::{FUSED_MAX_ENTRIES, FusedMaps, fuses_stages, stage_matrices};
pub use gemv::gemv_cm;
pub use kernel::{FixedKernel, Kernel, RuntimeKernel};
pub use memory::{StepperBytes, ec_stepper_bytes};
pub use newton::NEWTON_REFRESH_THETA;
pub use settings::{
    PARALLEL_MIN_DIM, Predictor, SolverSettings, StageScale, StageSolver, StepReport, SweepLimit,
};
pub use sized::SizedEcStepper;
pub use step::{EcStepper, Stepper};
pub use stopping::{
    ROUNDOFF_RESIDUAL, STAGNATION_THETA, Y1_SHARE, stages_fault, sweeps_converged,
    sweeps_converged_scaled, y1_converged,
};
