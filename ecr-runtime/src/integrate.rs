//! Fixed-step integration over [t0, T] with observers and a final report.

use crate::error::{Error, Result};
use crate::second_order::{SecondOrderSystem, TcStepper};
use crate::stepper::{Buffers, Kernel, SizedEcStepper, StepReport, Stepper};
use crate::system::System;

/// A one-step method with a fixed step size acting on a flat state vector: what
/// [`integrate`] drives. Implemented by [`Stepper`] and [`SizedEcStepper`] (state y) and
/// [`TcStepper`] (state (q, p), concatenated).
pub trait Integrator {
    /// The step size.
    fn step_size(&self) -> f64;
    /// Changes the step size.
    ///
    /// # Errors
    /// As the stepper's `set_step_size`.
    fn set_step_size(&mut self, h: f64) -> Result<()>;
    /// One step of the flat state in place.
    ///
    /// # Errors
    /// As the stepper's `step`.
    fn step_state(&mut self, y: &mut [f64]) -> Result<StepReport>;
    /// The energy of a flat state, if known.
    fn energy_of(&self, y: &[f64]) -> Option<f64>;
}

impl<K: Kernel, S: System, B: Buffers> Integrator for Stepper<K, S, B> {
    fn step_size(&self) -> f64 {
        Stepper::step_size(self)
    }
    fn set_step_size(&mut self, h: f64) -> Result<()> {
        Stepper::set_step_size(self, h)
    }
    fn step_state(&mut self, y: &mut [f64]) -> Result<StepReport> {
        self.step(y)
    }
    fn energy_of(&self, y: &[f64]) -> Option<f64> {
        self.system().energy(y)
    }
}

impl<S: System> Integrator for SizedEcStepper<S> {
    fn step_size(&self) -> f64 {
        SizedEcStepper::step_size(self)
    }
    fn set_step_size(&mut self, h: f64) -> Result<()> {
        SizedEcStepper::set_step_size(self, h)
    }
    fn step_state(&mut self, y: &mut [f64]) -> Result<StepReport> {
        self.step(y)
    }
    fn energy_of(&self, y: &[f64]) -> Option<f64> {
        self.system().energy(y)
    }
}

impl<S: SecondOrderSystem, K: Kernel, B: Buffers> Integrator for TcStepper<S, K, B> {
    fn step_size(&self) -> f64 {
        TcStepper::step_size(self)
    }
    fn set_step_size(&mut self, h: f64) -> Result<()> {
        TcStepper::set_step_size(self, h)
    }
    fn step_state(&mut self, y: &mut [f64]) -> Result<StepReport> {
        self.stepper_mut().step(y)
    }
    fn energy_of(&self, y: &[f64]) -> Option<f64> {
        self.stepper().system().energy(y)
    }
}

/// A boxed integrator is one too: [`integrate`] drives a method chosen at run time
/// (`Box<dyn Integrator>`, or a box of a trait object whose trait extends [`Integrator`]) with
/// the same steps, bit for bit, as the method itself.
impl<I: Integrator + ?Sized> Integrator for Box<I> {
    fn step_size(&self) -> f64 {
        (**self).step_size()
    }
    fn set_step_size(&mut self, h: f64) -> Result<()> {
        (**self).set_step_size(h)
    }
    fn step_state(&mut self, y: &mut [f64]) -> Result<StepReport> {
        (**self).step_state(y)
    }
    fn energy_of(&self, y: &[f64]) -> Option<f64> {
        (**self).energy_of(y)
    }
}

/// Summary of an integration.
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    /// Final time reached.
    pub t_end: f64,
    /// Steps taken.
    pub steps: usize,
    /// Evaluations of g.
    pub g_evals: usize,
    /// Fixed-point sweeps, summed over the steps.
    pub sweeps: usize,
    /// Largest number of sweeps in one step.
    pub max_sweeps: usize,
    /// Steps whose stage iteration stopped at the sweep limit without reaching the tolerance
    /// (only possible with `SweepLimit::Accept`).
    pub unconverged_steps: usize,
    /// H(y0), if the system knows H.
    pub energy_start: Option<f64>,
    /// H(y(T)).
    pub energy_end: Option<f64>,
    /// max over the observed steps of |H − H0| / max(|H0|, tiny) (every step when
    /// `energy_every` is 1).
    pub max_energy_error: Option<f64>,
}

/// Options of [`integrate`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IntegrateOptions {
    /// Evaluate H every this many steps for `max_energy_error` (0: only at the end).
    pub energy_every: usize,
    /// Call the observer every this many steps (0: never). It always sees t0 and T.
    pub observe_every: usize,
}

