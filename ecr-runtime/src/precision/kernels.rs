//! φ-functions and the Legendre kernels Ψⱼ in the scalar `S`, for the linear parts of
//! [`LinearPart`]: a multiple of the identity, a diagonal, or a dense matrix.
//!
//! `φ₀(X), …, φ_p(X)` of a d × d matrix `X` (a 1 × 1 one for scalars and each diagonal entry):
//! scaling and squaring. With `Y = 2^{−q} X`, `‖Y‖_∞ ≤ 1/4`, the Taylor series
//! `φ_k(Y) = Σ_{m≤M} Yᵐ/(m+k)!` with `M = 22` leaves out less than `4⁻²³/23! ≈ 1e−36` relative to
//! `1/k!`; then `q` doublings `φ_k(2Y) = 2^{−k} [φ₀(Y) φ_k(Y) + Σ_{j=1..k} φⱼ(Y)/(k−j)!]`.
//! Every constant is a correctly rounded double-double (from the exact rationals).
//!
//! The kernels are `Ψⱼ(τ, Z) = Σ_{k≤j} c_{jk} τᵏ φ_{k+1}(τZ) = ∫₀¹ e^{(1−ξ)τZ} P̃ⱼ(τξ) dξ`
//! (`docs/method.md#legendre-kernels`; tests check them against the integral at 320 bits).

use super::{GenericTables, LinearPart, Real};

/// Taylor terms of the scaled φ-functions.
pub(crate) const TAYLOR_TERMS: usize = 22;

/// A linear map in the structure of the linear part it comes from.
#[derive(Clone, Debug)]
pub(crate) enum Map<S> {
    /// `c I`.
    Scalar(S),
    /// `diag(v)`.
    Diagonal(Vec<S>),
    /// A d × d matrix, row-major.
    Dense(Vec<S>),
}

impl<S: Real> Map<S> {
    /// `out += self · x`.
    #[inline]
    pub(crate) fn apply_add(&self, x: &[S], out: &mut [S]) {
        match self {
            Map::Scalar(c) => {
                for (o, &v) in out.iter_mut().zip(x) {
                    *o += *c * v;
                }
            }
            Map::Diagonal(c) => {
                for ((o, &v), &ci) in out.iter_mut().zip(x).zip(c) {
                    *o += ci * v;
                }
            }
            Map::Dense(m) => {
                let d = x.len();
                for (o, row) in out.iter_mut().zip(m.chunks_exact(d)) {
                    let mut acc = S::zero();
                    for (&a, &v) in row.iter().zip(x) {
                        acc += a * v;
                    }
                    *o += acc;
                }
            }
        }
    }

    /// `self · c` for a scalar `c`.
    fn scaled(&self, c: S) -> Map<S> {
        match self {
            Map::Scalar(v) => Map::Scalar(*v * c),
            Map::Diagonal(v) => Map::Diagonal(v.iter().map(|&x| x * c).collect()),
            Map::Dense(v) => Map::Dense(v.iter().map(|&x| x * c).collect()),
        }
    }
}

/// `out = a b` for d × d row-major matrices.
fn matmul<S: Real>(a: &[S], b: &[S], d: usize, out: &mut [S]) {
    for i in 0..d {
        for j in 0..d {
            let mut acc = S::zero();
            for k in 0..d {
                acc += a[i * d + k] * b[k * d + j];
            }
            out[i * d + j] = acc;
        }
    }
}

/// `φ₀(X), …, φ_p(X)` of the d × d row-major `x` (see the module docs).
pub(crate) fn phi_matrices<S: Real>(
    x: &[S],
    d: usize,
    p: usize,
    inv_factorial: &[S],
) -> Vec<Vec<S>> {
    debug_assert!(TAYLOR_TERMS + p < inv_factorial.len());
    let norm = x
        .chunks_exact(d)
        .map(|row| row.iter().map(|v| v.to_f64().abs()).sum::<f64>())
        .fold(0.0f64, f64::max);
    let q = if norm <= 0.25 {
        0
    } else {
        (norm / 0.25).log2().ceil() as i32
    };
    let scale = S::from_f64(2f64.powi(-q));
    let y: Vec<S> = x.iter().map(|&v| v * scale).collect();
    // Y⁰ … Y^M.
    let mut powers: Vec<Vec<S>> = Vec::with_capacity(TAYLOR_TERMS + 1);
    let mut identity = vec![S::zero(); d * d];
    for i in 0..d {
        identity[i * d + i] = S::one();
    }
    powers.push(identity);
    for m in 1..=TAYLOR_TERMS {
        let mut next = vec![S::zero(); d * d];
        matmul(&powers[m - 1], &y, d, &mut next);
        powers.push(next);
    }
    let mut phis: Vec<Vec<S>> = (0..=p)
        .map(|k| {
            let mut acc = vec![S::zero(); d * d];
            // Smallest terms first.
            for m in (0..=TAYLOR_TERMS).rev() {
                let c = inv_factorial[m + k];
                for (a, &v) in acc.iter_mut().zip(&powers[m]) {
                    *a += c * v;
                }
            }
            acc
        })
        .collect();
    let mut product = vec![S::zero(); d * d];
    for _ in 0..q {
        let next: Vec<Vec<S>> = (0..=p)
            .map(|k| {
                matmul(&phis[0], &phis[k], d, &mut product);
                let mut acc = product.clone();
                for j in 1..=k {
                    let c = inv_factorial[k - j];
                    for (a, &v) in acc.iter_mut().zip(&phis[j]) {
                        *a += c * v;
                    }
                }
                let half_k = S::from_f64(2f64.powi(-(k as i32)));
                acc.iter_mut().for_each(|a| *a *= half_k);
                acc
            })
            .collect();
        phis = next;
    }
    phis
}

