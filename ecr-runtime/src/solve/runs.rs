//! The runs of a solve on one step sequence: the answer, Gauss EC(r)P of order 2r, and for a
//! verified solve its check, ECr−1P of order 2r − 2 on the r + 1 Gauss–Lobatto points of the
//! step (its ends included). Both take every step of the same size from their own states, so every
//! grid point is a meeting point: the difference of the two there estimates the error of the
//! check, and bounds that of the answer.
//!
//! The controller sees them through the [`Runs`] trait, without the system's type: only this
//! file and the stepper are compiled once per system.

use std::sync::Arc;

use super::SolveCache;
use super::between::Which;
use super::value_steps::{Seed, seed_pays, value_steps};
use crate::error::{Error, Result};
use crate::operator::LinearOperator;
use crate::stepper::{EcStepper, RuntimeKernel, SolverSettings, StepReport};
use crate::system::System;
use crate::tables::QuadratureKind;

/// What the steps of a stretch cost: the answer's steps, the check's, and the steps to values
/// between grid points (outputs, events), each with their evaluations of g.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Cost {
    pub(super) steps: usize,
    pub(super) g_evals: usize,
    pub(super) sweeps: usize,
    pub(super) check_steps: usize,
    pub(super) check_g_evals: usize,
    pub(super) dense_steps: usize,
    pub(super) dense_g_evals: usize,
}

impl Cost {
    pub(super) fn add(&mut self, c: &Cost) {
        self.steps += c.steps;
        self.g_evals += c.g_evals;
        self.sweeps += c.sweeps;
        self.check_steps += c.check_steps;
        self.check_g_evals += c.check_g_evals;
        self.dense_steps += c.dense_steps;
        self.dense_g_evals += c.dense_g_evals;
    }

    /// Takes the share `part`/`whole` of the steps of both runs (and their g) out of this cost
    /// and returns it: the steps of a window that are not kept when its first steps are.
    pub(super) fn take_share(&mut self, part: usize, whole: usize) -> Cost {
        let share = |n: &mut usize| {
            let taken = (*n * part).div_ceil(whole.max(1)).min(*n);
            *n -= taken;
            taken
        };
        Cost {
            steps: share(&mut self.steps),
            g_evals: share(&mut self.g_evals),
            sweeps: share(&mut self.sweeps),
            check_steps: share(&mut self.check_steps),
            check_g_evals: share(&mut self.check_g_evals),
            dense_steps: 0,
            dense_g_evals: 0,
        }
    }

    pub(super) fn total_steps(&self) -> usize {
        self.steps + self.check_steps + self.dense_steps
    }

    pub(super) fn total_g_evals(&self) -> usize {
        self.g_evals + self.check_g_evals + self.dense_g_evals
    }
}

