//! Matrix-free exprb43 for large systems: φ-functions of the Jacobian applied to vectors by
//! Krylov projection of an augmented matrix, so that EEI3s4 (exprb43 with J = A + g'(yₙ)
//! refreshed every step) is affordable where the dense φ-functions are not (the NLS, d = 256).
//!
//! [`KrylovPhi`] computes w = Σ_{k=0}^{p} φ_k(M) b_k for M = tJ with only products J·x, by
//! the identity of Al-Mohy & Higham (SIAM J. Sci. Comput. 33, 2011, Thm 2.1):
//! w = [I 0] exp(B) [b₀; e_p],  B = [[M, W], [0, J_p]],  W = [b_p, …, b₁],  J_p the p × p shift.
//! exp(B)z is approximated in the Arnoldi basis of B and z (Saad 1992), with the a-posteriori
//! estimate β h_{m+1,m} |e_mᵀ exp(H_m) e₁| and halving of B (exp(B) = exp(B/2)²) when m
//! reaches its limit.

use ecr_runtime::integrate::Integrator;
use ecr_runtime::operator::LinearOperator;
use ecr_runtime::phi::phi_dense;
use ecr_runtime::stepper::StepReport;
use ecr_runtime::system::System;
use ecr_runtime::{Error, Result};
use nalgebra::DMatrix;

/// The product y = J x, supplied by the caller.
pub type JMul<'a> = dyn FnMut(&[f64], &mut [f64]) -> Result<()> + 'a;

/// Krylov evaluator of Σ_k φ_k(tJ) b_k, with its workspace.
pub struct KrylovPhi {
    n: usize,
    p: usize,
    m_max: usize,
    tol: f64,
    basis: Vec<Vec<f64>>,
    w: Vec<f64>,
    z: Vec<f64>,
    jx: Vec<f64>,
}

impl KrylovPhi {
    /// Workspace for vectors of length n, φ-functions up to order p, at most `m_max` Arnoldi
    /// vectors per exponential, relative tolerance `tol`.
    pub fn new(n: usize, p: usize, m_max: usize, tol: f64) -> Self {
        let big = n + p;
        KrylovPhi {
            n,
            p,
            m_max,
            tol,
            basis: (0..=m_max).map(|_| vec![0.0; big]).collect(),
            w: vec![0.0; big],
            z: vec![0.0; big],
            jx: vec![0.0; n],
        }
    }

    /// `out = Σ_{k=0}^{b.len()−1} φ_k(t J) b[k]` (b.len() ≤ p + 1), J given by `jmul(x, y)`:
    /// y = J x.
    ///
    /// # Errors
    /// [`Error::Numerical`] if the Krylov iteration does not reach the tolerance after 12
    /// halvings, or a φ-function of the projected matrix fails.
    pub fn apply(
        &mut self,
        jmul: &mut JMul<'_>,
        t: f64,
        b: &[&[f64]],
        out: &mut [f64],
    ) -> Result<()> {
        let (n, p) = (self.n, b.len() - 1);
        assert!(p <= self.p && out.len() == n);
        // z₀ = [b₀; e_p] (for p = 0 just b₀).
        self.z.iter_mut().for_each(|v| *v = 0.0);
        self.z[..n].copy_from_slice(b[0]);
        if p > 0 {
            self.z[n + p - 1] = 1.0;
        }
        let z = std::mem::take(&mut self.z);
        let mut cur = z.clone();
        let result = self.exp_times(jmul, t, b, &mut cur, 0);
        self.z = z;
        result?;
        out.copy_from_slice(&cur[..n]);
        Ok(())
    }

    /// v ← exp(σ B) v with σ = 2^{−level} (applied 2^level times through recursion).
    fn exp_times(
        &mut self,
        jmul: &mut JMul<'_>,
        t: f64,
        b: &[&[f64]],
        v: &mut Vec<f64>,
        level: u32,
    ) -> Result<()> {
        let sigma = 0.5f64.powi(level as i32);
        if self.try_exp(jmul, t, b, v, sigma)? {
            return Ok(());
        }
        if level >= 12 {
            return Err(Error::Numerical(
                "Krylov φ-evaluation did not converge".into(),
            ));
        }
        self.exp_times(jmul, t, b, v, level + 1)?;
        self.exp_times(jmul, t, b, v, level + 1)
    }

