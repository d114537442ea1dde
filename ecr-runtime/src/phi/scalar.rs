//! Scalar φ-functions: real, complex and trigonometric arguments.
//!
//! Both recurrences `φ_{k+1} = (φ_k − 1/k!)/z` (upward) and `φ_k = z φ_{k+1} + 1/k!` (downward)
//! are exact identities; in floating point one of them is stable for each k. Each run carries an
//! a-priori bound of its rounding error (in units of the unit roundoff `u = 2⁻⁵³`): a step that
//! subtracts `c` from `v` amplifies the relative error of `v` by `|v|/|v − c|`, and adds a few
//! roundings. For each k the value with the smaller bound is kept. The downward run starts from
//! the Taylor series of `ψ_P = P! φ_P` at an order `P ≥ 2|z|`, where consecutive terms shrink by
//! at least a factor 2 (so the series has no cancellation worth mentioning), and runs on the
//! scaled values `ψ_k = k! φ_k` so that no factorial over- or underflows.

use num_complex::Complex64;
use std::ops::{Add, Mul, Sub};

use super::factorial::inv_factorial;

/// Real part above which the upward recurrence runs on `e^{−σ}`-scaled values (`e^z` alone
/// would overflow near `Re z ≈ 709.8`, while `φ_k(z) ≈ e^z/z^k` may still fit).
const SCALED_RE: f64 = 600.0;
/// `|e^{z−σ}|` used in the scaled recurrence: `e^{560} ≈ 1e243`, so that `|z|·e^{560}` cannot
/// overflow for `|z| < 1e65`.
const SCALED_TARGET: f64 = 560.0;
/// Below this modulus only the downward (Taylor) run is used: the upward one divides by `z`.
const SMALL: f64 = 0.25;
/// Upward values whose bound is at most this many units of roundoff are accepted without
/// computing the downward run.
const UP_GOOD: f64 = 6.0;
/// Relative size of the first neglected Taylor term (`2⁻⁵⁸ ≈ 3.5e−18 ≈ u/32`).
const TAYLOR_TOL: f64 = 3.469446951953614e-18;
/// Scratch length kept on the stack; longer outputs use the heap.
const STACK: usize = 40;
/// Smallest `tol² |other|²` for which [`Field::modulus_le`] decides by squared moduli: `2⁻⁹⁰⁰`,
/// far from underflow (and `tol` from its square).
const MODULUS_LE_MIN: f64 = 1.1830521861667747e-271;

/// The arithmetic the φ engine needs; implemented for `f64` and `Complex64`.
pub(super) trait Field:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self>
{
    fn real(x: f64) -> Self;
    fn nan() -> Self;
    fn modulus(self) -> f64;
    /// `self.modulus() <= tol * other.modulus()` for a power of two `tol`: the same decision,
    /// without the square roots where the squared moduli decide it.
    fn modulus_le(self, tol: f64, other: Self) -> bool;
    fn re_part(self) -> f64;
    fn has_nan(self) -> bool;
    fn all_finite(self) -> bool;
    /// The imaginary part is finite (always, for `f64`).
    fn im_finite(self) -> bool;
    /// `self / d`, without spurious overflow (Smith's algorithm for complex numbers).
    fn quot(self, d: Self) -> Self;
    fn quot_real(self, a: f64) -> Self;
    fn scale(self, a: f64) -> Self;
    /// `e^self` (only called with `Re self ≤ 600`).
    fn fexp(self) -> Self;
    /// `e^self − 1` without cancellation (only called with `Re self ≤ 600`).
    fn fexpm1(self) -> Self;
    /// `self − s` for real `s`.
    fn shift(self, s: f64) -> Self;
    /// `self · e^s` for `s ≥ 0`, overflowing to ±∞ per component but never producing NaN
    /// (a zero component stays zero).
    fn mul_exp(self, s: f64) -> Self;
    /// Fills `out` with the limits of `φ_k(self)` for infinite arguments (NaN where none exists).
    fn limits_at_infinity(self, out: &mut [Self]);
}

