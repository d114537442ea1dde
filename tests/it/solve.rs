//! The solve API: tolerances met on the paper's problems, the continuous solution between grid
//! points as accurate as the grid, events, observers, output times.

use std::ops::ControlFlow;

use ecr::problems::{Duffing, Nls, Wind};
use ecr::runtime::integrate::{IntegrateOptions, integrate};
use ecr::runtime::nalgebra::DMatrix;
use ecr::runtime::operator::Dense;
use ecr::runtime::solve::{Direction, Event, Options, Problem, SolveError, Status, linspace};
use ecr::runtime::stepper::EcStepper;
use ecr::runtime::system::{Semilinear, System};

/// max_i |a_i − b_i| / (tol + tol |b_i|): the error in units of the tolerance.
fn scaled_error(a: &[f64], b: &[f64], tol: f64) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / (tol + tol * y.abs()))
        .fold(0.0, f64::max)
}

fn reference<S: System>(system: &S, y0: &[f64], t: f64, r: usize, h: f64) -> Vec<f64> {
    let mut stepper = EcStepper::new(system, r, h).unwrap();
    let mut y = y0.to_vec();
    let options = IntegrateOptions {
        energy_every: 0,
        observe_every: 0,
    };
    integrate(&mut stepper, 0.0, t, &mut y, options, |_, _, _| {}).unwrap();
    y
}

/// Each tolerance 1e−4 … 1e−12: the error at t_end within 10× the tolerance; at 1e−12 the
/// solve may instead say that the tolerance is at the round-off floor.
fn sweep<S: System>(name: &str, system: S, y0: Vec<f64>, t_end: f64, exact: &[f64]) {
    let problem = Problem::new(system, y0, (0.0, t_end)).unwrap();
    for k in [4, 6, 8, 10, 12] {
        let tol = 10f64.powi(-k);
        let sol = match problem.solve(&Options::tolerance(tol).t_eval([t_end])) {
            Ok(sol) => sol,
            Err(SolveError::Unverified { reason, .. })
                if k == 12 && reason.contains("round-off") =>
            {
                eprintln!("{name}: tol 1e-{k}: not verified: {reason}");
                continue;
            }
            Err(e) => panic!("{name}: tol 1e-{k}: {e}"),
        };
        let ratio = scaled_error(sol.last().unwrap(), exact, tol);
        eprintln!(
            "{name}: tol 1e-{k}: EC{}P h = {:.4e}, {} steps, error / tol = {ratio:.3}, g: pilot \
             {}, run {}",
            sol.r, sol.h, sol.stats.steps, sol.stats.pilot_g_evals, sol.stats.g_evals
        );
        assert!(ratio <= 10.0, "{name}: tol 1e-{k}: error / tol = {ratio}");
    }
}

#[test]
fn tolerances_are_met_on_duffing() {
    let d = Duffing::new(20.0, 0.07).unwrap();
    let t_end = 1000.0;
    let exact = d.exact(t_end).unwrap();
    sweep(
        "duffing",
        d.system().unwrap(),
        d.initial_value(),
        t_end,
        &exact,
    );
}

#[test]
fn tolerances_are_met_on_the_wind_problem() {
    let w = Wind::conservative();
    let system = w.system().unwrap();
    let t_end = 100.0;
    // EC6P at h = 0.1/128: its error is ~1e−15 (the bench's reference).
    let exact = reference(&system, &w.initial_value(), t_end, 6, 0.1 / 128.0);
    sweep("wind", system, w.initial_value(), t_end, &exact);
}

#[test]
fn tolerances_are_met_on_the_nls() {
    let n = Nls::new(128).unwrap();
    let system = n.system().unwrap();
    let t_end = 10.0;
    let exact = reference(&system, &n.initial_value(), t_end, 6, 0.1 / 256.0);
    sweep("nls", system, n.initial_value(), t_end, &exact);
}

