//! The Legendre kernels of ECrP: `ψ_m(x) = ∫₀¹ e^{(1−ξ)x} P̃_m(ξ) dξ` and, for a node τ,
//! `Ψ_j(τ, x) = ∫₀¹ e^{(1−ξ)τx} P̃_j(τξ) dξ`.
//!
//! # Why
//!
//! The moment form of ECrP (`docs/method.md#moment-form`) writes a stage as
//! `h Σ_k τ^{k+1} φ_{k+1}(τhA) G_k` with the moments
//! `G_k = Σ_j w_kj g(Y_j)`. Both factors are large and cancel: `|w_kj|` reaches 1.4e7 at r = 8
//! (the monomial coefficients `c_jk` of P̃_j grow like 6^j), so the f64 rounding of the weights,
//! of `G_k` and of the φ-functions leaves an error of `1e−9 |g|` in the stage. Regrouped by
//! Legendre degree the same formula reads
//!
//! ```text
//! Y(τ) = e^{τhA} y₀ + hτ Σ_j (2j+1) Ψ_j(τ, hA) L_j,     L_j = Σ_i b_i P̃_j(c_i) g(Y_i)
//! Ψ_j(τ, Z) = Σ_{k≤j} c_jk τ^k φ_{k+1}(τZ)
//! ```
//!
//! where `|P̃_j| ≤ 1` on [0, 1] and `|Ψ_j(τ, x)| ≤ φ₁(Re τx)`: every factor is bounded and the
//! error of a stage stays at a few units of roundoff times `h |g|`, for every r. The kernels
//! must then be computed directly, not from the φ-functions (that sum is the cancellation).
//!
//! # How
//!
//! `P̃_j(τξ) = Σ_{m≤j} K_jm(τ) P̃_m(ξ)` ([`LegendreKernels::node_map`]; for τ ∈ [0, 1] this is
//! the restriction of P̃_j to [0, τ], with `|K_jm(τ)| ≤ 2m+1`), so `Ψ_j(τ, x) = Σ_m K_jm(τ)
//! ψ_m(τx)`, and for ψ:
//!
//! * n ≥ 3 and `2⁻¹⁰ ≤ |x| ≤ 4`: the Taylor series (below) of `ψ_{n−2}` and `ψ_{n−1}`, then
//!   the three-term recurrence `ψ_{m−1} = ψ_{m+1} − 2(2m+1) ψ_m / x` downwards (ψ_m is
//!   `e^{x/2}` times a modified spherical Bessel function, the recurrence's minimal solution, so
//!   the downward direction is stable);
//! * otherwise, `|x| ≤ 1/2`: the Taylor series `ψ_m(x) = (−1)^m Σ_{k≥m} k!/((k−m)!(k+m+1)!) x^k`
//!   (consecutive terms shrink by at least 4, no cancellation);
//! * `|x| ≥ 4n²` (n functions): the exact finite sum from repeated integration by parts,
//!   `ψ_m(x) = Σ_{q≤m} D_mq ((−1)^{m+q} e^x − 1)/x^{q+1}` with `D_mq = P̃_m^{(q)}(1) =
//!   (m+q)!/(q!(m−q)!)`, whose terms shrink by at least 4;
//! * in between: scaling and doubling. Splitting [0, 2] into halves,
//!   `ψ_l(2y) = ½ Σ_m (e^y L_lm + (−1)^{l+m} L_lm) ψ_m(y)` with `L = K(1/2)`, applied
//!   `⌈log₂ 2|x|⌉` times from the Taylor value at `x/2^s` (at most 11 doublings for n ≤ 12).
//!
//! Accuracy (tests/it/legendre_kernels.rs, against 256-bit references): the absolute error of
//! `Ψ_j(τ, x)` is a few units of roundoff times `φ₁(Re τx)`, the natural bound of the kernel
//! (relative accuracy is neither available nor needed: a stage needs `Ψ_j L_j` to `ε h |g|`).
//! Matrices ([`LegendreKernels::psi_dense`]): the same Taylor series and doubling on matrices.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

