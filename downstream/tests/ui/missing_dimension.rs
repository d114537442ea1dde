// A fixed-size stepper without its dimension: the error names the alias the user wrote (`Ec3`).
use ecr::prelude::*;

ecr_method!(r = 3);

fn main() -> Result<()> {
    let a = SMatrix::<f64, 2, 2>::new(0.0, 1.0, -1.0, 0.0);
    let g = |_: &[f64], out: &mut [f64]| out.fill(0.0);
    let system = Semilinear::new(DenseStatic::new(a)?, g);
    let mut st = Ec3::fixed(system, 0.01)?;
    let mut y = [1.0, 0.0];
    st.step(&mut y)?;
    Ok(())
}