/// `c · h` with `0 · ∞ = 0` (a component that is exactly zero stays zero when scaled up).
#[inline]
fn mul0(c: f64, h: f64) -> f64 {
    if c == 0.0 { c } else { c * h }
}

/// `c · e^s`, `s ≥ 0`, see [`Field::mul_exp`].
#[inline]
fn mul_exp_f64(c: f64, s: f64) -> f64 {
    if s <= 1400.0 {
        let h = (0.5 * s).exp();
        mul0(mul0(c, h), h)
    } else {
        mul0(c, f64::INFINITY)
    }
}

impl Field for f64 {
    #[inline]
    fn real(x: f64) -> Self {
        x
    }
    #[inline]
    fn nan() -> Self {
        f64::NAN
    }
    #[inline]
    fn modulus(self) -> f64 {
        self.abs()
    }
    #[inline]
    fn modulus_le(self, tol: f64, other: Self) -> bool {
        self.abs() <= tol * other.abs()
    }
    #[inline]
    fn re_part(self) -> f64 {
        self
    }
    #[inline]
    fn has_nan(self) -> bool {
        self.is_nan()
    }
    #[inline]
    fn all_finite(self) -> bool {
        self.is_finite()
    }
    #[inline]
    fn im_finite(self) -> bool {
        true
    }
    #[inline]
    fn quot(self, d: Self) -> Self {
        self / d
    }
    #[inline]
    fn quot_real(self, a: f64) -> Self {
        self / a
    }
    #[inline]
    fn scale(self, a: f64) -> Self {
        self * a
    }
    #[inline]
    fn fexp(self) -> Self {
        self.exp()
    }
    #[inline]
    fn fexpm1(self) -> Self {
        self.exp_m1()
    }
    #[inline]
    fn shift(self, s: f64) -> Self {
        self - s
    }
    #[inline]
    fn mul_exp(self, s: f64) -> Self {
        mul_exp_f64(self, s)
    }
    fn limits_at_infinity(self, out: &mut [Self]) {
        // φ_k(−∞) = 0 for every k (φ_k(x) ~ 1/((k−1)!|x|)); φ_k(+∞) = +∞.
        let v = if self < 0.0 { 0.0 } else { f64::INFINITY };
        out.fill(v);
    }
}

