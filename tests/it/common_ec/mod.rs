//! Shared harness: the paper's problems as systems, error measurement and order fitting.
#![allow(dead_code)]

use ecr::problems::{Duffing, Wind};
use ecr_runtime::integrate::{IntegrateOptions, integrate};
use ecr_runtime::operator::Dense;
use ecr_runtime::stepper::{EcStepper, SolverSettings};
use ecr_runtime::system::System;

/// Duffing as a system (dense 2 × 2 linear part).
pub fn duffing_system(p: Duffing) -> impl System<Op = Dense> {
    p.system().expect("valid Duffing parameters")
}

/// Wind-induced oscillation as a system.
pub fn wind_system(p: Wind) -> impl System<Op = Dense> {
    p.system().expect("valid wind parameters")
}

/// Runs ECrP(r, s) with step h from t = 0 to t_end, returning the final state.
pub fn solve<S: System>(sys: S, r: usize, s: usize, h: f64, y0: &[f64], t_end: f64) -> Vec<f64> {
    let mut st = EcStepper::with_nodes(sys, r, s, h, SolverSettings::default()).unwrap();
    let mut y = y0.to_vec();
    integrate(
        &mut st,
        0.0,
        t_end,
        &mut y,
        IntegrateOptions {
            energy_every: 0,
            observe_every: 0,
        },
        |_, _, _| {},
    )
    .unwrap();
    y
}

pub fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// Least-squares slope of log(err) against log(h) over the points with err in (floor, ceil).
pub fn fitted_order(hs: &[f64], errs: &[f64], floor: f64, ceil: f64) -> (f64, usize) {
    let pts: Vec<(f64, f64)> = hs
        .iter()
        .zip(errs)
        .filter(|&(_, &e)| e > floor && e < ceil)
        .map(|(&h, &e)| (h.ln(), e.ln()))
        .collect();
    (slope(&pts), pts.len())
}

/// Least-squares slope of y against x over the points (x, y).
pub fn slope(pts: &[(f64, f64)]) -> f64 {
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    sxy / sxx
}

/// The asymptotic order: least-squares slope of log(err) vs log(h) over the `k` smallest step
/// sizes whose error is above the round-off floor of their run, 30·N·ε·scale (N = T/h steps;
/// rounding accumulates at most linearly, and the factor 30 keeps its scatter out of the fit).
/// Returns (order, points used, first h used).
pub fn asymptotic_order(
    hs: &[f64],
    errs: &[f64],
    t_end: f64,
    scale: f64,
    k: usize,
) -> (f64, usize, f64) {
    let mut pts: Vec<(f64, f64)> = hs
        .iter()
        .zip(errs)
        .filter(|&(&h, &e)| e > 30.0 * (t_end / h) * f64::EPSILON * scale)
        .map(|(&h, &e)| (h, e))
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    pts.truncate(k);
    let (hs, es): (Vec<f64>, Vec<f64>) = pts.iter().copied().unzip();
    let (o, n) = fitted_order(&hs, &es, 0.0, f64::INFINITY);
    (o, n, hs.last().copied().unwrap_or(f64::NAN))
}
