//! Explicit exponential integrators the paper compares against
//! (`docs/architecture.md#baselines`).
//!
//! * [`Exprb43`]: the exponential Rosenbrock method *exprb43* of Hochbruck, Ostermann and
//!   Schweitzer (SIAM J. Numer. Anal. 47, 2009), the paper's "EEI3s4": explicit, three stages,
//!   order 4, with the Jacobian `J_n = A + g'(y_n)` refreshed every step,
//!
//!   ```text
//!   N_n(y) = f(y) − J_n y,   D_{ni} = N_n(U_{ni}) − N_n(y_n) = g(U_{ni}) − g(y_n) − g'(y_n)(U_{ni} − y_n)
//!   U_{n2}  = y_n + (h/2) φ₁(hJ_n/2) f(y_n)
//!   U_{n3}  = y_n + h φ₁(hJ_n) f(y_n) + h φ₁(hJ_n) D_{n2}
//!   y_{n+1} = y_n + h φ₁(hJ_n) f(y_n) + h (16φ₃ − 48φ₄)(hJ_n) D_{n2} + h (−2φ₃ + 12φ₄)(hJ_n) D_{n3}
//!   ```
//!
//!   (the weights satisfy the stiff order conditions `Σ bᵢ cᵢ² = 2φ₃`, `Σ bᵢ cᵢ³ = 6φ₄`).
//!   The φ-functions of the dense `hJ_n/2` come from [`phi_dense`] each step (`O(d³)`; the
//!   method's real cost), those of `hJ_n` by one doubling step. [`Exprb43::frozen`] keeps
//!   `J = A`: then `N_n'(y_n) = g'(y_n) ≠ 0` and the method is only of order 2 for nonlinear g.
//! * [`HochOst4`]: the five-stage explicit exponential Runge–Kutta method of Hochbruck and
//!   Ostermann (SIAM J. Numer. Anal. 43, 2005), stiff order 4, with the fixed linear part A:
//!
//!   ```text
//!   U_i     = e^{c_i hA} y_n + h Σ_{j<i} a_ij(hA) g(U_j),   c = (0, ½, ½, 1, ½)
//!   y_{n+1} = e^{hA} y_n + h Σ_i b_i(hA) g(U_i)
//!   ```
//!
//!   with `φ_{j,i} = φ_j(c_i hA)`: `a₂₁ = ½φ₁,₂`; `a₃₁ = ½φ₁,₃ − φ₂,₃`, `a₃₂ = φ₂,₃`;
//!   `a₄₁ = φ₁,₄ − 2φ₂,₄`, `a₄₂ = a₄₃ = φ₂,₄`; `a₅₂ = a₅₃ = ½φ₂,₅ − φ₃,₄ + ¼φ₂,₄ − ½φ₃,₅`,
//!   `a₅₄ = ¼φ₂,₅ − a₅₂`, `a₅₁ = ½φ₁,₅ − 2a₅₂ − a₅₄`; `b₁ = φ₁ − 3φ₂ + 4φ₃`, `b₂ = b₃ = 0`,
//!   `b₄ = −φ₂ + 4φ₃`, `b₅ = 4φ₂ − 8φ₃` (`φ_k = φ_k(hA)`). All coefficient matrices are built
//!   once per step size.
//!
//! Both reduce to the exact flow `y_{n+1} = e^{hA} y_n` for `g = 0`. The linear part is used
//! as a dense matrix, assembled once at construction by applying
//! [`LinearOperator::apply`] to the unit vectors: these baselines are meant for small d.
//! Steps of [`HochOst4`] and of the frozen [`Exprb43`] do not allocate; a step of the
//! refreshed [`Exprb43`] allocates only inside [`phi_dense`].

use nalgebra::DMatrix;

/// The 1-norm (largest column sum of magnitudes).
fn norm1(a: &DMatrix<f64>) -> f64 {
    a.column_iter()
        .map(|c| c.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max)
}

use ecr_runtime::integrate::Integrator;
use ecr_runtime::operator::LinearOperator;
use ecr_runtime::phi::phi_dense;
use ecr_runtime::stepper::StepReport;
use ecr_runtime::system::System;
use ecr_runtime::{Error, Result};

