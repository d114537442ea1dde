//! Long runs (issue: numerical stability at the extremes): the energy of ECrP over many steps
//! of Duffing (ω = 5, k = 0.07) and of the conservative wind problem, with the fitted drift per
//! step and the CPU time.
//!
//! The method's own energy error is bounded (O(h^{2r}), oscillating); what grows linearly is
//! round-off that repeats every step. The drift is the least-squares slope of the relative
//! energy error (sampled every 1000 steps) against the step number.
//!
//! Run: `cargo run --release --example long_run -- [STEPS] [R] [H] [TOL]` (defaults 1e7, 3,
//! 0.01 and the stage solver's default tolerance; 10–20 s per problem at 1e7 steps).

use ecr::problems::{Duffing, Wind};
use ecr::runtime::integrate::{IntegrateOptions, integrate};
use ecr::runtime::stepper::{EcStepper, SolverSettings};
use ecr::runtime::system::System;
use std::time::Instant;

/// What to run: ECrP with r, h, the number of steps and the solver settings.
struct Config {
    r: usize,
    h: f64,
    steps: usize,
    settings: SolverSettings,
}

/// Runs the configured steps of ECrP and prints the energy statistics.
fn run<S: System>(
    label: &str,
    sys: S,
    y0: Vec<f64>,
    energy: impl Fn(&[f64]) -> f64,
    cfg: &Config,
) -> Result<(), ecr::runtime::Error> {
    let Config {
        r,
        h,
        steps,
        settings,
    } = *cfg;
    let mut st = EcStepper::with_nodes(sys, r, r, h, settings)?;
    let mut y = y0;
    let h0 = energy(&y);
    let mut samples: Vec<(f64, f64)> = Vec::new();
    let opts = IntegrateOptions {
        energy_every: 0,
        observe_every: 1000,
    };
    let start = Instant::now();
    let rep = integrate(&mut st, 0.0, steps as f64 * h, &mut y, opts, |t, y, _| {
        samples.push(((t / h).round(), (energy(y) - h0) / h0.abs()))
    })?;
    let cpu = start.elapsed().as_secs_f64();
    let n = samples.len() as f64;
    let (mx, my) = (
        samples.iter().map(|s| s.0).sum::<f64>() / n,
        samples.iter().map(|s| s.1).sum::<f64>() / n,
    );
    let sxy: f64 = samples.iter().map(|s| (s.0 - mx) * (s.1 - my)).sum();
    let sxx: f64 = samples.iter().map(|s| (s.0 - mx).powi(2)).sum();
    let drift = sxy / sxx;
    let max = samples.iter().fold(0.0f64, |m, s| m.max(s.1.abs()));
    let tenth = samples.len() / 10;
    let mean = |s: &[(f64, f64)]| s.iter().map(|v| v.1).sum::<f64>() / s.len() as f64;
    println!(
        "| {label} | {r} | {h} | {} | {max:.2e} | {:.2e} | {:.2e} | {drift:.2e} | {:.2e} | {cpu:.1} | {:.0} |",
        rep.steps,
        mean(&samples[..tenth]),
        mean(&samples[samples.len() - tenth..]),
        drift * rep.steps as f64,
        cpu / rep.steps as f64 * 1e9,
    );
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let steps: usize = match args.first() {
        Some(s) => s.parse::<f64>()? as usize,
        None => 10_000_000,
    };
    let r: usize = args.get(1).map_or(Ok(3), |s| s.parse())?;
    let h: f64 = args.get(2).map_or(Ok(0.01), |s| s.parse())?;
    let settings = SolverSettings {
        tolerance: args
            .get(3)
            .map_or(Ok(SolverSettings::default().tolerance), |s| s.parse())?,
        ..SolverSettings::default()
    };
    let cfg = Config {
        r,
        h,
        steps,
        settings,
    };
    println!(
        "| problem | r | h | steps | max rel. energy error | mean, first tenth | mean, last tenth | drift per step | drift × steps | CPU s | ns per step |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let d = Duffing::default();
    let dd = d.clone();
    run(
        "Duffing ω = 5, k = 0.07",
        d.system()?,
        d.initial_value(),
        move |y| dd.energy(y),
        &cfg,
    )?;
    let w = Wind::conservative();
    let ww = w;
    run(
        "wind θ = π/2",
        w.system()?,
        w.initial_value(),
        move |y| ww.energy(y),
        &cfg,
    )?;
    Ok(())
}