use nalgebra::DMatrix;
use num_complex::Complex64;

use super::gauss::{gauss_legendre, shifted_legendre};
use super::scalar::Field;
use crate::error::{Error, Result};

/// The tables' maps are looked up for every node of every bank (a value between grid points
/// builds two banks): foldhash's fixed-seed hasher, not SipHash (which took 3 % of such a
/// value's instructions on Duffing, callgrind; no key here comes from outside the process).
type Tables<K, V> = HashMap<K, V, foldhash::fast::FixedState>;

/// The Taylor series is used for `|x| ≤` this.
const TAYLOR_RADIUS: f64 = 0.5;
/// ψ comes from the recurrence ([`LegendreKernels::recurrence`]) for n ≥ 3 and `|x|` in
/// `[RECURRENCE_MIN, RECURRENCE_RADIUS]`: beyond the radius the two Taylor series it starts from
/// lose digits to cancellation (1e−13 of φ₁(Re x) at |x| = 8, 1e−10 at 16); below the least
/// value the highest ψ_m may underflow while ψ_0 does not.
const RECURRENCE_RADIUS: f64 = 4.0;
const RECURRENCE_MIN: f64 = 1.0 / 1024.0;
/// First neglected Taylor term relative to the sum: `2⁻⁵⁸ ≈ u/32`.
const TAYLOR_TOL: f64 = 3.469446951953614e-18;
/// At most this many Taylor terms after the first (far more than `|x| ≤ 1/2` needs).
const TAYLOR_TERMS: usize = 80;
/// Matrix Taylor series: powers `X^0..=X^MATRIX_TERMS` (`‖X‖₁ ≤ 1/2`; the terms are bounded by
/// `2^{−k}/(k+1)!`, below `1e−18` beyond k = 15).
const MATRIX_TERMS: usize = 16;
/// Scratch length kept on the stack.
const STACK: usize = 40;

/// The kernels `ψ_m`, `m < n`, and what is needed to evaluate them (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct LegendreKernels {
    n: usize,
    /// `m!/(2m+1)!`: the first Taylor coefficient of `(−1)^m ψ_m`.
    first: Vec<f64>,
    /// `ratio[m·TAYLOR_TERMS + j]`: the ratio `(k+1)/((k+1−m)(k+m+2))` of the Taylor
    /// coefficients `k + 1` and `k` of ψ_m, `k = m + j`.
    ratio: Vec<f64>,
    /// `L = K(1/2)`, row-major n × n (lower triangular).
    half: Vec<f64>,
    /// `D_mq = (m+q)!/(q!(m−q)!)`, row-major n × n (q ≤ m).
    deriv: Vec<f64>,
    /// `|x|` from which the finite integration-by-parts sum is used.
    big: f64,
    /// The n-point Gauss–Legendre rule on [0, 1] of [`node_map`](Self::node_map): nodes and
    /// weights, computed once for all nodes τ.
    gauss: (Vec<f64>, Vec<f64>),
}

impl LegendreKernels {
    /// The kernels `ψ_0 … ψ_{n−1}` (ECrP with r moments needs n = r). Cost O(n³) plus the
    /// Newton iterations of an n-point Gauss rule, tens of microseconds for n ≤ 12; the banks
    /// build one per n and process and share it.
    pub fn new(n: usize) -> Self {
        let mut first = Vec::with_capacity(n);
        let mut a = 1.0;
        for m in 0..n {
            first.push(a);
            a *= (m + 1) as f64 / ((2 * m + 2) * (2 * m + 3)) as f64;
        }
        let ratio = (0..n)
            .flat_map(|m| {
                (m..m + TAYLOR_TERMS)
                    .map(move |k| (k + 1) as f64 / ((k + 1 - m) * (k + m + 2)) as f64)
            })
            .collect();
        let mut deriv = vec![0.0; n * n];
        for m in 0..n {
            // D_m0 = 1, D_{m,q+1} = D_mq (m+q+1)(m−q)/(q+1).
            let mut v = 1.0;
            for q in 0..=m {
                deriv[m * n + q] = v;
                v *= ((m + q + 1) * (m - q)) as f64 / (q + 1) as f64;
            }
        }
        let mut k = LegendreKernels {
            n,
            first,
            ratio,
            half: Vec::new(),
            deriv,
            big: (4 * n * n).max(8) as f64,
            gauss: gauss_legendre(n),
        };
        k.half = k.node_map(0.5);
        k
    }