    /// y = σ B x.
    fn bmul(
        &mut self,
        jmul: &mut JMul<'_>,
        t: f64,
        b: &[&[f64]],
        sigma: f64,
        x: &[f64],
        y: &mut [f64],
    ) -> Result<()> {
        let (n, p) = (self.n, b.len() - 1);
        jmul(&x[..n], &mut self.jx)?;
        for i in 0..n {
            let mut s = t * self.jx[i];
            // W u = Σ_{i=1}^{p} u_i b_{p+1−i}, u_i = x[n + i − 1].
            for k in 1..=p {
                s += x[n + k - 1] * b[p + 1 - k][i];
            }
            y[i] = sigma * s;
        }
        for k in 0..p {
            y[n + k] = if k + 1 < p { sigma * x[n + k + 1] } else { 0.0 };
        }
        Ok(())
    }

    /// One Arnoldi approximation of exp(σB)v; false if the estimate misses the tolerance.
    fn try_exp(
        &mut self,
        jmul: &mut JMul<'_>,
        t: f64,
        b: &[&[f64]],
        v: &mut [f64],
        sigma: f64,
    ) -> Result<bool> {
        let big = self.n + b.len() - 1;
        let beta = v[..big].iter().map(|x| x * x).sum::<f64>().sqrt();
        if beta == 0.0 {
            return Ok(true);
        }
        let mut h = DMatrix::<f64>::zeros(self.m_max + 1, self.m_max);
        for (q, x) in self.basis[0].iter_mut().zip(v.iter()) {
            *q = x / beta;
        }
        let mut m = 0;
        let mut coeffs: Option<Vec<f64>> = None;
        while m < self.m_max {
            let mut w = std::mem::take(&mut self.w);
            let q = std::mem::take(&mut self.basis[m]);
            self.bmul(jmul, t, b, sigma, &q[..big], &mut w[..big])?;
            self.basis[m] = q;
            for i in 0..=m {
                let hij: f64 = w[..big]
                    .iter()
                    .zip(&self.basis[i][..big])
                    .map(|(a, c)| a * c)
                    .sum();
                h[(i, m)] = hij;
                w[..big]
                    .iter_mut()
                    .zip(&self.basis[i][..big])
                    .for_each(|(a, c)| *a -= hij * c);
            }
            let norm = w[..big].iter().map(|x| x * x).sum::<f64>().sqrt();
            h[(m + 1, m)] = norm;
            m += 1;
            let breakdown = norm <= 1e-14 * beta.max(1.0) * h.view((0, 0), (m, m)).amax().max(1.0);
            if !breakdown {
                for (q, a) in self.basis[m].iter_mut().zip(w.iter()) {
                    *q = a / norm;
                }
            }
            self.w = w;
            if breakdown || m % 4 == 0 || m == self.m_max {
                let hm = h.view((0, 0), (m, m)).into_owned();
                let e = phi_dense(&hm, 0)?.swap_remove(0);
                let est = beta * norm * e[(m - 1, 0)].abs();
                if breakdown || est <= self.tol * beta {
                    coeffs = Some((0..m).map(|i| beta * e[(i, 0)]).collect());
                    break;
                }
            }
        }
        let Some(c) = coeffs else { return Ok(false) };
        for x in v[..big].iter_mut() {
            *x = 0.0;
        }
        for (i, ci) in c.iter().enumerate() {
            v[..big]
                .iter_mut()
                .zip(&self.basis[i][..big])
                .for_each(|(x, q)| *x += ci * q);
        }
        Ok(true)
    }
}

