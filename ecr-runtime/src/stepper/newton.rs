//! Newton's method for the stage equations ([`StageSolver::Newton`],
//! [`StageSolver::SimplifiedNewton`]): the Newton matrix `I − ∂Φ/∂Y` from the stage matrices
//! and Jacobians of g, its factorisation, and the update of a sweep.

use nalgebra::{DMatrix, DMatrixView, DVector};

use super::buffers::Buffers;
use super::context::StepContext;
use super::fused::stage_matrices;
use super::kernel::Kernel;
use super::settings::StageSolver;
use crate::error::{Error, Result};
use crate::system::System;

/// Contraction estimates θ at or above this make [`StageSolver::Newton`] refresh its Jacobian
/// at the current stages (and redo the iteration's update with it). Below it the simplified
/// iteration is kept: at θ = 0.5 it needs about 50 iterations for 15 digits, and one LU
/// factorisation of the n × n Newton matrix (n = s·d, 2n³/3 operations) costs as many
/// operations as n/3 of its solves (2n² each): 43 at s = 2, d = 64. At θ ≥ 1 it diverges.
pub const NEWTON_REFRESH_THETA: f64 = 0.5;

/// The most numbers the Newton iteration holds at once: the stage matrices and the Newton
/// matrix (s²d² each), the Jacobian and one d × d block product, and at a refresh the
/// right-hand side and copies of the stages and of g there (s·d each); `None` on overflow.
pub(super) fn newton_entries(s: usize, d: usize) -> Option<usize> {
    let dd = d.checked_mul(d)?;
    s.checked_mul(s)?
        .checked_mul(dd)?
        .checked_add(dd)?
        .checked_mul(2)?
        .checked_add(s.checked_mul(d)?.checked_mul(3)?)
}

/// What the Newton iteration keeps: the stage matrices for the step size and scratch for the
/// Jacobians.
pub(super) struct NewtonState {
    /// The stage matrices `∂Φ_i/∂g_k` ([`stage_matrices`]).
    q: Vec<f64>,
    jac: JacobianScratch,
}

/// A Jacobian of g and the d-vectors that forward differences need.
struct JacobianScratch {
    jac: DMatrix<f64>,
    /// d-vectors: a point, g there, g at the base point.
    yp: Vec<f64>,
    gp: Vec<f64>,
    g0: Vec<f64>,
}

impl NewtonState {
    /// With the stage matrices `q` of the step size, for dimension d.
    fn new(q: Vec<f64>, d: usize) -> Self {
        NewtonState {
            q,
            jac: JacobianScratch {
                jac: DMatrix::zeros(d, d),
                yp: vec![0.0; d],
                gp: vec![0.0; d],
                g0: vec![0.0; d],
            },
        }
    }
}

/// The LU factorisation of the Newton matrix.
type NewtonLu = nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>;

/// The Jacobian of g at `y` into `js.jac`: the system's, or forward differences from g(y)
/// (`gy`, or evaluated here if `None`). Returns the evaluations of g it took.
///
/// # Errors
/// [`Error::DimensionMismatch`] if the system's Jacobian is not d × d, [`Error::NonFinite`]
/// (naming `at`) if it has a non-finite entry.
fn jacobian_into<S: System>(
    system: &S,
    y: &[f64],
    gy: Option<&[f64]>,
    js: &mut JacobianScratch,
    scratch: &mut [f64],
    at: &'static str,
) -> Result<usize> {
    let d = y.len();
    let mut evals = 0;
    if !system.jacobian(y, &mut js.jac, scratch) {
        let g0 = match gy {
            Some(gy) => gy,
            None => {
                system.nonlinear(y, &mut js.g0, scratch);
                evals += 1;
                &js.g0
            }
        };
        evals += d;
        for l in 0..d {
            js.yp.copy_from_slice(y);
            let step = f64::EPSILON.sqrt() * y[l].abs().max(1.0);
            js.yp[l] += step;
            let step = js.yp[l] - y[l];
            system.nonlinear(&js.yp, &mut js.gp, scratch);
            for (t, (a, b)) in js.gp.iter().zip(g0).enumerate() {
                js.jac[(t, l)] = (a - b) / step;
            }
        }
    }
    if js.jac.shape() != (d, d) {
        let found = js.jac.nrows() * js.jac.ncols();
        js.jac = DMatrix::zeros(d, d);
        return Err(Error::DimensionMismatch {
            what: "Jacobian of g (d × d entries)",
            expected: d * d,
            found,
        });
    }
    if js.jac.iter().any(|v| !v.is_finite()) {
        return Err(Error::NonFinite(at));
    }
    Ok(evals)
}

