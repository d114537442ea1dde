//! Problem 3: the cubic nonlinear Schrödinger equation, pseudospectral semi-discretisation.

use std::f64::consts::{PI, SQRT_2};
use std::fmt;
use std::sync::{Arc, Mutex, OnceLock};

use nalgebra::DMatrix;
use num_complex::Complex64;
use rustfft::{Fft, FftPlanner};

use super::{check_len, forward_test_problem};
use ecr_runtime::storage::ensure_allocatable;
use ecr_runtime::{Error, Result};

/// Problem 3 of the paper (§9): the cubic nonlinear Schrödinger equation
///
/// ```text
/// iψ_t + ψ_xx + 2|ψ|²ψ = 0   on [0, L), periodic,   ψ(x, 0) = 0.5 + 0.025 cos(μx),
/// L = 4√2 π,   μ = 2π/L = √2/4,
/// ```
///
/// with `ψ = p + iq` on the grid `x_j = jL/N`, `j = 0..N−1`, semi-discretised by the Fourier
/// pseudospectral method (paper eq. (semi sd)): for `y = (p, q) ∈ R²ᴺ`,
///
/// ```text
/// y' = [[0, −D₂], [D₂, 0]] y + (−2(p² + q²)·q, 2(p² + q²)·p),
/// H  = ½ pᵀD₂p + ½ qᵀD₂q + ½ Σᵢ (pᵢ² + qᵢ²)²,
/// ```
///
/// i.e. `Q = [[0, −I], [I, 0]]`, `M = diag(D₂, D₂)`, `V = ½ Σ(pᵢ² + qᵢ²)²`, `A = QM`
/// (products `·` and powers are componentwise).
///
/// # The matrix `D₂`
///
/// The paper's entries
///
/// ```text
/// (D₂)_jk = ½ μ² (−1)^{j+k+1} / sin²(μ(x_j − x_k)/2)   (j ≠ k),
/// (D₂)_jj = −μ² (2(N/2)² + 1)/6,
/// ```
///
/// are (with `μ(x_j − x_k)/2 = π(j − k)/N`) exactly the Fourier pseudospectral second
/// derivative of Trefethen (*Spectral Methods in MATLAB*, 2000, eq. (3.12)) scaled from
/// `[0, 2π)` to `[0, L)`: checked in the tests against `F⁻¹ diag(λ) F` entrywise. The formula has
/// **no typo**. Its eigenvalues ([`d2_eigenvalues`](Nls::d2_eigenvalues)) are `−(μκ)²` for the
/// wavenumbers `κ = 0, ±1, …, ±(N/2 − 1)` and `−(μN/2)²` for the Nyquist mode `(−1)ʲ`
/// (second derivative of the symmetric band-limited interpolant, whose Nyquist term is
/// `cos(Nμx/2)`; not `0` as for `D₁²`). `D₂` is symmetric, circulant
/// (`(D₂)_jk = c[(j − k) mod N]`, [`d2_first_column`](Nls::d2_first_column)) and negative
/// semidefinite. `N` must be even.
#[derive(Clone, Debug, PartialEq)]
pub struct Nls {
    n: usize,
    /// First column of `D₂`, exactly symmetric: `c[N − j] == c[j]`.
    column: Vec<f64>,
    /// The FFT of [`energy`](Nls::energy), planned at its first use.
    spectral: EnergyFft,
}

/// The forward FFT of length N and its buffers for [`Nls::energy`]: planned on first use (a
/// problem that is only constructed, or whose energy is never asked for, plans nothing).
#[derive(Default)]
struct EnergyFft {
    fft: OnceLock<Arc<dyn Fft<f64>>>,
    /// ψ̂ and the FFT scratch; concurrent calls that find it busy use their own buffers.
    buffers: Mutex<(Vec<Complex64>, Vec<Complex64>)>,
}

impl Clone for EnergyFft {
    fn clone(&self) -> Self {
        EnergyFft {
            fft: self.fft.clone(),
            buffers: Mutex::default(),
        }
    }
}

impl fmt::Debug for EnergyFft {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("EnergyFft")
    }
}

