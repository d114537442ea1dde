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

/// Runs the ignored test `child` of this binary under `ulimit -v kib`: it must succeed and say
/// on stderr that the solution's output would not fit.
fn child_refuses_the_output(kib: u64, child: &str) {
    let exe = std::env::current_exe().unwrap();
    // The test's name within the binary: this module's path without the crate's name.
    let module = module_path!().split_once("::").map_or("", |(_, m)| m);
    let child = format!("{module}::{child}");
    let out = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v {kib} && exec '{}' --exact {child} --ignored --nocapture --test-threads 1",
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

/// Output at every step of 10⁸ steps does not fit in 2 GB of address space: an error that
/// names the size, not an abort. Runs the solve in a child process of this test binary under
/// `ulimit -v`.
#[test]
fn output_beyond_memory_is_an_error() {
    child_refuses_the_output(2_000_000, "output_beyond_memory_child");
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

/// A fixed-step solve with 10⁷ output times under an 800 MB address space: an error naming
/// the output's size before the run (it aborted in `Runs::outputs_until` with "memory
/// allocation of 805306368 bytes failed": the fixed path had no size check).
#[test]
fn fixed_output_beyond_memory_is_an_error() {
    child_refuses_the_output(800_000, "fixed_output_beyond_memory_child");
}

#[test]
#[ignore = "run by fixed_output_beyond_memory_is_an_error under ulimit -v"]
fn fixed_output_beyond_memory_child() {
    let d = Duffing::default();
    let problem = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, 10.0)).unwrap();
    let options =
        Options::fixed(2, 0.01).t_eval(ecr::runtime::solve::linspace(0.0, 10.0, 10_000_000));
    match problem.solve(&options) {
        Err(SolveError::Failed(e)) => eprintln!("{e}"),
        Err(e) => panic!("another error: {e}"),
        Ok(sol) => panic!("{} outputs stored under 800 MB", sol.t.len()),
    }
}

/// `at(t)` is defined wherever the solution's times go: up to a terminal event between grid
/// points (it said "outside the integrated span [0, 1.111]" at the event time 1.192), for a
/// verified and a fixed-step solve, and at the observer's stop.
#[test]
fn at_is_defined_up_to_a_terminal_event() {
    let d = Duffing::default();
    let problem = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, 10.0)).unwrap();
    let event = || {
        Event::new(|t, _| t - 1.192)
            .direction(ecr::runtime::solve::Direction::Rising)
            .terminal()
    };
    for options in [
        Options::tolerance(1e-8).dense_output().event(event()),
        Options::fixed(3, 0.05).dense_output().event(event()),
    ] {
        let sol = problem.solve(&options).unwrap();
        let end = *sol.t.last().unwrap();
        assert!((end - 1.192).abs() < 1e-9, "ended at {end}");
        let y = sol.at(end).unwrap();
        let last = sol.last().unwrap();
        assert!(
            (y[0] - last[0]).abs() < 1e-7,
            "{y:?} vs {last:?} at the event"
        );
        let exact = d.exact(end - 0.01).unwrap();
        let y = sol.at(end - 0.01).unwrap();
        assert!((y[0] - exact[0]).abs() < 1e-5, "{y:?} vs {exact:?}");
        assert!(sol.at(end + 0.01).is_err(), "beyond the event");
    }
    let mut steps = 0;
    let sol = problem
        .solve_with(&Options::tolerance(1e-8).dense_output(), |_| {
            steps += 1;
            if steps == 7 {
                std::ops::ControlFlow::Break(())
            } else {
                std::ops::ControlFlow::Continue(())
            }
        })
        .unwrap();
    let end = *sol.t.last().unwrap();
    let (y, last) = (sol.at(end).unwrap(), sol.last().unwrap());
    assert!(
        (y[0] - last[0]).abs() < 1e-7,
        "{y:?} vs {last:?} at the stop"
    );
}

