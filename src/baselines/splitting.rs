//! Splitting methods with the exact linear flow, composed to high order (what users of
//! oscillatory Hamiltonians with a stiff linear part pick: `docs/architecture.md#baselines`).
//!
//! * [`composition`]: symmetric compositions `Ψ_h = Φ_{γ_s h} ∘ … ∘ Φ_{γ_1 h}` of a symmetric
//!   order-2 base method Φ (Σγᵢ = 1, γᵢ = γ_{s+1−i}) of orders 2, 4, 6 and 8.
//! * [`LinearFlowSplitting`]: for `y' = Ay + g(y)` whose nonlinear part has the explicit flow
//!   `y + t·g(y)` (kick), the base method kick(τ/2) ∘ e^{τA} ∘ kick(τ/2) (rotate with the exact
//!   linear flow), composed.
//! * [`StormerVerlet`]: velocity Verlet for `q'' = −Ωq − ∇U(q)` (no exact linear flow: the
//!   force includes Ωq), composed.
//!
//! Both compose their base method with the same table, merge adjacent half-kicks and reuse the
//! last kick's force as the next step's first (FSAL): a step costs s evaluations of g (of ∇U),
//! the first step one more. Both are symplectic for Hamiltonian problems (each substep is the
//! exact flow of a Hamiltonian), so their energy error stays bounded without drift.

use std::ops::Range;

use nalgebra::DMatrix;

use ecr_runtime::integrate::Integrator;
use ecr_runtime::operator::{LinearOperator, PhiBank};
use ecr_runtime::second_order::SecondOrderSystem;
use ecr_runtime::stepper::StepReport;
use ecr_runtime::system::System;
use ecr_runtime::{Error, Result};

/// Strang splitting itself: s = 1, γ₁ = 1 (order 2).
pub const STRANG: [f64; 1] = [1.0];

/// The "triple jump" of Yoshida (Phys. Lett. A 150, 1990) = Suzuki (1990), order 4, s = 3:
/// γ₁ = γ₃ = 1/(2 − 2^{1/3}), γ₂ = −2^{1/3}/(2 − 2^{1/3}) (HLW (II.4.4)); decimals evaluated
/// to 30 digits in 50-digit arithmetic (mpmath).
#[allow(clippy::excessive_precision)]
pub const YOSHIDA4: [f64; 3] = [
    1.351_207_191_959_657_634_047_687_808_97,  // 1/(2 − 2^{1/3})
    -1.702_414_383_919_315_268_095_375_617_94, // −2^{1/3}/(2 − 2^{1/3})
    1.351_207_191_959_657_634_047_687_808_97,  // γ₃ = γ₁
];

/// Kahan & Li, "Composition constants for raising the orders of unconventional schemes for
/// ordinary differential equations", Math. Comp. 66 (1997) 1089–1099, method "s9odr6a":
/// order 6, s = 9, as printed (26 digits) in Hairer–Lubich–Wanner, *Geometric Numerical
/// Integration*, 2nd ed., §V.3.2. Checked: Σγ = 1 and Σγ³ = Σγ⁵ = 0 to 1e−26, and the measured
/// order of the composed Strang splitting is 6.0 in 50-digit arithmetic (and in the tests).
#[allow(clippy::excessive_precision)]
pub const KAHAN_LI6: [f64; 9] = [
    0.392_161_444_007_314_139_279_250_56,  // γ₁ = γ₉
    0.332_599_136_789_359_438_599_748_64,  // γ₂ = γ₈
    -0.706_246_172_557_639_359_809_964_82, // γ₃ = γ₇
    0.082_213_596_293_550_800_231_490_45,  // γ₄ = γ₆
    0.798_543_990_934_829_963_398_950_35,  // γ₅
    0.082_213_596_293_550_800_231_490_45,
    -0.706_246_172_557_639_359_809_964_82,
    0.332_599_136_789_359_438_599_748_64,
    0.392_161_444_007_314_139_279_250_56,
];