/// The plan and buffers are derived from N, which [`Nls`] compares.
impl PartialEq for EnergyFft {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl Default for Nls {
    /// The paper's grid, `N = 128`.
    fn default() -> Self {
        Nls::new(128).expect("N = 128 is valid")
    }
}

impl Nls {
    /// The period `L = 4√2 π`.
    pub const LENGTH: f64 = 4.0 * SQRT_2 * PI;
    /// The wavenumber `μ = 2π/L = √2/4` (correctly rounded).
    pub const MU: f64 = SQRT_2 / 4.0;

    /// The semi-discrete problem on `n` grid points.
    ///
    /// # Errors
    ///
    /// [`Error::InvalidParameter`] if `n` is odd or zero (the paper's `D₂` formula is the
    /// even-`N` pseudospectral matrix), [`Error::InvalidInput`] if its `N` numbers cannot be
    /// allocated.
    pub fn new(n: usize) -> Result<Self> {
        if n == 0 || n % 2 != 0 {
            return Err(Error::InvalidParameter(format!(
                "NLS grid size N = {n} must be even and positive"
            )));
        }
        ensure_allocatable(&format!("the NLS grid of N = {n} points"), Some(n))?;
        let mu2 = Self::MU * Self::MU;
        let half = n / 2;
        let mut column = vec![0.0; n];
        column[0] = -mu2 * (2.0 * (half as f64).powi(2) + 1.0) / 6.0;
        for j in 1..=half {
            let s = (PI * j as f64 / n as f64).sin();
            let sign = if j % 2 == 0 { -1.0 } else { 1.0 }; // (−1)^{j+1}
            column[j] = 0.5 * mu2 * sign / (s * s);
            column[n - j] = column[j];
        }
        Ok(Nls {
            n,
            column,
            spectral: EnergyFft::default(),
        })
    }

    /// The number of grid points `N`.
    pub fn n(&self) -> usize {
        self.n
    }

    /// The dimension `2N` of `y = (p, q)`.
    pub fn dim(&self) -> usize {
        2 * self.n
    }

    /// The grid `x_j = jL/N`, `j = 0..N−1`.
    pub fn grid(&self) -> Vec<f64> {
        (0..self.n)
            .map(|j| j as f64 * Self::LENGTH / self.n as f64)
            .collect()
    }

    /// The first column `c` of the symmetric circulant `D₂`: `(D₂)_jk = c[(j − k) mod N]`,
    /// `c[0] = −μ²(2(N/2)² + 1)/6`, `c[j] = ½μ²(−1)^{j+1} / sin²(πj/N)`.
    pub fn d2_first_column(&self) -> Vec<f64> {
        self.column.clone()
    }

    /// The eigenvalues of `D₂` in FFT order: entry `κ` belongs to the Fourier mode
    /// `exp(iκμx_j)` and equals `−(μκ′)²` with `κ′ = κ` for `κ ≤ N/2`, `κ′ = κ − N` otherwise
    /// (the Nyquist entry `κ = N/2` is `−(μN/2)²`).
    pub fn d2_eigenvalues(&self) -> Vec<f64> {
        (0..self.n)
            .map(|k| {
                let kk = if k <= self.n / 2 {
                    k as f64
                } else {
                    k as f64 - self.n as f64
                };
                -(Self::MU * kk).powi(2)
            })
            .collect()
    }

    /// The dense `N × N` matrix `D₂`.
    pub fn d2_matrix(&self) -> DMatrix<f64> {
        let n = self.n;
        DMatrix::from_fn(n, n, |j, k| self.column[(j + n - k) % n])
    }

    /// `out = D₂ x` by the circulant structure, `O(N²)` without allocation (an FFT-based
    /// operator is the fast alternative: `D₂ = F⁻¹ diag(d2_eigenvalues) F`).
    ///
    /// # Panics
    ///
    /// If `x` or `out` does not have length `N`.
    pub fn apply_d2(&self, x: &[f64], out: &mut [f64]) {
        let n = self.n;
        check_len("x", x.len(), n);
        check_len("out", out.len(), n);
        for (j, o) in out.iter_mut().enumerate() {
            // c[(j − k) mod N] for k = 0..N−1: c[j], c[j−1], …, c[0], c[N−1], …, c[j+1].
            let (head, tail) = x.split_at(j + 1);
            let a: f64 = head
                .iter()
                .rev()
                .zip(&self.column)
                .map(|(x, c)| x * c)
                .sum();
            let b: f64 = tail
                .iter()
                .zip(self.column[j + 1..].iter().rev())
                .map(|(x, c)| x * c)
                .sum();
            *o = a + b;
        }
    }