/// Between grid points the continuous solution is within 10× the error on the grid, for every
/// r = 2..6; the stage-order interpolant ũ(τ) is not.
#[test]
fn continuous_solution_has_the_order_of_the_grid() {
    let d = Duffing::default();
    let t_end = 20.0;
    // Step sizes at which the grid error is well above round-off.
    for (r, h) in [(2, 0.02), (3, 0.05), (4, 0.1), (5, 0.15), (6, 0.2)] {
        let problem = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, t_end)).unwrap();
        let sol = problem.solve(&Options::fixed(r, h).dense_output()).unwrap();
        let mut grid = 0.0f64;
        for (t, y) in sol.t.iter().zip(&sol.y) {
            let e = d.exact(*t).unwrap();
            grid = grid.max((y[0] - e[0]).abs().max((y[1] - e[1]).abs()));
        }
        let mut between = 0.0f64;
        for w in sol.t.windows(2) {
            for frac in [0.25, 0.5, 0.75] {
                let t = w[0] + frac * (w[1] - w[0]);
                let y = sol.at(t).unwrap();
                let e = d.exact(t).unwrap();
                between = between.max((y[0] - e[0]).abs().max((y[1] - e[1]).abs()));
            }
        }
        // The stage-order interpolant of the same steps, at the same points of the last steps.
        let mut stepper = EcStepper::new(d.system().unwrap(), r, h).unwrap();
        let mut y = d.initial_value();
        let (mut stage_order, mut early_grid) = (0.0f64, 0.0f64);
        let mut t = 0.0;
        for _ in 0..50 {
            stepper.step(&mut y).unwrap();
            for frac in [0.25, 0.5, 0.75] {
                let u = stepper.dense_output(frac).unwrap();
                let e = d.exact(t + frac * h).unwrap();
                stage_order = stage_order.max((u[0] - e[0]).abs().max((u[1] - e[1]).abs()));
            }
            t += h;
            let e = d.exact(t).unwrap();
            early_grid = early_grid.max((y[0] - e[0]).abs().max((y[1] - e[1]).abs()));
        }
        eprintln!(
            "EC{r}P h = {h}: grid error {grid:.3e}, between grid points {between:.3e} (ratio \
             {:.2}); over the first 50 steps: grid {early_grid:.3e}, the stage-order \
             interpolant between them {stage_order:.3e} (ratio {:.0}); g-evaluations per point \
             between grid points {:.1} (per step of the run {:.1})",
            between / grid,
            stage_order / early_grid,
            sol.dense_evaluations().1 as f64 / sol.dense_evaluations().0 as f64,
            sol.stats.g_evals as f64 / sol.stats.steps as f64,
        );
        assert!(
            between <= 10.0 * grid,
            "r = {r}: {between:e} vs grid {grid:e}"
        );
    }
}

/// Output times take no part in the steps: the solve with 21 output times takes the steps of
/// the solve without them, bit for bit (the same segments, the same grid values), and each value
/// between grid points carries its estimate within the tolerance.
#[test]
fn output_times_leave_the_steps_alone() {
    let d = Duffing::default();
    let problem = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, 2.0)).unwrap();
    let times: Vec<f64> = (0..=20).map(|i| i as f64 * 0.1).collect();
    let sol = problem
        .solve(&Options::tolerance(1e-8).t_eval(times.clone()))
        .unwrap();
    assert_eq!(sol.t, times);
    assert!(sol.error_estimates.iter().all(|&e| e <= 1.0));
    let every = problem.solve(&Options::tolerance(1e-8)).unwrap();
    assert_eq!(sol.segments, every.segments);
    assert_eq!(sol.stats.steps, every.stats.steps);
    assert_eq!(sol.last(), every.last(), "t_end is a grid point of both");
    for (t, y) in sol.t.iter().zip(&sol.y) {
        if let Some(k) = every.t.iter().position(|s| s == t) {
            assert_eq!(y, &every.y[k], "t = {t}");
        }
    }
}

