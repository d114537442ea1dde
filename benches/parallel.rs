//! Serial vs concurrent stage path of the ECrP stepper on large systems (the FFT operators of
//! the NLS), paired: each case builds two steppers that differ only in
//! `SolverSettings::parallel_min_dim` (`usize::MAX`: serial; 0: concurrent), times runs of a
//! few steps from the same start interleaved in rounds, and prints the fastest run of each
//! (a shared machine's interruptions only add time) and their ratio; the two end states are
//! checked to agree bit for bit.
//!
//! `cargo bench --bench parallel` runs every case; a filter argument runs some:
//! `cargo bench --bench parallel -- nls2d` (the 2D NLS, 512 × 512, EC2P and EC3P),
//! `-- nls1d` (the 1D NLS, N = 2^16), `-- threshold` (the 1D NLS from N = 2^5 to 2^14: where
//! the concurrent path starts to pay, which sets `PARALLEL_MIN_DIM`). The steppers use the
//! extrapolating predictor, as `ecr bench scaling` does, and h = 1/200. Each line also
//! gives the machine's capacity at the time: how much work two threads did in the time one
//! did it alone (2.00 with both cores free; on a shared machine, less).

use ecr::runtime::problems::{Nls, Nls2d};
use ecr::runtime::stepper::{EcStepper, Predictor, SolverSettings};
use ecr::runtime::system::System;
use std::hint::black_box;
use std::time::Instant;

const H: f64 = 1.0 / 200.0;

fn settings(parallel: bool) -> SolverSettings {
    SolverSettings {
        predictor: Predictor::Extrapolate,
        parallel_min_dim: if parallel { 0 } else { usize::MAX },
        ..SolverSettings::default()
    }
}

/// Seconds and sweeps of `steps` steps from `y0`, and the end state.
fn run<S: System>(st: &mut EcStepper<S>, y0: &[f64], steps: usize) -> (f64, usize, Vec<f64>) {
    let mut y = y0.to_vec();
    let mut sweeps = 0;
    let t = Instant::now();
    for _ in 0..steps {
        sweeps += st.step(black_box(&mut y)).unwrap().sweeps;
    }
    (t.elapsed().as_secs_f64(), sweeps, y)
}

/// The fastest of `rounds` interleaved runs of `steps` steps, serial and concurrent, of ECrP
/// with s = r on the system `make()` builds; returns (serial, concurrent) seconds per step.
fn paired<S: System>(
    label: &str,
    make: impl Fn() -> S,
    y0: &[f64],
    r: usize,
    steps: usize,
    rounds: usize,
) -> (f64, f64) {
    let mut serial = EcStepper::with_nodes(make(), r, r, H, settings(false)).unwrap();
    let mut par = EcStepper::with_nodes(make(), r, r, H, settings(true)).unwrap();
    // Warm-up (caches, page faults of the buffers, rayon's threads).
    run(&mut serial, y0, 1);
    run(&mut par, y0, 1);
    let (mut ts, mut tp, mut sweeps) = (f64::INFINITY, f64::INFINITY, 0);
    for _ in 0..rounds {
        let (t, sw, ys) = run(&mut serial, y0, steps);
        ts = ts.min(t);
        let (t, _, yp) = run(&mut par, y0, steps);
        tp = tp.min(t);
        assert!(
            ys.iter().zip(&yp).all(|(a, b)| a.to_bits() == b.to_bits()),
            "{label}: serial and concurrent steps differ"
        );
        sweeps = sw;
    }
    let (ts, tp) = (ts / steps as f64, tp / steps as f64);
    println!(
        "{label}, EC{r}P, d = {}: serial {:.3} ms/step, concurrent {:.3} ms/step, speed-up \
         {:.2} (fastest of {rounds} interleaved runs of {steps} steps, {:.1} sweeps/step; \
         machine capacity {:.2})",
        y0.len(),
        ts * 1e3,
        tp * 1e3,
        ts / tp,
        sweeps as f64 / steps as f64,
        capacity(5)
    );
    (ts, tp)
}

/// About 10 ms of arithmetic on one core.
fn work() -> f64 {
    (0..4_000_000u64).map(|i| (i as f64).sqrt()).sum()
}

/// How much work 2 threads of rayon's pool do in the time one does it alone, the fastest of
/// `rounds` tries: 2.0 when both cores are free, less when other work holds them (the machine
/// is shared). Printed beside each result: a speed-up can only be judged against it.
fn capacity(rounds: usize) -> f64 {
    let (mut one, mut two) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..rounds {
        let t = Instant::now();
        black_box(work());
        one = one.min(t.elapsed().as_secs_f64());
        let t = Instant::now();
        black_box(rayon::join(work, work));
        two = two.min(t.elapsed().as_secs_f64());
    }
    2.0 * one / two
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
    let wants = |name: &str| args.is_empty() || args.iter().any(|a| name.contains(a.as_str()));
    println!("rayon threads: {}", rayon::current_num_threads());
    if wants("nls2d") {
        let p = Nls2d::new(512).unwrap();
        let y0 = p.initial_value();
        for r in [2, 3] {
            paired("2D NLS 512 x 512", || p.system().unwrap(), &y0, r, 3, 5);
        }
    }
    if wants("nls1d") {
        let p = Nls::new(1 << 16).unwrap();
        let y0 = p.initial_value();
        for r in [2, 3] {
            paired("1D NLS N = 2^16", || p.system().unwrap(), &y0, r, 10, 10);
        }
    }
    if wants("threshold") {
        for r in [2, 3] {
            for k in 5..=14 {
                let p = Nls::new(1 << k).unwrap();
                let y0 = p.initial_value();
                // About 20 ms of serial steps per run.
                let steps = (100_000 >> k).clamp(5, 5000);
                let label = format!("1D NLS N = 2^{k}");
                paired(&label, || p.system().unwrap(), &y0, r, steps, 15);
            }
        }
    }
}
