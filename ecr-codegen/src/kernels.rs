//! Power series of the method's kernels with exact rational coefficients, each computed two
//! or three ways: from the closed form the paper gives, from the moment form the runtime
//! uses, and from the defining integral (exact polynomial integration). The test suite checks
//! they agree; a disagreement is a typo in a closed form (erratum E1 is one:
//! `docs/errata.md#e1-kernel-tau-factor`).
//!
//! All series are truncated: element `n` of a returned vector is the coefficient of zⁿ (or Kⁿ).

use crate::legendre::{beta, c_jk, projection_kernel, shifted_legendre};
use crate::poly::Poly;
use crate::rat::{Rat, factorial, int, inv_factorial, pow};
use num_traits::{One, Zero};

fn sign(n: usize) -> Rat {
    if n % 2 == 0 { Rat::one() } else { -Rat::one() }
}

/// Taylor coefficients of φ_k: φ_k(z) = Σₙ zⁿ / (n+k)!, n < terms.
pub fn phi_taylor(k: usize, terms: usize) -> Vec<Rat> {
    (0..terms).map(|n| inv_factorial((n + k) as u64)).collect()
}

/// Series of the trigonometric φᵗ_m(K) = Σ_l (−K)^l / (2l+m)!, l < terms.
pub fn phi_trig_series(m: usize, terms: usize) -> Vec<Rat> {
    (0..terms)
        .map(|l| sign(l) * inv_factorial((2 * l + m) as u64))
        .collect()
}

// ---------------------------------------------------------------------------------------
// First order: Ā_{τ,σ}(z), z standing for hA.
// ---------------------------------------------------------------------------------------

/// Ā_{τ,σ}(z) = Σ_{j<r} (2j+1) P̃ⱼ(σ) Σ_{k≤j} c_{jk} τᵏ φ_{k+1}(τz): the corrected closed form
/// of the paper's eq. `barA` (which omits τᵏ), as a series in z.
pub fn ec_kernel_closed(r: usize, tau: &Rat, sigma: &Rat, terms: usize) -> Vec<Rat> {
    ec_kernel_closed_impl(r, tau, sigma, terms, true)
}

/// The paper's eq. `barA` as printed (without τᵏ) — kept to show that the tests catch it.
pub fn ec_kernel_as_printed(r: usize, tau: &Rat, sigma: &Rat, terms: usize) -> Vec<Rat> {
    ec_kernel_closed_impl(r, tau, sigma, terms, false)
}

fn ec_kernel_closed_impl(
    r: usize,
    tau: &Rat,
    sigma: &Rat,
    terms: usize,
    with_tau_k: bool,
) -> Vec<Rat> {
    (0..terms)
        .map(|n| {
            let mut acc = Rat::zero();
            for j in 0..r {
                let pj = shifted_legendre(j).eval(sigma) * int(2 * j as i64 + 1);
                for k in 0..=j {
                    let tk = if with_tau_k { pow(tau, k) } else { Rat::one() };
                    // c_{jk} τᵏ · [zⁿ] φ_{k+1}(τz) = c_{jk} τᵏ τⁿ / (n+k+1)!
                    acc += &pj * c_jk(j, k) * tk * pow(tau, n) * inv_factorial((n + k + 1) as u64);
                }
            }
            acc
        })
        .collect()
}

/// Moment form Ā_{τ,σ}(z) = Σ_{k<r} τᵏ φ_{k+1}(τz) β_k(σ) (what the runtime evaluates).
pub fn ec_kernel_moment(r: usize, tau: &Rat, sigma: &Rat, terms: usize) -> Vec<Rat> {
    let betas: Vec<Rat> = (0..r).map(|k| beta(r, k).eval(sigma)).collect();
    (0..terms)
        .map(|n| {
            betas.iter().enumerate().fold(Rat::zero(), |acc, (k, b)| {
                acc + b * pow(tau, k + n) * inv_factorial((n + k + 1) as u64)
            })
        })
        .collect()
}

/// The defining integral Ā_{τ,σ}(z) = ∫₀¹ e^{(1−ξ)τz} P(ξτ, σ) dξ (paper eq. `Aexplicit`),
/// P(x, σ) = Σ_{j<r} (2j+1) P̃ⱼ(x) P̃ⱼ(σ): \[zⁿ\] = τⁿ/n! ∫₀¹ (1−ξ)ⁿ P(ξτ, σ) dξ, integrated exactly.
pub fn ec_kernel_by_integral(r: usize, tau: &Rat, sigma: &Rat, terms: usize) -> Vec<Rat> {
    let p = projection_kernel(r, sigma).dilate(tau);
    (0..terms)
        .map(|n| {
            Poly::one_minus_x_pow(n).mul(&p).integral_01() * pow(tau, n) * inv_factorial(n as u64)
        })
        .collect()
}

// ---------------------------------------------------------------------------------------
// Second order (TCr, paper §3 and §8.2), series in K.
// ---------------------------------------------------------------------------------------