/// `e^{τZ}` and the kernels `Ψ₀(τ, Z), …, Ψ_{r−1}(τ, Z)` for `Z = h A` in the structure of A.
pub(crate) fn kernels_at<S: Real>(
    linear: &LinearPart<S>,
    h: S,
    tau: S,
    tables: &GenericTables<S>,
) -> (Map<S>, Vec<Map<S>>) {
    let r = tables.r;
    let th = tau * h;
    // Ψⱼ from φ₁..φ_r of one matrix (or number), as flat values.
    let psi = |phis: &[Vec<S>]| -> Vec<Vec<S>> {
        (0..r)
            .map(|j| {
                let mut acc = vec![S::zero(); phis[0].len()];
                let mut tk = S::one();
                for k in 0..=j {
                    let c = tables.c[j * r + k] * tk;
                    for (a, &v) in acc.iter_mut().zip(&phis[k + 1]) {
                        *a += c * v;
                    }
                    tk *= tau;
                }
                acc
            })
            .collect()
    };
    match linear {
        LinearPart::Scalar(l) => {
            let phis = phi_matrices(&[*l * th], 1, r, &tables.inv_factorial);
            let psis = psi(&phis);
            (
                Map::Scalar(phis[0][0]),
                psis.into_iter().map(|v| Map::Scalar(v[0])).collect(),
            )
        }
        LinearPart::Diagonal(ls) => {
            let mut e = Vec::with_capacity(ls.len());
            let mut ks: Vec<Vec<S>> = vec![Vec::with_capacity(ls.len()); r];
            for &l in ls {
                let phis = phi_matrices(&[l * th], 1, r, &tables.inv_factorial);
                e.push(phis[0][0]);
                for (k, v) in ks.iter_mut().zip(psi(&phis)) {
                    k.push(v[0]);
                }
            }
            (
                Map::Diagonal(e),
                ks.into_iter().map(Map::Diagonal).collect(),
            )
        }
        LinearPart::Dense { dim, entries } => {
            let x: Vec<S> = entries.iter().map(|&a| a * th).collect();
            let phis = phi_matrices(&x, *dim, r, &tables.inv_factorial);
            let psis = psi(&phis);
            (
                Map::Dense(phis[0].clone()),
                psis.into_iter().map(Map::Dense).collect(),
            )
        }
    }
}

/// What a step of size h applies: per node the propagator `e^{cᵢhA}` and the stage kernels
/// `h cᵢ (2j+1) Ψⱼ(cᵢ, hA)`; for the step's end `e^{hA}` and `h (2j+1) Ψⱼ(1, hA)`; for the
/// predictor the same at `τ = 1 + cᵢ`: the previous step's continuous solution
/// `u(τ) = e^{τhA} y₀ + τh Σⱼ (2j+1) Ψⱼ(τ, hA) Lⱼ` at the next step's nodes.
#[derive(Clone, Debug)]
pub(crate) struct StepMaps<S> {
    pub(crate) stage_propagators: Vec<Map<S>>,
    /// Row-major s × r.
    pub(crate) stage_kernels: Vec<Map<S>>,
    pub(crate) propagator: Map<S>,
    pub(crate) kernels: Vec<Map<S>>,
    pub(crate) predictor_propagators: Vec<Map<S>>,
    /// Row-major s × r.
    pub(crate) predictor_kernels: Vec<Map<S>>,
}

/// `e^{τhA}` and `τh (2j+1) Ψⱼ(τ, hA)` for each τ of `taus`.
fn continuous_maps<S: Real>(
    linear: &LinearPart<S>,
    h: S,
    taus: impl Iterator<Item = S>,
    tables: &GenericTables<S>,
) -> (Vec<Map<S>>, Vec<Map<S>>) {
    let mut propagators = Vec::new();
    let mut kernels = Vec::new();
    for tau in taus {
        let (e, psis) = kernels_at(linear, h, tau, tables);
        propagators.push(e);
        for (j, k) in psis.iter().enumerate() {
            kernels.push(k.scaled(h * tau * S::from_f64((2 * j + 1) as f64)));
        }
    }
    (propagators, kernels)
}

