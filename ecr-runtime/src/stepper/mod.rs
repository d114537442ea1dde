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
//! Long runs: where the bank carries the propagator beyond f64 ([`PhiBank::propagate_dd`]:
//! every operator kind, dense and symmetric ones up to `DD_PROPAGATOR_MAX_DIM`), the new
//! state is `e^{hA} y₀` in double-double plus the nonlinear part plus `e^{hA} c`, where `c` is
//! the rounding error of the previous state (compensated summation; valid while the caller
//! passes back the state the last step returned). An f64 propagator and an f64 state rounded the same way every period
//! of an oscillation make the energy drift linearly (Duffing, r = 3, h = 0.01: 7.5e−17 per
//! step); with both carried it is 6e−23 per step over 1e7 steps.
//!
//! One algorithm, [`Stepper`], serves every form of the method. What varies is the
//! [`Kernel`] (r, s, the nodes, and the moment accumulation L = ℓ g: looped over run-time
//! coefficients in [`RuntimeKernel`], unrolled over `const` coefficients in the kernels that
//! `ecr_method!` emits) and the [`Buffers`] holding the stage state ([`VecBuffers`], allocated
//! once; [`StaticBuffers`], fixed-size arrays: what a step hands on inside the stepper, the
//! stage state local to each step, so that it stays in registers). [`EcStepper`] is the
//! run-time-r form.

use crate::concurrent::for_each_chunk;
use crate::operator::{LinearOperator, PhiBank};
use crate::phi::two_sum;
use crate::storage::ensure_allocatable;
use crate::system::System;
use crate::tables::{Coefficients, coefficients};
use crate::{Error, Result};
use std::sync::Arc;

/// Scaled stage updates at or below this (100 ε) count as round-off: when the update stops
/// decreasing there, the iteration has converged as far as f64 allows.
pub const ROUNDOFF_RESIDUAL: f64 = 100.0 * f64::EPSILON;

/// Contraction estimates θ at or above this, with the update at round-off level, count as
/// stagnation: the iteration no longer makes progress.
pub const STAGNATION_THETA: f64 = 0.9;

/// The share of the stage tolerance that the estimated effect of the remaining stage error on
/// y₁ may take ([`y1_converged`]): 2⁻¹⁷, i.e. 7.6e−21 relative with the default tolerance.
/// A stage error that the predictor leaves with the same sign every step reaches y₁ the same
/// way every step, so this bounds a drift per step: with 1/16 instead, the wind problem's
/// energy drifted by 1.3e−18 per step over 1e7 steps (r = 3, h = 0.01, extrapolating
/// predictor), with 2⁻¹⁷ by −1.2e−20, as without the rule.
pub const Y1_SHARE: f64 = 1.0 / 131_072.0;

/// ECrP's second stopping rule, for fast contractions: the stage iteration may stop before its
/// update is within `tolerance` when what is left does not reach y₁.
///
/// y₁ is computed from g at the stages, and a stage error e reaches y₁ through the same kind of
/// map as it reaches the next iterate (the kernels at τ = 1 instead of τ = cᵢ), i.e. reduced by
/// about the contraction θ. So the iteration stops once the estimated stage error e = θ/(1 −
/// θ)·r is within `tolerance` and its effect on y₁, θ·e, is within [`Y1_SHARE`] of it (far
/// below round-off: see there). θ is the larger of this sweep's r/p and `theta_floor`,
/// the largest ratio seen in the step before: a ratio of two updates can be small by chance
/// where the contraction alternates between fast and slow (observed on HBVM(5,2): ratios 0.6,
/// 0.017, 0.3, 0.008, …, where the latest ratio alone stopped sweeps early and the energy
/// error over 2000 steps grew from 3e−14 to 1.3e−12), while the contraction of a step size
/// changes little from one step to the next. With θ < ½ only.
///
/// This saves the last sweep where the contraction is fast: Duffing (ω = 20, r = 6, h = 1/16)
/// contracts by θ ≈ 2e−6 per sweep from a predictor 2e−5 off: updates 5e−5, 1e−10, 3e−16; the
/// third sweep only confirmed what the second had left (e ≈ 3e−16, θe ≈ 1e−21).
#[inline]
pub fn y1_converged(residual: f64, previous: f64, theta_floor: f64, tolerance: f64) -> bool {
    let (r, p) = (residual, previous);
    if !(r < p && p.is_finite()) {
        return false;
    }
    let theta = (r / p).max(theta_floor);
    if theta.is_nan() || theta >= 0.5 {
        return false;
    }
    let e = theta / (1.0 - theta) * r;
    e <= tolerance && theta * e <= Y1_SHARE * tolerance
}

/// The stopping rule of the fixed-point sweeps, shared by every implicit stepper.
///
/// With θ = ‖ΔYₖ‖/‖ΔYₖ₋₁‖ the observed contraction, the distance to the fixed point is about
/// θ/(1 − θ)·‖ΔYₖ‖ (Hairer–Wanner, *Solving ODEs II*, §IV.8). Converged when both the update
/// and that estimate are ≤ `tolerance`, or when the update is at round-off level (≤
/// [`ROUNDOFF_RESIDUAL`]) and no longer contracting (θ ≥ [`STAGNATION_THETA`]).
///
/// Both halves matter for long runs, where a stage error left at the same sign every step shows
/// up as energy drift: the update alone is not enough for slow contraction (θ = 0.6: an update
/// of 1e−15 leaves an error of 1.5e−15, and "no longer halving" is not stagnation there), and
/// the estimate alone stops fast contractions (θ = 0.01) with an error of `tolerance` where one
/// more cheap sweep would reach round-off.
///
/// ECrP adds [`y1_converged`] to this rule.
///
/// Division-free (it runs once per sweep on the hot path): with θ = r/p, θ/(1 − θ) = r/(p − r),
/// so the estimate is r when 2r ≤ p (or θ ≥ 1) and r²/(p − r) otherwise.
#[inline]
pub fn sweeps_converged(residual: f64, previous: f64, tolerance: f64) -> bool {
    sweeps_converged_scaled(residual, previous, residual, tolerance)
}

/// [`sweeps_converged`] for an update measured in a scale of its own (e.g. per component,
/// [`StageScale::PerComponent`]), with `global` the same update in the scale of the whole
/// state (‖ΔY‖∞ / max(1, ‖Y‖∞)).
///
/// The estimate and the contraction θ come from `residual`; round-off is judged on `global`:
/// stagnation is `global` ≤ [`ROUNDOFF_RESIDUAL`] with θ ≥ [`STAGNATION_THETA`]. A component
/// computed from much larger ones carries their rounding error, ε times *their* size, which is
/// far above ε in its own scale (so is a component near zero): its scaled update never falls
/// to [`ROUNDOFF_RESIDUAL`], but it stops contracting once the whole state is at round-off,
/// and that ends the iteration. With `global = residual` this is [`sweeps_converged`].
#[inline]
pub fn sweeps_converged_scaled(residual: f64, previous: f64, global: f64, tolerance: f64) -> bool {
    let (r, p) = (residual, previous); // p = ∞ on the first sweep: θ = 0
    let estimate_ok = if r < p && 2.0 * r > p {
        r * r <= tolerance * (p - r)
    } else {
        r <= tolerance
    };
    estimate_ok || (global <= ROUNDOFF_RESIDUAL && r >= STAGNATION_THETA * p)
}

/// Contraction estimates θ at or above this make [`StageSolver::Newton`] refresh its Jacobian
/// at the current stages (and redo the iteration's update with it). Below it the simplified
/// iteration is kept: at θ = 0.5 it needs about 50 iterations for 15 digits, and one LU
/// factorisation of the n × n Newton matrix (n = s·d, 2n³/3 operations) costs as many
/// operations as n/3 of its solves (2n² each): 43 at s = 2, d = 64. At θ ≥ 1 it diverges.
pub const NEWTON_REFRESH_THETA: f64 = 0.5;

/// The [`Error::NonFinite`] of a diverging stage iteration.
const DIVERGED: &str = "stage values (the stage iteration diverged: try a smaller h, or \
                        StageSolver::Newton for a stiff g)";

/// The [`Error::Overflow`] of stage values that overflowed at the first sweep, or while the
/// iteration was contracting.
const STAGES_OVERFLOWED: &str = "stage values";

/// The [`Error::Overflow`] of y₁ from finite stages.
const Y1_OVERFLOWED: &str = "the new state y₁";

/// The error of stages that became non-finite at a sweep whose previous scaled update was
/// `previous` (∞ at the first sweep), with g at the previous iterate: g's fault if g is not
/// finite ([`g_fault`]); divergence if the iteration was already moving the stages by half
/// their size or more; otherwise the stage values themselves overflowed (at the first sweep
/// the stages are e^{cᵢhA} y₀ plus the exponential Euler update: the solution, not the
/// iteration, leaves the f64 range).
#[cold]
fn stage_fault(g: &[f64], previous: f64) -> Error {
    g_fault(g, previous).map_or_else(|| stages_fault(previous), Error::NonFinite)
}

/// The error of a fixed-point stage iteration whose stage values became non-finite with g
/// finite, `previous` being the scaled update of the sweep before (∞ at the first sweep), as
/// every stepper here reports it: [`Error::NonFinite`] saying the iteration diverged (try a
/// smaller h, or [`StageSolver::Newton`]) if that update was already half the stages or more,
/// else [`Error::Overflow`] of the stage values (the solution itself left the f64 range).
///
/// For iterations of one's own that should fail the way the built-in steppers do (as
/// [`sweeps_converged`] is for their stopping rule).
#[cold]
pub fn stages_fault(previous: f64) -> Error {
    if previous.is_finite() && previous >= 0.5 {
        Error::NonFinite(DIVERGED)
    } else {
        Error::Overflow(STAGES_OVERFLOWED)
    }
}

/// The [`Error::NonFinite`] of g at a stage.
const G_NONFINITE: &str = "g(Y) at a stage";

/// The [`Error::NonFinite`] of g at the stages of an iteration that was diverging.
const G_DIVERGED: &str =
    "g(Y) at the iterates of a diverging stage iteration (last update >= half the stages)";

/// The [`Error::NonFinite`] message if g is not finite at stages that the last sweep moved by
/// `residual` (`None` if it is finite): g overflowing at stages that moved by half their size
/// or more (a relative update tends to 1 as the iterates blow up) is most likely the iteration
/// diverging (e.g. a stiff g with fixed-point sweeps) rather than a fault of g: say so.
/// (Inlined: a call would make fixed-size arrays of g leave registers.)
#[inline(always)]
fn g_fault(g: &[f64], residual: f64) -> Option<&'static str> {
    match (all_finite(g), residual >= 0.5) {
        (true, _) => None,
        (false, true) => Some(G_DIVERGED),
        (false, false) => Some(G_NONFINITE),
    }
}

