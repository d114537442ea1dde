//! Allen–Cahn, u_t = ε u_xx + u − u³ on a periodic interval: the operator decides the cost.
//!
//! Second differences on a periodic grid are a circulant matrix: as a `Circulant` the linear
//! part is applied by FFT, O(N log N), and its φ-functions are N numbers per node. The same
//! flow as a `GradientFlow` holds M as a dense `Symmetric` matrix: O(N²) per application and
//! an O(N³) set-up for each step size. Both are the same method on the same equations (their
//! steps agree to round-off); this program solves N = 256 with the `Circulant` and times both
//! operators on N = 128 (the dense set-up alone takes seconds at N = 256). It prints the
//! times and asserts no speed: they vary from machine to machine.
//!
//! The flow is a gradient flow of U(u) = Σ ε(u_{i+1} − u_i)²/(2Δx²) + ¼(u_i² − 1)²: U decreases.
//!
//! `cargo run --release --example allen_cahn`
use ecr::prelude::*;
use std::f64::consts::PI;
use std::time::Instant;

const EPS: f64 = 0.01;
const T: f64 = 10.0;

/// The first column of A = ε D₂ (periodic second difference on n points of [−1, 1)), the
/// initial state, and the Lyapunov function U.
fn allen_cahn(n: usize) -> (Vec<f64>, Vec<f64>, impl Fn(&[f64]) -> f64) {
    let dx = 2.0 / n as f64;
    let mut c = vec![0.0; n];
    (c[0], c[1], c[n - 1]) = (-2.0 * EPS / (dx * dx), EPS / (dx * dx), EPS / (dx * dx));
    let u0 = (0..n)
        .map(|i| PI * (i as f64 * dx - 1.0))
        .map(|x| 0.4 * x.sin() + 0.3 * (3.0 * x).cos() + 0.1 * (7.0 * x).sin())
        .collect();
    let lyapunov = move |u: &[f64]| {
        (0..n)
            .map(|i| {
                let du = u[(i + 1) % n] - u[i];
                0.5 * EPS * du * du / (dx * dx) + 0.25 * (u[i] * u[i] - 1.0).powi(2)
            })
            .sum::<f64>()
    };
    (c, u0, lyapunov)
}

/// y' = Ay + g(y) with g(u) = u − u³.
fn g(u: &[f64], out: &mut [f64]) {
    out.iter_mut().zip(u).for_each(|(o, u)| *o = u - u * u * u);
}

/// ∇V for the gradient-flow form y' = −My − ∇V(y), V = Σ ¼(u_i² − 1)².
fn grad_v(u: &[f64], out: &mut [f64]) {
    out.iter_mut().zip(u).for_each(|(o, u)| *o = u * u * u - u);
}

fn main() -> Result<()> {
    let n = 256;
    let (c, u0, lyapunov) = allen_cahn(n);
    let system = Semilinear::with_energy(Circulant::new(c)?, g, lyapunov);
    let start = Instant::now();
    let options = Options::tolerance(1e-6).t_eval(linspace(0.0, T, 11));
    let sol = Problem::new(system, u0, (0.0, T))?.solve(&options)?;
    let seconds = start.elapsed().as_secs_f64();
    let u_values = sol.energy.as_ref().expect("U is known");
    assert!(u_values.windows(2).all(|w| w[1] <= w[0]), "U decreases");
    println!("Allen–Cahn, N = {n}, ε = {EPS}, [0, {T}], tolerance 1e-6, Circulant operator:");
    println!(
        "  solve: {seconds:.3} s, EC{}P, {} steps, {} g-evaluations in all",
        sol.r,
        sol.stats.steps,
        sol.stats.total_g_evals()
    );
    for (t, u) in sol.t.iter().zip(u_values).step_by(2) {
        println!("  t = {t:4.1}: U = {u:.6}");
    }

    // The same flow on N = 128, with A as a Circulant and with M = −A as a dense matrix
    // (GradientFlow: a Symmetric operator), the same method and step size, set-up included.
    let n = 128;
    let (c, u0, _) = allen_cahn(n);
    let (r, h, steps) = (sol.r, 0.1, 20);
    let span = (0.0, steps as f64 * h);
    let fixed = Options::fixed(r, h);
    let start = Instant::now();
    let circulant = Problem::new(
        Semilinear::new(Circulant::new(c.clone())?, g),
        u0.clone(),
        span,
    )?;
    let a = circulant.solve(&fixed)?;
    let t_circulant = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let m = DMatrix::from_fn(n, n, |i, j| -c[(i + n - j) % n]);
    let dense = Problem::new(GradientFlow::new(m, grad_v, None)?, u0, span)?;
    let b = dense.solve(&fixed)?;
    let t_dense = start.elapsed().as_secs_f64();
    let (ya, yb) = (a.last().expect("a state"), b.last().expect("a state"));
    let diff = ya
        .iter()
        .zip(yb)
        .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(
        diff < 1e-10,
        "the two operators give the same steps: {diff:e}"
    );
    println!(
        "N = {n}, {steps} steps of EC{r}P with h = {h}, set-up included (results agree to {diff:.0e}):"
    );
    println!("  Circulant (FFT):   {:>9.2} ms", 1e3 * t_circulant);
    println!(
        "  dense Symmetric:   {:>9.2} ms  ({:.0} times as long)",
        1e3 * t_dense,
        t_dense / t_circulant
    );
    Ok(())
}
