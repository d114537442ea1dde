//! What a caller sets for the stage iteration ([`SolverSettings`]: tolerance, sweep limit,
//! predictor, fixed point or Newton, scale, compensated update, concurrent path) and what a
//! step reports ([`StepReport`]).

use crate::error::{Error, Result};

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
    /// A guess whose iteration fails (diverges, or reaches the sweep limit with
    /// [`SweepLimit::Error`]) does not fail the step: the step is restarted from y₀, and the
    /// guess is tried again after 1, 2, 4, … steps from y₀ while it keeps failing (wind, r ≥ 8
    /// at h ≥ 0.25: issue 28); the work of the failed iteration is counted in the
    /// [`StepReport`]. Steps whose guess converges are unchanged.
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
    /// Newton with a refreshed Jacobian where the simplified iteration stalls: each step starts as
    /// simplified Newton, `Y ← Y + (I − Φ'(y₀))⁻¹ (Φ(Y) − Y)`, with the Jacobian J of g at y₀ from
    /// [`System::jacobian`](crate::system::System::jacobian) or, where that is not provided,
    /// forward differences (d more evaluations of g). When an iteration's update is not at least
    /// [`NEWTON_REFRESH_THETA`](super::NEWTON_REFRESH_THETA) times the previous one (or is not
    /// finite), the update is discarded and redone with the Jacobians at the current stages, block
    /// (i, k) of the Newton matrix `δ_ik I − Q_ik J(Y_k)` (full Newton at that iterate; s
    /// Jacobians, and with forward differences s·d more evaluations of g); that matrix is then kept
    /// while the iteration contracts. A step on which the simplified iteration contracts costs what
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

/// How the stopping rule measures a stage update ΔY (see
/// [`sweeps_converged`](super::sweeps_converged)).
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
    /// ‖ΔY‖∞ / max(floor, ‖Y‖∞): [`Global`](Self::Global) with another floor (Global's is 1):
    /// relative to the largest stage component down to `floor` (> 0, finite), absolute below.
    /// `solve` takes floor = atol/rtol (at most 1) when its tolerance is mostly relative, so
    /// that a state of size 1e−100 solved with rtol alone converges relative to its own size,
    /// as one of size 1 does. As cheap as Global.
    GlobalFloor {
        /// States smaller than this are measured absolutely.
        floor: f64,
    },
    /// `max_i |ΔY_i| / max(|Y_i|, atol)`: each component relative to itself, absolute below `atol`
    /// (> 0, finite). For states whose components differ in size by many orders of magnitude.
    /// Components whose own rounding error is far above ε in their own scale (near zero, or
    /// computed from much larger components) cannot reach this test; the iteration then ends by
    /// round-off stagnation measured in the global scale
    /// ([`sweeps_converged_scaled`](super::sweeps_converged_scaled)). One more comparison per
    /// component and sweep. The ECrP stepper (and TCrP/RKNCrP, which run on it); the baselines
    /// reject it.
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
    /// [`sweeps_converged`](super::sweeps_converged)).
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
    /// Form y₁ with the propagator in double-double and carry its rounding error to the next step
    /// (compensated summation), where the kernel bank supports it
    /// ([`PhiBank::propagate_dd`](crate::operator::PhiBank::propagate_dd); see the module docs). On
    /// by default: it removes the round-off drift of the energy in long runs for a few more
    /// operations per step.
    pub compensated: bool,
    /// Systems of this dimension d or more run the independent work of each step's stages
    /// concurrently on rayon's thread pool: g at the s stages
    /// ([`System::nonlinear_stages`](crate::system::System::nonlinear_stages), concurrent where the
    /// system allows it), the bank's `combine` over the stage nodes
    /// ([`PhiBank::combine_concurrent`](crate::operator::PhiBank::combine_concurrent): for the FFT
    /// operators the inputs' transforms, then the nodes' inverse transforms) and the end of the
    /// step ([`PhiBank::join`](crate::operator::PhiBank::join)). The results are bit for bit those
    /// of the serial path. Default [`PARALLEL_MIN_DIM`], measured; `usize::MAX`: always serial.
    /// Smaller systems take the serial path unchanged.
    pub parallel_min_dim: usize,
    /// The arithmetic of the φ-banks
    /// ([`LinearOperator::kernel_bank_in`](crate::operator::LinearOperator::kernel_bank_in)):
    /// [`BankArithmetic::Extended`](crate::operator::BankArithmetic::Extended) (the default)
    /// or f64 where the bank's error is far below what the steps are used for.
    pub banks: crate::operator::BankArithmetic,
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
            banks: crate::operator::BankArithmetic::Extended,
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
        if let StageScale::GlobalFloor { floor } = self.scale {
            if !(floor.is_finite() && floor > 0.0) {
                return Err(Error::InvalidParameter(format!(
                    "StageScale::GlobalFloor needs a finite floor > 0 (got {floor:?})"
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
            banks: crate::operator::BankArithmetic::Extended,
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
