//! The step formula: y₁ from y₀ and the moments of g at the converged stages, with the
//! propagator in double-double and the previous step's rounding error carried
//! (compensated summation, [`SolverSettings::compensated`](super::SolverSettings::compensated)),
//! where the bank supports it; on the serial or the concurrent path.

use super::buffers::Buffers;
use super::context::StepContext;
use super::gemv::gemv_cm;
use super::kernel::Kernel;
use super::parallel::ParallelState;
use crate::operator::PhiBank;
use crate::phi::two_sum;
use crate::system::System;

impl<K: Kernel, S: System, B: Buffers> StepContext<'_, K, S, B> {
    /// y₁ into `y`: the moments of g at the stages, then `e^{hA} y₀` plus the nonlinear part,
    /// compensated where the settings and the bank allow (the rounding error of y₁ into
    /// `comp`); `tmp` is scratch (3d), `last` is overwritten.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn finish(
        &mut self,
        y0: &[f64],
        g: &[f64],
        moments: &mut [f64],
        y: &mut [f64],
        last: &mut [f64],
        comp: &mut [f64],
        tmp: &mut [f64],
    ) {
        let (m, s, d) = self.sizes;
        if let Some(p) = self.par.as_deref_mut() {
            p.moments(g, moments, d);
        } else {
            self.kernel.legendre_moments_sized(g, moments, self.sizes);
        }
        let (hi, rest) = tmp.split_at_mut(d);
        let (lo, ec) = rest.split_at_mut(d);
        let (bank, coef) = (self.bank, &self.coef[s * m..(s + 1) * m]);
        if let Some(p) = self.par.as_deref_mut() {
            let comp_on = self.settings.compensated;
            finish_concurrent(
                bank, p, self.ws, s, comp_on, y0, moments, coef, y, last, comp, hi, lo, ec,
            );
        } else if self.settings.compensated && bank.propagate_dd(s, y0, hi, lo, self.ws) {
            // y₁ = e^{hA} y₀ (double-double) + N + e^{hA} c, where N is the nonlinear part and
            // c the rounding error of the previous y₁ (compensated summation). Rounding the
            // f64 state the same way every period of an oscillation, and the f64 propagator,
            // would otherwise make the energy drift linearly (≈ 1e−16 per step).
            if let Some(f) = self.fused {
                let (e, kernels) = f.end.split_at(d * d);
                gemv_cm(kernels, d, [moments, &[]], None, y);
                gemv_cm(e, d, [comp, &[]], None, ec);
            } else {
                last.fill(0.0);
                bank.combine(s..s + 1, last, moments, coef, y, self.ws);
                bank.apply(s, 0, comp, ec, self.ws);
            }
            compensated_sum(y, comp, hi, lo, ec);
        } else if let Some(f) = self.fused {
            gemv_cm(&f.end, d, [y0, moments], None, y);
        } else {
            bank.combine(s..s + 1, y0, moments, coef, y, self.ws);
        }
    }
}

/// y₁ = hi + lo + N + e (double-double propagated state, nonlinear part N in `y`, propagated
/// rounding error e), rounded to `y`, its rounding error to `comp`.
#[inline(always)]
fn compensated_sum(y: &mut [f64], comp: &mut [f64], hi: &[f64], lo: &[f64], ec: &[f64]) {
    for ((((yv, c), h), l), e) in y
        .iter_mut()
        .zip(comp.iter_mut())
        .zip(hi.iter())
        .zip(lo.iter())
        .zip(ec.iter())
    {
        let (sum, err) = two_sum(*h, *l + *yv + *e);
        *yv = sum;
        *c = err;
    }
}

/// The end of a step on the concurrent path: y₁ as the serial path computes it (the
/// compensated update where `compensated` and the bank carries its propagator, else one
/// `combine` at τ = 1), with the independent bank operations run concurrently: e^{hA} y₀ in
/// double-double and then e^{hA} c on one task, the nonlinear part on the other.
#[allow(clippy::too_many_arguments)]
fn finish_concurrent<Bk: PhiBank>(
    bank: &Bk,
    par: &mut ParallelState<Bk::Workspace>,
    ws: &mut Bk::Workspace,
    s: usize,
    compensated: bool,
    y0: &[f64],
    moments: &[f64],
    coef: &[f64],
    y: &mut [f64],
    last: &mut [f64],
    comp: &mut [f64],
    hi: &mut [f64],
    lo: &mut [f64],
    ec: &mut [f64],
) {
    if compensated {
        last.fill(0.0);
        let (wa, wb) = par.helpers.split_at_mut(1);
        let comp_in: &[f64] = comp;
        let last: &[f64] = last;
        let (carried, ()) = bank.join(
            &mut wa[0],
            &mut wb[0],
            |bk, w| {
                let carried = bk.propagate_dd(s, y0, hi, lo, w);
                if carried {
                    bk.apply(s, 0, comp_in, ec, w);
                }
                carried
            },
            |bk, w| bk.combine(s..s + 1, last, moments, coef, y, w),
        );
        if carried {
            compensated_sum(y, comp, hi, lo, ec);
            return;
        }
    }
    bank.combine_concurrent(s..s + 1, y0, moments, coef, y, ws, &mut par.helpers);
}
