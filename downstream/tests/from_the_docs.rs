//! Programs a user writes from the README and docs/, with nothing but the prelude: the
//! documents' own Rust blocks and the examples the README names, verbatim (module
//! [`verbatim`]), and programs written from their text. They must compile as written there,
//! with the README's dependency line, and give what the documents promise (a solution
//! within its tolerance, energy kept, a Lyapunov function that decreases).
//!
//! Tolerances: `solve` promises an *estimated* global error within the tolerance; the
//! checks against exact or reference solutions allow 10 times the tolerance (the bound the
//! repository's own sweep, `tests/it/solve.rs`, holds it to), per component in the solver's
//! norm |e_i| ≤ atol + rtol |y_i|.
use ecr::prelude::*;
use std::f64::consts::PI;

/// The Rust blocks of README.md and docs/*.md, verbatim, and the examples the README names:
/// modules written by this crate's build script, each with a test that runs its `main`.
mod verbatim {
    include!(concat!(env!("OUT_DIR"), "/from_the_docs.rs"));
}

/// What a program's `main` returns: nothing, or a `Result` that must be `Ok`.
trait Outcome {
    fn check(self);
}

impl Outcome for () {
    fn check(self) {}
}

impl<E: std::fmt::Debug> Outcome for std::result::Result<(), E> {
    fn check(self) {
        if let Err(e) = self {
            panic!("main returned an error: {e:?}");
        }
    }
}

/// Largest |a_i − b_i| / (tol (1 + |b_i|)): the error in units of the tolerance.
fn in_tolerance_units(a: &[f64], b: &[f64], tol: f64) -> f64 {
    a.iter().zip(b).fold(0.0_f64, |m, (a, b)| {
        m.max((a - b).abs() / (tol * (1.0 + b.abs())))
    })
}

/// H = ½p² + ½q² + ¼q⁴ (the example of the crate root), solved in a function that returns
/// the solution: it outlives the problem it came from.
fn quartic_oscillator(t_end: f64, options: Options) -> Result<Solution<impl System>> {
    let grad_v = |y: &[f64], g: &mut [f64]| g[0] = y[0].powi(3);
    let system =
        Hamiltonian::canonical(DMatrix::identity(2, 2), grad_v)?.potential(|y| 0.25 * y[0].powi(4));
    // The binding of docs/solve.md: the problem is a temporary.
    let sol = Problem::new(system, [1.0, 0.0], (0.0, t_end))?.solve(&options)?;
    Ok(sol)
}

#[test]
fn the_one_line_binding_owns_its_solution() -> Result<()> {
    let tol = 1e-8;
    let sol = quartic_oscillator(20.0, Options::tolerance(tol).dense_output())?;
    // Against EC6P with a fixed step 50 times finer than the solver's.
    let reference = quartic_oscillator(20.0, Options::fixed(6, sol.h / 50.0))?;
    let (y, y_ref) = (sol.last().unwrap(), reference.last().unwrap());
    let error = in_tolerance_units(y, y_ref, tol);
    println!(
        "y(20) = {y:?}: {error:.3} tolerances off EC6P h/50; EC{}P h = {}",
        sol.r, sol.h
    );
    assert!(error <= 10.0, "{error}");
    // Between grid points, through the shared system.
    let y = sol.at(13.7)?;
    let h0 = 0.75; // H(1, 0)
    let h = 0.5 * y[1] * y[1] + 0.5 * y[0] * y[0] + 0.25 * y[0].powi(4);
    assert!((h - h0).abs() <= 10.0 * tol, "H(13.7) = {h}");
    assert!(sol.energy_error().unwrap() <= 10.0 * tol);
    Ok(())
}