impl Field for Complex64 {
    #[inline]
    fn real(x: f64) -> Self {
        Complex64::new(x, 0.0)
    }
    #[inline]
    fn nan() -> Self {
        Complex64::new(f64::NAN, f64::NAN)
    }
    #[inline]
    fn modulus(self) -> f64 {
        self.re.hypot(self.im)
    }
    #[inline]
    fn modulus_le(self, tol: f64, other: Self) -> bool {
        // a = |self|²(1 ± 3u) and b = |other|²(1 ± 3u) unless they under- or overflow; `tol²`
        // scales exactly. Where a differs from tol² b by more than a relative 1e−9, the exact
        // moduli differ by more than 4e−10 relative, far beyond the ulp of error in the two
        // hypot values: both comparisons agree. Otherwise (and for NaN, ∞ or tiny b) compare
        // the hypot values themselves.
        debug_assert_eq!(
            tol.to_bits() & ((1 << 52) - 1),
            0,
            "tol must be a power of two"
        );
        let a = self.re * self.re + self.im * self.im;
        let tb = (other.re * other.re + other.im * other.im) * (tol * tol);
        if tb.is_finite() && tb >= MODULUS_LE_MIN {
            if a < tb * (1.0 - 1e-9) {
                return true;
            }
            if a > tb * (1.0 + 1e-9) {
                return false;
            }
        }
        self.modulus() <= tol * other.modulus()
    }
    #[inline]
    fn re_part(self) -> f64 {
        self.re
    }
    #[inline]
    fn has_nan(self) -> bool {
        self.re.is_nan() || self.im.is_nan()
    }
    #[inline]
    fn all_finite(self) -> bool {
        self.re.is_finite() && self.im.is_finite()
    }
    #[inline]
    fn im_finite(self) -> bool {
        self.im.is_finite()
    }
    #[inline]
    fn quot(self, d: Self) -> Self {
        // Smith (1962): no overflow in |d|², and exact for purely real or imaginary d.
        if d.re.abs() >= d.im.abs() {
            let r = d.im / d.re;
            let den = d.re + d.im * r;
            Complex64::new((self.re + self.im * r) / den, (self.im - self.re * r) / den)
        } else {
            let r = d.re / d.im;
            let den = d.re * r + d.im;
            Complex64::new((self.re * r + self.im) / den, (self.im * r - self.re) / den)
        }
    }
    #[inline]
    fn quot_real(self, a: f64) -> Self {
        Complex64::new(self.re / a, self.im / a)
    }
    #[inline]
    fn scale(self, a: f64) -> Self {
        Complex64::new(self.re * a, self.im * a)
    }
    #[inline]
    fn fexp(self) -> Self {
        let (s, c) = self.im.sin_cos();
        let r = self.re.exp();
        Complex64::new(mul0(c, r), mul0(s, r))
    }
    #[inline]
    fn fexpm1(self) -> Self {
        // Re(e^z − 1) = expm1(x) cos y − 2 sin²(y/2),  Im(e^z − 1) = e^x sin y.
        let (x, y) = (self.re, self.im);
        let (s, c) = y.sin_cos();
        let h = (0.5 * y).sin();
        Complex64::new(x.exp_m1() * c - 2.0 * h * h, x.exp() * s)
    }
    #[inline]
    fn shift(self, s: f64) -> Self {
        Complex64::new(self.re - s, self.im)
    }
    #[inline]
    fn mul_exp(self, s: f64) -> Self {
        Complex64::new(mul_exp_f64(self.re, s), mul_exp_f64(self.im, s))
    }
    fn limits_at_infinity(self, out: &mut [Self]) {
        if self.im.is_finite() && self.re == f64::NEG_INFINITY {
            out.fill(Complex64::new(0.0, 0.0));
        } else if self.im.is_finite() && self.re == f64::INFINITY {
            // |φ_k(x + iy)| → ∞ with arg φ_k → y (arg z → 0).
            let (s, c) = self.im.sin_cos();
            out.fill(Complex64::new(
                mul0(c, f64::INFINITY),
                mul0(s, f64::INFINITY),
            ));
        } else {
            out.fill(Self::nan());
        }
    }
}

/// Runs `f` with three scratch slices of length `n` (on the stack when `n ≤ STACK`).
fn with_scratch<T: Field, R>(n: usize, f: impl FnOnce(&mut [f64], &mut [T], &mut [f64]) -> R) -> R {
    if n <= STACK {
        let mut a = [0.0; STACK];
        let mut b = [T::real(0.0); STACK];
        let mut c = [0.0; STACK];
        f(&mut a[..n], &mut b[..n], &mut c[..n])
    } else {
        let mut a = vec![0.0; n];
        let mut b = vec![T::real(0.0); n];
        let mut c = vec![0.0; n];
        f(&mut a, &mut b, &mut c)
    }
}

/// `out[k] = φ_k(z)` for `k = 0..out.len()`.
fn phi_engine<T: Field>(z: T, out: &mut [T]) {
    let n = out.len();
    if n == 0 {
        return;
    }
    if z.has_nan() {
        out.fill(T::nan());
        return;
    }
    if !z.all_finite() {
        z.limits_at_infinity(out);
        return;
    }
    if z.re_part() > SCALED_RE {
        upward_scaled(z, out);
        return;
    }
    out[0] = z.fexp();
    if n == 1 {
        return;
    }
    if z.modulus() == 0.0 {
        for (k, o) in out.iter_mut().enumerate() {
            *o = T::real(inv_factorial(k));
        }
        return;
    }
    with_scratch::<T, ()>(n, |eu, alt, ed| phi_core(z, out, eu, alt, ed));
}

