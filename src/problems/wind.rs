//! Problem 2: the averaged system in wind-induced oscillation.

use std::f64::consts::FRAC_PI_2;

use nalgebra::DMatrix;

use super::{check_len, forward_test_problem};
use ecr_runtime::{Error, Result};

/// Problem 2 of the paper (§9): the averaged system in wind-induced oscillation
/// (McLachlan–Quispel–Robidoux 1998)
///
/// ```text
/// x' = [[−ζ, −λ], [λ, −ζ]] x + (x₁x₂, ½(x₁² − x₂²)),   x(0) = (0, 1),
/// ζ = r cos θ (damping),   λ = r sin θ (detuning),   r ≥ 0,   0 ≤ θ ≤ π/2,
/// ```
///
/// in the form `x' = Q∇H` with `Q = [[−cos θ, −sin θ], [sin θ, −cos θ]]`, `M = r I`,
/// `V = −½ sin θ (x₁x₂² − x₁³/3) + ½ cos θ (−x₁²x₂ + x₂³/3)`, `H = ½ r |x|² + V`.
/// `θ = π/2` is conservative (`Q` skew, `H` a first integral); `θ < π/2` is dissipative (`Q`
/// negative definite, `H` a Lyapunov function). Note `g = Q∇V = (x₁x₂, ½(x₁² − x₂²))` does not
/// depend on `θ`.
///
/// The paper's "`r = 20`" is this **radius** `r` (not a number of nodes). The paper's runs:
/// [`Wind::conservative`] (`θ = π/2`, `r = 20`) and [`Wind::dissipative`]
/// (`θ = π/2 − 10⁻⁴`, `r = 20`).
///
/// `cos θ` and `sin θ` are stored, not recomputed: the conservative case has `cos θ = 0`
/// *exactly* (the `f64` nearest to π/2 has cosine `6.1·10⁻¹⁷`, which would add a spurious
/// damping `ζ ≈ 1.2·10⁻¹⁵` and a relative energy decay of `≈ 2·10⁻¹¹` over `t = 10⁴`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wind {
    theta: f64,
    radius: f64,
    cos_theta: f64,
    sin_theta: f64,
    /// `δ = π/2 − θ` when the problem was made from it (its trigonometric values are then
    /// `cos θ = sin δ`, `sin θ = cos δ`, also in other precisions).
    deviation: Option<f64>,
}

impl Default for Wind {
    /// The paper's conservative case, [`Wind::conservative`].
    fn default() -> Self {
        Wind::conservative()
    }
}

impl Wind {
    /// The system for angle `theta` (`θ`) and radius `radius` (`r`).
    ///
    /// `theta == std::f64::consts::FRAC_PI_2` is taken to mean `θ = π/2` exactly
    /// (`cos θ = 0`, `sin θ = 1`); for a small deviation from `π/2` prefer
    /// [`Wind::from_deviation`], which avoids the cancellation in `π/2 − θ`.
    ///
    /// # Errors
    ///
    /// [`Error::NonFinite`] for NaN or infinite input; [`Error::InvalidParameter`] unless
    /// `0 ≤ θ ≤ π/2` and `r ≥ 0` (the paper's ranges; they make `ζ ≥ 0`, `Q ≤ 0`).
    pub fn new(theta: f64, radius: f64) -> Result<Self> {
        if !theta.is_finite() {
            return Err(Error::NonFinite("wind angle θ"));
        }
        if !(0.0..=FRAC_PI_2).contains(&theta) {
            return Err(Error::InvalidParameter(format!(
                "wind angle θ = {theta:?} must lie in [0, π/2]"
            )));
        }
        let (sin_theta, cos_theta) = if theta == FRAC_PI_2 {
            (1.0, 0.0)
        } else {
            theta.sin_cos()
        };
        Self::with_trig(theta, radius, cos_theta, sin_theta)
    }

    /// The system for `θ = π/2 − delta` and radius `radius`: `cos θ = sin δ`, `sin θ = cos δ`
    /// computed from `δ` without cancellation. `delta = 0` is the conservative case.
    ///
    /// # Errors
    ///
    /// [`Error::NonFinite`] for NaN or infinite input; [`Error::InvalidParameter`] unless
    /// `0 ≤ δ ≤ π/2` and `r ≥ 0`.
    pub fn from_deviation(delta: f64, radius: f64) -> Result<Self> {
        if !delta.is_finite() {
            return Err(Error::NonFinite("wind angle deviation δ"));
        }
        if !(0.0..=FRAC_PI_2).contains(&delta) {
            return Err(Error::InvalidParameter(format!(
                "wind angle deviation δ = π/2 − θ = {delta:?} must lie in [0, π/2]"
            )));
        }
        let (cos_theta, sin_theta) = delta.sin_cos();
        let mut wind = Self::with_trig(FRAC_PI_2 - delta, radius, cos_theta, sin_theta)?;
        // δ = 0 is θ = π/2 exactly: the conservative problem, whichever way it was made.
        wind.deviation = (delta != 0.0).then_some(delta);
        Ok(wind)
    }

