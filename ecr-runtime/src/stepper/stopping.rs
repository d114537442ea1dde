//! When the stage iteration stops, and how it fails: the stopping rules (shared with the
//! baselines' iterations), the measures of a stage update, and the errors of non-finite
//! stages, g or y₁.

use crate::error::Error;

/// Scaled stage updates at or below this (100 ε) count as round-off: when the update stops
/// decreasing there, the iteration has converged as far as f64 allows.
pub const ROUNDOFF_RESIDUAL: f64 = 100.0 * f64::EPSILON;

/// Contraction estimates θ at or above this, with the update at round-off level, count as
/// stagnation: the iteration no longer makes progress.
pub const STAGNATION_THETA: f64 = 0.9;

/// The share of the stage tolerance that the estimated effect of the remaining stage error on
/// y₁ may take ([`y1_converged`]): 2⁻¹⁷, i.e. 7.6e−21 relative with the default tolerance.
/// A stage error that the predictor leaves with the same sign every step reaches y₁ the same
/// way every step, so this bounds a drift per step: with 1/16 instead, the wind problem's
/// energy drifted by 1.3e−18 per step over 1e7 steps (r = 3, h = 0.01, extrapolating
/// predictor), with 2⁻¹⁷ by −1.2e−20, as without the rule.
pub const Y1_SHARE: f64 = 1.0 / 131_072.0;

/// ECrP's second stopping rule, for fast contractions: the stage iteration may stop before its
/// update is within `tolerance` when what is left does not reach y₁.
///
/// y₁ is computed from g at the stages, and a stage error e reaches y₁ through the same kind of
/// map as it reaches the next iterate (the kernels at τ = 1 instead of τ = cᵢ), i.e. reduced by
/// about the contraction θ. So the iteration stops once the estimated stage error e = θ/(1 −
/// θ)·r is within `tolerance` and its effect on y₁, θ·e, is within [`Y1_SHARE`] of it (far
/// below round-off: see there). θ is the larger of this sweep's r/p and `theta_floor`,
/// the largest ratio seen in the step before: a ratio of two updates can be small by chance
/// where the contraction alternates between fast and slow (observed on HBVM(5,2): ratios 0.6,
/// 0.017, 0.3, 0.008, …, where the latest ratio alone stopped sweeps early and the energy
/// error over 2000 steps grew from 3e−14 to 1.3e−12), while the contraction of a step size
/// changes little from one step to the next. With θ < ½ only.
///
/// This saves the last sweep where the contraction is fast: Duffing (ω = 20, r = 6, h = 1/16)
/// contracts by θ ≈ 2e−6 per sweep from a predictor 2e−5 off: updates 5e−5, 1e−10, 3e−16; the
/// third sweep only confirmed what the second had left (e ≈ 3e−16, θe ≈ 1e−21).
#[inline]
pub fn y1_converged(residual: f64, previous: f64, theta_floor: f64, tolerance: f64) -> bool {
    let (r, p) = (residual, previous);
    if !(r < p && p.is_finite()) {
        return false;
    }
    let theta = (r / p).max(theta_floor);
    if theta.is_nan() || theta >= 0.5 {
        return false;
    }
    let e = theta / (1.0 - theta) * r;
    e <= tolerance && theta * e <= Y1_SHARE * tolerance
}