    /// `pᵀD₂p + qᵀD₂q = (1/N) Σ_κ λ_κ |ψ̂_κ|²` for `ψ = p + iq`, `ψ̂` its DFT: one complex FFT,
    /// `O(N log N)`. (With `p̂`, `q̂` the DFTs of the real parts, `|ψ̂_κ|² = |p̂_κ|² + |q̂_κ|² +
    /// 2 Im(p̂_κ q̂_κ*)`; the cross terms cancel between `κ` and `N − κ`, since `λ_κ = λ_{N−κ}`
    /// and `p̂_{N−κ} = p̂_κ*`, and vanish at `κ = 0, N/2`.) Allocates only at the first call
    /// (the plan and an `N`-vector kept for later calls) and when called concurrently.
    fn d2_quadratic_forms(&self, p: &[f64], q: &[f64]) -> f64 {
        let n = self.n;
        let fft = self
            .spectral
            .fft
            .get_or_init(|| FftPlanner::new().plan_fft_forward(n));
        let mut own = Default::default();
        let mut guard = self.spectral.buffers.try_lock();
        let (psi, scratch): &mut (Vec<Complex64>, Vec<Complex64>) = match guard.as_deref_mut() {
            Ok(buffers) => buffers,
            Err(_) => &mut own,
        };
        psi.clear();
        psi.extend(p.iter().zip(q).map(|(&re, &im)| Complex64::new(re, im)));
        scratch.resize(fft.get_inplace_scratch_len(), Complex64::new(0.0, 0.0));
        fft.process_with_scratch(psi, scratch);
        let mu2 = Self::MU * Self::MU;
        let sum: f64 = psi
            .iter()
            .enumerate()
            .map(|(k, z)| {
                // λ_κ = −(μκ′)², κ′ = κ for κ ≤ N/2, κ − N otherwise (d2_eigenvalues).
                let kk = if k <= n / 2 { k } else { n - k } as f64;
                -mu2 * kk * kk * z.norm_sqr()
            })
            .sum();
        sum / n as f64
    }

    /// `Q = [[0, −I], [I, 0]]` (`2N × 2N`, skew-symmetric).
    pub fn q_matrix(&self) -> DMatrix<f64> {
        let n = self.n;
        DMatrix::from_fn(2 * n, 2 * n, |i, j| {
            if i < n && j == i + n {
                -1.0
            } else if i >= n && j + n == i {
                1.0
            } else {
                0.0
            }
        })
    }

    /// `M = diag(D₂, D₂)` (`2N × 2N`).
    pub fn m_matrix(&self) -> DMatrix<f64> {
        let n = self.n;
        DMatrix::from_fn(2 * n, 2 * n, |i, j| {
            if (i < n) == (j < n) {
                self.column[(i % n + n - j % n) % n]
            } else {
                0.0
            }
        })
    }

    /// `A = QM = [[0, −D₂], [D₂, 0]]` (`2N × 2N`).
    pub fn linear_matrix(&self) -> DMatrix<f64> {
        let n = self.n;
        DMatrix::from_fn(2 * n, 2 * n, |i, j| {
            let c = self.column[(i % n + n - j % n) % n];
            if i < n && j >= n {
                -c
            } else if i >= n && j < n {
                c
            } else {
                0.0
            }
        })
    }

    /// `g(y) = Q∇V(y) = (−2(p² + q²)·q, 2(p² + q²)·p)`.
    ///
    /// # Panics
    ///
    /// If `y` or `out` does not have length `2N`.
    pub fn nonlinear(&self, y: &[f64], out: &mut [f64]) {
        check_len("y", y.len(), 2 * self.n);
        check_len("out", out.len(), 2 * self.n);
        let (p, q) = y.split_at(self.n);
        let (op, oq) = out.split_at_mut(self.n);
        for j in 0..self.n {
            let rho = 2.0 * (p[j] * p[j] + q[j] * q[j]);
            op[j] = -rho * q[j];
            oq[j] = rho * p[j];
        }
    }

