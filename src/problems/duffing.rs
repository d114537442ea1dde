//! Problem 1: the Duffing equation.

use nalgebra::DMatrix;

use super::{check_len, forward_test_problem};
use crate::special::JacobiElliptic;
use ecr_runtime::{Error, Result};

/// Problem 1 of the paper (§9): the Duffing equation
///
/// ```text
/// (q, p)' = [[0, 1], [−ω² − k², 0]] (q, p) + (0, 2k²q³),   (q, p)(0) = (0, ω),
/// H(q, p) = ½p² + ½(ω² + k²)q² − (k²/2)q⁴,
/// ```
///
/// in the form `y' = Q∇H` with `y = (q, p)`, `Q = [[0, 1], [−1, 0]]` (so `q' = ∂H/∂p`,
/// `p' = −∂H/∂q`), `M = diag(ω² + k², 1)`, `V = −(k²/2)q⁴`, and `A = QM`.
///
/// Its exact solution is `q(t) = sn(ωt | m)`, `p(t) = q'(t) = ω cn(ωt | m) dn(ωt | m)` with the
/// **parameter** `m = (k/ω)²`: the paper's "`sn(ωt; k/ω)`" names the *modulus* `k/ω`
/// (see [`crate::special`]). The paper uses `k = 0.07` and `ω = 5, 10, 20`.
#[derive(Clone, Debug, PartialEq)]
pub struct Duffing {
    omega: f64,
    k: f64,
    jacobi: JacobiElliptic,
}

impl Default for Duffing {
    /// The paper's first case: `ω = 5`, `k = 0.07`.
    fn default() -> Self {
        Duffing::new(5.0, 0.07).expect("ω = 5, k = 0.07 are valid")
    }
}

impl Duffing {
    /// The Duffing problem with frequency `omega` (`ω`) and nonlinearity `k`.
    ///
    /// # Errors
    ///
    /// [`Error::NonFinite`] if `omega` or `k` is NaN or infinite; [`Error::InvalidParameter`]
    /// unless `ω > 0` and `|k| ≤ ω` (the elliptic parameter `m = (k/ω)²` must lie in `[0, 1]`;
    /// for `|k| > ω` the solution from `(0, ω)` is not the `sn` of the paper).
    pub fn new(omega: f64, k: f64) -> Result<Self> {
        if !omega.is_finite() {
            return Err(Error::NonFinite("Duffing frequency ω"));
        }
        if !k.is_finite() {
            return Err(Error::NonFinite("Duffing parameter k"));
        }
        if omega <= 0.0 {
            return Err(Error::InvalidParameter(format!(
                "Duffing frequency ω = {omega:?} must be > 0"
            )));
        }
        if k.abs() > omega {
            return Err(Error::InvalidParameter(format!(
                "Duffing parameter |k| = {:?} must not exceed ω = {omega:?} (modulus k/ω ≤ 1)",
                k.abs()
            )));
        }
        if !(omega * omega + k * k).is_finite() {
            return Err(Error::InvalidParameter(format!(
                "Duffing frequency ω = {omega:?} is too large: the stiffness ω² + k² overflows f64"
            )));
        }
        let jacobi = JacobiElliptic::new((k / omega).powi(2))?;
        Ok(Duffing { omega, k, jacobi })
    }

    /// The frequency `ω`.
    pub fn omega(&self) -> f64 {
        self.omega
    }

    /// The nonlinearity parameter `k`.
    pub fn k(&self) -> f64 {
        self.k
    }

    /// The elliptic parameter `m = (k/ω)²` of the exact solution (the modulus is `k/ω`).
    pub fn elliptic_parameter(&self) -> f64 {
        self.jacobi.parameter()
    }

    /// The dimension, 2.
    pub fn dim(&self) -> usize {
        2
    }

    /// `ω² + k²`, the stiffness of the linear part.
    fn stiffness(&self) -> f64 {
        self.omega * self.omega + self.k * self.k
    }

