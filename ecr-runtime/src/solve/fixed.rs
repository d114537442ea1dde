//! A fixed method: ECrP with a fixed step, no check and no estimate.

use super::between::Trail;
use super::record::{Observer, Record};
use super::runs::{Cost, Runs};
use super::window::{Ctx, GridPoint, State, StepFailure, advance, keep, start_outputs};
use crate::error::{Error, Result};

/// ECrP with a fixed step (no check, no estimate): `full` steps of h and, if the plan says so,
/// a last one of another size; the observer sees every step at once.
pub(super) fn fixed(
    ctx: &Ctx<'_>,
    runs: &mut dyn Runs,
    h: f64,
    plan: crate::integrate::StepPlan,
    observer: &mut Observer<'_>,
) -> Result<Record> {
    const CHUNK: usize = 1024;
    let options = ctx.options;
    let mut record = Record::new(ctx.t0, h);
    let mut ev_prev = options
        .events
        .iter()
        .enumerate()
        .map(|(k, e)| e.value(k, ctx.t0, ctx.y0))
        .collect::<Result<Vec<_>>>()?;
    let mut t_eval_next = 0;
    start_outputs(ctx, &mut record, &mut t_eval_next)?;
    if options.dense {
        record.grid(ctx.t0, ctx.y0, ctx.y0)?;
    }
    // The last grid points, for the events' scan of each step (a fixed run's values between
    // grid points are its steps').
    let mut trail = (!options.events.is_empty()).then(|| {
        let mut trail = Trail::default();
        trail.push(ctx.t0, ctx.y0, ctx.y0);
        trail
    });
    let mut state = ctx.start();
    let chunk = if observer.is_some() { 1 } else { CHUNK };
    let total = plan.steps();
    while state.n < total && !record.ended() {
        let done = state.n;
        // A last step that differs from h only by the rounding of n·h against the span is a
        // step of h moved along the vector field by the difference: no bank for it.
        let rounding = plan.last.filter(|&l| {
            (l - h).abs()
                <= crate::integrate::StepPlan::TIME_ULPS
                    * 2.0
                    * f64::EPSILON
                    * ctx.t0.abs().max(ctx.t_end.abs())
        });
        let (steps, size, origin, end) = if done < plan.full_steps {
            let k = chunk.min(plan.full_steps - done);
            (
                k,
                h,
                (ctx.t0, 0.0, done),
                (done + k == total).then_some(ctx.t_end),
            )
        } else if rounding.is_some() {
            (1, h, (ctx.t0, 0.0, done), Some(ctx.t_end))
        } else {
            let last = plan.last.expect("the plan's last step");
            (1, last, (state.t, state.t_lo, 0), Some(ctx.t_end))
        };
        runs.set_step_size(size)?;
        let mut cost = Cost::default();
        let mut points = advance(ctx, runs, &state, origin, (steps, end), None, &mut cost)
            .map_err(|StepFailure { t, h, error }| Error::AtStep {
                step: done + 1,
                t,
                h,
                source: Box::new(error),
            })?;
        if let (Some(l), true) = (rounding, done >= plan.full_steps) {
            let last = points.last_mut().expect("one step");
            runs.drift(&mut last.answer, l - h)?;
        }
        record.cost.add(&cost);
        let start = GridPoint {
            t: state.t,
            t_lo: state.t_lo,
            answer: state.answer.clone(),
            check: state.check.clone(),
            est: 0.0,
        };
        if let Some(trail) = &mut trail {
            for q in &points {
                trail.push(q.t, &q.answer, &q.check);
            }
        }
        keep(
            ctx,
            runs,
            &mut record,
            &start,
            done,
            &points,
            &mut t_eval_next,
            &mut ev_prev,
            observer.is_some(),
            trail.as_mut(),
        )?;
        if let Some(trail) = &mut trail {
            trail.trim();
        }
        record.step_size_from(state.t, size);
        let last = points.last().expect("a chunk has a step");
        state = State {
            t: last.t,
            t_lo: last.t_lo,
            n: done + points.len(),
            worst: 0.0,
            answer: last.answer.clone(),
            check: last.check.clone(),
        };
        record.show(observer);
    }
    Ok(record)
}
