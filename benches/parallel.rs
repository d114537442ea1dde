//! Serial vs concurrent stage path of the ECrP stepper on large systems (the FFT operators of
//! the NLS), paired: each case builds two steppers that differ only in
//! `SolverSettings::parallel_min_dim` (`usize::MAX`: serial; 0: concurrent), times runs of a
//! few steps from the same start, serial and concurrent one after the other, in rounds, and
//! prints the fastest run of each and their ratio; the two end states are checked to agree bit
//! for bit. The steppers use the extrapolating predictor, as `ecr bench scaling` does, and
//! h = 1/200.
//!
//! The machine is shared: while other work holds a core, a concurrent run cannot be faster
//! than a serial one. So each round measures the machine's free capacity just before and just
//! after its runs (how much work two threads do in the time one does it alone: 2.00 with both
//! cores free) and only rounds with both ≥ 1.85 count ("free rounds"); the rounds of all cases
//! are interleaved, so that every case samples the whole time of the run. A case without free
//! rounds is reported from all its rounds and says so.
//!
//! `cargo bench --bench parallel` runs every case; a filter argument runs some:
//! `cargo bench --bench parallel -- nls2d` (the 2D NLS, 512 × 512, EC2P and EC3P),
//! `-- nls1d` (the 1D NLS, N = 2^16), `-- threshold` (the 1D NLS from N = 2^9 to 2^15, EC2P and
//! EC3P: where the concurrent path starts to pay, which sets `PARALLEL_MIN_DIM`); a number
//! sets the rounds (default 20).

use ecr::problems::{Nls, Nls2d};
use ecr::runtime::stepper::{EcStepper, Predictor, SolverSettings};
use ecr::runtime::system::System;
use std::hint::black_box;
use std::time::Instant;

const H: f64 = 1.0 / 200.0;
/// The free capacity from which a round counts.
const FREE: f64 = 1.85;

fn settings(parallel: bool) -> SolverSettings {
    SolverSettings {
        predictor: Predictor::Extrapolate,
        parallel_min_dim: if parallel { 0 } else { usize::MAX },
        ..SolverSettings::default()
    }
}

/// About 3 ms of arithmetic on one core.
fn work() -> f64 {
    (0..1_000_000u64).map(|i| (i as f64).sqrt()).sum()
}

/// How much work 2 threads of rayon's pool do in the time one does it alone: 2.0 when both
/// cores are free, less when other work holds them.
fn capacity() -> f64 {
    let t = Instant::now();
    black_box(work());
    let one = t.elapsed().as_secs_f64();
    let t = Instant::now();
    black_box(rayon::join(work, work));
    2.0 * one / t.elapsed().as_secs_f64()
}

/// A paired case: its two steppers and the fastest runs so far.
trait Case {
    /// One round: a serial and a concurrent run; `free` says whether it counts as free.
    fn round(&mut self, free: &dyn Fn() -> bool);
    fn report(&self);
}

struct Paired<S: System> {
    label: String,
    r: usize,
    serial: EcStepper<S>,
    par: EcStepper<S>,
    y0: Vec<f64>,
    steps: usize,
    /// Fastest serial and concurrent runs over free rounds and over all rounds (seconds).
    free: (f64, f64),
    all: (f64, f64),
    rounds: (usize, usize),
    sweeps: usize,
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

impl<S: System> Paired<S> {
    /// ECrP with s = r on two systems from `make`, `steps` steps per run.
    fn new(label: String, make: impl Fn() -> S, y0: Vec<f64>, r: usize, steps: usize) -> Self {
        let mut serial = EcStepper::with_nodes(make(), r, r, H, settings(false)).unwrap();
        let mut par = EcStepper::with_nodes(make(), r, r, H, settings(true)).unwrap();
        // Warm-up (caches, page faults of the buffers, rayon's threads).
        run(&mut serial, &y0, 1);
        run(&mut par, &y0, 1);
        Paired {
            label,
            r,
            serial,
            par,
            y0,
            steps,
            free: (f64::INFINITY, f64::INFINITY),
            all: (f64::INFINITY, f64::INFINITY),
            rounds: (0, 0),
            sweeps: 0,
        }
    }
}

impl<S: System> Case for Paired<S> {
    fn round(&mut self, free: &dyn Fn() -> bool) {
        let before = free();
        let (ts, sweeps, ys) = run(&mut self.serial, &self.y0, self.steps);
        let (tp, _, yp) = run(&mut self.par, &self.y0, self.steps);
        let after = free();
        assert!(
            ys.iter().zip(&yp).all(|(a, b)| a.to_bits() == b.to_bits()),
            "{}: serial and concurrent steps differ",
            self.label
        );
        self.sweeps = sweeps;
        self.rounds.1 += 1;
        self.all = (self.all.0.min(ts), self.all.1.min(tp));
        if before && after {
            self.rounds.0 += 1;
            self.free = (self.free.0.min(ts), self.free.1.min(tp));
        }
    }

    fn report(&self) {
        let (free, all) = self.rounds;
        let ((ts, tp), which) = if free > 0 {
            (self.free, format!("{free} free rounds of {all}"))
        } else {
            (self.all, format!("no free round: all {all} rounds"))
        };
        let (ts, tp) = (ts / self.steps as f64, tp / self.steps as f64);
        println!(
            "{}, EC{}P, d = {}: serial {:.3} ms/step, concurrent {:.3} ms/step, speed-up {:.2} \
             (fastest runs of {} steps, {which}; {:.1} sweeps/step)",
            self.label,
            self.r,
            self.y0.len(),
            ts * 1e3,
            tp * 1e3,
            ts / tp,
            self.steps,
            self.sweeps as f64 / self.steps as f64
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
    let rounds = args.iter().find_map(|a| a.parse().ok()).unwrap_or(20);
    let names: Vec<&String> = args
        .iter()
        .filter(|a| a.parse::<usize>().is_err())
        .collect();
    let wants = |name: &str| names.is_empty() || names.iter().any(|a| name.contains(a.as_str()));
    println!("rayon threads: {}", rayon::current_num_threads());
    let mut cases: Vec<Box<dyn Case>> = Vec::new();
    if wants("nls2d") {
        let p = Nls2d::new(512).unwrap();
        for r in [2, 3] {
            let label = "2D NLS 512 x 512".to_string();
            let make = || p.system().unwrap();
            cases.push(Box::new(Paired::new(label, make, p.initial_value(), r, 4)));
        }
    }
    if wants("nls1d") {
        let p = Nls::new(1 << 16).unwrap();
        for r in [2, 3] {
            let label = "1D NLS N = 2^16".to_string();
            let make = || p.system().unwrap();
            cases.push(Box::new(Paired::new(label, make, p.initial_value(), r, 5)));
        }
    }
    if wants("threshold") {
        for r in [2, 3] {
            for k in 9..=15 {
                let p = Nls::new(1 << k).unwrap();
                // About 5 ms of serial steps per run.
                let steps = (25_000 >> k).max(2);
                let label = format!("1D NLS N = 2^{k}");
                let make = || p.system().unwrap();
                cases.push(Box::new(Paired::new(
                    label,
                    make,
                    p.initial_value(),
                    r,
                    steps,
                )));
            }
        }
    }
    let free = || capacity() >= FREE;
    for _ in 0..rounds {
        for case in &mut cases {
            case.round(&free);
        }
    }
    for case in &cases {
        case.report();
    }
}
