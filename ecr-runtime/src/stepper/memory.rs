//! The memory a stepper takes, before it is built: for refusing a run that cannot get it in
//! one line instead of aborting when an allocation fails part-way.

use super::fused::FUSED_MAX_ENTRIES;
use super::newton::newton_entries;
use super::settings::{Predictor, SolverSettings, StageSolver};
use crate::operator::LinearOperator;
use crate::system::System;

/// The memory of an [`EcStepper`](super::EcStepper) (or [`SizedEcStepper`](super::SizedEcStepper)),
/// from [`ec_stepper_bytes`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StepperBytes {
    /// What the stepper holds: its buffers, kernel bank, workspaces and the rest (see
    /// [`ec_stepper_bytes`]).
    pub held: usize,
    /// Its kernel bank alone: [`set_step_size`](super::Stepper::set_step_size) builds the
    /// new bank before the old one goes, so a change of step size needs this much more while
    /// it runs.
    pub bank: usize,
}

impl StepperBytes {
    /// The peak of several steppers held at once whose step sizes change one at a time: what
    /// they hold together and the largest bank once more. `None` on overflow.
    pub fn peak_of(steppers: &[StepperBytes]) -> Option<usize> {
        let held = steppers
            .iter()
            .try_fold(0usize, |acc, s| acc.checked_add(s.held))?;
        held.checked_add(steppers.iter().map(|s| s.bank).max().unwrap_or(0))
    }
}

/// The bytes an [`EcStepper`](super::EcStepper) (or [`SizedEcStepper`](super::SizedEcStepper))
/// of `system` with r moments and s nodes allocates with `settings`, or `None` if the count
/// overflows a `usize`:
///
/// - its buffers, `(4s + r + 6) d` numbers, and the system's scratch;
/// - its kernel bank ([`LinearOperator::bank_bytes`]: s + 1 nodes, 2s + 1 with
///   [`Predictor::Extrapolate`]; r kernels) and the bank's workspace;
/// - from d = `settings.parallel_min_dim` on, the concurrent stage path's workspaces (one per
///   task: rayon's threads, at least 2 and at most max(s, r + 1)) and scratch (this starts
///   rayon's pool, as the stepper would);
/// - the fused step maps of a small system (at most `FUSED_MAX_ENTRIES` numbers) and, with
///   [`StageSolver::Newton`], its `2s²d² + 2d² + 3sd` numbers.
///
/// A solve holds several steppers at once (the answer, its checks and the dense output's):
/// its peak is [`StepperBytes::peak_of`] theirs. Compare it with what can be had with
/// [`ensure_bytes_allocatable`](crate::storage::ensure_bytes_allocatable).
pub fn ec_stepper_bytes<S: System>(
    system: &S,
    r: usize,
    s: usize,
    settings: &SolverSettings,
) -> Option<StepperBytes> {
    let d = system.dim();
    let scratch = system.scratch_len();
    let len = if settings.predictor == Predictor::Extrapolate {
        s.checked_mul(2)?.checked_add(1)?
    } else {
        s.checked_add(1)?
    };
    let (bank, workspace) = system.linear().bank_bytes(len, r)?;
    let buffers = s
        .checked_mul(4)?
        .checked_add(r)?
        .checked_add(6)?
        .checked_mul(d)?
        .checked_add(scratch)?
        .checked_mul(8)?;
    let concurrent = if d >= settings.parallel_min_dim {
        let tasks = rayon::current_num_threads().clamp(2, s.max(r + 1).max(2));
        tasks
            .checked_mul(workspace)?
            .checked_add(s.checked_mul(scratch)?.checked_mul(8)?)?
    } else {
        0
    };
    let sd = s.checked_mul(d)?;
    let fused = match sd.checked_mul(sd) {
        Some(e) if e <= FUSED_MAX_ENTRIES => 2 * FUSED_MAX_ENTRIES.min(e + 4 * sd + 4 * d) * 8,
        _ => 0,
    };
    let newton = if settings.solver == StageSolver::FixedPoint {
        0
    } else {
        newton_entries(s, d)?.checked_mul(8)?
    };
    let held = bank
        .checked_add(workspace)?
        .checked_add(buffers)?
        .checked_add(concurrent)?
        .checked_add(fused)?
        .checked_add(newton)?;
    Some(StepperBytes { held, bank })
}