/// Both recurrences with error bounds (`out[0] = e^z` is already set; `z ≠ 0`, `Re z ≤ 600`).
fn phi_core<T: Field>(z: T, out: &mut [T], eu: &mut [f64], alt: &mut [T], ed: &mut [f64]) {
    let n = out.len();
    let p = n - 1;
    let r = z.modulus();
    // Beyond this modulus the upward run is stable for every k ≤ p (|k! φ_k| ≲ k/|z| ≤ 1/4 in
    // the closed left half-plane; in the right half-plane it is ill-conditioned only next to
    // the zeros of φ_k, where no f64 recurrence does better).
    let r_max = 4.0 * p as f64 + 16.0;

    let mut have_up = false;
    if r >= SMALL {
        // φ₁ = expm1(z)/z has no cancellation; then φ_{k+1} = (φ_k − 1/k!)/z.
        out[1] = z.fexpm1().quot(z);
        eu[0] = 1.0;
        eu[1] = 3.0;
        for k in 1..p {
            let c = inv_factorial(k);
            let d = out[k] - T::real(c);
            let nd = d.modulus();
            out[k + 1] = d.quot(z);
            eu[k + 1] = if nd > 0.0 {
                (eu[k] * out[k].modulus() + 0.5 * c) / nd + 2.5
            } else {
                f64::INFINITY
            };
        }
        have_up = true;
        if r > r_max || eu[1..=p].iter().all(|&e| e <= UP_GOOD) {
            return;
        }
    }

    // Downward: ψ_P = P! φ_P = Σ_n zⁿ P!/(n+P)! by Horner with ratios |z|/(P+n) ≤ 1/2, then
    // ψ_{k−1} = 1 + z ψ_k / k.
    let big_p = p.max((2.0 * r).ceil() as usize);
    let mut nterms = 0usize;
    let mut t = 1.0;
    while t > TAYLOR_TOL {
        nterms += 1;
        t *= r / (big_p + nterms) as f64;
    }
    let one = T::real(1.0);
    let mut psi = one;
    let mut psi_abs = 1.0;
    for j in (1..=nterms).rev() {
        let q = (big_p + j) as f64;
        psi = one + (z * psi).quot_real(q);
        psi_abs = 1.0 + r * psi_abs / q;
    }
    // Horner on a series whose terms shrink geometrically: error ≲ 2u Σ|terms| / |sum|.
    let mut e = 2.0 * psi_abs / psi.modulus() + 1.0;
    let mut k = big_p;
    loop {
        if k <= p {
            alt[k] = psi.scale(inv_factorial(k));
            ed[k] = e + 1.0;
        }
        if k == 1 {
            break;
        }
        let t = (z * psi).quot_real(k as f64);
        psi = one + t;
        e = (e + 2.0) * t.modulus() / psi.modulus() + 1.0;
        k -= 1;
    }
    for k in 1..=p {
        // Also takes the downward value when a bound is NaN.
        let up_is_better = have_up && eu[k] <= ed[k];
        if !up_is_better {
            out[k] = alt[k];
        }
    }
}

/// Upward recurrence on `φ̃_k = e^{−σ} φ_k` for `Re z > 600`, `σ = Re z − 560`.
///
/// Here `|φ_k(z)| ≈ |e^z/z^k| ≫ 1/k!`, so every step is a subtraction of a negligible term
/// followed by a division: the error grows by about one rounding per step.
fn upward_scaled<T: Field>(z: T, out: &mut [T]) {
    let sigma = z.re_part() - SCALED_TARGET;
    let c = (-sigma).exp(); // e^{−σ} ≤ e^{−40}; underflows harmlessly for huge σ
    out[0] = z.shift(sigma).fexp();
    for k in 0..out.len() - 1 {
        out[k + 1] = (out[k] - T::real(c * inv_factorial(k))).quot(z);
    }
    for o in out.iter_mut() {
        *o = o.mul_exp(sigma);
    }
}