/// The dense matrix of the system's linear part, column j = A e_j.
fn dense_linear<S: System>(system: &S) -> Result<DMatrix<f64>> {
    let op = system.linear();
    let d = op.dim();
    let mut a = DMatrix::zeros(d, d);
    let mut e = vec![0.0; d];
    let mut col = vec![0.0; d];
    for j in 0..d {
        e[j] = 1.0;
        op.apply(&e, &mut col);
        e[j] = 0.0;
        a.column_mut(j).copy_from_slice(&col);
    }
    if a.iter().any(|v| !v.is_finite()) {
        return Err(Error::NonFinite("linear part A"));
    }
    Ok(a)
}

fn check_h(h: f64) -> Result<()> {
    if !(h.is_finite() && h > 0.0) {
        return Err(Error::InvalidStepSize(h));
    }
    Ok(())
}

fn check_state(y: &[f64], d: usize) -> Result<()> {
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
    Ok(())
}

/// `out += alpha · M x` (M column-major, square of size `out.len()`). Does not allocate.
fn matvec_add(m: &DMatrix<f64>, x: &[f64], alpha: f64, out: &mut [f64]) {
    let d = out.len();
    debug_assert_eq!(m.nrows(), d);
    debug_assert_eq!(m.ncols(), x.len());
    for (col, &xj) in m.as_slice().chunks_exact(d).zip(x) {
        let s = alpha * xj;
        for (o, &mij) in out.iter_mut().zip(col) {
            *o += s * mij;
        }
    }
}

/// `m += alpha · x` entrywise.
fn add_scaled(m: &mut DMatrix<f64>, alpha: f64, x: &DMatrix<f64>) {
    for (a, b) in m.iter_mut().zip(x.iter()) {
        *a += alpha * b;
    }
}

/// Evaluates g(y) into `out` and checks it is finite.
fn eval_g<S: System>(
    system: &S,
    y: &[f64],
    out: &mut [f64],
    scratch: &mut [f64],
    what: &'static str,
) -> Result<()> {
    system.nonlinear(y, out, scratch);
    if out.iter().any(|v| !v.is_finite()) {
        return Err(Error::NonFinite(what));
    }
    Ok(())
}

/// Where [`Exprb43`] takes the Jacobian g'(yₙ) from.
enum JacobianSource<J> {
    /// Central differences of g.
    FiniteDifference,
    /// A user closure writing g'(y) into a zeroed d × d matrix.
    Closure(J),
    /// No Jacobian: J = A always (order 2 for nonlinear g).
    Frozen,
}

/// The exponential Rosenbrock method exprb43 (Hochbruck–Ostermann–Schweitzer 2009), the
/// paper's EEI3s4; see the [module documentation](self) for the scheme.
///
/// Three evaluations of g per step, plus 2d for the finite-difference Jacobian
/// ([`Exprb43::new`]); one [`phi_dense`] of a d × d matrix and three d × d products per step
/// (none for [`Exprb43::frozen`], whose φ-functions are built once per step size).
pub struct Exprb43<S: System, J = fn(&[f64], &mut DMatrix<f64>)> {
    system: S,
    h: f64,
    source: JacobianSource<J>,
    /// The dense linear part A.
    a: DMatrix<f64>,
    /// g'(yₙ) (zero when frozen).
    gjac: DMatrix<f64>,
    /// hJ/2, then scratch for the doubling products.
    work: DMatrix<f64>,
    /// ‖hJ/2‖₁ of the last φ-functions built (for the message of an overflow).
    work_norm: f64,
    /// φ₁(hJ/2).
    phi1_half: DMatrix<f64>,
    /// φ₁(hJ).
    phi1: DMatrix<f64>,
    /// 16φ₃(hJ) − 48φ₄(hJ).
    b2: DMatrix<f64>,
    /// −2φ₃(hJ) + 12φ₄(hJ).
    b3: DMatrix<f64>,
    y0: Vec<f64>,
    f0: Vec<f64>,
    g0: Vec<f64>,
    w: Vec<f64>,
    u: Vec<f64>,
    gu: Vec<f64>,
    d2: Vec<f64>,
    d3: Vec<f64>,
    out: Vec<f64>,
    scratch: Vec<f64>,
}