    /// [`new`](Self::new)`(n)`, built once per process and shared: every bank with n kernels
    /// (each operator, step size and stepper) uses the same tables.
    pub(crate) fn shared(n: usize) -> Arc<Self> {
        type Cache = Mutex<Tables<usize, Arc<LegendreKernels>>>;
        static CACHE: OnceLock<Cache> = OnceLock::new();
        let cache = CACHE.get_or_init(Default::default);
        if let Some(k) = cache.lock().unwrap_or_else(|e| e.into_inner()).get(&n) {
            return Arc::clone(k);
        }
        let k = Arc::new(Self::new(n));
        let mut map = cache.lock().unwrap_or_else(|e| e.into_inner());
        Arc::clone(map.entry(n).or_insert(k))
    }

    /// [`node_map`](Self::node_map)`(τ)`, computed once per process for each (n, τ) and
    /// shared: the banks' nodes are the same few for every step size (at most `MAPS_KEPT`
    /// maps are kept; past that the table starts again).
    pub(crate) fn node_map_shared(&self, tau: f64) -> Arc<[f64]> {
        type Cache = Mutex<Tables<(usize, u64), Arc<[f64]>>>;
        static CACHE: OnceLock<Cache> = OnceLock::new();
        const MAPS_KEPT: usize = 1 << 12;
        let key = (self.n, tau.to_bits());
        let cache = CACHE.get_or_init(Default::default);
        if let Some(k) = cache.lock().unwrap_or_else(|e| e.into_inner()).get(&key) {
            return Arc::clone(k);
        }
        let k: Arc<[f64]> = self.node_map(tau).into();
        let mut map = cache.lock().unwrap_or_else(|e| e.into_inner());
        if map.len() >= MAPS_KEPT {
            map.clear();
        }
        Arc::clone(map.entry(key).or_insert(k))
    }

    /// The number of kernels n.
    pub fn n(&self) -> usize {
        self.n
    }

    /// `K(τ)`, row-major n × n: `P̃_j(τξ) = Σ_{m≤j} K_jm(τ) P̃_m(ξ)`. Exact for τ = 0 and τ = 1
    /// (`K(1) = I`); otherwise from an n-point Gauss–Legendre rule (exact for the degree 2n − 2
    /// integrands), with errors of a few units of roundoff in entries bounded by `2m + 1` for
    /// τ ∈ [0, 1]. τ > 1 (the predictor's extrapolation) is allowed; the entries then grow
    /// like `P̃_j(τ)`.
    pub fn node_map(&self, tau: f64) -> Vec<f64> {
        let n = self.n;
        let mut k = vec![0.0; n * n];
        if tau == 1.0 {
            for j in 0..n {
                k[j * n + j] = 1.0;
            }
            return k;
        }
        if tau == 0.0 {
            for j in 0..n {
                k[j * n] = if j % 2 == 0 { 1.0 } else { -1.0 };
            }
            return k;
        }
        let (nodes, weights) = &self.gauss;
        let mut pt = vec![0.0; n];
        let mut p = vec![0.0; n];
        for (xi, wq) in nodes.iter().zip(weights) {
            shifted_legendre(tau * xi, &mut pt);
            shifted_legendre(*xi, &mut p);
            for j in 0..n {
                for m in 0..=j {
                    k[j * n + m] += wq * pt[j] * p[m];
                }
            }
        }
        for j in 0..n {
            for m in 0..=j {
                k[j * n + m] *= (2 * m + 1) as f64;
            }
        }
        k
    }

