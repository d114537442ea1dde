//! Ensembles on every core (`ecr_runtime::ensemble`), measured; `cargo bench --bench ensemble`
//! (a few minutes on 2 cores), or one part: `-- scaling`, `-- memory`, `-- banks`.
//!
//! - scaling: 10⁴ Hénon–Heiles members at the energy 1/8 from a 100 × 100 grid of (q2, p2) ∈
//!   [−0.3, 0.3]² (q1 = 0, p1 from the energy), each to t = 10 at the tolerance 1e−8, its final
//!   q2 kept: a plain loop of `Problem::solve` against the ensemble on a pool of 1 thread (the
//!   ensemble's overhead per member) and of 2 threads (the speed-up). The fastest of 3 rounds,
//!   the three interleaved in each round, so that a slow phase of a shared machine falls on
//!   all three alike.
//! - memory: 10⁶ members of the same kind to t = 1 at the tolerance 1e−6 (varying q2 and p2
//!   over a 1000 × 1000 grid), their final q2 kept (a scalar): the peak resident memory of the
//!   process (`VmHWM` in `/proc/self/status`, Linux), which must stay under 200 MB.
//! - banks (criterion): 10⁴ members of one linear operator, a dense 8 × 8 A (four coupled
//!   oscillators with a cubic nonlinearity, members differing in y₀), each solved on one
//!   thread with its own φ-banks (as every solve did before `Ensemble::share_banks`) and with
//!   the banks shared: with a fixed method (EC3P, h = 0.05, T = 1) and to the tolerance 1e−8
//!   (T = 1).

use criterion::Criterion;
use ecr::problems::{HenonHeiles, HenonHeilesSystem};
use ecr::runtime::ensemble::{Ensemble, MemberResult};
use ecr::runtime::nalgebra::DMatrix;
use ecr::runtime::operator::Dense;
use ecr::runtime::solve::{Options, Problem};
use ecr::runtime::system::Semilinear;
use std::time::Instant;

const ENERGY: f64 = 0.125;

/// Member i of a `side` × `side` grid of (q2, p2) over [−0.3, 0.3]², to `t_end`.
fn member(
    system: &HenonHeilesSystem,
    side: usize,
    t_end: f64,
    i: usize,
) -> ecr::runtime::Result<Problem<&HenonHeilesSystem>> {
    let at = |k: usize| -0.3 + 0.6 * k as f64 / (side - 1) as f64;
    let (q2, p2) = (at(i / side), at(i % side));
    let rest = HenonHeiles::default().energy(&[0.0, q2, 0.0, p2]);
    let p1 = (2.0 * (ENERGY - rest)).sqrt();
    Problem::new(system, [0.0, q2, p1, p2], (0.0, t_end))
}

/// The peak resident memory of this process in bytes (`VmHWM`), where Linux tells it.
fn peak_resident() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool")
}

fn scaling() {
    let (side, t_end, tol) = (100, 10.0, 1e-8);
    let n = side * side;
    let system = HenonHeiles::default().system().expect("the system");
    let options = Options::tolerance(tol).t_eval([t_end]);
    let final_q2 = |sol: &ecr::runtime::solve::Solution| sol.last().map_or(f64::NAN, |y| y[1]);
    let plain_loop = || {
        let mut out = Vec::with_capacity(n);
        for i in 0..n {
            let problem = member(&system, side, t_end, i).expect("a member");
            out.push(match problem.solve(&options) {
                Ok(sol) => Some(final_q2(&sol.into_data())),
                Err(_) => None,
            });
        }
        out
    };
    let ensemble = Ensemble::new((), n, |_: &(), i| member(&system, side, t_end, i));
    let on = |threads: usize| {
        pool(threads).install(|| {
            ensemble
                .solve(&options, |_, sol| final_q2(sol))
                .expect("valid options")
        })
    };
    let (mut t_loop, mut t_one, mut t_two) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
    let mut checked = false;
    for round in 1..=3 {
        let start = Instant::now();
        let looped = plain_loop();
        t_loop = t_loop.min(start.elapsed().as_secs_f64());
        let start = Instant::now();
        let one = on(1);
        t_one = t_one.min(start.elapsed().as_secs_f64());
        let start = Instant::now();
        let two = on(2);
        t_two = t_two.min(start.elapsed().as_secs_f64());
        if !checked {
            // The same numbers from all three.
            let bits = |r: &[MemberResult<f64>]| -> Vec<Option<u64>> {
                r.iter()
                    .map(|m| m.outcome.as_ref().ok().map(|v| v.to_bits()))
                    .collect()
            };
            let looped: Vec<Option<u64>> = looped.iter().map(|v| v.map(f64::to_bits)).collect();
            assert_eq!(bits(&one.members), looped);
            assert_eq!(bits(&two.members), looped);
            println!(
                "{n} members, {} verified, {} steps and {} evaluations of g in all",
                one.verified(),
                one.stats.steps,
                one.stats.total_g_evals()
            );
            checked = true;
        }
        println!(
            "round {round}: loop {t_loop:.3} s, 1 thread {t_one:.3} s, 2 threads {t_two:.3} s (fastest so far)"
        );
    }
    println!(
        "per member: plain loop {:.1} µs, ensemble on 1 thread {:.1} µs (overhead {:+.1} %), on \
         2 threads {:.1} µs: 2 threads {:.2}× 1 thread",
        t_loop / n as f64 * 1e6,
        t_one / n as f64 * 1e6,
        (t_one / t_loop - 1.0) * 100.0,
        t_two / n as f64 * 1e6,
        t_one / t_two
    );
}