/// φ₀(z), …, φ_{n−1}(z) for real `z`: `out[k] = φ_k(z)`, `n = out.len()`.
///
/// `φ₀(z) = eᶻ` and `φ_k(z) = Σ_{n≥0} zⁿ/(n+k)!` (`docs/method.md#phi-functions`), all orders
/// at once, with a relative error below 1e−14 for `k ≤ 12` and `1e−16 ≤ |z| ≤ 1e12` (measured
/// in tests/it/phi.rs; see the module documentation for the method).
///
/// Extremes: for large negative `z`, `e^z` underflows gracefully to 0 while `φ_k(z) ≈
/// 1/((k−1)!|z|)`; for large positive `z` values beyond `f64::MAX` are `+∞`; `φ_k(−∞) = 0`,
/// `φ_k(+∞) = +∞`; NaN gives NaN. Never panics. For `k > 32` the constant `1/k!` is itself
/// not correctly rounded (see [`inv_factorial`]).
///
/// Allocates only when `out.len() > 40`.
pub fn phi_real(z: f64, out: &mut [f64]) {
    phi_engine(z, out);
}

/// φ₀(z), …, φ_{n−1}(z) for complex `z`: `out[k] = φ_k(z)`, `n = out.len()`.
///
/// The same method and accuracy as [`phi_real`], with the error measured in modulus
/// (`|computed − exact| / |exact|`). In the right half-plane φ_k (k ≥ 1) has zeros (φ₁ at
/// `2πin`, φ_k, k ≥ 2, near the curve `|e^z| ≈ |z|^{k−1}/(k−1)!`); next to them the relative
/// error grows like the condition number `|z φ_k'(z)/φ_k(z)|`, as for any f64 algorithm.
/// Values that overflow are ±∞ per component (never NaN for non-NaN finite input).
/// Limits: `φ_k(−∞ + iy) = 0`; NaN or infinite imaginary parts give NaN.
///
/// Allocates only when `out.len() > 40`.
pub fn phi_complex(z: Complex64, out: &mut [Complex64]) {
    phi_engine(z, out);
}

/// The trigonometric φ-functions `out[m] = φᵗ_m(K) = Σ_{l≥0} (−K)^l/(2l+m)!`.
///
/// With `K = θ²`: `φᵗ₀ = cos θ`, `φᵗ₁ = sin θ/θ`, `φᵗ₂ = (1 − cos θ)/θ² = ½ (sin(θ/2)/(θ/2))²`
/// and `φᵗ_{m+2}(K) = (1/m! − φᵗ_m(K))/K` (`docs/method.md#phi-functions`, TCrP). These three
/// closed forms are used for m ≤ 2 (accurate even next to their zeros), then the upward
/// recurrence where it is stable (`θ` large compared with m) and the downward one
/// `φᵗ_m = 1/m! − K φᵗ_{m+2}` from a Taylor series elsewhere, chosen per m by error bound as
/// for [`phi_real`].
///
/// `K < 0` is accepted: `φᵗ_m(−θ²) = ½ (φ_m(θ) + φ_m(−θ))` (hyperbolic case). `K = +∞` and NaN
/// give NaN, `K = −∞` gives `+∞`.
///
/// Note that `θ = √K` is rounded: the result is the exact value at a `K` perturbed by one
/// rounding, which for large `K` is a large relative change of `cos √K` (the problem is
/// ill-conditioned there, not the algorithm).
///
/// Allocates only when `out.len() > 40`.
pub fn phi_trig(k: f64, out: &mut [f64]) {
    let n = out.len();
    if n == 0 {
        return;
    }
    if k.is_nan() || k == f64::INFINITY {
        out.fill(f64::NAN);
        return;
    }
    if k < 0.0 {
        let theta = (-k).sqrt();
        if theta.is_infinite() {
            out.fill(f64::INFINITY);
            return;
        }
        with_scratch::<f64, ()>(n, |_, a, _| {
            phi_real(theta, out);
            phi_real(-theta, a);
            for (o, b) in out.iter_mut().zip(a.iter()) {
                *o = 0.5 * (*o + *b);
            }
        });
        return;
    }
    if k == 0.0 {
        for (m, o) in out.iter_mut().enumerate() {
            *o = inv_factorial(m);
        }
        return;
    }
    let theta = k.sqrt();
    out[0] = theta.cos();
    if n == 1 {
        return;
    }
    with_scratch::<f64, ()>(n, |eu, alt, ed| trig_core(k, theta, out, eu, alt, ed));
}

