//! Second-order oscillatory systems q'' + Ωq = −∇U(q) (paper §3) and the trigonometric
//! collocation methods TCrP and, for Ω = 0, RKNCrP.
//!
//! TCrP is ECrP applied to the first-order form
//!
//! ```text
//! y = (q, p),   y' = A y + g(y),   A = [[0, I], [−Ω, 0]],   g(y) = (0, −∇U(q)),
//! ```
//!
//! so it runs on the one ECrP stepper ([`Stepper`]) with the [`Oscillator`] operator, whose
//! banks hold the Legendre kernels of `A` in trigonometric form (three numbers per mode; no
//! `2n × 2n` matrix for zero, scalar or diagonal Ω, the eigenvectors of a dense one). Written
//! out with `K = τ²h²Ω` and `φᵗ_m(K) = Σ_l (−K)^l/(2l+m)!` it is the paper's
//! `q₁ = φᵗ₀(K) q₀ + h φᵗ₁(K) p₀ + h² Σ_k φᵗ_{k+2}(K) F_k`, `p₁ = −hΩφᵗ₁(K) q₀ + φᵗ₀(K) p₀ + h Σ_k
//! φᵗ_{k+1}(K) F_k` with `F_k = −Σ_j w_kj ∇U(Q_j)`; the stepper evaluates the same method in its
//! Legendre form, with everything the first-order stepper has: bounded weights for every r,
//! the compensated update with the propagator in double-double, Newton, the predictor, fused
//! sweeps for one mode, dense output.
//!
//! [`SecondOrderForm`] turns a [`SecondOrderSystem`] into that [`System`]; [`TcStepper`] is the
//! stepper on it with positions and momenta as separate slices.

use crate::error::{Error, Result};
use crate::operator::Oscillator;
pub use crate::operator::omega::Omega;
use crate::stepper::{
    Buffers, FixedKernel, Kernel, RuntimeKernel, SolverSettings, StepReport, Stepper, VecBuffers,
};
use crate::system::System;
use nalgebra::DMatrix;

/// A second-order system q'' + Ωq = −∇U(q).
pub trait SecondOrderSystem {
    /// Ω.
    fn omega(&self) -> &Omega;
    /// Writes f(q) = ∇U(q) into `out`.
    fn force(&self, q: &[f64], out: &mut [f64]);
    /// U(q), if known.
    fn potential(&self, _q: &[f64]) -> Option<f64> {
        None
    }
    /// H = ½pᵀp + ½qᵀΩq + U(q), if U is known.
    fn energy(&self, q: &[f64], p: &[f64]) -> Option<f64> {
        let u = self.potential(q)?;
        Some(0.5 * p.iter().map(|x| x * x).sum::<f64>() + self.omega().half_quadratic(q) + u)
    }
}

impl<S: SecondOrderSystem + ?Sized> SecondOrderSystem for &S {
    fn omega(&self) -> &Omega {
        (**self).omega()
    }
    fn force(&self, q: &[f64], out: &mut [f64]) {
        (**self).force(q, out)
    }
    fn potential(&self, q: &[f64]) -> Option<f64> {
        (**self).potential(q)
    }
    fn energy(&self, q: &[f64], p: &[f64]) -> Option<f64> {
        (**self).energy(q, p)
    }
}

/// q'' + Ωq = −∇U(q) from Ω, a closure for ∇U and optionally one for U.
pub struct SecondOrder<F, U = fn(&[f64]) -> f64> {
    omega: Omega,
    grad_u: F,
    u: Option<U>,
}

impl<F: Fn(&[f64], &mut [f64])> SecondOrder<F> {
    /// Without a known potential (no energy).
    pub fn new(omega: Omega, grad_u: F) -> Self {
        SecondOrder {
            omega,
            grad_u,
            u: None,
        }
    }
}

impl<F: Fn(&[f64], &mut [f64]), U: Fn(&[f64]) -> f64> SecondOrder<F, U> {
    /// With the potential U: the energy H is reported.
    pub fn with_potential(omega: Omega, grad_u: F, u: U) -> Self {
        SecondOrder {
            omega,
            grad_u,
            u: Some(u),
        }
    }
}

impl<F: Fn(&[f64], &mut [f64]), U: Fn(&[f64]) -> f64> SecondOrderSystem for SecondOrder<F, U> {
    fn omega(&self) -> &Omega {
        &self.omega
    }
    fn force(&self, q: &[f64], out: &mut [f64]) {
        (self.grad_u)(q, out)
    }
    fn potential(&self, q: &[f64]) -> Option<f64> {
        self.u.as_ref().map(|u| u(q))
    }
}

