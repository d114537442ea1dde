//! The test problems as [`System`]s, ready for the steppers.
//!
//! [`ProblemSystem`] pairs a [`TestProblem`] (which supplies g and H) with a structured linear
//! operator for A = QM:
//!
//! * [`Duffing::system`], [`Wind::system`]: A as a [`Dense`] 2 × 2 matrix;
//! * [`Nls::system`]: A = [[0, −D₂], [D₂, 0]] as a [`SkewPair`] of the [`Circulant`] D₂, applied
//!   and exponentiated with FFTs in O(N log N) per vector;
//! * [`Nls::dense_system`]: the same A as a [`Dense`] 2N × 2N matrix (for comparisons).
//!
//! ```
//! use ecr::problems::Duffing;
//! use ecr_runtime::stepper::EcStepper;
//! let duffing = Duffing::default();
//! let mut stepper = EcStepper::new(duffing.system()?, 2, 0.01)?;
//! let mut y = duffing.initial_value();
//! stepper.step(&mut y)?;
//! let exact = duffing.exact(0.01)?;
//! assert!((y[0] - exact[0]).abs() < 1e-10);
//! # Ok::<(), ecr_runtime::Error>(())
//! ```

use super::{Duffing, Fpu, HenonHeiles, Nls, TestProblem, Wind};
use ecr_runtime::operator::{Circulant, Dense, LinearOperator, SkewPair};
use ecr_runtime::second_order::{Omega, SecondOrderSystem};
use ecr_runtime::storage::ensure_allocatable;
use ecr_runtime::system::System;
use ecr_runtime::{Error, Result};

/// A [`TestProblem`] as a [`System`] y' = Ay + g(y): the linear part is the operator `Op`
/// (which must represent the problem's `linear_matrix()`), g is the problem's `nonlinear`, and
/// the energy is the problem's `energy`.
#[derive(Clone, Debug)]
pub struct ProblemSystem<P, Op> {
    problem: P,
    op: Op,
}

/// Duffing (Problem 1) with a dense linear part.
pub type DuffingSystem = ProblemSystem<Duffing, Dense>;
/// Wind-induced oscillation (Problem 2) with a dense linear part.
pub type WindSystem = ProblemSystem<Wind, Dense>;
/// [`HenonHeiles`] with its linear part as a dense matrix.
pub type HenonHeilesSystem = ProblemSystem<HenonHeiles, Dense>;
/// Cubic NLS (Problem 3) with the linear part as a skew pair of the circulant D₂ (FFT).
pub type NlsSystem = ProblemSystem<Nls, SkewPair<Circulant>>;
/// Cubic NLS (Problem 3) with a dense linear part (O(N²) per application; for comparisons).
pub type NlsDenseSystem = ProblemSystem<Nls, Dense>;

impl<P: TestProblem, Op: LinearOperator> ProblemSystem<P, Op> {
    /// Pairs `problem` with the operator `op`, which the caller asserts represents
    /// `problem.linear_matrix()`; only the dimensions are checked.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] if `op.dim() != problem.dim()`.
    pub fn new(problem: P, op: Op) -> Result<Self> {
        if op.dim() != problem.dim() {
            return Err(Error::DimensionMismatch {
                what: "linear operator and problem",
                expected: problem.dim(),
                found: op.dim(),
            });
        }
        Ok(ProblemSystem { problem, op })
    }

    /// The problem.
    pub fn problem(&self) -> &P {
        &self.problem
    }
}

impl<P: TestProblem> ProblemSystem<P, Dense> {
    /// The problem with A = `problem.linear_matrix()` as a [`Dense`] operator.
    ///
    /// # Errors
    /// [`Error::NonFinite`] if the matrix has NaN/∞ entries (extreme parameters),
    /// [`Error::InvalidInput`] naming the size if its d² entries cannot be allocated.
    pub fn dense(problem: P) -> Result<Self> {
        let d = problem.dim();
        ensure_allocatable(
            &format!("the dense {d} × {d} linear part"),
            d.checked_mul(d),
        )?;
        let op = Dense::new(problem.linear_matrix())?;
        Self::new(problem, op)
    }
}

