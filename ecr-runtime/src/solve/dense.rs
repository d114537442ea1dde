//! The solution between grid points: the run's method stepped from a grid point.

use std::sync::Arc;

use super::SolveCache;
use crate::error::Result;
use crate::stepper::{EcStepper, Predictor, SolverSettings};
use crate::system::System;

/// Steps from a grid point to a time between grid points: `n` steps of (distance / n) of
/// ECrP of order 2r, the stages started from the grid state (constant predictor, as the
/// steps do not continue a run). The stepper is kept between calls; its φ-bank is rebuilt
/// for each new distance.
pub(super) struct DenseStep<'a, S: System> {
    system: &'a S,
    r: usize,
    settings: SolverSettings,
    stepper: Option<EcStepper<&'a S>>,
    cache: Arc<SolveCache<S>>,
}

impl<'a, S: System> DenseStep<'a, S> {
    pub(super) fn new(
        system: &'a S,
        r: usize,
        settings: SolverSettings,
        cache: &Arc<SolveCache<S>>,
    ) -> Self {
        DenseStep {
            cache: Arc::clone(cache),
            system,
            r,
            settings: SolverSettings {
                predictor: Predictor::Constant,
                ..settings
            },
            stepper: None,
        }
    }

    /// `out` = the state `n` steps of `dt / n` after `from`; returns (steps, g-evaluations).
    pub(super) fn advance(
        &mut self,
        from: &[f64],
        dt: f64,
        n: usize,
        out: &mut [f64],
    ) -> Result<(usize, usize)> {
        out.copy_from_slice(from);
        if dt <= 0.0 {
            return Ok((0, 0));
        }
        let h = dt / n as f64;
        let stepper = match &mut self.stepper {
            Some(st) => {
                st.set_step_size(h)?;
                st
            }
            slot => slot.insert(EcStepper::with_nodes_cached(
                self.system,
                (self.r, self.r),
                h,
                self.settings,
                &self.cache,
            )?),
        };
        let mut g = 0;
        for _ in 0..n {
            g += stepper.step(out)?.g_evals;
        }
        Ok((n, g))
    }
}
