//! The paper's test problems (§9 "Numerical experiments") as plain data and functions.
//!
//! Every problem has the form of the paper's eq. (IVPPP)/(H):
//!
//! ```text
//! y' = Q ∇H(y),   H(y) = ½ yᵀ M y + V(y),   i.e.   y' = A y + g(y),   A = Q M,   g = Q ∇V,
//! ```
//!
//! with `Q` skew-symmetric (conservative: `H` is a first integral) or negative semidefinite
//! (dissipative: `H` is a Lyapunov function).
//!
//! * [`Duffing`] — Problem 1, the Duffing equation, with its exact solution in Jacobi elliptic
//!   functions ([`Duffing::exact`]).
//! * [`Wind`] — Problem 2, the averaged system in wind-induced oscillation, conservative
//!   ([`Wind::conservative`]) and dissipative ([`Wind::dissipative`]).
//! * [`HenonHeiles`] — the Hénon–Heiles system (two oscillators, cubic coupling; chaotic at
//!   the default energy 1/8).
//! * [`Nls`] — Problem 3, the cubic nonlinear Schrödinger equation, semi-discretised by the
//!   Fourier pseudospectral method; [`Nls2d`] is its 2D analogue (for scaling studies).
//!
//! [`Duffing`], [`Wind`] and [`HenonHeiles`] also implement
//! [`GenericSystem`](ecr_runtime::precision::GenericSystem) for every
//! [`Real`](ecr_runtime::precision::Real) scalar: they run in double-double precision with
//! [`GenericStepper`](ecr_runtime::precision::GenericStepper).
//!
//! Each type offers the same inherent methods, and implements [`TestProblem`] for code that runs
//! one harness over all of them. The nonlinearity, the gradient and the energies work on slices
//! and never allocate (except [`Nls::energy`], an FFT whose plan and buffers are made at its
//! first call); the matrices are built on request as [`DMatrix`].
//!
//! ```
//! use ecr::problems::Duffing;
//! let duffing = Duffing::default(); // ω = 5, k = 0.07
//! let y0 = duffing.initial_value();
//! let mut g = [0.0; 2];
//! duffing.nonlinear(&y0, &mut g);
//! let y = duffing.exact(1.0)?;
//! assert!((duffing.energy(&y) - duffing.energy(&y0)).abs() < 1e-13);
//! # Ok::<(), ecr_runtime::Error>(())
//! ```

use nalgebra::DMatrix;

mod duffing;
mod fpu;
mod henon_heiles;
mod nls;
mod nls2d;
mod precise;
mod systems;
mod wind;

pub use duffing::Duffing;
pub use fpu::Fpu;
pub use henon_heiles::HenonHeiles;
pub use nls::Nls;
pub use nls2d::{Nls2d, Nls2dSystem};
pub use systems::{
    DuffingSystem, HenonHeilesSystem, NlsDenseSystem, NlsSystem, ProblemSystem, WindSystem,
};
pub use wind::Wind;

/// A problem `y' = Q∇H(y) = Ay + g(y)` with `H(y) = ½yᵀMy + V(y)`, `A = QM`, `g = Q∇V`
/// (paper eqs. (IVPPP), (H)).
///
/// The methods mirror the inherent methods of [`Duffing`], [`Wind`] and [`Nls`]; see those for
/// the formulas.
///
/// # Panics
///
/// The slice methods panic if a slice length differs from [`dim`](TestProblem::dim).
pub trait TestProblem {
    /// The dimension `d` of `y`.
    fn dim(&self) -> usize;
    /// The structure matrix `Q` (`d × d`).
    fn q_matrix(&self) -> DMatrix<f64>;
    /// The symmetric matrix `M` of the quadratic part of `H` (`d × d`).
    fn m_matrix(&self) -> DMatrix<f64>;
    /// The linear part `A = QM` (`d × d`).
    fn linear_matrix(&self) -> DMatrix<f64>;
    /// The nonlinear part `g(y) = Q∇V(y)`, written into `out`.
    fn nonlinear(&self, y: &[f64], out: &mut [f64]);
    /// g at several states, block `skip` of `out` left as it is (what
    /// [`System::nonlinear_stages`](ecr_runtime::system::System::nonlinear_stages) of a
    /// [`ProblemSystem`] does): one after another by default; the built-in problems evaluate
    /// them concurrently, one task per state on rayon's pool (as
    /// [`nonlinear_concurrent`](ecr_runtime::system::nonlinear_concurrent) does for a system).
    fn nonlinear_stages(&self, ys: &[f64], out: &mut [f64], skip: Option<usize>) {
        let d = self.dim();
        for (j, (y, o)) in ys.chunks_exact(d).zip(out.chunks_exact_mut(d)).enumerate() {
            if skip != Some(j) {
                self.nonlinear(y, o);
            }
        }
    }
    /// The gradient `∇V(y)`, written into `out`.
    fn grad_v(&self, y: &[f64], out: &mut [f64]);
    /// The potential `V(y)`.
    fn potential_v(&self, y: &[f64]) -> f64;
    /// The energy (first integral or Lyapunov function) `H(y) = ½yᵀMy + V(y)`.
    fn energy(&self, y: &[f64]) -> f64;
    /// The paper's initial value `y(0)`.
    fn initial_value(&self) -> Vec<f64>;
}

