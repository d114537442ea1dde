//! Split-step Fourier methods for NLS-type systems (what NLS users pick:
//! `docs/architecture.md#baselines`).
//!
//! For `ψ = p + iq ∈ ℂⁿ`, stored as `y = (p, q) ∈ ℝ²ⁿ`,
//!
//! ```text
//! ψ' = i·Cψ + i·ρ(|ψ|²)·ψ        (componentwise ρ, C real symmetric)
//! ```
//!
//! splits into two exactly solvable parts:
//!
//! * linear `L_t`: `ψ ← e^{itC}ψ`, i.e. `y ← e^{tA}y` with `A = [[0, −C], [C, 0]]` (a
//!   [`SkewPair`]; for the NLS C = D₂ is circulant and the flow costs two FFTs). Taken from one
//!   φ-bank `phi_bank(h, distinct b_j, 0)` of the operator, built once per step size.
//! * nonlinear `N_t`: `ψ_j ← ψ_j·e^{itρ(|ψ_j|²)}` — `|ψ_j|` is constant along `ψ' = iρψ`, so
//!   this is its exact flow, O(n) with one `sin_cos` per point.
//!
//! For the cubic NLS of the paper ([`Nls`](crate::problems::Nls)), `ρ(u) = 2u`: `g = iρψ` is
//! `(−2(p² + q²)q, 2(p² + q²)p)`, exactly [`Nls::nonlinear`](crate::problems::Nls::nonlinear).
//!
//! A step is `N_{a_0 h} L_{b_1 h} N_{a_1 h} … L_{b_m h} N_{a_m h}` with `a_0 = a_m`
//! (palindromic, so the method is symmetric):
//!
//! | order | scheme | m (linear substeps = FFT pairs) |
//! |---|---|---|
//! | 2 | Strang: a = (½, ½), b = (1) | 1 |
//! | 4 | Blanes–Moan PRK₆⁴ "S6" (J. Comput. Appl. Math. 142 (2002) 313–330) | 6 |
//! | 6 | Kahan–Li s9odr6a composition of Strang ([`KAHAN_LI6`]) | 9 |
//! | 8 | Kahan–Li s15odr8 composition of Strang ([`KAHAN_LI8`]) | 15 |
//!
//! **Which flow is outermost.** The nonlinear one: it is O(n) against O(n log n) for the
//! linear flow, so a step has m linear substeps (not m + 1), and the outer nonlinear substeps
//! merge across steps: the last substep's phase factors `e^{i a_m h ρ}` (of the same |ψ|, which
//! the nonlinear flow keeps) are exactly the next step's first (FSAL), so a step computes
//! **m** fields ρ(|ψ|²) and `sin_cos` sets (the first step, or one from a state other than the
//! last result, one more). The reported `g_evals` counts these evaluations of the nonlinearity:
//! 1, 6, 9, 15 per step for orders 2, 4, 6, 8.
//!
//! Both substeps are unitary, so the mass `Σ|ψ_j|²` is conserved up to round-off in every step.
//! The composition with negative coefficients (orders ≥ 4) runs the linear flow backwards in
//! time, which is exact here (the flow is unitary).

use crate::problems::NlsSystem;
use ecr_runtime::integrate::Integrator;
use ecr_runtime::operator::{Circulant, LinearOperator, PhiBank, SkewPair};
use ecr_runtime::stepper::StepReport;
use ecr_runtime::system::System;
use ecr_runtime::{Error, Result};

use super::splitting::{KAHAN_LI6, KAHAN_LI8, check_state, check_step_size, distinct, same_bits};

/// Blanes & Moan (2002), PRK₆⁴ "S6": the a-coefficients of the outer flow (here the nonlinear
/// one) a₁, a₂, a₃ as printed (15 digits; a₄ = 1 − 2(a₁ + a₂ + a₃)).
const BM4_A: [f64; 3] = [0.0792036964311957, 0.353172906049774, -0.0420650803577195];
/// Blanes & Moan (2002), PRK₆⁴: b₁, b₂ as printed (b₃ = ½ − (b₁ + b₂)).
const BM4_B: [f64; 2] = [0.209515106613362, -0.143851773179818];

