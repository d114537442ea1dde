//! A user-written Hamiltonian with a tolerance and output times (the README's first example).
use ecr::prelude::*;

fn main() -> Result<()> {
    // H(q, p) = ½|p|² + ½(q₁² + 4q₂²) + ½q₁²q₂², y = (q₁, q₂, p₁, p₂)
    let m = DMatrix::from_diagonal(&DVector::from_vec(vec![1.0, 4.0, 1.0, 1.0]));
    let grad_v = |y: &[f64], dv: &mut [f64]| {
        dv.copy_from_slice(&[y[0] * y[1] * y[1], y[0] * y[0] * y[1], 0.0, 0.0]);
    };
    let system = Hamiltonian::canonical(m, grad_v)?.potential(|y| 0.5 * (y[0] * y[1]).powi(2));
    let problem = Problem::new(system, [1.0, 0.5, 0.0, 0.0], (0.0, 100.0))?;
    let sol = problem.solve(&Options::tolerance(1e-8).t_eval(linspace(0.0, 100.0, 11)))?;
    println!(
        "q(100) = {:?}, energy error {:.1e}",
        &sol.y[10][..2],
        sol.energy_error().unwrap()
    );
    Ok(())
}
