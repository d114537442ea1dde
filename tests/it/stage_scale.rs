//! The stopping rule's scale ([`StageScale`]): two decoupled oscillators, the second 1e−20
//! times the size of the first. In the global scale (‖ΔY‖∞ / max(1, ‖Y‖∞)) the small one's
//! updates are invisible, so its stages get only the sweeps the large one needs; per
//! component they converge in their own scale. And a component whose own rounding error is
//! O(1) in its own scale (computed from a cancellation of much larger numbers) still ends
//! the iteration, by round-off stagnation judged in the global scale.

use ecr::problems::Fpu;
use ecr_runtime::Error;
use ecr_runtime::operator::Dense;
use ecr_runtime::second_order::TcStepper;
use ecr_runtime::stepper::{EcStepper, SolverSettings, StageScale};
use ecr_runtime::system::Semilinear;
use nalgebra::DMatrix;

/// The size of the small oscillator.
const SMALL: f64 = 1e-20;
const OMEGA: f64 = 2.0;
/// Cubic stiffness of the large oscillator (weak: its sweeps contract fast) and of the small
/// one in its own scale (strong: slow contraction).
const K_LARGE: f64 = 0.001;
const K_SMALL: f64 = 10.0;
const H: f64 = 0.1;
const STEPS: usize = 10;

/// `q'' = −ω² q − k q³` as `(q, p)' = [[0, 1], [−ω², 0]] (q, p) + (0, −k q³)`, for each
/// oscillator on the diagonal of a 2n × 2n operator.
fn oscillators(n: usize) -> Dense {
    let mut a = DMatrix::zeros(2 * n, 2 * n);
    for i in 0..n {
        a[(2 * i, 2 * i + 1)] = 1.0;
        a[(2 * i + 1, 2 * i)] = -OMEGA * OMEGA;
    }
    Dense::new(a).unwrap()
}

fn per_component() -> SolverSettings {
    SolverSettings {
        scale: StageScale::PerComponent { atol: 1e-300 },
        ..SolverSettings::default()
    }
}

/// `STEPS` steps of the pair (large, small · 1e−20) and of the small oscillator alone in its
/// own scale (the reference), from (1, 0); the largest relative difference of the small
/// oscillator from the reference over the steps, and the sweeps of the pair.
fn small_oscillator_error(settings: SolverSettings) -> (f64, usize) {
    // z = 1e−20 w with w'' = −ω² w − K_SMALL w³: z'' = −ω² z − (K_SMALL / 1e−40) z³.
    let k_z = K_SMALL / (SMALL * SMALL);
    let pair = Semilinear::new(oscillators(2), move |y: &[f64], o: &mut [f64]| {
        o[0] = 0.0;
        o[1] = -K_LARGE * y[0] * y[0] * y[0];
        o[2] = 0.0;
        o[3] = -k_z * y[2] * y[2] * y[2];
    });
    let alone = Semilinear::new(oscillators(1), |y: &[f64], o: &mut [f64]| {
        o[0] = 0.0;
        o[1] = -K_SMALL * y[0] * y[0] * y[0];
    });
    let mut st = EcStepper::with_nodes(pair, 2, 2, H, settings).unwrap();
    let mut reference = EcStepper::with_nodes(alone, 2, 2, H, SolverSettings::default()).unwrap();
    let (mut y, mut w) = (vec![1.0, 0.0, SMALL, 0.0], vec![1.0, 0.0]);
    let (mut worst, mut sweeps) = (0.0_f64, 0);
    for _ in 0..STEPS {
        let rep = st.step(&mut y).unwrap();
        assert!(rep.converged);
        sweeps += rep.sweeps;
        reference.step(&mut w).unwrap();
        let norm = w[0].abs().max(w[1].abs());
        for (z, w) in y[2..].iter().zip(&w) {
            worst = worst.max((z / SMALL - w).abs() / norm);
        }
    }
    (worst, sweeps)
}

#[test]
fn a_component_of_size_1e_minus_20_converges_in_its_own_scale() {
    let (global, sweeps_global) = small_oscillator_error(SolverSettings::default());
    let (own, sweeps_own) = small_oscillator_error(per_component());
    println!(
        "small oscillator (1e-20), {STEPS} steps of h = {H}, relative to its own reference: \
         StageScale::Global {global:.2e} ({sweeps_global} sweeps), \
         PerComponent {{ atol: 1e-300 }} {own:.2e} ({sweeps_own} sweeps)"
    );
    assert!(own <= 1e-14, "per component: {own:e}");
    // The global rule stops when the large oscillator has converged.
    assert!(global >= 1e-9, "global: {global:e}");
}