    /// `out[m] = ψ_m(x)` for real x, `m < out.len() ≤ n`. `ψ_m(−∞) = 0`; other infinite or
    /// NaN arguments give NaN; values beyond `f64::MAX` overflow to ±∞. Allocation-free for
    /// n ≤ 40.
    ///
    /// # Panics
    /// If `out.len() > n`.
    pub fn psi_real(&self, x: f64, out: &mut [f64]) {
        self.psi(x, out);
    }

    /// `out[m] = ψ_m(z)` for complex z (as [`psi_real`](Self::psi_real); `ψ_m(−∞ + iy) = 0`).
    ///
    /// # Panics
    /// If `out.len() > n`.
    pub fn psi_complex(&self, z: Complex64, out: &mut [Complex64]) {
        self.psi(z, out);
    }

    /// One bank row at a node: `out[0] = e^x`, `out[1 + j] = Ψ_j(τ, x/τ) = Σ_m K_jm ψ_m(x)`
    /// for `j < out.len() − 1`, where `x = τ h λ` and `kmap = node_map(τ)`.
    ///
    /// # Panics
    /// If `out.len() > n + 1` or `kmap.len() ≠ n²`.
    pub fn row_real(&self, kmap: &[f64], x: f64, out: &mut [f64]) {
        self.row(kmap, x, out);
    }

    /// [`row_real`](Self::row_real) for complex arguments.
    ///
    /// # Panics
    /// As [`row_real`](Self::row_real).
    pub fn row_complex(&self, kmap: &[f64], z: Complex64, out: &mut [Complex64]) {
        self.row(kmap, z, out);
    }

    fn row<T: Field>(&self, kmap: &[f64], x: T, out: &mut [T]) {
        assert!(out.len() <= self.n + 1 && kmap.len() == self.n * self.n);
        let Some((first, rest)) = out.split_first_mut() else {
            return;
        };
        *first = if x.has_nan() { T::nan() } else { x.fexp() };
        let m = rest.len();
        with_stack(m, |psi| {
            self.psi(x, psi);
            for (j, o) in rest.iter_mut().enumerate() {
                let mut acc = T::real(0.0);
                for (mm, p) in psi.iter().enumerate().take(j + 1) {
                    let c = kmap[j * self.n + mm];
                    if c != 0.0 {
                        acc = acc + p.scale(c);
                    }
                }
                *o = acc;
            }
        });
    }

    fn psi<T: Field>(&self, x: T, out: &mut [T]) {
        let n = out.len();
        assert!(n <= self.n, "{n} kernels requested, {} available", self.n);
        if n == 0 {
            return;
        }
        if x.has_nan() {
            out.fill(T::nan());
            return;
        }
        if !x.all_finite() {
            let limit = if x.re_part() == f64::NEG_INFINITY && x.im_finite() {
                T::real(0.0)
            } else {
                T::nan()
            };
            out.fill(limit);
            return;
        }
        let a = x.modulus();
        if n >= 3 && (RECURRENCE_MIN..=RECURRENCE_RADIUS).contains(&a) {
            self.recurrence(x, out);
        } else if a <= TAYLOR_RADIUS {
            self.taylor(x, 0, out);
        } else if a >= self.big {
            self.finite(x, out);
        } else {
            let s = (a / TAYLOR_RADIUS).log2().ceil().max(0.0) as i32;
            let mut y = x.scale((-s as f64).exp2());
            self.taylor(y, 0, out);
            with_stack(n, |next| {
                for _ in 0..s {
                    let e = y.fexp();
                    for (l, nx) in next.iter_mut().enumerate() {
                        // A = Σ_{l+m even} L_lm ψ_m, B = Σ_{l+m odd}: ψ_l(2y) = A + ½ (e−1)(A+B)
                        // = ½ [e (A+B) + (A−B)].
                        let (mut ea, mut ob) = (T::real(0.0), T::real(0.0));
                        for (m, p) in out.iter().enumerate().take(l + 1) {
                            let c = self.half[l * self.n + m];
                            if (l + m) % 2 == 0 {
                                ea = ea + p.scale(c);
                            } else {
                                ob = ob + p.scale(c);
                            }
                        }
                        *nx = (e * (ea + ob) + (ea - ob)).scale(0.5);
                    }
                    out.copy_from_slice(next);
                    y = y.scale(2.0);
                }
            });
        }
    }

