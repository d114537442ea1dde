//! The cubic NLS on a doubly periodic square, pseudospectral in both directions: the 2D
//! analogue of Problem 3, used to measure how the cost of a step scales with the dimension.

use super::Nls;
use ecr_runtime::operator::{Circulant2d, LinearOperator, SkewPair};
use ecr_runtime::system::System;
use ecr_runtime::{Error, Result};
use std::f64::consts::PI;

/// The cubic nonlinear Schrödinger equation on `[0, L)²`, periodic,
///
/// ```text
/// iψ_t + Δψ + 2|ψ|²ψ = 0,   ψ(x, y, 0) = 0.5 + 0.025 (cos μx + cos μy),   L = 4√2 π, μ = 2π/L,
/// ```
///
/// on the `n × n` grid `(x_i, y_j) = (iL/n, jL/n)` (row-major, entry `(i, j)` at `i·n + j`),
/// semi-discretised by the Fourier pseudospectral method: `Δ = D₂ ⊗ I + I ⊗ D₂` with the 1D
/// matrix `D₂` of [`Nls`]. For `y = (p, q) ∈ R^{2n²}`, `ψ = p + iq`,
///
/// ```text
/// y' = [[0, −Δ], [Δ, 0]] y + (−2(p² + q²)·q, 2(p² + q²)·p),
/// H  = ½ pᵀΔp + ½ qᵀΔq + ½ Σ (pᵢ² + qᵢ²)²,
/// ```
///
/// exactly the structure of [`Nls`] with `D₂` replaced by `Δ`. The linear part is a
/// [`SkewPair`] of the [`Circulant2d`] `Δ`: `O(n² log n)` per application and per
/// φ-combination, `O(n²)` memory per φ-function — a 512 × 512 grid (`d ≈ 5·10⁵`) is routine.
#[derive(Clone, Debug, PartialEq)]
pub struct Nls2d {
    n: usize,
}

/// [`Nls2d`] as a [`System`] (`A` a skew pair of the 2D circulant Laplacian).
#[derive(Clone, Debug)]
pub struct Nls2dSystem {
    problem: Nls2d,
    op: SkewPair<Circulant2d>,
}

impl Nls2d {
    /// The problem on an `n × n` grid.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] if `n` is odd or smaller than 2 (as [`Nls::new`]).
    pub fn new(n: usize) -> Result<Self> {
        Nls::new(n)?;
        Ok(Nls2d { n })
    }

    /// Grid points per direction.
    pub fn n(&self) -> usize {
        self.n
    }

    /// The dimension `2n²` of `y = (p, q)`.
    pub fn dim(&self) -> usize {
        2 * self.n * self.n
    }

    /// `ψ(x, y, 0) = 0.5 + 0.025 (cos μx + cos μy)` as `y = (Re ψ, Im ψ)`.
    pub fn initial_value(&self) -> Vec<f64> {
        let n = self.n;
        let mut y = vec![0.0; 2 * n * n];
        let cos: Vec<f64> = (0..n)
            .map(|j| (2.0 * PI * j as f64 / n as f64).cos()) // μx_j = 2πj/n
            .collect();
        for (k, p) in y[..n * n].iter_mut().enumerate() {
            *p = 0.5 + 0.025 * (cos[k / n] + cos[k % n]);
        }
        y
    }

    /// `g(y) = (−2(p² + q²)·q, 2(p² + q²)·p)`.
    ///
    /// # Panics
    /// If `y` or `out` does not have length `2n²`.
    pub fn nonlinear(&self, y: &[f64], out: &mut [f64]) {
        let m = self.n * self.n;
        assert!(
            y.len() == 2 * m && out.len() == 2 * m,
            "Nls2d::nonlinear: y and out must have length 2n² = {}",
            2 * m
        );
        let (p, q) = y.split_at(m);
        let (op, oq) = out.split_at_mut(m);
        for j in 0..m {
            let rho = 2.0 * (p[j] * p[j] + q[j] * q[j]);
            op[j] = -rho * q[j];
            oq[j] = rho * p[j];
        }
    }

    /// The system with the FFT-based linear part.
    ///
    /// # Errors
    /// Whatever building the 2D circulant or its real spectrum reports (not expected).
    pub fn system(&self) -> Result<Nls2dSystem> {
        let d2 = Nls::new(self.n)?.d2_first_column();
        let op = SkewPair::new(Circulant2d::kron_sum(&d2, &d2)?)?;
        Ok(Nls2dSystem {
            problem: self.clone(),
            op,
        })
    }
}

