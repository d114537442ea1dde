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
//!   from the zeros of φ_k; tests/it/phi.rs measures at most 1.7e−15 against 384-bit references.
//! * Dense matrices ([`phi_dense`], [`phi_dense_static`]): scaling and modified squaring
//!   (Skaflestad & Wright, 2009): Taylor series of all φ_k at `X = 2^{−s}A` with `‖X‖₁ ≤ 1`, then
//!   `s` applications of the doubling formula. The exponential is carried as `E = e^X − I`
//!   (`E ← E² + 2E`) so that eigen-components near 1 keep their accuracy through many doublings.
//! * Symmetric matrices ([`phi_symmetric`]): eigendecomposition `A = QΛQᵀ`,
//!   `φ_k(A) = Q φ_k(Λ) Qᵀ` with the scalar functions.

mod dd;
mod dense;
mod expm_dd;
mod factorial;
mod gauss;
mod legendre;
mod scalar;

pub use dense::{phi_dense, phi_dense_static, phi_symmetric};
pub use factorial::{INV_FACTORIAL, inv_factorial};
pub use legendre::LegendreKernels;
pub use scalar::{phi_complex, phi_diagonal, phi_real, phi_trig};

pub(crate) use crate::double_double::{two_prod, two_sum};
pub(crate) use dd::{Dd, cexp_dd, cos_sin_dd, exp_dd};
pub(crate) use dense::{check_symmetric, symmetric_eigen, validate as validate_matrix};
pub(crate) use expm_dd::{expm_dd, expm_dd_split};
