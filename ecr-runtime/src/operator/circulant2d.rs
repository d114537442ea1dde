//! Doubly periodic convolutions on an `nx × ny` grid (block-circulant matrices with circulant
//! blocks), by the 2D FFT: 1D transforms along the rows, then along the columns.

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

/// Columns gathered per batch for the transforms along the first grid index (cache blocking).
const COLUMN_BATCH: usize = 16;

/// The 2D discrete Fourier basis on an `nx × ny` grid stored row-major (entry `(ix, iy)` at
/// `ix·ny + iy`): `û = (F_nx ⊗ F_ny) u` (forward), `u = (F_nx ⊗ F_ny)⁻¹ û` (inverse, divided by
/// `nx·ny`). Block-circulant matrices with circulant blocks are diagonal in it.
#[derive(Clone)]
pub struct Fourier2dBasis {
    nx: usize,
    ny: usize,
    row_fwd: Arc<dyn Fft<f64>>,
    row_inv: Arc<dyn Fft<f64>>,
    col_fwd: Arc<dyn Fft<f64>>,
    col_inv: Arc<dyn Fft<f64>>,
}

impl fmt::Debug for Fourier2dBasis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Fourier2dBasis")
            .field("nx", &self.nx)
            .field("ny", &self.ny)
            .finish()
    }
}

/// Scratch of [`Fourier2dBasis`]: a batch of gathered columns and the FFT scratch.
#[derive(Debug, Clone)]
pub struct Fourier2dScratch {
    cols: Vec<Complex64>,
    fft: Vec<Complex64>,
}

impl Fourier2dBasis {
    fn new(nx: usize, ny: usize) -> Self {
        let mut planner = FftPlanner::new();
        Fourier2dBasis {
            nx,
            ny,
            row_fwd: planner.plan_fft_forward(ny),
            row_inv: planner.plan_fft_inverse(ny),
            col_fwd: planner.plan_fft_forward(nx),
            col_inv: planner.plan_fft_inverse(nx),
        }
    }

    /// The grid shape `(nx, ny)`.
    pub fn shape(&self) -> (usize, usize) {
        (self.nx, self.ny)
    }

    /// Transforms every row (contiguous, length ny), then every column (stride ny, length nx)
    /// in batches of [`COLUMN_BATCH`] gathered into contiguous scratch.
    fn transform(
        &self,
        u: &mut [Complex64],
        s: &mut Fourier2dScratch,
        rows: &dyn Fft<f64>,
        cols: &dyn Fft<f64>,
    ) {
        let (nx, ny) = (self.nx, self.ny);
        debug_assert_eq!(u.len(), nx * ny);
        rows.process_with_scratch(u, &mut s.fft);
        let mut start = 0;
        while start < ny {
            let b = COLUMN_BATCH.min(ny - start);
            let batch = &mut s.cols[..b * nx];
            for (ix, row) in u.chunks_exact(ny).enumerate() {
                for (j, v) in row[start..start + b].iter().enumerate() {
                    batch[j * nx + ix] = *v;
                }
            }
            cols.process_with_scratch(batch, &mut s.fft);
            for (ix, row) in u.chunks_exact_mut(ny).enumerate() {
                for (j, v) in row[start..start + b].iter_mut().enumerate() {
                    *v = batch[j * nx + ix];
                }
            }
            start += b;
        }
    }
}

impl SpectralBasis for Fourier2dBasis {
    type Scratch = Fourier2dScratch;

    fn dim(&self) -> usize {
        self.nx * self.ny
    }

    fn scratch_bytes(&self) -> usize {
        let fft_len = [&self.row_fwd, &self.row_inv, &self.col_fwd, &self.col_inv]
            .iter()
            .map(|f| f.get_inplace_scratch_len())
            .max()
            .unwrap_or(0);
        16 * (COLUMN_BATCH.min(self.ny) * self.nx + fft_len)
    }

