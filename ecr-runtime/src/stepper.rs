//! The ECrP stepper (paper eq. `PEEPCr`, DESIGN.md §2) for any r and s ≥ r, chosen at run time.
//!
//! ```text
//! G_k = Σ_j w_kj g(Y_j),                                 k = 0..r−1
//! Y_i = φ₀(cᵢhA) y₀ + h Σ_k cᵢ^{k+1} φ_{k+1}(cᵢhA) G_k,   i = 1..s   (fixed-point sweeps)
//! y₁  = φ₀(hA) y₀  + h Σ_k φ_{k+1}(hA) G_k
//! ```
//!
//! The φ-bank for the nodes and τ = 1 is built once per step size; a step allocates nothing.

use crate::operator::{LinearOperator, PhiBank};
use crate::system::System;
use crate::tables::{Coefficients, coefficients};
use crate::{Error, Result};
use std::sync::Arc;

/// Scaled stage updates at or below this (100 ε) count as round-off: when the update stops
/// decreasing there, the iteration has converged as far as f64 allows.
pub const ROUNDOFF_RESIDUAL: f64 = 100.0 * f64::EPSILON;

/// What to do when the stage equations have not converged after the allowed sweeps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SweepLimit {
    /// Return [`Error::NoConvergence`] (the default).
    Error,
    /// Accept the stages after the last sweep, as the paper does ("at most N iterations").
    Accept,
}

/// Settings of the fixed-point stage solver.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolverSettings {
    /// Stop when the scaled max-norm of the stage update ‖ΔY‖∞ / max(1, ‖Y‖∞) is ≤ this, or
    /// when it stagnates at round-off level (≤ [`ROUNDOFF_RESIDUAL`] and no longer halving).
    pub tolerance: f64,
    /// Maximum number of sweeps per step.
    pub max_sweeps: usize,
    /// What happens at the sweep limit.
    pub on_limit: SweepLimit,
}

impl Default for SolverSettings {
    /// Tolerance 1e−15, at most 100 sweeps, error at the limit.
    fn default() -> Self {
        SolverSettings {
            tolerance: 1e-15,
            max_sweeps: 100,
            on_limit: SweepLimit::Error,
        }
    }
}

