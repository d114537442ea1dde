//! Scaling of the cost of a step with the dimension: EC2P with the FFT (circulant) operator on
//! the 1D NLS, N = 2^7 … 2^16 (d = 2N), and on the 2D NLS, n × n up to 512 × 512 (d = 2n²).

use ecr::problems::{Nls, Nls2d};
use ecr_runtime::operator::{SkewGenerator, SkewPair};
use ecr_runtime::stepper::EcStepper;
use ecr_runtime::system::System;
use std::time::Instant;

/// Step size of every run (the paper's energy step for the NLS).
pub const H: f64 = 1.0 / 200.0;
/// Most steps per timed run (h · MAX_STEPS = 1).
pub const MAX_STEPS: usize = 200;
/// Order parameter: EC2P (order 4), s = r = 2.
pub const R: usize = 2;

/// One measured size.
#[derive(Clone, Debug)]
pub struct ScalingPoint {
    /// "1D" or "2D".
    pub case: &'static str,
    /// Grid, e.g. "N = 1024" or "512 × 512".
    pub grid: String,
    /// Dimension of y.
    pub d: usize,
    /// Steps per timed run.
    pub steps: usize,
    /// Median wall-clock seconds per step.
    pub seconds_per_step: f64,
    /// Fixed-point sweeps per step (mean over the timed runs).
    pub sweeps_per_step: f64,
    /// |H(y_end) − H(y_0)| / |H(y_0)| over every step taken.
    pub energy_error: f64,
    /// Seconds to build the stepper (φ-bank for h and the stage nodes).
    pub setup_seconds: f64,
}

/// Least-squares fit of log t = a + b log d.
#[derive(Clone, Debug)]
pub struct Fit {
    pub what: String,
    /// Exponent b of t ∝ d^b.
    pub exponent: f64,
    /// Exponent of t / (d log₂ d) against d: ≈ 0 where the cost is d log d.
    pub exponent_over_dlogd: f64,
    pub points: usize,
}

/// The whole study.
pub struct Scaling {
    pub points: Vec<ScalingPoint>,
    pub fits: Vec<Fit>,
    /// Repeats per point (median).
    pub repeats: usize,
    /// Minimum wall-clock seconds of one timed run.
    pub min_run: f64,
}

/// ½ pᵀCp + ½ qᵀCq + ½ Σ (p² + q²)², the NLS energy with the generator C of the skew pair.
fn nls_energy<C: SkewGenerator>(op: &SkewPair<C>, y: &[f64]) -> f64 {
    let m = y.len() / 2;
    let mut out = vec![0.0; m];
    let mut quad = 0.0;
    for half in y.chunks_exact(m) {
        op.generator().apply(half, &mut out);
        quad += half.iter().zip(&out).map(|(a, b)| a * b).sum::<f64>();
    }
    let (p, q) = y.split_at(m);
    let v: f64 = p.iter().zip(q).map(|(p, q)| (p * p + q * q).powi(2)).sum();
    0.5 * (quad + v)
}

fn err_s(e: ecr_runtime::Error) -> String {
    e.to_string()
}