    fn scratch(&self) -> Fourier2dScratch {
        let fft_len = [&self.row_fwd, &self.row_inv, &self.col_fwd, &self.col_inv]
            .iter()
            .map(|f| f.get_inplace_scratch_len())
            .max()
            .unwrap_or(0);
        Fourier2dScratch {
            cols: vec![Complex64::new(0.0, 0.0); COLUMN_BATCH.min(self.ny) * self.nx],
            fft: vec![Complex64::new(0.0, 0.0); fft_len],
        }
    }

    fn forward(&self, u: &mut [Complex64], s: &mut Fourier2dScratch) {
        self.transform(u, s, &*self.row_fwd, &*self.col_fwd);
    }

    fn inverse(&self, u: &mut [Complex64], s: &mut Fourier2dScratch) {
        self.transform(u, s, &*self.row_inv, &*self.col_inv);
        let scale = 1.0 / (self.nx * self.ny) as f64;
        for v in u.iter_mut() {
            *v = v.scale(scale);
        }
    }
}

/// The doubly periodic convolution on an `nx × ny` grid (row-major, entry `(ix, iy)` at
/// `ix·ny + iy`) with kernel `c`:
///
/// ```text
/// (C x)(ix, iy) = Σ_{jx, jy} c((ix − jx) mod nx, (iy − jy) mod ny) · x(jx, jy),
/// ```
///
/// a block-circulant matrix with circulant `ny × ny` blocks whose first column is `c`. Its
/// eigenvalues are the 2D DFT of `c`; `φ_k(τhC) = F₂⁻¹ diag(φ_k(τhλ)) F₂`, so banks store
/// `φ_k(τ_i h λ_m)` per mode and `combine` costs one 2D FFT per input vector and one inverse
/// per output block, O(d log d). The spectral Laplacian on a periodic grid is
/// [`kron_sum`](Circulant2d::kron_sum) of two 1D second-derivative columns.
pub struct Circulant2d {
    nx: usize,
    ny: usize,
    c: Vec<f64>,
    lambda: Vec<Complex64>,
    basis: Fourier2dBasis,
    /// Buffers for [`LinearOperator::apply`], which has no workspace argument.
    apply_scratch: Mutex<(Vec<Complex64>, Fourier2dScratch)>,
}

impl fmt::Debug for Circulant2d {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Circulant2d")
            .field("nx", &self.nx)
            .field("ny", &self.ny)
            .finish()
    }
}

impl Clone for Circulant2d {
    fn clone(&self) -> Self {
        Circulant2d {
            nx: self.nx,
            ny: self.ny,
            c: self.c.clone(),
            lambda: self.lambda.clone(),
            basis: self.basis.clone(),
            apply_scratch: Mutex::new(self.new_apply_scratch()),
        }
    }
}

