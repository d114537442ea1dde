//! The stage iteration: sweeps `Y ← Φ(Y)` (fixed point, or Newton's update of it) until the
//! stopping rule holds ([`sweeps_converged`], [`y1_converged`]).

use super::buffers::Buffers;
use super::context::StepContext;
use super::gemv::gemv_cm;
use super::kernel::Kernel;
use super::newton::NewtonStep;
use super::settings::StageScale;
use super::stopping::{
    global_update, per_component_update, stage_fault, sweeps_converged, sweeps_converged_scaled,
    y1_converged,
};
use crate::error::Result;
use crate::operator::PhiBank;
use crate::system::System;

/// How the stage iteration of a step ended (the work done is in [`Effort`]).
pub(super) struct Iteration {
    /// The last update in the stopping rule's scale.
    pub(super) residual: f64,
    /// The last update in the global scale.
    pub(super) global: f64,
    /// Whether the stopping rule held (else the sweep limit was reached).
    pub(super) converged: bool,
    /// The largest ratio of consecutive updates (0 if there was one sweep).
    pub(super) theta_step: f64,
}

/// The work of a stage iteration so far, kept up to date sweep by sweep, so that a step counts
/// also the work of an iteration that failed (and was restarted from y₀).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Effort {
    /// Sweeps done.
    pub(super) sweeps: usize,
    /// Evaluations of g in the sweeps.
    pub(super) g_evals: usize,
}

impl<K: Kernel, S: System, B: Buffers> StepContext<'_, K, S, B> {
    /// `new_stages = Φ(Y)` for g at the stages `Y`: the stage formula at the nodes, from the
    /// moments of g and a `combine` of the bank (the moments are left in `moments`), or one
    /// product with the fused stage matrices plus the propagated starts `props`.
    #[inline(always)]
    fn map_stages(
        &mut self,
        y0: &[f64],
        g: &[f64],
        moments: &mut [f64],
        props: &mut [f64],
        new_stages: &mut [f64],
    ) {
        let (m, s, d) = self.sizes;
        let coef = &self.coef[..s * m];
        if let Some(f) = self.fused {
            gemv_cm(&f.stage, s * d, [g, &[]], Some(props), new_stages);
        } else if let Some(p) = self.par.as_deref_mut() {
            p.moments(g, moments, d);
            let helpers = &mut p.helpers;
            self.bank
                .combine_concurrent(0..s, y0, moments, coef, new_stages, self.ws, helpers);
        } else {
            self.kernel.legendre_moments_sized(g, moments, self.sizes);
            if B::LOCAL_STAGES {
                self.bank.combine(0..s, y0, moments, coef, props, self.ws);
                new_stages.copy_from_slice(props);
            } else {
                self.bank
                    .combine(0..s, y0, moments, coef, new_stages, self.ws);
            }
        }
    }

    /// Sweeps from the first iterate in `stages` (g there in `g`) until the stopping rule
    /// holds or the sweep limit is reached; each sweep's update measured in the settings'
    /// scale (`per_component`, else the global one), corrected by Newton where `newton` is
    /// given. Always inlined: where the caller's flags are constants, the code of the other
    /// choices is gone.
    /// `theta_floor` is the contraction seen in the step before (1 if none is known). `effort`
    /// receives the sweeps and evaluations of g done, also when the iteration fails.
    ///
    /// # Errors
    /// As [`stage_fault`] when the stages become non-finite; Newton's errors.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn iterate(
        &mut self,
        per_component: bool,
        y0: &[f64],
        stages: &mut [f64],
        new_stages: &mut [f64],
        props: &mut [f64],
        g: &mut [f64],
        moments: &mut [f64],
        theta_floor: f64,
        mut newton: Option<&mut NewtonStep<'_>>,
        effort: &mut Effort,
    ) -> Result<Iteration> {
        let (_, s, d) = self.sizes;
        let (tolerance, max_sweeps) = (self.settings.tolerance, self.settings.max_sweeps);
        let (atol, floor) = match self.settings.scale {
            StageScale::PerComponent { atol } => (atol, 1.0),
            StageScale::Global => (1.0, 1.0),
            StageScale::GlobalFloor { floor } => (1.0, floor),
        };
        let (mut sweeps, mut g_evals, mut theta_step) = (0, 0, 0.0_f64);
        // The last update in the stopping rule's scale and in the global one.
        // (In the global scale the two are the same number: only `previous` is kept.)
        let (mut previous, mut previous_global) = (f64::INFINITY, f64::INFINITY);
        // The stage at a node c = 0, if any (Lobatto-type kernels, e.g. RKEPC2): its value is
        // y₀ at every sweep, so g there is already in place (g is a function of y): one
        // evaluation of g per sweep saved, results bit-identical.
        let origin = self.kernel.nodes().iter().position(|&c| c == 0.0);
        if let Some(f) = self.fused {
            // e^{cᵢhA} y₀, once per step.
            gemv_cm(&f.props, s * d, [y0, &[]], None, props);
        }
        loop {
            // The last update in the global scale.
            let last_global = if per_component {
                previous_global
            } else {
                previous
            };
            self.map_stages(y0, g, moments, props, new_stages);
            if let Some(nt) = newton.as_deref_mut() {
                let (system, scratch) = (self.system, &mut *self.scratch);
                let first = sweeps == 0;
                nt.update(
                    system,
                    scratch,
                    stages,
                    new_stages,
                    g,
                    first,
                    last_global,
                    s,
                    d,
                )?;
            }
            let global = global_update(new_stages, stages, floor);
            // The stopping rule's measure (per component: a second pass).
            let residual = if per_component {
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
                effort.sweeps = sweeps;
                return Err(stage_fault(g, last_global));
            }
            self.eval_stages(stages, g, unchanged)?;
            g_evals += s - usize::from(unchanged.is_some());
            *effort = Effort { sweeps, g_evals };
            if previous.is_finite() {
                theta_step = theta_step.max(residual / previous);
            }
            let converged = if per_component {
                sweeps_converged_scaled(residual, previous, global, tolerance)
            } else {
                sweeps_converged(residual, previous, tolerance)
            } || y1_converged(residual, previous, theta_floor, tolerance);
            if converged || sweeps >= max_sweeps {
                return Ok(Iteration {
                    residual,
                    global,
                    converged,
                    theta_step,
                });
            }
            previous = residual;
            if per_component {
                previous_global = global;
            }
        }
    }
}