    /// `∇V(y) = (2(p² + q²)·p, 2(p² + q²)·q)`.
    ///
    /// # Panics
    ///
    /// If `y` or `out` does not have length `2N`.
    pub fn grad_v(&self, y: &[f64], out: &mut [f64]) {
        check_len("y", y.len(), 2 * self.n);
        check_len("out", out.len(), 2 * self.n);
        let (p, q) = y.split_at(self.n);
        let (op, oq) = out.split_at_mut(self.n);
        for j in 0..self.n {
            let rho = 2.0 * (p[j] * p[j] + q[j] * q[j]);
            op[j] = rho * p[j];
            oq[j] = rho * q[j];
        }
    }

    /// `V(y) = ½ Σᵢ (pᵢ² + qᵢ²)²`.
    ///
    /// # Panics
    ///
    /// If `y` does not have length `2N`.
    pub fn potential_v(&self, y: &[f64]) -> f64 {
        check_len("y", y.len(), 2 * self.n);
        let (p, q) = y.split_at(self.n);
        0.5 * p
            .iter()
            .zip(q)
            .map(|(p, q)| (p * p + q * q).powi(2))
            .sum::<f64>()
    }

    /// `H(y) = ½ pᵀD₂p + ½ qᵀD₂q + ½ Σᵢ (pᵢ² + qᵢ²)²`, the quadratic part in the Fourier
    /// basis: `½ (1/N) Σ_κ λ_κ |ψ̂_κ|²` with `ψ̂` the DFT of `ψ = p + iq` (one FFT, `O(N log N)`;
    /// the first call plans the FFT and allocates its buffers, later calls reuse them).
    ///
    /// # Panics
    ///
    /// If `y` does not have length `2N`.
    pub fn energy(&self, y: &[f64]) -> f64 {
        check_len("y", y.len(), 2 * self.n);
        let (p, q) = y.split_at(self.n);
        0.5 * self.d2_quadratic_forms(p, q) + self.potential_v(y)
    }

    /// The paper's initial value: `p_j = 0.5 + 0.025 cos(μx_j)`, `q_j = 0`.
    pub fn initial_value(&self) -> Vec<f64> {
        let mut y = vec![0.0; 2 * self.n];
        for (j, p) in y[..self.n].iter_mut().enumerate() {
            *p = 0.5 + 0.025 * (2.0 * PI * j as f64 / self.n as f64).cos(); // μx_j = 2πj/N
        }
        y
    }

    /// An exact solution of the semi-discrete system: the plane wave
    /// `ψ_j(t) = a exp(i(κμx_j + (2a² + λ_κ)t))`, `λ_κ = −(μκ)²` the eigenvalue of `D₂`
    /// (`|κ| ≤ N/2`), returned as `y = (Re ψ, Im ψ)`. (`D₂` maps the mode to `λ_κ` times itself
    /// and `|ψ_j|² = a²`, so `iψ′ + D₂ψ + 2|ψ|²ψ = 0` holds exactly.)
    ///
    /// # Errors
    ///
    /// [`Error::NonFinite`] for NaN or infinite `amplitude` or `t`; [`Error::InvalidParameter`]
    /// if `|wavenumber| > N/2`.
    pub fn plane_wave(&self, amplitude: f64, wavenumber: i64, t: f64) -> Result<Vec<f64>> {
        if !amplitude.is_finite() {
            return Err(Error::NonFinite("plane-wave amplitude"));
        }
        if !t.is_finite() {
            return Err(Error::NonFinite("time t"));
        }
        let n = self.n as i64;
        if wavenumber.unsigned_abs() > (n / 2) as u64 {
            return Err(Error::InvalidParameter(format!(
                "plane-wave wavenumber {wavenumber} exceeds N/2 = {}",
                n / 2
            )));
        }
        let kappa = wavenumber.rem_euclid(n);
        let lambda = self.d2_eigenvalues()[kappa as usize];
        let freq = 2.0 * amplitude * amplitude + lambda;
        let mut y = vec![0.0; 2 * self.n];
        for j in 0..self.n {
            // κμx_j = 2π(κj mod N)/N, reduced exactly in integers.
            let space = 2.0 * PI * ((kappa * j as i64) % n) as f64 / n as f64;
            let (s, c) = (space + freq * t).sin_cos();
            y[j] = amplitude * c;
            y[self.n + j] = amplitude * s;
        }
        Ok(y)
    }
}

forward_test_problem!(Nls);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problems::testutil::{Rng, check_structure};
    use nalgebra::DVector;

