//! High-precision arithmetic (astro-float) for the references: exact solutions and a
//! Taylor-series integrator for polynomial vector fields.

use astro_float::{BigFloat, Consts, Radix, RoundingMode, Sign};

/// Bits of the high-precision references (57 decimal digits).
pub const PREC: usize = 192;
const RM: RoundingMode = RoundingMode::ToEven;

/// High-precision arithmetic at a fixed precision.
pub struct Hp {
    pub prec: usize,
    cc: Consts,
}

impl Hp {
    pub fn new(prec: usize) -> Self {
        Hp {
            prec,
            cc: Consts::new().expect("astro-float constants cache"),
        }
    }
    /// Exact (no f64 here is subnormal).
    pub fn f(&self, x: f64) -> BigFloat {
        BigFloat::from_f64(x, self.prec)
    }
    pub fn add(&self, a: &BigFloat, b: &BigFloat) -> BigFloat {
        a.add(b, self.prec, RM)
    }
    pub fn sub(&self, a: &BigFloat, b: &BigFloat) -> BigFloat {
        a.sub(b, self.prec, RM)
    }
    pub fn mul(&self, a: &BigFloat, b: &BigFloat) -> BigFloat {
        a.mul(b, self.prec, RM)
    }
    pub fn div(&self, a: &BigFloat, b: &BigFloat) -> BigFloat {
        a.div(b, self.prec, RM)
    }
    pub fn neg(&self, a: &BigFloat) -> BigFloat {
        a.neg()
    }
    pub fn sqrt(&self, a: &BigFloat) -> BigFloat {
        a.sqrt(self.prec, RM)
    }
    pub fn floor(&self, a: &BigFloat) -> BigFloat {
        a.floor()
    }
    pub fn pi(&mut self) -> BigFloat {
        self.cc.pi(self.prec, RM)
    }
    pub fn sin(&mut self, a: &BigFloat) -> BigFloat {
        a.sin(self.prec, RM, &mut self.cc)
    }
    pub fn cos(&mut self, a: &BigFloat) -> BigFloat {
        a.cos(self.prec, RM, &mut self.cc)
    }
    pub fn exp(&mut self, a: &BigFloat) -> BigFloat {
        a.exp(self.prec, RM, &mut self.cc)
    }
    pub fn atan(&mut self, a: &BigFloat) -> BigFloat {
        a.atan(self.prec, RM, &mut self.cc)
    }
    /// Σ_{j=0}^{k} a_j b_{k−j}: the k-th coefficient of a product of series.
    pub fn cauchy(&self, a: &[BigFloat], b: &[BigFloat], k: usize) -> BigFloat {
        let mut s = self.mul(&a[0], &b[k]);
        for j in 1..=k {
            s = self.add(&s, &self.mul(&a[j], &b[k - j]));
        }
        s
    }
    /// Decimal digits (all of the precision).
    pub fn decimal(&mut self, a: &BigFloat) -> String {
        a.format(Radix::Dec, RM, &mut self.cc).expect("format")
    }
}

/// The nearest f64 (to within an ulp: from the top 64 bits of the mantissa).
pub fn to_f64(x: &BigFloat) -> f64 {
    if x.is_zero() {
        return 0.0;
    }
    let (m, _n, s, e, _) = x.as_raw_parts().expect("finite value");
    let top = *m.last().expect("mantissa") as f64 / 18446744073709551616.0; // in [1/2, 1)
    let e1 = e / 2;
    let v = top * 2f64.powi(e1) * 2f64.powi(e - e1);
    if s == Sign::Neg { -v } else { v }
}

/// The k-th Taylor coefficient of the right-hand side f(x(t)) from the coefficients 0..=k of
/// x (and of auxiliary series, which it extends by their k-th coefficient).
pub type TaylorRhs = fn(&Hp, &[Vec<BigFloat>], &mut Vec<Vec<BigFloat>>, usize) -> Vec<BigFloat>;

/// A Taylor-series integration of x' = f(x) from (t0, x0) to each of `times` (ascending,
/// reached exactly), `order` terms, step ρ·`shrink` with ρ the radius of convergence
/// estimated from the last two coefficients (Jorba & Zou 2005). Returns the states and the
/// number of steps.
pub fn taylor(
    hp: &Hp,
    f: TaylorRhs,
    x0: &[BigFloat],
    t0: f64,
    times: &[f64],
    order: usize,
    shrink: f64,
) -> (Vec<Vec<BigFloat>>, usize) {
    let d = x0.len();
    let mut x = x0.to_vec();
    let mut t = hp.f(t0);
    let mut out = Vec::with_capacity(times.len());
    let mut steps = 0;
    for &target in times {
        let target = hp.f(target);
        while t.cmp(&target).is_some_and(|c| c < 0) {
            let mut c: Vec<Vec<BigFloat>> = x.iter().map(|v| vec![v.clone()]).collect();
            let mut aux = Vec::new();
            for k in 0..order {
                let fk = f(hp, &c, &mut aux, k);
                let kk = hp.f((k + 1) as f64);
                for i in 0..d {
                    c[i].push(hp.div(&fk[i], &kk));
                }
            }
            let norm = |j: usize| c.iter().map(|ci| to_f64(&ci[j]).abs()).fold(0.0, f64::max);
            let scale = norm(0).max(1.0);
            let rho = [order - 1, order]
                .iter()
                .map(|&j| (scale / norm(j)).powf(1.0 / j as f64))
                .fold(f64::INFINITY, f64::min);
            let left = hp.sub(&target, &t);
            let (h, last) = if rho * shrink >= to_f64(&left) {
                (left, true)
            } else {
                (hp.f(rho * shrink), false)
            };
            for i in 0..d {
                let mut s = c[i][order].clone();
                for j in (0..order).rev() {
                    s = hp.add(&hp.mul(&s, &h), &c[i][j]);
                }
                x[i] = s;
            }
            t = if last { target.clone() } else { hp.add(&t, &h) };
            steps += 1;
        }
        out.push(x.clone());
    }
    (out, steps)
}
