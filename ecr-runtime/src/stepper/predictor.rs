//! Where the stage iteration of a step starts ([`Predictor`](super::Predictor)): the previous
//! step's continuous solution extrapolated to the new nodes, or y₀ at every stage.

use super::buffers::Buffers;
use super::context::StepContext;
use super::gemv::gemv_cm;
use super::kernel::Kernel;
use super::stopping::{G_NONFINITE, all_finite};
use crate::error::{Error, Result};
use crate::operator::PhiBank;
use crate::system::System;

impl<K: Kernel, S: System, B: Buffers> StepContext<'_, K, S, B> {
    /// The first iterate of the stages and g there; `y0` = y. With `extrapolate`, the
    /// previous step's continuous solution at τ = 1 + cᵢ (`y0` and `moments` still hold that
    /// step's values when called); otherwise every stage at y and g(y) evaluated once. Returns
    /// the evaluations of g.
    ///
    /// # Errors
    /// [`Error::NonFinite`] if g is not finite there.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn start(
        &mut self,
        extrapolate: bool,
        y: &[f64],
        y0: &mut [f64],
        moments: &[f64],
        stages: &mut [f64],
        props: &mut [f64],
        g: &mut [f64],
    ) -> Result<usize> {
        let (m, s, d) = self.sizes;
        if extrapolate {
            let pred = (s + 1) * m..(2 * s + 1) * m;
            if let Some(f) = self.fused {
                gemv_cm(&f.pred, s * d, [y0, moments], None, stages);
            } else if B::LOCAL_STAGES {
                let c = &self.coef[pred];
                self.bank
                    .combine(s + 1..2 * s + 1, y0, moments, c, props, self.ws);
                stages.copy_from_slice(props);
            } else if let Some(p) = self.par.as_deref_mut() {
                let c = &self.coef[pred];
                self.bank.combine_concurrent(
                    s + 1..2 * s + 1,
                    y0,
                    moments,
                    c,
                    stages,
                    self.ws,
                    &mut p.helpers,
                );
            } else {
                let c = &self.coef[pred];
                self.bank
                    .combine(s + 1..2 * s + 1, y0, moments, c, stages, self.ws);
            }
            self.eval_stages(stages, g, None)?;
            if !all_finite(g) {
                return Err(Error::NonFinite(G_NONFINITE));
            }
            y0.copy_from_slice(y);
            Ok(s)
        } else {
            y0.copy_from_slice(y);
            // Every stage at y₀, g(y₀) once.
            for j in 0..s {
                stages[j * d..(j + 1) * d].copy_from_slice(y);
            }
            let (g0, rest) = g.split_at_mut(d);
            self.system.nonlinear(y, g0, self.scratch);
            if !all_finite(g0) {
                return Err(Error::NonFinite(G_NONFINITE));
            }
            for gj in rest.chunks_exact_mut(d) {
                gj.copy_from_slice(g0);
            }
            Ok(1)
        }
    }

    /// The first iterate from given stage values ([`Stepper::seed`](super::Stepper::seed)),
    /// g there; `y0` = y. A stage at a node c = 0 is y. Returns the evaluations of g.
    ///
    /// # Errors
    /// [`Error::NonFinite`] if g is not finite there.
    pub(super) fn start_seeded(
        &mut self,
        seed: &[f64],
        y: &[f64],
        y0: &mut [f64],
        stages: &mut [f64],
        g: &mut [f64],
    ) -> Result<usize> {
        let (_, s, d) = self.sizes;
        stages.copy_from_slice(seed);
        for (j, &c) in self.kernel.nodes().iter().enumerate() {
            if c == 0.0 {
                stages[j * d..(j + 1) * d].copy_from_slice(y);
            }
        }
        self.eval_stages(stages, g, None)?;
        if !all_finite(g) {
            return Err(Error::NonFinite(G_NONFINITE));
        }
        y0.copy_from_slice(y);
        Ok(s)
    }
}