impl Nls2dSystem {
    /// The problem.
    pub fn problem(&self) -> &Nls2d {
        &self.problem
    }

    /// `H(y)`; `O(n² log n)`, allocates two vectors of length `n²` (not for hot paths).
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] if `y.len() ≠ 2n²`.
    pub fn energy_of(&self, y: &[f64]) -> Result<f64> {
        let d = self.problem.dim();
        if y.len() != d {
            return Err(Error::DimensionMismatch {
                what: "NLS 2D state (2n²)",
                expected: d,
                found: y.len(),
            });
        }
        let m = d / 2;
        let lap = self.op.generator();
        let mut out = vec![0.0; m];
        let mut quad = 0.0;
        for half in y.chunks_exact(m) {
            lap.apply(half, &mut out);
            quad += half.iter().zip(&out).map(|(a, b)| a * b).sum::<f64>();
        }
        let (p, q) = y.split_at(m);
        let v: f64 = p.iter().zip(q).map(|(p, q)| (p * p + q * q).powi(2)).sum();
        Ok(0.5 * quad + 0.5 * v)
    }
}

impl System for Nls2dSystem {
    type Op = SkewPair<Circulant2d>;
    fn dim(&self) -> usize {
        self.problem.dim()
    }
    fn linear(&self) -> &Self::Op {
        &self.op
    }
    fn nonlinear(&self, y: &[f64], out: &mut [f64], _scratch: &mut [f64]) {
        self.problem.nonlinear(y, out)
    }
    /// Concurrently ([`nonlinear_concurrent`](ecr_runtime::system::nonlinear_concurrent)).
    fn nonlinear_stages(
        &self,
        ys: &[f64],
        out: &mut [f64],
        scratch: &mut [f64],
        skip: Option<usize>,
    ) {
        ecr_runtime::system::nonlinear_concurrent(self, ys, out, scratch, skip)
    }
    fn energy(&self, y: &[f64]) -> Option<f64> {
        self.energy_of(y).ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ecr_runtime::stepper::{EcStepper, SolverSettings};

    #[test]
    fn constructor_validates() {
        for n in [0, 1, 3, 15] {
            assert!(matches!(Nls2d::new(n), Err(Error::InvalidParameter(_))));
        }
        let p = Nls2d::new(8).unwrap();
        assert_eq!(p.dim(), 128);
        assert_eq!(p.system().unwrap().dim(), 128);
        assert!(matches!(
            p.system().unwrap().energy_of(&[0.0; 3]),
            Err(Error::DimensionMismatch { .. })
        ));
    }

    /// Data constant in y: the 2D problem reduces to the 1D NLS in x, step for step.
    #[test]
    fn reduces_to_the_1d_nls_for_data_constant_in_y() {
        let n = 16;
        let one = Nls::new(n).unwrap();
        let two = Nls2d::new(n).unwrap();
        let y1 = one.initial_value();
        let mut y2 = vec![0.0; two.dim()];
        for i in 0..n {
            for j in 0..n {
                y2[i * n + j] = y1[i];
                y2[n * n + i * n + j] = y1[n + i];
            }
        }
        let h = 0.01;
        let settings = SolverSettings::default();
        let mut s1 = EcStepper::with_nodes(one.system().unwrap(), 2, 2, h, settings).unwrap();
        let mut s2 = EcStepper::with_nodes(two.system().unwrap(), 2, 2, h, settings).unwrap();
        let (mut a, mut b) = (y1.clone(), y2.clone());
        for _ in 0..20 {
            s1.step(&mut a).unwrap();
            s2.step(&mut b).unwrap();
        }
        let mut err = 0.0f64;
        for i in 0..n {
            for j in 0..n {
                err = err.max((b[i * n + j] - a[i]).abs());
                err = err.max((b[n * n + i * n + j] - a[n + i]).abs());
            }
        }
        // Same arithmetic up to the FFT sizes: agreement to a few hundred ulps of |y| ≈ 0.5.
        assert!(err < 1e-13, "2D vs 1D after 20 steps: {err:e}");
        // And the energies agree up to the factor n (the y-sum of a constant).
        let e1 = one.energy(&a);
        let e2 = s2.system().energy(&b).unwrap();
        assert!(
            (e2 / n as f64 - e1).abs() < 1e-12 * e1.abs(),
            "{e2} vs {e1}"
        );
    }
}