impl Default for IntegrateOptions {
    fn default() -> Self {
        IntegrateOptions {
            energy_every: 1,
            observe_every: 0,
        }
    }
}

/// How [`integrate`] divides [t0, t_end] into steps of size h: `full_steps` steps of h, then,
/// if they do not reach t_end exactly, one last step of size `last`.
///
/// Step n ends at t₀ + n·h (computed from n, not accumulated, so the times do not drift).
/// The sizes of the steps add up to t_end − t₀ exactly, up to the rounding of the last one:
/// the steps advance the solution by n·fl(h), not by the rounded t₀ + n·h, so `last` is the
/// remainder t_end − t₀ − n·fl(h) evaluated exactly (error-free sum and product, the latter by
/// [`f64::mul_add`]) and rounded once. If t₀ + n·h is within [`StepPlan::TIME_ULPS`] units of
/// round-off (ε·max(|t₀|, |t_end|)) of t_end, the n-th step itself is `last`: h plus that
/// remainder, a few units of round-off from h (`None` if it rounds to h, as when h divides the
/// span exactly); otherwise `last` is a shortened step after n full ones, so that the
/// integration ends at t_end for every h, also h > t_end − t₀. Without the correction, n steps
/// of fl(h) miss the span by up to n·ulp(h)/2 (h = 0.1 over [0, 1000]: 5.6e−14), which is the
/// error floor of an accurate method on a fast oscillation (Duffing ω = 20: 2e−11; issue 27).
/// h itself is never adjusted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepPlan {
    /// Steps of the full size h.
    pub full_steps: usize,
    /// The size of a final step that is not h, if one is needed: shortened (0 < last < h), or
    /// h corrected by the round-off of n·fl(h) against the span (|last − h| ≤
    /// [`StepPlan::TIME_ULPS`]·ε·max(|t₀|, |t_end|) and the rounding of the sizes).
    pub last: Option<f64>,
}

impl StepPlan {
    /// How many units of round-off ε·max(|t₀|, |t_end|) apart t₀ + n·h and t_end may be and
    /// still count as the same time (the rounding of h, of n·h and of the sum).
    pub const TIME_ULPS: f64 = 4.0;

    /// The plan for [t0, t_end] with step h.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] if t0 or t_end is not finite or t_end < t0, or if the interval
    /// needs more than 2⁵² steps (the step count would no longer be exact in f64);
    /// [`Error::InvalidStepSize`] for h ≤ 0 or not finite.
    pub fn new(t0: f64, t_end: f64, h: f64) -> Result<Self> {
        if !t0.is_finite() || !t_end.is_finite() {
            return Err(Error::InvalidInput(format!(
                "t0 = {t0:?} and t_end = {t_end:?} must be finite"
            )));
        }
        if t_end < t0 {
            return Err(Error::InvalidInput(format!(
                "t_end = {t_end:?} is before t0 = {t0:?}"
            )));
        }
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidStepSize(h));
        }
        let span = t_end - t0;
        let ratio = span / h;
        if ratio > (1u64 << 52) as f64 {
            return Err(Error::InvalidInput(format!(
                "t_end − t0 = {span:?} needs more than 2^52 steps of h = {h:?}"
            )));
        }
        let tol = Self::TIME_ULPS * f64::EPSILON * t0.abs().max(t_end.abs());
        if span <= tol {
            // The span is within the rounding of time: one step of the span.
            return Ok(StepPlan {
                full_steps: 0,
                last: (span > 0.0).then_some(span),
            });
        }
        if h <= tol {
            return Err(Error::InvalidInput(format!(
                "h = {h:e} is below the resolution of time on [{t0:?}, {t_end:?}] \
                 ({}ε·|t| = {tol:e}): the steps could not advance the clock",
                Self::TIME_ULPS
            )));
        }
        let at = |n: f64| t0 + n * h;
        // The most full steps that end no later than t_end (up to round-off); the division
        // may be off by one either way.
        let mut n = ratio.floor();
        while n > 0.0 && at(n) > t_end + tol {
            n -= 1.0;
        }
        while at(n + 1.0) <= t_end + tol {
            n += 1.0;
        }
        if n == 0.0 {
            return Ok(StepPlan {
                full_steps: 0,
                last: (span > 0.0).then(|| exact_rest(t0, t_end, 0.0, h)),
            });
        }
        if t_end - at(n) > tol {
            // A shortened step after n full ones.
            return Ok(StepPlan {
                full_steps: n as usize,
                last: Some(exact_rest(t0, t_end, n, h)),
            });
        }
        // n steps reach t_end up to round-off: the n-th is h plus what n·fl(h) misses.
        let last = exact_rest(t0, t_end, n - 1.0, h);
        Ok(if last == h {
            StepPlan {
                full_steps: n as usize,
                last: None,
            }
        } else {
            StepPlan {
                full_steps: n as usize - 1,
                last: Some(last),
            }
        })
    }

    /// The number of steps, the last one included.
    pub fn steps(&self) -> usize {
        self.full_steps + usize::from(self.last.is_some())
    }
}

