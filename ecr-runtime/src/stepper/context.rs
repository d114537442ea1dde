//! What one step works with: [`StepContext`], borrowed from the stepper for the length of a
//! step. The parts of a step are its methods, each in the file named after it: where the
//! stage iteration starts (`predictor.rs`), the sweeps (`iteration.rs`, Newton's update in
//! `newton.rs`) and the step formula (`finish.rs`); `step.rs` calls them in that order.

use std::marker::PhantomData;

use super::buffers::Buffers;
use super::fused::FusedMaps;
use super::kernel::Kernel;
use super::parallel::ParallelState;
use super::settings::SolverSettings;
use crate::error::Result;
use crate::operator::{LinearOperator, PhiBank};
use crate::system::System;

/// The kernel bank of a system's linear operator.
pub(super) type Bank<S> = <<S as System>::Op as LinearOperator>::Bank;

/// The workspace of a system's kernel bank.
pub(super) type BankWorkspace<S> = <Bank<S> as PhiBank>::Workspace;

/// The stepper's parts that one step reads (the kernel, the system, the settings, the bank for
/// h and its combine coefficients, the fused maps) and the workspaces it writes, with the
/// sizes (r, s, d), compile-time constants for fixed-size buffers `B`.
pub(super) struct StepContext<'a, K: Kernel, S: System, B: Buffers> {
    pub(super) kernel: &'a K,
    pub(super) system: &'a S,
    pub(super) settings: &'a SolverSettings,
    pub(super) bank: &'a Bank<S>,
    pub(super) ws: &'a mut BankWorkspace<S>,
    /// The combine coefficients of the bank's nodes (see [`Stepper`](super::Stepper)).
    pub(super) coef: &'a [f64],
    /// Scratch for g ([`System::scratch_len`]).
    pub(super) scratch: &'a mut [f64],
    /// The step as dense maps, where the stepper fuses it.
    pub(super) fused: Option<&'a FusedMaps>,
    /// The concurrent stage path's state; `None` on the serial path (always with fixed-size
    /// buffers).
    pub(super) par: Option<&'a mut ParallelState<BankWorkspace<S>>>,
    /// (r, s, d).
    pub(super) sizes: (usize, usize, usize),
    pub(super) buffers: PhantomData<fn() -> B>,
}

impl<K: Kernel, S: System, B: Buffers> StepContext<'_, K, S, B> {
    /// g at every stage into `g`, except at the stage `unchanged` (whose value the last sweep
    /// left bit for bit as it was: g there is already in place). Concurrent on the concurrent
    /// path ([`System::nonlinear_stages`]). Not checked for finiteness here: a non-finite g
    /// makes the next sweep's stages non-finite, which the residual catches, or, after the
    /// last sweep, y₁ (both then check g to name the cause).
    #[inline(always)]
    pub(super) fn eval_stages(
        &mut self,
        stages: &[f64],
        g: &mut [f64],
        unchanged: Option<usize>,
    ) -> Result<()> {
        if let Some(p) = self.par.as_deref_mut() {
            self.system
                .nonlinear_stages(stages, g, &mut p.scratch, unchanged);
            return Ok(());
        }
        let (system, scratch, (_, s, d)) = (self.system, &mut *self.scratch, self.sizes);
        self.kernel.each_stage_sized(s, |j| {
            if unchanged == Some(j) {
                return Ok(());
            }
            let at = j * d..(j + 1) * d;
            system.nonlinear(&stages[at.clone()], &mut g[at], scratch);
            Ok(())
        })
    }
}