/// The stopping rule of the fixed-point sweeps, shared by every implicit stepper.
///
/// With θ = ‖ΔYₖ‖/‖ΔYₖ₋₁‖ the observed contraction, the distance to the fixed point is about
/// θ/(1 − θ)·‖ΔYₖ‖ (Hairer–Wanner, *Solving ODEs II*, §IV.8). Converged when both the update
/// and that estimate are ≤ `tolerance`, or when the update is at round-off level (≤
/// [`ROUNDOFF_RESIDUAL`]) and no longer contracting (θ ≥ [`STAGNATION_THETA`]).
///
/// Both halves matter for long runs, where a stage error left at the same sign every step shows
/// up as energy drift: the update alone is not enough for slow contraction (θ = 0.6: an update
/// of 1e−15 leaves an error of 1.5e−15, and "no longer halving" is not stagnation there), and
/// the estimate alone stops fast contractions (θ = 0.01) with an error of `tolerance` where one
/// more cheap sweep would reach round-off.
///
/// ECrP adds [`y1_converged`] to this rule.
///
/// Division-free (it runs once per sweep on the hot path): with θ = r/p, θ/(1 − θ) = r/(p − r),
/// so the estimate is r when 2r ≤ p (or θ ≥ 1) and r²/(p − r) otherwise.
#[inline]
pub fn sweeps_converged(residual: f64, previous: f64, tolerance: f64) -> bool {
    sweeps_converged_scaled(residual, previous, residual, tolerance)
}

/// [`sweeps_converged`] for an update measured in a scale of its own (e.g. per component,
/// [`StageScale::PerComponent`](super::StageScale::PerComponent)), with `global` the same update in
/// the scale of the whole state (‖ΔY‖∞ / max(1, ‖Y‖∞)).
///
/// The estimate and the contraction θ come from `residual`; round-off is judged on `global`:
/// stagnation is `global` ≤ [`ROUNDOFF_RESIDUAL`] with θ ≥ [`STAGNATION_THETA`]. A component
/// computed from much larger ones carries their rounding error, ε times *their* size, which is
/// far above ε in its own scale (so is a component near zero): its scaled update never falls
/// to [`ROUNDOFF_RESIDUAL`], but it stops contracting once the whole state is at round-off,
/// and that ends the iteration. With `global = residual` this is [`sweeps_converged`].
#[inline]
pub fn sweeps_converged_scaled(residual: f64, previous: f64, global: f64, tolerance: f64) -> bool {
    let (r, p) = (residual, previous); // p = ∞ on the first sweep: θ = 0
    let estimate_ok = if r < p && 2.0 * r > p {
        r * r <= tolerance * (p - r)
    } else {
        r <= tolerance
    };
    estimate_ok || (global <= ROUNDOFF_RESIDUAL && r >= STAGNATION_THETA * p)
}

/// The [`Error::NonFinite`] of a diverging stage iteration.
const DIVERGED: &str = "stage values (the stage iteration diverged: try a smaller h, or \
                        StageSolver::Newton for a stiff g)";

/// The [`Error::Overflow`] of stage values that overflowed at the first sweep, or while the
/// iteration was contracting.
const STAGES_OVERFLOWED: &str = "stage values";

/// The [`Error::Overflow`] of y₁ from finite stages.
pub(super) const Y1_OVERFLOWED: &str = "the new state y₁";

/// The error of stages that became non-finite at a sweep whose previous scaled update was
/// `previous` (∞ at the first sweep), with g at the previous iterate: g's fault if g is not
/// finite ([`g_fault`]); divergence if the iteration was already moving the stages by half
/// their size or more; otherwise the stage values themselves overflowed (at the first sweep
/// the stages are e^{cᵢhA} y₀ plus the exponential Euler update: the solution, not the
/// iteration, leaves the f64 range).
#[cold]
pub(super) fn stage_fault(g: &[f64], previous: f64) -> Error {
    g_fault(g, previous).map_or_else(|| stages_fault(previous), Error::NonFinite)
}

/// The error of a fixed-point stage iteration whose stage values became non-finite with g finite,
/// `previous` being the scaled update of the sweep before (∞ at the first sweep), as every stepper
/// here reports it: [`Error::NonFinite`] saying the iteration diverged (try a smaller h, or
/// [`StageSolver::Newton`](super::StageSolver::Newton)) if that update was already half the stages
/// or more, else [`Error::Overflow`] of the stage values (the solution itself left the f64 range).
///
/// For iterations of one's own that should fail the way the built-in steppers do (as
/// [`sweeps_converged`] is for their stopping rule).
#[cold]
pub fn stages_fault(previous: f64) -> Error {
    if previous.is_finite() && previous >= 0.5 {
        Error::NonFinite(DIVERGED)
    } else {
        Error::Overflow(STAGES_OVERFLOWED)
    }
}