fn memory() {
    let (side, t_end, tol) = (1000, 1.0, 1e-6);
    let n = side * side;
    let system = HenonHeiles::default().system().expect("the system");
    let options = Options::tolerance(tol).t_eval([t_end]);
    let before = peak_resident();
    let ensemble = Ensemble::new((), n, |_: &(), i| member(&system, side, t_end, i));
    let start = Instant::now();
    let result = ensemble
        .solve(&options, |_, sol| sol.last().map_or(f64::NAN, |y| y[1]))
        .expect("valid options");
    let seconds = start.elapsed().as_secs_f64();
    let after = peak_resident();
    let mb = |b: Option<u64>| {
        b.map_or("unknown".to_string(), |b| {
            format!("{:.1} MB", b as f64 / 1e6)
        })
    };
    println!(
        "{n} members ({} verified) on {} threads in {seconds:.1} s; {} bytes per result \
         (MemberResult<f64>); peak resident memory {} before, {} after (limit 200 MB)",
        result.verified(),
        rayon::current_num_threads(),
        std::mem::size_of::<MemberResult<f64>>(),
        mb(before),
        mb(after)
    );
    if let Some(peak) = after {
        assert!(
            peak < 200_000_000,
            "peak resident memory {} over 200 MB",
            mb(after)
        );
    }
}

/// 10⁴ members of one dense 8 × 8 operator, with their own φ-banks or shared ones.
fn banks() {
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
    let system = Semilinear::new(
        Dense::new(a).expect("an operator"),
        |y: &[f64], g: &mut [f64]| {
            g.fill(0.0);
            for i in 0..4 {
                g[4 + i] = -y[i].powi(3);
            }
        },
    );
    let n = 10_000;
    let make = |_: &(), i: usize| {
        let mut y0 = vec![0.0; 8];
        y0[i % 4] = 0.1 + 0.5 * (i as f64 / n as f64);
        Problem::new(&system, y0, (0.0, 1.0))
    };
    let one = pool(1);
    let mut c = Criterion::default()
        .sample_size(10)
        .measurement_time(std::time::Duration::from_secs(30))
        .configure_from_args();
    let mut group = c.benchmark_group("banks");
    for (name, options) in [
        ("fixed", Options::fixed(3, 0.05).t_eval([1.0])),
        ("tol", Options::tolerance(1e-8).t_eval([1.0])),
    ] {
        for share in [false, true] {
            let ensemble = Ensemble::new((), n, make);
            let ensemble = if share {
                ensemble.share_banks()
            } else {
                ensemble
            };
            let id = format!("{name}/{}", if share { "shared" } else { "own" });
            group.bench_function(id, |b| {
                b.iter(|| {
                    let r = one.install(|| {
                        ensemble
                            .solve(&options, |_, s| s.last().map_or(f64::NAN, |y| y[0]))
                            .expect("valid options")
                    });
                    assert_eq!(r.verified(), n);
                    r
                })
            });
        }
    }
    group.finish();
}

fn main() {
    let parts: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let all = parts.is_empty();
    if all || parts.iter().any(|p| p == "scaling") {
        scaling();
    }
    if all || parts.iter().any(|p| p == "memory") {
        memory();
    }
    if all || parts.iter().any(|p| p == "banks") {
        banks();
    }
}