/// Subtracts `Q_ik J` from block (i, k) of the Newton matrix `nm`, for every i < s.
fn subtract_column_block(
    nm: &mut DMatrix<f64>,
    q: &[f64],
    jac: &DMatrix<f64>,
    k: usize,
    s: usize,
    d: usize,
) {
    let sd = s * d;
    let q = DMatrixView::from_slice(&q[k * d * sd..(k + 1) * d * sd], sd, d);
    let mut view = nm.columns_mut(k * d, d);
    view -= q * jac;
}

/// The LU factorisation of the Newton matrix `nm`.
///
/// # Errors
/// [`Error::Numerical`] if it is singular.
fn factor_newton_matrix(nm: DMatrix<f64>) -> Result<NewtonLu> {
    let lu = nm.lu();
    if !lu.is_invertible() {
        return Err(Error::Numerical(
            "the Newton matrix of the stage equations is singular".into(),
        ));
    }
    Ok(lu)
}

/// The Newton matrix at the stages `ys` (g there: `gs`), block (i, k) = `δ_ik I − Q_ik
/// J(Y_k)`, factorised; and the evaluations of g its Jacobians took. Off the hot path: only
/// when the simplified iteration stops contracting.
#[cold]
#[inline(never)]
fn refreshed_newton_lu<S: System>(
    system: &S,
    nw: &mut NewtonState,
    ys: &[f64],
    gs: &[f64],
    s: usize,
    d: usize,
    scratch: &mut [f64],
) -> Result<(NewtonLu, usize)> {
    let mut nm = DMatrix::<f64>::identity(s * d, s * d);
    let mut evals = 0;
    for k in 0..s {
        let at = k * d..(k + 1) * d;
        evals += jacobian_into(
            system,
            &ys[at.clone()],
            Some(&gs[at]),
            &mut nw.jac,
            scratch,
            "Jacobian of g at a stage",
        )?;
        subtract_column_block(&mut nm, &nw.q, &nw.jac.jac, k, s, d);
    }
    Ok((factor_newton_matrix(nm)?, evals))
}

/// `new = old + (I − Φ')⁻¹ rhs` with the factorised Newton matrix (`rhs = Φ(old) − old`);
/// returns the global measure of that update, ‖new − old‖∞ / max(1, ‖new‖∞) (NaN or ∞ if
/// it is not finite).
#[inline]
fn newton_apply(lu: &NewtonLu, rhs: &DVector<f64>, old: &[f64], new: &mut [f64]) -> f64 {
    let delta = lu.solve(rhs);
    let delta = delta.as_ref().unwrap_or(rhs);
    let (mut diff, mut mag) = (0.0_f64, 1.0_f64);
    for ((n, y), dl) in new.iter_mut().zip(old).zip(delta.iter()) {
        *n = y + dl;
        diff = diff.max(dl.abs());
        mag = mag.max(n.abs());
    }
    if new.iter().all(|v| v.is_finite()) {
        diff / mag
    } else {
        f64::NAN
    }
}

/// Newton within one step: the factorised Newton matrix in use (at y₀, or at the stages of the
/// last refresh), the stepper's Newton data, and what the step has cost so far.
pub(super) struct NewtonStep<'a> {
    /// `None` only while a refresh replaces it.
    lu: Option<NewtonLu>,
    state: &'a mut NewtonState,
    /// Whether the Jacobian is refreshed where the iteration stalls ([`StageSolver::Newton`]).
    refresh: bool,
    /// Jacobians of g formed.
    pub(super) jacobian_evals: usize,
    /// Refreshes of the Newton matrix.
    pub(super) refreshes: usize,
    /// Evaluations of g for the Jacobians.
    pub(super) g_evals: usize,
}