/// Whether every entry of `x` is finite, without branches: `0·x` is ±0 for finite x and NaN
/// for ±∞ and NaN, so the sum is 0 exactly when all are finite.
///
/// Four interleaved sums, so that long vectors (a whole state of a large system) are not
/// held up by the latency of one chain of additions.
#[inline(always)]
pub(crate) fn all_finite(x: &[f64]) -> bool {
    let mut acc = [0.0_f64; 4];
    let mut quads = x.chunks_exact(4);
    for q in &mut quads {
        for (a, v) in acc.iter_mut().zip(q) {
            *a += 0.0 * v;
        }
    }
    let rest = quads.remainder().iter().fold(0.0, |a, v| a + 0.0 * v);
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + rest == 0.0
}

/// What to do when the stage equations have not converged after the allowed sweeps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SweepLimit {
    /// Return [`Error::NoConvergence`] (the default).
    Error,
    /// Accept the stages after the last sweep, as the paper does ("at most N iterations").
    Accept,
}

/// Where the fixed-point iteration of a step starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Predictor {
    /// Every stage starts at y₀ (the paper's iteration; the first sweep is then the
    /// exponential Euler predictor).
    Constant,
    /// The stages start at the previous step's continuous solution extrapolated to
    /// τ = 1 + cᵢ: ũ(1 + cᵢ) = φ₀((1 + cᵢ)hA) y₋₁ + h Σ_k (1 + cᵢ)^{k+1} φ_{k+1}((1 + cᵢ)hA) G_k,
    /// exact for the linear part and O(h^{r+1}) close to the stages, so fewer sweeps are needed
    /// (the converged step is the same up to round-off). Used when the step starts where the
    /// previous one ended (compared bit for bit) with the same h; otherwise as `Constant`.
    /// Costs s more φ-bank entries and one `combine` over s nodes per step. The default: it
    /// saves about one sweep per step on Duffing (ω = 20, r = 2..8, h = 1/4..1/64) and three
    /// to four on the NLS (N = 128, r = 3..5, h = 0.025..0.2), for the cost of about one
    /// (`cargo run --release --example sweeps`).
    Extrapolate,
}

/// How the stage equations `Y = Φ(Y)` are solved.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum StageSolver {
    /// Fixed-point sweeps `Y ← Φ(Y)` (the paper's). They contract when `h ‖∂g/∂y‖` is small
    /// (the linear part, however stiff, is integrated exactly and does not count).
    #[default]
    FixedPoint,
    /// Newton with a refreshed Jacobian where the simplified iteration stalls: each step
    /// starts as simplified Newton, `Y ← Y + (I − Φ'(y₀))⁻¹ (Φ(Y) − Y)`, with the Jacobian J
    /// of g at y₀ from [`System::jacobian`] or, where that is not provided, forward
    /// differences (d more evaluations of g). When an iteration's update is not at least
    /// [`NEWTON_REFRESH_THETA`] times the previous one (or is not finite), the update is
    /// discarded and redone with the Jacobians at the current stages, block (i, k) of the
    /// Newton matrix `δ_ik I − Q_ik J(Y_k)` (full Newton at that iterate; s Jacobians, and with
    /// forward differences s·d more evaluations of g); that matrix is then kept while the
    /// iteration contracts. A step on which the simplified iteration contracts costs what
    /// [`SimplifiedNewton`](Self::SimplifiedNewton) costs, bit for bit the same stages.
    /// [`StepReport::jacobian_evals`] and [`StepReport::newton_refreshes`] say what ran.
    ///
    /// For stiff nonlinearities (e.g. Allen–Cahn with small ε, or a reaction term whose
    /// Jacobian changes sign across the step). Cost per step: the s·d × s·d Newton matrix and
    /// its LU factorisation (allocated per step, and per refresh), s² products of d × d
    /// matrices; once per step size, the kernel matrices from `s·r·d` bank applications.
    /// Meant for moderate d: construction fails with an error naming the size when the
    /// `2s²d² + 2d² + 3sd` numbers cannot be allocated. The ECrP stepper (and so
    /// TCrP/RKNCrP, which run on it); the baselines reject it.
    Newton,
    /// Simplified Newton only: the Jacobian frozen at y₀ for the whole step, never refreshed
    /// (one Jacobian and one factorisation per step, whatever the contraction). It diverges
    /// where g' changes a lot across the step; [`Newton`](Self::Newton) is the same iteration
    /// with the refresh.
    SimplifiedNewton,
}

/// How the stopping rule measures a stage update ΔY (see [`sweeps_converged`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum StageScale {
    /// ‖ΔY‖∞ / max(1, ‖Y‖∞): relative to the largest stage component, absolute below 1 (the
    /// default). Robust (every component's rounding error is at most ε times the largest
    /// component, so the iteration always reaches this test or round-off stagnation) and
    /// the cheapest; but components far smaller than the largest are converged only to
    /// `tolerance · max(1, ‖Y‖∞)` in absolute terms (a component of size 1e−20 beside ones of
    /// size 1 keeps a relative error of up to `tolerance`/1e−20).
    #[default]
    Global,
    /// `max_i |ΔY_i| / max(|Y_i|, atol)`: each component relative to itself, absolute below
    /// `atol` (> 0, finite). For states whose components differ in size by many orders of
    /// magnitude. Components whose own rounding error is far above ε in their own scale (near
    /// zero, or computed from much larger components) cannot reach this test; the iteration
    /// then ends by round-off stagnation measured in the global scale
    /// ([`sweeps_converged_scaled`]). One more comparison per component and sweep. The ECrP
    /// stepper (and TCrP/RKNCrP, which run on it); the baselines reject it.
    PerComponent {
        /// Components below this size are measured absolutely.
        atol: f64,
    },
}

/// Settings of the stage solver.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolverSettings {
    /// Stop when the estimated distance to the fixed point, from the scaled max-norm of the
    /// stage update (‖ΔY‖∞ / max(1, ‖Y‖∞), or per component: [`scale`](Self::scale)) and the
    /// observed contraction, is ≤ this, or when the update stagnates at round-off level (see
    /// [`sweeps_converged`]).
    pub tolerance: f64,
    /// Maximum number of sweeps per step.
    pub max_sweeps: usize,
    /// What happens at the sweep limit.
    pub on_limit: SweepLimit,
    /// The initial iterate of the stages.
    pub predictor: Predictor,
    /// Fixed-point sweeps or Newton (each "sweep" of the reports is then one Newton
    /// iteration; the stopping rule is the same).
    pub solver: StageSolver,
    /// How the stopping rule measures the stage update: in the scale of the whole state (the
    /// default) or per component.
    pub scale: StageScale,
    /// Form y₁ with the propagator in double-double and carry its rounding error to the next
    /// step (compensated summation), where the kernel bank supports it
    /// ([`PhiBank::propagate_dd`]; see the module docs). On by default: it removes the
    /// round-off drift of the energy in long runs for a few more operations per step.
    pub compensated: bool,
    /// Systems of this dimension d or more run the independent work of each step's stages
    /// concurrently on rayon's thread pool: g at the s stages ([`System::nonlinear_stages`],
    /// concurrent where the system allows it), the bank's `combine` over the stage nodes
    /// ([`PhiBank::combine_concurrent`]: for the FFT operators the inputs' transforms, then the
    /// nodes' inverse transforms) and the end of the step ([`PhiBank::join`]). The results are
    /// bit for bit those of the serial path. Default [`PARALLEL_MIN_DIM`], measured;
    /// `usize::MAX`: always serial. Smaller systems take the serial path unchanged.
    pub parallel_min_dim: usize,
}

/// The default [`SolverSettings::parallel_min_dim`], d = 2^15: from there on the concurrent
/// stage path is the faster one, measured on 2 cores for the 1D NLS (FFT operators, h = 1/200,
/// extrapolating predictor; `cargo bench --bench parallel -- threshold`, free-machine rounds).
/// Speed-up serial → concurrent: EC2P 0.30, 0.72, 0.87, 0.97, 1.08, 1.26 and EC3P 0.66, 0.73,
/// 0.94, 1.06, 1.20, 1.28 at d = 2^11 … 2^16; 1.4 at d = 2^17. Below, the hand-overs to the
/// pool (3 per sweep and 4 more per step, each waking threads: about 20 µs, from the step
/// times at d = 2^10) cost more than the work they share.
pub const PARALLEL_MIN_DIM: usize = 1 << 15;

impl Default for SolverSettings {
    /// Tolerance 1e−15, at most 100 sweeps, error at the limit, stages started from the
    /// previous step extrapolated ([`Predictor::Extrapolate`]), fixed-point sweeps, the global
    /// scale, compensated update.
    fn default() -> Self {
        SolverSettings {
            tolerance: 1e-15,
            max_sweeps: 100,
            on_limit: SweepLimit::Error,
            predictor: Predictor::Extrapolate,
            solver: StageSolver::FixedPoint,
            scale: StageScale::Global,
            compensated: true,
            parallel_min_dim: PARALLEL_MIN_DIM,
        }
    }
}

impl SolverSettings {
    /// Checks tolerance ≥ 0 (not NaN), max_sweeps ≥ 1, and a finite atol > 0 for
    /// [`StageScale::PerComponent`].
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] otherwise.
    pub fn validate(&self) -> Result<()> {
        if self.tolerance.is_nan() || self.tolerance < 0.0 || self.max_sweeps == 0 {
            return Err(Error::InvalidParameter(format!(
                "solver settings need tolerance >= 0 and max_sweeps >= 1 (got {self:?})"
            )));
        }
        if let StageScale::PerComponent { atol } = self.scale {
            if !(atol.is_finite() && atol > 0.0) {
                return Err(Error::InvalidParameter(format!(
                    "StageScale::PerComponent needs a finite atol > 0 (got {atol:?})"
                )));
            }
        }
        Ok(())
    }

    /// The paper's setting (§9): tolerance 1e−16, at most 5 sweeps, accepted at the limit,
    /// stages started at y₀.
    pub fn paper() -> Self {
        SolverSettings {
            tolerance: 1e-16,
            max_sweeps: 5,
            on_limit: SweepLimit::Accept,
            predictor: Predictor::Constant,
            solver: StageSolver::FixedPoint,
            scale: StageScale::Global,
            compensated: true,
            parallel_min_dim: PARALLEL_MIN_DIM,
        }
    }
}

/// What one step did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepReport {
    /// Fixed-point sweeps performed.
    pub sweeps: usize,
    /// Final residual (scaled max-norm of the last stage update).
    pub residual: f64,
    /// Evaluations of g.
    pub g_evals: usize,
    /// Whether the tolerance was reached.
    pub converged: bool,
    /// Jacobians of g formed (each d × d, analytic or by forward differences, whose
    /// evaluations of g are in `g_evals`): 0 for fixed-point sweeps, 1 (at y₀) for
    /// simplified Newton, plus s per refresh ([`StageSolver::Newton`]).
    pub jacobian_evals: usize,
    /// How often [`StageSolver::Newton`] refreshed its Jacobian at the stages (0: the step
    /// was simplified Newton throughout).
    pub newton_refreshes: usize,
}