impl<S: System> Exprb43<S> {
    /// exprb43 with the Jacobian g'(yₙ) by central differences, column j with the step
    /// `δ_j = ε^{1/3} max(1, |y_j|)` (the optimal step for central differences: truncation
    /// and rounding errors both O(ε^{2/3})), 2d extra evaluations of g per step.
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`], [`Error::NonFinite`] if A has non-finite entries, the errors
    /// of [`check_system`](ecr_runtime::system::check_system).
    pub fn new(system: S, h: f64) -> Result<Self> {
        Self::build(system, h, JacobianSource::FiniteDifference)
    }

    /// exprb43 with J = A frozen (no Jacobian of g): an exponential Rosenbrock scheme with a
    /// wrong Jacobian, **order 2** for nonlinear g (order 4 only if g is constant). Kept to
    /// show why the Jacobian must be refreshed.
    ///
    /// # Errors
    /// As [`Exprb43::new`], and whatever [`phi_dense`] reports for hA.
    pub fn frozen(system: S, h: f64) -> Result<Self> {
        Self::build(system, h, JacobianSource::Frozen)
    }
}

impl<S: System, J: Fn(&[f64], &mut DMatrix<f64>)> Exprb43<S, J> {
    /// exprb43 with a user-supplied Jacobian of g: `jacobian(y, m)` writes g'(y) into the
    /// d × d matrix `m`, which is zeroed before each call (only the nonzero entries need be
    /// written).
    ///
    /// # Errors
    /// As [`Exprb43::new`].
    pub fn with_jacobian(system: S, h: f64, jacobian: J) -> Result<Self> {
        Self::build(system, h, JacobianSource::Closure(jacobian))
    }

    fn build(system: S, h: f64, source: JacobianSource<J>) -> Result<Self> {
        check_h(h)?;
        ecr_runtime::system::check_system(&system)?;
        let a = dense_linear(&system)?;
        let d = a.nrows();
        let z = || DMatrix::zeros(d, d);
        let v = || vec![0.0; d];
        let scratch = vec![0.0; system.scratch_len()];
        let mut method = Exprb43 {
            system,
            h,
            source,
            a,
            gjac: z(),
            work: z(),
            work_norm: 0.0,
            phi1_half: z(),
            phi1: z(),
            b2: z(),
            b3: z(),
            y0: v(),
            f0: v(),
            g0: v(),
            w: v(),
            u: v(),
            gu: v(),
            d2: v(),
            d3: v(),
            out: v(),
            scratch,
        };
        if method.is_frozen() {
            method.build_phis()?;
        }
        Ok(method)
    }

    /// Whether J = A is frozen ([`Exprb43::frozen`]).
    pub fn is_frozen(&self) -> bool {
        matches!(self.source, JacobianSource::Frozen)
    }

    /// The system.
    pub fn system(&self) -> &S {
        &self.system
    }

    /// The step size.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// Changes the step size (rebuilds the φ-functions of the frozen variant).
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`] and, when frozen, whatever [`phi_dense`] reports.
    pub fn set_step_size(&mut self, h: f64) -> Result<()> {
        check_h(h)?;
        if h == self.h {
            return Ok(());
        }
        let old = self.h;
        self.h = h;
        if self.is_frozen()
            && let Err(e) = self.build_phis()
        {
            self.h = old;
            self.build_phis()?;
            return Err(e);
        }
        Ok(())
    }

    /// φ₁(hJ/2), φ₁(hJ), 16φ₃ − 48φ₄ and −2φ₃ + 12φ₄ at hJ, J = A + gjac.
    ///
    /// φ_k(2Z) = 2^{−k} [φ₀(Z) φ_k(Z) + Σ_{j=1}^{k} φ_j(Z)/(k − j)!] with Z = hJ/2.
    fn build_phis(&mut self) -> Result<()> {
        let half = 0.5 * self.h;
        for ((w, a), g) in self
            .work
            .iter_mut()
            .zip(self.a.iter())
            .zip(self.gjac.iter())
        {
            *w = half * (a + g);
        }
        self.work_norm = norm1(&self.work);
        let ph = phi_dense(&self.work, 4)?;
        self.phi1_half.copy_from(&ph[1]);
        // φ₁(2Z) = ½ (φ₀φ₁ + φ₁)
        self.phi1.copy_from(&ph[1]);
        self.phi1.gemm(0.5, &ph[0], &ph[1], 0.5);
        // φ₃(2Z) = ⅛ (φ₀φ₃ + φ₁/2 + φ₂ + φ₃) into b2 (temporarily)
        self.b2.copy_from(&ph[3]);
        self.b2 += &ph[2];
        add_scaled(&mut self.b2, 0.5, &ph[1]);
        self.b2.gemm(0.125, &ph[0], &ph[3], 0.125);
        // φ₄(2Z) = 1/16 (φ₀φ₄ + φ₁/6 + φ₂/2 + φ₃ + φ₄) into work
        self.work.copy_from(&ph[4]);
        self.work += &ph[3];
        add_scaled(&mut self.work, 0.5, &ph[2]);
        add_scaled(&mut self.work, 1.0 / 6.0, &ph[1]);
        self.work.gemm(0.0625, &ph[0], &ph[4], 0.0625);
        // b3 = −2φ₃ + 12φ₄, b2 = 16φ₃ − 48φ₄
        for ((b3, b2), p4) in self
            .b3
            .iter_mut()
            .zip(self.b2.iter_mut())
            .zip(self.work.iter())
        {
            let p3 = *b2;
            *b3 = -2.0 * p3 + 12.0 * p4;
            *b2 = 16.0 * p3 - 48.0 * p4;
        }
        if [&self.phi1_half, &self.phi1, &self.b2, &self.b3]
            .iter()
            .any(|m| m.iter().any(|v| !v.is_finite()))
        {
            return Err(Error::Numerical(format!(
                "φ-functions of hJ overflow f64 (‖hJ‖₁ = {:.3e}: e^(hJ) grows up to \
                 e^‖hJ‖₁, through eigenvalues with a large positive real part or the transient \
                 growth of a non-normal J); a smaller h keeps them finite",
                2.0 * self.work_norm
            )));
        }
        Ok(())
    }

    /// g'(y0) into `gjac`; returns the evaluations of g it used.
    fn jacobian(&mut self) -> Result<usize> {
        let d = self.y0.len();
        match &self.source {
            JacobianSource::Frozen => Ok(0),
            JacobianSource::Closure(jac) => {
                self.gjac.fill(0.0);
                jac(&self.y0, &mut self.gjac);
                if self.gjac.nrows() != d || self.gjac.ncols() != d {
                    let found = self.gjac.nrows();
                    self.gjac = DMatrix::zeros(d, d);
                    return Err(Error::DimensionMismatch {
                        what: "Jacobian g'(y) (rows)",
                        expected: d,
                        found,
                    });
                }
                if self.gjac.iter().any(|v| !v.is_finite()) {
                    return Err(Error::NonFinite("Jacobian g'(y)"));
                }
                Ok(0)
            }
            JacobianSource::FiniteDifference => {
                let cbrt_eps = f64::EPSILON.cbrt();
                self.u.copy_from_slice(&self.y0);
                for j in 0..d {
                    let yj = self.y0[j];
                    let plus = yj + cbrt_eps * yj.abs().max(1.0);
                    let minus = yj - (plus - yj);
                    let width = plus - minus;
                    self.u[j] = plus;
                    eval_g(
                        &self.system,
                        &self.u,
                        &mut self.gu,
                        &mut self.scratch,
                        "g(y) in the finite-difference Jacobian",
                    )?;
                    self.u[j] = minus;
                    eval_g(
                        &self.system,
                        &self.u,
                        &mut self.d3,
                        &mut self.scratch,
                        "g(y) in the finite-difference Jacobian",
                    )?;
                    self.u[j] = yj;
                    for ((c, p), m) in self
                        .gjac
                        .column_mut(j)
                        .iter_mut()
                        .zip(&self.gu)
                        .zip(&self.d3)
                    {
                        *c = (p - m) / width;
                    }
                }
                Ok(2 * d)
            }
        }
    }

    /// `D = g(U) − g(y0) − g'(y0) w`, with `U = y0 + w` in `u` and g(U) in `gu`.
    fn defect(gu: &[f64], g0: &[f64], gjac: &DMatrix<f64>, w: &[f64], frozen: bool, d: &mut [f64]) {
        for ((di, a), b) in d.iter_mut().zip(gu).zip(g0) {
            *di = a - b;
        }
        if !frozen {
            matvec_add(gjac, w, -1.0, d);
        }
    }

    /// Advances y by one step of size h in place.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] for a wrong length, [`Error::NonFinite`] if y, g, the
    /// Jacobian or the result is NaN/infinite, [`Error::Numerical`] if the φ-functions of hJ
    /// overflow. On error, y is unchanged.
    pub fn step(&mut self, y: &mut [f64]) -> Result<StepReport> {
        let d = self.a.nrows();
        check_state(y, d)?;
        let h = self.h;
        let frozen = self.is_frozen();
        self.y0.copy_from_slice(y);
        eval_g(
            &self.system,
            &self.y0,
            &mut self.g0,
            &mut self.scratch,
            "g(y)",
        )?;
        // f(y0) = A y0 + g(y0)
        self.system.linear().apply(&self.y0, &mut self.f0);
        for (f, g) in self.f0.iter_mut().zip(&self.g0) {
            *f += g;
        }
        let mut g_evals = 1 + self.jacobian()?;
        if !frozen {
            self.build_phis()?;
        }
        // U2 = y0 + (h/2) φ₁(hJ/2) f0
        self.w.fill(0.0);
        matvec_add(&self.phi1_half, &self.f0, 0.5 * h, &mut self.w);
        for ((u, y), w) in self.u.iter_mut().zip(&self.y0).zip(&self.w) {
            *u = y + w;
        }
        eval_g(
            &self.system,
            &self.u,
            &mut self.gu,
            &mut self.scratch,
            "g(U2)",
        )?;
        Self::defect(
            &self.gu,
            &self.g0,
            &self.gjac,
            &self.w,
            frozen,
            &mut self.d2,
        );
        // U3 = y0 + h φ₁(hJ) (f0 + D2)
        for ((u, f), d2) in self.u.iter_mut().zip(&self.f0).zip(&self.d2) {
            *u = f + d2;
        }
        self.w.fill(0.0);
        matvec_add(&self.phi1, &self.u, h, &mut self.w);
        for ((u, y), w) in self.u.iter_mut().zip(&self.y0).zip(&self.w) {
            *u = y + w;
        }
        eval_g(
            &self.system,
            &self.u,
            &mut self.gu,
            &mut self.scratch,
            "g(U3)",
        )?;
        Self::defect(
            &self.gu,
            &self.g0,
            &self.gjac,
            &self.w,
            frozen,
            &mut self.d3,
        );
        g_evals += 2;
        // y1 = y0 + h φ₁ f0 + h b2 D2 + h b3 D3
        self.out.copy_from_slice(&self.y0);
        matvec_add(&self.phi1, &self.f0, h, &mut self.out);
        matvec_add(&self.b2, &self.d2, h, &mut self.out);
        matvec_add(&self.b3, &self.d3, h, &mut self.out);
        if self.out.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("exprb43 step result"));
        }
        y.copy_from_slice(&self.out);
        Ok(super::explicit_step(g_evals))
    }
}