/// Kepler's problem: y = (q, p), H = ½|p|² − 1/|q|, no linear part (`Zero`). The orbit has
/// semi-major axis 1 (period 2π) and starts at the pericentre (1 − e, 0).
fn kepler(e: f64, t_end: f64) -> Result<Problem<impl System>> {
    let g = |y: &[f64], out: &mut [f64]| {
        let r3 = (y[0] * y[0] + y[1] * y[1]).powf(1.5);
        (out[0], out[1], out[2], out[3]) = (y[2], y[3], -y[0] / r3, -y[1] / r3);
    };
    let energy = |y: &[f64]| 0.5 * (y[2] * y[2] + y[3] * y[3]) - 1.0 / y[0].hypot(y[1]);
    let system = Semilinear::with_energy(Zero::new(4), g, energy);
    Problem::new(system, kepler_exact(e, 0.0), (0.0, t_end))
}

/// The exact state at t from Kepler's equation E − e sin E = t (bisection: the left side
/// increases in E; then one Newton step).
fn kepler_exact(e: f64, t: f64) -> [f64; 4] {
    let m = t.rem_euclid(2.0 * PI);
    let f = |x: f64| x - e * x.sin() - m;
    let (mut lo, mut hi) = (0.0, 2.0 * PI);
    for _ in 0..64 {
        let mid = 0.5 * (lo + hi);
        if f(mid) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let x = 0.5 * (lo + hi);
    let x = x - f(x) / (1.0 - e * x.cos());
    let (s, c) = x.sin_cos();
    let b = (1.0 - e * e).sqrt();
    let rate = 1.0 / (1.0 - e * c);
    [c - e, b * s, -s * rate, b * c * rate]
}

#[test]
fn kepler_with_zero_meets_its_tolerance() -> Result<()> {
    let tol = 1e-8;
    for e in [0.3, 0.7] {
        let t_end = 4.0 * PI;
        let times = linspace(0.0, t_end, 9);
        let sol = kepler(e, t_end)?.solve(&Options::tolerance(tol).t_eval(times))?;
        let worst = sol
            .t
            .iter()
            .zip(&sol.y)
            .map(|(&t, y)| in_tolerance_units(y, &kepler_exact(e, t), tol))
            .fold(0.0, f64::max);
        println!(
            "e = {e}: {worst:.3} tolerances off Kepler's equation, EC{}P, {} g-evaluations",
            sol.r,
            sol.stats.total_g_evals()
        );
        assert!(worst <= 10.0, "e = {e}: {worst}");
        assert!(sol.energy_error().unwrap() <= 10.0 * tol);
    }
    Ok(())
}

/// A fixed step must be small everywhere when the orbit is eccentric: with the step count
/// that is plenty at e = 0.3, e = 0.9 is far off. Either a verified answer or an honest
/// `Unverified` comes back from a tolerance.
#[test]
fn kepler_eccentric_orbit_needs_a_tolerance_not_a_fixed_step() -> Result<()> {
    let t_end = 2.0 * PI;
    let error = |e: f64| -> Result<f64> {
        let sol = kepler(e, t_end)?.solve(&Options::fixed(3, t_end / 200.0))?;
        Ok(in_tolerance_units(
            sol.last().unwrap(),
            &kepler_exact(e, t_end),
            1.0,
        ))
    };
    let (mild, eccentric) = (error(0.3)?, error(0.9)?);
    println!("200 fixed steps of EC3P: error {mild:.1e} at e = 0.3, {eccentric:.1e} at e = 0.9");
    assert!(
        mild < 1e-8 && eccentric > 1e3 * mild,
        "{mild:e} {eccentric:e}"
    );
    let tol = 1e-6;
    match kepler(0.9, t_end)?.solve(&Options::tolerance(tol)) {
        Ok(sol) => {
            let error = in_tolerance_units(sol.last().unwrap(), &kepler_exact(0.9, t_end), tol);
            println!(
                "tolerance {tol:e}: {error:.3} tolerances off, {} segments",
                sol.segments.len()
            );
            assert!(error <= 10.0, "{error}");
        }
        Err(SolveError::Unverified { reason, .. }) => println!("unverified: {reason}"),
        Err(e) => return Err(e.into()),
    }
    Ok(())
}

/// Allen–Cahn u_t = εu_xx + u − u³ on a periodic grid of n points: the second difference as
/// a `Circulant` (first column), and U = Σ ε(u_{i+1} − u_i)²/(2Δx²) + ¼(u_i² − 1)².
fn allen_cahn(n: usize, eps: f64) -> (Vec<f64>, Vec<f64>, impl Fn(&[f64]) -> f64) {
    let dx = 2.0 * PI / n as f64;
    let u0 = (0..n)
        .map(|i| i as f64 * dx)
        .map(|x| 0.4 * x.sin() + 0.3 * (3.0 * x).cos())
        .collect();
    let mut c = vec![0.0; n];
    (c[0], c[1], c[n - 1]) = (-2.0 * eps / (dx * dx), eps / (dx * dx), eps / (dx * dx));
    let lyapunov = move |u: &[f64]| {
        (0..n)
            .map(|i| {
                let du = u[(i + 1) % n] - u[i];
                0.5 * eps * du * du / (dx * dx) + 0.25 * (u[i] * u[i] - 1.0).powi(2)
            })
            .sum::<f64>()
    };
    (c, u0, lyapunov)
}

#[test]
fn allen_cahn_with_circulant_decreases_u_and_meets_its_tolerance() -> Result<()> {
    let (n, tol, t_end) = (64, 1e-6, 5.0);
    let (c, u0, lyapunov) = allen_cahn(n, 0.01);
    let g =
        |u: &[f64], out: &mut [f64]| out.iter_mut().zip(u).for_each(|(o, u)| *o = u - u * u * u);
    let system = Semilinear::with_energy(Circulant::new(c.clone())?, g, lyapunov);
    let problem = Problem::new(system, u0.clone(), (0.0, t_end))?;
    let times = linspace(0.0, t_end, 6);
    let sol = problem.solve(&Options::tolerance(tol).t_eval(times.clone()))?;
    let u = sol.energy.as_ref().unwrap();
    println!("U at t = 0, 1, ..., 5: {u:?}");
    assert!(u.windows(2).all(|w| w[1] < w[0]), "U decreases: {u:?}");
    // At every output time, against EC6P with a step 20 times smaller.
    let reference = problem.solve(&Options::fixed(6, sol.h / 20.0).t_eval(times))?;
    let errors: Vec<f64> = sol
        .y
        .iter()
        .zip(&reference.y)
        .map(|(y, z)| in_tolerance_units(y, z, tol))
        .collect();
    let worst = errors.iter().copied().fold(0.0, f64::max);
    println!(
        "{worst:.1e} tolerances off EC6P with h/20 (EC{}P, h = {})",
        sol.r, sol.h
    );
    assert!(worst <= 10.0, "{errors:?}");
    // The comparison sees an error of the size asked for: EC1P with h = 0.5 is off.
    let crude = problem.solve(&Options::fixed(1, 0.5))?;
    let off = in_tolerance_units(crude.last().unwrap(), reference.last().unwrap(), tol);
    assert!(off > 10.0, "{off}");

    // The same flow as a GradientFlow with the dense M = −A (no V given: no energy), a few
    // steps of the same method: the same steps up to round-off.
    let m = DMatrix::from_fn(n, n, |i, j| -c[(i + n - j) % n]);
    let grad_v =
        |u: &[f64], out: &mut [f64]| out.iter_mut().zip(u).for_each(|(o, u)| *o = u * u * u - u);
    let dense = GradientFlow::new(m, grad_v, None)?;
    let fixed = Options::fixed(sol.r, sol.h);
    let span = (0.0, 10.0 * sol.h);
    let a = Problem::new(dense, u0.clone(), span)?.solve(&fixed)?;
    let b = Problem::new(problem.system(), u0, span)?.solve(&fixed)?;
    assert_eq!(a.energy, None);
    let diff = in_tolerance_units(a.last().unwrap(), b.last().unwrap(), 1.0);
    // Two operators, two roundings of the same φ-functions (eigendecomposition vs FFT): 1e-12.
    assert!(diff < 1e-12, "{diff:e}");
    Ok(())
}
