//! Second-order oscillatory systems q'' + Ωq = −∇U(q) (paper §3) and the trigonometric
//! collocation stepper TCrP (paper eq. `EEPCr of erkn` with Gauss–Legendre quadrature, in the
//! moment form of DESIGN.md §2); Ω = 0 gives RKNCrP (eq. `EEPCr of rkn`).
//!
//! ```text
//! F_k = −Σ_j w_kj f(Q_j)                                         f = ∇U
//! Q_i = φᵗ₀(Kᵢ) q₀ + cᵢh φᵗ₁(Kᵢ) p₀ + h² Σ_k cᵢ^{k+2} φᵗ_{k+2}(Kᵢ) F_k,      Kᵢ = cᵢ²h²Ω
//! q₁  = φᵗ₀(K) q₀ + h φᵗ₁(K) p₀ + h² Σ_k φᵗ_{k+2}(K) F_k,                     K = h²Ω
//! p₁  = −hΩ φᵗ₁(K) q₀ + φᵗ₀(K) p₀ + h Σ_k φᵗ_{k+1}(K) F_k
//! ```
//!
//! This is ECrP applied to (q, p)' = [[0, I], [−Ω, 0]](q, p) + (0, −f(q)) (tested to agree),
//! at a fraction of its cost: only positions are iterated, and Ω is handled in its modal
//! basis (identity for zero, scalar and diagonal Ω; eigenvectors for a dense one), so each
//! φᵗ-function is a per-mode scalar computed once per step size.
//!
//! The φᵗ values come from [`crate::phi::phi_trig`], accurate to a few ulp for every
//! K = (τhω)² ≥ 0: it picks, per value, between closed forms, the upward recurrence and a
//! Taylor series by an a-priori error bound (rather than at one fixed switch point), so there
//! is no loss of digits as hω → 0 and the RKN limit (φᵗ_m(0) = 1/m!) is reached continuously.

use crate::phi::phi_trig;
use crate::stepper::{
    FixedKernel, Kernel, Predictor, RuntimeKernel, SolverSettings, StepReport, SweepLimit,
    sweeps_converged,
};
use crate::{Error, Result};
use nalgebra::DMatrix;

/// The stiffness Ω (symmetric positive semidefinite), modelled as what it is.
#[derive(Clone, Debug)]
pub struct Omega {
    dim: usize,
    /// Eigenvalues (modal stiffnesses), one per mode.
    lambda: Vec<f64>,
    /// Eigenvectors (columns), for a dense Ω; `None`: the standard basis is modal.
    basis: Option<DMatrix<f64>>,
}

impl Omega {
    /// Ω = 0 (RKNCr).
    pub fn zero(dim: usize) -> Self {
        Omega {
            dim,
            lambda: vec![0.0; dim],
            basis: None,
        }
    }

    /// Ω = ω² I.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] for a negative or non-finite value.
    pub fn scalar(omega_squared: f64, dim: usize) -> Result<Self> {
        Self::diagonal(vec![omega_squared; dim])
    }

    /// Ω = diag(λ).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] for a negative or non-finite entry.
    pub fn diagonal(lambda: Vec<f64>) -> Result<Self> {
        check_eigenvalues(&lambda, 0.0)?;
        Ok(Omega {
            dim: lambda.len(),
            lambda,
            basis: None,
        })
    }

