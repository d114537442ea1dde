//! A downstream program embedding a fixed-order stepper: `ecr_method!(r = 3)` emits `Ec3`
//! (order 6, coefficients generated exactly at compile time, no heap use per step), here on
//! the paper's Duffing problem (ω = 5, k = 0.07) over [0, 100] with h = 0.01.
//!
//! Run: `cargo run --release --example duffing_ec3`

use ecr::ecr_method;
use ecr::problems::Duffing;
use ecr::runtime::operator::DenseStatic;
use ecr::runtime::system::Semilinear;
use nalgebra::SMatrix;

ecr_method!(r = 3);

fn main() -> Result<(), ecr::runtime::Error> {
    let (omega, k) = (5.0, 0.07);
    let problem = Duffing::new(omega, k)?;
    // y = (q, p): y' = A y + g(y), A = [[0, 1], [−(ω² + k²), 0]], g = (0, 2k² q³).
    let a = SMatrix::<f64, 2, 2>::new(0.0, 1.0, -(omega * omega + k * k), 0.0);
    let g = move |y: &[f64], out: &mut [f64]| {
        out[0] = 0.0;
        out[1] = 2.0 * k * k * y[0].powi(3);
    };
    let mut stepper: Ec3<_, 2> = Ec3::fixed(Semilinear::new(DenseStatic::new(a)?, g), 0.01)?;
    let mut y = [0.0, omega];
    let h0 = problem.energy(&y);
    let mut max_energy_error: f64 = 0.0;
    for _ in 0..10_000 {
        stepper.step(&mut y)?;
        max_energy_error = max_energy_error.max((problem.energy(&y) - h0).abs() / h0.abs());
    }
    let exact = problem.exact(100.0)?;
    println!("Ec3 (order {}), h = 0.01, t = 100", 2 * Ec3Kernel::R);
    println!("  y      = [{:.15}, {:.15}]", y[0], y[1]);
    println!("  exact  = [{:.15}, {:.15}]", exact[0], exact[1]);
    println!(
        "  global error {:.2e}",
        (y[0] - exact[0]).abs().max((y[1] - exact[1]).abs())
    );
    println!("  max relative energy error {max_energy_error:.2e}");
    Ok(())
}
