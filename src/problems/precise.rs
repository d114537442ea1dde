//! The problems in any [`Real`] scalar: [`GenericSystem`] for [`Duffing`], [`Wind`] and
//! [`HenonHeiles`], the same formulas as their `f64` methods.

use super::{Duffing, HenonHeiles, Wind};
use ecr_runtime::precision::{GenericSystem, LinearPart, Real};

impl Duffing {
    /// `ω² + k²` in `S` (the parameters are exact `f64`).
    fn stiffness_in<S: Real>(&self) -> S {
        let (w, k) = (S::from_f64(self.omega()), S::from_f64(self.k()));
        w * w + k * k
    }
}

impl<S: Real> GenericSystem<S> for Duffing {
    fn dim(&self) -> usize {
        2
    }

    fn linear_part(&self) -> LinearPart<S> {
        LinearPart::Dense {
            dim: 2,
            entries: vec![S::zero(), S::one(), -self.stiffness_in::<S>(), S::zero()],
        }
    }

    fn nonlinear(&self, y: &[S], out: &mut [S]) {
        let k = S::from_f64(self.k());
        let q = y[0];
        out[0] = S::zero();
        out[1] = S::from_f64(2.0) * k * k * q * q * q;
    }

    fn energy(&self, y: &[S]) -> Option<S> {
        let (q, p) = (y[0], y[1]);
        let k = S::from_f64(self.k());
        let half = S::from_f64(0.5);
        let q2 = q * q;
        Some(half * p * p + half * self.stiffness_in::<S>() * q2 - half * k * k * q2 * q2)
    }
}

impl Wind {
    /// `(cos θ, sin θ)` in `S`: exact for θ = π/2, from δ when made from δ.
    fn trig_in<S: Real>(&self) -> (S, S) {
        if self.is_conservative() {
            (S::zero(), S::one())
        } else if let Some(delta) = self.deviation() {
            let (c, s) = S::cos_sin(delta);
            (s, c)
        } else {
            S::cos_sin(self.theta())
        }
    }
}

impl<S: Real> GenericSystem<S> for Wind {
    fn dim(&self) -> usize {
        2
    }

    fn linear_part(&self) -> LinearPart<S> {
        let (c, s) = self.trig_in::<S>();
        let r = S::from_f64(self.radius());
        let (zeta, lambda) = (r * c, r * s);
        LinearPart::Dense {
            dim: 2,
            entries: vec![-zeta, -lambda, lambda, -zeta],
        }
    }

    fn nonlinear(&self, y: &[S], out: &mut [S]) {
        let (x1, x2) = (y[0], y[1]);
        out[0] = x1 * x2;
        out[1] = S::from_f64(0.5) * (x1 * x1 - x2 * x2);
    }

    fn energy(&self, y: &[S]) -> Option<S> {
        let (x1, x2) = (y[0], y[1]);
        let (c, s) = self.trig_in::<S>();
        let half = S::from_f64(0.5);
        let three = S::from_f64(3.0);
        let v = -half * s * (x1 * x2 * x2 - x1 * x1 * x1 / three)
            + half * c * (-x1 * x1 * x2 + x2 * x2 * x2 / three);
        Some(half * S::from_f64(self.radius()) * (x1 * x1 + x2 * x2) + v)
    }
}

impl<S: Real> GenericSystem<S> for HenonHeiles {
    fn dim(&self) -> usize {
        4
    }

    fn linear_part(&self) -> LinearPart<S> {
        let (o, z) = (S::one(), S::zero());
        LinearPart::Dense {
            dim: 4,
            entries: vec![z, z, o, z, z, z, z, o, -o, z, z, z, z, -o, z, z],
        }
    }

    fn nonlinear(&self, y: &[S], out: &mut [S]) {
        let (q1, q2) = (y[0], y[1]);
        out[0] = S::zero();
        out[1] = S::zero();
        out[2] = -(S::from_f64(2.0) * q1 * q2);
        out[3] = q2 * q2 - q1 * q1;
    }

    fn energy(&self, y: &[S]) -> Option<S> {
        let (q1, q2, p1, p2) = (y[0], y[1], y[2], y[3]);
        let half = S::from_f64(0.5);
        Some(
            half * (p1 * p1 + p2 * p2) + half * (q1 * q1 + q2 * q2) + q1 * q1 * q2
                - q2 * q2 * q2 / S::from_f64(3.0),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problems::TestProblem;
    use ecr_runtime::precision::DoubleDouble;

    /// The generic formulas in f64 are the problems' f64 methods (to a rounding or two), and in
    /// double-double agree with them to f64 accuracy.
    fn agrees<P: TestProblem + GenericSystem<f64> + GenericSystem<DoubleDouble>>(
        p: &P,
        ys: &[Vec<f64>],
    ) {
        let d = TestProblem::dim(p);
        for y in ys {
            let mut g = vec![0.0; d];
            let mut gf = vec![0.0; d];
            TestProblem::nonlinear(p, y, &mut g);
            GenericSystem::<f64>::nonlinear(p, y, &mut gf);
            let yd: Vec<DoubleDouble> = y.iter().map(|&v| v.into()).collect();
            let mut gd = vec![DoubleDouble::default(); d];
            GenericSystem::<DoubleDouble>::nonlinear(p, &yd, &mut gd);
            let scale = g.iter().fold(1e-300f64, |m, v| m.max(v.abs()));
            for i in 0..d {
                assert!((g[i] - gf[i]).abs() <= 4e-16 * scale, "g[{i}]");
                assert!((g[i] - gd[i].to_f64()).abs() <= 4e-16 * scale, "g[{i}] dd");
            }
            let e = TestProblem::energy(p, y);
            let ef = GenericSystem::<f64>::energy(p, y).unwrap();
            let ed = GenericSystem::<DoubleDouble>::energy(p, &yd).unwrap();
            assert!((e - ef).abs() <= 1e-15 * e.abs().max(1.0));
            assert!((e - ed.to_f64()).abs() <= 1e-15 * e.abs().max(1.0));
            let a = p.linear_matrix();
            match GenericSystem::<DoubleDouble>::linear_part(p) {
                LinearPart::Dense { dim, entries } => {
                    assert_eq!(dim, d);
                    for i in 0..d {
                        for j in 0..d {
                            let v = entries[i * d + j].to_f64();
                            assert!((a[(i, j)] - v).abs() <= 1e-15 * a.amax(), "A[{i},{j}]");
                        }
                    }
                }
                other => panic!("unexpected linear part {other:?}"),
            }
        }
    }

    #[test]
    fn generic_forms_match_the_f64_problems() {
        let ys = vec![vec![0.3, -0.7], vec![1.1, 0.25], vec![0.0, 5.0]];
        agrees(&Duffing::default(), &ys);
        agrees(&Duffing::new(20.0, 0.3).unwrap(), &ys);
        agrees(&Wind::conservative(), &ys);
        agrees(&Wind::dissipative(), &ys);
        agrees(&Wind::new(0.3, 2.0).unwrap(), &ys);
        let ys4 = vec![vec![0.1, -0.2, 0.3, 0.05], vec![0.0, 0.0, 0.5, 0.0]];
        agrees(&HenonHeiles::default(), &ys4);
    }

    #[test]
    fn dissipative_wind_trig_in_double_double() {
        // cos θ = sin δ to double-double accuracy (not the f64 value).
        let w = Wind::dissipative();
        let (c, s) = w.trig_in::<DoubleDouble>();
        assert_eq!(c.to_f64(), 1e-4f64.sin());
        assert!(c.lo() != 0.0 && s.to_f64() == 1e-4f64.cos());
    }
}