/// The two interleaved recurrences of [`phi_trig`] (`K > 0`, `out[0] = cos θ` set).
fn trig_core(k: f64, theta: f64, out: &mut [f64], eu: &mut [f64], alt: &mut [f64], ed: &mut [f64]) {
    let n = out.len();
    let p = n - 1;
    let mut have_up = false;
    if theta >= SMALL {
        out[1] = theta.sin() / theta;
        eu[0] = 1.0;
        eu[1] = 2.0;
        if p >= 2 {
            let h = 0.5 * theta;
            let s = h.sin() / h;
            out[2] = 0.5 * s * s;
            eu[2] = 3.0;
        }
        for m in 1..p.saturating_sub(1) {
            let c = inv_factorial(m);
            let d = c - out[m];
            let nd = d.abs();
            out[m + 2] = d / k;
            eu[m + 2] = if nd > 0.0 {
                (eu[m] * out[m].abs() + 0.5 * c) / nd + 1.5
            } else {
                f64::INFINITY
            };
        }
        have_up = true;
        if theta > 2.0 * p as f64 + 16.0 || eu[1..=p].iter().all(|&e| e <= UP_GOOD) {
            return;
        }
    }
    // Downward on ψ_m = m! φᵗ_m: ψ_m = 1 − K ψ_{m+2}/((m+1)(m+2)), from Taylor series at the
    // two top orders P − 1 and P with K/(P(P+1)) ≤ 1/4.
    let big_p = p.max((2.0 * theta).ceil() as usize + 1);
    for top in [big_p, big_p - 1] {
        let mut nterms = 0usize;
        let mut t = 1.0;
        while t > TAYLOR_TOL {
            nterms += 1;
            t *= k / ((top + 2 * nterms - 1) * (top + 2 * nterms)) as f64;
        }
        let mut psi = 1.0;
        let mut psi_abs = 1.0;
        for j in (1..=nterms).rev() {
            let den = ((top + 2 * j - 1) * (top + 2 * j)) as f64;
            psi = 1.0 - k * psi / den;
            psi_abs = 1.0 + k * psi_abs / den;
        }
        let mut e = 2.0 * psi_abs / psi.abs() + 1.0;
        let mut m = top;
        loop {
            if m <= p {
                alt[m] = psi * inv_factorial(m);
                ed[m] = e + 1.0;
            }
            if m <= 2 {
                break;
            }
            let t = k * psi / ((m - 1) * m) as f64;
            psi = 1.0 - t;
            e = (e + 2.0) * t.abs() / psi.abs() + 1.0;
            m -= 2;
        }
    }
    for m in 1..=p {
        let up_is_better = have_up && eu[m] <= ed[m];
        if !up_is_better {
            out[m] = alt[m];
        }
    }
}

/// φ-functions of a diagonal matrix, entry by entry: `result[k][j] = φ_k(d[j])` for
/// `k = 0..=p` (each inner vector is the diagonal of `φ_k(diag(d))`).
///
/// Uses [`phi_real`] for every entry (all k at once); the same accuracy and extremes.
pub fn phi_diagonal(d: &[f64], p: usize) -> Vec<Vec<f64>> {
    let mut result = vec![vec![0.0; d.len()]; p + 1];
    with_scratch::<f64, ()>(p + 1, |_, buf, _| {
        for (j, &x) in d.iter().enumerate() {
            phi_real(x, buf);
            for (k, row) in result.iter_mut().enumerate() {
                row[j] = buf[k];
            }
        }
    });
    result
}