impl<S: System, J: Fn(&[f64], &mut DMatrix<f64>)> Integrator for Exprb43<S, J> {
    fn step_size(&self) -> f64 {
        self.h
    }
    fn set_step_size(&mut self, h: f64) -> Result<()> {
        Exprb43::set_step_size(self, h)
    }
    fn step_state(&mut self, y: &mut [f64]) -> Result<StepReport> {
        self.step(y)
    }
    fn energy_of(&self, y: &[f64]) -> Option<f64> {
        self.system.energy(y)
    }
}

/// The coefficient matrices of [`HochOst4`] for one step size (all without the factor h).
struct HochOst4Coefficients {
    /// e^{hA/2}.
    e_half: DMatrix<f64>,
    /// e^{hA}.
    e_one: DMatrix<f64>,
    a21: DMatrix<f64>,
    a31: DMatrix<f64>,
    a32: DMatrix<f64>,
    a41: DMatrix<f64>,
    /// a₄₂ = a₄₃.
    a42: DMatrix<f64>,
    a51: DMatrix<f64>,
    /// a₅₂ = a₅₃.
    a52: DMatrix<f64>,
    a54: DMatrix<f64>,
    b1: DMatrix<f64>,
    b4: DMatrix<f64>,
    b5: DMatrix<f64>,
}

