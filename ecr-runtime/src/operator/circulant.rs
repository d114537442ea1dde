//! Circulant operators (periodic convolutions, Fourier pseudospectral derivatives), by FFT.

use std::fmt;
use std::sync::{Arc, Mutex};

use num_complex::Complex64;
use rustfft::{Fft, FftPlanner};

use super::entries::NodeFunctions;
use super::spectral::{
    SkewGenerator, SpectralBank, SpectralBasis, SpectralWorkspace, spectral_apply, sum_dd,
};
use super::traits::LinearOperator;
use crate::error::{Error, Result};

/// Relative asymmetry of the first column tolerated by [`SkewGenerator::real_spectrum`].
const SYMMETRY_TOL: f64 = 1e-12;

/// The discrete Fourier basis of length n: `û = F u` (forward FFT), `u = F⁻¹ û` (inverse FFT
/// divided by n). Circulant matrices are diagonal in it.
#[derive(Clone)]
pub struct FourierBasis {
    n: usize,
    fwd: Arc<dyn Fft<f64>>,
    inv: Arc<dyn Fft<f64>>,
}

impl fmt::Debug for FourierBasis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("FourierBasis").field("n", &self.n).finish()
    }
}

impl FourierBasis {
    fn new(n: usize) -> Self {
        let mut planner = FftPlanner::new();
        FourierBasis {
            n,
            fwd: planner.plan_fft_forward(n),
            inv: planner.plan_fft_inverse(n),
        }
    }

    fn scratch_len(&self) -> usize {
        self.fwd
            .get_inplace_scratch_len()
            .max(self.inv.get_inplace_scratch_len())
    }
}

impl SpectralBasis for FourierBasis {
    /// FFT scratch.
    type Scratch = Vec<Complex64>;

    fn dim(&self) -> usize {
        self.n
    }

    fn scratch_bytes(&self) -> usize {
        16 * self.scratch_len()
    }

    fn scratch(&self) -> Vec<Complex64> {
        vec![Complex64::new(0.0, 0.0); self.scratch_len()]
    }

    fn forward(&self, u: &mut [Complex64], s: &mut Vec<Complex64>) {
        self.fwd.process_with_scratch(u, s);
    }

    fn inverse(&self, u: &mut [Complex64], s: &mut Vec<Complex64>) {
        self.inv.process_with_scratch(u, s);
        let scale = 1.0 / self.n as f64;
        for v in u.iter_mut() {
            *v = v.scale(scale);
        }
    }
}

/// The circulant matrix with first column `c`: `C_{jk} = c[(j − k) mod n]`, i.e. `C x = c ⊛ x`
/// (periodic convolution). Its eigenvalues are `λ = F c` (DFT), with the Fourier vectors as
/// eigenvectors, so `φ_k(τhC) = F⁻¹ diag(φ_k(τhλ)) F`: banks store `φ_k(τ_i h λ_m)` per mode and
/// `combine` costs one FFT per input vector and one inverse FFT per output block.
pub struct Circulant {
    c: Vec<f64>,
    lambda: Vec<Complex64>,
    basis: FourierBasis,
    /// Buffers for [`LinearOperator::apply`], which has no workspace argument.
    apply_scratch: Mutex<(Vec<Complex64>, Vec<Complex64>)>,
}

impl fmt::Debug for Circulant {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Circulant").field("c", &self.c).finish()
    }
}

impl Clone for Circulant {
    fn clone(&self) -> Self {
        Circulant {
            c: self.c.clone(),
            lambda: self.lambda.clone(),
            basis: self.basis.clone(),
            apply_scratch: Mutex::new(self.new_apply_scratch()),
        }
    }
}