impl<S: Real> StepMaps<S> {
    pub(crate) fn new(linear: &LinearPart<S>, h: S, tables: &GenericTables<S>) -> Self {
        let nodes = || tables.nodes.iter().copied();
        let (stage_propagators, stage_kernels) = continuous_maps(linear, h, nodes(), tables);
        let (mut end, kernels) = continuous_maps(linear, h, std::iter::once(S::one()), tables);
        let (predictor_propagators, predictor_kernels) =
            continuous_maps(linear, h, nodes().map(|c| S::one() + c), tables);
        StepMaps {
            stage_propagators,
            stage_kernels,
            propagator: end.remove(0),
            kernels,
            predictor_propagators,
            predictor_kernels,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::precision::{DoubleDouble, Real};
    use astro_float::{BigFloat, Consts, RoundingMode};

    const PREC: usize = 448;
    const RM: RoundingMode = RoundingMode::ToEven;
    type Dd = DoubleDouble;

    fn big(x: f64) -> BigFloat {
        BigFloat::from_f64(x, PREC)
    }
    fn big_dd(x: Dd) -> BigFloat {
        big(x.hi()).add(&big(x.lo()), PREC, RM)
    }
    /// |x| as f64 from the top mantissa word (enough for error sizes).
    fn mag(x: &BigFloat) -> f64 {
        if x.is_zero() {
            return 0.0;
        }
        let (m, _, _, e, _) = x.as_raw_parts().unwrap();
        *m.last().unwrap() as f64 / 18446744073709551616.0 * 2f64.powi(e)
    }

    /// Coefficients of P̃ⱼ (integers, exact in f64 for j ≤ 10).
    fn legendre(j: usize) -> Vec<f64> {
        let b = |n: usize, k: usize| -> f64 {
            (0..k)
                .fold(1.0, |acc, i| acc * (n - i) as f64 / (i + 1) as f64)
                .round()
        };
        (0..=j)
            .map(|k| {
                let m = b(j, k) * b(j + k, k);
                if (j + k) % 2 == 0 { m } else { -m }
            })
            .collect()
    }

    /// The defining integral `Ψⱼ(τ, Z) = ∫₀¹ e^{(1−ξ)τZ} P̃ⱼ(τξ) dξ` for a d × d `Z` (row-major,
    /// exact f64 entries times the double-double τ), integrated term by term:
    /// `Σ_m (τZ)ᵐ Σ_k p_{jk} τᵏ k!/(m+k+1)!` (∫₀¹ (1−ξ)ᵐ ξᵏ dξ = m! k!/(m+k+1)!).
    fn psi_by_integral(z: &[f64], d: usize, tau: Dd, j: usize, terms: usize) -> Vec<BigFloat> {
        let t = big_dd(tau);
        let tz: Vec<BigFloat> = z.iter().map(|&v| big(v).mul(&t, PREC, RM)).collect();
        let p = legendre(j);
        let mut power: Vec<BigFloat> = (0..d * d)
            .map(|i| if i % (d + 1) == 0 { big(1.0) } else { big(0.0) })
            .collect();
        let mut acc: Vec<BigFloat> = vec![big(0.0); d * d];
        for m in 0..terms {
            // c_m = Σ_k p_k τᵏ k!/(m+k+1)!
            let mut c = big(0.0);
            let mut tk = big(1.0);
            for (k, &pk) in p.iter().enumerate() {
                // k!/(m+k+1)! = 1/((k+1)(k+2)…(m+k+1))
                let mut den = big(1.0);
                for i in (k + 1)..=(m + k + 1) {
                    den = den.mul(&big(i as f64), PREC, RM);
                }
                c = c.add(&big(pk).mul(&tk, PREC, RM).div(&den, PREC, RM), PREC, RM);
                tk = tk.mul(&t, PREC, RM);
            }
            for (a, pw) in acc.iter_mut().zip(&power) {
                *a = a.add(&pw.mul(&c, PREC, RM), PREC, RM);
            }
            let mut next = vec![big(0.0); d * d];
            for i in 0..d {
                for l in 0..d {
                    let mut s = big(0.0);
                    for q in 0..d {
                        s = s.add(&power[i * d + q].mul(&tz[q * d + l], PREC, RM), PREC, RM);
                    }
                    next[i * d + l] = s;
                }
            }
            power = next;
        }
        acc
    }

    /// Ψⱼ in double-double against the integral at 448 bits: scalars over [−20, 8] and the
    /// Duffing and wind matrices times h, every node and τ = 1, r = 8.
    #[test]
    fn kernels_match_their_defining_integral() {
        let r = 8;
        let tables = GenericTables::<Dd>::new(r, r).unwrap();
        let mut taus = tables.nodes.clone();
        taus.push(Dd::from(1.0));
        let mut worst = 0.0f64;
        let mut cases: Vec<(Vec<f64>, usize)> = [-20.0, -3.0, -0.5, 0.0, 1e-3, 0.7, 8.0]
            .iter()
            .map(|&z| (vec![z], 1))
            .collect();
        // Duffing ω = 5, k = 0.07 (ω² + k² rounded to f64 here: the entries are data) at h = 0.2,
        // and the dissipative wind at h = 0.1.
        cases.push((vec![0.0, 0.2, -0.2 * (25.0 + 0.0049), 0.0], 2));
        cases.push((vec![-0.002, -2.0, 2.0, -0.002], 2));
        for (z, d) in &cases {
            let entries: Vec<Dd> = z.iter().map(|&v| Dd::from(v)).collect();
            let linear = if *d == 1 {
                LinearPart::Scalar(entries[0])
            } else {
                LinearPart::Dense { dim: *d, entries }
            };
            for &tau in &taus {
                let (_, psis) = kernels_at(&linear, Dd::from(1.0), tau, &tables);
                for (j, psi) in psis.iter().enumerate() {
                    let got: Vec<Dd> = match psi {
                        Map::Scalar(v) => vec![*v],
                        Map::Dense(v) => v.clone(),
                        Map::Diagonal(v) => v.clone(),
                    };
                    let want = psi_by_integral(z, *d, tau, j, 150);
                    // The condition of Σ_k c_jk τᵏ φ_{k+1}: the sum of its terms' magnitudes
                    // (entrywise; the φ from the same computation).
                    let tz: Vec<Dd> = z.iter().map(|&v| Dd::from(v) * tau).collect();
                    let phis = phi_matrices(&tz, *d, r, &tables.inv_factorial);
                    let cond = (0..=j).fold(0.0f64, |acc, k| {
                        let tk = (0..k).fold(1.0, |p, _| p * tau.to_f64());
                        let m = phis[k + 1]
                            .iter()
                            .map(|v| v.to_f64().abs())
                            .fold(0.0, f64::max);
                        acc + tables.c[j * r + k].to_f64().abs() * tk * m
                    });
                    let scale = want.iter().map(mag).fold(0.0f64, f64::max);
                    for (g, w) in got.iter().zip(&want) {
                        let err = mag(&big_dd(*g).sub(w, PREC, RM));
                        // A few units of round-off of the terms, and of the result.
                        let bound = 32.0 * Dd::EPSILON * (cond + scale);
                        worst = worst.max(err / (cond + scale));
                        assert!(
                            err <= bound,
                            "Z = {z:?}, τ = {tau}, j = {j}: error {err:e} > {bound:e}"
                        );
                    }
                }
            }
        }
        println!("Ψⱼ (r = 8) against the defining integral: worst relative error {worst:e}");
    }

    /// φ_k of large scalars against the closed form `(eᶻ − Σ_{i<k} zⁱ/i!)/zᵏ` at 448 bits
    /// (stiff diagonal entries: many doublings).
    #[test]
    fn phis_of_large_scalars() {
        let tables = GenericTables::<Dd>::new(8, 8).unwrap();
        let mut cc = Consts::new().unwrap();
        let mut worst = 0.0f64;
        for z in [-1e4, -700.0, -50.0, 30.0, 200.0] {
            let phis = phi_matrices(&[Dd::from(z)], 1, 8, &tables.inv_factorial);
            let bz = big(z);
            let ez = bz.exp(PREC, RM, &mut cc);
            let mut partial = big(0.0);
            let mut term = big(1.0);
            let mut zk = big(1.0);
            for (k, phi) in phis.iter().enumerate() {
                let exact = ez.sub(&partial, PREC, RM).div(&zk, PREC, RM);
                let err = mag(&big_dd(phi[0]).sub(&exact, PREC, RM));
                if mag(&exact) < 1e-280 {
                    // e^z below the f64 range (z = −1e4): zero, or an absolute error below it.
                    assert!(err < 1e-300, "φ_{k}({z}): absolute error {err:e}");
                } else {
                    let err = err / mag(&exact);
                    worst = worst.max(err);
                    assert!(err < 1e-29, "φ_{k}({z}): relative error {err:e}");
                }
                partial = partial.add(&term, PREC, RM);
                term = term.mul(&bz, PREC, RM).div(&big((k + 1) as f64), PREC, RM);
                zk = zk.mul(&bz, PREC, RM);
            }
        }
        println!("φ_k of large scalars: worst relative error {worst:e}");
    }
}