/// The zeros of q located by the continuous solution: q(t) = sn(ωt; m) falls through 0 at
/// t = 2K(m)/ω.
#[test]
fn events_are_located_to_the_tolerance() {
    let d = Duffing::default();
    let problem = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, 5.0)).unwrap();
    let k = ecr::special::elliptic_k(d.elliptic_parameter()).unwrap();
    let half_period = 2.0 * k / d.omega();
    let options = Options::tolerance(1e-10)
        .event(Event::new(|_, y| y[0]).direction(Direction::Falling))
        .event(
            Event::new(|_, y| y[0])
                .direction(Direction::Rising)
                .terminal(),
        );
    let sol = problem.solve(&options).unwrap();
    // Falling zeros at 2K/ω·(1, 3, ...), the first rising one (t > 0) at 4K/ω ends the run.
    let falling: Vec<f64> = sol
        .events
        .iter()
        .filter(|e| e.event == 0)
        .map(|e| e.t)
        .collect();
    assert_eq!(falling.len(), 1, "{:?}", sol.events);
    assert!(
        (falling[0] - half_period).abs() < 1e-10,
        "{} vs {half_period}",
        falling[0]
    );
    match sol.status {
        Status::Terminated { event: 1, t } => {
            assert!(
                (t - 2.0 * half_period).abs() < 1e-10,
                "{t} vs {}",
                2.0 * half_period
            );
            assert_eq!(*sol.t.last().unwrap(), t);
            assert!(sol.last().unwrap()[0].abs() < 1e-9);
        }
        other => panic!("expected the terminal event, got {other:?}"),
    }
}

#[test]
fn an_observer_stops_the_run() {
    let d = Duffing::default();
    let problem = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, 10.0)).unwrap();
    let sol = problem
        .solve_with(&Options::fixed(3, 0.01), |step| {
            if step.step == 10 {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        })
        .unwrap();
    assert_eq!(sol.stats.steps, 10);
    assert_eq!(sol.t.len(), 11);
    assert!(matches!(sol.status, Status::Stopped { t } if (t - 0.1).abs() < 1e-15));
}

#[test]
fn bad_options_are_errors() {
    let d = Duffing::default();
    let problem = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, 1.0)).unwrap();
    for options in [
        Options::tolerance(-1.0),
        Options::tolerance(f64::NAN),
        Options::fixed(3, 0.0),
        Options::tolerance(1e-8).t_eval([0.5, 0.2]),
        Options::tolerance(1e-8).t_eval([2.0]),
        #[allow(clippy::reversed_empty_ranges)]
        Options::tolerance(1e-8).orders(3..=2),
        Options::fixed(3, 1e-9).max_steps(10),
    ] {
        assert!(problem.solve(&options).is_err(), "{options:?}");
    }
    assert!(Problem::new(d.system().unwrap(), vec![0.0; 3], (0.0, 1.0)).is_err());
    assert!(Problem::new(d.system().unwrap(), d.initial_value(), (1.0, 0.0)).is_err());
    assert!(Problem::new(d.system().unwrap(), [f64::NAN, 0.0], (0.0, 1.0)).is_err());
}

/// A million steps at the step size the solver chose: the energy error stays bounded (no
/// drift). `cargo test --release --test it solve:: -- --ignored --nocapture`.
#[test]
#[ignore = "a million steps: run in release"]
fn energy_is_bounded_over_a_million_chosen_steps() {
    let d = Duffing::new(20.0, 0.07).unwrap();
    let t_end = 7.5e4;
    let problem = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, t_end)).unwrap();
    let times: Vec<f64> = (0..=100).map(|i| i as f64 * t_end / 100.0).collect();
    let sol = problem
        .solve(&Options::tolerance(1e-10).t_eval(times))
        .unwrap();
    let e = sol.energy.as_ref().unwrap();
    let first_half = e[..50].iter().map(|x| (x - e[0]).abs()).fold(0.0, f64::max);
    let second_half = e[50..].iter().map(|x| (x - e[0]).abs()).fold(0.0, f64::max);
    eprintln!(
        "EC{}P h = {:.4e}, {} steps: |H − H0| ≤ {first_half:.3e} (first half), \
         {second_half:.3e} (second half), relative {:.3e}",
        sol.r,
        sol.h,
        sol.stats.steps,
        sol.energy_error().unwrap()
    );
    assert!(sol.stats.steps >= 1_000_000);
    assert!(sol.energy_error().unwrap() < 1e-12);
}

