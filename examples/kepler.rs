//! Kepler's problem at eccentricity e = 0.99: which tool fits.
//!
//! The orbit passes the centre at distance 1 − e = 0.01 with speed 14, once per period 2π,
//! and spends the rest of the period far out, slowly. ECrP keeps its step size constant (for
//! its long-time energy behaviour, docs/solve.md), so the pericentre sets the step for the
//! whole orbit: at a low order that takes a great many steps. `solve` with a tolerance picks
//! the order and the step for the accuracy asked for and verifies the answer, or returns
//! `SolveError::Unverified` saying why. (For many periods of an orbit this eccentric, a time
//! transformation that slows the clock near the centre, or an adaptive-step code, fits
//! better than any constant step.) Errors are against the exact solution from Kepler's
//! equation E − e sin E = t.
//!
//! `cargo run --release --example kepler`
use ecr::prelude::*;
use std::f64::consts::PI;
use std::time::Instant;

/// Eccentricity.
const E: f64 = 0.99;
/// Time span: two periods.
const T: f64 = 4.0 * PI;

/// The exact state (q₁, q₂, p₁, p₂) at time t of the orbit with semi-major axis 1 that starts
/// at the pericentre (1 − e, 0): E − e sin E = t solved by bisection (the left side increases
/// in E), then one Newton step.
fn exact(e: f64, t: f64) -> [f64; 4] {
    let m = t.rem_euclid(2.0 * PI);
    let f = |x: f64| x - e * x.sin() - m;
    let (mut lo, mut hi) = (0.0, 2.0 * PI);
    for _ in 0..64 {
        let mid = 0.5 * (lo + hi);
        if f(mid) < 0.0 { lo = mid } else { hi = mid }
    }
    let x = 0.5 * (lo + hi);
    let x = x - f(x) / (1.0 - e * x.cos());
    let (s, c) = x.sin_cos();
    let b = (1.0 - e * e).sqrt();
    let rate = 1.0 / (1.0 - e * c); // dE/dt
    [c - e, b * s, -s * rate, b * c * rate]
}

fn max_error(y: &[f64], t: f64) -> f64 {
    let z = exact(E, t);
    y.iter()
        .zip(z)
        .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()))
}

fn main() -> Result<()> {
    // y = (q, p), H = ½|p|² − 1/|q|: y' = (p, −q/|q|³), no linear part (`Zero`).
    let g = |y: &[f64], out: &mut [f64]| {
        let r3 = (y[0] * y[0] + y[1] * y[1]).powf(1.5);
        (out[0], out[1], out[2], out[3]) = (y[2], y[3], -y[0] / r3, -y[1] / r3);
    };
    let energy = |y: &[f64]| 0.5 * (y[2] * y[2] + y[3] * y[3]) - 1.0 / y[0].hypot(y[1]);
    let system = Semilinear::with_energy(Zero::new(4), g, energy);
    let problem = Problem::new(system, exact(E, 0.0), (0.0, T))?;

    println!("Kepler, e = {E}, two periods (T = 4π); error = max |y(T) − exact|");
    println!(
        "{:<28} {:>12} {:>10} {:>10} {:>8}",
        "", "g-evals", "error", "|ΔH|/|H|", "seconds"
    );
    let row = |name: &str, sol: &Solution<_>, seconds: f64| {
        let y = sol.last().expect("the solution has a last state");
        println!(
            "{name:<28} {:>12} {:>10.1e} {:>10.1e} {seconds:>8.3}",
            sol.stats.total_g_evals(),
            max_error(y, T),
            sol.energy_error().unwrap_or(f64::NAN),
        );
    };

    // A fixed step: the step the pericentre needs, everywhere.
    for steps in [20_000, 80_000, 320_000] {
        let start = Instant::now();
        let sol = problem.solve(&Options::fixed(3, T / steps as f64))?;
        row(
            &format!("fixed EC3P, {steps} steps"),
            &sol,
            start.elapsed().as_secs_f64(),
        );
    }

    // A tolerance: the order and the step chosen, the answer verified.
    for tol in [1e-6, 1e-8] {
        let start = Instant::now();
        match problem.solve(&Options::tolerance(tol)) {
            Ok(sol) => {
                let name = format!("solve, tolerance {tol:.0e}");
                row(&name, &sol, start.elapsed().as_secs_f64());
                let (h_min, h_max) = sol
                    .segments
                    .iter()
                    .fold((f64::INFINITY, 0.0_f64), |(lo, hi), s| {
                        (lo.min(s.h), hi.max(s.h))
                    });
                println!(
                    "{:<28} (EC{}P, h = {h_min:.1e} to {h_max:.1e}, {} steps)",
                    "", sol.r, sol.stats.steps
                );
            }
            // Honest failure: the best answer it has, and why it is not verified.
            Err(SolveError::Unverified { reason, solution }) => {
                let name = format!("solve {tol:.0e} (unverified)");
                let y = solution.last().expect("a best solution has a last state");
                println!(
                    "{name:<28} {reason}; error {:.1e}",
                    max_error(y, solution.t[solution.t.len() - 1])
                );
            }
            Err(e) => return Err(e.into()),
        }
    }
    Ok(())
}
