//! Steps to values between grid points: where their stage iterations start (the answer's
//! step at hand, the grid's interpolant, or the grid state) and what they count. One step of
//! each run, [`value_steps`], serves outputs, events and `Solution::at` alike.

use super::between::Which;
use super::runs::Cost;
use crate::error::Result;
use crate::stepper::EcStepper;
use crate::system::System;

/// Where the stage iterations of a step to a value between grid points start:
/// `seed(nodes, check, out)` writes the answer's (or with `check` the check's) values at the
/// fractions `nodes` of that step (the grid's interpolant), state after state, into `out`.
pub(super) type Seed<'s> = &'s dyn Fn(&[f64], bool, &mut [f64]);

/// A step to a value between grid points starts from the interpolant ([`Seed`]) where the
/// run's own steps take at least this many sweeps of the stage iteration on average (g far
/// from linear over a step): a seed costs s evaluations of g where the grid state costs one,
/// and saves sweeps only there (Lotka–Volterra at h = 0.78, 12.8 sweeps a step: the events'
/// evaluations of g 11–13 % fewer; Duffing ω = 20, 2.0 sweeps a step: 5 % more).
pub(super) const SEED_SWEEPS: f64 = 3.0;

/// Whether steps to values between grid points start from the interpolant, after the run's
/// own `steps` took `sweeps` ([`SEED_SWEEPS`]).
pub(super) fn seed_pays(steps: usize, sweeps: usize) -> bool {
    steps > 0 && sweeps as f64 >= SEED_SWEEPS * steps as f64
}

/// Seeds the stepper's next step with the values `seed` gives at its nodes (the check's with
/// `check`), in `buf` (resized once).
///
/// # Errors
/// What [`Stepper::seed`](crate::stepper::Stepper) reports.
pub(super) fn seed_stepper<S: System>(
    stepper: &mut EcStepper<&S>,
    seed: Seed<'_>,
    check: bool,
    buf: &mut Vec<f64>,
) -> Result<()> {
    use crate::stepper::Kernel;
    let d = stepper.system().dim();
    let nodes = stepper.kernel().nodes();
    buf.resize(nodes.len() * d, 0.0);
    seed(nodes, check, buf);
    stepper.seed(buf)
}

/// How far past the end of the answer's step before a seed may reach (as a fraction of that
/// step): the polynomial through its values is extrapolated no further.
const SEED_REACH: f64 = 1.25;