/// A clock τ (τ' = 1) drives an oscillator u'' = −(1 + 400 e^{−((τ − 8)/0.4)²}) u whose
/// frequency rises twentyfold around t = 8: smooth, but the error is made late in the span.
#[allow(clippy::type_complexity)] // the closure's type cannot be named in an alias
fn late_burst() -> (
    Semilinear<Dense, impl Fn(&[f64], &mut [f64]) + Clone>,
    Vec<f64>,
) {
    let a = DMatrix::from_row_slice(3, 3, &[0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    let g = |y: &[f64], out: &mut [f64]| {
        let bump = 400.0 * (-((y[2] - 8.0) / 0.4).powi(2)).exp();
        out[0] = 0.0;
        out[1] = -bump * y[0];
        out[2] = 1.0;
    };
    (
        Semilinear::new(Dense::new(a).unwrap(), g),
        vec![1.0, 0.0, 0.0],
    )
}

/// Pilots cost less than the verified run they choose (the returned run and its checking runs;
/// a pilot runs both too), on the paper's problems over the tolerances the sweep uses. Against
/// the returned run alone the pilot costs more on the shortest runs: NLS at 1e-8 takes 66 steps,
/// and its pilot 4097 evaluations of g against the run's 2796 (2026-11-27).
#[test]
fn pilots_cost_less_than_the_run() {
    let d = Duffing::new(20.0, 0.07).unwrap();
    let duffing = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, 1000.0)).unwrap();
    let n = Nls::new(128).unwrap();
    let nls = Problem::new(n.system().unwrap(), n.initial_value(), (0.0, 10.0)).unwrap();
    for k in [4, 6, 8, 10] {
        let tol = 10f64.powi(-k);
        let options = Options::tolerance(tol).t_eval([1000.0]);
        let sol = duffing.solve(&options).unwrap();
        let run = sol.stats.g_evals + sol.stats.check_g_evals;
        eprintln!(
            "duffing 1e-{k}: pilot {} g, run {} g ({run} with its checks)",
            sol.stats.pilot_g_evals, sol.stats.g_evals
        );
        assert!(sol.stats.pilot_g_evals <= run, "duffing 1e-{k}");
        let sol = nls.solve(&Options::tolerance(tol).t_eval([10.0])).unwrap();
        let run = sol.stats.g_evals + sol.stats.check_g_evals;
        eprintln!(
            "nls 1e-{k}: pilot {} g, run {} g ({run} with its checks)",
            sol.stats.pilot_g_evals, sol.stats.g_evals
        );
        assert!(sol.stats.pilot_g_evals <= run, "nls 1e-{k}");
    }
}