    fn with_trig(theta: f64, radius: f64, cos_theta: f64, sin_theta: f64) -> Result<Self> {
        if !radius.is_finite() {
            return Err(Error::NonFinite("wind radius r"));
        }
        if radius < 0.0 {
            return Err(Error::InvalidParameter(format!(
                "wind radius r = {radius:?} must be ≥ 0"
            )));
        }
        Ok(Wind {
            theta,
            radius,
            cos_theta,
            sin_theta,
            deviation: None,
        })
    }

    /// The paper's conservative case: `θ = π/2` (exactly), `r = 20`.
    pub fn conservative() -> Self {
        Wind {
            theta: FRAC_PI_2,
            radius: 20.0,
            cos_theta: 0.0,
            sin_theta: 1.0,
            deviation: None,
        }
    }

    /// The paper's dissipative case: `θ = π/2 − 10⁻⁴`, `r = 20` (`ζ = 20 sin 10⁻⁴ ≈ 2·10⁻³`).
    pub fn dissipative() -> Self {
        Wind::from_deviation(1e-4, 20.0).expect("δ = 1e-4, r = 20 are valid")
    }

    /// The angle `θ` (for the conservative case the `f64` nearest to `π/2`).
    pub fn theta(&self) -> f64 {
        self.theta
    }

    /// The radius `r`.
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The damping factor `ζ = r cos θ`.
    pub fn zeta(&self) -> f64 {
        self.radius * self.cos_theta
    }

    /// The detuning parameter `λ = r sin θ`.
    pub fn lambda(&self) -> f64 {
        self.radius * self.sin_theta
    }

    /// `δ = π/2 − θ`, if the problem was made by [`Wind::from_deviation`].
    pub fn deviation(&self) -> Option<f64> {
        self.deviation
    }

    /// Whether `cos θ = 0` exactly, i.e. `Q` is skew-symmetric and `H` a first integral.
    pub fn is_conservative(&self) -> bool {
        self.cos_theta == 0.0
    }

    /// The dimension, 2.
    pub fn dim(&self) -> usize {
        2
    }

    /// `Q = [[−cos θ, −sin θ], [sin θ, −cos θ]]`.
    pub fn q_matrix(&self) -> DMatrix<f64> {
        let (c, s) = (self.cos_theta, self.sin_theta);
        DMatrix::from_row_slice(2, 2, &[-c, -s, s, -c])
    }

    /// `M = r I`.
    pub fn m_matrix(&self) -> DMatrix<f64> {
        DMatrix::from_diagonal_element(2, 2, self.radius)
    }

    /// `A = QM = [[−ζ, −λ], [λ, −ζ]]`.
    pub fn linear_matrix(&self) -> DMatrix<f64> {
        let (z, l) = (self.zeta(), self.lambda());
        DMatrix::from_row_slice(2, 2, &[-z, -l, l, -z])
    }

    /// `g(x) = Q∇V(x) = (x₁x₂, ½(x₁² − x₂²))`.
    ///
    /// # Panics
    ///
    /// If `y` or `out` does not have length 2.
    pub fn nonlinear(&self, y: &[f64], out: &mut [f64]) {
        check_len("y", y.len(), 2);
        check_len("out", out.len(), 2);
        let (x1, x2) = (y[0], y[1]);
        out[0] = x1 * x2;
        out[1] = 0.5 * (x1 * x1 - x2 * x2);
    }

    /// `∇V(x) = (½ sin θ (x₁² − x₂²) − cos θ x₁x₂, −sin θ x₁x₂ + ½ cos θ (x₂² − x₁²))`.
    ///
    /// # Panics
    ///
    /// If `y` or `out` does not have length 2.
    pub fn grad_v(&self, y: &[f64], out: &mut [f64]) {
        check_len("y", y.len(), 2);
        check_len("out", out.len(), 2);
        let (x1, x2) = (y[0], y[1]);
        let (c, s) = (self.cos_theta, self.sin_theta);
        let half_diff = 0.5 * (x1 * x1 - x2 * x2);
        out[0] = s * half_diff - c * x1 * x2;
        out[1] = -s * x1 * x2 - c * half_diff;
    }

    /// `V(x) = −½ sin θ (x₁x₂² − x₁³/3) + ½ cos θ (−x₁²x₂ + x₂³/3)`.
    ///
    /// # Panics
    ///
    /// If `y` does not have length 2.
    pub fn potential_v(&self, y: &[f64]) -> f64 {
        check_len("y", y.len(), 2);
        let (x1, x2) = (y[0], y[1]);
        let (c, s) = (self.cos_theta, self.sin_theta);
        -0.5 * s * (x1 * x2 * x2 - x1 * x1 * x1 / 3.0)
            + 0.5 * c * (-x1 * x1 * x2 + x2 * x2 * x2 / 3.0)
    }

