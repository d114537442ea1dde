//! Ensembles (`ecr_runtime::ensemble`): the same results bit for bit with 1, 2 and 4 threads
//! (also on the concurrent stage path), members that fail reported as such while the others
//! complete, a progress callback that stops the work.

use ecr::problems::HenonHeiles;
use ecr::runtime::ensemble::{Control, Ensemble, EnsembleSolution, MemberError};
use ecr::runtime::operator::Zero;
use ecr::runtime::solve::{Options, Problem, Solution};
use ecr::runtime::stepper::SolverSettings;
use ecr::runtime::system::Semilinear;
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicUsize, Ordering};

/// What the tests keep of a member: every number of its final state, estimate and energy
/// error as bits, and its counts.
type Bits = (Vec<u64>, Option<u64>, Option<u64>, usize, usize);

fn bits(sol: &Solution) -> Bits {
    (
        sol.last().unwrap().iter().map(|v| v.to_bits()).collect(),
        sol.error_estimate.map(f64::to_bits),
        sol.energy_error().map(f64::to_bits),
        sol.stats.steps,
        sol.stats.total_g_evals(),
    )
}

/// The outcomes of an ensemble in member order, comparable bit for bit.
fn outcomes(result: &EnsembleSolution<Bits>) -> Vec<(usize, Result<Bits, String>)> {
    result
        .members
        .iter()
        .map(|m| {
            let o = match &m.outcome {
                Ok(b) => Ok(b.clone()),
                Err(e) => Err(format!("{e}")),
            };
            (m.index, o)
        })
        .collect()
}

/// Hénon–Heiles from a 5 × 4 grid of (q2, p2) at the energy 1/10 (q1 = 0, p1 from the energy),
/// solved on a pool of `threads` threads with `options`.
fn henon_heiles_grid(threads: usize, options: &Options) -> EnsembleSolution<Bits> {
    let system = HenonHeiles::default().system().unwrap();
    let template =
        Problem::new(&system, HenonHeiles::default().initial_value(), (0.0, 8.0)).unwrap();
    let energy = 0.1;
    let ensemble = Ensemble::new(template, 20, |t: &Problem<_>, i| {
        let (q2, p2) = (-0.2 + 0.1 * (i / 4) as f64, -0.15 + 0.1 * (i % 4) as f64);
        let rest = HenonHeiles::default().energy(&[0.0, q2, 0.0, p2]);
        let p1 = (2.0 * (energy - rest)).sqrt();
        Problem::new(*t.system(), [0.0, q2, p1, p2], t.span())
    });
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| ensemble.solve(options, |_, sol| bits(sol)))
        .unwrap()
}

#[test]
fn one_two_and_four_threads_give_the_same_bits() {
    let options = Options::tolerance(1e-7).t_eval([4.0, 8.0]);
    let one = henon_heiles_grid(1, &options);
    assert_eq!(one.verified(), 20, "{:?}", outcomes(&one));
    for threads in [2, 4] {
        let more = henon_heiles_grid(threads, &options);
        assert_eq!(outcomes(&more), outcomes(&one), "{threads} threads");
        assert_eq!(more.stats, one.stats, "{threads} threads");
    }
    // The members are not all alike: the test would see a member solved as another.
    let first = one.members[0].outcome.as_ref().unwrap();
    assert!(
        one.members[1..]
            .iter()
            .all(|m| m.outcome.as_ref().unwrap().0 != first.0)
    );
}

/// The concurrent stage path of large systems (forced here on d = 4, where it evaluates g at
/// the stages as concurrent tasks and splits the φ-combinations over the pool's threads)
/// nested in the ensemble's threads: the same bits with 1, 2 and 4 threads, and the same as
/// the serial path's.
#[test]
fn the_concurrent_stage_path_gives_the_same_bits_on_any_pool() {
    let concurrent = SolverSettings {
        parallel_min_dim: 1,
        ..SolverSettings::default()
    };
    let options = Options::fixed(3, 0.05).t_eval([8.0]).settings(concurrent);
    let serial = henon_heiles_grid(1, &Options::fixed(3, 0.05).t_eval([8.0]));
    let one = henon_heiles_grid(1, &options);
    assert_eq!(one.verified(), 20);
    assert_eq!(outcomes(&one), outcomes(&serial));
    for threads in [2, 4] {
        assert_eq!(
            outcomes(&henon_heiles_grid(threads, &options)),
            outcomes(&one),
            "{threads} threads"
        );
    }
}

