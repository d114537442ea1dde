//! Circulant operators (periodic convolutions, Fourier pseudospectral derivatives), by FFT.

use std::fmt;
use std::ops::Range;
use std::sync::{Arc, Mutex};

use num_complex::Complex64;
use rustfft::{Fft, FftPlanner};

use super::skew::{SkewGenerator, SpectralBasis};
use super::{
    Distinct, LinearOperator, NodeFunctions, PhiBank, apply_shape, check_bank_args,
    check_bank_values, combine_shape,
};
use crate::concurrent::two_phase_combine;
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
        let spectrum = Distinct::complex(lambda);
        let (phis, increments) = spectral_entries(&spectrum, h, taus, p, &f, |th, l| {
            Complex64::new(th * l.re, th * l.im)
        })?;
        Ok(SpectralBank {
            len: taus.len(),
            p,
            phis,
            increments,
            basis: basis.clone(),
        })
    }
}

/// The entries of a spectral bank ([`SpectralBank`], [`SkewPairBank`](super::SkewPairBank)):
/// `phis[(i (p+1) + k) n + mode]` = slot k of the functions `f` at node i and `z = arg(τ_i h,
/// μ_mode)` for the spectrum μ, and at the nodes that carry their propagator beyond f64 the
/// increments `e^z − 1` rounded from double-double (slot 0 then holds `e^z` from the same
/// evaluation). The functions are evaluated once per distinct value of μ ([`Distinct`]).
///
/// # Errors
/// [`Error::Numerical`] if a value overflows.
#[allow(clippy::type_complexity)]
pub(super) fn spectral_entries<T: Copy>(
    spectrum: &Distinct<T>,
    h: f64,
    taus: &[f64],
    p: usize,
    f: &NodeFunctions,
    arg: impl Fn(f64, T) -> Complex64,
) -> Result<(Vec<Complex64>, Vec<Option<Vec<Complex64>>>)> {
    let zero = Complex64::new(0.0, 0.0);
    let carries = |i| f.carries_dd(i);
    let (phis, increments) = spectrum.bank_entries(taus.len(), p, zero, carries, |i, v, row| {
        let z = arg(taus[i] * h, v);
        f.complex(i, z, row);
        if f.carries_dd(i) {
            let inc;
            (inc, row[0]) = exp_increment(z);
            inc
        } else {
            zero
        }
    });
    check_bank_values(phis.iter().flat_map(|v| [v.re, v.im]))?;
    check_bank_values(
        increments
            .iter()
            .flatten()
            .flatten()
            .flat_map(|v| [v.re, v.im]),
    )?;
    Ok((phis, increments))
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
        two_phase_combine(
            &mut ws.spec[..(m + 1) * n],
            n,
            out,
            n,
            helpers,
            &|k, s, w: &mut Self::Workspace| self.input_spectrum(input(k), s, &mut w.scratch),
            &|j, spec, o, w: &mut Self::Workspace| {
                let c = &coef[j * m..(j + 1) * m];
                self.output_block(indices.start + j, spec, c, o, &mut w.buf, &mut w.scratch);
            },
        );
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

    /// The entries evaluated per mode, without merging equal values (the reference for
    /// [`spectral_entries`]).
    #[allow(clippy::type_complexity)]
    fn per_mode<T: Copy>(
        spectrum: &[T],
        h: f64,
        taus: &[f64],
        p: usize,
        f: &NodeFunctions,
        arg: impl Fn(f64, T) -> Complex64,
    ) -> (Vec<Complex64>, Vec<Option<Vec<Complex64>>>) {
        let n = spectrum.len();
        let zero = Complex64::new(0.0, 0.0);
        let mut phis = vec![zero; taus.len() * (p + 1) * n];
        let mut increments = vec![None; taus.len()];
        let mut buf = vec![zero; p + 1];
        for (i, tau) in taus.iter().enumerate() {
            let th = tau * h;
            let mut inc = f.carries_dd(i).then(|| vec![zero; n]);
            for (mode, l) in spectrum.iter().enumerate() {
                let z = arg(th, *l);
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
        (phis, increments)
    }

    fn bits(v: &[Complex64]) -> Vec<(u64, u64)> {
        v.iter().map(|z| (z.re.to_bits(), z.im.to_bits())).collect()
    }

    fn assert_same(
        a: &(Vec<Complex64>, Vec<Option<Vec<Complex64>>>),
        b: &(Vec<Complex64>, Vec<Option<Vec<Complex64>>>),
        what: &str,
    ) {
        assert_eq!(bits(&a.0), bits(&b.0), "{what}: entries");
        let inc = |x: &Vec<Option<Vec<Complex64>>>| {
            x.iter().map(|v| v.as_deref().map(bits)).collect::<Vec<_>>()
        };
        assert_eq!(inc(&a.1), inc(&b.1), "{what}: increments");
    }

    /// Merging equal eigenvalues changes no bit: the entries of a spectrum with repeated values
    /// (0, a mirrored pair λ_k = λ_{N−k}, −0, a pair ±λ) equal those evaluated mode by mode.
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

    #[test]
    fn entries_per_distinct_value_equal_entries_per_mode() {
        let h = 0.37;
        let taus = [0.0, 0.2, 0.5, 1.0, 1.4];
        // A symmetric circulant's layout: 0, then λ_k = λ_{N−k}; then −0 and ±λ.
        let real = [
            0.0, -2.0, -4.0, -9.5, -4.0, -2.0, -0.0, 3.25, -3.25, 1e-9, 0.0, -2.0,
        ];
        let complex: Vec<Complex64> = [
            (0.0, 0.0),
            (-2.0, 1.5),
            (-2.0, -1.5),
            (-7.0, 0.0),
            (-2.0, -1.5),
            (-2.0, 1.5),
            (0.0, 0.0),
            (-0.0, 0.0),
            (0.25, 40.0),
        ]
        .iter()
        .map(|&(re, im)| Complex64::new(re, im))
        .collect();
        for p in [0, 1, 3, 6] {
            for (name, f) in [
                ("phi", NodeFunctions::phi()),
                ("kernels", NodeFunctions::legendre(&taus, p)),
            ] {
                let skew = |th: f64, l: f64| Complex64::new(0.0, th * l);
                let merged = spectral_entries(&Distinct::real(&real), h, &taus, p, &f, skew);
                let reference = per_mode(&real, h, &taus, p, &f, skew);
                assert_same(&merged.unwrap(), &reference, &format!("real {name} p={p}"));

                let circ = |th: f64, l: Complex64| Complex64::new(th * l.re, th * l.im);
                let distinct = Distinct::complex(&complex);
                let merged = spectral_entries(&distinct, h, &taus, p, &f, circ);
                let reference = per_mode(&complex, h, &taus, p, &f, circ);
                assert_same(
                    &merged.unwrap(),
                    &reference,
                    &format!("complex {name} p={p}"),
                );
            }
        }
    }
}
