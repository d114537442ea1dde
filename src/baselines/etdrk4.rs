//! ETDRK4: the fourth-order exponential time-differencing Runge–Kutta method of Cox and
//! Matthews (J. Comput. Phys. 176 (2002) 430–455, §2: the formulas for aₙ, bₙ, cₙ, uₙ₊₁) for `y' = Ay + g(y)`
//! (the NLS users' other choice: `docs/architecture.md#baselines`).
//!
//! With `N = g` and `φ_k = φ_k(hA)`, `φ_k^½ = φ_k(hA/2)`:
//!
//! ```text
//! a   = φ₀^½ y + (h/2) φ₁^½ N(y)
//! b   = φ₀^½ y + (h/2) φ₁^½ N(a)
//! c   = φ₀^½ a + (h/2) φ₁^½ (2N(b) − N(y))
//! y₁  = φ₀ y + h [φ₁ N(y) + φ₂ (−3N(y) + 2N(a) + 2N(b) − N(c)) + φ₃ (4N(y) − 4N(a) − 4N(b) + 4N(c))]
//! ```
//!
//! which is Cox–Matthews' `y₁ = e^{hA}y + h[f₁N(y) + f₂(N(a) + N(b)) + f₃N(c)]` with
//! `f₁ = φ₁ − 3φ₂ + 4φ₃`, `f₂ = 2φ₂ − 4φ₃`, `f₃ = 4φ₃ − φ₂` regrouped by φ_k. Each formula is
//! one [`PhiBank::combine`] of the operator's bank `phi_bank(h, &[0.5, 1.0], 3)`, built once per
//! step size; that bank evaluates the φ_k without cancellation for every hA (the role of the
//! Kassam–Trefethen contour integrals in the original MATLAB setting).
//!
//! Four evaluations of g per step, no FSAL (y₁ is not a stage). Exact for g = 0
//! (`y₁ = e^{hA}y`); classical order 4 (it does not satisfy all stiff order conditions of
//! Hochbruck–Ostermann 2005, so the order may drop for stiff problems with non-smooth data).
//!
//! It conserves nothing exactly. Measured (`tests/it/baselines_peers.rs`): on Duffing (ω = 1,
//! k = 0.9, h = 0.1, 1e5 steps) the energy error grows linearly in time, 3.1e−8 per unit time
//! to 3.1e−4 at t = 1e4 (the symplectic splittings of orders 2 and 4 stay bounded at 1.3e−3
//! and 1.9e−5 on the same run); on the NLS (N = 32, h = 0.01, 1e4 steps) the mass drifts by a
//! relative 5.8e−6 (split-step: ≤ 8.3e−12).

use ecr_runtime::integrate::Integrator;
use ecr_runtime::operator::{LinearOperator, PhiBank};
use ecr_runtime::stepper::StepReport;
use ecr_runtime::system::System;
use ecr_runtime::{Error, Result};

use super::splitting::{check_state, check_step_size};

/// ETDRK4 of Cox and Matthews (2002); see the [module documentation](self).
pub struct Etdrk4<S: System> {
    system: S,
    h: f64,
    bank: <S::Op as LinearOperator>::Bank,
    ws: <<S::Op as LinearOperator>::Bank as PhiBank>::Workspace,
    y0: Vec<f64>,
    a: Vec<f64>,
    b: Vec<f64>,
    c: Vec<f64>,
    /// N(y), N(a), N(b), N(c).
    ny: Vec<f64>,
    na: Vec<f64>,
    nb: Vec<f64>,
    nc: Vec<f64>,
    /// The three g-blocks of the final combine (also 2N(b) − N(y) for c).
    blocks: Vec<f64>,
    out: Vec<f64>,
    scratch: Vec<f64>,
}

