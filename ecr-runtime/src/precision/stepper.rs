//! ECrP in any [`Real`] scalar.

use super::kernels::StepMaps;
use super::{GenericSystem, GenericTables, LinearPart, Real};
use crate::error::{Error, Result};

/// Stage sweeps allowed per step before the step is refused.
pub const GENERIC_MAX_SWEEPS: usize = 200;

/// The stage iteration has converged when the last update is at most this many units of
/// round-off of the stages (`‖ΔY‖_∞ ≤ 8 ε ‖Y‖_∞`), or when it has stopped shrinking (it halved
/// less than once in the last sweep) within `ROUNDOFF_FLOOR` units: the rounding noise of a
/// sweep, which no further sweep removes.
const CONVERGED_UNITS: f64 = 8.0;
const ROUNDOFF_FLOOR: f64 = 1024.0;

/// ECrP (`docs/method.md#ecrp`) with r moments and s Gauss–Legendre points, in the scalar `S`:
/// the method of [`crate::stepper::EcStepper`], written once for `f64` and
/// [`DoubleDouble`](super::DoubleDouble).
///
/// Per step of size h, with the Legendre moments `Lⱼ = Σᵢ ℓ_{ji} g(Yᵢ)`:
///
/// ```text
/// Yᵢ = e^{cᵢhA} y₀ + h cᵢ Σⱼ (2j+1) Ψⱼ(cᵢ, hA) Lⱼ      (fixed-point sweeps)
/// y₁ = e^{hA} y₀  + h Σⱼ (2j+1) Ψⱼ(1, hA) Lⱼ
/// ```
///
/// The sweeps start from the previous step's continuous solution at the new nodes (the same
/// formula at τ = 1 + cᵢ, with the previous start and moments) after a step of the same size,
/// and from `e^{cᵢhA} y₀` otherwise. The maps are built once per step size; the sweeps run
/// until the stages are converged to
/// the round-off of `S` (an unconverged step is an error, never a silent result). Where
/// [`crate::stepper::EcStepper`] is tuned for speed in `f64` (fused maps, predictors, SIMD-friendly
/// loops), this stepper is the reference: in `DoubleDouble` it shows the order 2r for every r
/// (`docs/method.md#measured-orders`).
#[derive(Clone, Debug)]
pub struct GenericStepper<S: Real, Sys> {
    system: Sys,
    d: usize,
    tables: GenericTables<S>,
    linear: LinearPart<S>,
    h: S,
    /// The maps of the step size `h`, built at the first step that needs them (so that
    /// `integrate`, which may round h to divide the span, builds them once).
    maps: Option<StepMaps<S>>,
    max_sweeps: usize,
    stages: Vec<S>,
    starts: Vec<S>,
    next: Vec<S>,
    g: Vec<S>,
    moments: Vec<S>,
    /// The previous step's start and moments, while they predict the next step's stages.
    previous_start: Vec<S>,
    previous_moments: Vec<S>,
    previous_valid: bool,
    last_sweeps: usize,
}

/// What [`GenericStepper::integrate`] did.
#[derive(Clone, Debug, PartialEq)]
pub struct GenericReport<S> {
    /// Steps taken.
    pub steps: usize,
    /// The step size of every step but the last.
    pub h: S,
    /// The size of the last step: `h`, or the step that makes the sizes add up to the span
    /// exactly (`None` for an empty run).
    pub h_last: Option<S>,
    /// The time reached.
    pub t_end: S,
    /// Stage sweeps over all steps.
    pub sweeps: usize,
    /// The most sweeps one step took.
    pub max_sweeps: usize,
    /// Evaluations of g.
    pub g_evals: usize,
    /// The energy at the start and at the end, if the system has one.
    pub energy_start: Option<S>,
    /// See `energy_start`.
    pub energy_end: Option<S>,
    /// `max_n |H(y_n) − H(y₀)| / |H(y₀)|` (absolute if `H(y₀) = 0`).
    pub max_energy_error: Option<f64>,
}

impl<S: Real, Sys: GenericSystem<S>> GenericStepper<S, Sys> {
    /// A stepper of order 2r with s = r Gauss–Legendre points and step size `h`.
    ///
    /// # Errors
    /// As [`GenericStepper::with_nodes`].
    pub fn new(system: Sys, r: usize, h: S) -> Result<Self> {
        Self::with_nodes(system, r, r, h)
    }

