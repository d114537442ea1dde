// A fixed-size stepper without its dimension: the error names the alias the user wrote (`Ec3`).
use ecr_runtime::ecr_method;
use ecr_runtime::nalgebra::SMatrix;
use ecr_runtime::operator::DenseStatic;
use ecr_runtime::system::Semilinear;

ecr_method!(r = 3);

fn main() -> ecr_runtime::Result<()> {
    let a = SMatrix::<f64, 2, 2>::new(0.0, 1.0, -1.0, 0.0);
    let g = |_: &[f64], out: &mut [f64]| out.fill(0.0);
    let system = Semilinear::new(DenseStatic::new(a)?, g);
    let mut st = Ec3::fixed(system, 0.01)?;
    let mut y = [1.0, 0.0];
    st.step(&mut y)?;
    Ok(())
}