/// The two runs of a solve (or the one run of a fixed method), stepping states the caller
/// holds.
pub(super) trait Runs {
    /// The step size of the grid steps.
    fn step_size(&self) -> f64;
    /// Sets the step size of both runs (their banks for it are built or taken from the cache).
    ///
    /// # Errors
    /// What building a bank reports.
    fn set_step_size(&mut self, h: f64) -> Result<()>;
    /// One step of the answer from `ya` and of the check from `yc`, both in place.
    ///
    /// # Errors
    /// What a stepper reports (the states may then be anything: the caller restores them).
    fn step(&mut self, ya: &mut [f64], yc: &mut [f64], cost: &mut Cost) -> Result<()>;
    /// One step of the check from `from` (the answer's state before a step) into `out`: set
    /// against the answer's step from the same state, the error the check makes in that step
    /// alone, which the flow has not carried (counted as the check's).
    ///
    /// # Errors
    /// What the stepper reports.
    fn step_local(&mut self, from: &[f64], out: &mut [f64], cost: &mut Cost) -> Result<()>;
    /// The values of the runs `dt` (≤ the step size) after the grid states `ya`, `yc`: one
    /// step of size dt of each method `which` names (the check's only if there is one; what is
    /// not stepped is left as anything), their stage iterations started from `seed` where
    /// given.
    ///
    /// # Errors
    /// What a stepper reports.
    fn partial(
        &mut self,
        from: (&[f64], &[f64]),
        dt: f64,
        out: (&mut [f64], &mut [f64]),
        seed: Option<Seed<'_>>,
        which: Which,
        cost: &mut Cost,
    ) -> Result<()>;
    /// `y` moved along the vector field by `dt`, for a time within the rounding of a grid
    /// point's (a step that short would round to nothing).
    ///
    /// # Errors
    /// [`Error::NonFinite`] if the field is not finite there.
    fn drift(&self, y: &mut [f64], dt: f64) -> Result<()>;
    /// The slope `Ay + g(y)` at `y` into `out` (counted as an evaluation between grid points).
    ///
    /// # Errors
    /// [`Error::NonFinite`] if the slope is not finite.
    fn slope(&mut self, y: &[f64], out: &mut [f64], cost: &mut Cost) -> Result<()>;
    /// [`stiffness`] of the system's linear part (computed once).
    fn stiffness(&mut self) -> &[f64];
}

/// How much the linear part magnifies a perturbation of a state, per component: the larger of
/// |A·1| and |A·(1, −1, 1, …)| (a smooth and a rough perturbation). A slope `Ay + g(y)` at a
/// grid state known to δ is known to about δ times this.
pub(super) fn stiffness<S: System>(system: &S) -> Vec<f64> {
    let d = system.dim();
    let ones = vec![1.0; d];
    let alt: Vec<f64> = (0..d)
        .map(|i| if i % 2 == 0 { 1.0 } else { -1.0 })
        .collect();
    let (mut a, mut b) = (vec![0.0; d], vec![0.0; d]);
    system.linear().apply(&ones, &mut a);
    system.linear().apply(&alt, &mut b);
    a.iter()
        .zip(&b)
        .map(|(x, y)| x.abs().max(y.abs()))
        .collect()
}

/// Makes the runs of order r (with or without the check) at step h.
pub(super) type Make<'m, 's> = dyn FnMut(usize, bool, f64) -> Result<Box<dyn Runs + 's>> + 'm;

/// The answer's kernel: Gauss–Legendre, r moments on r points.
pub(super) fn answer_kernel(r: usize) -> Result<RuntimeKernel> {
    RuntimeKernel::new(r, r)
}

/// The check's kernel: r − 1 moments on the r + 1 Gauss–Lobatto points (c = 0 and c = 1
/// among them), so that it sees g at the ends of every step, where the answer's Gauss points do
/// not look (a kink of g just after a grid point lies before all of them), and so that no
/// interval of a step holds the same share of both rules' weights: a jump of g at position σ of
/// a step moves a rule's result by the weight of its nodes past σ, and with r Lobatto points
/// for even r both rules put exactly ½ past every σ of the middle gap of their nodes, so the
/// answer and the check erred alike there. With r + 1 points the partial sums of the two rules
/// differ at every σ, by at least 1/1.45 of the answer's own error (r = 2 … 10; docs/solve.md).
pub(super) fn check_kernel(r: usize) -> Result<RuntimeKernel> {
    RuntimeKernel::with_quadrature(QuadratureKind::GaussLobatto, r - 1, r + 1)
}