/// Implements [`TestProblem`] by forwarding to the inherent methods of the same names.
macro_rules! forward_test_problem {
    ($ty:ty) => {
        impl $crate::problems::TestProblem for $ty {
            fn dim(&self) -> usize {
                <$ty>::dim(self)
            }
            fn q_matrix(&self) -> nalgebra::DMatrix<f64> {
                <$ty>::q_matrix(self)
            }
            fn m_matrix(&self) -> nalgebra::DMatrix<f64> {
                <$ty>::m_matrix(self)
            }
            fn linear_matrix(&self) -> nalgebra::DMatrix<f64> {
                <$ty>::linear_matrix(self)
            }
            fn nonlinear(&self, y: &[f64], out: &mut [f64]) {
                <$ty>::nonlinear(self, y, out)
            }
            fn nonlinear_stages(&self, ys: &[f64], out: &mut [f64], skip: Option<usize>) {
                use rayon::prelude::*;
                let d = <$ty>::dim(self);
                out.par_chunks_mut(d)
                    .enumerate()
                    .with_max_len(1)
                    .for_each(|(j, o)| {
                        if skip != Some(j) {
                            <$ty>::nonlinear(self, &ys[j * d..(j + 1) * d], o);
                        }
                    });
            }
            fn grad_v(&self, y: &[f64], out: &mut [f64]) {
                <$ty>::grad_v(self, y, out)
            }
            fn potential_v(&self, y: &[f64]) -> f64 {
                <$ty>::potential_v(self, y)
            }
            fn energy(&self, y: &[f64]) -> f64 {
                <$ty>::energy(self, y)
            }
            fn initial_value(&self) -> Vec<f64> {
                <$ty>::initial_value(self)
            }
        }
    };
}
use forward_test_problem;

/// Panics with a clear message unless `len == expected` (the documented `# Panics` contract).
#[track_caller]
fn check_len(what: &str, len: usize, expected: usize) {
    assert!(
        len == expected,
        "{what} has length {len}, expected {expected}"
    );
}

#[cfg(test)]
pub(crate) mod testutil {
    //! Checks shared by the problems' tests.

    use super::TestProblem;
    use nalgebra::DVector;

    /// Deterministic pseudo-random numbers in [0, 1) (SplitMix64, fixed seed).
    pub struct Rng(pub u64);

    impl Rng {
        pub fn next(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        }

        /// Uniform in [−a, a].
        pub fn sym(&mut self, a: f64) -> f64 {
            a * (2.0 * self.next() - 1.0)
        }
    }

    fn max_abs(v: &[f64]) -> f64 {
        v.iter().fold(0.0, |m, x| m.max(x.abs()))
    }