    /// A stepper of order 2r with s ≥ r Gauss–Legendre points and step size `h`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for (r, s) outside the tables' range;
    /// [`Error::InvalidStepSize`] unless `h` is finite and > 0; [`Error::DimensionMismatch`]
    /// or [`Error::NonFinite`] for a linear part that does not fit the system.
    pub fn with_nodes(system: Sys, r: usize, s: usize, h: S) -> Result<Self> {
        let d = system.dim();
        if d == 0 {
            return Err(Error::InvalidParameter("a system of dimension 0".into()));
        }
        check_step(h)?;
        let linear = system.linear_part();
        linear.check(d)?;
        let tables = GenericTables::new(r, s)?;
        Ok(GenericStepper {
            system,
            d,
            linear,
            h,
            maps: None,
            max_sweeps: GENERIC_MAX_SWEEPS,
            stages: vec![S::zero(); s * d],
            starts: vec![S::zero(); s * d],
            next: vec![S::zero(); s * d],
            g: vec![S::zero(); s * d],
            moments: vec![S::zero(); r * d],
            previous_start: vec![S::zero(); d],
            previous_moments: vec![S::zero(); r * d],
            previous_valid: false,
            last_sweeps: 0,
            tables,
        })
    }

    /// The system.
    pub fn system(&self) -> &Sys {
        &self.system
    }

    /// The step size.
    pub fn step_size(&self) -> S {
        self.h
    }

    /// Order parameter r (the method has order 2r).
    pub fn r(&self) -> usize {
        self.tables.r
    }

    /// Number of quadrature points s.
    pub fn s(&self) -> usize {
        self.tables.s
    }

    /// The sweeps of the last step.
    pub fn last_sweeps(&self) -> usize {
        self.last_sweeps
    }

    /// Sets the most sweeps a step may take (at least 1).
    pub fn set_max_sweeps(&mut self, n: usize) {
        self.max_sweeps = n.max(1);
    }