/// Kahan & Li (1997), method "s15odr8": order 8, s = 15, as printed (26 digits) in
/// Hairer–Lubich–Wanner, §V.3.2 (the same values as Suzuki & Umeno 1993 / McLachlan 1995, as
/// several public codes note). Checked: Σγ = 1 and Σγ³ = Σγ⁵ = Σγ⁷ = 0 to 1e−26, and the
/// measured order of the composed Strang splitting tends to 8 in 50-digit arithmetic (10.4,
/// 9.1, 8.5 over successive halvings) and is 8 in the tests.
#[allow(clippy::excessive_precision)]
pub const KAHAN_LI8: [f64; 15] = [
    0.741_670_364_350_612_953_448_227_80,  // γ₁ = γ₁₅
    -0.409_100_825_800_031_593_997_300_10, // γ₂ = γ₁₄
    0.190_754_710_296_238_379_953_876_26,  // γ₃ = γ₁₃
    -0.573_862_471_116_082_266_656_387_73, // γ₄ = γ₁₂
    0.299_064_181_303_655_923_844_463_54,  // γ₅ = γ₁₁
    0.334_624_918_245_298_183_784_957_98,  // γ₆ = γ₁₀
    0.315_293_092_396_766_596_632_056_66,  // γ₇ = γ₉
    -0.796_887_939_352_916_354_019_788_84, // γ₈
    0.315_293_092_396_766_596_632_056_66,
    0.334_624_918_245_298_183_784_957_98,
    0.299_064_181_303_655_923_844_463_54,
    -0.573_862_471_116_082_266_656_387_73,
    0.190_754_710_296_238_379_953_876_26,
    -0.409_100_825_800_031_593_997_300_10,
    0.741_670_364_350_612_953_448_227_80,
];

/// The composition coefficients γ₁..γ_s of the given order: 2 → [`STRANG`], 4 →
/// [`YOSHIDA4`], 6 → [`KAHAN_LI6`], 8 → [`KAHAN_LI8`].
///
/// # Errors
/// [`Error::InvalidParameter`] for any other order.
pub fn composition(order: usize) -> Result<&'static [f64]> {
    match order {
        2 => Ok(&STRANG),
        4 => Ok(&YOSHIDA4),
        6 => Ok(&KAHAN_LI6),
        8 => Ok(&KAHAN_LI8),
        _ => Err(Error::InvalidParameter(format!(
            "composition order {order}: 2, 4, 6 or 8 are available"
        ))),
    }
}

/// The distinct values of `taus` (exact equality, first occurrence order) and, for each entry,
/// its index among them.
pub(crate) fn distinct(taus: &[f64]) -> (Vec<f64>, Vec<usize>) {
    let mut values: Vec<f64> = Vec::new();
    let index = taus
        .iter()
        .map(|&t| match values.iter().position(|&v| v == t) {
            Some(i) => i,
            None => {
                values.push(t);
                values.len() - 1
            }
        })
        .collect();
    (values, index)
}

pub(crate) fn check_step_size(h: f64) -> Result<()> {
    if !(h.is_finite() && h > 0.0) {
        return Err(Error::InvalidStepSize(h));
    }
    Ok(())
}

#[inline]
pub(crate) fn check_state(y: &[f64], d: usize, what: &'static str) -> Result<()> {
    if y.len() != d {
        return Err(Error::DimensionMismatch {
            what,
            expected: d,
            found: y.len(),
        });
    }
    if y.iter().any(|v| !v.is_finite()) {
        return Err(Error::NonFinite(what));
    }
    Ok(())
}

/// `a` and `b` hold the same bits.
#[inline]
pub(crate) fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// `y += alpha · x`.
pub(crate) fn axpy(alpha: f64, x: &[f64], y: &mut [f64]) {
    y.iter_mut().zip(x).for_each(|(y, x)| *y += alpha * x);
}

#[inline]
fn all_finite(x: &[f64]) -> bool {
    x.iter().all(|v| v.is_finite())
}

fn one(i: usize) -> Range<usize> {
    i..i + 1
}

