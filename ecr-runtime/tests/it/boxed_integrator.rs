//! `integrate` drives a boxed integrator (`Box<dyn Integrator>`: a method chosen at run time)
//! exactly as the integrator itself: the same state to the bit, the same report. The interval
//! is not a multiple of h, so the shortened last step (`set_step_size`) goes through the box
//! too, and the system has an energy (`energy_of`).

use ecr_runtime::integrate::{IntegrateOptions, Integrator, Report, integrate};
use ecr_runtime::operator::Zero;
use ecr_runtime::stepper::EcStepper;
use ecr_runtime::system::Semilinear;

/// The pendulum q' = p, p' = −sin q with H = p²/2 − cos q, by EC3P with h = 0.1.
fn pendulum() -> EcStepper<impl ecr_runtime::system::System> {
    let g = |y: &[f64], g: &mut [f64]| {
        g[0] = y[1];
        g[1] = -y[0].sin();
    };
    let h = |y: &[f64]| 0.5 * y[1] * y[1] - y[0].cos();
    EcStepper::new(Semilinear::with_energy(Zero::new(2), g, h), 3, 0.1).unwrap()
}

/// What the observer saw at one step: t, y and H(y).
type Seen = (f64, Vec<f64>, Option<f64>);

/// Integrates from (q, p) = (2.5, 0) over [0, 10.05] with every step observed: the final
/// state, the report and what the observer saw.
fn run(stepper: &mut impl Integrator) -> ([f64; 2], Report, Vec<Seen>) {
    let mut y = [2.5, 0.0];
    let mut seen = Vec::new();
    let options = IntegrateOptions {
        energy_every: 1,
        observe_every: 1,
    };
    let report = integrate(stepper, 0.0, 10.05, &mut y, options, |t, y, e| {
        seen.push((t, y.to_vec(), e));
    })
    .unwrap();
    (y, report, seen)
}

#[test]
fn a_boxed_integrator_takes_the_same_steps_bit_for_bit() {
    let (y, report, seen) = run(&mut pendulum());
    let mut boxed: Box<dyn Integrator> = Box::new(pendulum());
    let (y_boxed, report_boxed, seen_boxed) = run(&mut boxed);
    assert_eq!(y.map(f64::to_bits), y_boxed.map(f64::to_bits));
    assert_eq!(report, report_boxed);
    assert_eq!(seen.len(), seen_boxed.len());
    for ((t, a, e), (tb, b, eb)) in seen.iter().zip(&seen_boxed) {
        assert_eq!(t.to_bits(), tb.to_bits());
        assert!(
            a.iter().zip(b).all(|(x, z)| x.to_bits() == z.to_bits()),
            "t = {t}"
        );
        assert_eq!(e.map(f64::to_bits), eb.map(f64::to_bits), "t = {t}");
    }
    // The last step was shortened to end at T, and h is restored through the box.
    assert_eq!(report_boxed.t_end, 10.05);
    assert_eq!(boxed.step_size(), 0.1);
    // The run did something: the energy is known and the state moved.
    assert!(report.energy_start.is_some() && report.max_energy_error.is_some());
    assert!(y[0] != 2.5);
}