    /// `Q = [[0, 1], [−1, 0]]` (skew-symmetric: `H` is a first integral).
    pub fn q_matrix(&self) -> DMatrix<f64> {
        DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -1.0, 0.0])
    }

    /// `M = diag(ω² + k², 1)`.
    pub fn m_matrix(&self) -> DMatrix<f64> {
        DMatrix::from_row_slice(2, 2, &[self.stiffness(), 0.0, 0.0, 1.0])
    }

    /// `A = QM = [[0, 1], [−ω² − k², 0]]`.
    pub fn linear_matrix(&self) -> DMatrix<f64> {
        DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -self.stiffness(), 0.0])
    }

    /// `g(y) = Q∇V(y) = (0, 2k²q³)`.
    ///
    /// # Panics
    ///
    /// If `y` or `out` does not have length 2.
    pub fn nonlinear(&self, y: &[f64], out: &mut [f64]) {
        check_len("y", y.len(), 2);
        check_len("out", out.len(), 2);
        let q = y[0];
        out[0] = 0.0;
        out[1] = 2.0 * self.k * self.k * q * q * q;
    }

    /// `∇V(y) = (−2k²q³, 0)`.
    ///
    /// # Panics
    ///
    /// If `y` or `out` does not have length 2.
    pub fn grad_v(&self, y: &[f64], out: &mut [f64]) {
        check_len("y", y.len(), 2);
        check_len("out", out.len(), 2);
        let q = y[0];
        out[0] = -2.0 * self.k * self.k * q * q * q;
        out[1] = 0.0;
    }

    /// `V(y) = −(k²/2)q⁴`.
    ///
    /// # Panics
    ///
    /// If `y` does not have length 2.
    pub fn potential_v(&self, y: &[f64]) -> f64 {
        check_len("y", y.len(), 2);
        let q2 = y[0] * y[0];
        -0.5 * self.k * self.k * q2 * q2
    }

    /// `H(q, p) = ½p² + ½(ω² + k²)q² − (k²/2)q⁴`.
    ///
    /// # Panics
    ///
    /// If `y` does not have length 2.
    pub fn energy(&self, y: &[f64]) -> f64 {
        check_len("y", y.len(), 2);
        let (q, p) = (y[0], y[1]);
        0.5 * p * p + 0.5 * self.stiffness() * q * q + self.potential_v(y)
    }

    /// `y(0) = (0, ω)`; `H(y(0)) = ω²/2`.
    pub fn initial_value(&self) -> Vec<f64> {
        vec![0.0, self.omega]
    }

    /// The exact solution `(q, p)(t) = (sn(ωt | m), ω cn(ωt | m) dn(ωt | m))`, `m = (k/ω)²`.
    ///
    /// Accurate to about `2.3·10⁻¹⁶` in `q` and `ω·2.3·10⁻¹⁶` in `p` for the `f64` argument
    /// `ωt` (see [`crate::special`]); the rounding of the product `ωt` itself is a phase error
    /// of at most `ε ωt/2`.
    ///
    /// # Errors
    ///
    /// [`Error::NonFinite`] if `t` (or `ωt`) is NaN or infinite.
    pub fn exact(&self, t: f64) -> Result<[f64; 2]> {
        if !t.is_finite() {
            return Err(Error::NonFinite("time t"));
        }
        let (sn, cn, dn) = self.jacobi.sn_cn_dn(self.omega * t)?;
        Ok([sn, self.omega * cn * dn])
    }
}

