//! The extrapolating predictor (`Predictor::Extrapolate`): it changes where the stage iteration
//! starts, not the fixed point, so the steps agree with the y₀ start up to the solver tolerance,
//! it needs fewer sweeps, and it is used only when the step continues the previous one.

use ecr::problems::{Duffing, Fpu, Nls};
use ecr_runtime::second_order::TcStepper;
use ecr_runtime::stepper::{EcStepper, Predictor, SolverSettings};
use ecr_runtime::system::System;

fn settings(predictor: Predictor) -> SolverSettings {
    SolverSettings {
        predictor,
        ..SolverSettings::default()
    }
}

fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(1.0f64, |m, x| m.max(x.abs()));
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
        / scale
}

/// Runs `n` steps with each predictor; returns (max relative difference of the states over the
/// run, total sweeps with y₀ start, total sweeps with the predictor).
fn compare_ec<S: System + Clone>(
    sys: S,
    r: usize,
    h: f64,
    y0: &[f64],
    n: usize,
) -> (f64, usize, usize) {
    let mut a = EcStepper::with_nodes(sys.clone(), r, r, h, settings(Predictor::Constant)).unwrap();
    let mut b = EcStepper::with_nodes(sys, r, r, h, settings(Predictor::Extrapolate)).unwrap();
    let (mut ya, mut yb) = (y0.to_vec(), y0.to_vec());
    let (mut sa, mut sb, mut worst) = (0, 0, 0.0f64);
    for _ in 0..n {
        sa += a.step(&mut ya).unwrap().sweeps;
        sb += b.step(&mut yb).unwrap().sweeps;
        worst = worst.max(rel_diff(&yb, &ya));
    }
    (worst, sa, sb)
}

#[test]
fn same_steps_fewer_sweeps_ec() {
    let d = Duffing::new(20.0, 0.07).unwrap();
    let nls = Nls::new(64).unwrap();
    let cases: Vec<(&str, f64, usize, usize)> = vec![
        {
            let (e, a, b) = compare_ec(d.system().unwrap(), 3, 0.05, &d.initial_value(), 400);
            ("Duffing ω = 20, r = 3, h = 0.05", e, a, b)
        },
        {
            let (e, a, b) = compare_ec(nls.system().unwrap(), 2, 0.01, &nls.initial_value(), 200);
            ("NLS N = 64, r = 2, h = 0.01", e, a, b)
        },
    ];
    for (what, diff, constant, extrapolated) in cases {
        println!("{what}: max relative difference {diff:.2e}; sweeps {constant} → {extrapolated}");
        // Both iterate to the same fixed point to ≤ 1e-15 per step; the difference is
        // round-off carried along a few hundred steps of a (weakly) unstable flow.
        assert!(diff <= 1e-12, "{what}: {diff:e}");
        assert!(
            (extrapolated as f64) < 0.85 * constant as f64,
            "{what}: {extrapolated} sweeps with the predictor vs {constant}"
        );
    }
}

#[test]
fn predictor_is_used_only_when_continuing_the_previous_step() {
    let d = Duffing::new(5.0, 0.07).unwrap();
    let y0 = d.initial_value();
    let h = 0.05;
    let mut b = EcStepper::with_nodes(
        d.system().unwrap(),
        2,
        2,
        h,
        settings(Predictor::Extrapolate),
    )
    .unwrap();
    let mut y = y0.clone();
    b.step(&mut y).unwrap();
    // A different state: the step must be exactly that of a fresh stepper (y₀ start).
    let mut other = vec![y[0] + 1e-3, y[1]];
    let mut fresh =
        EcStepper::with_nodes(d.system().unwrap(), 2, 2, h, settings(Predictor::Constant)).unwrap();
    let mut expect = other.clone();
    let rb = b.step(&mut other).unwrap();
    let rf = fresh.step(&mut expect).unwrap();
    assert_eq!(
        other, expect,
        "state changed between steps: no extrapolation"
    );
    assert_eq!(rb.sweeps, rf.sweeps);
    // Continuing: fewer sweeps than the fresh start from the same state.
    let mut cont = other.clone();
    let mut again = other.clone();
    let rc = b.step(&mut cont).unwrap();
    let ra = fresh.step(&mut again).unwrap();
    assert!(rc.sweeps < ra.sweeps, "{} vs {}", rc.sweeps, ra.sweeps);
    // A new step size drops the previous step (its moments belong to the old h).
    b.set_step_size(0.025).unwrap();
    let mut fresh2 = EcStepper::with_nodes(
        d.system().unwrap(),
        2,
        2,
        0.025,
        settings(Predictor::Constant),
    )
    .unwrap();
    let (mut y1, mut y2) = (cont.clone(), cont.clone());
    b.step(&mut y1).unwrap();
    fresh2.step(&mut y2).unwrap();
    assert_eq!(y1, y2, "after set_step_size: no extrapolation");
}

#[test]
fn same_steps_fewer_sweeps_tc() {
    let fpu = Fpu::new(3, 50.0).unwrap();
    let (q0, p0) = fpu.initial_value();
    let h = 0.02;
    let mut a = TcStepper::with_nodes(
        fpu.system().unwrap(),
        3,
        3,
        h,
        settings(Predictor::Constant),
    )
    .unwrap();
    let mut b = TcStepper::with_nodes(
        fpu.system().unwrap(),
        3,
        3,
        h,
        settings(Predictor::Extrapolate),
    )
    .unwrap();
    let (mut qa, mut pa, mut qb, mut pb) = (q0.clone(), p0.clone(), q0.clone(), p0.clone());
    let (mut sa, mut sb, mut worst) = (0, 0, 0.0f64);
    for _ in 0..500 {
        sa += a.step(&mut qa, &mut pa).unwrap().sweeps;
        sb += b.step(&mut qb, &mut pb).unwrap().sweeps;
        worst = worst.max(rel_diff(&qb, &qa)).max(rel_diff(&pb, &pa));
    }
    println!("FPU TC3P h = {h}: max relative difference {worst:.2e}; sweeps {sa} → {sb}");
    assert!(worst <= 1e-12, "{worst:e}");
    assert!((sb as f64) < 0.85 * sa as f64, "{sb} vs {sa}");
}
