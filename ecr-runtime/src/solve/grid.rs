//! The step grid of a stretch of the runs.

use super::estimate::at_most;
use super::run::{Grid, MEET};
use crate::error::{Error, Result};

/// The step grid of a stretch from `a` to `end` with a step close to `h` (not larger), so
/// that the stretch is a whole number of blocks of [`MEET`] steps (where all three runs
/// meet) and, with evenly spaced output times (spacing `quantum`), every output time is the
/// end of a block.
pub(super) fn fit_grid(
    h: f64,
    a: f64,
    end: f64,
    quantum: Option<f64>,
    max_steps: usize,
) -> Result<Grid> {
    let span = end - a;
    let block = MEET as f64;
    let (h, n_end) = match quantum {
        Some(q) if ((span / q) - (span / q).round()).abs() < 1e-9 && q > 0.0 => {
            let m = (q / (block * h)).ceil().max(1.0);
            (q / (block * m), block * m * (span / q).round())
        }
        _ => {
            let m = (span / (block * h)).ceil().max(1.0);
            (span / (block * m), block * m)
        }
    };
    if !at_most(n_end, max_steps as f64) || !h.is_finite() || h <= 0.0 {
        return Err(Error::InvalidInput(format!(
            "the run needs {n_end:.0} steps of h = {h:.3e} over [{a:?}, {end:?}], more than \
             max_steps = {max_steps}"
        )));
    }
    Ok(Grid {
        a,
        h,
        n_end: n_end as usize,
        end,
    })
}

/// The spacing of evenly spaced output times that start and end on multiples of it from
/// t₀ (so that a grid can pass through all of them), if they are.
pub(super) fn quantum(t_eval: Option<&[f64]>, t0: f64, t_end: f64) -> Option<f64> {
    let ts = t_eval.filter(|ts| ts.len() >= 2)?;
    let m = ts.len() - 1;
    let delta = (ts[m] - ts[0]) / m as f64;
    if at_most(delta, 0.0) || delta.is_nan() {
        return None;
    }
    let even = ts
        .iter()
        .enumerate()
        .all(|(i, &t)| (t - (ts[0] + i as f64 * delta)).abs() <= 1e-12 * delta.max(t.abs()));
    let on = |x: f64| (x / delta - (x / delta).round()).abs() < 1e-9;
    (even && on(ts[0] - t0) && on(t_end - t0)).then_some(delta)
}