    /// A dense symmetric positive semidefinite Ω, by its eigendecomposition.
    ///
    /// # Errors
    /// [`Error::NotSquare`], [`Error::NonFinite`], [`Error::InvalidInput`] if Ω is not
    /// symmetric (relative 1e−12) or has a negative eigenvalue (below −1e−12 ‖Ω‖).
    pub fn dense(omega: DMatrix<f64>) -> Result<Self> {
        let (n, m) = omega.shape();
        if n != m {
            return Err(Error::NotSquare {
                what: "Ω",
                rows: n,
                cols: m,
            });
        }
        if omega.iter().any(|x| !x.is_finite()) {
            return Err(Error::NonFinite("Ω"));
        }
        let scale = omega.amax();
        let asym = (&omega - omega.transpose()).amax();
        if asym > 1e-12 * scale {
            return Err(Error::InvalidInput(format!(
                "Ω must be symmetric (max |Ω − Ωᵀ| = {asym:e})"
            )));
        }
        let eig = nalgebra::SymmetricEigen::new((&omega + omega.transpose()) * 0.5);
        let mut lambda: Vec<f64> = eig.eigenvalues.iter().copied().collect();
        check_eigenvalues(&lambda, 1e-12 * scale)?;
        // Round-off may leave tiny negative eigenvalues of a semidefinite Ω: they are zero.
        lambda.iter_mut().for_each(|l| *l = l.max(0.0));
        Ok(Omega {
            dim: n,
            lambda,
            basis: Some(eig.eigenvectors),
        })
    }

    /// The dimension.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// The modal stiffnesses (eigenvalues of Ω).
    pub fn eigenvalues(&self) -> &[f64] {
        &self.lambda
    }

    /// y = Ω x.
    pub fn apply(&self, x: &[f64], y: &mut [f64]) {
        match &self.basis {
            None => y
                .iter_mut()
                .zip(x)
                .zip(&self.lambda)
                .for_each(|((y, x), l)| *y = l * x),
            Some(v) => {
                // Ω x = V Λ Vᵀ x
                let z: Vec<f64> = (0..self.dim)
                    .map(|j| {
                        self.lambda[j] * v.column(j).iter().zip(x).map(|(a, b)| a * b).sum::<f64>()
                    })
                    .collect();
                for (i, yi) in y.iter_mut().enumerate() {
                    *yi = (0..self.dim).map(|j| v[(i, j)] * z[j]).sum();
                }
            }
        }
    }

    /// ½ xᵀΩx.
    pub fn half_quadratic(&self, x: &[f64]) -> f64 {
        let mut y = vec![0.0; self.dim];
        self.apply(x, &mut y);
        0.5 * x.iter().zip(&y).map(|(a, b)| a * b).sum::<f64>()
    }

    fn physical_to_modal(&self, x: &[f64], out: &mut [f64]) {
        match &self.basis {
            None => out.copy_from_slice(x),
            Some(v) => {
                for (j, o) in out.iter_mut().enumerate() {
                    *o = v.column(j).iter().zip(x).map(|(a, b)| a * b).sum();
                }
            }
        }
    }

    fn modal_to_physical(&self, x: &[f64], out: &mut [f64]) {
        match &self.basis {
            None => out.copy_from_slice(x),
            Some(v) => {
                for (i, o) in out.iter_mut().enumerate() {
                    *o = (0..self.dim).map(|j| v[(i, j)] * x[j]).sum();
                }
            }
        }
    }
}

fn check_eigenvalues(lambda: &[f64], slack: f64) -> Result<()> {
    if let Some(l) = lambda.iter().find(|l| !l.is_finite() || **l < -slack) {
        return Err(Error::InvalidInput(format!(
            "Ω must be positive semidefinite with finite entries (eigenvalue {l:e})"
        )));
    }
    Ok(())
}

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

/// φᵗ_m(τᵢ²h²λ_l) for every node τᵢ (c₁..c_s, 1), m = 0..=r+1 and mode l: layout
/// [i][m][l].
#[derive(Clone, Debug)]
struct TrigBank {
    values: Vec<f64>,
    p: usize,
    d: usize,
}

impl TrigBank {
    fn new(omega: &Omega, h: f64, taus: &[f64], p: usize) -> Result<Self> {
        let d = omega.dim();
        let mut values = vec![0.0; taus.len() * (p + 1) * d];
        let mut buf = vec![0.0; p + 1];
        for (i, &t) in taus.iter().enumerate() {
            for (l, &lam) in omega.lambda.iter().enumerate() {
                let th = t * h;
                phi_trig(th * th * lam, &mut buf);
                for (m, v) in buf.iter().enumerate() {
                    values[(i * (p + 1) + m) * d + l] = *v;
                }
            }
        }
        if values.iter().any(|v| !v.is_finite()) {
            return Err(Error::Numerical(
                "a trigonometric φ-function is not finite".into(),
            ));
        }
        Ok(TrigBank { values, p, d })
    }