/// Rising factorial (a)_n for a rational a.
fn pochhammer(a: &Rat, n: usize) -> Rat {
    (0..n).fold(Rat::one(), |acc, i| acc * (a + int(i as i64)))
}

/// ₂F₁(a, b; c; x), a terminating series (a a non-positive integer), exactly.
fn hyp2f1_terminating(a: i64, b: &Rat, c: &Rat, x: &Rat) -> Rat {
    let n = (-a) as usize;
    let a = int(a);
    (0..=n).fold(Rat::zero(), |acc, l| {
        acc + pochhammer(&a, l) * pochhammer(b, l)
            / (pochhammer(c, l) * Rat::from_integer(factorial(l as u64)))
            * pow(x, l)
    })
}

/// Series of ₀F₁(; b; c·K) in K, `terms` terms.
fn hyp0f1_series(b: &Rat, c: &Rat, terms: usize) -> Vec<Rat> {
    (0..terms)
        .map(|l| pow(c, l) / (pochhammer(b, l) * Rat::from_integer(factorial(l as u64))))
        .collect()
}

fn series_mul(a: &[Rat], b: &[Rat], terms: usize) -> Vec<Rat> {
    (0..terms)
        .map(|n| {
            (0..=n).fold(Rat::zero(), |acc, i| match (a.get(i), b.get(n - i)) {
                (Some(x), Some(y)) => acc + x * y,
                _ => acc,
            })
        })
        .collect()
}

/// 𝒜_{τ,σ}(K) by the paper's hypergeometric closed form, eq. `A re of erkn`:
/// Σⱼ √(2j+1) p̂ⱼ(σ) Σ_l (−1)^{j+l}/(2l+2)! ₂F₁(−j, j+1; 2l+3; τ) K^l.
pub fn tc_a_hypergeometric(r: usize, tau: &Rat, sigma: &Rat, terms: usize) -> Vec<Rat> {
    (0..terms)
        .map(|l| {
            (0..r).fold(Rat::zero(), |acc, j| {
                let pj = shifted_legendre(j).eval(sigma) * int(2 * j as i64 + 1);
                let f = hyp2f1_terminating(
                    -(j as i64),
                    &int(j as i64 + 1),
                    &int(2 * l as i64 + 3),
                    tau,
                );
                acc + pj * sign(j + l) * inv_factorial((2 * l + 2) as u64) * f
            })
        })
        .collect()
}

/// 𝒜_{τ,σ}(K) in moment form: Σ_k τᵏ φᵗ_{k+2}(K) β_k(σ) (`docs/method.md#tcrp`).
pub fn tc_a_moment(r: usize, tau: &Rat, sigma: &Rat, terms: usize) -> Vec<Rat> {
    let betas: Vec<Rat> = (0..r).map(|k| beta(r, k).eval(sigma)).collect();
    (0..terms)
        .map(|l| {
            betas.iter().enumerate().fold(Rat::zero(), |acc, (k, b)| {
                acc + b * pow(tau, k) * sign(l) * inv_factorial((2 * l + k + 2) as u64)
            })
        })
        .collect()
}

/// 𝒜_{τ,σ}(K) from its defining integral (paper eq. `AB of erkn`):
/// ∫₀¹ (1−ξ) φᵗ₁((1−ξ)²K) P(ξτ, σ) dξ, so [K^l] = (−1)^l/(2l+1)! ∫₀¹ (1−ξ)^{2l+1} P(ξτ, σ) dξ.
pub fn tc_a_by_integral(r: usize, tau: &Rat, sigma: &Rat, terms: usize) -> Vec<Rat> {
    let p = projection_kernel(r, sigma).dilate(tau);
    (0..terms)
        .map(|l| {
            Poly::one_minus_x_pow(2 * l + 1).mul(&p).integral_01()
                * sign(l)
                * inv_factorial((2 * l + 1) as u64)
        })
        .collect()
}

/// S_j(K) by the paper's closed form, eq. `Computate S` (products of two ₀F₁).
pub fn tc_s_closed(j: usize, terms: usize) -> Vec<Rat> {
    let m = j / 2;
    let c = -Rat::new(1.into(), 16.into());
    let half = Rat::new(1.into(), 2.into());
    let (pref, shift, b1, b2) = if j % 2 == 0 {
        // (−1)^m (2m)!/(4m+1)! K^m ₀F₁(;1/2;−K/16) ₀F₁(;2m+3/2;−K/16)
        (
            sign(m) * Rat::new(factorial(2 * m as u64), factorial(4 * m as u64 + 1)),
            m,
            half.clone(),
            int(2 * m as i64 + 1) + &half,
        )
    } else {
        // (−1)^m (2m+2)!/(4m+4)! K^{m+1} ₀F₁(;3/2;−K/16) ₀F₁(;2m+5/2;−K/16)
        (
            sign(m) * Rat::new(factorial(2 * m as u64 + 2), factorial(4 * m as u64 + 4)),
            m + 1,
            int(1) + &half,
            int(2 * m as i64 + 2) + &half,
        )
    };
    let prod = series_mul(
        &hyp0f1_series(&b1, &c, terms),
        &hyp0f1_series(&b2, &c, terms),
        terms,
    );
    (0..terms)
        .map(|l| {
            if l < shift {
                Rat::zero()
            } else {
                &pref * &prod[l - shift]
            }
        })
        .collect()
}