impl<P: TestProblem, Op: LinearOperator> System for ProblemSystem<P, Op> {
    type Op = Op;
    fn dim(&self) -> usize {
        self.problem.dim()
    }
    fn linear(&self) -> &Op {
        &self.op
    }
    fn nonlinear(&self, y: &[f64], out: &mut [f64], _scratch: &mut [f64]) {
        self.problem.nonlinear(y, out)
    }
    fn nonlinear_stages(
        &self,
        ys: &[f64],
        out: &mut [f64],
        _scratch: &mut [f64],
        skip: Option<usize>,
    ) {
        self.problem.nonlinear_stages(ys, out, skip)
    }
    fn energy(&self, y: &[f64]) -> Option<f64> {
        Some(self.problem.energy(y))
    }
}

/// The Fermi–Pasta–Ulam chain as a second-order system q'' + Ωq = −∇U(q), Ω diagonal
/// (for [`ecr_runtime::second_order::TcStepper`]; Ω = 0 when ω = 0, an RKNC problem).
#[derive(Clone, Debug)]
pub struct FpuSystem {
    fpu: Fpu,
    omega: Omega,
}

impl SecondOrderSystem for FpuSystem {
    fn omega(&self) -> &Omega {
        &self.omega
    }
    fn force(&self, q: &[f64], out: &mut [f64]) {
        self.fpu.grad_u(q, out)
    }
    fn potential(&self, q: &[f64]) -> Option<f64> {
        Some(self.fpu.potential_u(q))
    }
    fn energy(&self, q: &[f64], p: &[f64]) -> Option<f64> {
        Some(self.fpu.energy(q, p))
    }
}

/// The Fermi–Pasta–Ulam chain in first-order form y = (q, p), A = [[0, I], [−Ω, 0]] dense
/// (for ECrP, e.g. to compare with TCrP).
#[derive(Clone, Debug)]
pub struct FpuFirstOrderSystem {
    fpu: Fpu,
    op: Dense,
}

impl System for FpuFirstOrderSystem {
    type Op = Dense;
    fn linear(&self) -> &Dense {
        &self.op
    }
    fn nonlinear(&self, y: &[f64], out: &mut [f64], _scratch: &mut [f64]) {
        self.fpu.nonlinear_first_order(y, out)
    }
    fn energy(&self, y: &[f64]) -> Option<f64> {
        Some(self.fpu.energy_first_order(y))
    }
}

impl Fpu {
    /// The second-order system (diagonal Ω).
    ///
    /// # Errors
    /// Never for a valid `Fpu`; the `Result` is for uniformity.
    pub fn system(&self) -> Result<FpuSystem> {
        Ok(FpuSystem {
            fpu: self.clone(),
            omega: Omega::diagonal(self.omega_diagonal())?,
        })
    }

    /// The first-order form as a [`System`] with a dense linear part.
    ///
    /// # Errors
    /// [`Error::NonFinite`] if ω² overflows.
    pub fn first_order_system(&self) -> Result<FpuFirstOrderSystem> {
        Ok(FpuFirstOrderSystem {
            fpu: self.clone(),
            op: Dense::new(self.linear_matrix())?,
        })
    }
}

impl Duffing {
    /// This problem as a [`System`] with A = [`linear_matrix`](Duffing::linear_matrix) dense.
    ///
    /// # Errors
    /// [`Error::NonFinite`] if ω² + k² overflows.
    pub fn system(&self) -> Result<DuffingSystem> {
        ProblemSystem::dense(self.clone())
    }
}

impl HenonHeiles {
    /// This problem as a [`System`] with A = [`linear_matrix`](HenonHeiles::linear_matrix)
    /// dense.
    ///
    /// # Errors
    /// None in practice (the entries are 0 and ±1); the signature is that of the others.
    pub fn system(&self) -> Result<HenonHeilesSystem> {
        ProblemSystem::dense(self.clone())
    }
}

impl Wind {
    /// This problem as a [`System`] with A = [`linear_matrix`](Wind::linear_matrix) dense.
    ///
    /// # Errors
    /// [`Error::NonFinite`] if an entry of A overflows (huge radius).
    pub fn system(&self) -> Result<WindSystem> {
        ProblemSystem::dense(*self)
    }
}

impl Nls {
    /// This problem as a [`System`] with A = [[0, −D₂], [D₂, 0]] a [`SkewPair`] of the
    /// [`Circulant`] D₂ ([`d2_first_column`](Nls::d2_first_column)): O(N log N) per
    /// application and per φ-combination.
    ///
    /// # Errors
    /// Whatever building the circulant or its real spectrum reports (not expected for a
    /// valid `Nls`).
    pub fn system(&self) -> Result<NlsSystem> {
        let op = SkewPair::new(Circulant::new(self.d2_first_column())?)?;
        ProblemSystem::new(self.clone(), op)
    }

