//! A program embedding a fixed-order stepper: `ecr_method!(r = 3)` emits `Ec3` (EC3P, order 6,
//! coefficients generated exactly while this crate compiles, no heap use per step), here on
//! Duffing's equation q'' = −(ω² + k²)q + 2k²q³ (ω = 5, k = 0.07) over [0, 100] with h = 0.01.
//! It needs nothing but the library (`ecr = { …, default-features = false }`).
//!
//! Run: `cargo run --release --example duffing_ec3`

use ecr::ecr_method;
use ecr::nalgebra::SMatrix;
use ecr::runtime::operator::DenseStatic;
use ecr::runtime::system::Semilinear;

ecr_method!(r = 3);

/// y(t_end) from y(0) = (0, ω) with EC3P and `steps` steps of h = t_end / steps, and the
/// largest relative error of the energy on the way.
fn run(omega: f64, k: f64, t_end: f64, steps: u32) -> Result<([f64; 2], f64), ecr::runtime::Error> {
    let w2 = omega * omega + k * k;
    // y = (q, p): y' = A y + g(y), A = [[0, 1], [−(ω² + k²), 0]], g = (0, 2k² q³).
    let a = SMatrix::<f64, 2, 2>::new(0.0, 1.0, -w2, 0.0);
    let g = move |y: &[f64], out: &mut [f64]| {
        out[0] = 0.0;
        out[1] = 2.0 * k * k * y[0].powi(3);
    };
    let energy =
        |y: &[f64; 2]| 0.5 * y[1] * y[1] + 0.5 * w2 * y[0] * y[0] - 0.5 * k * k * y[0].powi(4);
    let h = t_end / f64::from(steps);
    let mut stepper: Ec3<_, 2> = Ec3::fixed(Semilinear::new(DenseStatic::new(a)?, g), h)?;
    let mut y = [0.0, omega];
    let h0 = energy(&y);
    let mut max_energy_error: f64 = 0.0;
    for _ in 0..steps {
        stepper.step(&mut y)?;
        max_energy_error = max_energy_error.max((energy(&y) - h0).abs() / h0.abs());
    }
    Ok((y, max_energy_error))
}

fn main() -> Result<(), ecr::runtime::Error> {
    let (omega, k, t_end) = (5.0, 0.07, 100.0);
    let (y, energy_error) = run(omega, k, t_end, 10_000)?;
    // The error of an order-6 method at h/4 is 4⁶ ≈ 4000 times smaller: a reference.
    let (reference, _) = run(omega, k, t_end, 40_000)?;
    let error = (y[0] - reference[0]).abs().max((y[1] - reference[1]).abs());
    println!("Ec3 (order {}), h = 0.01, t = {t_end}", 2 * Ec3Kernel::R);
    println!("  y         = [{:.15}, {:.15}]", y[0], y[1]);
    println!(
        "  reference = [{:.15}, {:.15}] (h = 0.0025)",
        reference[0], reference[1]
    );
    println!("  global error {error:.2e}, max relative energy error {energy_error:.2e}");
    assert!(
        error < 1e-8 && energy_error < 1e-10,
        "EC3P lost its accuracy"
    );
    Ok(())
}
