//! `solve` at its edges: a NaN is never hidden (energy, event function, g), a step beyond the
//! span is one step of the span, and output beyond memory is an error naming its size, not an
//! abort. Each of these misbehaved in an earlier `solve`.

use std::process::Command;

use ecr::problems::Duffing;
use ecr::runtime::nalgebra::DMatrix;
use ecr::runtime::operator::Dense;
use ecr::runtime::solve::{Event, Options, Problem, SolveError};
use ecr::runtime::system::{Hamiltonian, Semilinear};

/// An energy function that returns NaN is not reported as conserved.
#[test]
fn a_nan_energy_is_not_conserved() {
    let grad_v = |y: &[f64], g: &mut [f64]| g[0] = y[0].powi(3);
    let system = Hamiltonian::canonical(DMatrix::identity(2, 2), grad_v)
        .unwrap()
        .potential(|y| {
            if y[0] < 0.0 {
                f64::NAN
            } else {
                0.25 * y[0].powi(4)
            }
        });
    let problem = Problem::new(system, [1.0, 0.0], (0.0, 10.0)).unwrap();
    let sol = problem.solve(&Options::tolerance(1e-8)).unwrap();
    let e = sol.energy_error().expect("the system knows H");
    assert!(
        e.is_nan(),
        "energy error {e} although H was NaN at some outputs"
    );
}

/// An event function that returns NaN is an error that names it, not a silently ignored
/// event, with a tolerance and with a fixed step.
#[test]
fn a_nan_event_is_an_error() {
    let d = Duffing::default();
    let problem = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, 2.0)).unwrap();
    let nan_late = |t: f64, y: &[f64]| if t > 1.0 { f64::NAN } else { y[0] };
    for options in [Options::tolerance(1e-8), Options::fixed(3, 0.01)] {
        let err = problem
            .solve(&options.event(Event::new(nan_late)))
            .expect_err("an event function that returns NaN");
        assert!(
            matches!(err, SolveError::Failed(_)) && err.to_string().contains("event function 0"),
            "{err}"
        );
    }
}

/// g that is NaN in a stretch of time (a clock τ' = 1 drives it): the solve says so, where,
/// and stops trying after a few smaller steps.
#[test]
fn a_transient_nan_in_g_is_reported_where_it_is() {
    let a = DMatrix::from_row_slice(3, 3, &[0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    let g = |y: &[f64], out: &mut [f64]| {
        out[0] = 0.0;
        out[1] = if (3.0..3.2).contains(&y[2]) {
            f64::NAN
        } else {
            0.0
        };
        out[2] = 1.0;
    };
    let system = Semilinear::new(Dense::new(a).unwrap(), g);
    let problem = Problem::new(system, [1.0, 0.0, 0.0], (0.0, 10.0)).unwrap();
    let err = problem
        .solve(&Options::tolerance(1e-8))
        .expect_err("g is NaN between t = 3 and 3.2");
    let message = err.to_string();
    eprintln!("{message}");
    let at: f64 = message
        .split("failed at t = ")
        .nth(1)
        .and_then(|rest| rest.split(' ').next())
        .and_then(|t| t.parse().ok())
        .expect("the message says where the step failed");
    assert!(
        message.contains("NaN") && (2.5..3.2).contains(&at),
        "{message}"
    );
    let best = err.solution().expect("the best solution comes with it");
    assert!(
        best.t.last().is_some_and(|&t| t < 3.2),
        "{:?}",
        best.t.last()
    );
    assert!(best.stats.retries <= 4, "{} tries", best.stats.retries);
}

/// A fixed step far beyond the span is one step of the span.
#[test]
fn a_fixed_step_beyond_the_span_is_one_step() {
    let d = Duffing::default();
    let problem = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, 0.1)).unwrap();
    let sol = problem.solve(&Options::fixed(4, 1e15)).unwrap();
    assert_eq!(sol.stats.steps, 1);
    assert_eq!(sol.t.last(), Some(&0.1));
    let exact = d.exact(0.1).unwrap();
    let y = sol.last().unwrap();
    assert!((y[0] - exact[0]).abs() < 1e-6, "{y:?} vs {exact:?}");
}

/// Output at every step of 10⁸ steps does not fit in 2 GB of address space: an error that
/// names the size, not an abort. Runs the solve in a child process of this test binary under
/// `ulimit -v`.
#[test]
fn output_beyond_memory_is_an_error() {
    let exe = std::env::current_exe().unwrap();
    let out = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v 2000000 && exec '{}' --exact output_beyond_memory_child --ignored \
             --nocapture --test-threads 1",
            exe.display()
        ))
        .output()
        .expect("sh runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "the child failed ({:?}): {stdout}\n{stderr}",
        out.status
    );
    assert!(stderr.contains("the solution's output"), "{stderr}");
}

#[test]
#[ignore = "run by output_beyond_memory_is_an_error under ulimit -v"]
fn output_beyond_memory_child() {
    let d = Duffing::default();
    let problem = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, 100.0)).unwrap();
    match problem.solve(&Options::fixed(1, 1e-6)) {
        Err(SolveError::Failed(e)) => eprintln!("{e}"),
        Err(e) => panic!("another error: {e}"),
        Ok(sol) => panic!("{} outputs stored under 2 GB", sol.t.len()),
    }
}
