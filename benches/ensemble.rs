//! Ensembles on every core (`ecr_runtime::ensemble`), measured; `cargo bench --bench ensemble`
//! (about a minute on 2 cores), or one part: `-- scaling`, `-- memory`.
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

use ecr::problems::{HenonHeiles, HenonHeilesSystem};
use ecr::runtime::ensemble::{Ensemble, MemberResult};
use ecr::runtime::solve::{Options, Problem};
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
}