    /// `ψ_m`, `m < n`, from the Taylor series of the last two and the three-term recurrence
    /// `x (ψ_{m+1} − ψ_{m−1}) = 2(2m+1) ψ_m` (integration by parts of `P̃'_{m+1} − P̃'_{m−1}
    /// = 2(2m+1) P̃_m`) run downwards, `ψ_{m−1} = ψ_{m+1} − 2(2m+1) ψ_m / x`. ψ_m is, up to
    /// `e^{x/2}`, the modified spherical Bessel function `i_m(x/2)`: the solution of the
    /// recurrence that is smallest for large m, which the downward direction computes stably
    /// (Miller). Two series instead of n, and no doubling: for `|x| ≤ RECURRENCE_RADIUS`,
    /// where the two series are accurate (measured against 256-bit references in
    /// tests/it/legendre_kernels.rs).
    fn recurrence<T: Field>(&self, x: T, out: &mut [T]) {
        let n = out.len();
        self.taylor_pair(x, n - 2, &mut out[n - 2..]);
        let inv = T::real(1.0).quot(x);
        for m in (1..n - 1).rev() {
            out[m - 1] = out[m + 1] - (out[m] * inv).scale((4 * m + 2) as f64);
        }
    }

    /// [`taylor`](Self::taylor) for the two series the recurrence starts from, `out[j] =
    /// ψ_{m0 + j}(x)`, j < 2: the same operations in the same order (so the same bits), in
    /// registers, without the general loop's bookkeeping (the kernels of a value between grid
    /// points on Duffing took 35k instructions a call with it, 25k without; callgrind).
    fn taylor_pair<T: Field>(&self, x: T, m0: usize, out: &mut [T]) {
        let mut xm = T::real(1.0);
        for _ in 0..m0 {
            xm = xm * x;
        }
        let t0 = xm.scale(self.first[m0]);
        let t1 = (xm * x).scale(self.first[m0 + 1]);
        let mut term = [t0, t1];
        let mut sum = term;
        let first = &self.ratio[m0 * TAYLOR_TERMS..(m0 + 1) * TAYLOR_TERMS];
        let second = &self.ratio[(m0 + 1) * TAYLOR_TERMS..(m0 + 2) * TAYLOR_TERMS];
        let mut done = [false; 2];
        for (&a, &b) in first.iter().zip(second) {
            for (q, ratio) in [a, b].into_iter().enumerate() {
                if !done[q] {
                    term[q] = (term[q] * x).scale(ratio);
                    sum[q] = sum[q] + term[q];
                    done[q] = term[q].modulus_le(TAYLOR_TOL, sum[q]);
                }
            }
            if done[0] && done[1] {
                break;
            }
        }
        // The odd-indexed ψ's series alternate: as in `taylor`, the sign of ψ_m for odd m.
        let flip = 1 - m0 % 2;
        sum[flip] = sum[flip].scale(-1.0);
        out[..2].copy_from_slice(&sum);
    }

