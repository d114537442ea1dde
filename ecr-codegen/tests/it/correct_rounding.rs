//! The generator's f64 outputs are correctly rounded: checked against an independent
//! high-precision computation done here (fixed-point Newton on the Legendre three-term
//! recurrence, Christoffel-function weights), not against the generator's own enclosures
//! and not against numbers copied from elsewhere.

use ecr_codegen::legendre::c_jk;
use ecr_codegen::rat::{Rat, to_f64};
use ecr_codegen::{Family, MethodTable};
use num_bigint::BigInt;
use num_traits::{One, Signed, ToPrimitive};

/// Fixed-point numbers X / 2^P with P = 400 bits (≈ 120 digits).
const P: usize = 400;

#[derive(Clone, Debug)]
struct Fx(BigInt);

impl Fx {
    fn from_f64(x: f64) -> Fx {
        let r = Rat::from_float(x).unwrap();
        Fx((r.numer() << P) / r.denom())
    }
    fn int(n: i64) -> Fx {
        Fx(BigInt::from(n) << P)
    }
    fn add(&self, o: &Fx) -> Fx {
        Fx(&self.0 + &o.0)
    }
    fn sub(&self, o: &Fx) -> Fx {
        Fx(&self.0 - &o.0)
    }
    fn mul(&self, o: &Fx) -> Fx {
        Fx((&self.0 * &o.0) >> P)
    }
    fn div(&self, o: &Fx) -> Fx {
        Fx((&self.0 << P) / &o.0)
    }
    fn scale(&self, n: i64) -> Fx {
        Fx(&self.0 * BigInt::from(n))
    }
    fn rat(&self) -> Rat {
        Rat::new(self.0.clone(), BigInt::one() << P)
    }
}

/// Legendre P_s(x) and P_{s−1}(x) on [−1, 1] by the three-term recurrence.
fn legendre_pair(s: usize, x: &Fx) -> (Fx, Fx) {
    let (mut p0, mut p1) = (Fx::int(1), x.clone());
    if s == 0 {
        return (p0, Fx::int(0));
    }
    for n in 1..s {
        // (n+1) P_{n+1} = (2n+1) x P_n − n P_{n−1}
        let p2 = x.mul(&p1).scale(2 * n as i64 + 1).sub(&p0.scale(n as i64));
        let p2 = Fx(p2.0 / BigInt::from(n + 1));
        p0 = p1;
        p1 = p2;
    }
    (p1, p0)
}

/// Nodes on [0, 1], ascending, by Newton in fixed point from Tricomi's initial guesses.
fn gauss_nodes(s: usize) -> Vec<Fx> {
    (1..=s)
        .map(|i| {
            let guess = (std::f64::consts::PI * (i as f64 - 0.25) / (s as f64 + 0.5)).cos();
            let mut x = Fx::from_f64(guess);
            for _ in 0..14 {
                let (ps, pm) = legendre_pair(s, &x);
                // P_s'(x) = s (x P_s − P_{s−1}) / (x² − 1)
                let dp = x
                    .mul(&ps)
                    .sub(&pm)
                    .scale(s as i64)
                    .div(&x.mul(&x).sub(&Fx::int(1)));
                x = x.sub(&ps.div(&dp));
            }
            // c = (1 − x)/2 (x descending in i, so c ascending).
            Fx(Fx::int(1).sub(&x).0 / BigInt::from(2))
        })
        .collect()
}

/// Shifted Legendre P̃_j(c) for j < n by the recurrence in x = 2c − 1.
fn shifted_values(n: usize, c: &Fx) -> Vec<Fx> {
    let x = c.scale(2).sub(&Fx::int(1));
    (0..n).map(|j| legendre_pair(j, &x).0).collect()
}

/// Christoffel weights b = 1 / Σ_{j<s} (2j+1) P̃_j(c)².
fn gauss_weight(s: usize, c: &Fx) -> Fx {
    let sum = shifted_values(s, c)
        .iter()
        .enumerate()
        .fold(Fx::int(0), |acc, (j, p)| {
            acc.add(&p.mul(p).scale(2 * j as i64 + 1))
        });
    Fx::int(1).div(&sum)
}

/// Asserts that `f` is the float nearest to the exact value approximated by `x` (error 2^−380),
/// checked directly against half an ulp — independently of `BigRational::to_f64`.
fn assert_correctly_rounded(f: f64, x: &Fx, what: &str) {
    let exact = x.rat();
    let err = (&exact - Rat::from_float(f).unwrap()).abs();
    let up = Rat::from_float(f64::from_bits(f.abs().to_bits() + 1)).unwrap();
    let half_ulp = (up - Rat::from_float(f.abs()).unwrap()) / Rat::from_integer(2.into());
    let slack = Rat::new(BigInt::one(), BigInt::one() << 380);
    assert!(
        err <= half_ulp + slack,
        "{what}: {f:?} is not the nearest float to {}",
        exact.to_f64().unwrap()
    );
    assert_eq!(to_f64(&exact).to_bits(), f.to_bits(), "{what}");
}

#[test]
fn nodes_weights_and_moment_weights_are_correctly_rounded_for_s_up_to_16() {
    for s in 1..=16 {
        for r in [1, s / 2, s].into_iter().filter(|&r| r >= 1 && r <= s) {
            let t = MethodTable::generate(Family::Ec, r, s).unwrap();
            let nodes = gauss_nodes(s);
            for (i, c) in nodes.iter().enumerate() {
                assert_correctly_rounded(t.nodes[i].value, c, &format!("c_{i} (s = {s})"));
                let b = gauss_weight(s, c);
                assert_correctly_rounded(t.weights[i].value, &b, &format!("b_{i} (s = {s})"));
                // β_k(c) = Σ_{j=k}^{r−1} (2j+1) c_{jk} P̃_j(c), P̃_j by the recurrence.
                let pv = shifted_values(r, c);
                for k in 0..r {
                    let beta = (k..r).fold(Fx::int(0), |acc, j| {
                        let cjk = c_jk(j, k).to_integer() * BigInt::from(2 * j + 1);
                        acc.add(&Fx(&pv[j].0 * cjk))
                    });
                    let w = b.mul(&beta);
                    assert_correctly_rounded(
                        t.w[k][i].value,
                        &w,
                        &format!("w_{k}{i} (r = {r}, s = {s})"),
                    );
                }
            }
        }
    }
}

#[test]
fn to_f64_rounds_to_nearest_even() {
    // Independent check of the single conversion the generator uses.
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    for _ in 0..2000 {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let num = BigInt::from(state) * BigInt::from(state >> 3) + BigInt::from(7);
        let den = BigInt::from(state.rotate_left(17) | 1) << (state % 90) as usize;
        let x = Rat::new(num, den);
        let f = to_f64(&x);
        let fr = Rat::from_float(f).unwrap();
        let next = Rat::from_float(f64::from_bits(f.to_bits() + 1)).unwrap();
        let prev = Rat::from_float(f64::from_bits(f.to_bits() - 1)).unwrap();
        let d = (&x - &fr).abs();
        assert!(
            d <= (&x - &next).abs() && d <= (&x - &prev).abs(),
            "{x} -> {f:?}"
        );
    }
}