    /// The structural identities of (IVPPP)/(H) at the points `ys`:
    ///
    /// * `A == QM` (entrywise, relative 1e-15 of max|A|: the products here are exact or
    ///   one rounding);
    /// * `Q∇V(y) == g(y)` (max-norm, relative 1e-14: a few roundings in a 2-term combination);
    /// * `∇V` against the fourth-order centred difference of `V` with `h = 2⁻¹⁰`. All three
    ///   potentials are polynomials of degree ≤ 4, for which that stencil is exact: the error is
    ///   round-off only, ≤ 3ε·max|V(y ± jh eᵢ)|/h per component; tolerance
    ///   1e-14 max|∇V| + 8ε max|V|/h;
    /// * `H(y) == ½yᵀMy + V(y)` with the matrices (relative 1e-13 of the sum of magnitudes);
    /// * along the vector field `f = Ay + g = Q∇H`: `∇H·f = ∇Hᵀ Q ∇H`, which is 0 for skew `Q`
    ///   (tolerance 1e-13·|∇H||f|) and ≤ 0 for a negative semidefinite `Q`;
    /// * `Q` exactly skew-symmetric if `conservative`, else its symmetric part negative
    ///   semidefinite (eigenvalues ≤ 1e-15).
    pub fn check_structure<P: TestProblem>(problem: &P, ys: &[Vec<f64>], conservative: bool) {
        let d = problem.dim();
        let (q, m, a) = (
            problem.q_matrix(),
            problem.m_matrix(),
            problem.linear_matrix(),
        );
        assert_eq!((q.nrows(), q.ncols(), m.nrows(), a.ncols()), (d, d, d, d));
        let qm = &q * &m;
        let scale = a.amax().max(f64::MIN_POSITIVE);
        assert!(
            (&a - &qm).amax() <= 1e-15 * scale,
            "A != QM: {}",
            (&a - &qm).amax()
        );
        assert_eq!(m, m.transpose(), "M must be symmetric");
        if conservative {
            assert_eq!(q.transpose(), -&q, "Q must be skew-symmetric");
        } else {
            let sym = (&q + q.transpose()) * 0.5;
            let max_eig = sym.symmetric_eigenvalues().max();
            assert!(
                max_eig <= 1e-15,
                "Q must be negative semidefinite: λmax = {max_eig}"
            );
        }

        let mut grad = vec![0.0; d];
        let mut g = vec![0.0; d];
        for y in ys {
            problem.grad_v(y, &mut grad);
            problem.nonlinear(y, &mut g);
            // Q ∇V == g.
            let qgrad = &q * DVector::from_column_slice(&grad);
            let diff = (&qgrad - DVector::from_column_slice(&g)).amax();
            assert!(
                diff <= 1e-14 * max_abs(&g).max(f64::MIN_POSITIVE),
                "Q∇V != g: {diff:e}"
            );
            // ∇V by the fourth-order centred difference.
            let h = 1.0 / 1024.0;
            let mut yy = y.clone();
            let mut vmax: f64 = 0.0;
            for i in 0..d {
                let mut v = [0.0; 4];
                for (slot, shift) in v.iter_mut().zip([h, -h, 2.0 * h, -2.0 * h]) {
                    yy[i] = y[i] + shift;
                    *slot = problem.potential_v(&yy);
                }
                yy[i] = y[i];
                vmax = vmax.max(max_abs(&v));
                let fd = (8.0 * (v[0] - v[1]) - (v[2] - v[3])) / (12.0 * h);
                let tol = 1e-14 * max_abs(&grad) + 8.0 * f64::EPSILON * max_abs(&v) / h;
                assert!(
                    (fd - grad[i]).abs() <= tol,
                    "∂V/∂y{i}: {} vs fd {fd}",
                    grad[i]
                );
            }
            // H == ½yᵀMy + V.
            let yv = DVector::from_column_slice(y);
            let quad = 0.5 * yv.dot(&(&m * &yv));
            let v = problem.potential_v(y);
            let h_val = problem.energy(y);
            let size = 0.5 * yv.abs().dot(&(m.abs() * yv.abs())) + v.abs();
            assert!(
                (h_val - (quad + v)).abs() <= 1e-13 * size,
                "H = {h_val} vs {}",
                quad + v
            );
            // ∇H·f = ∇Hᵀ Q ∇H.
            let grad_h = &m * &yv + DVector::from_column_slice(&grad);
            let f = &a * &yv + DVector::from_column_slice(&g);
            let power = grad_h.dot(&f);
            let tol = 1e-13 * grad_h.norm() * f.norm();
            if conservative {
                assert!(
                    power.abs() <= tol,
                    "dH/dt = {power:e} for a conservative problem"
                );
            } else {
                assert!(
                    power <= tol,
                    "dH/dt = {power:e} > 0 for a dissipative problem"
                );
            }
        }
    }
}