/// Kick–rotate–kick splitting of `y' = Ay + g(y)` with the exact linear flow, composed to
/// order 2, 4, 6 or 8 (see [`composition`]).
///
/// # The method
///
/// Base method (symmetric, order 2), with the kick `K_t(y) = y + t·g(y)`:
///
/// ```text
/// Φ_τ = K_{τ/2} ∘ e^{τA} ∘ K_{τ/2},     Ψ_h = Φ_{γ_s h} ∘ … ∘ Φ_{γ_1 h},
/// ```
///
/// computed with adjacent half-kicks merged: `y ← y + c_i h g(y)` before the rotation
/// `y ← e^{γ_{i+1} hA} y` (i = 0..s−1) and once after the last, `c_0 = γ₁/2`,
/// `c_i = (γ_i + γ_{i+1})/2`, `c_s = γ_s/2`.
///
/// **Requirement.** `K_t` is the exact flow of `y' = g(y)` only if `g'(y)g(y) = 0` (g is
/// constant along its own flow), e.g. the second-order form `y = (q, p)`, `g = (0, f(q))`
/// (Duffing, FPU in first-order form). Otherwise the method is still defined but loses its
/// order and symplecticity. The caller asserts this; it is not checked.
///
/// Under the same requirement g(K_t(y)) = g(y), so the last kick's g is the next step's first
/// (FSAL): a step costs **s evaluations of g** (1, 3, 9, 15 for orders 2, 4, 6, 8), the first
/// step (or one from a state other than the last result, compared bit for bit) one more.
///
/// The rotations come from one φ-bank `phi_bank(h, distinct γ_i, 0)` of the system's operator,
/// built in the constructor and in [`set_step_size`](Self::set_step_size); a step does not
/// allocate. For `y' = J∇H` with `H = ½yᵀMy + V(y)`, `A = JM`, `g = J∇V` both substeps are exact
/// Hamiltonian flows, so the method is symplectic: bounded energy error without drift. With
/// g = 0 it is the exact flow `e^{hA}`.
pub struct LinearFlowSplitting<S: System> {
    system: S,
    order: usize,
    gammas: &'static [f64],
    /// Bank index of each γᵢ.
    node: Vec<usize>,
    h: f64,
    bank: <S::Op as LinearOperator>::Bank,
    ws: <<S::Op as LinearOperator>::Bank as PhiBank>::Workspace,
    u: Vec<f64>,
    tmp: Vec<f64>,
    /// g at the current stage; after a successful step, g at its result (FSAL).
    gval: Vec<f64>,
    /// The last result, bit for bit, valid when `fsal`.
    last: Vec<f64>,
    fsal: bool,
    scratch: Vec<f64>,
}

impl<S: System> LinearFlowSplitting<S> {
    /// The splitting of `order` ∈ {2, 4, 6, 8} with step size `h`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for another order, [`Error::InvalidStepSize`], and whatever
    /// the operator's `phi_bank` reports.
    pub fn new(system: S, order: usize, h: f64) -> Result<Self> {
        let gammas = composition(order)?;
        check_step_size(h)?;
        ecr_runtime::system::check_system(&system)?;
        let (taus, node) = distinct(gammas);
        let bank = system.linear().phi_bank(h, &taus, 0)?;
        let ws = bank.workspace();
        let d = system.dim();
        Ok(LinearFlowSplitting {
            order,
            gammas,
            node,
            h,
            bank,
            ws,
            u: vec![0.0; d],
            tmp: vec![0.0; d],
            gval: vec![0.0; d],
            last: vec![0.0; d],
            fsal: false,
            scratch: vec![0.0; system.scratch_len()],
            system,
        })
    }

    /// The system.
    pub fn system(&self) -> &S {
        &self.system
    }

    /// The order (2, 4, 6 or 8).
    pub fn order(&self) -> usize {
        self.order
    }

