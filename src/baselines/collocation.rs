//! Collocation-type baselines (A = 0 methods applied to the whole field f = Ay + g, and the
//! exponential AVF method):
//!
//! - [`hbvm`]: HBVM(k, s) of Brugnano–Iavernaro–Trigiante — polynomial degree s, k-point
//!   Gauss–Legendre or Gauss–Lobatto quadrature. It is ECrP with r = s, k points and A = 0,
//!   which is how it is computed here (the same [`Stepper`]);
//! - [`rkepc2`]: RKEPC2 = HBVM(5, 2) on Lobatto points, Hairer's energy-preserving collocation
//!   of order 4 with its integral by 5-point Lobatto quadrature (the paper's "extended Lobatto
//!   IIIA method of order four");
//! - [`gauss_collocation`]: Gauss collocation of order 2r = HBVM(r, r);
//! - [`avf`]: the average vector field method (order 2) = HBVM(k, 1);
//! - [`ExpAvf`]: the exponential AVF method of Li & Wu (2016):
//!   y₁ = φ₀(hA) y₀ + h φ₁(hA) ∫₀¹ g((1 − τ) y₀ + τ y₁) dτ (energy-preserving for y' = Q∇H with
//!   Q skew, order 2).

use ecr_runtime::integrate::Integrator;
use ecr_runtime::operator::{LinearOperator, PhiBank, Zero};
use ecr_runtime::stepper::{
    RuntimeKernel, SolverSettings, StageScale, StageSolver, StepReport, Stepper, SweepLimit,
    VecBuffers, sweeps_converged,
};
use ecr_runtime::system::System;
use ecr_runtime::tables::{QuadratureKind, coefficients};
use ecr_runtime::{Error, Result};

/// A system's whole vector field f(y) = Ay + g(y) as the "nonlinearity" of a system with
/// A = 0: what the classical (non-exponential) methods integrate.
pub struct WholeField<S: System> {
    inner: S,
    zero: Zero,
}

impl<S: System> WholeField<S> {
    /// Wraps a system.
    pub fn new(inner: S) -> Self {
        let zero = Zero::new(inner.dim());
        WholeField { inner, zero }
    }

    /// The wrapped system.
    pub fn inner(&self) -> &S {
        &self.inner
    }
}

impl<S: System> System for WholeField<S> {
    type Op = Zero;
    fn linear(&self) -> &Zero {
        &self.zero
    }
    fn nonlinear(&self, y: &[f64], out: &mut [f64], scratch: &mut [f64]) {
        let d = y.len();
        let (tmp, rest) = scratch.split_at_mut(d);
        self.inner.nonlinear(y, tmp, rest);
        self.inner.linear().apply(y, out);
        out.iter_mut().zip(tmp.iter()).for_each(|(o, t)| *o += t);
    }
    fn scratch_len(&self) -> usize {
        self.inner.dim() + self.inner.scratch_len()
    }
    fn energy(&self, y: &[f64]) -> Option<f64> {
        self.inner.energy(y)
    }
}

/// HBVM(k, s) and its special cases: the ECrP stepper with A = 0 on the whole field.
pub type Hbvm<S> = Stepper<RuntimeKernel, WholeField<S>, VecBuffers>;

/// HBVM(k, s): polynomial degree s, k ≥ s quadrature points of the given kind.
///
/// # Errors
/// [`Error::InvalidParameter`] for s = 0, k < s (Lobatto: k ≥ 2), the errors of
/// [`check_system`](ecr_runtime::system::check_system) for `system`, and the stepper's errors.
pub fn hbvm<S: System>(
    system: S,
    k: usize,
    s: usize,
    kind: QuadratureKind,
    h: f64,
    settings: SolverSettings,
) -> Result<Hbvm<S>> {
    let kernel = RuntimeKernel::with_quadrature(kind, s, k)?;
    ecr_runtime::system::check_system(&system)?;
    Stepper::from_kernel(kernel, WholeField::new(system), h, settings)
}

/// RKEPC2 = HBVM(5, 2) on Gauss–Lobatto points (order 4; conserves polynomial energies of
/// degree ≤ 4 exactly).
///
/// # Errors
/// As [`hbvm`].
pub fn rkepc2<S: System>(system: S, h: f64, settings: SolverSettings) -> Result<Hbvm<S>> {
    hbvm(system, 5, 2, QuadratureKind::GaussLobatto, h, settings)
}

/// Gauss collocation with r stages (order 2r, symplectic) = HBVM(r, r).
///
/// # Errors
/// As [`hbvm`].
pub fn gauss_collocation<S: System>(
    system: S,
    r: usize,
    h: f64,
    settings: SolverSettings,
) -> Result<Hbvm<S>> {
    hbvm(system, r, r, QuadratureKind::GaussLegendre, h, settings)
}

/// The AVF method y₁ = y₀ + h ∫₀¹ f((1 − τ)y₀ + τy₁) dτ with a k-point Gauss rule for the
/// integral (exact for polynomial f of degree ≤ 2k − 1) = HBVM(k, 1). Order 2.
///
/// # Errors
/// As [`hbvm`].
pub fn avf<S: System>(system: S, k: usize, h: f64, settings: SolverSettings) -> Result<Hbvm<S>> {
    hbvm(system, k, 1, QuadratureKind::GaussLegendre, h, settings)
}