    #[inline]
    fn get(&self, i: usize, m: usize) -> &[f64] {
        let o = (i * (self.p + 1) + m) * self.d;
        &self.values[o..o + self.d]
    }
}

/// TCrP (and RKNCrP for Ω = 0) with run-time r and s ≥ r, for a [`SecondOrderSystem`].
pub struct TcStepper<S: SecondOrderSystem, K: Kernel = RuntimeKernel> {
    kernel: K,
    system: S,
    settings: SolverSettings,
    h: f64,
    bank: TrigBank,
    /// h τᵢ and h² τᵢ^{k+2} per node (τ = c₁..c_s, 1, and 1 + c₁..1 + c_s with the
    /// extrapolating predictor): (1 + r) per node.
    coef: Vec<f64>,
    q0m: Vec<f64>,
    p0m: Vec<f64>,
    /// The modal start (q, p) of the last completed step, for the predictor.
    prev_q0m: Vec<f64>,
    prev_p0m: Vec<f64>,
    /// The last step completed with this h and its start and moments are kept.
    have_previous: bool,
    /// The last output (q, p) in physical coordinates, bit for bit, whose exact modal
    /// coordinates are still in q0m/p0m: continuing from it skips the round trip through a
    /// numerically orthogonal eigenbasis, which would otherwise add a systematic O(ε) per step.
    last_q: Vec<f64>,
    last_p: Vec<f64>,
    modal_valid: bool,
    stages: Vec<f64>,
    new_stages: Vec<f64>,
    modal: Vec<f64>,
    f: Vec<f64>,
    moments: Vec<f64>,
    moments_m: Vec<f64>,
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
    /// [`Error::InvalidParameter`] for r, s or settings, [`Error::InvalidStepSize`] for h.
    pub fn with_nodes(
        system: S,
        r: usize,
        s: usize,
        h: f64,
        settings: SolverSettings,
    ) -> Result<Self> {
        Self::from_kernel(RuntimeKernel::new(r, s)?, system, h, settings)
    }
}

impl<S: SecondOrderSystem, K: FixedKernel> TcStepper<S, K> {
    /// The fixed-order stepper (kernel emitted by `ecr_method!(family = tc | rknc, …)`) with
    /// default solver settings.
    ///
    /// # Errors
    /// As [`TcStepper::from_kernel`].
    pub fn fixed(system: S, h: f64) -> Result<Self> {
        Self::from_kernel(K::default(), system, h, SolverSettings::default())
    }
}

impl<S: SecondOrderSystem, K: Kernel> TcStepper<S, K> {
    /// A stepper from a kernel (run-time or emitted by `ecr_method!`).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for bad settings, [`Error::InvalidStepSize`] for h,
    /// [`Error::InvalidInput`] for Ω of dimension 0.
    pub fn from_kernel(kernel: K, system: S, h: f64, settings: SolverSettings) -> Result<Self> {
        settings.validate()?;
        settings.require_fixed_point("TcStepper")?;
        let (r, s, d) = (kernel.r(), kernel.s(), system.omega().dim());
        if d == 0 {
            return Err(Error::InvalidInput(
                "the system has dimension 0 (Ω is 0 × 0): there is nothing to integrate".into(),
            ));
        }
        let (bank, coef) = Self::build(&system, &kernel, h, settings.predictor)?;
        Ok(TcStepper {
            kernel,
            system,
            settings,
            h,
            bank,
            coef,
            q0m: vec![0.0; d],
            p0m: vec![0.0; d],
            prev_q0m: vec![0.0; d],
            prev_p0m: vec![0.0; d],
            have_previous: false,
            last_q: vec![0.0; d],
            last_p: vec![0.0; d],
            modal_valid: false,
            stages: vec![0.0; s * d],
            new_stages: vec![0.0; s * d],
            modal: vec![0.0; d],
            f: vec![0.0; s * d],
            moments: vec![0.0; r * d],
            moments_m: vec![0.0; r * d],
        })
    }