/// Times EC2P on `sys` from `y0`: a warm-up step, then `repeats` runs of `steps` steps, the
/// number of steps chosen so that one run takes at least `min_run` seconds.
fn measure<C: SkewGenerator, S: System<Op = SkewPair<C>>>(
    case: &'static str,
    grid: String,
    sys: S,
    y0: Vec<f64>,
    repeats: usize,
    min_run: f64,
) -> Result<ScalingPoint, String> {
    let d = y0.len();
    let start = Instant::now();
    let mut stepper =
        EcStepper::with_nodes(sys, R, R, H, super::series::solver()).map_err(err_s)?;
    let setup_seconds = start.elapsed().as_secs_f64();
    let e0 = nls_energy(stepper.system().linear(), &y0);
    let mut y = y0;
    let t = Instant::now();
    stepper.step(&mut y).map_err(err_s)?;
    let first = t.elapsed().as_secs_f64().max(1e-9);
    // At most MAX_STEPS per run, so that every size simulates about the same interval (the
    // dynamics, and so the sweeps per step, change along a long run: the 2D focusing NLS with
    // this much mass develops a modulational instability within t ≈ 10).
    let steps = ((min_run / first).ceil() as usize).clamp(3, MAX_STEPS);
    let (mut times, mut sweeps) = (Vec::new(), 0usize);
    for _ in 0..repeats {
        let t = Instant::now();
        for _ in 0..steps {
            sweeps += stepper.step(&mut y).map_err(err_s)?.sweeps;
        }
        times.push(t.elapsed().as_secs_f64() / steps as f64);
    }
    times.sort_by(f64::total_cmp);
    if y.iter().any(|v| !v.is_finite()) {
        return Err(format!("{case} {grid}: the solution is not finite"));
    }
    let e1 = nls_energy(stepper.system().linear(), &y);
    Ok(ScalingPoint {
        case,
        grid,
        d,
        steps,
        seconds_per_step: times[times.len() / 2],
        sweeps_per_step: sweeps as f64 / (repeats * steps) as f64,
        energy_error: (e1 - e0).abs() / e0.abs(),
        setup_seconds,
    })
}

/// Slope of the least-squares line through (x, y).
pub fn slope(xy: &[(f64, f64)]) -> f64 {
    let n = xy.len() as f64;
    let (mx, my) = xy
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let sxy: f64 = xy.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xy.iter().map(|(x, _)| (x - mx) * (x - mx)).sum();
    sxy / sxx
}

fn fit(what: String, pts: &[&ScalingPoint]) -> Fit {
    let ln_d = |p: &ScalingPoint| (p.d as f64).ln();
    let raw: Vec<(f64, f64)> = pts
        .iter()
        .map(|p| (ln_d(p), p.seconds_per_step.ln()))
        .collect();
    let over: Vec<(f64, f64)> = pts
        .iter()
        .map(|p| {
            let d = p.d as f64;
            (ln_d(p), (p.seconds_per_step / (d * d.log2())).ln())
        })
        .collect();
    Fit {
        what,
        exponent: slope(&raw),
        exponent_over_dlogd: slope(&over),
        points: pts.len(),
    }
}

/// Runs the study: 1D N = 2^7 … 2^16 and 2D n = 32 … 512 (`quick`: 1D up to 2^10, 2D up to 64).
pub fn run(quick: bool, progress: &mut dyn FnMut(&str)) -> Result<Scaling, String> {
    let (repeats, min_run) = if quick { (1, 0.005) } else { (5, 0.3) };
    let (max_1d, max_2d) = if quick { (10, 6) } else { (16, 9) };
    let mut points = Vec::new();
    for k in 7..=max_1d {
        let n = 1usize << k;
        progress(&format!("scaling: 1D NLS N = {n}"));
        let nls = Nls::new(n).map_err(err_s)?;
        let sys = nls.system().map_err(err_s)?;
        points.push(measure(
            "1D",
            format!("N = {n}"),
            sys,
            nls.initial_value(),
            repeats,
            min_run,
        )?);
    }
    for k in 5..=max_2d {
        let n = 1usize << k;
        progress(&format!("scaling: 2D NLS {n} × {n}"));
        let nls = Nls2d::new(n).map_err(err_s)?;
        let sys = nls.system().map_err(err_s)?;
        points.push(measure(
            "2D",
            format!("{n} × {n}"),
            sys,
            nls.initial_value(),
            repeats,
            min_run,
        )?);
    }
    let one: Vec<&ScalingPoint> = points.iter().filter(|p| p.case == "1D").collect();
    let two: Vec<&ScalingPoint> = points.iter().filter(|p| p.case == "2D").collect();
    let mut fits = vec![
        fit("1D, every N".to_string(), &one),
        fit("2D, every n".to_string(), &two),
    ];
    // Small sizes are dominated by per-call overhead: fit the upper half of the 1D range too.
    let upper = &one[one.len() / 2..];
    if upper.len() >= 3 {
        fits.push(fit(format!("1D, N ≥ {}", upper[0].d / 2), upper));
    }
    Ok(Scaling {
        points,
        fits,
        repeats,
        min_run,
    })
}
