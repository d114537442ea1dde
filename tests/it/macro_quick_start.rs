//! The quick start of `ecr-macros` (its crate docs), compiled and run here: the macro crate
//! cannot depend on the runtime its output calls.

use ecr_runtime::ecr_method;
use ecr_runtime::nalgebra::SMatrix;
use ecr_runtime::operator::DenseStatic;
use ecr_runtime::system::Semilinear;

// EC2P: order 4, two Gauss–Legendre nodes. Emits `Ec2Kernel`, `Ec2<Sys, D>`, `Ec2Dyn<Sys>`.
ecr_method!(r = 2);

#[test]
fn harmonic_oscillator_returns_after_one_period() {
    // The harmonic oscillator y' = Ay, A = [[0, 1], [−1, 0]], and g = 0: ECrP integrates
    // y' = Ay exactly, so after one period (2π) the state is back at y₀ up to round-off.
    let a = SMatrix::<f64, 2, 2>::new(0.0, 1.0, -1.0, 0.0);
    let system = Semilinear::new(DenseStatic::new(a).unwrap(), |_: &[f64], g: &mut [f64]| {
        g.fill(0.0)
    });
    let n = 64;
    let mut stepper: Ec2<_, 2> = Ec2::fixed(system, std::f64::consts::TAU / n as f64).unwrap();
    let mut y = [1.0, 0.0];
    for _ in 0..n {
        stepper.step(&mut y).unwrap();
    }
    assert!((y[0] - 1.0).abs() < 1e-13 && y[1].abs() < 1e-13);
    // The constants are the correctly rounded Gauss–Legendre nodes 1/2 ∓ √3/6.
    assert_eq!(Ec2Kernel::NODES, [0.2113248654051871, 0.7886751345948129]);
}