/// The runs of a solve of `S`: the answer's stepper and the check's, and their copies for
/// values between grid points (started from the grid state, no predictor).
pub(super) struct PairRuns<'a, S: System> {
    system: &'a S,
    answer: EcStepper<&'a S>,
    check: Option<EcStepper<&'a S>>,
    between: Option<(EcStepper<&'a S>, Option<EcStepper<&'a S>>)>,
    /// The check's stepper for [`Runs::step_local`], built the first time.
    local: Option<EcStepper<&'a S>>,
    r: usize,
    settings: SolverSettings,
    /// The stage solver's settings of the steps to values between grid points
    /// ([`between_settings`](super::between_settings)).
    between_settings: SolverSettings,
    cache: Arc<SolveCache<S>>,
    slope_scratch: Vec<f64>,
    stiffness: Option<Vec<f64>>,
    /// The stage values of a seeded step ([`Seed`]).
    seed_buf: Vec<f64>,
    /// The answer's steps and their sweeps, for [`seed_pays`].
    swept: (usize, usize),
    /// The length of the completed step the answer's stepper for values between grid points
    /// holds in its buffers (`None` where it holds none), which seeds the next such steps
    /// from the same grid state ([`value_steps`]).
    between_last: Option<f64>,
    /// The signs of the check's kicks ([`Kick`]).
    kick: Kick,
}

impl<'a, S: System> PairRuns<'a, S> {
    /// The answer of order 2r at step h and, with `check`, its check; the steps to values
    /// between grid points with `between_settings` ([`between_settings`](super::between_settings)).
    ///
    /// # Errors
    /// What building the steppers reports (r out of range, the banks).
    pub(super) fn new(
        system: &'a S,
        r: usize,
        check: bool,
        h: f64,
        settings: SolverSettings,
        between_settings: SolverSettings,
        cache: &Arc<SolveCache<S>>,
    ) -> Result<Self> {
        let answer = EcStepper::from_kernel_cached(
            answer_kernel(r)?,
            system,
            h,
            settings,
            Some(Arc::clone(cache)),
        )?;
        let check = if check {
            Some(EcStepper::from_kernel_cached(
                check_kernel(r)?,
                system,
                h,
                settings,
                Some(Arc::clone(cache)),
            )?)
        } else {
            None
        };
        Ok(PairRuns {
            system,
            answer,
            check,
            between: None,
            local: None,
            r,
            settings,
            between_settings,
            cache: Arc::clone(cache),
            slope_scratch: Vec::new(),
            stiffness: None,
            seed_buf: Vec::new(),
            swept: (0, 0),
            between_last: None,
            kick: Kick::default(),
        })
    }

    /// One step of length `h` (the step size these runs were built at) to a value between
    /// grid points, with the runs' own steppers, as [`Runs::partial`] takes it with the
    /// steppers kept for such values ([`value_steps`]): for [`Solution::at`](super::Solution::at),
    /// which builds the runs for the value's length.
    ///
    /// # Errors
    /// What a stepper reports.
    pub(super) fn value_step(
        &mut self,
        from: (&[f64], &[f64]),
        out: (&mut [f64], &mut [f64]),
        seed: Option<Seed<'_>>,
        which: Which,
        cost: &mut Cost,
    ) -> Result<()> {
        let mut buf = std::mem::take(&mut self.seed_buf);
        let h = self.answer.step_size();
        let check = self.check.as_mut().filter(|_| which != Which::Answer);
        let done = value_steps(
            (&mut self.answer, check),
            from,
            h,
            out,
            (seed, None),
            which,
            cost,
            &mut buf,
        );
        self.seed_buf = buf;
        done.map(|_| ())
    }

    /// The steppers for values between grid points, built at step `dt` the first time.
    fn between(&mut self, dt: f64) -> Result<&mut (EcStepper<&'a S>, Option<EcStepper<&'a S>>)> {
        let settings = self.between_settings;
        if self.between.is_none() {
            let cache = Some(Arc::clone(&self.cache));
            let answer = EcStepper::from_kernel_cached(
                answer_kernel(self.r)?,
                self.system,
                dt,
                settings,
                cache.clone(),
            )?;
            let check = match self.check {
                Some(_) => Some(EcStepper::from_kernel_cached(
                    check_kernel(self.r)?,
                    self.system,
                    dt,
                    settings,
                    cache,
                )?),
                None => None,
            };
            self.between = Some((answer, check));
        }
        let pair = self.between.as_mut().expect("built above");
        pair.0.set_step_size(dt)?;
        if let Some(c) = &mut pair.1 {
            c.set_step_size(dt)?;
        }
        Ok(pair)
    }
}