impl<S: System> Etdrk4<S> {
    /// ETDRK4 for `system` with step size `h`.
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`], the errors of [`check_system`](ecr_runtime::system::check_system)
    /// and whatever the operator's `phi_bank` reports.
    pub fn new(system: S, h: f64) -> Result<Self> {
        check_step_size(h)?;
        ecr_runtime::system::check_system(&system)?;
        let bank = system.linear().phi_bank(h, &[0.5, 1.0], 3)?;
        let ws = bank.workspace();
        let d = system.dim();
        let v = || vec![0.0; d];
        Ok(Etdrk4 {
            h,
            bank,
            ws,
            y0: v(),
            a: v(),
            b: v(),
            c: v(),
            ny: v(),
            na: v(),
            nb: v(),
            nc: v(),
            blocks: vec![0.0; 3 * d],
            out: v(),
            scratch: vec![0.0; system.scratch_len()],
            system,
        })
    }

    /// The system.
    pub fn system(&self) -> &S {
        &self.system
    }

    /// The step size.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// Changes the step size (rebuilds the φ-bank).
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`] and whatever `phi_bank` reports; then nothing changed.
    pub fn set_step_size(&mut self, h: f64) -> Result<()> {
        check_step_size(h)?;
        if h != self.h {
            let bank = self.system.linear().phi_bank(h, &[0.5, 1.0], 3)?;
            self.ws = bank.workspace();
            self.bank = bank;
            self.h = h;
        }
        Ok(())
    }

    /// Advances y by one step in place. Does not allocate.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] for a wrong length, [`Error::NonFinite`] if y, g at a
    /// stage or the result is NaN/infinite. On error, y is unchanged.
    pub fn step(&mut self, y: &mut [f64]) -> Result<StepReport> {
        let d = self.y0.len();
        check_state(y, d, "state y")?;
        let half = [0.5 * self.h];
        let Etdrk4 {
            system,
            h,
            bank,
            ws,
            y0,
            a,
            b,
            c,
            ny,
            na,
            nb,
            nc,
            blocks,
            out,
            scratch,
        } = self;
        let h = *h;
        y0.copy_from_slice(y);
        eval_g(system, y0, ny, scratch, "g(y)")?;
        bank.combine(0..1, y0, ny, &half, a, ws);
        eval_g(system, a, na, scratch, "g(a)")?;
        bank.combine(0..1, y0, na, &half, b, ws);
        eval_g(system, b, nb, scratch, "g(b)")?;
        let w = &mut blocks[..d];
        w.iter_mut()
            .zip(nb.iter())
            .zip(ny.iter())
            .for_each(|((w, nb), ny)| *w = 2.0 * nb - ny);
        bank.combine(0..1, a, w, &half, c, ws);
        eval_g(system, c, nc, scratch, "g(c)")?;
        let (g1, rest) = blocks.split_at_mut(d);
        let (g2, g3) = rest.split_at_mut(d);
        for i in 0..d {
            let (y, a, b, c) = (ny[i], na[i], nb[i], nc[i]);
            g1[i] = y;
            g2[i] = -3.0 * y + 2.0 * a + 2.0 * b - c;
            g3[i] = 4.0 * (y - a - b + c);
        }
        bank.combine(1..2, y0, blocks, &[h, h, h], out, ws);
        if !out.iter().all(|v| v.is_finite()) {
            return Err(Error::NonFinite("ETDRK4 step result"));
        }
        y.copy_from_slice(out);
        Ok(StepReport {
            sweeps: 0,
            residual: 0.0,
            g_evals: 4,
            converged: true,
            jacobian_evals: 0,
            newton_refreshes: 0,
        })
    }
}

fn eval_g<S: System>(
    system: &S,
    y: &[f64],
    out: &mut [f64],
    scratch: &mut [f64],
    what: &'static str,
) -> Result<()> {
    system.nonlinear(y, out, scratch);
    if !out.iter().all(|v| v.is_finite()) {
        return Err(Error::NonFinite(what));
    }
    Ok(())
}

impl<S: System> Integrator for Etdrk4<S> {
    fn step_size(&self) -> f64 {
        self.h
    }
    fn set_step_size(&mut self, h: f64) -> Result<()> {
        Etdrk4::set_step_size(self, h)
    }
    fn step_state(&mut self, y: &mut [f64]) -> Result<StepReport> {
        self.step(y)
    }
    fn energy_of(&self, y: &[f64]) -> Option<f64> {
        self.system.energy(y)
    }
}