impl<K: Kernel, S: System, B: Buffers> StepContext<'_, K, S, B> {
    /// Newton at the start of a step: the stage matrices (the fused sweeps' where there are
    /// some, the same numbers; built at the first step for this h into `newton`), the Jacobian
    /// of g at y₀ (the system's, or forward differences) and the factorised `I − ∂Φ/∂Y` there.
    ///
    /// # Errors
    /// As [`jacobian_into`] and [`factor_newton_matrix`].
    pub(super) fn newton_start<'n>(
        &mut self,
        newton: &'n mut Option<Box<NewtonState>>,
        y: &[f64],
    ) -> Result<NewtonStep<'n>> {
        let (_, s, d) = self.sizes;
        let nw = newton.get_or_insert_with(|| {
            let q = match self.fused {
                Some(f) => f.stage.clone(),
                None => stage_matrices(self.kernel, self.bank, self.coef, self.ws, d),
            };
            Box::new(NewtonState::new(q, d))
        });
        let g_evals = jacobian_into(
            self.system,
            y,
            None,
            &mut nw.jac,
            self.scratch,
            "Jacobian of g at y₀",
        )?;
        // I − ∂Φ/∂Y at y₀: block (i, k) = δ_ik I − Q_ik J.
        let mut nm = DMatrix::<f64>::identity(s * d, s * d);
        for k in 0..s {
            subtract_column_block(&mut nm, &nw.q, &nw.jac.jac, k, s, d);
        }
        Ok(NewtonStep {
            lu: Some(factor_newton_matrix(nm)?),
            state: nw,
            refresh: self.settings.solver == StageSolver::Newton,
            jacobian_evals: 1,
            refreshes: 0,
            g_evals,
        })
    }
}

impl NewtonStep<'_> {
    /// Newton's update of a sweep: `Y ← Y + (I − Φ'(Y*))⁻¹ (Φ(Y) − Y)` into `new_stages`
    /// (which holds Φ(Y)), Y* = y₀ or the stages of the last refresh. Where the update does not
    /// contract by [`NEWTON_REFRESH_THETA`] against `last_global` (or is not finite), and this is
    /// not the `first` iteration (whose Jacobian is that of y₀, where the stages start), it is
    /// redone with the Jacobians at the current stages ([`StageSolver::Newton`] only).
    ///
    /// # Errors
    /// As [`refreshed_newton_lu`].
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn update<S: System>(
        &mut self,
        system: &S,
        scratch: &mut [f64],
        stages: &[f64],
        new_stages: &mut [f64],
        g: &[f64],
        first: bool,
        last_global: f64,
        s: usize,
        d: usize,
    ) -> Result<()> {
        let Some(current) = self.lu.as_ref() else {
            return Ok(());
        };
        let rhs = DVector::from_iterator(
            s * d,
            new_stages.iter().zip(stages.iter()).map(|(a, b)| a - b),
        );
        let update = newton_apply(current, &rhs, stages, new_stages);
        // (False for a NaN update too.)
        let contracts = update < NEWTON_REFRESH_THETA * last_global;
        if self.refresh && !first && !contracts {
            // Heap copies (a refresh allocates the Newton matrix anyway), so that fixed-size
            // stage arrays are not handed to a function that is not inlined.
            let ys = DVector::from_iterator(s * d, stages.iter().copied());
            let gs = DVector::from_iterator(s * d, g.iter().copied());
            drop(self.lu.take()); // the old factorisation goes before the new one is built
            let (fresh, evals) = refreshed_newton_lu(
                system,
                self.state,
                ys.as_slice(),
                gs.as_slice(),
                s,
                d,
                scratch,
            )?;
            newton_apply(&fresh, &rhs, stages, new_stages);
            self.lu = Some(fresh);
            self.g_evals += evals;
            self.jacobian_evals += s;
            self.refreshes += 1;
        }
        Ok(())
    }
}