/// The check's rounding made independent of the answer's. Both runs take their steps' ends
/// from the same bank functions at τ = 1 (the propagator and the kernels `Ψ_j(1, hA)`, j < r −
/// 1), so the f64 rounding of those kernels times the nearly equal moments is an error the two
/// runs share, which their difference does not show; where the flow amplifies rounding (a
/// separatrix: one ulp per step grows to the tolerance) that shared part can be most of the
/// answer's error. After each of its steps the check's state moves by one unit of rounding,
/// `±ε |y₁|` per component, with signs from a fixed pseudo-random sequence (the same for every
/// solve: results are reproducible): a rounding error at least of the size of the shared one
/// that the answer does not make, carried and amplified by the flow as the answer's own
/// rounding is, so that it shows in the estimate (the idea of stochastic arithmetic, CESTAC).
/// One unit of rounding of the step's increment, `±ε |y₁ − y₀|`, was too small for that (the
/// Duffing separatrix at 1e−8 stayed `Ok` 6.8 tolerances off; docs/solve.md §2.3). Where the
/// flow does not amplify, the kicks add ~ε√n of the state, below the round-off model of
/// [`estimate`].
#[derive(Clone, Copy, Debug)]
pub(super) struct Kick(u64);

impl Default for Kick {
    fn default() -> Self {
        Kick(0x9e37_79b9_7f4a_7c15)
    }
}

impl Kick {
    /// The next sign, ±1 (a linear congruential generator's top bit).
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        if self.0 >> 63 == 0 { 1.0 } else { -1.0 }
    }
}

fn answer_cost(cost: &mut Cost, rep: &StepReport) {
    cost.steps += 1;
    cost.g_evals += rep.g_evals;
    cost.sweeps += rep.sweeps;
}

fn check_cost(cost: &mut Cost, rep: &StepReport) {
    cost.check_steps += 1;
    cost.check_g_evals += rep.g_evals;
}

impl<S: System> Runs for PairRuns<'_, S> {
    fn step_size(&self) -> f64 {
        self.answer.step_size()
    }

    fn set_step_size(&mut self, h: f64) -> Result<()> {
        self.answer.set_step_size(h)?;
        if let Some(c) = &mut self.check {
            c.set_step_size(h)?;
        }
        if let Some(c) = &mut self.local {
            c.set_step_size(h)?;
        }
        Ok(())
    }

    fn step_local(&mut self, from: &[f64], out: &mut [f64], cost: &mut Cost) -> Result<()> {
        let h = self.answer.step_size();
        if self.local.is_none() {
            self.local = Some(EcStepper::from_kernel_cached(
                check_kernel(self.r)?,
                self.system,
                h,
                self.settings,
                Some(Arc::clone(&self.cache)),
            )?);
        }
        let local = self.local.as_mut().expect("built above");
        local.set_step_size(h)?;
        out.copy_from_slice(from);
        let rep = local.step(out)?;
        check_cost(cost, &rep);
        Ok(())
    }

    fn step(&mut self, ya: &mut [f64], yc: &mut [f64], cost: &mut Cost) -> Result<()> {
        let rep = self.answer.step(ya)?;
        answer_cost(cost, &rep);
        self.swept = (self.swept.0 + 1, self.swept.1 + rep.sweeps);
        if let Some(c) = &mut self.check {
            let rep = c.step(yc)?;
            check_cost(cost, &rep);
            let kick = &mut self.kick;
            c.perturb(yc, |_, y1| y1 + kick.next() * f64::EPSILON * y1.abs());
        }
        Ok(())
    }

    fn partial(
        &mut self,
        (ya, yc): (&[f64], &[f64]),
        dt: f64,
        (oa, oc): (&mut [f64], &mut [f64]),
        seed: Option<Seed<'_>>,
        which: Which,
        cost: &mut Cost,
    ) -> Result<()> {
        let seed = seed.filter(|_| seed_pays(self.swept.0, self.swept.1));
        let mut buf = std::mem::take(&mut self.seed_buf);
        let last = self.between_last.take();
        let stepped = self.between(dt).and_then(|(answer, check)| {
            let check = check.as_mut().filter(|_| which != Which::Answer);
            value_steps(
                (answer, check),
                (ya, yc),
                dt,
                (oa, oc),
                (seed, last),
                which,
                cost,
                &mut buf,
            )
        });
        self.seed_buf = buf;
        self.between_last = stepped?;
        Ok(())
    }

    fn drift(&self, y: &mut [f64], dt: f64) -> Result<()> {
        drift(self.system, y, dt)
    }

    fn slope(&mut self, y: &[f64], out: &mut [f64], cost: &mut Cost) -> Result<()> {
        cost.dense_g_evals += 1;
        slope(self.system, y, out, &mut self.slope_scratch)
    }

    fn stiffness(&mut self) -> &[f64] {
        let system = self.system;
        self.stiffness.get_or_insert_with(|| stiffness(system))
    }
}