/// A pilot round never measures again a step it measured for the same order: where the stage
/// iteration fails above a step measured within the target (stiff_g, λ large, at 1e−3: EC5P
/// fails at h = 0.0113 above 0.0057), the rounds end with that step; they used to go down to
/// h / 4 and climb back to the step measured before (27 % of this solve's g were pilots, 33 %
/// before).
#[test]
fn a_pilot_measures_no_step_twice() {
    use std::sync::{Arc, Mutex};
    let case = crate::common_suite::odes::stiff_in_g();
    let lines = Arc::new(Mutex::new(Vec::<String>::new()));
    let sink = Arc::clone(&lines);
    let options = Options::tolerance(1e-3).trace(move |l| sink.lock().unwrap().push(l.to_owned()));
    let sol = case.solve(options).expect("stiff_g at 1e-3 is verified");
    let lines = lines.lock().unwrap();
    let lines: Vec<&str> = lines
        .iter()
        .filter_map(|l| l.strip_prefix("solve: pilot EC"))
        .collect();
    // "pilot EC5P round 2: h = 2.8297e-3, 8 steps, ..." and "pilot EC5P h = ...: a step failed".
    let mut seen = std::collections::BTreeSet::new();
    let mut failures = 0;
    for l in &lines {
        failures += usize::from(l.contains("a step failed"));
        let Some((order, rest)) = l.split_once(' ') else {
            continue;
        };
        let Some(h) = rest
            .split("h = ")
            .nth(1)
            .and_then(|s| s.split([',', ':']).next())
        else {
            continue;
        };
        if l.contains(" round ") {
            assert!(
                seen.insert((order.to_owned(), h.to_owned())),
                "measured twice: {l}"
            );
        }
    }
    assert!(
        failures > 0,
        "the case no longer has a failing pilot step: {lines:?}"
    );
    let share = sol.stats.pilot_g_evals as f64 / sol.stats.total_g_evals() as f64;
    eprintln!("stiff_g 1e-3: pilots {:.1} % of all g", 100.0 * share);
    assert!(share <= 0.30, "pilots {share}");
}

/// A terminal event at t = 2.25 in a span of 10⁴ ends the work: everything the solve
/// evaluates (pilots, checks, discarded tries) stays within a small multiple of what a
/// verified run to t = 2.25 alone costs.
#[test]
fn an_early_terminal_event_ends_the_work_too() {
    let d = Duffing::default();
    let half_period = 2.0 * ecr::special::elliptic_k(d.elliptic_parameter()).unwrap() / d.omega();
    let stop = 2.25;
    let event = move |t: f64, _: &[f64]| t - stop;
    let long = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, 1e4)).unwrap();
    let sol = long
        .solve(&Options::tolerance(1e-8).event(Event::new(event).terminal()))
        .unwrap();
    assert!(
        matches!(sol.status, Status::Terminated { t, .. } if (t - stop).abs() < 1e-12),
        "{:?}",
        sol.status
    );
    let short = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, stop)).unwrap();
    let alone = short.solve(&Options::tolerance(1e-8)).unwrap();
    let (with_event, without) = (sol.stats.total_g_evals(), alone.stats.total_g_evals());
    eprintln!(
        "span 1e4 with a terminal event at {stop}: {with_event} g-evaluations; the span \
         [0, {stop}] alone: {without} (half period {half_period:.4})"
    );
    assert!(with_event <= 10 * without, "{with_event} vs {without}");
}

/// An answer whose error is made late (after the pilots and the first chunks) is integrated
/// again with a smaller step: the retry is verified and counted, and the observer sees every
/// step of the returned run once, in time order (never a discarded one).
#[test]
fn retries_are_verified_counted_and_never_shown_twice() {
    let (system, y0) = late_burst();
    let problem = Problem::new(system, y0.clone(), (0.0, 10.0)).unwrap();
    let tol = 1e-8;
    let mut seen: Vec<(f64, usize)> = Vec::new();
    let sol = problem
        .solve_with(&Options::tolerance(tol), |step| {
            seen.push((step.t, step.step));
            ControlFlow::Continue(())
        })
        .unwrap();
    assert!(
        seen.windows(2)
            .all(|w| w[1].0 > w[0].0 && w[1].1 == w[0].1 + 1),
        "the observer saw time go backwards or a step twice"
    );
    assert_eq!(
        seen.len(),
        sol.stats.steps,
        "one call per step of the returned run"
    );
    // The answer is verified: against a fine fixed run.
    let reference = problem.solve(&Options::fixed(6, 1e-3)).unwrap();
    let error = scaled_error(sol.last().unwrap(), reference.last().unwrap(), tol);
    eprintln!(
        "late burst, tol {tol:e}: retries {}, discarded {} g, error/tol {error:.3}, estimate \
         {:?}",
        sol.stats.retries, sol.stats.discarded_g_evals, sol.error_estimate
    );
    assert!(sol.stats.retries >= 1 && sol.stats.discarded_g_evals > 0);
    assert!(error <= 10.0, "error / tol = {error}");
    assert!(sol.error_estimates.iter().all(|&e| e <= 1.0));
    // Without an observer, the same: a verified answer, the retries counted.
    let plain = problem.solve(&Options::tolerance(tol)).unwrap();
    let error = scaled_error(plain.last().unwrap(), reference.last().unwrap(), tol);
    assert!(plain.stats.retries >= 1 && error <= 10.0, "{error}");
}

