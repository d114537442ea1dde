//! The stiffness Ω of a second-order system `q'' + Ωq = −∇U(q)`: what the oscillator
//! operator is built from ([`Oscillator`](super::Oscillator)), re-exported as
//! [`second_order::Omega`](crate::second_order::Omega).

use nalgebra::DMatrix;

use crate::error::{Error, Result};

/// The stiffness Ω (symmetric positive semidefinite), modelled as what it is.
#[derive(Clone, Debug)]
pub struct Omega {
    dim: usize,
    /// Eigenvalues (modal stiffnesses), one per mode.
    lambda: Vec<f64>,
    /// Eigenvectors (columns), for a dense Ω; `None`: the standard basis is modal.
    basis: Option<DMatrix<f64>>,
    /// The matrix Ω itself, for a dense Ω.
    matrix: Option<DMatrix<f64>>,
}

impl Omega {
    /// Ω = 0 (RKNCr).
    pub fn zero(dim: usize) -> Self {
        Omega {
            dim,
            lambda: vec![0.0; dim],
            basis: None,
            matrix: None,
        }
    }

    /// Ω = ω² I.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] for a negative or non-finite value.
    pub fn scalar(omega_squared: f64, dim: usize) -> Result<Self> {
        Self::diagonal(vec![omega_squared; dim])
    }

    /// Ω = diag(λ).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] for a negative or non-finite entry.
    pub fn diagonal(lambda: Vec<f64>) -> Result<Self> {
        check_eigenvalues(&lambda, 0.0)?;
        Ok(Omega {
            dim: lambda.len(),
            lambda,
            basis: None,
            matrix: None,
        })
    }

    /// A dense symmetric positive semidefinite Ω, by its eigendecomposition.
    ///
    /// # Errors
    /// [`Error::NotSquare`], [`Error::NonFinite`], [`Error::InvalidInput`] if Ω is not
    /// symmetric (relative 1e−12) or has a negative eigenvalue (below −1e−12 ‖Ω‖).
    pub fn dense(omega: DMatrix<f64>) -> Result<Self> {
        let (n, m) = omega.shape();
        if n != m {
            return Err(Error::NotSquare {
                what: "Ω",
                rows: n,
                cols: m,
            });
        }
        if omega.iter().any(|x| !x.is_finite()) {
            return Err(Error::NonFinite("Ω"));
        }
        let scale = omega.amax();
        let asym = (&omega - omega.transpose()).amax();
        if asym > 1e-12 * scale {
            return Err(Error::InvalidInput(format!(
                "Ω must be symmetric (max |Ω − Ωᵀ| = {asym:e})"
            )));
        }
        let omega = (&omega + omega.transpose()) * 0.5;
        let eig = nalgebra::SymmetricEigen::new(omega.clone());
        let mut lambda: Vec<f64> = eig.eigenvalues.iter().copied().collect();
        check_eigenvalues(&lambda, 1e-12 * scale)?;
        // Round-off may leave tiny negative eigenvalues of a semidefinite Ω: they are zero.
        lambda.iter_mut().for_each(|l| *l = l.max(0.0));
        Ok(Omega {
            dim: n,
            lambda,
            basis: Some(eig.eigenvectors),
            matrix: Some(omega),
        })
    }

    /// The dimension.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// The modal stiffnesses (eigenvalues of Ω).
    pub fn eigenvalues(&self) -> &[f64] {
        &self.lambda
    }

    /// The eigenvectors (columns) of a dense Ω; `None` for zero, scalar and diagonal Ω, whose
    /// modes are the coordinates.
    pub fn basis(&self) -> Option<&DMatrix<f64>> {
        self.basis.as_ref()
    }

    /// The (symmetrised) matrix of a dense Ω; `None` for zero, scalar and diagonal Ω.
    pub fn matrix(&self) -> Option<&DMatrix<f64>> {
        self.matrix.as_ref()
    }

    /// y = Ω x. Does not allocate.
    pub fn apply(&self, x: &[f64], y: &mut [f64]) {
        match &self.matrix {
            None => y
                .iter_mut()
                .zip(x)
                .zip(&self.lambda)
                .for_each(|((y, x), l)| *y = l * x),
            Some(m) => {
                for (i, yi) in y.iter_mut().enumerate() {
                    *yi = m.row(i).iter().zip(x).map(|(a, b)| a * b).sum();
                }
            }
        }
    }

    /// ½ xᵀΩx.
    pub fn half_quadratic(&self, x: &[f64]) -> f64 {
        match &self.matrix {
            None => {
                0.5 * x
                    .iter()
                    .zip(&self.lambda)
                    .map(|(v, l)| l * v * v)
                    .sum::<f64>()
            }
            Some(m) => {
                let mut sum = 0.0;
                for (i, xi) in x.iter().enumerate() {
                    sum += xi * m.row(i).iter().zip(x).map(|(a, b)| a * b).sum::<f64>();
                }
                0.5 * sum
            }
        }
    }
}

fn check_eigenvalues(lambda: &[f64], slack: f64) -> Result<()> {
    if let Some(l) = lambda.iter().find(|l| !l.is_finite() || **l < -slack) {
        return Err(Error::InvalidInput(format!(
            "Ω must be positive semidefinite with finite entries (eigenvalue {l:e})"
        )));
    }
    Ok(())
}
