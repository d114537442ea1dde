//! Values between grid points, one rule for all who ask (`t_eval`, events, `Solution::at`):
//! the grid's Hermite interpolant where its own estimate serves ([`INTERP_MAX`]), else partial
//! steps of the runs from the grid point before; and the trail of the last grid points that
//! the interpolant reads.

use super::record::Point;
use super::runs::{Cost, Runs};
use super::value_steps::Seed;
use super::window::{Ctx, GridPoint};
use crate::error::{Error, Result};

/// The values of the runs at `t` between the grid point `base` (before t) and the next:
/// partial steps of both (the grid value itself where t is the grid point's time, moved along
/// the field where t is within the rounding of it).
#[allow(clippy::too_many_arguments)]
pub(super) fn between(
    ctx: &Ctx<'_>,
    runs: &mut dyn Runs,
    base: &GridPoint,
    n: usize,
    t: f64,
    trail: Option<&mut Trail>,
    source: Source<'_>,
    cost: &mut Cost,
) -> Result<Point> {
    between_into(ctx, runs, base, n, t, trail, source, None, cost)
}

/// [`between`], and the check's value at t into `check` where given (with [`Source::Steps`]:
/// the check's step, or the grid's check moved along the field where t is within the rounding
/// of the grid point's time).
#[allow(clippy::too_many_arguments)]
pub(super) fn between_into(
    ctx: &Ctx<'_>,
    runs: &mut dyn Runs,
    base: &GridPoint,
    n: usize,
    t: f64,
    trail: Option<&mut Trail>,
    source: Source<'_>,
    check: Option<&mut [f64]>,
    cost: &mut Cost,
) -> Result<Point> {
    let d = base.answer.len();
    let tolerance = (ctx.options.rtol, ctx.options.atol);
    let mut interp = None;
    if let Some(trail) = trail {
        if let Some(stencil) = trail.grid(d).stencil(t) {
            trail.slopes(stencil.range(), runs, cost)?;
            interp = Some((&*trail, stencil));
        }
    }
    let mut y = vec![0.0; d];
    let est = value_between(
        ValueAt {
            t,
            base: (base.t, &base.answer, &base.check, base.est),
            n,
            tolerance,
            unit: ctx.unit,
            verified: ctx.verified,
            source,
        },
        interp.map(|(trail, stencil)| {
            let (sa, sc) = trail.slopes_at(stencil.range());
            (trail.grid(d), stencil, sa, sc)
        }),
        &mut RunSteps(runs, cost),
        (&mut y, check),
    )?;
    Ok(Point { t, y, est })
}

/// Where a value between grid points comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Source<'a> {
    /// The interpolant where its estimate allows, else a step of each run (the one rule of
    /// [`value_between`]).
    Rule,
    /// A step of each run (one source for all the values of a search).
    Steps,
    /// A step of the answer alone, without an estimate (a search's trial values: only the
    /// value it stops at needs the check's).
    Answer,
    /// The answer's value given (a trial value of a search, where it stopped), and a step of
    /// the check for its estimate.
    Check(&'a [f64]),
}

/// Which runs a step to a value between grid points advances.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Which {
    Both,
    Answer,
    Check,
}

/// What a value between grid points is asked for: the time, the grid point before it (its
/// time, the answer's and the check's states and its estimate), the steps to it, the tolerance
/// and the round-off model's unit.
pub(super) struct ValueAt<'a> {
    pub(super) t: f64,
    pub(super) base: (f64, &'a [f64], &'a [f64], f64),
    pub(super) n: usize,
    pub(super) tolerance: (f64, f64),
    pub(super) unit: f64,
    /// A checked run (else the estimate is 0 and no interpolant is tried).
    pub(super) verified: bool,
    /// Where the value comes from (the interpolant, where it does not serve the value, still
    /// starts the steps' stage iterations).
    pub(super) source: Source<'a>,
}

/// A stencil of the grid and its slopes (answer's, check's at the stencil's points).
pub(super) type Interp<'g> = (
    super::interp::Grid<'g>,
    super::interp::Stencil,
    &'g [f64],
    &'g [f64],
);

/// How a value between grid points is reached where the interpolant does not serve.
pub(super) trait PartialSteps {
    /// `y` moved along the vector field by `dt` (a time within the rounding of a grid point's).
    ///
    /// # Errors
    /// [`Error::NonFinite`] if the field is not finite there.
    fn drift(&mut self, y: &mut [f64], dt: f64) -> Result<()>;
    /// One step of length `dt` of the answer's method from `from.0` into `out.0` and of the
    /// check's from `from.1` into `out.1`, or only those `which` names (what is not stepped
    /// may be left as anything), their stage iterations started from `seed` where given.
    ///
    /// # Errors
    /// What the steps report.
    fn partial(
        &mut self,
        from: (&[f64], &[f64]),
        dt: f64,
        out: (&mut [f64], &mut [f64]),
        seed: Option<Seed<'_>>,
        which: Which,
    ) -> Result<()>;
}