/// t_end − t₀ − n·h in exact arithmetic, rounded once (up to a relative 2ε where it is far
/// smaller than the span): what n steps of h leave of [t₀, t_end]. n ≤ 2⁵² is exact, and so are
/// the error-free transformations of t_end − t₀ (two-sum) and n·h (two-product by
/// [`f64::mul_add`]); the difference of their leading parts is exact by Sterbenz's lemma when
/// n·h is within a factor 2 of the span.
pub(crate) fn exact_rest(t0: f64, t_end: f64, n: f64, h: f64) -> f64 {
    // t_end − t₀ = span + span_err exactly.
    let span = t_end - t0;
    let v = span - t_end;
    let span_err = (t_end - (span - v)) + (-t0 - v);
    // n·h = p + p_err exactly.
    let p = n * h;
    let p_err = n.mul_add(h, -p);
    ((span - p) + span_err) - p_err
}

/// Integrates from (t0, y) to t_end with the stepper's step size h, in place (for a
/// [`TcStepper`], y = (q, p)).
///
/// The steps are those of [`StepPlan::new`]: full steps of h ending at t₀ + n·h, then, if
/// they do not reach t_end, one last step whose size makes the steps add up to t_end − t₀
/// (shortened, or h corrected by round-off; its φ-bank is built once, then the original h
/// restored). The report's `t_end` is the time reached, t_end itself
/// (also when h > t_end − t0). The observer receives (t, y, H(y)).
///
/// # Errors
/// As [`StepPlan::new`]; a step's error wrapped in [`Error::AtStep`] with the number of the
/// step, the time it started at and its size (the state is left at the last successful step).
pub fn integrate<I: Integrator>(
    stepper: &mut I,
    t0: f64,
    t_end: f64,
    y: &mut [f64],
    options: IntegrateOptions,
    mut observer: impl FnMut(f64, &[f64], Option<f64>),
) -> Result<Report> {
    let h = stepper.step_size();
    let plan = StepPlan::new(t0, t_end, h)?;
    let steps = plan.steps();
    let e0 = stepper.energy_of(y);
    let scale = e0.map(|e| e.abs().max(f64::MIN_POSITIVE));
    let mut report = Report {
        t_end: t0,
        steps: 0,
        g_evals: 0,
        sweeps: 0,
        max_sweeps: 0,
        unconverged_steps: 0,
        energy_start: e0,
        energy_end: e0,
        max_energy_error: e0.map(|_| 0.0),
    };
    if options.observe_every > 0 {
        observer(t0, y, e0);
    }
    for n in 1..=steps {
        let last_short = plan.last.filter(|_| n == steps);
        if let Some(rest) = last_short {
            stepper.set_step_size(rest)?;
        }
        let rep = stepper.step_state(y);
        if last_short.is_some() {
            stepper.set_step_size(h)?;
        }
        let rep = rep.map_err(|e| Error::AtStep {
            step: n,
            t: t0 + (n - 1) as f64 * h,
            h: last_short.unwrap_or(h),
            source: Box::new(e),
        })?;
        report.steps = n;
        report.g_evals += rep.g_evals;
        report.sweeps += rep.sweeps;
        report.max_sweeps = report.max_sweeps.max(rep.sweeps);
        report.unconverged_steps += usize::from(!rep.converged);
        let t = if n == steps { t_end } else { t0 + n as f64 * h };
        report.t_end = t;
        let check_energy =
            n == steps || (options.energy_every > 0 && n % options.energy_every == 0);
        let observe = options.observe_every > 0 && (n % options.observe_every == 0 || n == steps);
        if check_energy || observe {
            let e = stepper.energy_of(y);
            if let (Some(e), Some(e0), Some(sc), Some(m)) =
                (e, e0, scale, report.max_energy_error.as_mut())
            {
                *m = m.max((e - e0).abs() / sc);
            }
            if n == steps {
                report.energy_end = e;
            }
            if observe {
                observer(t, y, e);
            }
        }
    }
    Ok(report)
}