    fn build(system: &S, kernel: &K, h: f64, predictor: Predictor) -> Result<(TrigBank, Vec<f64>)> {
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidStepSize(h));
        }
        let r = kernel.r();
        let mut taus = kernel.nodes().to_vec();
        taus.push(1.0);
        if predictor == Predictor::Extrapolate {
            taus.extend(kernel.nodes().iter().map(|c| 1.0 + c));
        }
        let bank = TrigBank::new(system.omega(), h, &taus, r + 1)?;
        let coef = taus
            .iter()
            .flat_map(|&t| {
                std::iter::once(h * t).chain((0..r).map(move |k| h * h * t.powi(k as i32 + 2)))
            })
            .collect();
        Ok((bank, coef))
    }

    /// The step size.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// The system.
    pub fn system(&self) -> &S {
        &self.system
    }

    /// Changes the step size (rebuilds the φᵗ bank).
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`].
    pub fn set_step_size(&mut self, h: f64) -> Result<()> {
        if h != self.h {
            let (bank, coef) = Self::build(&self.system, &self.kernel, h, self.settings.predictor)?;
            self.bank = bank;
            self.coef = coef;
            self.h = h;
            self.have_previous = false;
        }
        Ok(())
    }

    /// Positions of stage i in modal coordinates into `out`:
    /// φᵗ₀ q₀ + hτ φᵗ₁ p₀ − Σ_k h²τ^{k+2} φᵗ_{k+2} M_k (M = Σ_j w_kj f_j, modal), from the
    /// current step's start (or, for the predictor nodes i > s, the previous step's).
    fn stage_modal(&self, i: usize, out: &mut [f64]) {
        let (r, d) = (self.kernel.r(), out.len());
        let (q0m, p0m) = if i > self.kernel.s() {
            (&self.prev_q0m, &self.prev_p0m)
        } else {
            (&self.q0m, &self.p0m)
        };
        let c = &self.coef[i * (r + 1)..(i + 1) * (r + 1)];
        let (t0, t1) = (self.bank.get(i, 0), self.bank.get(i, 1));
        for l in 0..d {
            out[l] = t0[l] * q0m[l] + c[0] * t1[l] * p0m[l];
        }
        for k in 0..r {
            let tk = self.bank.get(i, k + 2);
            let mk = &self.moments_m[k * d..(k + 1) * d];
            for l in 0..d {
                out[l] -= c[k + 1] * tk[l] * mk[l];
            }
        }
    }

    fn eval_f(&mut self, j: usize) -> Result<()> {
        let d = self.q0m.len();
        let out = &mut self.f[j * d..(j + 1) * d];
        self.system.force(&self.stages[j * d..(j + 1) * d], out);
        if out.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("f(Q) at a stage"));
        }
        Ok(())
    }

    fn update_moments(&mut self) {
        let (r, d) = (self.kernel.r(), self.q0m.len());
        self.kernel.moments(&self.f, &mut self.moments, d);
        for k in 0..r {
            let (src, dst) = (
                &self.moments[k * d..(k + 1) * d],
                &mut self.moments_m[k * d..(k + 1) * d],
            );
            self.system.omega().physical_to_modal(src, dst);
        }
    }

    /// Advances (q, p) by one step in place. Allocation-free.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`], [`Error::NonFinite`] (input or force),
    /// [`Error::NoConvergence`] as for [`crate::stepper::Stepper::step`]. On error, (q, p) are
    /// unchanged.
    pub fn step(&mut self, q: &mut [f64], p: &mut [f64]) -> Result<StepReport> {
        let d = self.q0m.len();
        let (r, s) = (self.kernel.r(), self.kernel.s());
        for (what, x) in [("position q", &*q), ("momentum p", &*p)] {
            if x.len() != d {
                return Err(Error::DimensionMismatch {
                    what,
                    expected: d,
                    found: x.len(),
                });
            }
            if x.iter().any(|v| !v.is_finite()) {
                return Err(Error::NonFinite(what));
            }
        }
        let omega = self.system.omega();
        let same = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
        let continuing = self.modal_valid && same(q, &self.last_q) && same(p, &self.last_p);
        if !continuing {
            omega.physical_to_modal(q, &mut self.q0m);
            omega.physical_to_modal(p, &mut self.p0m);
        }
        self.modal_valid = false;
        let extrapolate = std::mem::take(&mut self.have_previous)
            && continuing
            && self.settings.predictor == Predictor::Extrapolate;
        let mut g_evals;
        if extrapolate {
            // Start: the previous step's continuous solution at τ = 1 + cᵢ (its modal start
            // and moments are still held).
            let mut modal = std::mem::take(&mut self.modal);
            let mut stages = std::mem::take(&mut self.stages);
            for i in 0..s {
                self.stage_modal(s + 1 + i, &mut modal);
                self.system
                    .omega()
                    .modal_to_physical(&modal, &mut stages[i * d..(i + 1) * d]);
            }
            self.modal = modal;
            self.stages = stages;
            for j in 0..s {
                self.eval_f(j)?;
            }
            g_evals = s;
        } else {
            for j in 0..s {
                self.stages[j * d..(j + 1) * d].copy_from_slice(q);
            }
            self.eval_f(0)?;
            for j in 1..s {
                let (first, rest) = self.f.split_at_mut(j * d);
                rest[..d].copy_from_slice(&first[..d]);
            }
            g_evals = 1;
        }
        let (mut sweeps, mut previous) = (0, f64::INFINITY);
        let (residual, converged) = loop {
            self.update_moments();
            let mut modal = std::mem::take(&mut self.modal);
            let mut new_stages = std::mem::take(&mut self.new_stages);
            for i in 0..s {
                self.stage_modal(i, &mut modal);
                self.system
                    .omega()
                    .modal_to_physical(&modal, &mut new_stages[i * d..(i + 1) * d]);
            }
            self.modal = modal;
            let (mut diff, mut mag) = (0.0f64, 1.0f64);
            for (a, b) in new_stages.iter().zip(&self.stages) {
                diff = diff.max((a - b).abs());
                mag = mag.max(a.abs());
            }
            self.new_stages = std::mem::replace(&mut self.stages, new_stages);
            let residual = diff / mag;
            sweeps += 1;
            for j in 0..s {
                self.eval_f(j)?;
            }
            g_evals += s;
            if !residual.is_finite() {
                return Err(crate::stepper::stages_fault(previous));
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
        self.update_moments();
        // q₁ (modal) into `modal`, p₁ (modal) into new_stages[..d] as scratch.
        let mut modal = std::mem::take(&mut self.modal);
        self.stage_modal(s, &mut modal);
        let (t0, t1) = (self.bank.get(s, 0), self.bank.get(s, 1));
        let lam = self.system.omega().eigenvalues();
        let h = self.h;
        let pm = &mut self.new_stages[..d];
        for l in 0..d {
            pm[l] = -h * lam[l] * t1[l] * self.q0m[l] + t0[l] * self.p0m[l];
        }
        for k in 0..r {
            let tk = self.bank.get(s, k + 1);
            let mk = &self.moments_m[k * d..(k + 1) * d];
            for l in 0..d {
                pm[l] -= h * tk[l] * mk[l];
            }
        }
        let omega = self.system.omega();
        omega.modal_to_physical(&modal, q);
        omega.modal_to_physical(&self.new_stages[..d], p);
        std::mem::swap(&mut self.q0m, &mut self.prev_q0m);
        std::mem::swap(&mut self.p0m, &mut self.prev_p0m);
        self.q0m.copy_from_slice(&modal);
        self.p0m.copy_from_slice(&self.new_stages[..d]);
        self.have_previous = true;
        self.last_q.copy_from_slice(q);
        self.last_p.copy_from_slice(p);
        self.modal_valid = true;
        self.modal = modal;
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
