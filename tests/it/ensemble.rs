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

/// Counts that no vector of results can hold are refused with `Err` before the results are
/// allocated, even when the progress callback would stop the work after two members (issue
/// 52: `usize::MAX` panicked with "capacity overflow" and 2·10⁹ aborted on 128 GB).
#[test]
fn huge_member_counts_are_refused_before_the_results_are_allocated() {
    let system = HenonHeiles::default().system().unwrap();
    let options = Options::fixed(2, 0.05);
    for n in [usize::MAX, 2_000_000_000] {
        let made = AtomicUsize::new(0);
        let ensemble = Ensemble::new((), n, |_: &(), i| {
            made.fetch_add(1, Ordering::Relaxed);
            Problem::new(&system, [0.0, 1e-3 * (i % 7) as f64, 0.4, 0.0], (0.0, 0.1))
        });
        let stop = Control::new().progress(|p| {
            if p.done >= 2 {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        });
        let e = ensemble.solve_with(&options, &stop, |_, _| 0.0_f64);
        assert!(
            matches!(&e, Err(ecr::runtime::Error::InvalidInput(m)) if m.contains("members")),
            "{n} members: {:?}",
            e.map(|r| r.members.len())
        );
        assert_eq!(made.load(Ordering::Relaxed), 0, "{n} members");
    }
}

/// A dense linear operator shared by every member (d = 8: four coupled oscillators, the
/// members differing in y₀): shared φ-banks give the same bits as each member building its
/// own, on one thread and on two.
#[test]
fn shared_banks_give_the_same_bits() {
    use ecr::runtime::nalgebra::DMatrix;
    use ecr::runtime::operator::Dense;
    let d = 8;
    let mut a = DMatrix::zeros(d, d);
    for i in 0..d / 2 {
        a[(i, d / 2 + i)] = 1.0;
        a[(d / 2 + i, i)] = -(1.0 + i as f64);
        if i + 1 < d / 2 {
            a[(d / 2 + i, i + 1)] = 0.1;
            a[(d / 2 + i + 1, i)] = 0.1;
        }
    }
    let system = Semilinear::new(Dense::new(a).unwrap(), |y: &[f64], g: &mut [f64]| {
        g.fill(0.0);
        for i in 0..4 {
            g[4 + i] = -y[i].powi(3);
        }
    });
    let make = |_: &(), i: usize| {
        let mut y0 = vec![0.0; 8];
        y0[i % 4] = 0.1 + 0.01 * i as f64;
        Problem::new(&system, y0, (0.0, 2.0))
    };
    for options in [
        Options::fixed(3, 0.1).t_eval([1.0, 2.0]),
        Options::tolerance(1e-8).t_eval([1.0, 2.0]),
    ] {
        let own = Ensemble::new((), 16, make)
            .solve(&options, |_, s| bits(s))
            .unwrap();
        assert_eq!(own.verified(), 16);
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let ensemble = Ensemble::new((), 16, make).share_banks();
            assert!(ensemble.shares_banks());
            let shared = pool
                .install(|| ensemble.solve(&options, |_, s| bits(s)))
                .unwrap();
            assert_eq!(outcomes(&shared), outcomes(&own), "{threads} threads");
        }
    }
}