/// The exponential AVF method (Li & Wu, Sci. China Math. 2016), the order-2 exponential
/// energy-preserving scheme the paper cites:
/// y₁ = φ₀(hA) y₀ + h φ₁(hA) ∫₀¹ g((1 − τ) y₀ + τ y₁) dτ, the integral by a k-point Gauss rule,
/// y₁ by fixed-point sweeps.
pub struct ExpAvf<S: System> {
    system: S,
    settings: SolverSettings,
    h: f64,
    bank: <S::Op as LinearOperator>::Bank,
    ws: <<S::Op as LinearOperator>::Bank as PhiBank>::Workspace,
    nodes: Vec<f64>,
    weights: Vec<f64>,
    y0: Vec<f64>,
    y1: Vec<f64>,
    next: Vec<f64>,
    point: Vec<f64>,
    gval: Vec<f64>,
    integral: Vec<f64>,
    scratch: Vec<f64>,
}

impl<S: System> ExpAvf<S> {
    /// The method with a k-point Gauss rule and step size h.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for k = 0 or bad settings, [`Error::InvalidStepSize`], and
    /// the errors of [`check_system`](ecr_runtime::system::check_system).
    pub fn new(system: S, k: usize, h: f64, settings: SolverSettings) -> Result<Self> {
        settings.validate()?;
        require_fixed_point(&settings, "ExpAvf")?;
        ecr_runtime::system::check_system(&system)?;
        let c = coefficients(1, k)?;
        let d = system.dim();
        let bank = system.linear().phi_bank(h, &[1.0], 1)?;
        let ws = bank.workspace();
        Ok(ExpAvf {
            scratch: vec![0.0; system.scratch_len()],
            system,
            settings,
            h,
            bank,
            ws,
            nodes: c.nodes.clone(),
            weights: c.weights.clone(),
            y0: vec![0.0; d],
            y1: vec![0.0; d],
            next: vec![0.0; d],
            point: vec![0.0; d],
            gval: vec![0.0; d],
            integral: vec![0.0; d],
        })
    }

    /// One step in place.
    ///
    /// # Errors
    /// As [`Stepper::step`].
    pub fn step(&mut self, y: &mut [f64]) -> Result<StepReport> {
        let d = self.y0.len();
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
        self.y1.copy_from_slice(y);
        let (mut sweeps, mut g_evals, mut previous) = (0, 0, f64::INFINITY);
        let (residual, converged) = loop {
            self.integral.fill(0.0);
            for (c, b) in self.nodes.iter().zip(&self.weights) {
                for ((p, a), e) in self.point.iter_mut().zip(&self.y0).zip(&self.y1) {
                    *p = (1.0 - c) * a + c * e;
                }
                self.system
                    .nonlinear(&self.point, &mut self.gval, &mut self.scratch);
                if self.gval.iter().any(|v| !v.is_finite()) {
                    return Err(Error::NonFinite("g at a quadrature point"));
                }
                self.integral
                    .iter_mut()
                    .zip(&self.gval)
                    .for_each(|(i, g)| *i += b * g);
            }
            g_evals += self.nodes.len();
            self.bank.combine(
                0..1,
                &self.y0,
                &self.integral,
                &[self.h],
                &mut self.next,
                &mut self.ws,
            );
            let (mut diff, mut mag) = (0.0f64, 1.0f64);
            for (a, b) in self.next.iter().zip(&self.y1) {
                diff = diff.max((a - b).abs());
                mag = mag.max(a.abs());
            }
            std::mem::swap(&mut self.y1, &mut self.next);
            sweeps += 1;
            let residual = diff / mag;
            if !residual.is_finite() {
                return Err(ecr_runtime::stepper::stages_fault(previous));
            }
            if sweeps_converged(residual, previous, self.settings.tolerance) {
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
        y.copy_from_slice(&self.y1);
        Ok(StepReport {
            sweeps,
            residual,
            g_evals,
            converged,
            jacobian_evals: 0,
            newton_refreshes: 0,
        })
    }
}

impl<S: System> Integrator for ExpAvf<S> {
    fn step_size(&self) -> f64 {
        self.h
    }
    fn set_step_size(&mut self, h: f64) -> Result<()> {
        if h != self.h {
            self.bank = self.system.linear().phi_bank(h, &[1.0], 1)?;
            self.ws = self.bank.workspace();
            self.h = h;
        }
        Ok(())
    }
    fn step_state(&mut self, y: &mut [f64]) -> Result<StepReport> {
        self.step(y)
    }
    fn energy_of(&self, y: &[f64]) -> Option<f64> {
        self.system.energy(y)
    }
}

/// `Err(InvalidParameter)` unless the solver is [`StageSolver::FixedPoint`] and the scale
/// [`StageScale::Global`] (for steppers without a Newton iteration or a per-component
/// stopping rule).
fn require_fixed_point(settings: &SolverSettings, stepper: &str) -> Result<()> {
    if settings.solver != StageSolver::FixedPoint {
        Err(Error::InvalidParameter(format!(
            "{stepper} solves its stages by fixed-point sweeps only (StageSolver::Newton is \
             implemented for the ECrP stepper and TCrP/RKNCrP)"
        )))
    } else if settings.scale != StageScale::Global {
        Err(Error::InvalidParameter(format!(
            "{stepper} measures its stage updates in the global scale only \
             (StageScale::PerComponent is implemented for the ECrP stepper and TCrP/RKNCrP)"
        )))
    } else {
        Ok(())
    }
}
