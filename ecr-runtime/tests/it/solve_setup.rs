//! Set-up once: a solve builds the φ-bank of each step size and kernel (the answer's Gauss
//! points, the check's Lobatto points) once, whatever uses it (pilots, attempts, windows
//! integrated again, a last step shortened by rounding), and a fixed run builds one bank for its
//! step size (and one for a last step that the step size does not divide).
//!
//! The operator below is a dense matrix that counts and records the step sizes of the kernel
//! banks built from it.

use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use ecr_runtime::operator::{Dense, DenseBank, LinearOperator};
use ecr_runtime::solve::{Options, Problem};
use ecr_runtime::system::{Semilinear, System};
use nalgebra::DMatrix;

/// A dense operator that records the step size and the nodes of every kernel bank built from
/// it.
struct Counting {
    inner: Dense,
    builds: AtomicUsize,
    steps: Mutex<Vec<(f64, Vec<f64>)>>,
}

impl Counting {
    fn new(a: DMatrix<f64>) -> Self {
        Counting {
            inner: Dense::new(a).unwrap(),
            builds: AtomicUsize::new(0),
            steps: Mutex::new(Vec::new()),
        }
    }

    /// (banks built, distinct (step size, nodes) among them).
    fn counts(&self) -> (usize, usize) {
        let mut hs: Vec<Vec<u64>> = self
            .steps
            .lock()
            .unwrap()
            .iter()
            .map(|(h, taus)| {
                std::iter::once(*h)
                    .chain(taus.iter().copied())
                    .map(f64::to_bits)
                    .collect()
            })
            .collect();
        hs.sort();
        hs.dedup();
        (self.builds.load(Ordering::Relaxed), hs.len())
    }
}

impl LinearOperator for Counting {
    type Bank = DenseBank;
    fn dim(&self) -> usize {
        self.inner.dim()
    }
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        self.inner.apply(x, y)
    }
    fn phi_bank(&self, h: f64, taus: &[f64], p: usize) -> ecr_runtime::Result<DenseBank> {
        self.inner.phi_bank(h, taus, p)
    }
    fn kernel_bank(&self, h: f64, taus: &[f64], n: usize) -> ecr_runtime::Result<DenseBank> {
        self.builds.fetch_add(1, Ordering::Relaxed);
        self.steps.lock().unwrap().push((h, taus.to_vec()));
        self.inner.kernel_bank(h, taus, n)
    }
}

/// A Duffing-like oscillator q'' = −ω²q − q³ (ω = 4) from (1, 0): its linear part counted.
fn oscillator() -> Semilinear<Counting, impl Fn(&[f64], &mut [f64])> {
    let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -16.0, 0.0]);
    Semilinear::new(Counting::new(a), |y: &[f64], g: &mut [f64]| {
        g[0] = 0.0;
        g[1] = -y[0] * y[0] * y[0];
    })
}

#[test]
fn a_solve_builds_each_bank_once() {
    for tol in [1e-6, 1e-9] {
        let problem = Problem::new(oscillator(), [1.0, 0.0], (0.0, 40.0)).unwrap();
        let sol = problem.solve(&Options::tolerance(tol)).unwrap();
        let (builds, distinct) = problem.system().linear().counts();
        assert!(sol.stats.steps > 0);
        assert_eq!(
            builds, distinct,
            "tol {tol:e}: {builds} banks built for {distinct} step sizes and kernels"
        );
    }
}

#[test]
fn a_fixed_run_builds_one_bank_per_step_size() {
    // 0.1 does not divide 40 in f64 arithmetic exactly: 400 steps of fl(0.1) miss 40 by a few
    // units of round-off, and the run still ends at 40 without a bank for that last step.
    let problem = Problem::new(oscillator(), [1.0, 0.0], (0.0, 40.0)).unwrap();
    let sol = problem.solve(&Options::fixed(3, 0.1)).unwrap();
    assert_eq!(*sol.t.last().unwrap(), 40.0);
    assert_eq!(problem.system().linear().counts(), (1, 1));
    // A step size that leaves a genuinely shorter last step: one bank more, for that step.
    let problem = Problem::new(oscillator(), [1.0, 0.0], (0.0, 40.0)).unwrap();
    problem.solve(&Options::fixed(3, 0.3)).unwrap();
    assert_eq!(problem.system().linear().counts(), (2, 2));
}

/// n steps of fl(h) miss the end of the span by a few units of round-off: a last step of its
/// own size (what `integrate` does, building a bank for it) and a full step moved along the
/// vector field by the difference (what `solve` does, with no bank) agree to round-off, while
/// the difference itself moves this fast oscillation (ω = 10⁴) by far more than that. The two
/// runs make the same steps but the last, so everything else cancels.
#[test]
fn the_last_step_off_by_rounding_moves_the_state_along_the_field() {
    use ecr_runtime::integrate::{IntegrateOptions, StepPlan, integrate};
    use ecr_runtime::stepper::EcStepper;
    let fast = || {
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -1e8, 0.0]);
        Semilinear::new(Counting::new(a), |y: &[f64], g: &mut [f64]| {
            g[0] = 0.0;
            g[1] = -y[0] * y[0] * y[0];
        })
    };
    let (t0, t_end, h) = (0.0, 40.0, 0.1);
    let plan = StepPlan::new(t0, t_end, h).unwrap();
    let rest = plan.last.expect("a corrected last step") - h;
    let y0 = [1.0, 0.0];
    let problem = Problem::new(fast(), y0, (t0, t_end)).unwrap();
    let by_solve = problem.solve(&Options::fixed(4, h)).unwrap();
    let system = fast();
    let mut stepper = EcStepper::new(&system, 4, h).unwrap();
    let mut y = y0;
    integrate(
        &mut stepper,
        t0,
        t_end,
        &mut y,
        IntegrateOptions::default(),
        |_, _, _| {},
    )
    .unwrap();
    let last = by_solve.last().unwrap();
    let scale = y.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    // |y'| ≤ ω·‖y‖: the correction is at least this large where the state moves fastest.
    let moved = rest.abs() * 1e4 * scale;
    let apart = last
        .iter()
        .zip(&y)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(
        moved > 1e3 * 1e-15 * scale,
        "rest {rest:e} moves the state too little to test"
    );
    assert!(apart <= 1e-14 * scale, "{last:?} vs {y:?} (rest {rest:e})");
}