/// One step of length `dt` to a value between grid points of the methods `which` names,
/// the answer's from `ya` into `oa` and the check's from `yc` into `oc` (what is not stepped
/// is left as the start), counted as steps between grid points. Each stage iteration starts
/// from the answer's completed step from the same state where there is one — the one just
/// taken, for the check, or `last` (its length) that the answer's stepper holds from before,
/// a search's previous trial — through [`seed_from_step`]; else from `seed` (the grid's
/// interpolant), else from the grid state. Returns the length of the completed step the
/// answer's stepper holds afterwards (`last` where it did not step).
///
/// # Errors
/// What a stepper reports.
#[allow(clippy::too_many_arguments)]
pub(super) fn value_steps<S: System>(
    (answer, check): (&mut EcStepper<&S>, Option<&mut EcStepper<&S>>),
    (ya, yc): (&[f64], &[f64]),
    dt: f64,
    (oa, oc): (&mut [f64], &mut [f64]),
    (seed, last): (Option<Seed<'_>>, Option<f64>),
    which: Which,
    cost: &mut Cost,
    buf: &mut Vec<f64>,
) -> Result<Option<f64>> {
    use crate::stepper::Kernel;
    oa.copy_from_slice(ya);
    oc.copy_from_slice(yc);
    let mut held = last;
    if which != Which::Check {
        let own = held.is_some_and(|dt0| {
            let nodes = answer.kernel().nodes();
            seed_from_step(answer, dt / dt0, nodes, (ya, ya), buf)
        });
        value_step_from(answer, own, seed, false, oa, cost, buf)?;
        held = Some(dt);
    }
    if let Some(c) = check {
        let own = held.is_some_and(|dt0| {
            let nodes = c.kernel().nodes();
            seed_from_step(answer, dt / dt0, nodes, (ya, yc), buf)
        });
        value_step_from(c, own, seed, true, oc, cost, buf)?;
    }
    Ok(held)
}

/// One step of `stepper` (the check's with `check`) on `y` for [`value_steps`], its stage
/// iteration started from `buf` where `own` (a seed from the answer's step), else from `seed`
/// where given, and counted as a step between grid points.
fn value_step_from<S: System>(
    stepper: &mut EcStepper<&S>,
    own: bool,
    seed: Option<Seed<'_>>,
    check: bool,
    y: &mut [f64],
    cost: &mut Cost,
    buf: &mut Vec<f64>,
) -> Result<()> {
    if own {
        stepper.seed(buf)?;
    } else if let Some(seed) = seed {
        seed_stepper(stepper, seed, check, buf)?;
    }
    let rep = stepper.step(y)?;
    cost.dense_steps += 1;
    cost.dense_g_evals += rep.g_evals;
    Ok(())
}

/// The seed, into `out`, of a step from `from` whose nodes are `nodes` (fractions of its
/// length), from the answer's completed step from the grid state `ya`: the polynomial
/// through that step's values — `ya` at 0, its stages at its nodes, its end at 1 — at the
/// fractions `ratio · c`, moved by `from − ya` (`from` is `ya` for the answer, the check's
/// grid state for the check). For a zero linear part that is the answer's own collocation
/// polynomial; a step from the same state to a nearby length, or the check's over the same
/// step, starts within its own difference from it. `false` (nothing that counts written)
/// where the stepper keeps no stages, its step did not start from `ya` (another grid
/// state), or the fractions reach past [`SEED_REACH`].
fn seed_from_step<S: System>(
    answer: &EcStepper<&S>,
    ratio: f64,
    nodes: &[f64],
    (ya, from): (&[f64], &[f64]),
    out: &mut Vec<f64>,
) -> bool {
    use crate::stepper::Kernel;
    let Some((y0, stages, y1)) = answer.last_step() else {
        return false;
    };
    let d = from.len();
    let reach = ratio * nodes.iter().fold(0.0f64, |m, &c| m.max(c));
    if !(ratio > 0.0 && reach <= SEED_REACH) || y0 != ya {
        return false;
    }
    // The interpolation points: 0, the stages' nodes strictly inside (0, 1), 1; `at[k]` the
    // offset of point k's value in `stages` (none for the ends).
    let (mut xs, mut at) = ([0.0f64; SEED_POINTS], [usize::MAX; SEED_POINTS]);
    let mut m = 1;
    for (j, &c) in answer.kernel().nodes().iter().enumerate() {
        if c > 0.0 && c < 1.0 {
            if m + 1 >= SEED_POINTS {
                return false;
            }
            (xs[m], at[m]) = (c, j * d);
            m += 1;
        }
    }
    xs[m] = 1.0;
    m += 1;
    let mut vals: [&[f64]; SEED_POINTS] = [&[]; SEED_POINTS];
    vals[0] = y0;
    for k in 1..m - 1 {
        vals[k] = &stages[at[k]..at[k] + d];
    }
    vals[m - 1] = y1;
    let (xs, vals) = (&xs[..m], &vals[..m]);
    // The Lagrange basis in its first barycentric form: ℓ_k(x) = Π_n (x − x_n) · b_k / (x − x_k),
    // b_k = 1 / Π_{n≠k} (x_k − x_n); at a point itself, that point's value.
    let mut b = [1.0f64; SEED_POINTS];
    for (k, bk) in b[..m].iter_mut().enumerate() {
        for (n, &xn) in xs.iter().enumerate() {
            if n != k {
                *bk *= xs[k] - xn;
            }
        }
        *bk = 1.0 / *bk;
    }
    out.clear();
    out.resize(nodes.len() * d, 0.0);
    let mut w = [0.0f64; SEED_POINTS];
    for (slot, &c) in out.chunks_exact_mut(d).zip(nodes) {
        let x = ratio * c;
        let w = &mut w[..m];
        if let Some(k) = xs.iter().position(|&xk| xk == x) {
            w.fill(0.0);
            w[k] = 1.0;
        } else {
            let all: f64 = xs.iter().map(|&xn| x - xn).product();
            for ((wk, &bk), &xk) in w.iter_mut().zip(&b[..m]).zip(xs) {
                *wk = all * bk / (x - xk);
            }
        }
        for (i, o) in slot.iter_mut().enumerate() {
            let mut acc = from[i] - y0[i];
            for (&wk, v) in w.iter().zip(vals) {
                acc += wk * v[i];
            }
            *o = acc;
        }
    }
    out.iter().all(|v| v.is_finite())
}

/// At most this many interpolation points in [`seed_from_step`] (r + 2 for r ≤ 14).
const SEED_POINTS: usize = 16;