/// S_j(K) from its definition: ∫₀¹ φᵗ₀((1−ξ)²K) P̃ⱼ(ξ) dξ, [K^l] = (−1)^l/(2l)! ∫₀¹ (1−ξ)^{2l} P̃ⱼ(ξ) dξ.
pub fn tc_s_by_integral(j: usize, terms: usize) -> Vec<Rat> {
    let pj = shifted_legendre(j);
    (0..terms)
        .map(|l| {
            Poly::one_minus_x_pow(2 * l).mul(&pj).integral_01()
                * sign(l)
                * inv_factorial((2 * l) as u64)
        })
        .collect()
}

/// ℬ_{1,σ}(K) = Σⱼ √(2j+1) p̂ⱼ(σ) Sⱼ(K) with the paper's closed-form Sⱼ (eq. `B`).
pub fn tc_b1_closed(r: usize, sigma: &Rat, terms: usize) -> Vec<Rat> {
    let mut acc = vec![Rat::zero(); terms];
    for j in 0..r {
        let pj = shifted_legendre(j).eval(sigma) * int(2 * j as i64 + 1);
        for (a, s) in acc.iter_mut().zip(tc_s_closed(j, terms)) {
            *a += &pj * s;
        }
    }
    acc
}

/// ℬ_{1,σ}(K) in moment form: Σ_k φᵗ_{k+1}(K) β_k(σ).
pub fn tc_b1_moment(r: usize, sigma: &Rat, terms: usize) -> Vec<Rat> {
    let betas: Vec<Rat> = (0..r).map(|k| beta(r, k).eval(sigma)).collect();
    (0..terms)
        .map(|l| {
            betas.iter().enumerate().fold(Rat::zero(), |acc, (k, b)| {
                acc + b * sign(l) * inv_factorial((2 * l + k + 1) as u64)
            })
        })
        .collect()
}

/// ℬ_{1,σ}(K) from the defining integral ∫₀¹ φᵗ₀((1−ξ)²K) P(ξ, σ) dξ.
pub fn tc_b1_by_integral(r: usize, sigma: &Rat, terms: usize) -> Vec<Rat> {
    let p = projection_kernel(r, sigma);
    (0..terms)
        .map(|l| {
            Poly::one_minus_x_pow(2 * l).mul(&p).integral_01()
                * sign(l)
                * inv_factorial((2 * l) as u64)
        })
        .collect()
}

// ---------------------------------------------------------------------------------------
// Padé approximants of φ_k.
// ---------------------------------------------------------------------------------------

/// The diagonal [m/m] Padé approximant N(z)/D(z) of φ_k, D(0) = 1, exact.
///
/// Solved from the defining conditions (D·φ_k − N = O(z^{2m+1})) by exact Gaussian
/// elimination; the test suite compares with Skaflestad–Wright's closed form.
pub fn phi_pade(k: usize, m: usize) -> (Poly, Poly) {
    let t = phi_taylor(k, 2 * m + 1);
    // Unknowns d_1..d_m: Σ_{i=0}^{m} d_i t_{n−i} = 0 for n = m+1..2m, d_0 = 1.
    let mut mat: Vec<Vec<Rat>> = (m + 1..=2 * m)
        .map(|n| {
            let mut row: Vec<Rat> = (1..=m).map(|i| t[n - i].clone()).collect();
            row.push(-t[n].clone());
            row
        })
        .collect();
    let d = solve(&mut mat, m);
    let mut den = vec![Rat::one()];
    den.extend(d);
    let num: Vec<Rat> = (0..=m)
        .map(|n| (0..=n).fold(Rat::zero(), |acc, i| acc + &den[i] * &t[n - i]))
        .collect();
    (Poly::new(num), Poly::new(den))
}

/// Solves the n × n system in augmented form exactly (Gaussian elimination, pivot on any
/// non-zero entry). The Padé systems of φ_k are nonsingular (φ_k's Padé table is normal).
fn solve(a: &mut [Vec<Rat>], n: usize) -> Vec<Rat> {
    for col in 0..n {
        let piv = (col..n)
            .find(|&r| !a[r][col].is_zero())
            .expect("singular Padé system");
        a.swap(col, piv);
        let p = a[col][col].clone();
        for x in a[col][col..=n].iter_mut() {
            *x = &*x / &p;
        }
        let pivot_row = a[col].clone();
        for (r, row) in a.iter_mut().enumerate() {
            if r != col && !row[col].is_zero() {
                let f = row[col].clone();
                for (x, pv) in row[col..=n].iter_mut().zip(&pivot_row[col..=n]) {
                    *x -= &f * pv;
                }
            }
        }
    }
    a.iter().map(|row| row[n].clone()).collect()
}