forward_test_problem!(Duffing);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problems::testutil::{Rng, check_structure};

    #[test]
    fn constructor_validates() {
        assert!(matches!(
            Duffing::new(0.0, 0.07),
            Err(Error::InvalidParameter(_))
        ));
        assert!(matches!(
            Duffing::new(-5.0, 0.07),
            Err(Error::InvalidParameter(_))
        ));
        assert!(matches!(
            Duffing::new(5.0, 5.1),
            Err(Error::InvalidParameter(_))
        ));
        assert!(matches!(
            Duffing::new(f64::NAN, 0.07),
            Err(Error::NonFinite(_))
        ));
        assert!(matches!(
            Duffing::new(5.0, f64::INFINITY),
            Err(Error::NonFinite(_))
        ));
        assert!(Duffing::new(5.0, 5.0).is_ok()); // m = 1: q = tanh(5t)
        let d = Duffing::default();
        assert_eq!((d.omega(), d.k(), d.dim()), (5.0, 0.07, 2));
        assert!((d.elliptic_parameter() - 1.96e-4).abs() <= 1e-19);
        assert!(matches!(d.exact(f64::NAN), Err(Error::NonFinite(_))));
    }

    #[test]
    fn structure() {
        let mut rng = Rng(11);
        for omega in [5.0, 10.0, 20.0] {
            let d = Duffing::new(omega, 0.07).unwrap();
            assert_eq!(d.linear_matrix()[(1, 0)], -(omega * omega + 0.0049));
            let ys: Vec<Vec<f64>> = (0..20)
                .map(|_| vec![rng.sym(1.5), rng.sym(omega)])
                .collect();
            check_structure(&d, &ys, true);
        }
    }

    #[test]
    fn exact_solution_starts_at_the_initial_value() {
        for omega in [5.0, 10.0, 20.0] {
            let d = Duffing::new(omega, 0.07).unwrap();
            assert_eq!(d.exact(0.0).unwrap().to_vec(), d.initial_value());
            assert_eq!(d.energy(&d.initial_value()), 0.5 * omega * omega);
        }
    }

    /// q' = p and q'' = −(ω² + k²)q + 2k²q³ along the exact solution, by fourth-order centred
    /// differences with h = 2⁻¹² at dyadic t (so t ± jh and ωt are exact). Truncation
    /// ≈ (ωh)⁴ω^ν/30 (≤ 3e-10 for q', ≤ 3e-9 for q''), round-off ≈ 3ε/(2h)·|q| ≤ 2e-12 for q'
    /// and 16·2ε/(12h²) ≤ 1e-8 for q''. Tolerances 1e-8·ω and 1e-9·ω² (q'' ~ ω²). A wrong
    /// modulus convention (m = k/ω instead of (k/ω)²) makes the residual ≈ ω²·k/ω ≈ 1.4.
    #[test]
    fn exact_solution_satisfies_the_ode() {
        let h = 1.0 / 4096.0;
        let mut rng = Rng(12);
        for omega in [5.0, 20.0] {
            let d = Duffing::new(omega, 0.07).unwrap();
            let k2 = 0.07 * 0.07;
            let mut ts: Vec<f64> = (0..40).map(|_| (rng.next() * 4096.0).round() * h).collect();
            ts.extend((0..40).map(|_| (rng.next() * 1e4 * 4096.0).round() * h));
            let mut worst = (0.0f64, 0.0f64);
            for t in ts {
                let y = |s: f64| d.exact(t + s * h).unwrap();
                let (y0, p1, m1, p2, m2) = (y(0.0), y(1.0), y(-1.0), y(2.0), y(-2.0));
                let dq = (8.0 * (p1[0] - m1[0]) - (p2[0] - m2[0])) / (12.0 * h);
                let ddq =
                    (16.0 * (p1[0] + m1[0]) - (p2[0] + m2[0]) - 30.0 * y0[0]) / (12.0 * h * h);
                let rhs = -(omega * omega + k2) * y0[0] + 2.0 * k2 * y0[0].powi(3);
                let (e1, e2) = (
                    (dq - y0[1]).abs() / omega,
                    (ddq - rhs).abs() / (omega * omega),
                );
                worst = (worst.0.max(e1), worst.1.max(e2));
                assert!(e1 <= 1e-8, "ω={omega} t={t}: q' = {dq} vs p = {}", y0[1]);
                assert!(e2 <= 1e-9, "ω={omega} t={t}: q'' = {ddq} vs {rhs}");
            }
            eprintln!(
                "ω = {omega}: max |q'−p|/ω = {:e}, max |q''−f|/ω² = {:e}",
                worst.0, worst.1
            );
        }
    }

    /// H(exact(t)) = H(y0) = ω²/2 for t up to 10⁴ with ω = 20 (ωt up to 2·10⁵). With the
    /// absolute accuracy 2.3e-16 of sn, cn, dn, the relative error of H is a few 1e-16;
    /// tolerance 2e-15 (the brief asked for 1e-13).
    #[test]
    fn exact_solution_conserves_the_energy() {
        let mut rng = Rng(13);
        let mut worst: f64 = 0.0;
        for omega in [5.0, 10.0, 20.0] {
            let d = Duffing::new(omega, 0.07).unwrap();
            let h0 = d.energy(&d.initial_value());
            let mut ts: Vec<f64> = (0..=1000).map(|i| i as f64 * 10.0).collect();
            ts.extend((0..500).map(|_| rng.next() * 1e4));
            for t in ts {
                let err = (d.energy(&d.exact(t).unwrap()) - h0).abs() / h0;
                worst = worst.max(err);
                assert!(
                    err <= 2e-15,
                    "ω={omega} t={t}: relative energy error {err:e}"
                );
            }
        }
        eprintln!("Duffing exact solution: max relative energy error {worst:e}");
    }
}