impl HochOst4Coefficients {
    fn new(a: &DMatrix<f64>, h: f64) -> Result<Self> {
        let one = phi_dense(&(a * h), 3)?;
        let half = phi_dense(&(a * (0.5 * h)), 3)?;
        let (p1, p2, p3) = (&one[1], &one[2], &one[3]);
        let (q1, q2, q3) = (&half[1], &half[2], &half[3]);
        let a52 = q2 * 0.5 - p3 + p2 * 0.25 - q3 * 0.5;
        let a54 = q2 * 0.25 - &a52;
        let a51 = q1 * 0.5 - &a52 * 2.0 - &a54;
        let c = HochOst4Coefficients {
            e_half: half[0].clone(),
            e_one: one[0].clone(),
            a21: q1 * 0.5,
            a31: q1 * 0.5 - q2,
            a32: q2.clone(),
            a41: p1 - p2 * 2.0,
            a42: p2.clone(),
            a51,
            a52,
            a54,
            b1: p1 - p2 * 3.0 + p3 * 4.0,
            b4: p3 * 4.0 - p2,
            b5: p2 * 4.0 - p3 * 8.0,
        };
        let all = [
            &c.e_half, &c.e_one, &c.a21, &c.a31, &c.a32, &c.a41, &c.a42, &c.a51, &c.a52, &c.a54,
            &c.b1, &c.b4, &c.b5,
        ];
        if all.iter().any(|m| m.iter().any(|v| !v.is_finite())) {
            return Err(Error::Numerical(format!(
                "φ-functions of hA overflow f64 (‖hA‖₁ = {:.3e}: e^(hA) grows up to \
                 e^‖hA‖₁, through eigenvalues with a large positive real part or the transient \
                 growth of a non-normal A); a smaller h keeps them finite",
                norm1(&(a * h))
            )));
        }
        Ok(c)
    }
}