/// A relative tolerance alone (atol = 0) with a component that starts at 0: the relative
/// error there is 0/0 at t₀ only; y₂ = 1 − e^{−t} grows from 0.
#[test]
fn a_relative_tolerance_works_with_zero_components() {
    let a = DMatrix::from_row_slice(2, 2, &[-1.0, 0.0, 1.0, 0.0]);
    let g = |_: &[f64], out: &mut [f64]| out.fill(0.0);
    let system = Semilinear::new(Dense::new(a).unwrap(), g);
    let problem = Problem::new(system, [1.0, 0.0], (0.0, 5.0)).unwrap();
    let sol = problem
        .solve(&Options::tolerance(1e-8).atol(0.0).t_eval([1.0, 5.0]))
        .unwrap();
    let exact = [(-5.0f64).exp(), 1.0 - (-5.0f64).exp()];
    let y = sol.last().unwrap();
    for (v, e) in y.iter().zip(exact) {
        assert!((v - e).abs() <= 1e-8 * e.abs(), "{v} vs {e}");
    }
}

/// A tolerance below what f64 reaches for the problem is refused, with the reachable floor
/// in the message.
#[test]
fn a_tolerance_below_the_f64_floor_is_refused() {
    let d = Duffing::default();
    let problem = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, 10.0)).unwrap();
    for tol in [1e-17, 1e-20, 1e-50] {
        let message = problem
            .solve(&Options::tolerance(tol))
            .map(|sol| format!("Ok with estimate {:?}", sol.stats))
            .expect_err("a tolerance below the f64 floor");
        let message = message.to_string();
        assert!(
            message.contains("below what f64 can verify") && message.contains("e"),
            "tol {tol:e}: {message}"
        );
    }
}

/// Lotka–Volterra u' = u(2/3 − 4/3 v), v' = v(u − 1) (no linear part).
fn lotka_volterra() -> Problem<impl System> {
    let system = Semilinear::new(
        ecr::runtime::operator::Zero::new(2),
        |y: &[f64], g: &mut [f64]| {
            g[0] = y[0] * (2.0 / 3.0 - 4.0 / 3.0 * y[1]);
            g[1] = y[1] * (y[0] - 1.0);
        },
    );
    Problem::new(system, [0.9, 0.9], (0.0, 50.0)).unwrap()
}

/// 200 evenly spaced outputs do not pick the step: the tolerance does (when every output was a
/// meeting point of the checking runs, h was a sixth of the spacing at 1e-8 and 1e-10 alike,
/// and the two runs were bit-identical). Each answer is within its tolerance of a reference.
#[test]
fn output_times_do_not_pick_the_step() {
    let problem = lotka_volterra();
    let times = linspace(0.0, 50.0, 200);
    let reference = problem
        .solve(&Options::fixed(8, 50.0 / 20_000.0).t_eval(times.clone()))
        .unwrap();
    let mut steps = Vec::new();
    for tol in [1e-8, 1e-10] {
        let sol = problem
            .solve(&Options::tolerance(tol).t_eval(times.clone()))
            .unwrap();
        let err = sol
            .y
            .iter()
            .zip(&reference.y)
            .flat_map(|(a, b)| {
                a.iter()
                    .zip(b)
                    .map(|(x, y)| (x - y).abs() / (tol * (1.0 + y.abs())))
            })
            .fold(0.0, f64::max);
        eprintln!(
            "tol {tol:e}: EC{}P h = {:.4e}, {} steps, error {err:.3e} of the tolerance",
            sol.r, sol.h, sol.stats.steps
        );
        assert!(err <= 1.0, "tol {tol:e}: error {err} times the tolerance");
        steps.push((sol.r, sol.stats.steps));
    }
    assert_ne!(steps[0], steps[1], "the same run at 1e-8 and 1e-10");
}