/// A [`SecondOrderSystem`] in first-order form `y = (q, p)`, `y' = Ay + g(y)` with the
/// [`Oscillator`] operator `A = [[0, I], [−Ω, 0]]` and `g(y) = (0, −∇U(q))`: a [`System`]
/// for the ECrP stepper, whose energy is the system's `H(q, p)`.
pub struct SecondOrderForm<S> {
    system: S,
    op: Oscillator,
}

impl<S: SecondOrderSystem> SecondOrderForm<S> {
    /// The first-order form of `system`.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] if Ω has dimension 0 (there is nothing to integrate).
    pub fn new(system: S) -> Result<Self> {
        if system.omega().dim() == 0 {
            return Err(Error::InvalidInput(
                "the system has dimension 0 (Ω is 0 × 0): there is nothing to integrate".into(),
            ));
        }
        let op = Oscillator::new(system.omega().clone());
        Ok(SecondOrderForm { system, op })
    }

    /// The second-order system.
    pub fn second_order(&self) -> &S {
        &self.system
    }
}

impl<S: SecondOrderSystem> System for SecondOrderForm<S> {
    type Op = Oscillator;
    fn linear(&self) -> &Oscillator {
        &self.op
    }
    /// `(0, −∇U(q))`.
    fn nonlinear(&self, y: &[f64], out: &mut [f64], _scratch: &mut [f64]) {
        let n = y.len() / 2;
        let (oq, op) = out.split_at_mut(n);
        oq.fill(0.0);
        self.system.force(&y[..n], op);
        op.iter_mut().for_each(|v| *v = -*v);
    }
    fn energy(&self, y: &[f64]) -> Option<f64> {
        let n = y.len() / 2;
        self.system.energy(&y[..n], &y[n..])
    }
}

/// TCrP (RKNCrP for Ω = 0) with kernel `K` (run-time r, or emitted by
/// `ecr_method!(family = tc | rknc)`) and stage storage `B`: the ECrP [`Stepper`] on the
/// [`SecondOrderForm`] of the system, stepping positions and momenta given as separate
/// slices.
pub struct TcStepper<S: SecondOrderSystem, K: Kernel = RuntimeKernel, B: Buffers = VecBuffers> {
    inner: Stepper<K, SecondOrderForm<S>, B>,
    /// The state (q, p) handed to the stepper, kept between steps so that its compensated
    /// update and predictor see the state they produced.
    y: Vec<f64>,
}

impl<S: SecondOrderSystem> TcStepper<S> {
    /// TCrP with s = r points and default solver settings.
    ///
    /// # Errors
    /// As [`TcStepper::with_nodes`].
    pub fn new(system: S, r: usize, h: f64) -> Result<Self> {
        Self::with_nodes(system, r, r, h, SolverSettings::default())
    }

    /// TCrP with r moments, s ≥ r Gauss–Legendre points, step h and solver settings.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for r, s or settings, [`Error::InvalidStepSize`] for h,
    /// and as [`TcStepper::from_kernel`].
    pub fn with_nodes(
        system: S,
        r: usize,
        s: usize,
        h: f64,
        settings: SolverSettings,
    ) -> Result<Self> {
        settings.validate()?;
        Self::from_kernel(RuntimeKernel::new(r, s)?, system, h, settings)
    }
}

impl<S: SecondOrderSystem, K: FixedKernel, B: Buffers> TcStepper<S, K, B> {
    /// The fixed-order stepper (kernel emitted by `ecr_method!(family = tc | rknc, …)`) with
    /// default solver settings.
    ///
    /// # Errors
    /// As [`TcStepper::from_kernel`].
    pub fn fixed(system: S, h: f64) -> Result<Self> {
        Self::from_kernel(K::default(), system, h, SolverSettings::default())
    }
}

impl<S: SecondOrderSystem, K: Kernel, B: Buffers> TcStepper<S, K, B> {
    /// A stepper from a kernel (run-time or emitted by `ecr_method!`).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] for Ω of dimension 0, otherwise as
    /// [`Stepper::from_kernel`].
    pub fn from_kernel(kernel: K, system: S, h: f64, settings: SolverSettings) -> Result<Self> {
        let form = SecondOrderForm::new(system)?;
        let d = form.dim();
        Ok(TcStepper {
            inner: Stepper::from_kernel(kernel, form, h, settings)?,
            y: vec![0.0; d],
        })
    }

    /// The step size.
    pub fn step_size(&self) -> f64 {
        self.inner.step_size()
    }

    /// The second-order system.
    pub fn system(&self) -> &S {
        self.inner.system().second_order()
    }