    /// The step size.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// Changes the step size (rebuilds the φ-bank; the FSAL value stays valid).
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`] and whatever `phi_bank` reports; then nothing changed.
    pub fn set_step_size(&mut self, h: f64) -> Result<()> {
        check_step_size(h)?;
        if h != self.h {
            let (taus, _) = distinct(self.gammas);
            let bank = self.system.linear().phi_bank(h, &taus, 0)?;
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
        check_state(y, self.u.len(), "state y")?;
        let h = self.h;
        let mut g_evals = 0;
        let reuse = self.fsal && same_bits(y, &self.last);
        self.fsal = false;
        if !reuse {
            eval_g(&self.system, y, &mut self.gval, &mut self.scratch)?;
            g_evals += 1;
        }
        self.u.copy_from_slice(y);
        let s = self.gammas.len();
        let mut c = 0.5 * self.gammas[0];
        for i in 0..s {
            axpy(c * h, &self.gval, &mut self.u);
            self.bank.combine(
                one(self.node[i]),
                &self.u,
                &[],
                &[],
                &mut self.tmp,
                &mut self.ws,
            );
            std::mem::swap(&mut self.u, &mut self.tmp);
            eval_g(&self.system, &self.u, &mut self.gval, &mut self.scratch)?;
            g_evals += 1;
            c = 0.5 * (self.gammas[i] + self.gammas.get(i + 1).copied().unwrap_or(0.0));
        }
        axpy(c * h, &self.gval, &mut self.u);
        if !all_finite(&self.u) {
            return Err(Error::NonFinite("splitting step result"));
        }
        y.copy_from_slice(&self.u);
        self.last.copy_from_slice(&self.u);
        self.fsal = true;
        Ok(super::explicit_step(g_evals))
    }
}

fn eval_g<S: System>(system: &S, y: &[f64], out: &mut [f64], scratch: &mut [f64]) -> Result<()> {
    system.nonlinear(y, out, scratch);
    if !all_finite(out) {
        return Err(Error::NonFinite("g at a splitting stage"));
    }
    Ok(())
}

impl<S: System> Integrator for LinearFlowSplitting<S> {
    fn step_size(&self) -> f64 {
        self.h
    }
    fn set_step_size(&mut self, h: f64) -> Result<()> {
        LinearFlowSplitting::set_step_size(self, h)
    }
    fn step_state(&mut self, y: &mut [f64]) -> Result<StepReport> {
        self.step(y)
    }
    fn energy_of(&self, y: &[f64]) -> Option<f64> {
        self.system.energy(y)
    }
}

/// Ω as applied by [`StormerVerlet`] (assembled once from [`Omega::apply`](ecr_runtime::second_order::Omega::apply)).
enum Stiffness {
    Zero,
    Diagonal(Vec<f64>),
    Dense(DMatrix<f64>),
}

impl Stiffness {
    fn new<S: SecondOrderSystem>(system: &S) -> Result<Self> {
        let omega = system.omega();
        let d = omega.dim();
        let mut m = DMatrix::zeros(d, d);
        let mut e = vec![0.0; d];
        let mut col = vec![0.0; d];
        for j in 0..d {
            e[j] = 1.0;
            omega.apply(&e, &mut col);
            e[j] = 0.0;
            m.column_mut(j).copy_from_slice(&col);
        }
        if !all_finite(m.as_slice()) {
            return Err(Error::NonFinite("Ω"));
        }
        let diagonal = (0..d).all(|j| (0..d).all(|i| i == j || m[(i, j)] == 0.0));
        Ok(if m.iter().all(|v| *v == 0.0) {
            Stiffness::Zero
        } else if diagonal {
            Stiffness::Diagonal(m.diagonal().iter().copied().collect())
        } else {
            Stiffness::Dense(m)
        })
    }

    /// `out −= Ω q`.
    fn subtract(&self, q: &[f64], out: &mut [f64]) {
        match self {
            Stiffness::Zero => {}
            Stiffness::Diagonal(l) => out
                .iter_mut()
                .zip(l)
                .zip(q)
                .for_each(|((o, l), q)| *o -= l * q),
            Stiffness::Dense(m) => {
                let d = out.len();
                for (col, &qj) in m.as_slice().chunks_exact(d).zip(q) {
                    out.iter_mut().zip(col).for_each(|(o, mij)| *o -= mij * qj);
                }
            }
        }
    }
}

/// The (q, p) state of a composed kick–substep–kick method and its FSAL force: what
/// [`StormerVerlet`] and [`RotationSplitting`] share. Only the force and the substep between
/// the half-kicks differ (a drift, or a rotation of each mode).
struct KickState {
    q: Vec<f64>,
    p: Vec<f64>,
    /// The force at the current positions; after a successful step, at its result (FSAL).
    force: Vec<f64>,
    /// The last result (q, p), bit for bit, valid when `fsal`.
    last: Vec<f64>,
    fsal: bool,
}

impl KickState {
    fn new(d: usize) -> Self {
        KickState {
            q: vec![0.0; d],
            p: vec![0.0; d],
            force: vec![0.0; d],
            last: vec![0.0; 2 * d],
            fsal: false,
        }
    }

    /// One step of `y = (q, p)` in place: `Φ_{γ_s h} ∘ … ∘ Φ_{γ_1 h}` with
    /// `Φ_τ = kick(τ/2) ∘ substep(τ) ∘ kick(τ/2)`, adjacent half-kicks merged, the force
    /// reused from the last step when y is its result. `force(q, out)` writes the force (and
    /// fails on a non-finite one); `substep(i, τ, q, p)` is the i-th composition node's middle
    /// flow. Does not allocate.
    fn step(
        &mut self,
        y: &mut [f64],
        gammas: &[f64],
        h: f64,
        what: &'static str,
        mut force: impl FnMut(&[f64], &mut [f64]) -> Result<()>,
        mut substep: impl FnMut(usize, f64, &mut [f64], &mut [f64]),
    ) -> Result<StepReport> {
        let d = self.q.len();
        check_state(y, 2 * d, "state (q, p)")?;
        let mut g_evals = 0;
        let reuse = self.fsal && same_bits(y, &self.last);
        self.fsal = false;
        self.q.copy_from_slice(&y[..d]);
        self.p.copy_from_slice(&y[d..]);
        if !reuse {
            force(&self.q, &mut self.force)?;
            g_evals += 1;
        }
        let mut c = 0.5 * gammas[0];
        for (i, &g) in gammas.iter().enumerate() {
            axpy(c * h, &self.force, &mut self.p);
            substep(i, g * h, &mut self.q, &mut self.p);
            force(&self.q, &mut self.force)?;
            g_evals += 1;
            c = 0.5 * (g + gammas.get(i + 1).copied().unwrap_or(0.0));
        }
        axpy(c * h, &self.force, &mut self.p);
        if !all_finite(&self.q) || !all_finite(&self.p) {
            return Err(Error::NonFinite(what));
        }
        y[..d].copy_from_slice(&self.q);
        y[d..].copy_from_slice(&self.p);
        self.last.copy_from_slice(y);
        self.fsal = true;
        Ok(super::explicit_step(g_evals))
    }

    /// [`KickState::step`] for a compile-time dimension `D` and a force −∇U: the kicks
    /// subtract `(c h)·∇U`, which rounds as adding `(c h)·(−∇U)` (the results are bit for bit
    /// those of the slice form), with q, p and ∇U in local arrays that the compiler keeps in
    /// registers for small D, and one finiteness check at the end of the step (a non-finite
    /// ∇U at a stage makes the result non-finite: the kick coefficients are never 0). For
    /// d = 1 the slice form took 2.2× the time of the same method written in C with scalars
    /// (its loads and stores, and a check per stage); this is what a user of a one- or
    /// few-mode oscillator writes.
    fn step_fixed<const D: usize>(
        &mut self,
        y: &mut [f64],
        (gammas, h, what): (&[f64], f64, &'static str),
        mut grad: impl FnMut(&[f64], &mut [f64]),
        mut substep: impl FnMut(usize, &mut [f64; D], &mut [f64; D]),
    ) -> Result<StepReport> {
        debug_assert_eq!(self.q.len(), D);
        check_state(y, 2 * D, "state (q, p)")?;
        let mut g_evals = 0;
        let reuse = self.fsal && same_bits(y, &self.last);
        self.fsal = false;
        let mut q: [f64; D] = y[..D].try_into().expect("length checked");
        let mut p: [f64; D] = y[D..].try_into().expect("length checked");
        let mut f = [0.0; D];
        // −∇U of the last result (FSAL), stored negated as the slice form stores it.
        if reuse {
            f.iter_mut().zip(&self.force).for_each(|(f, m)| *f = -m);
        } else {
            grad(&q, &mut f);
            g_evals += 1;
        }
        let mut c = 0.5 * gammas[0];
        for (i, &g) in gammas.iter().enumerate() {
            let ch = c * h;
            p.iter_mut().zip(&f).for_each(|(p, f)| *p -= ch * f);
            substep(i, &mut q, &mut p);
            grad(&q, &mut f);
            g_evals += 1;
            c = 0.5 * (g + gammas.get(i + 1).copied().unwrap_or(0.0));
        }
        let ch = c * h;
        p.iter_mut().zip(&f).for_each(|(p, f)| *p -= ch * f);
        if !q.iter().chain(&p).chain(&f).all(|v| v.is_finite()) {
            return Err(Error::NonFinite(what));
        }
        y[..D].copy_from_slice(&q);
        y[D..].copy_from_slice(&p);
        self.q.copy_from_slice(&q);
        self.p.copy_from_slice(&p);
        self.force.iter_mut().zip(&f).for_each(|(m, f)| *m = -f);
        self.last.copy_from_slice(y);
        self.fsal = true;
        Ok(super::explicit_step(g_evals))
    }
}

/// Velocity Verlet (Störmer–Verlet, kick–drift–kick) for `q'' = −Ωq − ∇U(q)`, composed to
/// order 2, 4, 6 or 8 (see [`composition`]); state `y = (q, p)` flat, as [`integrate`]
/// passes it.
///
/// ```text
/// F(q) = −Ωq − ∇U(q)
/// Φ_τ:  p ← p + (τ/2) F(q);   q ← q + τ p;   p ← p + (τ/2) F(q)
/// Ψ_h = Φ_{γ_s h} ∘ … ∘ Φ_{γ_1 h}    (adjacent half-kicks merged, as in LinearFlowSplitting)
/// ```
///
/// The linear force is part of the kick (no exact linear flow), so the step size is limited by
/// the stability bound `h·√λ_max(Ω) < 2` of Verlet (smaller for the compositions).
/// FSAL: a step costs **s evaluations of ∇U** (1, 3, 9, 15), the first step one more. Ω is
/// applied as assembled once at construction (zero, diagonal, or a dense d × d matrix); a step
/// does not allocate. Symplectic: bounded energy error without drift.
///
/// [`integrate`]: ecr_runtime::integrate::integrate
pub struct StormerVerlet<S: SecondOrderSystem> {
    system: S,
    order: usize,
    gammas: &'static [f64],
    h: f64,
    stiffness: Stiffness,
    /// (q, p) and F = −Ωq − ∇U(q) (FSAL).
    state: KickState,
}

impl<S: SecondOrderSystem> StormerVerlet<S> {
    /// The composed Verlet method of `order` ∈ {2, 4, 6, 8} with step size `h`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for another order, [`Error::InvalidStepSize`],
    /// [`Error::NonFinite`] if Ω has non-finite entries.
    pub fn new(system: S, order: usize, h: f64) -> Result<Self> {
        let gammas = composition(order)?;
        check_step_size(h)?;
        let stiffness = Stiffness::new(&system)?;
        let d = system.omega().dim();
        Ok(StormerVerlet {
            system,
            order,
            gammas,
            h,
            stiffness,
            state: KickState::new(d),
        })
    }