impl SolverSettings {
    /// The paper's setting (§9): tolerance 1e−16, at most 5 sweeps, accepted at the limit.
    pub fn paper() -> Self {
        SolverSettings {
            tolerance: 1e-16,
            max_sweeps: 5,
            on_limit: SweepLimit::Accept,
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
}

/// ECrP with r moments and s Gauss–Legendre points for a [`System`], run-time r.
pub struct EcStepper<S: System> {
    system: S,
    coeffs: Arc<Coefficients>,
    settings: SolverSettings,
    h: f64,
    bank: <S::Op as LinearOperator>::Bank,
    ws: <<S::Op as LinearOperator>::Bank as PhiBank>::Workspace,
    /// (s + 1) × r: h τᵢ^{k+1}, τ = c₁..c_s, 1.
    coef: Vec<f64>,
    y0: Vec<f64>,
    stages: Vec<f64>,
    new_stages: Vec<f64>,
    g_vals: Vec<f64>,
    moments: Vec<f64>,
    scratch: Vec<f64>,
}

impl<S: System> EcStepper<S> {
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
        if settings.tolerance.is_nan() || settings.tolerance < 0.0 || settings.max_sweeps == 0 {
            return Err(Error::InvalidParameter(format!(
                "solver settings need tolerance >= 0 and max_sweeps >= 1 (got {settings:?})"
            )));
        }
        let coeffs = coefficients(r, s)?;
        let d = system.dim();
        let (bank, coef) = Self::build_bank(&system, &coeffs, h)?;
        let ws = bank.workspace();
        Ok(EcStepper {
            scratch: vec![0.0; system.scratch_len()],
            system,
            settings,
            h,
            bank,
            ws,
            coef,
            y0: vec![0.0; d],
            stages: vec![0.0; s * d],
            new_stages: vec![0.0; s * d],
            g_vals: vec![0.0; s * d],
            moments: vec![0.0; r * d],
            coeffs,
        })
    }

    fn build_bank(
        system: &S,
        c: &Coefficients,
        h: f64,
    ) -> Result<(<S::Op as LinearOperator>::Bank, Vec<f64>)> {
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidStepSize(h));
        }
        let mut taus = c.nodes.clone();
        taus.push(1.0);
        let bank = system.linear().phi_bank(h, &taus, c.r)?;
        let coef = taus
            .iter()
            .flat_map(|&t| (0..c.r).map(move |k| h * t.powi(k as i32 + 1)))
            .collect();
        Ok((bank, coef))
    }

    /// Changes the step size (rebuilds the φ-bank: call it rarely).
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`] and whatever building the φ-bank reports.
    pub fn set_step_size(&mut self, h: f64) -> Result<()> {
        if h == self.h {
            return Ok(());
        }
        let (bank, coef) = Self::build_bank(&self.system, &self.coeffs, h)?;
        self.ws = bank.workspace();
        self.bank = bank;
        self.coef = coef;
        self.h = h;
        Ok(())
    }

    /// The step size.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// r (order 2r).
    pub fn r(&self) -> usize {
        self.coeffs.r
    }

    /// Number of quadrature points.
    pub fn s(&self) -> usize {
        self.coeffs.s
    }

    /// The system.
    pub fn system(&self) -> &S {
        &self.system
    }

    /// The solver settings.
    pub fn settings(&self) -> SolverSettings {
        self.settings
    }

    fn eval_g(&mut self, j: usize) -> Result<()> {
        let d = self.y0.len();
        let (y, out) = (
            &self.stages[j * d..(j + 1) * d],
            &mut self.g_vals[j * d..(j + 1) * d],
        );
        self.system.nonlinear(y, out, &mut self.scratch);
        if out.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("g(Y) at a stage"));
        }
        Ok(())
    }

    fn update_moments(&mut self) {
        let (r, s, d) = (self.coeffs.r, self.coeffs.s, self.y0.len());
        let w = &self.coeffs.w;
        for k in 0..r {
            let gk = &mut self.moments[k * d..(k + 1) * d];
            gk.fill(0.0);
            for j in 0..s {
                let wkj = w[k * s + j];
                for (m, g) in gk.iter_mut().zip(&self.g_vals[j * d..(j + 1) * d]) {
                    *m += wkj * g;
                }
            }
        }
    }

    /// Advances y by one step of size h in place. Allocation-free.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] for a wrong length, [`Error::NonFinite`] if y or g(Y) is
    /// NaN/infinite, [`Error::NoConvergence`] if the sweeps do not converge and
    /// [`SweepLimit::Error`] is set. On error, y is unchanged.
    pub fn step(&mut self, y: &mut [f64]) -> Result<StepReport> {
        let (s, d) = (self.coeffs.s, self.y0.len());
        let m = self.coeffs.r;
        if y.len() != d {
            return Err(Error::DimensionMismatch {
                what: "state y",
                expected: d,
                found: y.len(),
            });
        }
        if y.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("state y"));
        }
        self.y0.copy_from_slice(y);
        // Start: every stage at y₀, g(y₀) once.
        for j in 0..s {
            self.stages[j * d..(j + 1) * d].copy_from_slice(y);
        }
        self.eval_g(0)?;
        for j in 1..s {
            let (first, rest) = self.g_vals.split_at_mut(j * d);
            rest[..d].copy_from_slice(&first[..d]);
        }
        let mut g_evals = 1;
        let mut sweeps = 0;
        let mut previous = f64::INFINITY;
        let (residual, converged) = loop {
            self.update_moments();
            self.bank.combine(
                0..s,
                &self.y0,
                &self.moments,
                &self.coef[..s * m],
                &mut self.new_stages,
                &mut self.ws,
            );
            let mut diff: f64 = 0.0;
            let mut mag: f64 = 1.0;
            for (a, b) in self.new_stages.iter().zip(&self.stages) {
                diff = diff.max((a - b).abs());
                mag = mag.max(a.abs());
            }
            let residual = diff / mag;
            std::mem::swap(&mut self.stages, &mut self.new_stages);
            sweeps += 1;
            for j in 0..s {
                self.eval_g(j)?;
            }
            g_evals += s;
            if !residual.is_finite() {
                return Err(Error::NonFinite(
                    "stage values (the fixed-point iteration diverged)",
                ));
            }
            // Converged: the tolerance is met, or the update has stagnated at round-off level
            // (no longer halving while within ROUNDOFF_RESIDUAL), where further sweeps only
            // move the last bits.
            let stagnated = residual <= ROUNDOFF_RESIDUAL && residual > 0.5 * previous;
            if residual <= self.settings.tolerance || stagnated {
                break (residual, true);
            }
            if sweeps >= self.settings.max_sweeps {
                break (residual, false);
            }
            previous = residual;
        };
        if !converged && self.settings.on_limit == SweepLimit::Error {
            return Err(Error::NoConvergence {
                sweeps,
                residual,
                tolerance: self.settings.tolerance,
            });
        }
        self.update_moments();
        self.bank.combine(
            s..s + 1,
            &self.y0,
            &self.moments,
            &self.coef[s * m..],
            y,
            &mut self.ws,
        );
        if y.iter().any(|v| !v.is_finite()) {
            y.copy_from_slice(&self.y0);
            return Err(Error::NonFinite("new state y₁"));
        }
        Ok(StepReport {
            sweeps,
            residual,
            g_evals,
            converged,
        })
    }

    /// Dense output of the last step: ũ(τ) = φ₀(τhA)y₀ + h Σ_k τ^{k+1} φ_{k+1}(τhA) G_k, for
    /// τ ∈ [0, 1] (the method's continuous solution, paper eq. `EEPCr`). Builds a φ-bank for τ,
    /// so it allocates: use it for output, not in a hot loop.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] for τ outside [0, 1], and whatever building the bank reports.
    pub fn dense_output(&self, tau: f64) -> Result<Vec<f64>> {
        if !(0.0..=1.0).contains(&tau) {
            return Err(Error::InvalidInput(format!(
                "dense output needs 0 <= tau <= 1, got {tau}"
            )));
        }
        let d = self.y0.len();
        let r = self.coeffs.r;
        let mut out = vec![0.0; d];
        if tau == 0.0 {
            out.copy_from_slice(&self.y0);
            return Ok(out);
        }
        let bank = self.system.linear().phi_bank(self.h, &[tau], r)?;
        let mut ws = bank.workspace();
        let coef: Vec<f64> = (0..r).map(|k| self.h * tau.powi(k as i32 + 1)).collect();
        bank.combine(0..1, &self.y0, &self.moments, &coef, &mut out, &mut ws);
        Ok(out)
    }
}