/// The explicit exponential Runge–Kutta method of Hochbruck and Ostermann (2005): five
/// stages, stiff order 4, J = A fixed; see the [module documentation](self) for the tableau.
///
/// Five evaluations of g per step; the coefficient matrices are built once per step size
/// (two [`phi_dense`] calls), and a step does not allocate (`O(d²)` per stage).
pub struct HochOst4<S: System> {
    system: S,
    h: f64,
    a: DMatrix<f64>,
    c: HochOst4Coefficients,
    y0: Vec<f64>,
    /// g(U₁), …, g(U₅), each d entries.
    g: Vec<f64>,
    u: Vec<f64>,
    out: Vec<f64>,
    scratch: Vec<f64>,
}

impl<S: System> HochOst4<S> {
    /// The method for `system` with step size `h`.
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`], [`Error::NonFinite`] if A has non-finite entries, the errors
    /// of [`check_system`](ecr_runtime::system::check_system), and whatever [`phi_dense`] reports for
    /// hA.
    pub fn new(system: S, h: f64) -> Result<Self> {
        check_h(h)?;
        ecr_runtime::system::check_system(&system)?;
        let a = dense_linear(&system)?;
        let d = a.nrows();
        let c = HochOst4Coefficients::new(&a, h)?;
        let scratch = vec![0.0; system.scratch_len()];
        Ok(HochOst4 {
            system,
            h,
            a,
            c,
            y0: vec![0.0; d],
            g: vec![0.0; 5 * d],
            u: vec![0.0; d],
            out: vec![0.0; d],
            scratch,
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

    /// Changes the step size (rebuilds the coefficient matrices: call it rarely).
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`] and whatever [`phi_dense`] reports.
    pub fn set_step_size(&mut self, h: f64) -> Result<()> {
        check_h(h)?;
        if h != self.h {
            self.c = HochOst4Coefficients::new(&self.a, h)?;
            self.h = h;
        }
        Ok(())
    }

    /// Advances y by one step of size h in place. Does not allocate.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] for a wrong length, [`Error::NonFinite`] if y, g at a
    /// stage or the result is NaN/infinite. On error, y is unchanged.
    pub fn step(&mut self, y: &mut [f64]) -> Result<StepReport> {
        let d = self.a.nrows();
        check_state(y, d)?;
        let h = self.h;
        let HochOst4 {
            system,
            c,
            y0,
            g,
            u,
            out,
            scratch,
            ..
        } = self;
        y0.copy_from_slice(y);
        let (g1, rest) = g.split_at_mut(d);
        let (g2, rest) = rest.split_at_mut(d);
        let (g3, rest) = rest.split_at_mut(d);
        let (g4, g5) = rest.split_at_mut(d);
        eval_g(system, y0, g1, scratch, "g(U1)")?;
        // U2 = e^{hA/2} y0 + h a21 g1
        u.fill(0.0);
        matvec_add(&c.e_half, y0, 1.0, u);
        matvec_add(&c.a21, g1, h, u);
        eval_g(system, u, g2, scratch, "g(U2)")?;
        // U3 = e^{hA/2} y0 + h (a31 g1 + a32 g2)
        u.fill(0.0);
        matvec_add(&c.e_half, y0, 1.0, u);
        matvec_add(&c.a31, g1, h, u);
        matvec_add(&c.a32, g2, h, u);
        eval_g(system, u, g3, scratch, "g(U3)")?;
        // U4 = e^{hA} y0 + h (a41 g1 + a42 (g2 + g3))
        u.fill(0.0);
        matvec_add(&c.e_one, y0, 1.0, u);
        matvec_add(&c.a41, g1, h, u);
        matvec_add(&c.a42, g2, h, u);
        matvec_add(&c.a42, g3, h, u);
        eval_g(system, u, g4, scratch, "g(U4)")?;
        // U5 = e^{hA/2} y0 + h (a51 g1 + a52 (g2 + g3) + a54 g4)
        u.fill(0.0);
        matvec_add(&c.e_half, y0, 1.0, u);
        matvec_add(&c.a51, g1, h, u);
        matvec_add(&c.a52, g2, h, u);
        matvec_add(&c.a52, g3, h, u);
        matvec_add(&c.a54, g4, h, u);
        eval_g(system, u, g5, scratch, "g(U5)")?;
        // y1 = e^{hA} y0 + h (b1 g1 + b4 g4 + b5 g5)
        out.fill(0.0);
        matvec_add(&c.e_one, y0, 1.0, out);
        matvec_add(&c.b1, g1, h, out);
        matvec_add(&c.b4, g4, h, out);
        matvec_add(&c.b5, g5, h, out);
        if out.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("HochOst4 step result"));
        }
        y.copy_from_slice(out);
        Ok(StepReport {
            sweeps: 0,
            residual: 0.0,
            g_evals: 5,
            converged: true,
            jacobian_evals: 0,
            newton_refreshes: 0,
        })
    }
}

impl<S: System> Integrator for HochOst4<S> {
    fn step_size(&self) -> f64 {
        self.h
    }
    fn set_step_size(&mut self, h: f64) -> Result<()> {
        HochOst4::set_step_size(self, h)
    }
    fn step_state(&mut self, y: &mut [f64]) -> Result<StepReport> {
        self.step(y)
    }
    fn energy_of(&self, y: &[f64]) -> Option<f64> {
        self.system.energy(y)
    }
}