#[test]
fn per_component_is_global_for_components_of_size_one() {
    // With atol = 1 and no component above 1 in size, the two measures are the same number:
    // the same steps, bit for bit.
    let sys = || {
        Semilinear::new(oscillators(1), |y: &[f64], o: &mut [f64]| {
            o[0] = 0.0;
            o[1] = -K_LARGE * y[0] * y[0] * y[0];
        })
    };
    let unit = SolverSettings {
        scale: StageScale::PerComponent { atol: 1.0 },
        ..SolverSettings::default()
    };
    let mut a = EcStepper::with_nodes(sys(), 3, 3, H, SolverSettings::default()).unwrap();
    let mut b = EcStepper::with_nodes(sys(), 3, 3, H, unit).unwrap();
    let (mut ya, mut yb) = (vec![0.5, 0.0], vec![0.5, 0.0]);
    for _ in 0..50 {
        assert_eq!(a.step(&mut ya).unwrap(), b.step(&mut yb).unwrap());
        assert_eq!(ya, yb);
    }
}

#[test]
fn a_component_made_of_rounding_noise_still_ends_the_iteration() {
    // y₂' = −y₂ + c(y₀), with c(q) = (q + 0.1)² − q² − 0.2 q − 0.01 = 0 exactly but computed
    // with rounding errors of ε (q + 0.1)²: y₂ is noise, O(1) in its own scale, and changes
    // whenever the last bits of q do. Per component with atol = 1e−300 its update never
    // falls to the tolerance; every step must still converge (by stagnation).
    let mut a = DMatrix::zeros(3, 3);
    a[(0, 1)] = 1.0;
    a[(1, 0)] = -OMEGA * OMEGA;
    a[(2, 2)] = -1.0;
    let sys = Semilinear::new(Dense::new(a).unwrap(), |y: &[f64], o: &mut [f64]| {
        let q = y[0];
        o[0] = 0.0;
        o[1] = -K_LARGE * q * q * q;
        o[2] = (q + 0.1) * (q + 0.1) - q * q - 0.2 * q - 0.01;
    });
    let mut st = EcStepper::with_nodes(sys, 2, 2, H, per_component()).unwrap();
    let mut y = vec![1.0, 0.0, 0.0];
    let (mut by_stagnation, mut sweeps, mut worst_residual) = (0, 0, 0.0_f64);
    for n in 0..200 {
        let rep = st.step(&mut y).unwrap_or_else(|e| panic!("step {n}: {e}"));
        assert!(rep.converged, "step {n}: {rep:?}");
        sweeps += rep.sweeps;
        worst_residual = worst_residual.max(rep.residual);
        if rep.residual > 1e-6 {
            by_stagnation += 1;
        }
    }
    println!(
        "noise component: 200 steps, {sweeps} sweeps, {by_stagnation} steps ended by \
         stagnation with a per-component residual > 1e-6 (largest {worst_residual:.2e}); \
         |y2| = {:.2e}",
        y[2].abs()
    );
    assert!(y[2] != 0.0 && y[2].abs() < 1e-14, "y2 = {:e}", y[2]);
    assert!(
        by_stagnation > 0,
        "the noise never reached the stopping rule"
    );
}

#[test]
fn per_component_scale_is_rejected_where_it_is_not_implemented() {
    // The exponential AVF baseline measures its updates globally only; TCrP runs on the ECrP
    // stepper and takes the per-component scale.
    use ecr::baselines::collocation::ExpAvf;
    let f = Fpu::default();
    let r = ExpAvf::new(f.first_order_system().unwrap(), 3, 0.01, per_component());
    assert!(matches!(r, Err(Error::InvalidParameter(m)) if m.contains("PerComponent")));
    let mut tc = TcStepper::with_nodes(f.system().unwrap(), 2, 2, 0.01, per_component()).unwrap();
    let (mut q, mut p) = f.initial_value();
    for _ in 0..10 {
        assert!(tc.step(&mut q, &mut p).unwrap().converged);
    }
}