/// Nothing kept, nothing estimated: an unverified solution without outputs has no estimate
/// (it had `Some(0.0)`, which reads as exact), and a solution with outputs has the largest.
#[test]
fn no_output_has_no_estimate() {
    let d = Duffing::new(5.0, 5.0).unwrap();
    let problem = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, 5.0)).unwrap();
    match problem.solve(&Options::tolerance(1e-4)) {
        Err(SolveError::Unverified { solution, reason }) => {
            if solution.t.is_empty() {
                assert_eq!(solution.error_estimate, None, "{reason}");
            } else {
                let worst = solution.error_estimates.iter().copied().fold(0.0, f64::max);
                assert!(solution.error_estimate.unwrap() >= worst, "{reason}");
                assert!(solution.error_estimate.unwrap() > 1.0, "{reason}");
            }
        }
        Err(e) => panic!("{e}"),
        Ok(sol) => assert!(sol.error_estimate.unwrap() <= 1.0),
    }
}

/// A subnormal y₀ is solved like any tiny one (it took r = 1 and 131 076 steps on T = 10, and
/// on T = 1000 failed "needs 8589934596 steps", while the differences between the runs were
/// 1e-315: the round-off model ignored that f64 keeps fewer digits below 2.2e-308).
#[test]
fn a_subnormal_initial_value_takes_few_steps() {
    let d = Duffing::default();
    for t_end in [10.0, 1000.0] {
        let problem = Problem::new(d.system().unwrap(), [5e-324, -1e-310], (0.0, t_end)).unwrap();
        let sol = problem.solve(&Options::tolerance(1e-8)).unwrap();
        assert!(sol.stats.steps <= 100, "{} steps", sol.stats.steps);
        assert!(sol.error_estimate.unwrap() <= 1.0);
        assert!(sol.last().unwrap().iter().all(|v| v.abs() < 1e-300));
    }
}

/// Times at the edge of f64: output at 5e-324, a span of one ulp, a fixed step below the
/// resolution of time, and y₀ at the largest f64 get answers or messages that say what is
/// wrong (they said "h = 0.0", "more than max_steps = 18446744073709551615", stepped past
/// t_end, and "ask for about inf times the tolerance").
#[test]
fn times_at_the_edge_of_f64() {
    let d = Duffing::default();
    let y0 = d.initial_value();
    let problem = Problem::new(d.system().unwrap(), y0.clone(), (0.0, 1.0)).unwrap();
    let sol = problem
        .solve(&Options::tolerance(1e-8).dense_output())
        .unwrap();
    let y = sol.at(5e-324).unwrap();
    assert!((y[0] - y0[0]).abs() < 1e-300 && y[1] == y0[1], "{y:?}");
    let sol = problem
        .solve(&Options::tolerance(1e-8).t_eval([0.0, 5e-324, 1.0]))
        .unwrap();
    assert_eq!(sol.t.len(), 3);

    let next = 1.0 + f64::EPSILON;
    let ulp = Problem::new(d.system().unwrap(), y0.clone(), (1.0, next)).unwrap();
    for options in [Options::tolerance(1e-8), Options::fixed(2, 0.1)] {
        let sol = ulp.solve(&options).unwrap();
        assert_eq!(sol.t, vec![1.0, next], "{options:?}");
        let moved = y0[0] + f64::EPSILON * y0[1];
        assert!(
            (sol.last().unwrap()[0] - moved).abs() <= 1e-30,
            "{:?}",
            sol.y
        );
    }
    let ulp_estimate = ulp.solve(&Options::tolerance(1e-8)).unwrap().error_estimate;
    assert!(ulp_estimate.is_some_and(|e| e <= 1.0));

    let late = Problem::new(d.system().unwrap(), y0.clone(), (1000.0, 1001.0)).unwrap();
    match late.solve(&Options::fixed(2, 1e-14)) {
        Err(SolveError::Failed(e)) => {
            assert!(e.to_string().contains("resolution of time"), "{e}")
        }
        other => panic!("{:?}", other.map(|s| s.t.len())),
    }

    let huge = Problem::new(d.system().unwrap(), [f64::MAX, 0.0], (0.0, 1.0)).unwrap();
    match huge.solve(&Options::tolerance(1e-8)) {
        Err(SolveError::Failed(e)) => {
            let e = e.to_string();
            assert!(e.contains("rescale") && !e.contains("inf"), "{e}")
        }
        other => panic!("{:?}", other.map(|s| s.t.len())),
    }
}