    /// This problem as a [`System`] with A = [`linear_matrix`](Nls::linear_matrix) dense
    /// (O(N²) per application, O(N³) per φ-bank): for comparisons with [`Nls::system`].
    ///
    /// # Errors
    /// As [`Dense::new`].
    pub fn dense_system(&self) -> Result<NlsDenseSystem> {
        ProblemSystem::dense(self.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::super::testutil::Rng;
    use super::*;
    use ecr_runtime::stepper::{EcStepper, SolverSettings};
    use nalgebra::DVector;

    fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
        a.iter().zip(b).fold(0.0, |m, (x, y)| m.max((x - y).abs()))
    }

    /// `linear().apply(y)` equals `linear_matrix() · y`, g and H are the problem's.
    fn check_system<P: TestProblem, S: System>(problem: &P, sys: &S, rng: &mut Rng) {
        let d = problem.dim();
        assert_eq!(sys.dim(), d);
        let a = problem.linear_matrix();
        for _ in 0..3 {
            let y: Vec<f64> = (0..d).map(|_| rng.sym(1.0)).collect();
            let mut ay = vec![0.0; d];
            sys.linear().apply(&y, &mut ay);
            let expect = &a * DVector::from_column_slice(&y);
            let scale = a.amax() * d as f64;
            assert!(
                max_abs_diff(&ay, expect.as_slice()) <= 1e-13 * scale.max(1.0),
                "A y mismatch: {:e}",
                max_abs_diff(&ay, expect.as_slice())
            );
            let (mut g1, mut g2) = (vec![0.0; d], vec![0.0; d]);
            let mut scratch = vec![0.0; sys.scratch_len()];
            sys.nonlinear(&y, &mut g1, &mut scratch);
            problem.nonlinear(&y, &mut g2);
            assert_eq!(g1, g2);
            assert_eq!(sys.energy(&y), Some(problem.energy(&y)));
        }
    }

    #[test]
    fn duffing_and_wind_systems_match_matrices() {
        let mut rng = Rng(7);
        let duffing = Duffing::default();
        check_system(&duffing, &duffing.system().unwrap(), &mut rng);
        for wind in [Wind::conservative(), Wind::dissipative()] {
            check_system(&wind, &wind.system().unwrap(), &mut rng);
        }
    }

    #[test]
    fn nls_systems_match_matrix() {
        let mut rng = Rng(11);
        let nls = Nls::new(16).unwrap();
        check_system(&nls, &nls.system().unwrap(), &mut rng);
        check_system(&nls, &nls.dense_system().unwrap(), &mut rng);
    }

    #[test]
    fn nls_circulant_and_dense_steps_agree() {
        let nls = Nls::new(16).unwrap();
        let y0 = nls.initial_value();
        for (r, s) in [(1, 1), (2, 2), (2, 3)] {
            let settings = SolverSettings::default();
            let mut fast = EcStepper::with_nodes(nls.system().unwrap(), r, s, 0.05, settings)
                .expect("fft stepper");
            let mut dense =
                EcStepper::with_nodes(nls.dense_system().unwrap(), r, s, 0.05, settings)
                    .expect("dense stepper");
            let (mut y1, mut y2) = (y0.clone(), y0.clone());
            for _ in 0..2 {
                fast.step(&mut y1).unwrap();
                dense.step(&mut y2).unwrap();
            }
            let diff = max_abs_diff(&y1, &y2);
            assert!(
                diff < 1e-13,
                "r = {r}, s = {s}: circulant vs dense {diff:e}"
            );
        }
    }

    #[test]
    fn duffing_step_is_accurate_and_mismatched_operator_is_rejected() {
        let duffing = Duffing::default();
        let mut stepper = EcStepper::new(duffing.system().unwrap(), 2, 0.01).unwrap();
        let mut y = duffing.initial_value();
        for _ in 0..10 {
            stepper.step(&mut y).unwrap();
        }
        let exact = duffing.exact(0.1).unwrap();
        assert!(max_abs_diff(&y, &exact) < 1e-9);
        let op = Dense::new(Nls::new(2).unwrap().linear_matrix()).unwrap();
        let bad = ProblemSystem::new(duffing, op); // 4 × 4 operator for a 2-d problem
        assert!(matches!(bad, Err(Error::DimensionMismatch { .. })));
    }
}