    /// `H(x) = ½ r (x₁² + x₂²) + V(x)` (first integral for `θ = π/2`, Lyapunov function
    /// otherwise).
    ///
    /// # Panics
    ///
    /// If `y` does not have length 2.
    pub fn energy(&self, y: &[f64]) -> f64 {
        check_len("y", y.len(), 2);
        0.5 * self.radius * (y[0] * y[0] + y[1] * y[1]) + self.potential_v(y)
    }

    /// `x(0) = (0, 1)`.
    pub fn initial_value(&self) -> Vec<f64> {
        vec![0.0, 1.0]
    }
}

forward_test_problem!(Wind);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problems::testutil::{Rng, check_structure};

    #[test]
    fn constructors() {
        let c = Wind::conservative();
        assert!(c.is_conservative());
        assert_eq!((c.zeta(), c.lambda(), c.radius()), (0.0, 20.0, 20.0));
        assert_eq!(Wind::new(FRAC_PI_2, 20.0).unwrap(), c);
        assert_eq!(Wind::from_deviation(0.0, 20.0).unwrap(), c);
        assert_eq!(Wind::default(), c);
        let d = Wind::dissipative();
        assert!(!d.is_conservative());
        assert_eq!(d.theta(), FRAC_PI_2 - 1e-4);
        // ζ = 20 sin(1e-4) = 20(1e-4 − 1e-12/6 + ...), λ = 20 cos(1e-4).
        assert!((d.zeta() - 20.0 * (1e-4 - 1e-12 / 6.0)).abs() <= 1e-19);
        assert!((d.lambda() - 20.0 * (1.0 - 0.5e-8)).abs() <= 1e-14);
        // Through `new` the same case differs only by the rounding of π/2 − 1e-4.
        let d2 = Wind::new(FRAC_PI_2 - 1e-4, 20.0).unwrap();
        assert!((d2.zeta() - d.zeta()).abs() <= 1e-11 * d.zeta()); // ulp(π/2)/1e-4 ≈ 2e-12
        assert!(matches!(
            Wind::new(-0.1, 20.0),
            Err(Error::InvalidParameter(_))
        ));
        assert!(matches!(
            Wind::new(1.6, 20.0),
            Err(Error::InvalidParameter(_))
        ));
        assert!(matches!(
            Wind::new(1.0, -1.0),
            Err(Error::InvalidParameter(_))
        ));
        assert!(matches!(Wind::new(f64::NAN, 1.0), Err(Error::NonFinite(_))));
        assert!(matches!(
            Wind::new(1.0, f64::INFINITY),
            Err(Error::NonFinite(_))
        ));
        assert!(matches!(
            Wind::from_deviation(-1e-4, 1.0),
            Err(Error::InvalidParameter(_))
        ));
        assert!(matches!(
            Wind::from_deviation(f64::NAN, 1.0),
            Err(Error::NonFinite(_))
        ));
    }

    #[test]
    fn structure() {
        let mut rng = Rng(21);
        let ys: Vec<Vec<f64>> = (0..20).map(|_| vec![rng.sym(2.0), rng.sym(2.0)]).collect();
        check_structure(&Wind::conservative(), &ys, true);
        check_structure(&Wind::dissipative(), &ys, false);
        for theta in [0.0, 0.3, 1.2] {
            check_structure(&Wind::new(theta, 3.5).unwrap(), &ys, false);
        }
    }

    /// The vector field against the paper's first form, `x' = [[−ζ, −λ], [λ, −ζ]]x + g`,
    /// equal to `Q(Mx + ∇V)` (relative 1e-14 of the magnitudes involved).
    #[test]
    fn vector_field_matches_the_paper() {
        let mut rng = Rng(22);
        for w in [
            Wind::conservative(),
            Wind::dissipative(),
            Wind::new(0.7, 2.0).unwrap(),
        ] {
            for _ in 0..20 {
                let x = [rng.sym(2.0), rng.sym(2.0)];
                let paper = [
                    -w.zeta() * x[0] - w.lambda() * x[1] + x[0] * x[1],
                    w.lambda() * x[0] - w.zeta() * x[1] + 0.5 * (x[0] * x[0] - x[1] * x[1]),
                ];
                let mut grad = [0.0; 2];
                w.grad_v(&x, &mut grad);
                let gh = [w.radius() * x[0] + grad[0], w.radius() * x[1] + grad[1]];
                let q = w.q_matrix();
                for i in 0..2 {
                    let f = q[(i, 0)] * gh[0] + q[(i, 1)] * gh[1];
                    assert!((f - paper[i]).abs() <= 1e-14 * (1.0 + w.radius() * 2.0 * 2.0));
                }
            }
        }
    }

    #[test]
    fn initial_value_and_energy() {
        let w = Wind::conservative();
        assert_eq!(w.initial_value(), vec![0.0, 1.0]);
        // H(0, 1) = ½·20 + ½ cos θ/3 = 10 for θ = π/2.
        assert_eq!(w.energy(&w.initial_value()), 10.0);
    }
}
