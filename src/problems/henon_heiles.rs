//! The Hénon–Heiles system: two coupled oscillators with a cubic coupling.

use nalgebra::DMatrix;

use super::{check_len, forward_test_problem};
use ecr_runtime::{Error, Result};

/// The Hénon–Heiles system
///
/// ```text
/// H(q, p) = ½(p₁² + p₂²) + ½(q₁² + q₂²) + q₁²q₂ − q₂³/3,
/// ```
///
/// with `y = (q₁, q₂, p₁, p₂)`, `Q = [[0, I], [−I, 0]]`, `M = I`, `V = q₁²q₂ − q₂³/3`, so
/// `A = QM = [[0, I], [−I, 0]]` and `g = Q∇V = (0, 0, −2q₁q₂, q₂² − q₁²)`. Orbits with
/// `H < 1/6` stay bounded; near `H = 1/8` most are chaotic.
#[derive(Clone, Debug, PartialEq)]
pub struct HenonHeiles {
    y0: [f64; 4],
}

impl Default for HenonHeiles {
    /// From `(q₁, q₂, p₁, p₂) = (0, 0, 1/2, 0)`, energy `H = 1/8` (chaotic region).
    fn default() -> Self {
        HenonHeiles {
            y0: [0.0, 0.0, 0.5, 0.0],
        }
    }
}

impl HenonHeiles {
    /// The system started from `y0 = (q₁, q₂, p₁, p₂)`.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for a non-finite component; [`Error::InvalidParameter`] unless the
    /// energy is below the escape energy 1/6 (above it, orbits may leave to infinity).
    pub fn new(y0: [f64; 4]) -> Result<Self> {
        if y0.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("Hénon–Heiles initial value"));
        }
        let p = HenonHeiles { y0 };
        let h = p.energy(&y0);
        if h >= 1.0 / 6.0 {
            return Err(Error::InvalidParameter(format!(
                "Hénon–Heiles energy H(y0) = {h:?} must be below the escape energy 1/6"
            )));
        }
        Ok(p)
    }

    /// The dimension, 4.
    pub fn dim(&self) -> usize {
        4
    }

    /// `Q = [[0, I], [−I, 0]]`.
    pub fn q_matrix(&self) -> DMatrix<f64> {
        let mut q = DMatrix::zeros(4, 4);
        q[(0, 2)] = 1.0;
        q[(1, 3)] = 1.0;
        q[(2, 0)] = -1.0;
        q[(3, 1)] = -1.0;
        q
    }

    /// `M = I`.
    pub fn m_matrix(&self) -> DMatrix<f64> {
        DMatrix::identity(4, 4)
    }

    /// `A = QM = Q`.
    pub fn linear_matrix(&self) -> DMatrix<f64> {
        self.q_matrix()
    }

    /// `g(y) = (0, 0, −2q₁q₂, q₂² − q₁²)`.
    ///
    /// # Panics
    ///
    /// If `y` or `out` does not have length 4.
    pub fn nonlinear(&self, y: &[f64], out: &mut [f64]) {
        check_len("y", y.len(), 4);
        check_len("out", out.len(), 4);
        let (q1, q2) = (y[0], y[1]);
        out[0] = 0.0;
        out[1] = 0.0;
        out[2] = -2.0 * q1 * q2;
        out[3] = q2 * q2 - q1 * q1;
    }

    /// `∇V(y) = (2q₁q₂, q₁² − q₂², 0, 0)`.
    ///
    /// # Panics
    ///
    /// If `y` or `out` does not have length 4.
    pub fn grad_v(&self, y: &[f64], out: &mut [f64]) {
        check_len("y", y.len(), 4);
        check_len("out", out.len(), 4);
        let (q1, q2) = (y[0], y[1]);
        out[0] = 2.0 * q1 * q2;
        out[1] = q1 * q1 - q2 * q2;
        out[2] = 0.0;
        out[3] = 0.0;
    }

    /// `V(y) = q₁²q₂ − q₂³/3`.
    ///
    /// # Panics
    ///
    /// If `y` does not have length 4.
    pub fn potential_v(&self, y: &[f64]) -> f64 {
        check_len("y", y.len(), 4);
        let (q1, q2) = (y[0], y[1]);
        q1 * q1 * q2 - q2 * q2 * q2 / 3.0
    }

    /// `H(y) = ½|p|² + ½|q|² + V(q)` (a first integral).
    ///
    /// # Panics
    ///
    /// If `y` does not have length 4.
    pub fn energy(&self, y: &[f64]) -> f64 {
        check_len("y", y.len(), 4);
        0.5 * (y[2] * y[2] + y[3] * y[3]) + 0.5 * (y[0] * y[0] + y[1] * y[1]) + self.potential_v(y)
    }

    /// The initial value.
    pub fn initial_value(&self) -> Vec<f64> {
        self.y0.to_vec()
    }
}

forward_test_problem!(HenonHeiles);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problems::testutil::check_structure;

    #[test]
    fn structure_and_energy() {
        let p = HenonHeiles::default();
        assert_eq!(p.energy(&p.initial_value()), 0.125);
        let ys = vec![
            vec![0.1, -0.2, 0.3, 0.05],
            vec![-0.3, 0.25, -0.1, 0.2],
            p.initial_value(),
        ];
        check_structure(&p, &ys, true);
        assert!(HenonHeiles::new([0.0, 0.0, 0.6, 0.0]).is_err());
        assert!(HenonHeiles::new([f64::NAN, 0.0, 0.0, 0.0]).is_err());
        assert!(HenonHeiles::new([0.1, 0.1, 0.1, 0.1]).is_ok());
    }
}