/// `Solution::at` between grid points of a verified solve reads the grid's Hermite interpolant
/// where the grid resolves the solution (here Lotka–Volterra at 1e-8 with EC2P, h = 0.025):
/// no step of the method for nearly all calls (each call stepped from the grid point before
/// with a φ-bank of its own), within the tolerance of a reference. (With the order `solve`
/// picks, EC5P at h = 0.49, the grid does not resolve it: the interpolant's estimate is 40 to
/// 1e4 tolerances and `at` steps.)
#[test]
fn at_between_grid_points_takes_no_steps() {
    let problem = lotka_volterra();
    let tol = 1e-8;
    let sol = problem
        .solve(
            &Options::tolerance(tol)
                .method(ecr::runtime::solve::Method::Order(2))
                .dense_output(),
        )
        .unwrap();
    let mut times: Vec<f64> = (0..1000)
        .map(|k| 50.0 * ((k as f64 * 0.618_033_988_749_895) % 1.0))
        .collect();
    times.sort_by(f64::total_cmp);
    let reference = problem
        .solve(&Options::fixed(8, 50.0 / 20_000.0).t_eval(times.clone()))
        .unwrap();
    let mut worst = 0.0_f64;
    for (t, exact) in times.iter().zip(&reference.y) {
        let y = sol.at(*t).unwrap();
        for (a, b) in y.iter().zip(exact) {
            worst = worst.max((a - b).abs() / (tol * (1.0 + b.abs())));
        }
    }
    let (steps, g) = sol.dense_evaluations();
    eprintln!("at(): worst error {worst:.3e} of the tolerance, {steps} steps, {g} g");
    assert!(worst <= 1.0, "error {worst} times the tolerance");
    assert!(steps <= 100, "{steps} steps of the method for 1000 calls");
}

/// 10⁴ unevenly spaced output times cost little more than the solve without them (each took
/// a step with its own φ-bank: 478× the run with a fixed step, 592× with a tolerance).
#[test]
#[ignore = "target not met: 17.1x the g-evaluations of the solve without output times on 2026-12-03 (24.6x at 2f5b7cf, 20.7x at 725d8c0; Duffing omega = 20, EC6P at h*omega = 0.8: the grid's Hermite interpolant holds at few outputs, the others step both runs); cargo test -p ecr --test it many_output_times_cost_little -- --ignored --nocapture"]
fn many_output_times_cost_little() {
    let d = Duffing::new(20.0, 0.07).unwrap();
    let problem = Problem::new(d.system().unwrap(), d.initial_value(), (0.0, 100.0)).unwrap();
    let options = || Options::tolerance(1e-8);
    let plain = problem.solve(&options()).unwrap();
    let mut sorted: Vec<f64> = (0..10_000)
        .map(|k| 100.0 * ((k as f64 * 0.618_033_988_749_895) % 1.0))
        .collect();
    sorted.sort_by(f64::total_cmp);
    let with = problem.solve(&options().t_eval(sorted)).unwrap();
    let (a, b) = (plain.stats.total_g_evals(), with.stats.total_g_evals());
    eprintln!(
        "g evaluations: {a} without output times, {b} with 10^4 ({:.2}x)",
        b as f64 / a as f64
    );
    assert!(b as f64 <= 1.5 * a as f64, "{b} against {a}");
}
