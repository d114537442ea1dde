//! A dissipative system: the damped Duffing oscillator q'' + γq' + q + q³ = 0 as y' = Q∇H with
//! H = ½p² + ½q² + ¼q⁴ and Q = [[0, 1], [−1, −γ]]; H is a Lyapunov function and decreases.
use ecr::prelude::*;

fn main() -> Result<()> {
    let q = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -1.0, -0.1]);
    let grad_v = |y: &[f64], g: &mut [f64]| g[0] = y[0].powi(3);
    let system =
        Hamiltonian::new(q, DMatrix::identity(2, 2), grad_v)?.potential(|y| 0.25 * y[0].powi(4));
    let problem = Problem::new(system, [2.0, 0.0], (0.0, 50.0))?;
    let sol = problem.solve(&Options::tolerance(1e-10).t_eval(linspace(0.0, 50.0, 6)))?;
    let energy = sol.energy.as_ref().expect("H is known");
    assert!(energy.windows(2).all(|w| w[1] <= w[0]), "H decreases");
    for (t, h) in sol.t.iter().zip(energy) {
        println!("t = {t:4.0}: H = {h:.6e}");
    }
    Ok(())
}
