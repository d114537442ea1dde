//! The φ-functions of exponential integrators, for scalars and matrices.
//!
//! Definitions (paper eq. `phi`, §8.1; `docs/method.md#phi-functions`):
//!
//! ```text
//! φ₀(z) = eᶻ,   φ_k(z) = ∫₀¹ e^{(1−θ)z} θ^{k−1}/(k−1)! dθ = Σ_{n≥0} zⁿ/(n+k)!   (k ≥ 1)
//! φ_{k+1}(z) = (φ_k(z) − 1/k!)/z                                              (recurrence)
//! φ_k(2z) = 2^{−k} [φ₀(z) φ_k(z) + Σ_{j=1}^{k} φ_j(z)/(k−j)!]                 (doubling)
//! ```
//!
//! and the trigonometric functions of the second-order TCr methods (paper eq. `EEPCr of erkn`),
//! `φᵗ_m(K) = Σ_l (−K)^l/(2l+m)!`, so that `φᵗ₀(θ²) = cos θ`, `φᵗ₁(θ²) = sin θ/θ`,
//! `φᵗ_m(θ²) = Re φ_m(iθ)` and `θ φᵗ_{m+1}(θ²) = Im φ_m(iθ)`.
//!
//! Every function computes φ₀, …, φ_p at once.
//!
//! * Scalars ([`phi_real`], [`phi_complex`], [`phi_trig`], [`phi_diagonal`]): two three-term
//!   recurrences, each with a running a-priori rounding-error bound, and for every k the value
//!   with the smaller bound is returned. *Upward* from `e^z` and `expm1(z)/z` with
//!   `φ_{k+1} = (φ_k − 1/k!)/z` (stable where `|φ_k| ≪ 1/k!` or `|φ_k| ≫ 1/k!`, i.e. `|z|`
//!   large compared with k), and *downward* `φ_k = z φ_{k+1} + 1/k!` from a Taylor series at an
//!   order `P ≥ 2|z|` where the series has no cancellation (stable where `|z|` is small compared
//!   with k). Large `Re z` is handled with a scaled exponential so that values that fit in
//!   `f64` are returned even when `e^z` alone overflows. The relative error is ≤ 1e−14 for
//!   k ≤ 12 and 1e−16 ≤ |z| ≤ 1e12 on the real and imaginary axes and in the complex plane away
//!   from the zeros of φ_k; tests/phi.rs measures at most 1.7e−15 against 384-bit references.
//! * Dense matrices ([`phi_dense`], [`phi_dense_static`]): scaling and modified squaring
//!   (Skaflestad & Wright, 2009): Taylor series of all φ_k at `X = 2^{−s}A` with `‖X‖₁ ≤ 1`, then
//!   `s` applications of the doubling formula. The exponential is carried as `E = e^X − I`
//!   (`E ← E² + 2E`) so that eigen-components near 1 keep their accuracy through many doublings.
//! * Symmetric matrices ([`phi_symmetric`]): eigendecomposition `A = QΛQᵀ`,
//!   `φ_k(A) = Q φ_k(Λ) Qᵀ` with the scalar functions.

mod dd;
mod dense;
mod legendre;
mod scalar;

pub use dense::{phi_dense, phi_dense_static, phi_symmetric};
pub use legendre::LegendreKernels;
pub use scalar::{phi_complex, phi_diagonal, phi_real, phi_trig};

pub(crate) use dd::{Dd, cexp_dd, exp_dd};
pub(crate) use dense::{
    check_symmetric, expm_dd, symmetric_eigen, two_prod, two_sum, validate as validate_matrix,
};

/// `1/k!` for `k = 0..=32`, correctly rounded to `f64`.
///
/// Generated with Python's `float(Fraction(1, factorial(k)))` (correctly rounded division of
/// integers); tests/phi.rs checks every entry against `BigRational::to_f64`.
pub const INV_FACTORIAL: [f64; 33] = [
    1.0,                    // 1/0!
    1.0,                    // 1/1!
    0.5,                    // 1/2!
    0.16666666666666666,    // 1/3!
    0.041666666666666664,   // 1/4!
    0.008333333333333333,   // 1/5!
    0.001388888888888889,   // 1/6!
    0.0001984126984126984,  // 1/7!
    2.48015873015873e-05,   // 1/8!
    2.7557319223985893e-06, // 1/9!
    2.755731922398589e-07,  // 1/10!
    2.505210838544172e-08,  // 1/11!
    2.08767569878681e-09,   // 1/12!
    1.6059043836821613e-10, // 1/13!
    1.1470745597729725e-11, // 1/14!
    7.647163731819816e-13,  // 1/15!
    4.779477332387385e-14,  // 1/16!
    2.8114572543455206e-15, // 1/17!
    1.5619206968586225e-16, // 1/18!
    8.22063524662433e-18,   // 1/19!
    4.110317623312165e-19,  // 1/20!
    1.9572941063391263e-20, // 1/21!
    8.896791392450574e-22,  // 1/22!
    3.868170170630684e-23,  // 1/23!
    1.6117375710961184e-24, // 1/24!
    6.446950284384474e-26,  // 1/25!
    2.4795962632247976e-27, // 1/26!
    9.183689863795546e-29,  // 1/27!
    3.279889237069838e-30,  // 1/28!
    1.1309962886447716e-31, // 1/29!
    3.7699876288159054e-33, // 1/30!
    1.216125041553518e-34,  // 1/31!
    3.8003907548547434e-36, // 1/32!
];

/// `1/k!` as `f64`: correctly rounded for `k ≤ 32` ([`INV_FACTORIAL`]); beyond, by division
/// from `1/32!` (relative error ≤ (k − 32)·2⁻⁵³ + 2⁻⁵³), underflowing to 0 for `k > 177`.
#[inline]
pub fn inv_factorial(k: usize) -> f64 {
    if k < INV_FACTORIAL.len() {
        INV_FACTORIAL[k]
    } else {
        let mut v = INV_FACTORIAL[INV_FACTORIAL.len() - 1];
        for j in INV_FACTORIAL.len()..=k {
            v /= j as f64;
            if v == 0.0 {
                break;
            }
        }
        v
    }
}