    /// The system.
    pub fn system(&self) -> &S {
        &self.system
    }

    /// The order (2, 4, 6 or 8).
    pub fn order(&self) -> usize {
        self.order
    }

    /// The step size.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// Changes the step size (nothing to rebuild).
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`].
    pub fn set_step_size(&mut self, h: f64) -> Result<()> {
        check_step_size(h)?;
        self.h = h;
        Ok(())
    }

    /// Advances `y = (q, p)` (length 2d) by one step in place. Does not allocate.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] for a wrong length, [`Error::NonFinite`] if y, ∇U at a
    /// stage or the result is NaN/infinite. On error, y is unchanged.
    pub fn step(&mut self, y: &mut [f64]) -> Result<StepReport> {
        let (system, stiffness) = (&self.system, &self.stiffness);
        // F = −Ωq − ∇U(q).
        let force = |q: &[f64], f: &mut [f64]| {
            system.force(q, f);
            if !all_finite(f) {
                return Err(Error::NonFinite("∇U at a Verlet stage"));
            }
            f.iter_mut().for_each(|v| *v = -*v);
            stiffness.subtract(q, f);
            Ok(())
        };
        let drift = |_: usize, tau: f64, q: &mut [f64], p: &mut [f64]| axpy(tau, p, q);
        self.state
            .step(y, self.gammas, self.h, "Verlet step result", force, drift)
    }
}

impl<S: SecondOrderSystem> Integrator for StormerVerlet<S> {
    fn step_size(&self) -> f64 {
        self.h
    }
    fn set_step_size(&mut self, h: f64) -> Result<()> {
        StormerVerlet::set_step_size(self, h)
    }
    fn step_state(&mut self, y: &mut [f64]) -> Result<StepReport> {
        self.step(y)
    }
    fn energy_of(&self, y: &[f64]) -> Option<f64> {
        let d = y.len() / 2;
        self.system.energy(&y[..d], &y[d..])
    }
}

/// Kick–rotate–kick for `q'' + Ωq = −∇U(q)` with Ω **diagonal** (or scalar, or zero), the
/// rotation of each mode written out with its own cosine and sine, as users of a
/// second-order oscillatory system write it; composed to order 2, 4, 6 or 8 (see
/// [`composition`]); state `y = (q, p)` flat, as [`integrate`] passes it.
///
/// ```text
/// Φ_τ:  p ← p − (τ/2)∇U(q);
///       (qᵢ, pᵢ) ← (cos θᵢ qᵢ + sin θᵢ/ωᵢ pᵢ, −ωᵢ sin θᵢ qᵢ + cos θᵢ pᵢ),  θᵢ = τωᵢ, ωᵢ = √Ωᵢᵢ
///                  (as (qᵢ, pᵢ) + the increment, with cos θᵢ − 1 = −2 sin²(θᵢ/2));
///       p ← p − (τ/2)∇U(q)
/// ```
///
/// The same method as [`LinearFlowSplitting`] on the first-order form; the rotations come
/// from `f64::sin_cos` of each θᵢ (computed once per step size and composition node) instead
/// of the operator's φ-bank. FSAL: a step costs **s evaluations of ∇U** (1, 3, 9, 15), the
/// first step one more. A step does not allocate.
///
/// [`integrate`]: ecr_runtime::integrate::integrate
pub struct RotationSplitting<S: SecondOrderSystem> {
    system: S,
    order: usize,
    gammas: &'static [f64],
    /// For each composition node, the distinct-γ table index.
    node: Vec<usize>,
    h: f64,
    /// √Ωᵢᵢ.
    omega: Vec<f64>,
    /// Per composition node and mode: (cos θ − 1, sin θ/ω, −ω sin θ), θ = γhω (ω = 0:
    /// (0, γh, 0)), applied as the identity plus the increment (q, p) ↦ (q, p) +
    /// [[cos θ − 1, sin θ/ω], [−ω sin θ, cos θ − 1]] (q, p). Evaluated once per distinct γ
    /// (`node`), stored per node (the step reads it in order, without the indirection).
    rot: Vec<[f64; 3]>,
    /// (q, p) and −∇U(q) (FSAL).
    state: KickState,
}

impl<S: SecondOrderSystem> RotationSplitting<S> {
    /// The composed kick–rotate–kick method of `order` ∈ {2, 4, 6, 8} with step size `h`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for another order or a non-diagonal Ω (use
    /// [`LinearFlowSplitting`] on the first-order form), [`Error::InvalidStepSize`],
    /// [`Error::NonFinite`] if Ω has non-finite entries.
    pub fn new(system: S, order: usize, h: f64) -> Result<Self> {
        let gammas = composition(order)?;
        check_step_size(h)?;
        let d = system.omega().dim();
        let omega = match Stiffness::new(&system)? {
            Stiffness::Zero => vec![0.0; d],
            Stiffness::Diagonal(l) => l.iter().map(|l| l.max(0.0).sqrt()).collect(),
            Stiffness::Dense(_) => {
                return Err(Error::InvalidParameter(
                    "RotationSplitting needs a diagonal Ω; use LinearFlowSplitting on the \
                     first-order form"
                        .into(),
                ));
            }
        };
        let (_, node) = distinct(gammas);
        let mut m = RotationSplitting {
            system,
            order,
            gammas,
            node,
            h,
            omega,
            rot: Vec::new(),
            state: KickState::new(d),
        };
        m.rot = m.rotations(h);
        Ok(m)
    }