    #[test]
    fn constructor_validates() {
        for n in [0, 1, 3, 127] {
            assert!(
                matches!(Nls::new(n), Err(Error::InvalidParameter(_))),
                "N = {n}"
            );
        }
        assert_eq!(Nls::default().n(), 128);
        assert_eq!(Nls::default().dim(), 256);
        assert!((Nls::MU - 2.0 * PI / Nls::LENGTH).abs() <= 1e-16);
        let grid = Nls::new(8).unwrap().grid();
        assert_eq!(grid[0], 0.0);
        assert!((grid[4] - Nls::LENGTH / 2.0).abs() <= 1e-15);
    }

    #[test]
    fn d2_is_symmetric_and_circulant() {
        for n in [2, 4, 16, 128] {
            let nls = Nls::new(n).unwrap();
            let d2 = nls.d2_matrix();
            let c = nls.d2_first_column();
            assert_eq!(d2, d2.transpose(), "N = {n}: D₂ must be exactly symmetric");
            for j in 0..n {
                for k in 0..n {
                    assert_eq!(d2[(j, k)], c[(j + n - k) % n]);
                    assert_eq!(d2[(j, k)], d2[((j + 1) % n, (k + 1) % n)]);
                }
            }
            // The paper's off-diagonal formula with x_j − x_k, as printed.
            let mu = Nls::MU;
            let x = nls.grid();
            for j in 0..n {
                for k in 0..n {
                    let paper = if j == k {
                        -mu * mu * (2.0 * ((n / 2) as f64).powi(2) + 1.0) / 6.0
                    } else {
                        let s = (mu * (x[j] - x[k]) / 2.0).sin();
                        let sign = if (j + k + 1) % 2 == 0 { 1.0 } else { -1.0 };
                        0.5 * mu * mu * sign / (s * s)
                    };
                    assert!(
                        (d2[(j, k)] - paper).abs() <= 1e-13 * paper.abs(),
                        "({j},{k})"
                    );
                }
            }
        }
    }

    /// D₂ applied to the Fourier modes cos(κμx_j), sin(κμx_j) gives λ_κ times the mode, with
    /// λ_κ = −(μκ)² for κ < N/2 and −(μN/2)² for the Nyquist mode (−1)ʲ. Round-off: N terms of
    /// size ≤ max|c| ≈ μ²N²/12: tolerance 4Nε·max|c|.
    #[test]
    fn d2_has_the_pseudospectral_symbol() {
        for n in [2, 4, 16, 128] {
            let nls = Nls::new(n).unwrap();
            let d2 = nls.d2_matrix();
            let lambda = nls.d2_eigenvalues();
            let cmax = nls
                .d2_first_column()
                .iter()
                .fold(0.0f64, |m, c| m.max(c.abs()));
            let tol = 4.0 * n as f64 * f64::EPSILON * cmax;
            for kappa in 0..=n / 2 {
                let expected = -(Nls::MU * kappa as f64).powi(2);
                assert_eq!(lambda[kappa], expected);
                if kappa > 0 {
                    assert_eq!(lambda[n - kappa], expected);
                }
                let phase = |j: usize| 2.0 * PI * ((kappa * j) % n) as f64 / n as f64;
                let cos = DVector::from_fn(n, |j, _| phase(j).cos());
                let sin = DVector::from_fn(n, |j, _| phase(j).sin());
                let r1 = (&d2 * &cos - &cos * expected).amax();
                let r2 = (&d2 * &sin - &sin * expected).amax();
                assert!(
                    r1 <= tol && r2 <= tol,
                    "N={n} κ={kappa}: {r1:e} {r2:e} (tol {tol:e})"
                );
                // The same through the allocation-free product.
                let mut out = vec![0.0; n];
                nls.apply_d2(cos.as_slice(), &mut out);
                let r3 = (DVector::from_vec(out) - &cos * expected).amax();
                assert!(r3 <= tol, "apply_d2: N={n} κ={kappa}: {r3:e}");
            }
            // The eigenvalues of a symmetric circulant are the cosine transform of its column.
            let c = nls.d2_first_column();
            for (kappa, l) in lambda.iter().enumerate() {
                let sym: f64 = (0..n)
                    .map(|j| c[j] * (2.0 * PI * ((j * kappa) % n) as f64 / n as f64).cos())
                    .sum();
                assert!((sym - l).abs() <= tol, "N={n} κ={kappa}: {sym} vs {l}");
            }
        }
    }