/// The run's own steppers for values between grid points, with the cost counted.
struct RunSteps<'r>(&'r mut dyn Runs, &'r mut Cost);

impl PartialSteps for RunSteps<'_> {
    fn drift(&mut self, y: &mut [f64], dt: f64) -> Result<()> {
        self.0.drift(y, dt)
    }
    fn partial(
        &mut self,
        from: (&[f64], &[f64]),
        dt: f64,
        out: (&mut [f64], &mut [f64]),
        seed: Option<Seed<'_>>,
        which: Which,
    ) -> Result<()> {
        self.0.partial(from, dt, out, seed, which, self.1)
    }
}

/// The one rule for a value between grid points, used by outputs (`t_eval`), events and
/// [`Solution::at`](super::Solution::at): the grid value where t is its time; the grid value
/// moved along the field (`drift`) where t is within the rounding of it; the interpolant of
/// the grid where its estimate is at most [`INTERP_MAX`] tolerances; else one partial step of
/// each run from the grid point ([`PartialSteps`]), whose difference is the estimate. The
/// value goes to `out.0` (and the check's, where it is stepped or moved, to `out.1` where
/// given); returns its estimate in tolerances.
pub(super) fn value_between(
    at: ValueAt<'_>,
    interp: Option<Interp<'_>>,
    steps: &mut dyn PartialSteps,
    (out, check_out): (&mut [f64], Option<&mut [f64]>),
) -> Result<f64> {
    let ValueAt {
        t,
        base: (t_base, answer, check, est),
        n,
        tolerance,
        unit,
        verified,
        source,
    } = at;
    let dt = t - t_base;
    out.copy_from_slice(answer);
    let mut check_out = check_out;
    if let Some(c) = check_out.as_deref_mut() {
        c.copy_from_slice(check);
    }
    if dt <= 0.0 {
        return Ok(est);
    }
    if dt < 4.0 * f64::MIN_POSITIVE
        || dt <= crate::integrate::StepPlan::TIME_ULPS * f64::EPSILON * t.abs()
    {
        steps.drift(out, dt)?;
        if let Some(c) = check_out {
            steps.drift(c, dt)?;
        }
        return Ok(est);
    }
    // The interpolant of the grid where its estimate holds (no step, no φ-bank); where it
    // does not, it still starts the stage iterations of the steps (fewer sweeps than from the
    // grid state).
    let interp = interp.filter(|_| verified);
    if let Some((grid, stencil, sa, sc)) = interp.as_ref().filter(|_| source == Source::Rule) {
        let e = grid.value(t, *stencil, sa, sc, tolerance, unit, n + 1, out);
        if e <= INTERP_MAX {
            return Ok(e);
        }
    }
    let seed = |nodes: &[f64], check: bool, out: &mut [f64]| {
        if let Some((grid, stencil, sa, sc)) = &interp {
            let times = nodes.iter().map(|&c| t_base + c * dt);
            grid.states_at(times, *stencil, (sa, sc), check, out);
        }
    };
    let mut yc = vec![0.0; out.len()];
    let seed: Option<Seed<'_>> = interp.is_some().then_some(&seed);
    let which = match source {
        Source::Rule | Source::Steps => Which::Both,
        Source::Answer => Which::Answer,
        Source::Check(_) => Which::Check,
    };
    steps.partial((answer, check), dt, (out, &mut yc), seed, which)?;
    if let Source::Check(given) = source {
        out.copy_from_slice(given);
    }
    if let Some(c) = check_out.filter(|_| which != Which::Answer) {
        c.copy_from_slice(&yc);
    }
    if !verified || which == Which::Answer {
        return Ok(0.0);
    }
    // The runs' difference, and the share of the tolerance their stage iterations stop at
    // (`between_settings`): an iteration error both runs share from like seeds would not show
    // in their difference.
    let e = super::runs::estimate(tolerance, unit, out, &yc, n + 1) + super::BETWEEN_SWEEP_SHARE;
    if e.is_nan() {
        return Err(Error::NonFinite(
            "the estimate of the error between grid points",
        ));
    }
    Ok(e)
}

/// A value between grid points takes the interpolant where its estimate is at most this many
/// tolerances (else one step of each method, whose own estimate is usually far smaller).
pub(super) const INTERP_MAX: f64 = 0.5;

/// The last grid points of the run (times, the answer's and the check's states), for the
/// interpolant of values between them.
#[derive(Default)]
pub(super) struct Trail {
    t: Vec<f64>,
    answer: Vec<f64>,
    check: Vec<f64>,
    /// The runs' slopes there, NaN until a stencil needs them.
    slope_answer: Vec<f64>,
    slope_check: Vec<f64>,
    /// The runs' [`stiffness`](super::runs::stiffness), taken with the first slopes.
    stiffness: Vec<f64>,
    /// The last event scans' interpolation weights, for each of the two geometries.
    scan_weights: [super::interp::ScanWeights; 2],
}