/// The [`Error::NonFinite`] of g at a stage.
pub(super) const G_NONFINITE: &str = "g(Y) at a stage";

/// The [`Error::NonFinite`] of g at the stages of an iteration that was diverging.
const G_DIVERGED: &str =
    "g(Y) at the iterates of a diverging stage iteration (last update >= half the stages)";

/// The [`Error::NonFinite`] message if g is not finite at stages that the last sweep moved by
/// `residual` (`None` if it is finite): g overflowing at stages that moved by half their size
/// or more (a relative update tends to 1 as the iterates blow up) is most likely the iteration
/// diverging (e.g. a stiff g with fixed-point sweeps) rather than a fault of g: say so.
/// (Inlined: a call would make fixed-size arrays of g leave registers.)
#[inline(always)]
pub(super) fn g_fault(g: &[f64], residual: f64) -> Option<&'static str> {
    match (all_finite(g), residual >= 0.5) {
        (true, _) => None,
        (false, true) => Some(G_DIVERGED),
        (false, false) => Some(G_NONFINITE),
    }
}

/// Whether every entry of `x` is finite, without branches: `0·x` is ±0 for finite x and NaN
/// for ±∞ and NaN, so the sum is 0 exactly when all are finite.
///
/// Four interleaved sums, so that long vectors (a whole state of a large system) are not
/// held up by the latency of one chain of additions.
#[inline(always)]
pub(crate) fn all_finite(x: &[f64]) -> bool {
    let mut acc = [0.0_f64; 4];
    let mut quads = x.chunks_exact(4);
    for q in &mut quads {
        for (a, v) in acc.iter_mut().zip(q) {
            *a += 0.0 * v;
        }
    }
    let rest = quads.remainder().iter().fold(0.0, |a, v| a + 0.0 * v);
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + rest == 0.0
}

/// The global measure of a stage update, `‖new − old‖∞ / max(floor, ‖new‖∞)` (floor 1 for
/// [`StageScale::Global`](super::StageScale::Global)). max |Yᵢ| is taken
/// over the bit patterns: for non-negative floats they order as the values do, and |NaN|
/// orders above ∞, so a NaN or infinite stage makes the measure NaN (`f64::max` would skip
/// NaN); the update's max can skip it (comparisons are cheaper).
///
/// Four interleaved maxima, as [`all_finite`]'s sums: one chain of `max` over every stage
/// value waited on its own latency at each entry (on the NLS, N = 128, EC3P, this loop was a
/// tenth of `ecr run`). A maximum does not round, and NaN updates are skipped in every lane:
/// the same number as one chain (`global_update_is_one_chain_bit_for_bit`).
#[inline(always)]
pub(super) fn global_update(new: &[f64], old: &[f64], floor: f64) -> f64 {
    debug_assert_eq!(new.len(), old.len());
    let (mut diff, mut mag) = ([0.0_f64; 4], [floor.to_bits(); 4]);
    let (new_quads, old_quads) = (new.chunks_exact(4), old.chunks_exact(4));
    let rest = new_quads.remainder().iter().zip(old_quads.remainder());
    for (a4, b4) in new_quads.zip(old_quads) {
        for (l, (a, b)) in a4.iter().zip(b4).enumerate() {
            let t = (a - b).abs();
            if t > diff[l] {
                diff[l] = t;
            }
            mag[l] = mag[l].max(a.abs().to_bits());
        }
    }
    for (a, b) in rest {
        let t = (a - b).abs();
        if t > diff[0] {
            diff[0] = t;
        }
        mag[0] = mag[0].max(a.abs().to_bits());
    }
    let d = diff.iter().fold(0.0_f64, |d, &t| if t > d { t } else { d });
    let m = mag[0].max(mag[1]).max(mag[2].max(mag[3]));
    d / f64::from_bits(m)
}

