//! The `ecr_method!` stepper in a hot loop: order 6, exact compile-time coefficients, a
//! 2 × 2 operator on the stack, no heap use per step. Duffing q'' = −(ω² + k²)q + 2k²q³.
use ecr::prelude::*;

ecr_method!(r = 3);

fn main() -> Result<()> {
    let (omega, k) = (5.0, 0.07);
    let a = SMatrix::<f64, 2, 2>::new(0.0, 1.0, -(omega * omega + k * k), 0.0);
    let g =
        move |y: &[f64], out: &mut [f64]| out.copy_from_slice(&[0.0, 2.0 * k * k * y[0].powi(3)]);
    let mut stepper: Ec3<_, 2> = Ec3::fixed(Semilinear::new(DenseStatic::new(a)?, g), 0.01)?;
    let mut y = [0.0, omega];
    for _ in 0..10_000 {
        stepper.step(&mut y)?;
    }
    println!("y(100) = {y:?}");
    Ok(())
}