    /// The paper's formula equals the spectral construction F⁻¹ diag(λ) F entrywise:
    /// (D₂)_jk = (1/N) Σ_κ λ_κ cos(2πκ(j − k)/N). This is the check that the formula (signs,
    /// factor ½, diagonal) has no typo.
    #[test]
    fn d2_equals_the_spectral_construction() {
        for n in [2, 4, 6, 16, 128] {
            let nls = Nls::new(n).unwrap();
            let c = nls.d2_first_column();
            let lambda = nls.d2_eigenvalues();
            let lmax = lambda.iter().fold(0.0f64, |m, l| m.max(l.abs()));
            for (j, cj) in c.iter().enumerate() {
                let spectral: f64 = lambda
                    .iter()
                    .enumerate()
                    .map(|(k, l)| l * (2.0 * PI * ((k * j) % n) as f64 / n as f64).cos())
                    .sum::<f64>()
                    / n as f64;
                let tol = 4.0 * f64::EPSILON * lmax;
                assert!(
                    (cj - spectral).abs() <= tol,
                    "N={n} j={j}: {cj} vs {spectral}"
                );
            }
            // Consequently D₂ is negative semidefinite with trace N·c[0] = Σλ.
            let trace: f64 = lambda.iter().sum();
            assert!((n as f64 * c[0] - trace).abs() <= 1e-13 * trace.abs().max(1.0));
        }
    }

    #[test]
    fn structure() {
        let mut rng = Rng(31);
        for n in [4, 16, 128] {
            let nls = Nls::new(n).unwrap();
            let mut ys: Vec<Vec<f64>> = (0..3)
                .map(|_| (0..2 * n).map(|_| rng.sym(1.0)).collect())
                .collect();
            ys.push(nls.initial_value());
            check_structure(&nls, &ys, true);
        }
    }

    /// H against the paper's formula evaluated with the dense D₂ (relative 1e-13).
    #[test]
    fn energy_matches_the_direct_formula() {
        let mut rng = Rng(32);
        let nls = Nls::default();
        let n = nls.n();
        let d2 = nls.d2_matrix();
        for _ in 0..5 {
            let y: Vec<f64> = (0..2 * n).map(|_| rng.sym(1.0)).collect();
            let p = DVector::from_column_slice(&y[..n]);
            let q = DVector::from_column_slice(&y[n..]);
            let quartic: f64 = (0..n).map(|i| (p[i] * p[i] + q[i] * q[i]).powi(2)).sum();
            let direct = 0.5 * p.dot(&(&d2 * &p)) + 0.5 * q.dot(&(&d2 * &q)) + 0.5 * quartic;
            let h = nls.energy(&y);
            let size = 0.5
                * (p.abs().dot(&(d2.abs() * p.abs())) + q.abs().dot(&(d2.abs() * q.abs())))
                + 0.5 * quartic;
            assert!((h - direct).abs() <= 1e-13 * size, "{h} vs {direct}");
        }
        // At y(0): p = 0.5 + 0.025 cos(μx) is the κ = 0 and κ = 1 modes, so
        // ½pᵀD₂p = ½·(−μ²)·0.025²·N/2 and V = ½ Σ p_j⁴.
        // D₂·1 = 0 only up to round-off (row sums of entries up to |c₀| ≈ 170 cancel), so the
        // tolerance is 4Nε times the sum of magnitudes ½|p|ᵀ|D₂||p| + V.
        let y0 = nls.initial_value();
        let quartic: f64 = y0[..n].iter().map(|p| p.powi(4)).sum();
        let expected =
            0.5 * (-Nls::MU * Nls::MU) * 0.025 * 0.025 * (n as f64 / 2.0) + 0.5 * quartic;
        let p0 = DVector::from_column_slice(&y0[..n]);
        let size = 0.5 * p0.abs().dot(&(d2.abs() * p0.abs())) + 0.5 * quartic;
        let err = (nls.energy(&y0) - expected).abs();
        assert!(
            err <= 4.0 * n as f64 * f64::EPSILON * size,
            "H(y0) error {err:e}"
        );
    }