/// `max_i |new_i − old_i| / max(|new_i|, atol)` ([`StageScale::PerComponent`]; `atol` > 0),
/// division-free per component: `t / scale > rel ⇔ t > rel · scale`. Meaningless if a new
/// stage is not finite (the global measure, computed beside it, catches that).
#[inline]
pub(super) fn per_component_update(new: &[f64], old: &[f64], atol: f64) -> f64 {
    let mut rel = 0.0_f64;
    for (a, b) in new.iter().zip(old) {
        let t = (a - b).abs();
        let scale = a.abs().max(atol);
        if t > rel * scale {
            rel = t / scale;
        }
    }
    rel
}

#[cfg(test)]
mod tests {
    use super::{
        all_finite, global_update, sweeps_converged, sweeps_converged_scaled, y1_converged,
    };

    /// The four-lane `global_update` is the one-chain maximum it replaced, bit for bit: every
    /// length up to 13, mixed magnitudes, and NaN, ±∞ and −0 in any position.
    #[test]
    fn global_update_is_one_chain_bit_for_bit() {
        let one_chain = |new: &[f64], old: &[f64]| {
            let (mut diff, mut mag) = (0.0_f64, 1.0_f64.to_bits());
            for (a, b) in new.iter().zip(old) {
                let t = (a - b).abs();
                if t > diff {
                    diff = t;
                }
                mag = mag.max(a.abs().to_bits());
            }
            diff / f64::from_bits(mag)
        };
        let mut rng = crate::test_rng::XorShift(0x9E37_79B9_7F4A_7C15);
        let mut next = move || rng.mixed(20);
        let special = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -0.0, 0.0];
        for n in 0..14 {
            for trial in 0..40 {
                let mut new: Vec<f64> = (0..n).map(|_| next()).collect();
                let mut old: Vec<f64> = new.iter().map(|v| v + next() * 1e-3).collect();
                if n > 0 && trial % 2 == 1 {
                    let i = trial % n;
                    let v = special[trial % special.len()];
                    if trial % 4 == 1 {
                        new[i] = v;
                    } else {
                        old[i] = v;
                    }
                }
                let (got, want) = (global_update(&new, &old, 1.0), one_chain(&new, &old));
                assert_eq!(got.to_bits(), want.to_bits(), "n = {n}, trial {trial}");
            }
        }
    }

    #[test]
    fn finiteness_of_every_entry() {
        for n in 0..13 {
            let x: Vec<f64> = (0..n)
                .map(|i| [1.5, -0.0, f64::MAX, -f64::MAX, f64::MIN_POSITIVE][i % 5])
                .collect();
            assert!(all_finite(&x), "n = {n}");
            for i in 0..n {
                for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                    let mut y = x.clone();
                    y[i] = bad;
                    assert!(!all_finite(&y), "n = {n}, entry {i} = {bad}");
                }
            }
        }
    }

    const TOL: f64 = 1e-15;

    #[test]
    fn stopping_rule() {
        let inf = f64::INFINITY;
        // First sweep: the update itself.
        assert!(sweeps_converged(0.0, inf, TOL));
        assert!(sweeps_converged(1e-16, inf, TOL));
        assert!(!sweeps_converged(1e-14, inf, TOL));
        // Slow contraction θ = 0.6: an update of 1e-15 still leaves ≈ 1.5e-15.
        assert!(!sweeps_converged(1e-15, 1e-15 / 0.6, TOL));
        assert!(sweeps_converged(6e-16, 1e-15, TOL));
        // Fast contraction θ = 0.01: the update decides.
        assert!(sweeps_converged(1e-15, 1e-13, TOL));
        assert!(!sweeps_converged(2e-15, 2e-13, TOL));
        // Not contracting (θ ≥ 1): the update decides, and at round-off it is stagnation.
        assert!(sweeps_converged(8e-16, 5e-16, TOL));
        assert!(sweeps_converged(1e-14, 1.05e-14, TOL));
        assert!(sweeps_converged(1e-14, 0.9e-14, TOL));
        // Still halving at round-off level: not stagnation, go on.
        assert!(!sweeps_converged(1e-14, 2e-14, TOL));
        // Far above round-off and not contracting: no.
        assert!(!sweeps_converged(1e-10, 1e-11, TOL));
        // NaN is never convergence (the stepper reports divergence).
        assert!(!sweeps_converged(f64::NAN, 1e-3, TOL));
        assert!(!sweeps_converged(f64::NAN, inf, TOL));
    }

    #[test]
    fn y1_stopping_rule() {
        let inf = f64::INFINITY;
        // Duffing ω = 20, r = 6, h = 1/16: θ ≈ 2.4e-6, e ≈ 3e-16, θe ≈ 7e-22.
        assert!(y1_converged(1.3e-10, 5.5e-5, 0.0, TOL));
        // ... unless the step before saw a slow ratio: θ = 0.3 gives e = 5.6e-11.
        assert!(!y1_converged(1.3e-10, 5.5e-5, 0.3, TOL));
        // θ = 0.01: e = 2e-17, θe = 2e-19 (not within 2^-17 of it); e = 1e-14 is not within
        // the tolerance.
        assert!(!y1_converged(2e-15, 2e-13, 0.0, TOL));
        assert!(!y1_converged(1e-12, 1e-10, 0.0, TOL));
        // θ = 0.3: e = 8.6e-16 within the tolerance, θe = 2.6e-16 not within 2^-17 of it.
        assert!(!y1_converged(2e-15, 2e-15 / 0.3, 0.0, TOL));
        // θ = 0.1: e = 5.6e-16, but θe = 5.6e-17 is not within 2^-17 of the tolerance.
        assert!(!y1_converged(5e-15, 5e-14, 0.0, TOL));
        // θ = 1e-3: e = 1e-17, θe = 1e-20 is not; θ = 1e-4: e = 1e-18, θe = 1e-22 is.
        assert!(!y1_converged(1e-14, 1e-11, 0.0, TOL));
        assert!(y1_converged(1e-14, 1e-10, 0.0, TOL));
        // No contraction known (first sweep), not contracting, or NaN: never.
        assert!(!y1_converged(1e-20, inf, 0.0, TOL));
        assert!(!y1_converged(1e-16, 1e-16, 0.0, TOL));
        assert!(!y1_converged(f64::NAN, 1e-3, 0.0, TOL));
    }

    #[test]
    fn scaled_stopping_rule() {
        let inf = f64::INFINITY;
        // With the global measure equal to the scaled one it is the plain rule.
        for (r, p) in [
            (1e-16, inf),
            (1e-14, 2e-14),
            (8e-16, 5e-16),
            (6e-16, 1e-15),
            (0.3, 0.2),
        ] {
            assert_eq!(
                sweeps_converged_scaled(r, p, r, TOL),
                sweeps_converged(r, p, TOL),
                "{r:e} {p:e}"
            );
        }
        // A component whose own scale sees only noise (0.3, not contracting): stagnation once
        // the whole state is at round-off, not before.
        assert!(sweeps_converged_scaled(0.3, 0.2, 1e-16, TOL));
        assert!(!sweeps_converged_scaled(0.3, 0.2, 1e-12, TOL));
        // Still contracting in its own scale: go on, even at global round-off.
        assert!(!sweeps_converged_scaled(1e-9, 1e-6, 1e-17, TOL));
        // Converged in its own scale.
        assert!(sweeps_converged_scaled(1e-17, 1e-15, 1e-30, TOL));
        assert!(!sweeps_converged_scaled(f64::NAN, 1e-3, f64::NAN, TOL));
    }
}