    /// `out[j] = ψ_{m0 + j}(x)` by their Taylor series.
    fn taylor<T: Field>(&self, x: T, m0: usize, out: &mut [T]) {
        // The series are independent: they advance together, one term each per pass, so that
        // their multiplications overlap. Each sees the same operations in the same order as
        // when summed alone; `out` holds the partial sums, `done` marks the converged ones.
        let n = out.len();
        let mut done_stack = [false; STACK];
        let mut done_heap = Vec::new();
        let done: &mut [bool] = if n <= STACK {
            &mut done_stack[..n]
        } else {
            done_heap.resize(n, false);
            &mut done_heap
        };
        with_stack(n, |term| {
            let mut xm = T::real(1.0);
            for _ in 0..m0 {
                xm = xm * x;
            }
            let firsts = &self.first[m0..];
            for ((t, o), first) in term.iter_mut().zip(out.iter_mut()).zip(firsts) {
                *t = xm.scale(*first);
                *o = *t;
                xm = xm * x;
            }
            let mut live = n;
            let ratios = self.ratio.chunks_exact(TAYLOR_TERMS).skip(m0);
            for j in 0..TAYLOR_TERMS {
                let series = term.iter_mut().zip(out.iter_mut()).zip(done.iter_mut());
                for (((t, o), d), ratio) in series.zip(ratios.clone()) {
                    if *d {
                        continue;
                    }
                    *t = (*t * x).scale(ratio[j]);
                    *o = *o + *t;
                    if t.modulus_le(TAYLOR_TOL, *o) {
                        *d = true;
                        live -= 1;
                    }
                }
                if live == 0 {
                    break;
                }
            }
        });
        for o in out.iter_mut().skip(1 - m0 % 2).step_by(2) {
            *o = o.scale(-1.0);
        }
    }

    fn finite<T: Field>(&self, x: T, out: &mut [T]) {
        // ψ_m = e^x S⁻_m − S⁺_m with S^±_m = Σ_q (±1)^{m+q} D_mq / x^{q+1}: where e^x overflows
        // the result is ±∞ (not ∞ − ∞).
        let e = x.fexp();
        let inv = T::real(1.0).quot(x);
        for (m, o) in out.iter_mut().enumerate() {
            let (mut alt, mut plain) = (T::real(0.0), T::real(0.0));
            let mut pw = inv;
            for q in 0..=m {
                let t = pw.scale(self.deriv[m * self.n + q]);
                alt = if (m + q) % 2 == 0 { alt + t } else { alt - t };
                plain = plain + t;
                pw = pw * inv;
            }
            *o = e * alt - plain;
        }
    }