impl Circulant {
    /// The circulant matrix with first column `c` (`n = c.len() ≥ 1`).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] if `c` is empty, [`Error::NonFinite`] if an entry is NaN/∞.
    pub fn new(c: Vec<f64>) -> Result<Self> {
        if c.is_empty() {
            return Err(Error::InvalidInput(
                "circulant operator needs a first column of length >= 1".into(),
            ));
        }
        if c.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("circulant first column"));
        }
        let basis = FourierBasis::new(c.len());
        let mut lambda: Vec<Complex64> = c.iter().map(|&v| Complex64::new(v, 0.0)).collect();
        let mut scratch = basis.scratch();
        basis.forward(&mut lambda, &mut scratch);
        lambda[0] = Complex64::new(sum_dd(&c), 0.0);
        let mut op = Circulant {
            c,
            lambda,
            basis,
            apply_scratch: Mutex::new((Vec::new(), Vec::new())),
        };
        op.apply_scratch = Mutex::new(op.new_apply_scratch());
        Ok(op)
    }

    fn new_apply_scratch(&self) -> (Vec<Complex64>, Vec<Complex64>) {
        (
            vec![Complex64::new(0.0, 0.0); self.c.len()],
            self.basis.scratch(),
        )
    }

    /// The first column `c`.
    pub fn first_column(&self) -> &[f64] {
        &self.c
    }

    /// The eigenvalues `λ_m = Σ_j c_j e^{−2πi jm/n}` (the DFT of `c`).
    pub fn eigenvalues(&self) -> &[Complex64] {
        &self.lambda
    }

    /// `true` if `c[j] = c[(n − j) mod n]` to a relative `1e−12` (then C is symmetric and
    /// its eigenvalues are real).
    pub fn is_symmetric(&self) -> bool {
        let n = self.c.len();
        let scale = self.c.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        (1..n).all(|j| (self.c[j] - self.c[n - j]).abs() <= SYMMETRY_TOL * scale)
    }
}

/// φ-bank of [`Circulant`].
pub type CirculantBank = SpectralBank<FourierBasis>;
/// Scratch of [`CirculantBank`].
pub type CirculantWorkspace = SpectralWorkspace<Vec<Complex64>>;

impl LinearOperator for Circulant {
    type Bank = CirculantBank;

    fn dim(&self) -> usize {
        self.c.len()
    }

    fn bank_bytes(&self, len: usize, n: usize) -> Option<(usize, usize)> {
        super::spectral::spectral_bank_bytes(&self.basis, len, n)
    }

    /// `y = c ⊛ x` by FFT (O(n log n)); uses internal buffers behind a mutex, so concurrent
    /// calls on one operator serialise.
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        spectral_apply(&self.basis, &self.lambda, &self.apply_scratch, x, y);
    }

    fn phi_bank(&self, h: f64, taus: &[f64], p: usize) -> Result<CirculantBank> {
        SpectralBank::build(&self.basis, &self.lambda, h, taus, p, NodeFunctions::phi())
    }

    fn kernel_bank(&self, h: f64, taus: &[f64], n: usize) -> Result<CirculantBank> {
        let f = NodeFunctions::legendre(taus, n);
        SpectralBank::build(&self.basis, &self.lambda, h, taus, n, f)
    }
}

impl SkewGenerator for Circulant {
    type Basis = FourierBasis;

    /// The real eigenvalues `Re(F c)` of a symmetric circulant, with the symmetry of its
    /// spectrum exact: `λ_k = λ_{n−k}` (mathematically equal; the FFT rounds the two apart, by
    /// up to 256 ulps of the small ones for the NLS's D₂ at n = 128) is set to the mean of the
    /// two computed values. So the two modes of a wave number evolve alike, and the banks
    /// evaluate their functions once for both (once per distinct eigenvalue).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] if `c[j] ≠ c[(n − j) mod n]` beyond a relative `1e−12`.
    fn real_spectrum(&self) -> Result<(Vec<f64>, FourierBasis)> {
        if !self.is_symmetric() {
            return Err(Error::InvalidInput(
                "circulant generator of a skew pair must be symmetric: c[j] = c[n - j]".into(),
            ));
        }
        let n = self.lambda.len();
        let mut re: Vec<f64> = self.lambda.iter().map(|l| l.re).collect();
        for k in 1..n.div_ceil(2) {
            let mean = 0.5 * (re[k] + re[n - k]);
            (re[k], re[n - k]) = (mean, mean);
        }
        Ok((re, self.basis.clone()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn real_spectrum_is_exactly_symmetric() {
        // The pseudospectral second derivative's shape: c_j = c_{n−j}, in no particular scale.
        for n in [7, 64, 128] {
            let c: Vec<f64> = (0..n)
                .map(|j: usize| {
                    let m = j.min(n - j) as f64;
                    if j == 0 { -3.3 } else { 1.0 / (1.0 + m * m) }
                })
                .collect();
            let (re, _) = Circulant::new(c.clone()).unwrap().real_spectrum().unwrap();
            for k in 1..n {
                assert_eq!(re[k].to_bits(), re[n - k].to_bits(), "n = {n}, k = {k}");
            }
            // Still the eigenvalues: within the FFT's rounding of Re(F c).
            let plain: Vec<f64> = Circulant::new(c)
                .unwrap()
                .lambda
                .iter()
                .map(|l| l.re)
                .collect();
            let scale = plain.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for (a, b) in re.iter().zip(&plain) {
                assert!((a - b).abs() <= 64.0 * f64::EPSILON * scale);
            }
        }
    }
}
