//! Circulant operators (periodic convolutions, Fourier pseudospectral derivatives), by FFT.

use std::fmt;
use std::ops::Range;
use std::sync::{Arc, Mutex};

use num_complex::Complex64;
use rustfft::{Fft, FftPlanner};

use super::skew::{SkewGenerator, SpectralBasis};
use super::{
    LinearOperator, NodeFunctions, PhiBank, apply_shape, check_bank_args, check_bank_values,
    combine_shape,
};
use crate::concurrent::{for_each_chunk, in_pool};
use crate::phi::{cexp_dd, two_sum};
use crate::{Error, Result};

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

/// `Σ v` accumulated in double-double and rounded once: the eigenvalue of the constant mode,
/// which the FFT would round with the other modes' twiddle arithmetic. A kernel that sums to
/// zero exactly (a conservative difference stencil) then has the eigenvalue 0 exactly.
pub(super) fn sum_dd(v: &[f64]) -> f64 {
    let (mut s, mut c) = (0.0, 0.0);
    for x in v {
        let (t, e) = two_sum(s, *x);
        s = t;
        c += e;
    }
    s + c
}

/// `e^{z} − 1` from double-double, rounded to f64 componentwise, and `e^z` rounded (the
/// propagator's increment and value for one mode, `z = τhλ`).
pub(super) fn exp_increment(z: Complex64) -> (Complex64, Complex64) {
    let (re, im) = cexp_dd(z.re, z.im);
    let dre = re.add(crate::phi::Dd::new(-1.0));
    (Complex64::new(dre.hi, im.hi), Complex64::new(re.hi, im.hi))
}

/// `hi + lo = y0 + Re(w)`, per entry exactly (the increment `w` from an inverse transform).
#[inline]
pub(super) fn add_increment(
    y0: &[f64],
    w: impl Iterator<Item = f64>,
    hi: &mut [f64],
    lo: &mut [f64],
) {
    for (((h, l), y), wv) in hi.iter_mut().zip(lo.iter_mut()).zip(y0).zip(w) {
        (*h, *l) = two_sum(*y, wv);
    }
}

/// φ-bank of an operator with complex eigenvalues λ in a [`SpectralBasis`] (the circulants
/// [`Circulant`] and [`Circulant2d`](super::Circulant2d)): `φ_k(τ_i h λ_m)` per mode;
/// `combine` costs one forward transform per input vector and one inverse per output block.
#[derive(Debug, Clone)]
pub struct SpectralBank<B: SpectralBasis> {
    len: usize,
    p: usize,
    /// `phis[((i (p+1) + k) n + mode] = φ_k(τ_i h λ_mode)`.
    phis: Vec<Complex64>,
    /// Per node whose propagator is carried beyond f64 ([`PhiBank::propagate_dd`]): `e^{τ_i h
    /// λ_mode} − 1` rounded from double-double.
    increments: Vec<Option<Vec<Complex64>>>,
    basis: B,
}

/// Scratch of [`SpectralBank`]: spectra of the inputs, one output buffer, transform scratch.
#[derive(Debug, Clone)]
pub struct SpectralWorkspace<S> {
    spec: Vec<Complex64>,
    buf: Vec<Complex64>,
    scratch: S,
}

/// φ-bank of [`Circulant`].
pub type CirculantBank = SpectralBank<FourierBasis>;
/// Scratch of [`CirculantBank`].
pub type CirculantWorkspace = SpectralWorkspace<Vec<Complex64>>;

impl<B: SpectralBasis> SpectralBank<B> {
    /// `φ_k(τ_i h λ_m)` for every node, k ≤ p and mode m.
    ///
    /// # Errors
    /// As [`LinearOperator::phi_bank`].
    pub(super) fn build(
        basis: &B,
        lambda: &[Complex64],
        h: f64,
        taus: &[f64],
        p: usize,
        f: NodeFunctions,
    ) -> Result<Self> {
        check_bank_args(h, taus)?;
        let n = lambda.len();
        let mut phis = vec![Complex64::new(0.0, 0.0); taus.len() * (p + 1) * n];
        let mut increments = vec![None; taus.len()];
        let mut buf = vec![Complex64::new(0.0, 0.0); p + 1];
        for (i, tau) in taus.iter().enumerate() {
            let th = tau * h;
            let mut inc = f.carries_dd(i).then(|| vec![Complex64::new(0.0, 0.0); n]);
            for (mode, l) in lambda.iter().enumerate() {
                let z = Complex64::new(th * l.re, th * l.im);
                f.complex(i, z, &mut buf);
                if let Some(inc) = &mut inc {
                    (inc[mode], buf[0]) = exp_increment(z);
                }
                for (k, v) in buf.iter().enumerate() {
                    phis[(i * (p + 1) + k) * n + mode] = *v;
                }
            }
            increments[i] = inc;
        }
        check_bank_values(phis.iter().flat_map(|v| [v.re, v.im]))?;
        check_bank_values(
            increments
                .iter()
                .flatten()
                .flatten()
                .flat_map(|v| [v.re, v.im]),
        )?;
        Ok(SpectralBank {
            len: taus.len(),
            p,
            phis,
            increments,
            basis: basis.clone(),
        })
    }
}