/// (a, b) of the scheme of `order`: nonlinear coefficients a_0..a_m, linear b_1..b_m.
fn scheme(order: usize) -> Result<(Vec<f64>, Vec<f64>)> {
    let from_composition = |g: &[f64]| {
        let mut a = Vec::with_capacity(g.len() + 1);
        a.push(0.5 * g[0]);
        for w in g.windows(2) {
            a.push(0.5 * (w[0] + w[1]));
        }
        a.push(0.5 * g[g.len() - 1]);
        (a, g.to_vec())
    };
    match order {
        2 => Ok((vec![0.5, 0.5], vec![1.0])),
        4 => {
            let [a1, a2, a3] = BM4_A;
            let a4 = 1.0 - 2.0 * (a1 + a2 + a3);
            let [b1, b2] = BM4_B;
            let b3 = 0.5 - (b1 + b2);
            Ok((
                vec![a1, a2, a3, a4, a3, a2, a1],
                vec![b1, b2, b3, b3, b2, b1],
            ))
        }
        6 => Ok(from_composition(&KAHAN_LI6)),
        8 => Ok(from_composition(&KAHAN_LI8)),
        _ => Err(Error::InvalidParameter(format!(
            "split-step order {order}: 2, 4, 6 or 8 are available"
        ))),
    }
}

/// The energy of a split-step method's state, if known.
type EnergyFn = Box<dyn Fn(&[f64]) -> f64 + Send + Sync>;

/// Split-step Fourier method for `ψ' = i·Cψ + i·ρ(|ψ|²)ψ`, order 2, 4, 6 or 8; see the
/// [module documentation](self) for the scheme, the substep order and the cost.
///
/// `Op` is the linear part on `y = (Re ψ, Im ψ)`, e.g. `SkewPair<Circulant>` (any
/// [`LinearOperator`] of even dimension whose flow is `ψ ↦ e^{itC}ψ`; the caller asserts that
/// structure). `R` is ρ, applied to `|ψ_j|²`.
pub struct SplitStep<Op: LinearOperator, R> {
    op: Op,
    rho: R,
    energy: Option<EnergyFn>,
    order: usize,
    h: f64,
    /// Nonlinear coefficients a_0..a_m.
    a: Vec<f64>,
    /// Linear coefficients b_1..b_m and their bank indices.
    b: Vec<f64>,
    node: Vec<usize>,
    bank: Op::Bank,
    ws: <Op::Bank as PhiBank>::Workspace,
    u: Vec<f64>,
    tmp: Vec<f64>,
    /// cos, sin of the last nonlinear substep's phases (FSAL).
    cos: Vec<f64>,
    sin: Vec<f64>,
    last: Vec<f64>,
    fsal: bool,
}

impl<Op: LinearOperator, R: Fn(f64) -> f64> SplitStep<Op, R> {
    /// The split-step method of `order` ∈ {2, 4, 6, 8} with step size `h` for the linear part
    /// `op` (dimension 2n, on `(Re ψ, Im ψ)`) and the nonlinearity ρ (applied to `|ψ_j|²`).
    /// No energy is known (add one with [`with_energy`](Self::with_energy)).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for another order or an odd dimension,
    /// [`Error::InvalidStepSize`], and whatever `op.phi_bank` reports.
    pub fn new(op: Op, rho: R, order: usize, h: f64) -> Result<Self> {
        let (a, b) = scheme(order)?;
        check_step_size(h)?;
        let dim = op.dim();
        if dim % 2 != 0 {
            return Err(Error::InvalidParameter(format!(
                "split-step: the state (Re ψ, Im ψ) needs an even dimension, not {dim}"
            )));
        }
        let (taus, node) = distinct(&b);
        let bank = op.phi_bank(h, &taus, 0)?;
        let ws = bank.workspace();
        let n = dim / 2;
        Ok(SplitStep {
            op,
            rho,
            energy: None,
            order,
            h,
            a,
            b,
            node,
            bank,
            ws,
            u: vec![0.0; dim],
            tmp: vec![0.0; dim],
            cos: vec![0.0; n],
            sin: vec![0.0; n],
            last: vec![0.0; dim],
            fsal: false,
        })
    }

    /// Reports `energy(y)` as the energy of a state (for [`Integrator::energy_of`]).
    pub fn with_energy(mut self, energy: impl Fn(&[f64]) -> f64 + Send + Sync + 'static) -> Self {
        self.energy = Some(Box::new(energy));
        self
    }

    /// The linear part.
    pub fn operator(&self) -> &Op {
        &self.op
    }

    /// The order (2, 4, 6 or 8).
    pub fn order(&self) -> usize {
        self.order
    }