    /// Changes the step size (the φ-functions are rebuilt at the next step; nothing is rebuilt
    /// if it is equal).
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`] unless `h` is finite and > 0.
    pub fn set_step_size(&mut self, h: S) -> Result<()> {
        check_step(h)?;
        if h != self.h {
            self.maps = None;
            self.h = h;
            self.previous_valid = false;
        }
        Ok(())
    }

    /// One step of size [`GenericStepper::step_size`] from `y` (overwritten with the new
    /// state); returns the sweeps it took.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] for a `y` of the wrong length; [`Error::NonFinite`] for a
    /// `y` with NaN or infinite entries; [`Error::NoConvergence`] if
    /// the stages do not converge within the sweeps allowed; [`Error::Overflow`] if they
    /// become non-finite. `y` is unchanged on error.
    pub fn step(&mut self, y: &mut [S]) -> Result<usize> {
        let (d, r, s) = (self.d, self.tables.r, self.tables.s);
        if y.len() != d {
            return Err(Error::DimensionMismatch {
                what: "y",
                expected: d,
                found: y.len(),
            });
        }
        if y.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("the state y"));
        }
        if self.maps.is_none() {
            self.maps = Some(StepMaps::new(&self.linear, self.h, &self.tables));
        }
        let maps = self.maps.as_ref().expect("built above");
        for (i, p) in maps.stage_propagators.iter().enumerate() {
            let start = &mut self.starts[i * d..(i + 1) * d];
            start.fill(S::zero());
            p.apply_add(y, start);
        }
        if self.previous_valid {
            // The previous step's continuous solution at this step's nodes (the sweeps below
            // decide convergence; a wrong prediction only costs sweeps).
            for i in 0..s {
                let out = &mut self.stages[i * d..(i + 1) * d];
                out.fill(S::zero());
                maps.predictor_propagators[i].apply_add(&self.previous_start, out);
                for j in 0..r {
                    maps.predictor_kernels[i * r + j]
                        .apply_add(&self.previous_moments[j * d..(j + 1) * d], out);
                }
            }
            if self.stages.iter().any(|v| !v.is_finite()) {
                self.stages.copy_from_slice(&self.starts);
            }
        } else {
            self.stages.copy_from_slice(&self.starts);
        }
        self.previous_valid = false;
        let mut previous = f64::INFINITY;
        let mut converged = false;
        let mut sweeps = 0;
        let mut residual = f64::NAN;
        while sweeps < self.max_sweeps {
            sweeps += 1;
            for (yi, gi) in self.stages.chunks_exact(d).zip(self.g.chunks_exact_mut(d)) {
                self.system.nonlinear(yi, gi);
            }
            self.moments.fill(S::zero());
            for j in 0..r {
                let lj = &mut self.moments[j * d..(j + 1) * d];
                for (i, gi) in self.g.chunks_exact(d).enumerate() {
                    let w = self.tables.lw[j * s + i];
                    for (l, &v) in lj.iter_mut().zip(gi) {
                        *l += w * v;
                    }
                }
            }
            self.next.copy_from_slice(&self.starts);
            for i in 0..s {
                let out = &mut self.next[i * d..(i + 1) * d];
                for j in 0..r {
                    maps.stage_kernels[i * r + j].apply_add(&self.moments[j * d..(j + 1) * d], out);
                }
            }
            let mut delta = 0.0f64;
            let mut scale = 0.0f64;
            for (n, o) in self.next.iter().zip(&self.stages) {
                delta = delta.max((*n - *o).abs().to_f64());
                scale = scale.max(n.abs().to_f64());
            }
            std::mem::swap(&mut self.next, &mut self.stages);
            if !delta.is_finite() || !scale.is_finite() {
                self.last_sweeps = sweeps;
                return Err(Error::Overflow("the stage values"));
            }
            let unit = S::EPSILON * scale.max(f64::MIN_POSITIVE);
            residual = delta / scale.max(f64::MIN_POSITIVE);
            if delta <= CONVERGED_UNITS * unit
                || (delta > 0.5 * previous && delta <= ROUNDOFF_FLOOR * unit)
            {
                converged = true;
                break;
            }
            previous = delta;
        }
        self.last_sweeps = sweeps;
        if !converged {
            return Err(Error::NoConvergence {
                sweeps,
                residual,
                tolerance: CONVERGED_UNITS * S::EPSILON,
            });
        }
        // y₁ from the moments of the last sweep.
        let out = &mut self.next[..d];
        out.fill(S::zero());
        maps.propagator.apply_add(y, out);
        for j in 0..r {
            maps.kernels[j].apply_add(&self.moments[j * d..(j + 1) * d], out);
        }
        if out.iter().any(|v| !v.is_finite()) {
            return Err(Error::Overflow("the new state"));
        }
        self.previous_start.copy_from_slice(y);
        self.previous_moments.copy_from_slice(&self.moments);
        self.previous_valid = true;
        y.copy_from_slice(&self.next[..d]);
        Ok(sweeps)
    }

    /// Integrates from `t0` to `t_end` (≥ t0), overwriting `y`; `observe(n, t, y)` sees the
    /// state after every step (and at t0 with n = 0).
    ///
    /// The grid is `t0 + n h` with `h` the stepper's step size, ending exactly at `t_end`: when
    /// `(t_end − t0)/h` is within 1e−9 of an integer N, the step becomes `(t_end − t0)/N`
    /// (computed in `S`); otherwise the last step is shortened. The report gives both sizes; the
    /// stepper is left with the regular one.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for `t_end < t0` or non-finite times; a failed step as
    /// [`Error::AtStep`] (the state is that of the step before).
    pub fn integrate(
        &mut self,
        t0: S,
        t_end: S,
        y: &mut [S],
        mut observe: impl FnMut(usize, S, &[S]),
    ) -> Result<GenericReport<S>> {
        if !(t0.is_finite() && t_end.is_finite()) || t_end < t0 {
            return Err(Error::InvalidParameter(format!(
                "the span [{t0}, {t_end}] must be finite and ordered"
            )));
        }
        let span = t_end - t0;
        let ratio = span.to_f64() / self.h.to_f64();
        let nearest = ratio.round();
        let (steps, h, last) = if span == S::zero() {
            (0, self.h, None)
        } else if nearest >= 1.0 && (ratio - nearest).abs() <= 1e-9 * nearest {
            let h = span / S::from_f64(nearest);
            (nearest as usize, h, Some(h))
        } else {
            // At least one step: a span shorter than h is one step of its length.
            let n = ratio.ceil().max(1.0);
            let last = span - self.h * S::from_f64(n - 1.0);
            (n as usize, self.h, Some(last))
        };
        self.set_step_size(h)?;
        let energy_start = self.system.energy(y);
        let mut max_energy_error = energy_start.map(|_| 0.0f64);
        let mut report = GenericReport {
            steps: 0,
            h,
            h_last: last,
            t_end: t0,
            sweeps: 0,
            max_sweeps: 0,
            g_evals: 0,
            energy_start,
            energy_end: energy_start,
            max_energy_error: None,
        };
        observe(0, t0, y);
        for n in 1..=steps {
            if n == steps {
                if let Some(l) = last {
                    self.set_step_size(l)?;
                }
            }
            let step_size = self.h.to_f64();
            let sweeps = self.step(y).map_err(|e| Error::AtStep {
                step: n,
                t: report.t_end.to_f64(),
                h: step_size,
                source: Box::new(e),
            })?;
            report.steps = n;
            report.sweeps += sweeps;
            report.max_sweeps = report.max_sweeps.max(sweeps);
            report.g_evals += sweeps * self.tables.s;
            report.t_end = if n == steps {
                t_end
            } else {
                t0 + h * S::from_f64(n as f64)
            };
            if let (Some(h0), Some(err)) = (energy_start, max_energy_error.as_mut()) {
                if let Some(hn) = self.system.energy(y) {
                    let diff = (hn - h0).abs();
                    let rel = if h0.to_f64() == 0.0 {
                        diff
                    } else {
                        diff / h0.abs()
                    };
                    *err = err.max(rel.to_f64());
                    report.energy_end = Some(hn);
                }
            }
            observe(n, report.t_end, y);
        }
        // The regular step size stays for a next call (the maps are rebuilt only if a step
        // needs them).
        self.set_step_size(h)?;
        report.max_energy_error = max_energy_error;
        Ok(report)
    }
}

fn check_step<S: Real>(h: S) -> Result<()> {
    if !(h.is_finite() && h > S::zero()) {
        return Err(Error::InvalidStepSize(h.to_f64()));
    }
    Ok(())
}