    /// `xᵀD₂x` by the `O(N²)` circulant product [`Nls::apply_d2`]: the reference for the FFT
    /// form of [`Nls::energy`].
    fn dense_quadratic_form(nls: &Nls, x: &[f64]) -> f64 {
        let mut d2x = vec![0.0; x.len()];
        nls.apply_d2(x, &mut d2x);
        x.iter().zip(&d2x).map(|(a, b)| a * b).sum()
    }

    /// The FFT form of `pᵀD₂p + qᵀD₂q` equals the dense one for even N (powers of two and
    /// not) on random states and y(0): to 1e-14 of the magnitude sum `|p|ᵀ|D₂||p| +
    /// |q|ᵀ|D₂||q|` (observed: below 1e-15). On plane waves, whose value `λ_κ a² N` is known,
    /// the FFT form is within 1e-14 relative; the dense one rounds more (observed 1.6e-14 at
    /// the Nyquist mode for N = 1024, where all N² terms have one sign), within Nε.
    #[test]
    fn fft_energy_equals_the_dense_quadratic_form() {
        let mut rng = Rng(33);
        for n in [2, 4, 6, 10, 16, 30, 128, 254, 1024] {
            let nls = Nls::new(n).unwrap();
            let d2 = nls.d2_matrix().abs();
            let mut states: Vec<Vec<f64>> = (0..4)
                .map(|_| (0..2 * n).map(|_| rng.sym(1.0)).collect())
                .collect();
            states.push(nls.initial_value());
            let magnitude = |p: &[f64], q: &[f64]| {
                let pa = DVector::from_iterator(n, p.iter().map(|v| v.abs()));
                let qa = DVector::from_iterator(n, q.iter().map(|v| v.abs()));
                pa.dot(&(&d2 * &pa)) + qa.dot(&(&d2 * &qa))
            };
            for y in &states {
                let (p, q) = y.split_at(n);
                let dense = dense_quadratic_form(&nls, p) + dense_quadratic_form(&nls, q);
                let fft = nls.d2_quadratic_forms(p, q);
                let size = magnitude(p, q);
                assert!(
                    (fft - dense).abs() <= 1e-14 * size,
                    "N = {n}: FFT {fft:e}, dense {dense:e}, relative difference {:e}",
                    (fft - dense).abs() / size
                );
                let h = nls.energy(y);
                let direct = 0.5 * dense + nls.potential_v(y);
                assert!((h - direct).abs() <= 1e-14 * (size + direct.abs()));
            }
            let amp = 0.7;
            for kappa in [0, 1, n as i64 / 2 - 1, n as i64 / 2] {
                let y = nls.plane_wave(amp, kappa, 0.3).unwrap();
                let (p, q) = y.split_at(n);
                let exact = -(Nls::MU * kappa as f64).powi(2) * amp * amp * n as f64;
                let size = magnitude(p, q);
                let fft = nls.d2_quadratic_forms(p, q);
                assert!(
                    (fft - exact).abs() <= 1e-14 * size,
                    "N = {n} κ = {kappa}: {fft:e}"
                );
                let dense = dense_quadratic_form(&nls, p) + dense_quadratic_form(&nls, q);
                let tol = n as f64 * f64::EPSILON * size;
                assert!(
                    (dense - exact).abs() <= tol,
                    "N = {n} κ = {kappa}: {dense:e}"
                );
            }
            // A clone plans its own FFT; both give the same bits.
            let copy = nls.clone();
            assert_eq!(copy, nls);
            assert_eq!(copy.energy(&states[0]), nls.energy(&states[0]));
        }
    }