    fn rotations(&self, h: f64) -> Vec<[f64; 3]> {
        let (taus, _) = distinct(self.gammas);
        let table: Vec<[f64; 3]> = taus
            .iter()
            .flat_map(|&g| {
                self.omega.iter().map(move |&w| {
                    let tau = g * h;
                    if w == 0.0 {
                        [0.0, tau, 0.0]
                    } else {
                        // cos θ − 1 = −2 sin²(θ/2): no cancellation, and the rotation applied
                        // as the identity plus this increment keeps its determinant 1 to far
                        // below an ulp of the state.
                        let (sin, _) = (tau * w).sin_cos();
                        let half = (0.5 * tau * w).sin();
                        [-2.0 * half * half, sin / w, -w * sin]
                    }
                })
            })
            .collect();
        let d = self.omega.len();
        self.node
            .iter()
            .flat_map(|&u| table[u * d..(u + 1) * d].iter().copied())
            .collect()
    }

    /// The system.
    pub fn system(&self) -> &S {
        &self.system
    }

    /// The order (2, 4, 6 or 8).
    pub fn order(&self) -> usize {
        self.order
    }

    /// The step size.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// Changes the step size (recomputes the rotations).
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`].
    pub fn set_step_size(&mut self, h: f64) -> Result<()> {
        check_step_size(h)?;
        if h != self.h {
            self.rot = self.rotations(h);
            self.h = h;
        }
        Ok(())
    }

    /// Advances `y = (q, p)` (length 2d) by one step in place. Does not allocate.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] for a wrong length, [`Error::NonFinite`] if y, ∇U at a
    /// stage or the result is NaN/infinite. On error, y is unchanged.
    pub fn step(&mut self, y: &mut [f64]) -> Result<StepReport> {
        let system = &self.system;
        // −∇U(q).
        let force = |q: &[f64], f: &mut [f64]| {
            system.force(q, f);
            if !all_finite(f) {
                return Err(Error::NonFinite("∇U at a splitting stage"));
            }
            f.iter_mut().for_each(|v| *v = -*v);
            Ok(())
        };
        let rot = &self.rot;
        let d = self.state.q.len();
        // Rotate each mode by its table entry for the i-th node.
        let rotate = |i: usize, q: &mut [f64], p: &mut [f64]| {
            let r = &rot[i * d..(i + 1) * d];
            for ((q, p), r) in q.iter_mut().zip(p.iter_mut()).zip(r) {
                let (q0, p0) = (*q, *p);
                *q = q0 + (r[0] * q0 + r[1] * p0);
                *p = p0 + (r[2] * q0 + r[0] * p0);
            }
        };
        let method = (self.gammas, self.h, "splitting step result");
        // Few modes: the fixed-size form (bit for bit the same step, in registers).
        macro_rules! fixed {
            ($d:literal) => {
                self.state.step_fixed::<$d>(
                    y,
                    method,
                    |q, f| system.force(q, f),
                    |i, q, p| rotate(i, q, p),
                )
            };
        }
        match d {
            1 => fixed!(1),
            2 => fixed!(2),
            3 => fixed!(3),
            4 => fixed!(4),
            _ => {
                let (gammas, h, what) = method;
                self.state
                    .step(y, gammas, h, what, force, |i, _, q, p| rotate(i, q, p))
            }
        }
    }
}

impl<S: SecondOrderSystem> Integrator for RotationSplitting<S> {
    fn step_size(&self) -> f64 {
        self.h
    }
    fn set_step_size(&mut self, h: f64) -> Result<()> {
        RotationSplitting::set_step_size(self, h)
    }
    fn step_state(&mut self, y: &mut [f64]) -> Result<StepReport> {
        self.step(y)
    }
    fn energy_of(&self, y: &[f64]) -> Option<f64> {
        let d = y.len() / 2;
        self.system.energy(&y[..d], &y[d..])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compositions_sum_to_one_and_are_palindromic() {
        for order in [2, 4, 6, 8] {
            let g = composition(order).unwrap();
            assert_eq!(g.len(), [1, 3, 9, 15][order / 2 - 1]);
            let sum: f64 = g.iter().sum();
            // s rounded terms of magnitude < 2: a few ulp of 1.
            assert!(
                (sum - 1.0).abs() <= 8.0 * f64::EPSILON,
                "order {order}: {sum}"
            );
            for (a, b) in g.iter().zip(g.iter().rev()) {
                assert_eq!(a.to_bits(), b.to_bits(), "order {order} not symmetric");
            }
            // Symmetric compositions of order ≥ 4 need Σγ³ = 0 (HLW V.3.2); rounding only.
            if order >= 4 {
                let cubes: f64 = g.iter().map(|x| x * x * x).sum();
                assert!(cubes.abs() <= 1e-14, "order {order}: Σγ³ = {cubes:e}");
            }
        }
        assert!(matches!(composition(3), Err(Error::InvalidParameter(_))));
    }

    #[test]
    fn distinct_maps_every_entry() {
        let (v, i) = distinct(&KAHAN_LI8);
        assert_eq!(v.len(), 8);
        for (k, &g) in KAHAN_LI8.iter().enumerate() {
            assert_eq!(v[i[k]], g);
        }
    }
}