/// The coefficient-dependent part of an ECrP method.
pub trait Kernel {
    /// r: the method has order 2r and r moments.
    fn r(&self) -> usize;
    /// s: number of Gauss–Legendre points (s ≥ r).
    fn s(&self) -> usize;
    /// The nodes c₁..c_s.
    fn nodes(&self) -> &[f64];
    /// The Legendre moments m[k·d..(k+1)·d] = Σ_j ℓ_kj g[j·d..(j+1)·d], ℓ_kj = b_j P̃_k(c_j),
    /// k < r, each sum accumulated from 0.0 in the order j = 0, 1, … (so that every kernel
    /// rounds identically).
    fn legendre_moments(&self, g: &[f64], m: &mut [f64], d: usize);
    /// Calls `f(j)` for j = 0..s in order, stopping at the first error.
    fn each_stage<F: FnMut(usize) -> Result<()>>(&self, mut f: F) -> Result<()> {
        (0..self.s()).try_for_each(&mut f)
    }
}

/// A kernel with compile-time coefficients (what `ecr_method!` emits): constructible
/// without arguments, so that `Stepper::new(system, h)` can build it.
pub trait FixedKernel: Kernel + Default {}

/// The run-time kernel: coefficients from the built-in tables or generated once and cached.
#[derive(Clone, Debug)]
pub struct RuntimeKernel(Arc<Coefficients>);

impl RuntimeKernel {
    /// The kernel of ECrP with r moments and s points.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for r, s out of range.
    pub fn new(r: usize, s: usize) -> Result<Self> {
        coefficients(r, s).map(RuntimeKernel)
    }

    /// The kernel with r moments on an s-point quadrature of the given kind (Gauss–Lobatto:
    /// the HBVM baselines).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for r, s out of range.
    pub fn with_quadrature(
        kind: crate::tables::QuadratureKind,
        r: usize,
        s: usize,
    ) -> Result<Self> {
        crate::tables::coefficients_with(kind, r, s).map(RuntimeKernel)
    }

    /// The coefficients.
    pub fn coefficients(&self) -> &Coefficients {
        &self.0
    }
}

impl Kernel for RuntimeKernel {
    fn r(&self) -> usize {
        self.0.r
    }
    fn s(&self) -> usize {
        self.0.s
    }
    fn nodes(&self) -> &[f64] {
        &self.0.nodes
    }
    fn legendre_moments(&self, g: &[f64], m: &mut [f64], d: usize) {
        accumulate(&self.0.lw, self.0.r, self.0.s, g, m, d);
    }
}

/// `m_k = Σ_j w[k·s + j] g_j`, k < r, each sum from 0.0 in the order j = 0, 1, …. Components
/// go in blocks of 8, 4, 2 and 1 whose sums stay in registers (at small d a sum through memory
/// costs a store-to-load round trip per term).
fn accumulate(w: &[f64], r: usize, s: usize, g: &[f64], m: &mut [f64], d: usize) {
    let g = &g[..s * d];
    for (k, mk) in m[..r * d].chunks_exact_mut(d).enumerate() {
        let wk = &w[k * s..(k + 1) * s];
        let mut a0 = 0;
        while a0 < d {
            a0 += match d - a0 {
                8.. => accumulate_rows::<8>(wk, g, mk, a0, d),
                4.. => accumulate_rows::<4>(wk, g, mk, a0, d),
                2.. => accumulate_rows::<2>(wk, g, mk, a0, d),
                _ => accumulate_rows::<1>(wk, g, mk, a0, d),
            };
        }
    }
}

/// Components `a0..a0 + N` of one moment of [`accumulate`]; returns N.
#[inline(always)]
fn accumulate_rows<const N: usize>(
    wk: &[f64],
    g: &[f64],
    mk: &mut [f64],
    a0: usize,
    d: usize,
) -> usize {
    let mut acc = [0.0_f64; N];
    for (j, &wkj) in wk.iter().enumerate() {
        let gj: &[f64; N] = g[j * d + a0..j * d + a0 + N]
            .try_into()
            .expect("N components");
        for (x, gv) in acc.iter_mut().zip(gj) {
            *x += wkj * gv;
        }
    }
    mk[a0..a0 + N].copy_from_slice(&acc);
    N
}

/// Mutable views of a stepper's stage state: y₀ (d), stages and their next iterate (s·d),
/// g at the stages (s·d), moments (r·d), each stage or moment contiguous, and scratch.
pub struct BufferParts<'a> {
    /// The state at the start of the step.
    pub y0: &'a mut [f64],
    /// Stage values Y₁..Y_s.
    pub stages: &'a mut [f64],
    /// The next fixed-point iterate of the stages.
    pub new_stages: &'a mut [f64],
    /// The propagated start `e^{cᵢhA} y₀` of each stage (s·d; fused sweeps only).
    pub props: &'a mut [f64],
    /// g(Y₁)..g(Y_s).
    pub g: &'a mut [f64],
    /// Moments G₀..G_{r−1}.
    pub moments: &'a mut [f64],
    /// The state at the end of the last step (d).
    pub last: &'a mut [f64],
    /// The rounding error of the last step's compensated update (d), carried into the next.
    pub comp: &'a mut [f64],
    /// Scratch for the end of a step (3d): the double-double propagated state and the
    /// propagated rounding error.
    pub tmp: &'a mut [f64],
}