    /// The quadratic part `H − V` of a plane wave is `½λ_κa²N`: within 4e-15 of
    /// `½(|λ_κ| + μ²)a²N` (plus the rounding of `H − V`, 4ε·V) for large N and every kind of
    /// mode. (The former `O(N²)` sum in the grid basis was off by 6e-8 for the constant mode
    /// at N = 4096, where row sums of entries up to μ²N²/12 cancel to 0.)
    #[test]
    fn energy_of_plane_waves_is_exact() {
        let n = 4096;
        let nls = Nls::new(n).unwrap();
        let amp = 0.7;
        for kappa in [0, 1, 7, n as i64 / 2 - 1, n as i64 / 2, -(n as i64) / 2] {
            let y = nls.plane_wave(amp, kappa, 0.3).unwrap();
            let lambda = -(Nls::MU * kappa as f64).powi(2);
            let exact = 0.5 * lambda * amp * amp * n as f64;
            let scale = 0.5 * (lambda.abs() + Nls::MU * Nls::MU) * amp * amp * n as f64;
            let v = nls.potential_v(&y);
            let err = (nls.energy(&y) - v - exact).abs();
            let tol = 4e-15 * scale + 4.0 * f64::EPSILON * v;
            assert!(err <= tol, "κ = {kappa}: error {err:e}, tolerance {tol:e}");
        }
    }

    #[test]
    fn initial_value_is_the_papers() {
        let nls = Nls::default();
        let y0 = nls.initial_value();
        let x = nls.grid();
        for j in 0..nls.n() {
            // μx_j ≤ 2π carries ≈ 4ε·2π of rounding: 0.025·5.6e-15 ≈ 1.4e-16.
            assert!((y0[j] - (0.5 + 0.025 * (Nls::MU * x[j]).cos())).abs() <= 4e-16);
            assert_eq!(y0[nls.n() + j], 0.0);
        }
    }

    /// The plane wave is an exact solution: its time derivative (analytic, i·freq·ψ) equals the
    /// vector field A y + g(y) (relative 1e-13 of |λ| a), and it conserves H exactly.
    #[test]
    fn plane_wave_solves_the_semi_discrete_system() {
        let nls = Nls::new(32).unwrap();
        let n = nls.n();
        let a_mat = nls.linear_matrix();
        for (amp, kappa) in [
            (0.5, 0i64),
            (0.7, 1),
            (0.3, -3),
            (1.1, 15),
            (0.4, 16),
            (0.4, -16),
        ] {
            let kk = kappa.rem_euclid(n as i64) as usize;
            let freq = 2.0 * amp * amp + nls.d2_eigenvalues()[kk];
            let h0 = nls.energy(&nls.plane_wave(amp, kappa, 0.0).unwrap());
            for t in [0.0, 0.3, 17.0] {
                let y = nls.plane_wave(amp, kappa, t).unwrap();
                let mut g = vec![0.0; 2 * n];
                nls.nonlinear(&y, &mut g);
                let f = &a_mat * DVector::from_column_slice(&y) + DVector::from_vec(g);
                let scale = amp * (freq.abs() + 2.0 * amp * amp + (Nls::MU * 16.0).powi(2));
                for j in 0..n {
                    // d/dt (a cos θ, a sin θ) = freq·(−a sin θ, a cos θ)
                    assert!((f[j] + freq * y[n + j]).abs() <= 1e-13 * scale);
                    assert!((f[n + j] - freq * y[j]).abs() <= 1e-13 * scale);
                }
                assert!((nls.energy(&y) - h0).abs() <= 1e-13 * scale * n as f64);
            }
        }
        assert!(matches!(
            nls.plane_wave(1.0, 17, 0.0),
            Err(Error::InvalidParameter(_))
        ));
        assert!(matches!(
            nls.plane_wave(f64::NAN, 1, 0.0),
            Err(Error::NonFinite(_))
        ));
    }
}