/// EEI3s4 = exprb43 (Hochbruck–Ostermann–Schweitzer 2009) with J = A + g'(yₙ) refreshed every
/// step, matrix-free: J·x = A·x (the system's structured operator, e.g. FFT) + g'(yₙ)·x (central
/// difference of g), φ-functions by [`KrylovPhi`]. Same method as [`crate::baselines::exponential::Exprb43`] with its
/// finite-difference Jacobian; for large d.
pub struct Exprb43Krylov<S: System> {
    system: S,
    h: f64,
    krylov: KrylovPhi,
    y0: Vec<f64>,
    g0: Vec<f64>,
    f0: Vec<f64>,
    u: Vec<f64>,
    d2: Vec<f64>,
    d3: Vec<f64>,
    tmp: Vec<f64>,
    gp: Vec<f64>,
    gm: Vec<f64>,
    scratch: Vec<f64>,
    g_evals: usize,
}

impl<S: System> Exprb43Krylov<S> {
    /// The method with step size h (Krylov tolerance 1e−13 relative, at most 40 vectors).
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`], the errors of [`check_system`](ecr_runtime::system::check_system).
    pub fn new(system: S, h: f64) -> Result<Self> {
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidStepSize(h));
        }
        ecr_runtime::system::check_system(&system)?;
        let d = system.dim();
        let v = || vec![0.0; d];
        Ok(Exprb43Krylov {
            krylov: KrylovPhi::new(d, 4, 40, 1e-13),
            scratch: vec![0.0; system.scratch_len()],
            system,
            h,
            y0: v(),
            g0: v(),
            f0: v(),
            u: v(),
            d2: v(),
            d3: v(),
            tmp: v(),
            gp: v(),
            gm: v(),
            g_evals: 0,
        })
    }

    fn g(&mut self, y: &[f64], out: &mut [f64]) -> Result<()> {
        self.system.nonlinear(y, out, &mut self.scratch);
        self.g_evals += 1;
        if out.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("g(y)"));
        }
        Ok(())
    }

    /// out = g'(y₀) x by a central difference (step ε^{1/3}(1 + ‖y₀‖∞)/‖x‖∞).
    fn jvp_g(&mut self, x: &[f64], out: &mut [f64]) -> Result<()> {
        let xn = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if xn == 0.0 {
            out.fill(0.0);
            return Ok(());
        }
        let yn = self.y0.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let eps = f64::EPSILON.cbrt() * (1.0 + yn) / xn;
        let mut yp = std::mem::take(&mut self.tmp);
        let (mut gp, mut gm) = (std::mem::take(&mut self.gp), std::mem::take(&mut self.gm));
        for ((t, y), v) in yp.iter_mut().zip(&self.y0).zip(x) {
            *t = y + eps * v;
        }
        let r1 = self.g(&yp, &mut gp);
        for ((t, y), v) in yp.iter_mut().zip(&self.y0).zip(x) {
            *t = y - eps * v;
        }
        let r2 = self.g(&yp, &mut gm);
        for ((o, a), c) in out.iter_mut().zip(&gp).zip(&gm) {
            *o = (a - c) / (2.0 * eps);
        }
        self.tmp = yp;
        self.gp = gp;
        self.gm = gm;
        r1.and(r2)
    }

    /// D = g(u) − g(y₀) − g'(y₀)(u − y₀), u in `self.u`, into `out`.
    fn defect(&mut self, out: &mut [f64]) -> Result<()> {
        let u = std::mem::take(&mut self.u);
        let mut gu = vec![0.0; u.len()];
        self.g(&u, &mut gu)?;
        let du: Vec<f64> = u.iter().zip(&self.y0).map(|(a, b)| a - b).collect();
        let mut jd = vec![0.0; u.len()];
        self.jvp_g(&du, &mut jd)?;
        for i in 0..out.len() {
            out[i] = gu[i] - self.g0[i] - jd[i];
        }
        self.u = u;
        Ok(())
    }

    /// out = Σ φ_k(tJ) b_k with J x = A x + g'(y₀) x.
    fn phi(&mut self, t: f64, b: &[&[f64]], out: &mut [f64]) -> Result<()> {
        let mut krylov = std::mem::replace(&mut self.krylov, KrylovPhi::new(0, 0, 0, 0.0));
        let mut jmul = |x: &[f64], y: &mut [f64]| -> Result<()> {
            let mut gx = vec![0.0; x.len()];
            self.jvp_g(x, &mut gx)?;
            self.system.linear().apply(x, y);
            y.iter_mut().zip(&gx).for_each(|(a, c)| *a += c);
            Ok(())
        };
        let r = krylov.apply(&mut jmul, t, b, out);
        self.krylov = krylov;
        r
    }

    /// One step in place.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`], [`Error::NonFinite`], [`Error::Numerical`].
    pub fn step(&mut self, y: &mut [f64]) -> Result<StepReport> {
        let (d, h) = (self.y0.len(), self.h);
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
        self.g_evals = 0;
        self.y0.copy_from_slice(y);
        let y0 = self.y0.clone();
        let mut g0 = std::mem::take(&mut self.g0);
        self.g(&y0, &mut g0)?;
        self.g0 = g0;
        // f(y₀) = A y₀ + g(y₀)
        let mut f0 = std::mem::take(&mut self.f0);
        self.system.linear().apply(&y0, &mut f0);
        f0.iter_mut().zip(&self.g0).for_each(|(a, c)| *a += c);
        let zero = vec![0.0; d];
        // U₂ = y₀ + φ₁(hJ/2) (h/2) f
        let b1: Vec<f64> = f0.iter().map(|v| 0.5 * h * v).collect();
        let mut w = vec![0.0; d];
        self.phi(0.5 * h, &[&zero, &b1], &mut w)?;
        self.u
            .iter_mut()
            .zip(&y0)
            .zip(&w)
            .for_each(|((u, a), c)| *u = a + c);
        let mut d2 = std::mem::take(&mut self.d2);
        self.defect(&mut d2)?;
        // U₃ = y₀ + φ₁(hJ) h (f + D₂)
        let b1: Vec<f64> = f0.iter().zip(&d2).map(|(a, c)| h * (a + c)).collect();
        self.phi(h, &[&zero, &b1], &mut w)?;
        self.u
            .iter_mut()
            .zip(&y0)
            .zip(&w)
            .for_each(|((u, a), c)| *u = a + c);
        let mut d3 = std::mem::take(&mut self.d3);
        self.defect(&mut d3)?;
        // y₁ = y₀ + φ₁ h f + φ₃ h(16 D₂ − 2 D₃) + φ₄ h(−48 D₂ + 12 D₃), all at hJ.
        let b1: Vec<f64> = f0.iter().map(|v| h * v).collect();
        let b3: Vec<f64> = d2
            .iter()
            .zip(&d3)
            .map(|(a, c)| h * (16.0 * a - 2.0 * c))
            .collect();
        let b4: Vec<f64> = d2
            .iter()
            .zip(&d3)
            .map(|(a, c)| h * (-48.0 * a + 12.0 * c))
            .collect();
        self.phi(h, &[&zero, &b1, &zero, &b3, &b4], &mut w)?;
        self.d2 = d2;
        self.d3 = d3;
        self.f0 = f0;
        let out: Vec<f64> = y0.iter().zip(&w).map(|(a, c)| a + c).collect();
        if out.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("new state y₁"));
        }
        y.copy_from_slice(&out);
        Ok(StepReport {
            sweeps: 0,
            residual: 0.0,
            g_evals: self.g_evals,
            converged: true,
            jacobian_evals: 0,
            newton_refreshes: 0,
        })
    }
}

impl<S: System> Integrator for Exprb43Krylov<S> {
    fn step_size(&self) -> f64 {
        self.h
    }
    fn set_step_size(&mut self, h: f64) -> Result<()> {
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidStepSize(h));
        }
        self.h = h;
        Ok(())
    }
    fn step_state(&mut self, y: &mut [f64]) -> Result<StepReport> {
        self.step(y)
    }
    fn energy_of(&self, y: &[f64]) -> Option<f64> {
        self.system.energy(y)
    }
}