    /// `ψ_0(X) … ψ_{n−1}(X)` for a square matrix: the Taylor series at `2^{−s}X` with
    /// `‖2^{−s}X‖₁ ≤ 1/2` from shared powers, then `s` doublings `ψ(2Y) = A + ½ E (A + B)`
    /// with `E = e^Y − I` carried as `E ← E² + 2E` (the scalar recurrence in matrix form;
    /// functions of the same matrix commute). About `16 + s (n + 1)` matrix products.
    ///
    /// # Errors
    /// [`Error::NotSquare`], [`Error::NonFinite`] for NaN/∞ entries, [`Error::Numerical`] if
    /// `‖X‖₁ > 1e300` or the result overflows.
    pub fn psi_dense(&self, x: &DMatrix<f64>) -> Result<Vec<DMatrix<f64>>> {
        super::dense::validate(x, "matrix")?;
        let d = x.nrows();
        let n = self.n;
        let norm = super::dense::norm1(x);
        if norm > 1e300 {
            return Err(Error::Numerical(format!(
                "matrix 1-norm {norm:e} too large for scaling and squaring"
            )));
        }
        let s = if norm <= TAYLOR_RADIUS {
            0
        } else {
            (norm / TAYLOR_RADIUS).log2().ceil() as i32
        };
        let y = x * (-s as f64).exp2();
        let mut powers = Vec::with_capacity(MATRIX_TERMS + 1);
        powers.push(DMatrix::<f64>::identity(d, d));
        powers.push(y.clone());
        for k in 2..=MATRIX_TERMS {
            let mut next = DMatrix::<f64>::zeros(d, d);
            super::dense::mul_into(&powers[k - 1], &y, &mut next);
            powers.push(next);
        }
        // E = e^Y − I and ψ_m(Y) = (−1)^m Σ_{k≥m} a_mk Y^k.
        let mut e = DMatrix::<f64>::zeros(d, d);
        let mut c = 1.0;
        for (k, p) in powers.iter().enumerate().skip(1) {
            c /= k as f64;
            super::dense::axpy(&mut e, c, p);
        }
        let mut psi: Vec<DMatrix<f64>> = (0..n)
            .map(|m| {
                let mut acc = DMatrix::<f64>::zeros(d, d);
                let sign = if m % 2 == 0 { 1.0 } else { -1.0 };
                let mut a = self.first[m];
                for (k, pk) in powers.iter().enumerate().skip(m) {
                    super::dense::axpy(&mut acc, sign * a, pk);
                    a *= (k + 1) as f64 / ((k + 1 - m) * (k + m + 2)) as f64;
                }
                acc
            })
            .collect();
        drop(powers);
        let mut ea = DMatrix::<f64>::zeros(d, d);
        let mut sum = DMatrix::<f64>::zeros(d, d);
        let mut prod = DMatrix::<f64>::zeros(d, d);
        let mut next = psi.clone();
        for _ in 0..s {
            for (l, out) in next.iter_mut().enumerate() {
                ea.fill(0.0);
                sum.fill(0.0);
                for (m, p) in psi.iter().enumerate().take(l + 1) {
                    let c = self.half[l * n + m];
                    if (l + m) % 2 == 0 {
                        super::dense::axpy(&mut ea, c, p);
                    }
                    super::dense::axpy(&mut sum, c, p);
                }
                super::dense::mul_into(&e, &sum, &mut prod);
                out.copy_from(&ea);
                super::dense::axpy(out, 0.5, &prod);
            }
            std::mem::swap(&mut psi, &mut next);
            // E(2Y) = E² + 2E.
            super::dense::mul_into(&e, &e, &mut prod);
            super::dense::axpy(&mut prod, 2.0, &e);
            std::mem::swap(&mut e, &mut prod);
        }
        if psi.iter().any(|m| m.iter().any(|v| !v.is_finite())) {
            return Err(Error::Numerical(
                "Legendre kernels overflow f64 (the matrix has eigenvalues far in the right \
                 half-plane)"
                    .into(),
            ));
        }
        Ok(psi)
    }

    /// One dense bank node: `Ψ_j(τ, X/τ) = Σ_m K_jm ψ_m(X)`, `j < n`, with `kmap =
    /// node_map(τ)` and `X = τhA`.
    ///
    /// # Errors
    /// As [`psi_dense`](Self::psi_dense).
    pub fn rows_dense(&self, kmap: &[f64], x: &DMatrix<f64>) -> Result<Vec<DMatrix<f64>>> {
        let psi = self.psi_dense(x)?;
        let d = x.nrows();
        Ok((0..self.n)
            .map(|j| {
                let mut acc = DMatrix::<f64>::zeros(d, d);
                for (m, p) in psi.iter().enumerate().take(j + 1) {
                    let c = kmap[j * self.n + m];
                    if c != 0.0 {
                        super::dense::axpy(&mut acc, c, p);
                    }
                }
                acc
            })
            .collect())
    }
}