    /// The ECrP stepper on the first-order form (state y = (q, p)).
    pub fn stepper(&self) -> &Stepper<K, SecondOrderForm<S>, B> {
        &self.inner
    }

    /// The ECrP stepper on the first-order form, mutably: [`Stepper::step`] advances the
    /// concatenated state y = (q, p) without the copies of [`step`](Self::step).
    pub fn stepper_mut(&mut self) -> &mut Stepper<K, SecondOrderForm<S>, B> {
        &mut self.inner
    }

    /// Changes the step size (rebuilds the kernel bank).
    ///
    /// # Errors
    /// As [`Stepper::set_step_size`].
    pub fn set_step_size(&mut self, h: f64) -> Result<()> {
        self.inner.set_step_size(h)
    }

    /// Advances (q, p) by one step in place. Allocation-free.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] for slices of the wrong length, otherwise as
    /// [`Stepper::step`]. On error, (q, p) are unchanged.
    pub fn step(&mut self, q: &mut [f64], p: &mut [f64]) -> Result<StepReport> {
        let n = self.y.len() / 2;
        for (what, x) in [("position q", &*q), ("momentum p", &*p)] {
            if x.len() != n {
                return Err(Error::DimensionMismatch {
                    what,
                    expected: n,
                    found: x.len(),
                });
            }
        }
        let (yq, yp) = self.y.split_at_mut(n);
        yq.copy_from_slice(q);
        yp.copy_from_slice(p);
        let report = self.inner.step(&mut self.y)?;
        q.copy_from_slice(&self.y[..n]);
        p.copy_from_slice(&self.y[n..]);
        Ok(report)
    }

    /// Dense output (q, p) of the last step at τ ∈ [0, 1], concatenated (see
    /// [`Stepper::dense_output`]).
    ///
    /// # Errors
    /// As [`Stepper::dense_output`].
    pub fn dense_output(&self, tau: f64) -> Result<Vec<f64>> {
        self.inner.dense_output(tau)
    }
}

/// The damped second-order system q'' − Nq' + Ωq = −∇U(q) (paper eq. `2oprob`, N symmetric
/// negative semidefinite) in first-order form y = (q, p), p = q':
/// y' = [[0, I], [−Ω, N]] y + (0, −∇U(q)), with the Lyapunov function
/// H = ½pᵀp + ½qᵀΩq + U(q) (paper eq. `H2`). Integrate it with ECrP
/// ([`crate::stepper::EcStepper`]); N = 0 is the conservative case.
///
/// # Errors
/// [`Error::NotSquare`], [`Error::DimensionMismatch`], [`Error::NonFinite`], and
/// [`Error::InvalidInput`] if Ω is not symmetric positive semidefinite or N is not symmetric
/// negative semidefinite.
#[allow(clippy::type_complexity)] // the closures' types are unnameable: impl Trait is the point
pub fn damped_first_order<F, U>(
    omega: DMatrix<f64>,
    n: DMatrix<f64>,
    grad_u: F,
    u: U,
) -> Result<
    crate::system::Semilinear<
        crate::operator::Dense,
        impl Fn(&[f64], &mut [f64]),
        impl Fn(&[f64]) -> f64,
    >,
>
where
    F: Fn(&[f64], &mut [f64]),
    U: Fn(&[f64]) -> f64,
{
    let om = Omega::dense(omega.clone())?;
    let d = om.dim();
    if n.shape() != (d, d) {
        return Err(Error::DimensionMismatch {
            what: "N and Ω",
            expected: d,
            found: n.nrows(),
        });
    }
    // N ≤ 0 ⇔ −N is positive semidefinite.
    Omega::dense(-&n).map_err(|e| match e {
        Error::InvalidInput(_) => {
            Error::InvalidInput("N must be symmetric negative semidefinite".into())
        }
        other => other,
    })?;
    let mut a = DMatrix::zeros(2 * d, 2 * d);
    a.view_mut((0, d), (d, d)).fill_with_identity();
    a.view_mut((d, 0), (d, d)).copy_from(&(-&omega));
    a.view_mut((d, d), (d, d)).copy_from(&n);
    let g = move |y: &[f64], out: &mut [f64]| {
        out[..d].fill(0.0);
        grad_u(&y[..d], &mut out[d..]);
        out[d..].iter_mut().for_each(|x| *x = -*x);
    };
    let h = move |y: &[f64]| {
        0.5 * y[d..].iter().map(|x| x * x).sum::<f64>() + om.half_quadratic(&y[..d]) + u(&y[..d])
    };
    Ok(crate::system::Semilinear::with_energy(
        crate::operator::Dense::new(a)?,
        g,
        h,
    ))
}
