//! High-precision references for the φ-function tests (astro-float), and small helpers.
//!
//! The references never use the algorithms under test: Taylor series of φ_p followed by the
//! downward recurrence for moderate |z| (with enough guard bits to absorb any cancellation),
//! the closed form `φ_k(z) = (e^z − Σ_{j<k} z^j/j!)/z^k` for large |z|, and high-precision
//! exp/sin/cos.
#![allow(dead_code, clippy::needless_range_loop)]

pub use astro_float::BigFloat;
use astro_float::{Consts, RoundingMode, Sign};
use num_complex::Complex64;

const RM: RoundingMode = RoundingMode::ToEven;

/// A complex number in high precision.
#[derive(Clone, Debug)]
pub struct Hc {
    pub re: BigFloat,
    pub im: BigFloat,
}

/// High-precision arithmetic context.
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

    /// Exact conversion. (astro-float 0.9 converts subnormal f64 off by a factor 2, so those
    /// are scaled into the normal range first; the scaling by 2^100 is exact.)
    pub fn f(&self, x: f64) -> BigFloat {
        if x != 0.0 && x.abs() < f64::MIN_POSITIVE {
            let s = BigFloat::from_f64(2f64.powi(100), self.prec);
            BigFloat::from_f64(x * 2f64.powi(100), self.prec).div(&s, self.prec, RM)
        } else {
            BigFloat::from_f64(x, self.prec)
        }
    }
    pub fn int(&self, n: i64) -> BigFloat {
        BigFloat::from_i64(n, self.prec)
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
    pub fn exp(&mut self, a: &BigFloat) -> BigFloat {
        a.exp(self.prec, RM, &mut self.cc)
    }
    pub fn sin(&mut self, a: &BigFloat) -> BigFloat {
        a.sin(self.prec, RM, &mut self.cc)
    }
    pub fn cos(&mut self, a: &BigFloat) -> BigFloat {
        a.cos(self.prec, RM, &mut self.cc)
    }
    pub fn sqrt(&self, a: &BigFloat) -> BigFloat {
        a.sqrt(self.prec, RM)
    }

    pub fn c(&self, z: Complex64) -> Hc {
        Hc {
            re: self.f(z.re),
            im: self.f(z.im),
        }
    }
    pub fn creal(&self, x: &BigFloat) -> Hc {
        Hc {
            re: x.clone(),
            im: self.f(0.0),
        }
    }
    pub fn cadd(&self, a: &Hc, b: &Hc) -> Hc {
        Hc {
            re: self.add(&a.re, &b.re),
            im: self.add(&a.im, &b.im),
        }
    }
    pub fn csub(&self, a: &Hc, b: &Hc) -> Hc {
        Hc {
            re: self.sub(&a.re, &b.re),
            im: self.sub(&a.im, &b.im),
        }
    }
    pub fn cmul(&self, a: &Hc, b: &Hc) -> Hc {
        Hc {
            re: self.sub(&self.mul(&a.re, &b.re), &self.mul(&a.im, &b.im)),
            im: self.add(&self.mul(&a.re, &b.im), &self.mul(&a.im, &b.re)),
        }
    }
    pub fn cscale(&self, a: &Hc, s: &BigFloat) -> Hc {
        Hc {
            re: self.mul(&a.re, s),
            im: self.mul(&a.im, s),
        }
    }
    pub fn cdiv(&self, a: &Hc, b: &Hc) -> Hc {
        let den = self.add(&self.mul(&b.re, &b.re), &self.mul(&b.im, &b.im));
        let re = self.add(&self.mul(&a.re, &b.re), &self.mul(&a.im, &b.im));
        let im = self.sub(&self.mul(&a.im, &b.re), &self.mul(&a.re, &b.im));
        Hc {
            re: self.div(&re, &den),
            im: self.div(&im, &den),
        }
    }
    pub fn cabs(&self, a: &Hc) -> BigFloat {
        self.sqrt(&self.add(&self.mul(&a.re, &a.re), &self.mul(&a.im, &a.im)))
    }
    pub fn cexp(&mut self, z: &Hc) -> Hc {
        let r = self.exp(&z.re);
        let (c, s) = (self.cos(&z.im), self.sin(&z.im));
        Hc {
            re: self.mul(&r, &c),
            im: self.mul(&r, &s),
        }
    }

    /// `1/k!`.
    pub fn inv_fact(&self, k: usize) -> BigFloat {
        let mut v = self.f(1.0);
        for j in 2..=k {
            v = self.div(&v, &self.int(j as i64));
        }
        v
    }

    /// `φ_0(z), …, φ_p(z)` in high precision (see the module documentation).
    pub fn phi(&mut self, z: Complex64, p: usize) -> Vec<Hc> {
        let r = z.norm();
        let zz = self.c(z);
        let mut out = vec![self.creal(&self.f(0.0)); p + 1];
        if r <= 24.0 {
            // Taylor series of φ_p to well below 2^-prec, then φ_k = z φ_{k+1} + 1/k!. The
            // recurrence loses at most ~3|z| bits (the caller's precision covers it).
            let mut term = self.creal(&self.inv_fact(p));
            let mut sum = term.clone();
            let tiny = self.f(2f64.powi(-(self.prec as i32) - 20));
            let mut n = 0usize;
            loop {
                n += 1;
                term = self.cscale(
                    &self.cmul(&term, &zz),
                    &self.div(&self.f(1.0), &self.int((n + p) as i64)),
                );
                sum = self.cadd(&sum, &term);
                let mag = self.cabs(&term);
                if n as f64 > 2.0 * r + 4.0 && mag.cmp(&tiny).is_some_and(|c| c < 0) {
                    break;
                }
            }
            out[p] = sum;
            for k in (0..p).rev() {
                out[k] = self.cadd(&self.cmul(&zz, &out[k + 1]), &self.creal(&self.inv_fact(k)));
            }
        } else {
            // Closed form; e^z − Σ_{j<k} z^j/j! cancels only next to zeros of φ_k.
            let ez = self.cexp(&zz);
            out[0] = ez.clone();
            let mut poly = self.creal(&self.f(0.0)); // Σ_{j<k} z^j/j!
            let mut zj = self.creal(&self.f(1.0)); // z^j
            let mut zk = self.creal(&self.f(1.0)); // z^k
            for k in 1..=p {
                poly = self.cadd(&poly, &self.cscale(&zj, &self.inv_fact(k - 1)));
                zj = self.cmul(&zj, &zz);
                zk = self.cmul(&zk, &zz);
                out[k] = self.cdiv(&self.csub(&ez, &poly), &zk);
            }
        }
        out
    }

    /// `|c − r| / |r|` as f64 (modulus), with `c` converted exactly.
    pub fn rel_err(&self, c: Complex64, r: &Hc) -> f64 {
        let d = self.csub(&self.c(c), r);
        to_f64(&self.div(&self.cabs(&d), &self.cabs(r)))
    }

    /// `|c − r|` as f64.
    pub fn abs_err(&self, c: Complex64, r: &Hc) -> f64 {
        to_f64(&self.cabs(&self.csub(&self.c(c), r)))
    }

    pub fn abs_f64(&self, r: &Hc) -> f64 {
        to_f64(&self.cabs(r))
    }
}