impl Circulant2d {
    /// The 2D circulant with kernel (first column) `c` of length `nx·ny`, row-major.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] if `nx` or `ny` is zero, [`Error::DimensionMismatch`] if
    /// `c.len() ≠ nx·ny`, [`Error::NonFinite`] if an entry is NaN/∞.
    pub fn new(nx: usize, ny: usize, c: Vec<f64>) -> Result<Self> {
        if nx == 0 || ny == 0 {
            return Err(Error::InvalidInput(
                "2D circulant operator needs a grid of at least 1 x 1".into(),
            ));
        }
        if c.len() != nx * ny {
            return Err(Error::DimensionMismatch {
                what: "2D circulant kernel (nx * ny)",
                expected: nx * ny,
                found: c.len(),
            });
        }
        if c.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("2D circulant kernel"));
        }
        let basis = Fourier2dBasis::new(nx, ny);
        let mut lambda: Vec<Complex64> = c.iter().map(|&v| Complex64::new(v, 0.0)).collect();
        let mut scratch = basis.scratch();
        basis.forward(&mut lambda, &mut scratch);
        lambda[0] = Complex64::new(sum_dd(&c), 0.0);
        let mut op = Circulant2d {
            nx,
            ny,
            c,
            lambda,
            basis,
            apply_scratch: Mutex::new((Vec::new(), scratch)),
        };
        op.apply_scratch = Mutex::new(op.new_apply_scratch());
        Ok(op)
    }

    /// `Cx ⊗ I + I ⊗ Cy` for the 1D circulants with first columns `cx` (length nx, along the
    /// first index) and `cy` (length ny): e.g. the spectral Laplacian `D₂ₓ ⊗ I + I ⊗ D₂ᵧ`.
    ///
    /// # Errors
    /// As [`Circulant2d::new`].
    pub fn kron_sum(cx: &[f64], cy: &[f64]) -> Result<Self> {
        let (nx, ny) = (cx.len(), cy.len());
        let mut c = vec![0.0; nx * ny];
        if nx > 0 && ny > 0 {
            for (ix, v) in cx.iter().enumerate() {
                c[ix * ny] += v;
            }
            for (iy, v) in cy.iter().enumerate() {
                c[iy] += v;
            }
        }
        Self::new(nx, ny, c)
    }

    fn new_apply_scratch(&self) -> (Vec<Complex64>, Fourier2dScratch) {
        (
            vec![Complex64::new(0.0, 0.0); self.nx * self.ny],
            self.basis.scratch(),
        )
    }

    /// The grid shape `(nx, ny)`.
    pub fn shape(&self) -> (usize, usize) {
        (self.nx, self.ny)
    }

    /// The kernel (first column) `c`, row-major.
    pub fn first_column(&self) -> &[f64] {
        &self.c
    }

    /// The eigenvalues (the 2D DFT of `c`), row-major in FFT order.
    pub fn eigenvalues(&self) -> &[Complex64] {
        &self.lambda
    }

    /// `true` if `c(ix, iy) = c(−ix mod nx, −iy mod ny)` to a relative `1e−12` (then C is
    /// symmetric and its eigenvalues are real).
    pub fn is_symmetric(&self) -> bool {
        let (nx, ny) = (self.nx, self.ny);
        let scale = self.c.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        (0..nx).all(|ix| {
            (0..ny).all(|iy| {
                let mirror = ((nx - ix) % nx) * ny + (ny - iy) % ny;
                (self.c[ix * ny + iy] - self.c[mirror]).abs() <= SYMMETRY_TOL * scale
            })
        })
    }
}

/// φ-bank of [`Circulant2d`]: `φ_k(τ_i h λ_m)` per 2D Fourier mode.
pub type Circulant2dBank = SpectralBank<Fourier2dBasis>;
/// Scratch of [`Circulant2dBank`].
pub type Circulant2dWorkspace = SpectralWorkspace<Fourier2dScratch>;

impl LinearOperator for Circulant2d {
    type Bank = Circulant2dBank;

    fn dim(&self) -> usize {
        self.nx * self.ny
    }

    fn bank_bytes(&self, len: usize, n: usize) -> Option<(usize, usize)> {
        super::spectral::spectral_bank_bytes(&self.basis, len, n)
    }

    /// `y = c ⊛ x` by 2D FFT (O(d log d)); uses internal buffers behind a mutex, so
    /// concurrent calls on one operator serialise.
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        spectral_apply(&self.basis, &self.lambda, &self.apply_scratch, x, y);
    }

    fn phi_bank(&self, h: f64, taus: &[f64], p: usize) -> Result<Circulant2dBank> {
        SpectralBank::build(&self.basis, &self.lambda, h, taus, p, NodeFunctions::phi())
    }

    fn kernel_bank(&self, h: f64, taus: &[f64], n: usize) -> Result<Circulant2dBank> {
        let f = NodeFunctions::legendre(taus, n);
        SpectralBank::build(&self.basis, &self.lambda, h, taus, n, f)
    }
}

impl SkewGenerator for Circulant2d {
    type Basis = Fourier2dBasis;

    /// The real eigenvalues `Re(F₂ c)` of a symmetric 2D circulant.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] if `c(ix, iy) ≠ c(−ix, −iy)` beyond a relative `1e−12`.
    fn real_spectrum(&self) -> Result<(Vec<f64>, Fourier2dBasis)> {
        if !self.is_symmetric() {
            return Err(Error::InvalidInput(
                "2D circulant generator of a skew pair must be symmetric: c(ix, iy) = c(-ix, -iy)"
                    .into(),
            ));
        }
        Ok((
            self.lambda.iter().map(|l| l.re).collect(),
            self.basis.clone(),
        ))
    }
}