/// Runs `f` with a scratch slice of length `n` (on the stack when `n ≤ STACK`).
fn with_stack<T: Field, R>(n: usize, f: impl FnOnce(&mut [T]) -> R) -> R {
    if n <= STACK {
        let mut a = [T::real(0.0); STACK];
        f(&mut a[..n])
    } else {
        let mut a = vec![T::real(0.0); n];
        f(&mut a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ψ_m(x) by a 64-point Gauss–Legendre rule on the defining integral (smooth integrand for
    /// moderate x).
    fn quad(m: usize, x: f64) -> f64 {
        let (nodes, weights) = gauss_legendre(64);
        let mut p = vec![0.0; m + 1];
        nodes
            .iter()
            .zip(&weights)
            .map(|(xi, w)| {
                shifted_legendre(*xi, &mut p);
                w * ((1.0 - xi) * x).exp() * p[m]
            })
            .sum()
    }

    /// The squared-moduli shortcut of the Taylor stopping test decides exactly as the hypot
    /// values do: near the threshold (where it defers to them), far from it, and for tiny, huge
    /// and non-finite numbers.
    #[test]
    fn modulus_le_decides_as_hypot() {
        let mut rng = crate::test_rng::XorShift(0x2545_f491_4f6c_dd1d);
        let mut next = move || rng.unit();
        let mut cases = Vec::new();
        for _ in 0..20000 {
            let s = Complex64::from_polar(10f64.powf(40.0 * next() - 20.0), 7.0 * next());
            let rel = 1.0 + (next() - 0.5) * 10f64.powf(-4.0 - 12.0 * next());
            let t = Complex64::from_polar(s.norm() * TAYLOR_TOL * rel, 7.0 * next());
            cases.push((t, s));
            cases.push((t.scale(16.0), s));
            cases.push((t.scale(1.0 / 16.0), s));
        }
        let tiny = Complex64::new(1e-300, -3e-301);
        let huge = Complex64::new(1e300, 1e300);
        let nan = Complex64::new(f64::NAN, 0.0);
        let inf = Complex64::new(f64::INFINITY, 1.0);
        let zero = Complex64::new(0.0, 0.0);
        for a in [tiny, huge, nan, inf, zero, Complex64::new(1e-160, 1e-170)] {
            for b in [tiny, huge, nan, inf, zero, Complex64::new(0.5, 0.25)] {
                cases.push((a, b));
            }
        }
        for (t, s) in cases {
            let expect = t.re.hypot(t.im) <= TAYLOR_TOL * s.re.hypot(s.im);
            assert_eq!(t.modulus_le(TAYLOR_TOL, s), expect, "{t} vs {s}");
        }
    }

    #[test]
    fn three_regimes_agree_with_quadrature() {
        let k = LegendreKernels::new(12);
        let mut out = [0.0; 12];
        for &x in &[
            0.0, 1e-8, 0.3, -0.5, 0.7, -3.0, 9.0, -40.0, 100.0, -700.0, -1200.0,
        ] {
            k.psi_real(x, &mut out);
            let scale = if x == 0.0 { 1.0 } else { (x.exp() - 1.0) / x }.abs();
            for (m, o) in out.iter().enumerate() {
                let q = if x.abs() <= 40.0 { quad(m, x) } else { *o };
                assert!((o - q).abs() <= 1e-14 * scale, "m={m} x={x}: {o} vs {q}");
            }
        }
        // Far out: ψ_m(x) → −Σ_q D_mq/x^{q+1} = 1/|x| − m(m+1)/x² + O(|x|⁻³).
        k.psi_real(-1e12, &mut out);
        for (m, o) in out.iter().enumerate() {
            let expect = 1e-12 - (m * (m + 1)) as f64 * 1e-24;
            assert!((o - expect).abs() < 1e-27, "m={m}: {o}");
        }
    }

    #[test]
    fn node_map_restricts_legendre_polynomials() {
        let k = LegendreKernels::new(9);
        for &tau in &[0.0, 0.1127, 0.5, 0.9, 1.0, 1.7] {
            let map = k.node_map(tau);
            let mut lhs = vec![0.0; 9];
            let mut rhs = vec![0.0; 9];
            for &xi in &[0.0, 0.3, 0.77, 1.0] {
                shifted_legendre(tau * xi, &mut lhs);
                shifted_legendre(xi, &mut rhs);
                for j in 0..9 {
                    let v: f64 = (0..=j).map(|m| map[j * 9 + m] * rhs[m]).sum();
                    let size: f64 = (0..=j).map(|m| (map[j * 9 + m] * rhs[m]).abs()).sum();
                    assert!((v - lhs[j]).abs() < 1e-14 * (1.0 + size), "{tau} {j}");
                }
            }
        }
    }
}