/// `solve_in_order` hands the members on in member order (of a part, from `start_at`), and
/// its memory does not depend on the number of members: 2·10⁹ members with a callback that
/// stops after a few are streamed without any allocation of that size.
#[test]
fn streams_come_in_member_order_and_stop() {
    let system = HenonHeiles::default().system().unwrap();
    let options = Options::fixed(2, 0.05).t_eval([0.1]);
    let make = |_: &(), i: usize| {
        Problem::new(&system, [0.0, 1e-3 * (i % 7) as f64, 0.4, 0.0], (0.0, 0.1))
    };
    let ensemble = Ensemble::new((), 50, make);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    let mut seen = Vec::new();
    let control = Control::new().part(1, 3).start_at(20);
    let streamed = pool
        .install(|| {
            ensemble.solve_in_order(
                &options,
                &control,
                |i, _| i,
                |m| {
                    assert_eq!(*m.outcome.as_ref().unwrap(), m.index);
                    seen.push(m.index);
                    Ok(())
                },
            )
        })
        .unwrap();
    assert_eq!(seen, (22..50).step_by(3).collect::<Vec<_>>());
    assert_eq!((streamed.delivered, streamed.skipped), (10, 7));
    assert!(!streamed.stopped);

    let huge = Ensemble::new((), 2_000_000_000, make);
    let stop = Control::new().progress(|p| {
        if p.done >= 3 {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    });
    // One thread: the members finish in member order, so that the stop comes after the
    // third (with more, the third to finish may be one of another thread's range, and the
    // stream ends at the first member not run).
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let mut n = 0;
    let streamed = one
        .install(|| {
            huge.solve_in_order(
                &options,
                &stop,
                |_, _| (),
                |m| {
                    assert_eq!(m.index, n);
                    n += 1;
                    Ok(())
                },
            )
        })
        .unwrap();
    assert!(streamed.stopped);
    assert_eq!(n, 3, "{n} members delivered");
}

/// `write_table` stopped part-way (a progress callback that breaks) leaves no table but an
/// unfinished one; `Control::resume` keeps its rows and solves the rest: the table equals
/// an uninterrupted run's byte for byte, for a whole table and a part.
#[test]
fn tables_stopped_and_resumed_equal_uninterrupted_ones() {
    use ecr::runtime::ensemble::{Cell, Column, Table};
    let system = HenonHeiles::default().system().unwrap();
    let options = Options::tolerance(1e-7).t_eval([2.0]);
    let make =
        |_: &(), i: usize| Problem::new(&system, [0.0, 5e-4 * i as f64, 0.4, 0.0], (0.0, 2.0));
    let ensemble = Ensemble::new((), 700, make).share_banks();
    // Outputs of members without a state (none here) would be NaN, not a panic.
    let output = |_: usize, s: &Solution| {
        vec![
            Cell::F64(s.last().map_or(f64::NAN, |y| y[1])),
            s.error_estimate.into(),
        ]
    };
    let dir = std::env::temp_dir().join(format!("ecr-table-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let read = |p: &std::path::Path| std::fs::read(p).unwrap();
    for part in [None, Some((1, 2))] {
        let table = || {
            let t = Table::new(
                "q2 from 5e-4 i",
                vec![Column::f64("q2"), Column::f64("est")],
            )
            .inputs(vec![Column::f64("q2_0")], |i, cells| {
                cells.push(Cell::F64(5e-4 * i as f64))
            });
            if part.is_some() { t.as_part() } else { t }
        };
        let with_part = |c: Control<'static>| match part {
            Some((k, n)) => c.part(k, n),
            None => c,
        };
        let whole = dir.join("whole.csv");
        let report = ensemble
            .write_table(
                &options,
                &with_part(Control::new()),
                &table(),
                output,
                &whole,
            )
            .unwrap();
        assert!(report.complete && report.kept == 0);
        let out = dir.join("resumed.csv");
        let mut kept = Vec::new();
        let mut complete = false;
        for stop_after in [100, 300, 600] {
            let stop = with_part(Control::new().resume()).progress(move |p| {
                if p.done >= stop_after {
                    ControlFlow::Break(())
                } else {
                    ControlFlow::Continue(())
                }
            });
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(1)
                .build()
                .unwrap();
            let r = pool
                .install(|| ensemble.write_table(&options, &stop, &table(), output, &out))
                .unwrap();
            kept.push(r.kept + r.written);
            if r.complete {
                // The part's 350 members: the third run finishes it.
                assert!(r.kept > 0, "{r:?}");
                complete = true;
                break;
            }
            assert!(!out.exists());
        }
        assert!(kept.windows(2).all(|w| w[0] < w[1]), "{kept:?}");
        if !complete {
            let r = ensemble
                .write_table(
                    &options,
                    &with_part(Control::new().resume()),
                    &table(),
                    output,
                    &out,
                )
                .unwrap();
            assert!(r.complete && r.kept > 0, "{r:?}");
        }
        assert!(read(&out) == read(&whole), "part {part:?}");
        std::fs::remove_file(&out).unwrap();
        std::fs::remove_file(&whole).unwrap();
    }
    // Nothing unfinished is left.
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
    std::fs::remove_dir(&dir).unwrap();
}

/// `summarize` keeps the statistics of every output at every output time over the verified
/// members: against the values computed from all the outputs.
#[test]
fn summaries_agree_with_the_outputs() {
    use ecr::runtime::ensemble::Summary;
    let system = HenonHeiles::default().system().unwrap();
    let options = Options::tolerance(1e-7).t_eval([1.0, 2.0]);
    let make =
        |_: &(), i: usize| Problem::new(&system, [0.0, 0.005 * i as f64, 0.4, 0.0], (0.0, 2.0));
    let ensemble = Ensemble::new((), 60, make);
    let all = ensemble.solve(&options, |_, s| s.y.clone()).unwrap();
    let summary = Summary::new(2, 4, &[0.0, 0.5, 1.0]).unwrap();
    let result = ensemble
        .summarize(&options, &Control::new(), summary, |_, s, values| {
            for (t, y) in s.y.iter().enumerate() {
                values[4 * t..4 * t + 4].copy_from_slice(y);
            }
        })
        .unwrap();
    assert_eq!(result.summary.members(), 60);
    for t in 0..2 {
        for c in 0..4 {
            let mut v: Vec<f64> = all
                .members
                .iter()
                .map(|m| m.outcome.as_ref().unwrap()[t][c])
                .collect();
            let s = result.summary.get(t, c);
            let mean = v.iter().sum::<f64>() / 60.0;
            v.sort_by(f64::total_cmp);
            assert_eq!((s.count, s.min, s.max), (60, v[0], v[59]));
            assert!(
                (s.mean - mean).abs() <= 1e-14 * mean.abs().max(1e-3),
                "{t} {c}"
            );
            let median = v[29]; // rank ⌊0.5 · 59⌋
            let q = s.quantiles[1].1;
            assert!(
                (q - median).abs() <= 1e-3 * median.abs() + 1e-300,
                "{q} {median}"
            );
        }
    }
}
