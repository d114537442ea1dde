//! Operators diagonal in a spectral basis: the basis ([`SpectralBasis`]), the real symmetric
//! generators of skew pairs ([`SkewGenerator`]), and the φ-bank of complex eigenvalues
//! ([`SpectralBank`]) with the helpers that the circulant and skew-pair banks share.

use std::ops::Range;
use std::sync::Mutex;

use num_complex::Complex64;

use super::checks::{apply_shape, check_bank_args, check_bank_values, combine_shape};
use super::entries::{Distinct, NodeFunctions};
use super::traits::{LinearOperator, PhiBank, byte_sum};
use crate::concurrent::two_phase_combine;
use crate::error::Result;
use crate::phi::{Dd, cexp_dd, two_sum};

/// A unitary change of basis `V` acting on complex vectors of length n, in which a
/// [`SkewGenerator`] is diagonal.
///
/// `Sync`, with scratch that can be sent to another thread: the banks built on a basis run
/// their transforms concurrently for large systems
/// ([`PhiBank::combine_concurrent`](super::PhiBank::combine_concurrent)). A basis is an
/// immutable plan; the built-in ones are.
pub trait SpectralBasis: Clone + Sync {
    /// Scratch memory for one transform.
    type Scratch: Send;

    /// The length n.
    fn dim(&self) -> usize;

    /// Fresh scratch memory.
    fn scratch(&self) -> Self::Scratch;

    /// The bytes of [`scratch`](Self::scratch) (for memory estimates). The default counts a
    /// complex number per point.
    fn scratch_bytes(&self) -> usize {
        16 * self.dim()
    }

    /// `u ← V⁻¹ u` (coefficients in the eigenbasis). Does not allocate.
    fn forward(&self, u: &mut [Complex64], s: &mut Self::Scratch);

    /// `u ← V u`. Does not allocate.
    fn inverse(&self, u: &mut [Complex64], s: &mut Self::Scratch);

    /// `u ← V diag(f) V⁻¹ u`: a diagonal in the eigenbasis, through the transforms. Does not
    /// allocate.
    fn apply_diagonal(&self, f: &[Complex64], u: &mut [Complex64], s: &mut Self::Scratch) {
        self.forward(u, s);
        for (b, fv) in u.iter_mut().zip(f) {
            *b *= fv;
        }
        self.inverse(u, s);
    }
}

/// A real symmetric operator C that can be diagonalised, `C = V diag(λ) V⁻¹` with real λ: the
/// generator of a [`SkewPair`](super::SkewPair). Implemented by [`Circulant`](super::Circulant)
/// (FFT) and [`Symmetric`](super::Symmetric) (eigendecomposition).
pub trait SkewGenerator: LinearOperator {
    /// The eigenbasis.
    type Basis: SpectralBasis;

    /// The real eigenvalues and the eigenbasis.
    ///
    /// # Errors
    /// [`Error::InvalidInput`](crate::Error::InvalidInput) if the operator is not symmetric.
    fn real_spectrum(&self) -> Result<(Vec<f64>, Self::Basis)>;
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
    let dre = re.add(Dd::new(-1.0));
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
/// [`Circulant`](super::Circulant) and [`Circulant2d`](super::Circulant2d)): `φ_k(τ_i h λ_m)` per
/// mode; `combine` costs one forward transform per input vector and one inverse per output block.
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

/// [`LinearOperator::bank_bytes`] of a spectral bank on `basis` ([`SpectralBank`],
/// [`SkewPairBank`](super::SkewPairBank)): a complex number per mode, slot and node, the
/// increments of one carried node; a workspace of `n + 2` complex numbers per mode and the
/// transform's scratch.
pub(super) fn spectral_bank_bytes<B: SpectralBasis>(
    basis: &B,
    len: usize,
    n: usize,
) -> Option<(usize, usize)> {
    let modes = basis.dim();
    let slots = n.checked_add(1)?;
    let bank = byte_sum(&[
        (len.checked_mul(slots)?.checked_mul(modes)?, 16),
        (modes, 16),
    ])?;
    let workspace = byte_sum(&[
        (slots.checked_add(1)?.checked_mul(modes)?, 16),
        (basis.scratch_bytes(), 1),
    ])?;
    Some((bank, workspace))
}

/// The entries of a spectral bank ([`SpectralBank`], [`SkewPairBank`](super::SkewPairBank)):
/// `phis[(i (p+1) + k) n + mode]` = slot k of the functions `f` at node i and `z = arg(τ_i h,
/// μ_mode)` for the spectrum μ, and at the nodes that carry their propagator beyond f64 the
/// increments `e^z − 1` rounded from double-double (slot 0 then holds `e^z` from the same
/// evaluation). The functions are evaluated once per distinct value of μ ([`Distinct`]).
///
/// # Errors
/// [`Error::Numerical`](crate::Error::Numerical) if a value overflows.
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
    // The cause of an overflow: the largest real part of z = τ h μ.
    let cause = || {
        let mut top = f64::NEG_INFINITY;
        for t in taus {
            for &v in spectrum.values() {
                top = top.max(arg(t * h, v).re);
            }
        }
        format!(
            "the largest real part of τ·h·λ over the eigenvalues λ of A is {top:.3e}, and \
             |e^z| passes f64::MAX at Re z = {:.2}",
            f64::MAX.ln()
        )
    };
    check_bank_values(phis.iter().flat_map(|v| [v.re, v.im]), cause)?;
    check_bank_values(
        increments
            .iter()
            .flatten()
            .flatten()
            .flat_map(|v| [v.re, v.im]),
        cause,
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

    bank_shape!(|b| b.basis.dim());
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

    concurrent_join!();

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