    /// The step size.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// Changes the step size (rebuilds the φ-bank; the FSAL phases are dropped).
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`] and whatever `phi_bank` reports; then nothing changed.
    pub fn set_step_size(&mut self, h: f64) -> Result<()> {
        check_step_size(h)?;
        if h != self.h {
            let (taus, _) = distinct(&self.b);
            let bank = self.op.phi_bank(h, &taus, 0)?;
            self.ws = bank.workspace();
            self.bank = bank;
            self.h = h;
            self.fsal = false;
        }
        Ok(())
    }

    /// `u ← N_t u` with `t = coef·h`; the phases' cos and sin are left in `self.cos/sin`.
    fn nonlinear(&mut self, t: f64) -> Result<()> {
        let n = self.cos.len();
        let (p, q) = self.u.split_at_mut(n);
        for (((p, q), c), s) in p
            .iter_mut()
            .zip(q.iter_mut())
            .zip(self.cos.iter_mut())
            .zip(self.sin.iter_mut())
        {
            let theta = t * (self.rho)(*p * *p + *q * *q);
            (*s, *c) = theta.sin_cos();
            let (pp, qq) = (*p, *q);
            *p = pp * *c - qq * *s;
            *q = pp * *s + qq * *c;
        }
        if !self.u.iter().all(|v| v.is_finite()) {
            return Err(Error::NonFinite("ρ(|ψ|²) in a nonlinear substep"));
        }
        Ok(())
    }

    /// `u ← e^{iθ}u` with the stored phases.
    fn rotate_stored(&mut self) {
        let n = self.cos.len();
        let (p, q) = self.u.split_at_mut(n);
        for (((p, q), c), s) in p.iter_mut().zip(q.iter_mut()).zip(&self.cos).zip(&self.sin) {
            let (pp, qq) = (*p, *q);
            *p = pp * c - qq * s;
            *q = pp * s + qq * c;
        }
    }

    /// Advances `y = (Re ψ, Im ψ)` by one step in place. Does not allocate.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] for a wrong length, [`Error::NonFinite`] if y, ρ or the
    /// result is NaN/infinite. On error, y is unchanged.
    pub fn step(&mut self, y: &mut [f64]) -> Result<StepReport> {
        check_state(y, self.u.len(), "state (Re ψ, Im ψ)")?;
        let h = self.h;
        let reuse = self.fsal && same_bits(y, &self.last);
        self.fsal = false;
        self.u.copy_from_slice(y);
        let mut g_evals = 0;
        if reuse {
            self.rotate_stored();
        } else {
            self.nonlinear(self.a[0] * h)?;
            g_evals += 1;
        }
        for j in 0..self.b.len() {
            let i = self.node[j];
            self.bank
                .combine(i..i + 1, &self.u, &[], &[], &mut self.tmp, &mut self.ws);
            std::mem::swap(&mut self.u, &mut self.tmp);
            self.nonlinear(self.a[j + 1] * h)?;
            g_evals += 1;
        }
        if !self.u.iter().all(|v| v.is_finite()) {
            return Err(Error::NonFinite("split-step result"));
        }
        y.copy_from_slice(&self.u);
        self.last.copy_from_slice(&self.u);
        self.fsal = true;
        Ok(super::explicit_step(g_evals))
    }
}

impl SplitStep<SkewPair<Circulant>, fn(f64) -> f64> {
    /// The split-step Fourier method for the paper's cubic NLS ([`Nls::system`]): the linear
    /// part is the system's `SkewPair` of the circulant D₂ (FFT), ρ(u) = 2u, and the energy is
    /// the NLS Hamiltonian.
    ///
    /// # Errors
    /// As [`SplitStep::new`].
    ///
    /// [`Nls::system`]: crate::problems::Nls::system
    pub fn nls(system: NlsSystem, order: usize, h: f64) -> Result<Self> {
        fn rho(u: f64) -> f64 {
            2.0 * u
        }
        let op = system.linear().clone();
        let method = SplitStep::new(op, rho as fn(f64) -> f64, order, h)?;
        Ok(method.with_energy(move |y| system.problem().energy(y)))
    }
}

impl<Op: LinearOperator, R: Fn(f64) -> f64> Integrator for SplitStep<Op, R> {
    fn step_size(&self) -> f64 {
        self.h
    }
    fn set_step_size(&mut self, h: f64) -> Result<()> {
        SplitStep::set_step_size(self, h)
    }
    fn step_state(&mut self, y: &mut [f64]) -> Result<StepReport> {
        self.step(y)
    }
    fn energy_of(&self, y: &[f64]) -> Option<f64> {
        self.energy.as_ref().map(|e| e(y))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schemes_are_consistent_and_palindromic() {
        for order in [2, 4, 6, 8] {
            let (a, b) = scheme(order).unwrap();
            assert_eq!(a.len(), b.len() + 1);
            let (sa, sb): (f64, f64) = (a.iter().sum(), b.iter().sum());
            // Consistency Σa = Σb = 1, up to the rounding of ≤ 16 terms.
            assert!(
                (sa - 1.0).abs() <= 1e-15 && (sb - 1.0).abs() <= 1e-15,
                "{order}"
            );
            for (x, y) in a.iter().zip(a.iter().rev()) {
                assert!((x - y).abs() <= 1e-16, "{order}: a not palindromic");
            }
            for (x, y) in b.iter().zip(b.iter().rev()) {
                assert!((x - y).abs() <= 1e-16, "{order}: b not palindromic");
            }
        }
        assert!(scheme(5).is_err());
    }
}