/// The slope `Ay + g(y)` at `y` into `out`; `scratch` is resized to what the system needs
/// (once).
///
/// # Errors
/// [`Error::NonFinite`] if the slope is not finite.
pub(super) fn slope<S: System>(
    system: &S,
    y: &[f64],
    out: &mut [f64],
    scratch: &mut Vec<f64>,
) -> Result<()> {
    let d = y.len();
    scratch.resize(d + system.scratch_len(), 0.0);
    let (g, rest) = scratch.split_at_mut(d);
    system.linear().apply(y, out);
    system.nonlinear(y, g, rest);
    for (o, b) in out.iter_mut().zip(g.iter()) {
        *o += b;
        if !o.is_finite() {
            return Err(Error::NonFinite("the vector field at a grid point"));
        }
    }
    Ok(())
}

/// `y += dt (Ay + g(y))`: for a time within the rounding of a grid point's.
///
/// # Errors
/// [`Error::NonFinite`] if the increment is not finite.
pub(super) fn drift<S: System>(system: &S, y: &mut [f64], dt: f64) -> Result<()> {
    let mut f = vec![0.0; y.len()];
    slope(system, y, &mut f, &mut Vec::new())?;
    for (v, a) in y.iter_mut().zip(&f) {
        let dy = dt * a;
        if !dy.is_finite() {
            return Err(Error::NonFinite("the vector field at the end of the span"));
        }
        *v += dy;
    }
    Ok(())
}

/// The round-off model of the estimate: every step rounds each component by this many units of
/// max(ε, the stage tolerance / 5) of the largest component (the propagator and the stage sums
/// mix the components), and the roundings add up like a random walk.
pub(super) const NOISE: f64 = 2.0;

/// The estimate at a value of the answer after `n` steps, in units of the tolerance `(rtol,
/// atol)`: the difference to the check's value plus the modelled round-off (rounding unit
/// `unit`), max_i (|a_i − c_i| + noise) / (atol + rtol |a_i|), a zero counting 0 also where the
/// weight is 0.
pub(super) fn estimate(
    (rtol, atol): (f64, f64),
    unit: f64,
    answer: &[f64],
    check: &[f64],
    n: usize,
) -> f64 {
    let big = answer.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let noise = NOISE * unit * big.max(f64::MIN_POSITIVE) * (n as f64).sqrt();
    answer
        .iter()
        .zip(check)
        .map(|(a, c)| {
            let e = (a - c).abs() + noise;
            if e == 0.0 {
                0.0
            } else {
                e / (atol + rtol * a.abs())
            }
        })
        .fold(0.0, |m, x| if x > m || x.is_nan() { x } else { m })
}