impl Trail {
    /// Points kept besides a window's: an interpolant's stencil and its check before it.
    const KEEP: usize = super::interp::POINTS + 1;

    pub(super) fn push(&mut self, t: f64, answer: &[f64], check: &[f64]) {
        self.t.push(t);
        self.answer.extend_from_slice(answer);
        self.check.extend_from_slice(check);
        let d = answer.len();
        self.slope_answer
            .resize(self.slope_answer.len() + d, f64::NAN);
        self.slope_check
            .resize(self.slope_check.len() + d, f64::NAN);
    }

    /// Evaluates the slopes of the points in `range` not evaluated yet.
    ///
    /// # Errors
    /// What [`Runs::slope`] reports.
    pub(super) fn slopes(
        &mut self,
        range: std::ops::Range<usize>,
        runs: &mut dyn Runs,
        cost: &mut Cost,
    ) -> Result<()> {
        if self.stiffness.is_empty() {
            self.stiffness = runs.stiffness().to_vec();
        }
        let d = self.answer.len() / self.t.len().max(1);
        for j in range {
            let at = j * d..(j + 1) * d;
            if self.slope_answer[at.start].is_nan() {
                runs.slope(
                    &self.answer[at.clone()],
                    &mut self.slope_answer[at.clone()],
                    cost,
                )?;
            }
            if self.slope_check[at.start].is_nan() {
                runs.slope(&self.check[at.clone()], &mut self.slope_check[at], cost)?;
            }
        }
        Ok(())
    }

    /// The answer's interpolant at `times` (inside the grid's interval around `t`) into `out`
    /// (`d` numbers per time), for a scan of the event functions inside a step: on the grid
    /// points [`Grid::scan_range`](super::interp::Grid::scan_range) names, with the answer's slopes there (one evaluation of g
    /// per point not evaluated yet). `false` where the trail has no interpolant there.
    ///
    /// # Errors
    /// What [`Runs::slope`] reports.
    pub(super) fn scan(
        &mut self,
        t: f64,
        times: &[f64],
        runs: &mut dyn Runs,
        cost: &mut Cost,
        out: &mut [f64],
    ) -> Result<bool> {
        let d = self.answer.len() / self.t.len().max(1);
        let Some(range) = self.grid(d).scan_range(t) else {
            return Ok(false);
        };
        if self.stiffness.is_empty() {
            self.stiffness = runs.stiffness().to_vec();
        }
        for j in range.clone() {
            let at = j * d..(j + 1) * d;
            if self.slope_answer[at.start].is_nan() {
                runs.slope(&self.answer[at.clone()], &mut self.slope_answer[at], cost)?;
            }
        }
        // The weights of the two geometries (t in the stencil's first interval, or in its
        // second at the grid's end).
        let slot = usize::from(t >= self.t[range.start + 1]);
        let mut weights = std::mem::take(&mut self.scan_weights[slot]);
        if !weights.fits(&self.grid(d), range.clone(), times) {
            self.grid(d)
                .scan_weights(range.clone(), times, &mut weights);
        }
        let slopes = &self.slope_answer[range.start * d..range.end * d];
        self.grid(d).answer_on(range, slopes, &weights, out);
        self.scan_weights[slot] = weights;
        Ok(true)
    }

    /// The slopes of the points in `range` (evaluated by [`Trail::slopes`]).
    pub(super) fn slopes_at(&self, range: std::ops::Range<usize>) -> (&[f64], &[f64]) {
        let d = self.answer.len() / self.t.len().max(1);
        let at = range.start * d..range.end * d;
        (&self.slope_answer[at.clone()], &self.slope_check[at])
    }

    /// The number of points held.
    pub(super) fn len(&self) -> usize {
        self.t.len()
    }

    /// Back to `len` points (the ones pushed after are dropped).
    pub(super) fn truncate(&mut self, len: usize) {
        let d = self.answer.len().checked_div(self.t.len()).unwrap_or(0);
        self.t.truncate(len);
        self.answer.truncate(len * d);
        self.check.truncate(len * d);
        self.slope_answer.truncate(len * d);
        self.slope_check.truncate(len * d);
    }

    /// Keeps only the last [`Trail::KEEP`] points.
    pub(super) fn trim(&mut self) {
        let n = self.t.len();
        if n > Self::KEEP {
            let d = self.answer.len() / n;
            let drop = n - Self::KEEP;
            self.t.drain(..drop);
            self.answer.drain(..drop * d);
            self.check.drain(..drop * d);
            self.slope_answer.drain(..drop * d);
            self.slope_check.drain(..drop * d);
        }
    }

    pub(super) fn grid(&self, d: usize) -> super::interp::Grid<'_> {
        super::interp::Grid {
            t: &self.t,
            answer: &self.answer,
            check: &self.check,
            d,
            stiffness: &self.stiffness,
        }
    }
}
