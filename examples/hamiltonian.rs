//! A user-written Hamiltonian with a tolerance and output times (the README's first example).
use ecr::prelude::*;

fn main() -> Result<()> {
    // H(q, p) = ½|p|² + ½(q₁² + 4q₂²) + ½q₁²q₂², y = (q₁, q₂, p₁, p₂)
    let m = DMatrix::from_diagonal(&DVector::from_vec(vec![1.0, 4.0, 1.0, 1.0]));
    let grad_v = |y: &[f64], g: &mut [f64]| (g[0], g[1]) = (y[0] * y[1] * y[1], y[0] * y[0] * y[1]);
    let system = Hamiltonian::canonical(m, grad_v)?.potential(|y| 0.5 * (y[0] * y[1]).powi(2));
    let problem = Problem::new(system, [1.0, 0.5, 0.0, 0.0], (0.0, 100.0))?;
    let sol = problem.solve(&Options::tolerance(1e-8).t_eval(linspace(0.0, 100.0, 11)))?;
    println!("y(100) = {:?}, {:?}", sol.y[10], sol.energy_error());
    Ok(())
}