/// Storage for the stage state of a [`Stepper`].
pub trait Buffers: Sized {
    /// Storage for r moments, s stages, dimension d.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] if fixed-size storage does not have these sizes.
    fn with_sizes(r: usize, s: usize, d: usize) -> Result<Self>;
    /// The dimension d.
    fn dim(&self) -> usize;
    /// Calls `f` with all buffers, mutably. Fixed-size storage hands out the per-step state
    /// (stages, their next iterate, the propagated starts, g) as arrays local to the call, so
    /// that the compiler can keep them in registers; their contents are not kept from one call
    /// to the next (the step does not need them).
    fn with_parts<R>(&mut self, f: impl FnOnce(BufferParts<'_>) -> R) -> R;
    /// Whether the stages, their next iterate and g are local arrays (see
    /// [`with_parts`](Self::with_parts)). The step then lets only `props` and `tmp` reach
    /// functions that are not inlined (the φ-bank), routing their results through a copy, so
    /// that the others can stay in registers.
    const LOCAL_STAGES: bool = false;
    /// y₀ of the last step.
    fn y0(&self) -> &[f64];
    /// The moments of the last step.
    fn moments(&self) -> &[f64];
    /// (r, s, d) where they are compile-time constants (fixed-size storage), so that a step's
    /// loops over them unroll.
    const SIZES: Option<(usize, usize, usize)> = None;
}

/// Heap buffers, allocated once at construction (any d known at run time).
#[derive(Clone, Debug)]
pub struct VecBuffers {
    y0: Vec<f64>,
    stages: Vec<f64>,
    new_stages: Vec<f64>,
    props: Vec<f64>,
    g: Vec<f64>,
    moments: Vec<f64>,
    last: Vec<f64>,
    comp: Vec<f64>,
    tmp: Vec<f64>,
}

impl Buffers for VecBuffers {
    fn with_sizes(r: usize, s: usize, d: usize) -> Result<Self> {
        Ok(VecBuffers {
            y0: vec![0.0; d],
            stages: vec![0.0; s * d],
            new_stages: vec![0.0; s * d],
            props: vec![0.0; s * d],
            g: vec![0.0; s * d],
            moments: vec![0.0; r * d],
            last: vec![0.0; d],
            comp: vec![0.0; d],
            tmp: vec![0.0; 3 * d],
        })
    }
    fn dim(&self) -> usize {
        self.y0.len()
    }
    fn with_parts<R>(&mut self, f: impl FnOnce(BufferParts<'_>) -> R) -> R {
        f(BufferParts {
            y0: &mut self.y0,
            stages: &mut self.stages,
            new_stages: &mut self.new_stages,
            props: &mut self.props,
            g: &mut self.g,
            moments: &mut self.moments,
            last: &mut self.last,
            comp: &mut self.comp,
            tmp: &mut self.tmp,
        })
    }
    fn y0(&self) -> &[f64] {
        &self.y0
    }
    fn moments(&self) -> &[f64] {
        &self.moments
    }
}

/// Fixed-size buffers for dimension `B·D` (B blocks of D: `B = 2` holds the state (q, p) of a
/// second-order system with D positions), `S` stages and `R` moments: what a step hands on
/// (y₀, the moments, the end state and its rounding error) in arrays inside the stepper, the
/// stage state in arrays on the stack of each step (see [`Buffers::with_parts`]); no heap.
#[derive(Clone, Debug)]
pub struct StaticBuffers<const D: usize, const S: usize, const R: usize, const B: usize = 1> {
    y0: [[f64; D]; B],
    moments: [[[f64; D]; B]; R],
    last: [[f64; D]; B],
    comp: [[f64; D]; B],
}

impl<const D: usize, const S: usize, const R: usize, const B: usize> Buffers
    for StaticBuffers<D, S, R, B>
{
    fn with_sizes(r: usize, s: usize, d: usize) -> Result<Self> {
        for (what, expected, found) in [
            ("dimension", B * D, d),
            ("stages s", S, s),
            ("moments r", R, r),
        ] {
            if expected != found {
                return Err(Error::DimensionMismatch {
                    what,
                    expected,
                    found,
                });
            }
        }
        Ok(StaticBuffers {
            y0: [[0.0; D]; B],
            moments: [[[0.0; D]; B]; R],
            last: [[0.0; D]; B],
            comp: [[0.0; D]; B],
        })
    }
    fn dim(&self) -> usize {
        B * D
    }
    #[inline(always)]
    fn with_parts<R2>(&mut self, f: impl FnOnce(BufferParts<'_>) -> R2) -> R2 {
        let mut stages = [[[0.0; D]; B]; S];
        let mut new_stages = [[[0.0; D]; B]; S];
        let mut props = [[[0.0; D]; B]; S];
        let mut g = [[[0.0; D]; B]; S];
        let mut tmp = [[[0.0; D]; B]; 3];
        f(BufferParts {
            y0: self.y0.as_flattened_mut(),
            stages: stages.as_flattened_mut().as_flattened_mut(),
            new_stages: new_stages.as_flattened_mut().as_flattened_mut(),
            props: props.as_flattened_mut().as_flattened_mut(),
            g: g.as_flattened_mut().as_flattened_mut(),
            moments: self.moments.as_flattened_mut().as_flattened_mut(),
            last: self.last.as_flattened_mut(),
            comp: self.comp.as_flattened_mut(),
            tmp: tmp.as_flattened_mut().as_flattened_mut(),
        })
    }
    const LOCAL_STAGES: bool = true;
    fn y0(&self) -> &[f64] {
        self.y0.as_flattened()
    }
    fn moments(&self) -> &[f64] {
        self.moments.as_flattened().as_flattened()
    }
    const SIZES: Option<(usize, usize, usize)> = Some((R, S, B * D));
}

/// ECrP for a [`System`] with kernel `K` and stage storage `B`.
pub struct Stepper<K: Kernel, S: System, B: Buffers> {
    kernel: K,
    system: S,
    settings: SolverSettings,
    h: f64,
    bank: <S::Op as LinearOperator>::Bank,
    ws: <<S::Op as LinearOperator>::Bank as PhiBank>::Workspace,
    /// r coefficients h τ^{k+1} per bank node τ = c₁..c_s, 1 (and 1 + c₁..1 + c_s with the
    /// extrapolating predictor).
    coef: Vec<f64>,
    scratch: Vec<f64>,
    /// The step as dense maps ([`FusedMaps`]), where that is cheaper (see [`fuses_stages`]);
    /// otherwise `None` and each sweep forms the moments and combines.
    fused: Option<FusedMaps>,
    buf: B,
    /// The buffers hold a completed step (y₀, moments, and its end in `last`) for this h.
    have_previous: bool,
    /// Newton data ([`StageSolver::Newton`], [`StageSolver::SimplifiedNewton`]), built at the
    /// first step for this h.
    newton: Option<Box<NewtonState>>,
    /// The largest ratio of consecutive stage updates in the last completed step (1 when there
    /// is none): the floor of the contraction estimate of [`y1_converged`].
    theta: f64,
    /// The memory of the concurrent stage path, for d ≥
    /// [`SolverSettings::parallel_min_dim`] (else `None`: the serial path).
    par: Option<Box<ParallelState<BankWorkspace<S>>>>,
}

/// The workspace of a system's kernel bank.
type BankWorkspace<S> = <<<S as System>::Op as LinearOperator>::Bank as PhiBank>::Workspace;

/// What the concurrent stage path ([`SolverSettings::parallel_min_dim`]) uses besides the
/// serial path's buffers, allocated with the bank (never per step).
struct ParallelState<W> {
    /// One workspace per concurrent task of the bank's operations: as many as rayon's pool has
    /// threads, at least 2 (the end of a step runs two tasks) and at most max(s, r + 1) (the
    /// pieces of a `combine` over the stage nodes).
    helpers: Vec<W>,
    /// A scratch of [`System::scratch_len`] per stage, for g at the stages.
    scratch: Vec<f64>,
    /// The kernel's ℓ_kj (k < r, j < s, at `k·s + j`), for the moments.
    ell: Vec<f64>,
    /// s.
    s: usize,
    /// As many units as `helpers`: the tasks of the moments, which need no workspace.
    tasks: Vec<()>,
}

impl<W> ParallelState<W> {
    /// The state for a system of dimension d with scratch `scratch_len`, s stages and r
    /// moments, if d ≥ `min_dim`. Starts rayon's pool (once per process), so that steps do
    /// not allocate.
    fn new<K: Kernel, Bk: PhiBank<Workspace = W>>(
        kernel: &K,
        bank: &Bk,
        min_dim: usize,
        scratch_len: usize,
    ) -> Option<Box<Self>> {
        let (s, r) = (kernel.s(), kernel.r());
        (bank.dim() >= min_dim).then(|| {
            let tasks = rayon::current_num_threads().clamp(2, s.max(r + 1));
            // ℓ_kj: the moments of the unit vectors (d = 1), exact (one term is ℓ_kj · 1, the
            // others ℓ · 0).
            let mut ell = vec![0.0; r * s];
            let (mut unit, mut mom) = (vec![0.0; s], vec![0.0; r]);
            for j in 0..s {
                unit.fill(0.0);
                unit[j] = 1.0;
                kernel.legendre_moments(&unit, &mut mom, 1);
                for k in 0..r {
                    ell[k * s + j] = mom[k];
                }
            }
            Box::new(ParallelState {
                helpers: (0..tasks).map(|_| bank.workspace()).collect(),
                scratch: vec![0.0; s * scratch_len],
                ell,
                s,
                tasks: vec![(); tasks],
            })
        })
    }

    /// [`Kernel::legendre_moments`] with the moments (each in two halves where d is even)
    /// computed concurrently: bit for bit the kernel's, whose contract fixes the arithmetic
    /// (each sum from 0.0, terms `ℓ_kj g_j` in the order j = 0, 1, …).
    fn moments(&mut self, g: &[f64], m: &mut [f64], d: usize) {
        let (ell, s) = (&self.ell, self.s);
        let parts = if d % 2 == 0 { 2 } else { 1 };
        let len = d / parts;
        for_each_chunk(m, len, &mut self.tasks, &|q, mk: &mut [f64], _: &mut ()| {
            let (k, at) = (q / parts, (q % parts) * len);
            mk.fill(0.0);
            for j in 0..s {
                let w = ell[k * s + j];
                for (x, gv) in mk.iter_mut().zip(&g[j * d + at..j * d + at + len]) {
                    *x += w * gv;
                }
            }
        });
    }
}

/// The end of a step on the concurrent path: y₁ as the serial path computes it (the
/// compensated update where `compensated` and the bank carries its propagator, else one
/// `combine` at τ = 1), with the independent bank operations run concurrently: e^{hA} y₀ in
/// double-double and then e^{hA} c on one task, the nonlinear part on the other.
#[allow(clippy::too_many_arguments)]
fn finish_concurrent<Bk: PhiBank>(
    bank: &Bk,
    par: &mut ParallelState<Bk::Workspace>,
    ws: &mut Bk::Workspace,
    s: usize,
    compensated: bool,
    y0: &[f64],
    moments: &[f64],
    coef: &[f64],
    y: &mut [f64],
    last: &mut [f64],
    comp: &mut [f64],
    hi: &mut [f64],
    lo: &mut [f64],
    ec: &mut [f64],
) {
    if compensated {
        last.fill(0.0);
        let (wa, wb) = par.helpers.split_at_mut(1);
        let comp_in: &[f64] = comp;
        let last: &[f64] = last;
        let (carried, ()) = bank.join(
            &mut wa[0],
            &mut wb[0],
            |bk, w| {
                let carried = bk.propagate_dd(s, y0, hi, lo, w);
                if carried {
                    bk.apply(s, 0, comp_in, ec, w);
                }
                carried
            },
            |bk, w| bk.combine(s..s + 1, last, moments, coef, y, w),
        );
        if carried {
            compensated_sum(y, comp, hi, lo, ec);
            return;
        }
    }
    bank.combine_concurrent(s..s + 1, y0, moments, coef, y, ws, &mut par.helpers);
}

/// y₁ = hi + lo + N + e (double-double propagated state, nonlinear part N in `y`, propagated
/// rounding error e), rounded to `y`, its rounding error to `comp`.
#[inline(always)]
fn compensated_sum(y: &mut [f64], comp: &mut [f64], hi: &[f64], lo: &[f64], ec: &[f64]) {
    for ((((yv, c), h), l), e) in y
        .iter_mut()
        .zip(comp.iter_mut())
        .zip(hi.iter())
        .zip(lo.iter())
        .zip(ec.iter())
    {
        let (sum, err) = two_sum(*h, *l + *yv + *e);
        *yv = sum;
        *c = err;
    }
}

/// The most numbers the Newton iteration holds at once: the stage matrices and the Newton
/// matrix (s²d² each), the Jacobian and one d × d block product, and at a refresh the
/// right-hand side and copies of the stages and of g there (s·d each); `None` on overflow.
fn newton_entries(s: usize, d: usize) -> Option<usize> {
    let dd = d.checked_mul(d)?;
    s.checked_mul(s)?
        .checked_mul(dd)?
        .checked_add(dd)?
        .checked_mul(2)?
        .checked_add(s.checked_mul(d)?.checked_mul(3)?)
}

/// What the Newton iteration keeps: the stage matrices for the step size and scratch for the
/// Jacobians.
struct NewtonState {
    /// The stage matrices `∂Φ_i/∂g_k` ([`stage_matrices`]).
    q: Vec<f64>,
    jac: JacobianScratch,
}

/// A Jacobian of g and the d-vectors that forward differences need.
struct JacobianScratch {
    jac: nalgebra::DMatrix<f64>,
    /// d-vectors: a point, g there, g at the base point.
    yp: Vec<f64>,
    gp: Vec<f64>,
    g0: Vec<f64>,
}

impl NewtonState {
    /// With the stage matrices `q` of the step size, for dimension d.
    fn new(q: Vec<f64>, d: usize) -> Self {
        NewtonState {
            q,
            jac: JacobianScratch {
                jac: nalgebra::DMatrix::zeros(d, d),
                yp: vec![0.0; d],
                gp: vec![0.0; d],
                g0: vec![0.0; d],
            },
        }
    }
}

/// The LU factorisation of the Newton matrix.
type NewtonLu = nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>;

/// The Jacobian of g at `y` into `js.jac`: the system's, or forward differences from g(y)
/// (`gy`, or evaluated here if `None`). Returns the evaluations of g it took.
///
/// # Errors
/// [`Error::DimensionMismatch`] if the system's Jacobian is not d × d, [`Error::NonFinite`]
/// (naming `at`) if it has a non-finite entry.
fn jacobian_into<S: System>(
    system: &S,
    y: &[f64],
    gy: Option<&[f64]>,
    js: &mut JacobianScratch,
    scratch: &mut [f64],
    at: &'static str,
) -> Result<usize> {
    let d = y.len();
    let mut evals = 0;
    if !system.jacobian(y, &mut js.jac, scratch) {
        let g0 = match gy {
            Some(gy) => gy,
            None => {
                system.nonlinear(y, &mut js.g0, scratch);
                evals += 1;
                &js.g0
            }
        };
        evals += d;
        for l in 0..d {
            js.yp.copy_from_slice(y);
            let step = f64::EPSILON.sqrt() * y[l].abs().max(1.0);
            js.yp[l] += step;
            let step = js.yp[l] - y[l];
            system.nonlinear(&js.yp, &mut js.gp, scratch);
            for (t, (a, b)) in js.gp.iter().zip(g0).enumerate() {
                js.jac[(t, l)] = (a - b) / step;
            }
        }
    }
    if js.jac.shape() != (d, d) {
        let found = js.jac.nrows() * js.jac.ncols();
        js.jac = nalgebra::DMatrix::zeros(d, d);
        return Err(Error::DimensionMismatch {
            what: "Jacobian of g (d × d entries)",
            expected: d * d,
            found,
        });
    }
    if js.jac.iter().any(|v| !v.is_finite()) {
        return Err(Error::NonFinite(at));
    }
    Ok(evals)
}

/// Subtracts `Q_ik J` from block (i, k) of the Newton matrix `nm`, for every i < s.
fn subtract_column_block(
    nm: &mut nalgebra::DMatrix<f64>,
    q: &[f64],
    jac: &nalgebra::DMatrix<f64>,
    k: usize,
    s: usize,
    d: usize,
) {
    let sd = s * d;
    let q = nalgebra::DMatrixView::from_slice(&q[k * d * sd..(k + 1) * d * sd], sd, d);
    let mut view = nm.columns_mut(k * d, d);
    view -= q * jac;
}

/// The LU factorisation of the Newton matrix `nm`.
///
/// # Errors
/// [`Error::Numerical`] if it is singular.
fn factor_newton_matrix(nm: nalgebra::DMatrix<f64>) -> Result<NewtonLu> {
    let lu = nm.lu();
    if !lu.is_invertible() {
        return Err(Error::Numerical(
            "the Newton matrix of the stage equations is singular".into(),
        ));
    }
    Ok(lu)
}

/// The Newton matrix at the stages `ys` (g there: `gs`), block (i, k) = `δ_ik I − Q_ik
/// J(Y_k)`, factorised; and the evaluations of g its Jacobians took. Off the hot path: only
/// when the simplified iteration stops contracting.
#[cold]
#[inline(never)]
fn refreshed_newton_lu<S: System>(
    system: &S,
    nw: &mut NewtonState,
    ys: &[f64],
    gs: &[f64],
    s: usize,
    d: usize,
    scratch: &mut [f64],
) -> Result<(NewtonLu, usize)> {
    let mut nm = nalgebra::DMatrix::<f64>::identity(s * d, s * d);
    let mut evals = 0;
    for k in 0..s {
        let at = k * d..(k + 1) * d;
        evals += jacobian_into(
            system,
            &ys[at.clone()],
            Some(&gs[at]),
            &mut nw.jac,
            scratch,
            "Jacobian of g at a stage",
        )?;
        subtract_column_block(&mut nm, &nw.q, &nw.jac.jac, k, s, d);
    }
    Ok((factor_newton_matrix(nm)?, evals))
}

/// `new = old + (I − Φ')⁻¹ rhs` with the factorised Newton matrix (`rhs = Φ(old) − old`);
/// returns the global measure of that update, ‖new − old‖∞ / max(1, ‖new‖∞) (NaN or ∞ if
/// it is not finite).
#[inline]
fn newton_apply(lu: &NewtonLu, rhs: &nalgebra::DVector<f64>, old: &[f64], new: &mut [f64]) -> f64 {
    let delta = lu.solve(rhs);
    let delta = delta.as_ref().unwrap_or(rhs);
    let (mut diff, mut mag) = (0.0_f64, 1.0_f64);
    for ((n, y), dl) in new.iter_mut().zip(old).zip(delta.iter()) {
        *n = y + dl;
        diff = diff.max(dl.abs());
        mag = mag.max(n.abs());
    }
    if new.iter().all(|v| v.is_finite()) {
        diff / mag
    } else {
        f64::NAN
    }
}

/// `max_i |new_i − old_i| / max(|new_i|, atol)` ([`StageScale::PerComponent`]; `atol` > 0),
/// division-free per component: `t / scale > rel ⇔ t > rel · scale`. Meaningless if a new
/// stage is not finite (the global measure, computed beside it, catches that).
#[inline]
fn per_component_update(new: &[f64], old: &[f64], atol: f64) -> f64 {
    let mut rel = 0.0_f64;
    for (a, b) in new.iter().zip(old) {
        let t = (a - b).abs();
        let scale = a.abs().max(atol);
        if t > rel * scale {
            rel = t / scale;
        }
    }
    rel
}

/// The stage matrices of ECrP: `M_ik = Σ_j coef_ij ℓ_jk Ψ_j(cᵢ, hA)` (`coef_ij = h cᵢ (2j+1)`,
/// `ℓ_jk = b_k P̃_j(c_k)`), so that the stage equations read `Y_i = e^{cᵢhA} y₀ + Σ_k M_ik
/// g(Y_k)`: the moments and the kernels fused into one linear map, and `∂Φ_i/∂g_k` for
/// Newton. One column-major `sd × sd` matrix: entry (a, b) of block `M_ik` is at row `i·d + a`
/// of column `k·d + b`, so that a sweep is one matrix–vector product ([`gemv_cm`]); each entry
/// is summed over j = 0, 1, … from 0.0. Built from `s·r·d` applications of the kernel bank
/// (once per step size).
pub fn stage_matrices<K: Kernel, Bk: PhiBank>(
    kernel: &K,
    bank: &Bk,
    coef: &[f64],
    ws: &mut Bk::Workspace,
    d: usize,
) -> Vec<f64> {
    let (s, m) = (kernel.s(), kernel.r());
    // ℓ_jk: the Legendre moments of the unit vectors (d = 1).
    let mut ell = vec![0.0; m * s];
    let (mut unit, mut mom) = (vec![0.0; s], vec![0.0; m]);
    for k in 0..s {
        unit.fill(0.0);
        unit[k] = 1.0;
        kernel.legendre_moments(&unit, &mut mom, 1);
        for j in 0..m {
            ell[j * s + k] = mom[j];
        }
    }
    let sd = s * d;
    let mut q = vec![0.0; sd * sd];
    let (mut e, mut col) = (vec![0.0; d], vec![0.0; d]);
    for i in 0..s {
        for l in 0..d {
            e.fill(0.0);
            e[l] = 1.0;
            for j in 0..m {
                bank.apply(i, j + 1, &e, &mut col, ws);
                for k in 0..s {
                    let c = coef[i * m + j] * ell[j * s + k];
                    let start = (k * d + l) * sd + i * d;
                    for (a, b) in q[start..start + d].iter_mut().zip(&col) {
                        *a += c * b;
                    }
                }
            }
        }
    }
    q
}

/// The most entries (`s²d²`) the fused stage matrices may have: 8 MiB.
pub const FUSED_MAX_ENTRIES: usize = 1 << 20;

/// Whether ECrP fuses its sweeps for this bank: the bank states the cost of its `combine`
/// ([`PhiBank::combine_cost`]: dense matrices, or the 2 × 2 block of a one-mode oscillator),
/// and the fused sweep, `s²d²` multiply-adds, costs no more than the moments and `combine`,
/// `rsd + s · cost` (dense: `sd ≤ (r+1)d + r`, i.e. s = r or r + 1 for most d), within
/// [`FUSED_MAX_ENTRIES`].
pub fn fuses_stages<Bk: PhiBank>(bank: &Bk, r: usize, s: usize) -> bool {
    let d = bank.dim();
    let fused = s.saturating_mul(s).saturating_mul(d).saturating_mul(d);
    bank.combine_cost(r).is_some_and(|c| {
        fused <= s.saturating_mul(c).saturating_add(r * s * d) && fused <= FUSED_MAX_ENTRIES
    })
}

/// `out = init + M x` for a column-major matrix `M` with `rows` rows and `x = (x₁, x₂)` (two
/// slices, read as one vector: `M` has `x₁.len() + x₂.len()` columns); `init` absent is zero.
/// Each entry is summed from `init` over the columns in order, one product and one addition
/// per column (no fused multiply-add), so that every caller rounds identically whatever it
/// knows of the sizes at compile time. The rows go in blocks of 8, 4, 2 and 1 whose sums stay
/// in registers. Does not allocate.
///
/// Every linear map of a fused step is one call: the sweep (`M` the stage matrices, `x` = g at
/// the stages, `init` = `e^{cᵢhA} y₀`), the propagated starts, the predictor and the end of the
/// step ([`FusedMaps`]).
///
/// # Panics
/// If `mat` has fewer than `rows · cols` entries, or `out` (and `init`) fewer than `rows`.
// Always inlined: in a fixed-order stepper the sizes are constants and the loops unroll.
#[inline(always)]
pub fn gemv_cm(mat: &[f64], rows: usize, xs: [&[f64]; 2], init: Option<&[f64]>, out: &mut [f64]) {
    let cols = xs[0].len() + xs[1].len();
    let (mat, out) = (&mat[..rows * cols], &mut out[..rows]);
    let init = init.map(|v| &v[..rows]);
    let mut r0 = 0;
    while r0 < rows {
        r0 += match rows - r0 {
            8.. => gemv_rows::<8>(mat, rows, r0, xs, init, out),
            4.. => gemv_rows::<4>(mat, rows, r0, xs, init, out),
            2.. => gemv_rows::<2>(mat, rows, r0, xs, init, out),
            _ => gemv_rows::<1>(mat, rows, r0, xs, init, out),
        };
    }
}

/// Rows `r0..r0 + N` of [`gemv_cm`]; returns N.
#[inline(always)]
fn gemv_rows<const N: usize>(
    mat: &[f64],
    rows: usize,
    r0: usize,
    xs: [&[f64]; 2],
    init: Option<&[f64]>,
    out: &mut [f64],
) -> usize {
    let mut acc = [0.0_f64; N];
    if let Some(init) = init {
        acc.copy_from_slice(&init[r0..r0 + N]);
    }
    let mut col = r0;
    for x in xs {
        for &xc in x {
            let m: &[f64; N] = mat[col..col + N].try_into().expect("N rows");
            for (a, mv) in acc.iter_mut().zip(m) {
                *a += mv * xc;
            }
            col += rows;
        }
    }
    out[r0..r0 + N].copy_from_slice(&acc);
    N
}

/// A small system's step as dense maps, built with the bank where [`fuses_stages`]: each linear
/// map of a step is one column-major matrix applied by [`gemv_cm`], instead of `combine` calls
/// (whose cost per call dominates at small d). Entries are the bank's functions scaled by the
/// combine coefficients (`h τ (2j+1)` for the kernel of degree j), one rounding each.
#[derive(Clone, Debug)]
pub struct FusedMaps {
    /// The stage matrices ([`stage_matrices`]): `sd × sd`.
    pub stage: Vec<f64>,
    /// `e^{cᵢhA}` stacked: `sd × d`.
    pub props: Vec<f64>,
    /// The end of the step, `d × (d + rd)`: `[e^{hA} | h(2j+1)Ψ_j(1, hA), j < r]`, applied to
    /// `(y₀, L₀..L_{r−1})`.
    pub end: Vec<f64>,
    /// The extrapolating predictor, `sd × (d + rd)`: block row i is `[e^{(1+cᵢ)hA} | h(1+cᵢ)
    /// (2j+1)Ψ_j(1+cᵢ, hA), j < r]`, applied to the previous step's `(y₀, L)`; empty without
    /// the predictor.
    pub pred: Vec<f64>,
}

/// Writes `scale ·` the bank's function `(i, k)` into rows `row0..row0 + d` and columns
/// `col0..col0 + d` of the column-major matrix `mat` with `rows` rows (column l from the bank
/// applied to the unit vector e_l: exact).
#[allow(clippy::too_many_arguments)]
fn bank_block<Bk: PhiBank>(
    bank: &Bk,
    ws: &mut Bk::Workspace,
    (i, k): (usize, usize),
    scale: f64,
    mat: &mut [f64],
    rows: usize,
    (row0, col0): (usize, usize),
    d: usize,
) {
    let (mut e, mut col) = (vec![0.0; d], vec![0.0; d]);
    for l in 0..d {
        e.fill(0.0);
        e[l] = 1.0;
        bank.apply(i, k, &e, &mut col, ws);
        let start = (col0 + l) * rows + row0;
        for (a, c) in mat[start..start + d].iter_mut().zip(&col) {
            *a = scale * c;
        }
    }
}

/// The [`FusedMaps`] of a bank built for the nodes `c₁..c_s`, 1 (and `1 + cᵢ` with the
/// predictor), with its combine coefficients `coef`.
fn fused_maps<K: Kernel, Bk: PhiBank>(
    kernel: &K,
    bank: &Bk,
    coef: &[f64],
    ws: &mut Bk::Workspace,
    d: usize,
    predictor: bool,
) -> FusedMaps {
    let (s, m) = (kernel.s(), kernel.r());
    let (sd, cols) = (s * d, d + m * d);
    let mut props = vec![0.0; sd * d];
    for i in 0..s {
        bank_block(bank, ws, (i, 0), 1.0, &mut props, sd, (i * d, 0), d);
    }
    // Rows `row0..row0 + d` of `[e^{τhA} | coef·Ψ_j(τ, hA)]` for the bank's node `node`.
    let mut node_row = |mat: &mut [f64], rows: usize, node: usize, row0: usize| {
        bank_block(bank, ws, (node, 0), 1.0, mat, rows, (row0, 0), d);
        for j in 0..m {
            let c = coef[node * m + j];
            bank_block(bank, ws, (node, j + 1), c, mat, rows, (row0, d + j * d), d);
        }
    };
    let mut end = vec![0.0; d * cols];
    node_row(&mut end, d, s, 0);
    let mut pred = Vec::new();
    if predictor {
        pred = vec![0.0; sd * cols];
        for i in 0..s {
            node_row(&mut pred, sd, s + 1 + i, i * d);
        }
    }
    FusedMaps {
        stage: stage_matrices(kernel, bank, coef, ws, d),
        props,
        end,
        pred,
    }
}

/// ECrP with r and s chosen at run time.
pub type EcStepper<S> = Stepper<RuntimeKernel, S, VecBuffers>;

impl<S: System> Stepper<RuntimeKernel, S, VecBuffers> {
    /// ECrP with s = r (the paper's method) and step size h.
    ///
    /// # Errors
    /// As [`EcStepper::with_nodes`].
    pub fn new(system: S, r: usize, h: f64) -> Result<Self> {
        Self::with_nodes(system, r, r, h, SolverSettings::default())
    }

    /// ECrP with r moments, s ≥ r Gauss–Legendre points, step size h and solver settings.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for r, s out of range or bad settings,
    /// [`Error::InvalidStepSize`] for h, and whatever building the φ-bank reports.
    pub fn with_nodes(
        system: S,
        r: usize,
        s: usize,
        h: f64,
        settings: SolverSettings,
    ) -> Result<Self> {
        check_settings(&settings)?;
        Self::from_kernel(RuntimeKernel::new(r, s)?, system, h, settings)
    }
}

impl<K: FixedKernel, S: System, B: Buffers> Stepper<K, S, B> {
    /// The fixed-order stepper with default solver settings.
    ///
    /// # Errors
    /// As [`Stepper::from_kernel`].
    pub fn fixed(system: S, h: f64) -> Result<Self> {
        Self::from_kernel(K::default(), system, h, SolverSettings::default())
    }
}

fn check_settings(settings: &SolverSettings) -> Result<()> {
    settings.validate()
}

impl<K: Kernel, S: System, B: Buffers> Stepper<K, S, B> {
    /// A stepper from its parts: allocates the buffers and builds the φ-bank for h.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for bad settings, [`Error::InvalidStepSize`] for h,
    /// [`Error::DimensionMismatch`] if fixed-size buffers do not fit the system, the errors of
    /// [`check_system`](crate::system::check_system), [`Error::InvalidInput`] naming the size
    /// if [`StageSolver::Newton`]'s `O(s²d²)` matrices cannot be allocated (checked here,
    /// before the first step would abort on them), and whatever building the φ-bank reports.
    pub fn from_kernel(kernel: K, system: S, h: f64, settings: SolverSettings) -> Result<Self> {
        check_settings(&settings)?;
        crate::system::check_system(&system)?;
        if settings.solver != StageSolver::FixedPoint {
            let (s, d) = (kernel.s(), system.dim());
            ensure_allocatable(
                &format!("Newton for d = {d}, s = {s} (2s²d² + 2d² + 3sd numbers)"),
                newton_entries(s, d),
            )?;
        }
        let buf = B::with_sizes(kernel.r(), kernel.s(), system.dim())?;
        let (bank, coef, fused, ws) = Self::build_bank(&system, &kernel, h, settings.predictor)?;
        let par = ParallelState::new(
            &kernel,
            &bank,
            settings.parallel_min_dim,
            system.scratch_len(),
        );
        Ok(Stepper {
            scratch: vec![0.0; system.scratch_len()],
            kernel,
            system,
            settings,
            h,
            bank,
            ws,
            coef,
            fused,
            buf,
            have_previous: false,
            newton: None,
            theta: 1.0,
            par,
        })
    }

    /// The kernel bank for h, its combine coefficients, the step as dense maps (where
    /// [`fuses_stages`]) and a workspace.
    #[allow(clippy::type_complexity)]
    fn build_bank(
        system: &S,
        kernel: &K,
        h: f64,
        predictor: Predictor,
    ) -> Result<(
        <S::Op as LinearOperator>::Bank,
        Vec<f64>,
        Option<FusedMaps>,
        <<S::Op as LinearOperator>::Bank as PhiBank>::Workspace,
    )> {
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidStepSize(h));
        }
        let r = kernel.r();
        let mut taus = kernel.nodes().to_vec();
        taus.push(1.0);
        if predictor == Predictor::Extrapolate {
            taus.extend(kernel.nodes().iter().map(|c| 1.0 + c));
        }
        let bank = system.linear().kernel_bank(h, &taus, r)?;
        let coef = kernel_coefficients(h, &taus, r);
        let mut ws = bank.workspace();
        let fused = fuses_stages(&bank, r, kernel.s()).then(|| {
            let extrapolate = predictor == Predictor::Extrapolate;
            fused_maps(kernel, &bank, &coef, &mut ws, system.dim(), extrapolate)
        });
        Ok((bank, coef, fused, ws))
    }

    /// Changes the step size (rebuilds the φ-bank: call it rarely).
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`] and whatever building the φ-bank reports.
    pub fn set_step_size(&mut self, h: f64) -> Result<()> {
        if h == self.h {
            return Ok(());
        }
        let (bank, coef, fused, ws) =
            Self::build_bank(&self.system, &self.kernel, h, self.settings.predictor)?;
        // The concurrent path's workspaces are the new bank's (the old ones go first).
        self.par = None;
        self.par = ParallelState::new(
            &self.kernel,
            &bank,
            self.settings.parallel_min_dim,
            self.system.scratch_len(),
        );
        self.ws = ws;
        self.bank = bank;
        self.coef = coef;
        self.fused = fused;
        self.h = h;
        self.have_previous = false;
        self.newton = None;
        self.theta = 1.0;
        Ok(())
    }

    /// The step size.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// r (order 2r).
    pub fn r(&self) -> usize {
        self.kernel.r()
    }

    /// Number of quadrature points.
    pub fn s(&self) -> usize {
        self.kernel.s()
    }

    /// The fused stage matrices ([`stage_matrices`]: one column-major `sd × sd` matrix, for
    /// [`gemv_cm`]) if this stepper fuses its step ([`fuses_stages`]).
    pub fn stage_matrices(&self) -> Option<&[f64]> {
        self.fused.as_ref().map(|f| f.stage.as_slice())
    }

    /// The step as dense maps, if this stepper fuses it ([`fuses_stages`]).
    pub fn fused_maps(&self) -> Option<&FusedMaps> {
        self.fused.as_ref()
    }

    /// The φ-bank (kernel bank) of the step size: nodes c₁..c_s, then 1 (then 1 + cᵢ with the
    /// extrapolating predictor).
    pub fn bank(&self) -> &<S::Op as LinearOperator>::Bank {
        &self.bank
    }

    /// The kernel.
    pub fn kernel(&self) -> &K {
        &self.kernel
    }

    /// The system.
    pub fn system(&self) -> &S {
        &self.system
    }

    /// The solver settings.
    pub fn settings(&self) -> SolverSettings {
        self.settings
    }

    /// Advances y by one step of size h in place. Allocation-free.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] for a wrong length, [`Error::NonFinite`] if y or g(Y) is
    /// NaN/infinite or the iteration diverges, [`Error::Overflow`] if the stage values or y₁
    /// overflow while the iteration is not diverging (the solution leaves the f64 range within
    /// the step, or h is unstable for it), [`Error::NoConvergence`] if the sweeps do not
    /// converge and [`SweepLimit::Error`] is set. On error, y is unchanged.
    pub fn step(&mut self, y: &mut [f64]) -> Result<StepReport> {
        // One compiled step per stage solver kind and scale, so that the fixed-point sweeps in
        // the global scale (the small steppers' hot path) carry no code of the others.
        let newton = self.settings.solver != StageSolver::FixedPoint;
        if !B::LOCAL_STAGES && self.par.is_some() {
            return self.step_concurrent(y);
        }
        match (newton, self.settings.scale) {
            (false, StageScale::Global) => self.step_with::<false, false, false>(y),
            (false, StageScale::PerComponent { .. }) => self.step_with::<false, true, false>(y),
            (true, StageScale::Global) => self.step_with::<true, false, false>(y),
            (true, StageScale::PerComponent { .. }) => self.step_with::<true, true, false>(y),
        }
    }

    /// [`step`](Self::step) on the concurrent stage path of large systems
    /// ([`SolverSettings::parallel_min_dim`]): compiled apart, so that the serial steps carry
    /// none of its code.
    #[inline(never)]
    fn step_concurrent(&mut self, y: &mut [f64]) -> Result<StepReport> {
        let newton = self.settings.solver != StageSolver::FixedPoint;
        match (newton, self.settings.scale) {
            (false, StageScale::Global) => self.step_with::<false, false, true>(y),
            (false, StageScale::PerComponent { .. }) => self.step_with::<false, true, true>(y),
            (true, StageScale::Global) => self.step_with::<true, false, true>(y),
            (true, StageScale::PerComponent { .. }) => self.step_with::<true, true, true>(y),
        }
    }

    /// [`step`](Self::step) with Newton (`NEWTON`, else fixed-point sweeps) and the
    /// per-component scale (`PER_COMPONENT`, else the global one), as the settings say, on the
    /// concurrent stage path (`PAR`) or the serial one.
    fn step_with<const NEWTON: bool, const PER_COMPONENT: bool, const PAR: bool>(
        &mut self,
        y: &mut [f64],
    ) -> Result<StepReport> {
        // Compile-time constants for fixed-size storage (checked against the kernel and the
        // system when the buffers were made).
        let (m, s, d) = B::SIZES.unwrap_or((self.kernel.r(), self.kernel.s(), self.buf.dim()));
        if y.len() != d {
            return Err(Error::DimensionMismatch {
                what: "state y",
                expected: d,
                found: y.len(),
            });
        }
        if !all_finite(y) {
            return Err(Error::NonFinite("state y"));
        }
        let Stepper {
            kernel,
            system,
            settings,
            bank,
            ws,
            coef,
            scratch,
            fused,
            buf,
            have_previous,
            newton,
            theta,
            par,
            ..
        } = self;
        buf.with_parts(|parts| {
            let BufferParts {
                y0,
                stages,
                new_stages,
                props,
                g,
                moments,
                last,
                comp,
                tmp,
            } = parts;
            // Only a completed step that ended exactly at y may seed the predictor or hand on its
            // rounding error; a failed step leaves no usable previous step.
            let continuing = std::mem::take(have_previous) && *last == *y;
            // The concurrent path (large d; never with fixed-size buffers, which are for small
            // systems). `None` at compile time on the serial path.
            let mut par = if B::LOCAL_STAGES || !PAR {
                None
            } else {
                par.as_deref_mut()
            };
            if !continuing {
                comp.fill(0.0);
            }
            // The contraction seen in the step before (none known after a jump).
            let theta_floor = if continuing { *theta } else { 1.0 };
            let mut theta_step = 0.0_f64;
            let extrapolate = continuing && settings.predictor == Predictor::Extrapolate;
            let mut jacobian_evals = 0;
            let mut jacobian_g_evals = 0;
            let mut lu = if NEWTON {
                let nw = newton.get_or_insert_with(|| {
                    // The fused sweeps' stage matrices where there are some (the same numbers).
                    let q = match fused {
                        Some(f) => f.stage.clone(),
                        None => stage_matrices(&*kernel, &*bank, coef, ws, d),
                    };
                    Box::new(NewtonState::new(q, d))
                });
                // The Jacobian of g at y₀: the system's, or forward differences.
                jacobian_g_evals = jacobian_into(
                    &*system,
                    y,
                    None,
                    &mut nw.jac,
                    scratch,
                    "Jacobian of g at y₀",
                )?;
                jacobian_evals = 1;
                // I − ∂Φ/∂Y at y₀: block (i, k) = δ_ik I − Q_ik J.
                let mut nm = nalgebra::DMatrix::<f64>::identity(s * d, s * d);
                for k in 0..s {
                    subtract_column_block(&mut nm, &nw.q, &nw.jac.jac, k, s, d);
                }
                Some(factor_newton_matrix(nm)?)
            } else {
                None
            };
            let refresh = settings.solver == StageSolver::Newton;
            let mut newton_refreshes = 0;
            let atol = match settings.scale {
                StageScale::PerComponent { atol } => atol,
                StageScale::Global => 1.0,
            };
            // g at every stage. Not checked here: a non-finite g makes the next sweep's stages
            // non-finite, which the residual catches, or, after the last sweep, y₁ (both then
            // check g to name the cause); only g(y₀) is checked at once.
            //
            // `unchanged`: a stage whose value the last sweep left bit for bit as it was, so g
            // there is already in place (g is a function of y). That happens at a node c = 0
            // (Lobatto-type kernels, e.g. RKEPC2), whose stage is y₀ at every sweep: one
            // evaluation of g per sweep saved, results bit-identical.
            let eval_all =
                |stages: &[f64], g: &mut [f64], scratch: &mut [f64], unchanged: Option<usize>| {
                    kernel.each_stage(|j| {
                        if unchanged == Some(j) {
                            return Ok(());
                        }
                        let at = j * d..(j + 1) * d;
                        system.nonlinear(&stages[at.clone()], &mut g[at], scratch);
                        Ok(())
                    })
                };
            let mut g_evals;
            if extrapolate {
                // Start: the previous step's continuous solution at τ = 1 + cᵢ (y₀ and the
                // moments still hold that step's values).
                let pred = (s + 1) * m..(2 * s + 1) * m;
                if let Some(f) = fused {
                    gemv_cm(&f.pred, s * d, [y0, moments], None, stages);
                } else if B::LOCAL_STAGES {
                    bank.combine(s + 1..2 * s + 1, y0, moments, &coef[pred], props, ws);
                    stages.copy_from_slice(props);
                } else if let Some(p) = par.as_deref_mut() {
                    let c = &coef[pred];
                    bank.combine_concurrent(
                        s + 1..2 * s + 1,
                        y0,
                        moments,
                        c,
                        stages,
                        ws,
                        &mut p.helpers,
                    );
                } else {
                    bank.combine(s + 1..2 * s + 1, y0, moments, &coef[pred], stages, ws);
                }
                if let Some(p) = par.as_deref_mut() {
                    system.nonlinear_stages(stages, g, &mut p.scratch, None);
                } else {
                    eval_all(stages, g, scratch, None)?;
                }
                if !all_finite(g) {
                    return Err(Error::NonFinite(G_NONFINITE));
                }
                g_evals = s;
                y0.copy_from_slice(y);
            } else {
                y0.copy_from_slice(y);
                // Start: every stage at y₀, g(y₀) once.
                for j in 0..s {
                    stages[j * d..(j + 1) * d].copy_from_slice(y);
                }
                let (g0, rest) = g.split_at_mut(d);
                system.nonlinear(y, g0, scratch);
                if !all_finite(g0) {
                    return Err(Error::NonFinite(G_NONFINITE));
                }
                for gj in rest.chunks_exact_mut(d) {
                    gj.copy_from_slice(g0);
                }
                g_evals = 1;
            }
            g_evals += jacobian_g_evals;
            let mut sweeps = 0;
            // The last update in the stopping rule's scale and in the global one.
            // (In the global scale the two are the same number: only `previous` is kept.)
            let (mut previous, mut previous_global) = (f64::INFINITY, f64::INFINITY);
            // The stage at a node c = 0, if any (see `eval_all`).
            let origin = kernel.nodes().iter().position(|&c| c == 0.0);
            let fused = fused.as_ref();
            if let Some(f) = fused {
                // e^{cᵢhA} y₀, once per step.
                gemv_cm(&f.props, s * d, [y0, &[]], None, props);
            }
            let (residual, global, converged) = loop {
                // The last update in the global scale.
                let last_global = if PER_COMPONENT {
                    previous_global
                } else {
                    previous
                };
                if let Some(f) = fused {
                    gemv_cm(&f.stage, s * d, [g, &[]], Some(props), new_stages);
                } else if let Some(p) = par.as_deref_mut() {
                    p.moments(g, moments, d);
                    let (c, helpers) = (&coef[..s * m], &mut p.helpers);
                    bank.combine_concurrent(0..s, y0, moments, c, new_stages, ws, helpers);
                } else {
                    kernel.legendre_moments(g, moments, d);
                    if B::LOCAL_STAGES {
                        bank.combine(0..s, y0, moments, &coef[..s * m], props, ws);
                        new_stages.copy_from_slice(props);
                    } else {
                        bank.combine(0..s, y0, moments, &coef[..s * m], new_stages, ws);
                    }
                }
                if let Some(current) = lu.as_ref().filter(|_| NEWTON) {
                    // Newton: Y ← Y + (I − Φ'(Y*))⁻¹ (Φ(Y) − Y), Y* = y₀ or the stages of the
                    // last refresh.
                    let rhs = nalgebra::DVector::from_iterator(
                        s * d,
                        new_stages.iter().zip(stages.iter()).map(|(a, b)| a - b),
                    );
                    let update = newton_apply(current, &rhs, stages, new_stages);
                    // Not contracting by NEWTON_REFRESH_THETA (or not finite): redo the update
                    // with the Jacobians at the current stages. Not at the first iteration,
                    // whose Jacobian is that of y₀, where the stages start.
                    // (False for a NaN update too.)
                    let contracts = update < NEWTON_REFRESH_THETA * last_global;
                    if refresh && sweeps > 0 && !contracts {
                        if let Some(nw) = newton.as_deref_mut() {
                            // Heap copies (a refresh allocates the Newton matrix anyway), so
                            // that fixed-size stage arrays are not handed to a function that
                            // is not inlined.
                            let ys =
                                nalgebra::DVector::from_iterator(s * d, stages.iter().copied());
                            let gs = nalgebra::DVector::from_iterator(s * d, g.iter().copied());
                            drop(lu.take()); // the old factorisation goes before the new one is built
                            let (fresh, evals) = refreshed_newton_lu(
                                &*system,
                                nw,
                                ys.as_slice(),
                                gs.as_slice(),
                                s,
                                d,
                                scratch,
                            )?;
                            newton_apply(&fresh, &rhs, stages, new_stages);
                            lu = Some(fresh);
                            g_evals += evals;
                            jacobian_evals += s;
                            newton_refreshes += 1;
                        }
                    }
                }
                // The scaled max-norm of the update. max |Yᵢ| is taken over the bit patterns:
                // for non-negative floats they order as the values do, and |NaN| orders above
                // ∞, so a NaN or infinite stage makes the residual NaN (`f64::max` would skip
                // NaN); the update's max can skip it (comparisons are cheaper).
                let (mut diff, mut mag) = (0.0_f64, 1.0_f64.to_bits());
                for (a, b) in new_stages.iter().zip(stages.iter()) {
                    let t = (a - b).abs();
                    if t > diff {
                        diff = t;
                    }
                    mag = mag.max(a.abs().to_bits());
                }
                let global = diff / f64::from_bits(mag);
                // The stopping rule's measure (per component: a second pass).
                let residual = if PER_COMPONENT {
                    per_component_update(new_stages, stages, atol)
                } else {
                    global
                };
                let unchanged = origin.filter(|&j| {
                    let at = j * d..(j + 1) * d;
                    new_stages[at.clone()]
                        .iter()
                        .zip(&stages[at])
                        .all(|(a, b)| a.to_bits() == b.to_bits())
                });
                // A copy, not a swap of the two slices: fixed-size stage arrays then stay in
                // registers.
                stages.copy_from_slice(new_stages);
                sweeps += 1;
                if !global.is_finite() {
                    return Err(stage_fault(g, last_global));
                }
                if let Some(p) = par.as_deref_mut() {
                    system.nonlinear_stages(stages, g, &mut p.scratch, unchanged);
                } else {
                    eval_all(stages, g, scratch, unchanged)?;
                }
                g_evals += s - usize::from(unchanged.is_some());
                if previous.is_finite() {
                    theta_step = theta_step.max(residual / previous);
                }
                let converged =
                    if PER_COMPONENT {
                        sweeps_converged_scaled(residual, previous, global, settings.tolerance)
                    } else {
                        sweeps_converged(residual, previous, settings.tolerance)
                    } || y1_converged(residual, previous, theta_floor, settings.tolerance);
                if converged {
                    break (residual, global, true);
                }
                if sweeps >= settings.max_sweeps {
                    break (residual, global, false);
                }
                previous = residual;
                if PER_COMPONENT {
                    previous_global = global;
                }
            };
            if !converged && settings.on_limit == SweepLimit::Error {
                if let Some(what) = g_fault(g, global) {
                    return Err(Error::NonFinite(what));
                }
                return Err(Error::NoConvergence {
                    sweeps,
                    residual,
                    tolerance: settings.tolerance,
                });
            }
            if let Some(p) = par.as_deref_mut() {
                p.moments(g, moments, d);
            } else {
                kernel.legendre_moments(g, moments, d);
            }
            let (hi, rest) = tmp.split_at_mut(d);
            let (lo, ec) = rest.split_at_mut(d);
            if let Some(p) = par {
                let c = &coef[s * m..(s + 1) * m];
                let comp_on = settings.compensated;
                finish_concurrent(
                    bank, p, ws, s, comp_on, y0, moments, c, y, last, comp, hi, lo, ec,
                );
            } else if settings.compensated && bank.propagate_dd(s, y0, hi, lo, ws) {
                // y₁ = e^{hA} y₀ (double-double) + N + e^{hA} c, where N is the nonlinear part and
                // c the rounding error of the previous y₁ (compensated summation). Rounding the
                // f64 state the same way every period of an oscillation, and the f64 propagator,
                // would otherwise make the energy drift linearly (≈ 1e−16 per step).
                if let Some(f) = fused {
                    let (e, kernels) = f.end.split_at(d * d);
                    gemv_cm(kernels, d, [moments, &[]], None, y);
                    gemv_cm(e, d, [comp, &[]], None, ec);
                } else {
                    last.fill(0.0);
                    bank.combine(s..s + 1, last, moments, &coef[s * m..(s + 1) * m], y, ws);
                    bank.apply(s, 0, comp, ec, ws);
                }
                compensated_sum(y, comp, hi, lo, ec);
            } else if let Some(f) = fused {
                gemv_cm(&f.end, d, [y0, moments], None, y);
            } else {
                bank.combine(s..s + 1, y0, moments, &coef[s * m..(s + 1) * m], y, ws);
            }
            if !all_finite(y) {
                y.copy_from_slice(y0);
                // g is not checked per sweep: a non-finite g makes the next stages non-finite
                // (caught by the residual) or, at the last sweep, y₁.
                return Err(
                    g_fault(g, global).map_or(Error::Overflow(Y1_OVERFLOWED), Error::NonFinite)
                );
            }
            last.copy_from_slice(y);
            *have_previous = true;
            *theta = if theta_step > 0.0 {
                theta_step
            } else {
                theta_floor
            };
            Ok(StepReport {
                sweeps,
                residual,
                g_evals,
                converged,
                jacobian_evals,
                newton_refreshes,
            })
        })
    }

    /// Dense output of the last step: ũ(τ) = φ₀(τhA)y₀ + h Σ_k τ^{k+1} φ_{k+1}(τhA) G_k, for
    /// τ ∈ [0, 1] (the method's continuous solution, paper eq. `EEPCr`; evaluated in the
    /// Legendre form of the module docs). Builds a kernel bank for τ, so it allocates: use it
    /// for output, not in a hot loop.
    ///
    /// # Errors
    /// [`Error::NoCompletedStep`] before the first step, after a failed step and after
    /// [`set_step_size`](Self::set_step_size) (the buffers then hold no step of this h),
    /// [`Error::InvalidInput`] for τ outside [0, 1], and whatever building the bank reports.
    pub fn dense_output(&self, tau: f64) -> Result<Vec<f64>> {
        if !self.have_previous {
            return Err(Error::NoCompletedStep);
        }
        if !(0.0..=1.0).contains(&tau) {
            return Err(Error::InvalidInput(format!(
                "dense output needs 0 <= tau <= 1, got {tau:?}"
            )));
        }
        let y0 = self.buf.y0();
        if tau == 0.0 {
            return Ok(y0.to_vec());
        }
        let r = self.kernel.r();
        let mut out = vec![0.0; y0.len()];
        let bank = self.system.linear().kernel_bank(self.h, &[tau], r)?;
        let mut ws = bank.workspace();
        let coef = kernel_coefficients(self.h, &[tau], r);
        bank.combine(0..1, y0, self.buf.moments(), &coef, &mut out, &mut ws);
        Ok(out)
    }
}

/// The combine coefficients of a kernel bank: `h τ (2j+1)` for each node τ and j < r.
fn kernel_coefficients(h: f64, taus: &[f64], r: usize) -> Vec<f64> {
    taus.iter()
        .flat_map(|&t| (0..r).map(move |j| h * t * (2 * j + 1) as f64))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::{all_finite, sweeps_converged, sweeps_converged_scaled, y1_converged};

    #[test]
    fn finiteness_of_every_entry() {
        for n in 0..13 {
            let x: Vec<f64> = (0..n)
                .map(|i| [1.5, -0.0, f64::MAX, -f64::MAX, f64::MIN_POSITIVE][i % 5])
                .collect();
            assert!(all_finite(&x), "n = {n}");
            for i in 0..n {
                for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                    let mut y = x.clone();
                    y[i] = bad;
                    assert!(!all_finite(&y), "n = {n}, entry {i} = {bad}");
                }
            }
        }
    }

    const TOL: f64 = 1e-15;

    #[test]
    fn stopping_rule() {
        let inf = f64::INFINITY;
        // First sweep: the update itself.
        assert!(sweeps_converged(0.0, inf, TOL));
        assert!(sweeps_converged(1e-16, inf, TOL));
        assert!(!sweeps_converged(1e-14, inf, TOL));
        // Slow contraction θ = 0.6: an update of 1e-15 still leaves ≈ 1.5e-15.
        assert!(!sweeps_converged(1e-15, 1e-15 / 0.6, TOL));
        assert!(sweeps_converged(6e-16, 1e-15, TOL));
        // Fast contraction θ = 0.01: the update decides.
        assert!(sweeps_converged(1e-15, 1e-13, TOL));
        assert!(!sweeps_converged(2e-15, 2e-13, TOL));
        // Not contracting (θ ≥ 1): the update decides, and at round-off it is stagnation.
        assert!(sweeps_converged(8e-16, 5e-16, TOL));
        assert!(sweeps_converged(1e-14, 1.05e-14, TOL));
        assert!(sweeps_converged(1e-14, 0.9e-14, TOL));
        // Still halving at round-off level: not stagnation, go on.
        assert!(!sweeps_converged(1e-14, 2e-14, TOL));
        // Far above round-off and not contracting: no.
        assert!(!sweeps_converged(1e-10, 1e-11, TOL));
        // NaN is never convergence (the stepper reports divergence).
        assert!(!sweeps_converged(f64::NAN, 1e-3, TOL));
        assert!(!sweeps_converged(f64::NAN, inf, TOL));
    }

    #[test]
    fn y1_stopping_rule() {
        let inf = f64::INFINITY;
        // Duffing ω = 20, r = 6, h = 1/16: θ ≈ 2.4e-6, e ≈ 3e-16, θe ≈ 7e-22.
        assert!(y1_converged(1.3e-10, 5.5e-5, 0.0, TOL));
        // ... unless the step before saw a slow ratio: θ = 0.3 gives e = 5.6e-11.
        assert!(!y1_converged(1.3e-10, 5.5e-5, 0.3, TOL));
        // θ = 0.01: e = 2e-17, θe = 2e-19 (not within 2^-17 of it); e = 1e-14 is not within
        // the tolerance.
        assert!(!y1_converged(2e-15, 2e-13, 0.0, TOL));
        assert!(!y1_converged(1e-12, 1e-10, 0.0, TOL));
        // θ = 0.3: e = 8.6e-16 within the tolerance, θe = 2.6e-16 not within 2^-17 of it.
        assert!(!y1_converged(2e-15, 2e-15 / 0.3, 0.0, TOL));
        // θ = 0.1: e = 5.6e-16, but θe = 5.6e-17 is not within 2^-17 of the tolerance.
        assert!(!y1_converged(5e-15, 5e-14, 0.0, TOL));
        // θ = 1e-3: e = 1e-17, θe = 1e-20 is not; θ = 1e-4: e = 1e-18, θe = 1e-22 is.
        assert!(!y1_converged(1e-14, 1e-11, 0.0, TOL));
        assert!(y1_converged(1e-14, 1e-10, 0.0, TOL));
        // No contraction known (first sweep), not contracting, or NaN: never.
        assert!(!y1_converged(1e-20, inf, 0.0, TOL));
        assert!(!y1_converged(1e-16, 1e-16, 0.0, TOL));
        assert!(!y1_converged(f64::NAN, 1e-3, 0.0, TOL));
    }

    #[test]
    fn scaled_stopping_rule() {
        let inf = f64::INFINITY;
        // With the global measure equal to the scaled one it is the plain rule.
        for (r, p) in [
            (1e-16, inf),
            (1e-14, 2e-14),
            (8e-16, 5e-16),
            (6e-16, 1e-15),
            (0.3, 0.2),
        ] {
            assert_eq!(
                sweeps_converged_scaled(r, p, r, TOL),
                sweeps_converged(r, p, TOL),
                "{r:e} {p:e}"
            );
        }
        // A component whose own scale sees only noise (0.3, not contracting): stagnation once
        // the whole state is at round-off, not before.
        assert!(sweeps_converged_scaled(0.3, 0.2, 1e-16, TOL));
        assert!(!sweeps_converged_scaled(0.3, 0.2, 1e-12, TOL));
        // Still contracting in its own scale: go on, even at global round-off.
        assert!(!sweeps_converged_scaled(1e-9, 1e-6, 1e-17, TOL));
        // Converged in its own scale.
        assert!(sweeps_converged_scaled(1e-17, 1e-15, 1e-30, TOL));
        assert!(!sweeps_converged_scaled(f64::NAN, 1e-3, f64::NAN, TOL));
    }
}