/// y' = y² from y(0) = y₀ blows up at t = 1/y₀: over [0, 1], members with y₀ ≥ 1 meet the
/// singularity; a NaN y₀ cannot be made; a panic in the member's g is caught. The others
/// complete, verified and accurate, whatever happened to their neighbours.
#[test]
fn failing_members_are_reported_while_the_others_complete() {
    let square = |y: &[f64], g: &mut [f64]| {
        // Only member 6 meets −0.75 (the others stay positive): it panics at once.
        assert!(y[0] != -0.75, "g refuses -0.75");
        g[0] = y[0] * y[0];
    };
    let system = Semilinear::new(Zero::new(1), square);
    let y0s = [0.1, 0.5, 2.0, f64::NAN, 0.25, 4.0, -0.75, 0.8];
    let template = Problem::new(&system, [0.1], (0.0, 1.0)).unwrap();
    let ensemble = Ensemble::new(template, y0s.len(), |t: &Problem<_>, i| {
        Problem::new(*t.system(), [y0s[i]], t.span())
    });
    let tol = 1e-8;
    let result = ensemble
        .solve(&Options::tolerance(tol).t_eval([1.0]), |_, sol| {
            // An unverified member's best solution may end before t = 1, without an output.
            sol.last().map(|y| y[0])
        })
        .unwrap();
    for m in &result.members {
        let y0 = y0s[m.index];
        match &m.outcome {
            Ok(y) => {
                assert!(
                    y0 < 1.0 && y0 != -0.75,
                    "member {} (y0 = {y0}) verified",
                    m.index
                );
                let y = y.expect("a verified member has its output at t = 1");
                let exact = y0 / (1.0 - y0);
                assert!(
                    (y - exact).abs() <= 2.0 * tol * (1.0 + exact.abs()),
                    "y0 = {y0}: {y} against {exact}"
                );
            }
            // Past the singularity: not verified (with the best solution before it) or
            // failed, never a number presented as an answer.
            Err(MemberError::Unverified { .. } | MemberError::Failed(_)) if y0 >= 1.0 => {}
            Err(MemberError::Failed(e)) if y0.is_nan() => {
                assert!(e.to_string().contains("y0"), "{e}");
            }
            Err(MemberError::Panicked(msg)) if y0 == -0.75 => {
                assert!(msg.contains("g refuses -0.75"), "{msg}");
            }
            other => panic!("member {} (y0 = {y0}): {other:?}", m.index),
        }
    }
    assert_eq!(result.verified(), 4);
    assert!(result.stats.g_evals > 0);
}

/// A progress callback sees every member once, and stopping leaves the members not started
/// as not run (and only those).
#[test]
fn progress_sees_every_member_and_can_stop_the_work() {
    let options = Options::tolerance(1e-6).t_eval([1.0]);
    let system = HenonHeiles::default().system().unwrap();
    let template =
        Problem::new(&system, HenonHeiles::default().initial_value(), (0.0, 1.0)).unwrap();
    let ensemble = Ensemble::new(template, 40, |t: &Problem<_>, i| {
        Problem::new(*t.system(), [0.0, 0.01 * i as f64, 0.4, 0.0], t.span())
    });
    let calls = AtomicUsize::new(0);
    let control = Control::new().progress(|p| {
        calls.fetch_add(1, Ordering::Relaxed);
        assert_eq!(p.total, 40);
        ControlFlow::Continue(())
    });
    let all = ensemble.solve_with(&options, &control, |_, _| ()).unwrap();
    assert_eq!(calls.load(Ordering::Relaxed), 40);
    assert!(!all.stopped && all.verified() == 40);

    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let stop_at_5 = Control::new().progress(|p| {
        if p.done >= 5 {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    });
    let stopped = pool
        .install(|| ensemble.solve_with(&options, &stop_at_5, |_, _| ()))
        .unwrap();
    assert!(stopped.stopped);
    assert_eq!(stopped.members.len(), 40);
    assert_eq!(stopped.verified(), 5, "one thread: five members, then none");
    let not_run = stopped
        .members
        .iter()
        .filter(|m| matches!(m.outcome, Err(MemberError::NotRun)))
        .count();
    assert_eq!(not_run, 35);
}