/// `y = V diag(λ) V⁻¹ x` with the buffers behind `scratch` (the operators' `apply`, which has
/// no workspace argument: concurrent calls on one operator serialise).
pub(super) fn spectral_apply<B: SpectralBasis>(
    basis: &B,
    lambda: &[Complex64],
    scratch: &Mutex<(Vec<Complex64>, B::Scratch)>,
    x: &[f64],
    y: &mut [f64],
) {
    debug_assert_eq!(x.len(), lambda.len());
    debug_assert_eq!(y.len(), lambda.len());
    let mut guard = scratch
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    let (buf, scratch) = &mut *guard;
    for (b, xv) in buf.iter_mut().zip(x) {
        *b = Complex64::new(*xv, 0.0);
    }
    basis.forward(buf, scratch);
    for (b, l) in buf.iter_mut().zip(lambda) {
        *b *= l;
    }
    basis.inverse(buf, scratch);
    for (yv, b) in y.iter_mut().zip(buf.iter()) {
        *yv = b.re;
    }
}

impl LinearOperator for Circulant {
    type Bank = CirculantBank;

    fn dim(&self) -> usize {
        self.c.len()
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

/// `buf = f0 ⊙ s0 + Σ_k c_k f_{k+1} ⊙ s_{k+1}` on spectra (shared with the skew-pair bank).
#[inline]
pub(super) fn spectral_block(
    buf: &mut [Complex64],
    f: &[Complex64],
    spec: &[Complex64],
    coefs: &[f64],
) {
    let n = buf.len();
    for ((b, fv), sv) in buf.iter_mut().zip(&f[..n]).zip(&spec[..n]) {
        *b = fv * sv;
    }
    for (k, c) in coefs.iter().enumerate() {
        let fk = &f[(k + 1) * n..(k + 2) * n];
        let sk = &spec[(k + 1) * n..(k + 2) * n];
        for ((b, fv), sv) in buf.iter_mut().zip(fk).zip(sk) {
            *b += (fv * sv).scale(*c);
        }
    }
}

impl<B: SpectralBasis> SpectralBank<B> {
    /// `s` = the spectrum of the real input `x` (a stage of [`combine`](PhiBank::combine)).
    #[inline]
    fn input_spectrum(&self, x: &[f64], s: &mut [Complex64], scratch: &mut B::Scratch) {
        for (sv, xv) in s.iter_mut().zip(x) {
            *sv = Complex64::new(*xv, 0.0);
        }
        self.basis.forward(s, scratch);
    }

    /// Output block `o` of node `i` from the inputs' spectra `spec` and the block's
    /// coefficients `coef` (a stage of [`combine`](PhiBank::combine)).
    #[inline]
    fn output_block(
        &self,
        i: usize,
        spec: &[Complex64],
        coef: &[f64],
        o: &mut [f64],
        buf: &mut [Complex64],
        scratch: &mut B::Scratch,
    ) {
        let stride = (self.p + 1) * self.basis.dim();
        let f = &self.phis[i * stride..(i + 1) * stride];
        spectral_block(buf, f, spec, coef);
        self.basis.inverse(buf, scratch);
        for (ov, b) in o.iter_mut().zip(buf.iter()) {
            *ov = b.re;
        }
    }
}

impl<B: SpectralBasis> PhiBank for SpectralBank<B> {
    type Workspace = SpectralWorkspace<B::Scratch>;

    fn dim(&self) -> usize {
        self.basis.dim()
    }
    fn len(&self) -> usize {
        self.len
    }
    fn p(&self) -> usize {
        self.p
    }
    fn workspace(&self) -> Self::Workspace {
        let n = self.basis.dim();
        SpectralWorkspace {
            spec: vec![Complex64::new(0.0, 0.0); (self.p + 1) * n],
            buf: vec![Complex64::new(0.0, 0.0); n],
            scratch: self.basis.scratch(),
        }
    }

    fn combine(
        &self,
        indices: Range<usize>,
        y0: &[f64],
        g: &[f64],
        coef: &[f64],
        out: &mut [f64],
        ws: &mut Self::Workspace,
    ) {
        let n = self.basis.dim();
        let m = combine_shape(n, self.len, self.p, &indices, y0, g, coef, out);
        if indices.is_empty() {
            return;
        }
        let inputs = std::iter::once(y0).chain(g.chunks_exact(n));
        for (s, x) in ws.spec.chunks_exact_mut(n).zip(inputs) {
            self.input_spectrum(x, s, &mut ws.scratch);
        }
        for ((j, i), o) in indices.enumerate().zip(out.chunks_exact_mut(n)) {
            let c = &coef[j * m..(j + 1) * m];
            self.output_block(i, &ws.spec, c, o, &mut ws.buf, &mut ws.scratch);
        }
    }

    /// The inputs' transforms concurrently (one group per helper, into `ws`), then the output
    /// blocks (one group per helper); each by the code of [`combine`](PhiBank::combine).
    fn combine_concurrent(
        &self,
        indices: Range<usize>,
        y0: &[f64],
        g: &[f64],
        coef: &[f64],
        out: &mut [f64],
        ws: &mut Self::Workspace,
        helpers: &mut [Self::Workspace],
    ) {
        if helpers.is_empty() {
            return self.combine(indices, y0, g, coef, out, ws);
        }
        let n = self.basis.dim();
        let m = combine_shape(n, self.len, self.p, &indices, y0, g, coef, out);
        if indices.is_empty() {
            return;
        }
        let input = |k: usize| if k == 0 { y0 } else { &g[(k - 1) * n..k * n] };
        in_pool(|| {
            for_each_chunk(&mut ws.spec[..(m + 1) * n], n, helpers, &|k, s, w| {
                self.input_spectrum(input(k), s, &mut w.scratch)
            });
            let spec = &ws.spec;
            for_each_chunk(out, n, helpers, &|j, o, w| {
                let c = &coef[j * m..(j + 1) * m];
                self.output_block(indices.start + j, spec, c, o, &mut w.buf, &mut w.scratch);
            });
        });
    }

    fn join<RA, RB, A, B2>(
        &self,
        wa: &mut Self::Workspace,
        wb: &mut Self::Workspace,
        a: A,
        b: B2,
    ) -> (RA, RB)
    where
        RA: Send,
        RB: Send,
        A: FnOnce(&Self, &mut Self::Workspace) -> RA + Send,
        B2: FnOnce(&Self, &mut Self::Workspace) -> RB + Send,
    {
        rayon::join(|| a(self, wa), || b(self, wb))
    }

    /// `y0 + V ((e^{hΛ} − I) V⁻¹ y0)`: the increment through f64 transforms, added to y0
    /// exactly (see [`PhiBank::propagate_dd`]).
    fn propagate_dd(
        &self,
        i: usize,
        y0: &[f64],
        hi: &mut [f64],
        lo: &mut [f64],
        ws: &mut Self::Workspace,
    ) -> bool {
        let Some(inc) = &self.increments[i] else {
            return false;
        };
        let n = self.basis.dim();
        assert!(y0.len() == n && hi.len() == n && lo.len() == n);
        for (b, y) in ws.buf.iter_mut().zip(y0) {
            *b = Complex64::new(*y, 0.0);
        }
        self.basis.apply_diagonal(inc, &mut ws.buf, &mut ws.scratch);
        add_increment(y0, ws.buf.iter().map(|b| b.re), hi, lo);
        true
    }

    fn apply(&self, i: usize, k: usize, x: &[f64], out: &mut [f64], ws: &mut Self::Workspace) {
        let n = self.basis.dim();
        apply_shape(n, self.len, self.p, i, k, x, out);
        let f = &self.phis[(i * (self.p + 1) + k) * n..(i * (self.p + 1) + k + 1) * n];
        for (b, xv) in ws.buf.iter_mut().zip(x) {
            *b = Complex64::new(*xv, 0.0);
        }
        self.basis.apply_diagonal(f, &mut ws.buf, &mut ws.scratch);
        for (ov, b) in out.iter_mut().zip(&ws.buf) {
            *ov = b.re;
        }
    }
}

impl SkewGenerator for Circulant {
    type Basis = FourierBasis;

    /// The real eigenvalues `Re(F c)` of a symmetric circulant.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] if `c[j] ≠ c[(n − j) mod n]` beyond a relative `1e−12`.
    fn real_spectrum(&self) -> Result<(Vec<f64>, FourierBasis)> {
        if !self.is_symmetric() {
            return Err(Error::InvalidInput(
                "circulant generator of a skew pair must be symmetric: c[j] = c[n - j]".into(),
            ));
        }
        Ok((
            self.lambda.iter().map(|l| l.re).collect(),
            self.basis.clone(),
        ))
    }
}