/// Nearest f64 (from the top 64 mantissa bits; ±∞ beyond the range, 0 below it).
pub fn to_f64(x: &BigFloat) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    if x.is_inf_pos() {
        return f64::INFINITY;
    }
    if x.is_inf_neg() {
        return f64::NEG_INFINITY;
    }
    if x.is_zero() {
        return 0.0;
    }
    let (m, _n, s, e, _) = x.as_raw_parts().expect("finite value");
    let top = *m.last().expect("mantissa") as f64 / 18446744073709551616.0; // in [1/2, 1)
    let v = if e > 1100 {
        f64::INFINITY
    } else if e < -1200 {
        0.0
    } else {
        // two steps so that 2^e itself does not over/underflow prematurely
        let e1 = e / 2;
        top * 2f64.powi(e1) * 2f64.powi(e - e1)
    };
    if s == Sign::Neg { -v } else { v }
}

/// Complex reference converted to f64 (componentwise).
pub fn to_c64(z: &Hc) -> Complex64 {
    Complex64::new(to_f64(&z.re), to_f64(&z.im))
}

/// Deterministic pseudo-random numbers (SplitMix64) for test data.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in [a, b).
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.uniform()
    }
}

/// Logarithmic grid `10^e`, `e = lo, lo + 1/per_decade, …, hi`.
pub fn log_grid(lo: i32, hi: i32, per_decade: usize) -> Vec<f64> {
    let n = (hi - lo) as usize * per_decade;
    (0..=n)
        .map(|i| 10f64.powf(lo as f64 + i as f64 / per_decade as f64))
        .collect()
}
