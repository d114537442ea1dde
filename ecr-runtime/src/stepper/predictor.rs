//! Where the stage iteration of a step starts ([`Predictor`](super::Predictor)): the previous
//! step's continuous solution extrapolated to the new nodes, or y₀ at every stage, or stage
//! values given for the step ([`Stepper::seed`](super::Stepper::seed)); and when an
//! extrapolated guess that failed is tried again ([`GuessBackoff`]).

use super::buffers::Buffers;
use super::context::StepContext;
use super::gemv::gemv_cm;
use super::kernel::Kernel;
use super::stopping::{G_NONFINITE, all_finite};
use crate::error::{Error, Result};
use crate::operator::PhiBank;
use crate::system::System;

/// When to try the extrapolated guess
/// ([`Predictor::Extrapolate`](super::Predictor::Extrapolate)) again after it failed.
///
/// The guess is only a starting point: where the previous step's continuous solution does not
/// extend well beyond its step (wind, r ≥ 8 at h ≥ 0.25), the iteration from it can diverge
/// where the iteration from y₀ converges. A step whose iteration from the guess fails (an error,
/// or the sweep limit with [`SweepLimit::Error`](super::SweepLimit::Error)) is restarted from
/// y₀; the next `wait` steps then start from y₀, and the guess is tried again after 1, 2, 4, …
/// such steps while it keeps
/// failing (the wait doubles up to [`GuessBackoff::MAX_WAIT`]; a guess that converges resets
/// it). Steps whose guess converges are unchanged, bit for bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct GuessBackoff {
    /// Steps still to start from y₀ before the guess is tried again.
    wait: usize,
    /// The wait after the next failure of the guess.
    next_wait: usize,
}

impl GuessBackoff {
    /// The longest wait: the guess is tried at least once every this many steps, so that a run
    /// whose guess fails only in a stretch of it gets the guess back soon after.
    const MAX_WAIT: usize = 64;

    pub(super) const FRESH: GuessBackoff = GuessBackoff {
        wait: 0,
        next_wait: 1,
    };

    /// Whether this step starts from the guess (else from y₀, counting down the wait).
    pub(super) fn try_guess(&mut self) -> bool {
        if self.wait == 0 {
            return true;
        }
        self.wait -= 1;
        false
    }

    /// The guess failed: wait, and wait twice as long after the next failure.
    pub(super) fn failed(&mut self) {
        self.wait = self.next_wait;
        self.next_wait = (2 * self.next_wait).min(Self::MAX_WAIT);
    }

    /// The guess converged.
    pub(super) fn converged(&mut self) {
        self.next_wait = 1;
    }
}

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

#[cfg(test)]
mod tests {
    use crate::operator::Zero;
    use crate::stepper::{EcStepper, Kernel, Predictor, SolverSettings};
    use crate::system::Semilinear;

    /// Lotka–Volterra at h = 0.78 (g far from linear over a step): a step seeded with its own
    /// stage values from a first run converges at once to the same y₁ (within the stage
    /// tolerance) in fewer sweeps than from y₀; a seed of NaN falls back to y₀ (the same
    /// sweeps and y₁ as an unseeded step, its own work counted); a seed of the wrong length is
    /// an error; a seed serves one step only.
    #[test]
    fn a_seed_starts_one_step_and_a_bad_one_falls_back() {
        let system = Semilinear::new(Zero::new(2), |y: &[f64], g: &mut [f64]| {
            g[0] = y[0] * (2.0 / 3.0 - 4.0 / 3.0 * y[1]);
            g[1] = y[1] * (y[0] - 1.0);
        });
        let settings = SolverSettings {
            predictor: Predictor::Constant,
            ..SolverSettings::default()
        };
        let (r, h, y0) = (4, 0.78, [0.9, 0.9]);
        let mut stepper = EcStepper::with_nodes(&system, r, r, h, settings).unwrap();
        let mut plain = y0;
        let from_y0 = stepper.step(&mut plain).unwrap();
        // The converged stages of that step: its continuous solution at the nodes.
        let nodes = stepper.kernel().nodes().to_vec();
        let mut stages = Vec::new();
        for &c in &nodes {
            stages.extend(stepper.dense_output(c).unwrap());
        }
        let mut seeded = y0;
        stepper.seed(&stages).unwrap();
        let from_seed = stepper.step(&mut seeded).unwrap();
        assert!(
            from_seed.sweeps < from_y0.sweeps,
            "{from_seed:?} vs {from_y0:?}"
        );
        for (a, b) in seeded.iter().zip(&plain) {
            assert!((a - b).abs() <= 1e-13, "{seeded:?} vs {plain:?}");
        }
        // Served once: the next step starts from y₀ again, as the first did.
        let mut again = y0;
        assert_eq!(stepper.step(&mut again).unwrap().sweeps, from_y0.sweeps);
        assert_eq!(again, plain);
        // A seed that fails: from y₀, its work counted besides.
        stepper.seed(&vec![f64::NAN; stages.len()]).unwrap();
        let mut fallback = y0;
        let rep = stepper.step(&mut fallback).unwrap();
        assert_eq!(fallback, plain);
        assert!(rep.g_evals > from_y0.g_evals, "{rep:?} vs {from_y0:?}");
        assert!(stepper.seed(&stages[1..]).is_err());
    }
}
