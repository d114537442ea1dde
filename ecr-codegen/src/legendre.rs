//! Shifted Legendre polynomials on [0, 1] and the coefficients built from them
//! (`docs/method.md#legendre-basis`; paper §8.1, eq. `barA`).

use crate::poly::Poly;
use crate::rat::{Rat, binomial, factorial};
use num_bigint::BigInt;
use num_traits::{One, Zero};

/// The shifted Legendre polynomial P̃ⱼ(x) = Pⱼ(2x − 1) = Σₖ (−1)^{j+k} C(j,k) C(j+k,k) xᵏ.
///
/// Normalised by P̃ⱼ(1) = 1; its coefficients are integers. The orthonormal basis of the paper
/// is p̂ⱼ = √(2j+1) P̃ⱼ (the paper's sign convention (−1)ʲ Σ C(j,k)C(j+k,k)(−x)ᵏ is the same).
pub fn shifted_legendre(j: usize) -> Poly {
    let j64 = j as u64;
    Poly::new(
        (0..=j64)
            .map(|k| {
                let mag = binomial(j64, k) * binomial(j64 + k, k);
                let v = if (j64 + k) % 2 == 0 { mag } else { -mag };
                Rat::from_integer(v)
            })
            .collect(),
    )
}

/// c_{jk} = (−1)^{j+k} (j+k)! / (k! (j−k)!) for 0 ≤ k ≤ j (zero for k > j).
///
/// With these, P̃ⱼ(x) = Σₖ c_{jk} xᵏ / k!, and ∫₀¹ e^{(1−ξ)τz} P̃ⱼ(ξτ) dξ = Σₖ c_{jk} τᵏ φ_{k+1}(τz)
/// (the kernel Ψ_j of `docs/method.md#legendre-kernels`, with the factor τᵏ the paper's eq.
/// `barA` drops: `docs/errata.md#e1-kernel-tau-factor`).
pub fn c_jk(j: usize, k: usize) -> Rat {
    if k > j {
        return Rat::zero();
    }
    let mag = factorial((j + k) as u64) / (factorial(k as u64) * factorial((j - k) as u64));
    let v: BigInt = if (j + k) % 2 == 0 { mag } else { -mag };
    Rat::from_integer(v)
}

/// The r × r lower-triangular matrix of c_{jk}, j, k < r.
pub fn c_matrix(r: usize) -> Vec<Vec<Rat>> {
    (0..r)
        .map(|j| (0..=j).map(|k| c_jk(j, k)).collect())
        .collect()
}

/// β_k(σ) = Σ_{j=k}^{r−1} (2j+1) c_{jk} P̃ⱼ(σ): the moment polynomial of order r.
///
/// The kernel factors as Ā_{τ,σ}(hA) = Σ_{k<r} τᵏ φ_{k+1}(τhA) β_k(σ), which lets the method
/// collect the nonlinearity in r moments G_k = Σⱼ bⱼ β_k(cⱼ) g(Yⱼ).
pub fn beta(r: usize, k: usize) -> Poly {
    (k..r).fold(Poly::zero(), |acc, j| {
        let w = c_jk(j, k) * Rat::from_integer(BigInt::from(2 * j + 1));
        acc.add(&shifted_legendre(j).scale(&w))
    })
}

/// The projection kernel P(x, σ) = Σ_{j<r} (2j+1) P̃ⱼ(x) P̃ⱼ(σ) as a polynomial in x, σ fixed.
pub fn projection_kernel(r: usize, sigma: &Rat) -> Poly {
    (0..r).fold(Poly::zero(), |acc, j| {
        let pj = shifted_legendre(j);
        let w = pj.eval(sigma) * Rat::from_integer(BigInt::from(2 * j + 1));
        acc.add(&pj.scale(&w))
    })
}

/// Whether ∫₀¹ P̃ᵢ P̃ⱼ = δᵢⱼ / (2j+1) holds exactly for all i, j < n (orthonormality of p̂ⱼ).
pub fn check_orthogonality(n: usize) -> bool {
    (0..n).all(|i| {
        (0..n).all(|j| {
            let ip = shifted_legendre(i).mul(&shifted_legendre(j)).integral_01();
            let expected = if i == j {
                Rat::new(BigInt::one(), BigInt::from(2 * j + 1))
            } else {
                Rat::zero()
            };
            ip == expected
        })
    })
}
