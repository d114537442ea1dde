//! The diagonal operator `A = diag(d)` and its bank, stored once per distinct entry where
//! that halves it ([`DiagonalBank`]).

use std::ops::Range;

use nalgebra::DVector;

use super::checks::{
    apply_shape, check_bank_scale, check_bank_values, combine_shape, real_overflow_cause,
};
use super::entries::{Distinct, NodeFunctions};
use super::simple::mul_dd;
use super::traits::{LinearOperator, PhiBank};
use crate::error::{Error, Result};
use crate::phi::exp_dd;
use crate::storage::ensure_allocatable_for;

/// `A = diag(d)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Diagonal {
    diag: Vec<f64>,
}

impl Diagonal {
    /// `A = diag(diag)`.
    ///
    /// # Errors
    /// [`Error::NonFinite`] if an entry is NaN or infinite.
    pub fn new(diag: Vec<f64>) -> Result<Self> {
        if diag.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite("diagonal"));
        }
        Ok(Diagonal { diag })
    }

    /// `A = diag(v)` from an nalgebra vector.
    ///
    /// # Errors
    /// As [`Diagonal::new`].
    pub fn from_dvector(v: &DVector<f64>) -> Result<Self> {
        Self::new(v.iter().copied().collect())
    }

    /// The diagonal entries.
    pub fn entries(&self) -> &[f64] {
        &self.diag
    }
}

/// φ-bank of [`Diagonal`]: the numbers `φ_k(τ_i h d_t)`.
///
/// A diagonal that repeats its entries (a grid of a few materials, a spectrum with
/// multiplicities) gets one column of numbers per distinct entry and an index (`u8`, `u16` or
/// `u32`, the smallest that fits) from each entry to its column, when that at least halves the
/// storage; otherwise one column per entry. The numbers, and so every step, are the same bit
/// for bit either way ([`Diagonal::bank_size`] says which is taken and its size).
#[derive(Debug, Clone, PartialEq)]
pub struct DiagonalBank {
    dim: usize,
    len: usize,
    p: usize,
    /// The columns per slot: `dim`, or the number of distinct entries.
    cols: usize,
    /// `phis[(i (p+1) + k) cols + column(t)] = φ_k(τ_i h d_t)`.
    phis: Vec<f64>,
    /// The low parts of the propagators carried in double-double (`e^{τ_i h d_t} =
    /// phis[i (p+1) cols + column(t)] + lo[i][column(t)]`), see [`PhiBank::propagate_dd`].
    lo: Vec<Option<Vec<f64>>>,
    /// The column of each entry.
    index: EntryIndex,
}

/// The column of each entry of a [`DiagonalBank`]: its own, or that of its distinct value.
#[derive(Debug, Clone, PartialEq)]
enum EntryIndex {
    Own,
    U8(Vec<u8>),
    U16(Vec<u16>),
    U32(Vec<u32>),
}

/// An index into the columns of a [`DiagonalBank`].
trait Column: Copy {
    fn col(self) -> usize;
}

impl Column for u8 {
    #[inline(always)]
    fn col(self) -> usize {
        usize::from(self)
    }
}

impl Column for u16 {
    #[inline(always)]
    fn col(self) -> usize {
        usize::from(self)
    }
}

impl Column for u32 {
    #[inline(always)]
    fn col(self) -> usize {
        self as usize
    }
}

/// The bytes of one index entry for `distinct` columns, `None` beyond `u32`.
fn index_width(distinct: usize) -> Option<usize> {
    if distinct <= 1 << 8 {
        Some(1)
    } else if distinct <= 1 << 16 {
        Some(2)
    } else if u32::try_from(distinct - 1).is_ok() {
        Some(4)
    } else {
        None
    }
}

/// How a [`DiagonalBank`] of a given diagonal is stored, and its size
/// ([`Diagonal::bank_size`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DiagonalBankSize {
    /// The columns of numbers per function and node: the dimension, or the number of distinct
    /// entries when these are stored once each.
    pub columns: usize,
    /// Bytes per entry of the index from entries to columns (1, 2 or 4), 0 without one.
    pub index_bytes: usize,
    /// The bank's bytes (numbers, low parts of the carried propagators, index); `None` if the
    /// count overflows a `usize`.
    pub bytes: Option<usize>,
}

impl DiagonalBankSize {
    /// The numbers (`f64`) of the bank's main array, `None` on overflow.
    fn numbers(len: usize, p: usize, columns: usize) -> Option<usize> {
        len.checked_mul(p.checked_add(1)?)?.checked_mul(columns)
    }

    /// The size of the bank; `share`: whether shared columns may be taken (tests compare
    /// them with own ones).
    fn new(d: usize, distinct: usize, len: usize, p: usize, carried: usize, share: bool) -> Self {
        let bytes = |columns: usize, index_bytes: usize| -> Option<usize> {
            let numbers =
                Self::numbers(len, p, columns)?.checked_add(carried.checked_mul(columns)?)?;
            numbers
                .checked_mul(8)?
                .checked_add(d.checked_mul(index_bytes)?)
        };
        let own = DiagonalBankSize {
            columns: d,
            index_bytes: 0,
            bytes: bytes(d, 0),
        };
        let Some(width) = index_width(distinct).filter(|_| share) else {
            return own;
        };
        let shared = bytes(distinct, width);
        match (own.bytes, shared) {
            // Shared columns when they at least halve the storage (or the own ones overflow).
            (Some(o), Some(s)) if s.saturating_mul(2) > o => own,
            (_, Some(_)) => DiagonalBankSize {
                columns: distinct,
                index_bytes: width,
                bytes: shared,
            },
            (_, None) => own,
        }
    }
}

impl LinearOperator for Diagonal {
    type Bank = DiagonalBank;

    fn dim(&self) -> usize {
        self.diag.len()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        debug_assert_eq!(x.len(), self.diag.len());
        debug_assert_eq!(y.len(), self.diag.len());
        for ((yv, xv), dv) in y.iter_mut().zip(x).zip(&self.diag) {
            *yv = dv * xv;
        }
    }

    /// The kernel bank's size from [`Diagonal::bank_size`] (one node carried in double-double)
    /// and the scratch of its construction (sorted (bits, entry) pairs and an index per entry,
    /// 24 bytes per entry); no workspace. O(d log d).
    fn bank_bytes(&self, len: usize, n: usize) -> Option<(usize, usize)> {
        let building = self.diag.len().checked_mul(24)?;
        Some((self.bank_size(len, n, 1).bytes?.checked_add(building)?, 0))
    }

    fn phi_bank(&self, h: f64, taus: &[f64], p: usize) -> Result<DiagonalBank> {
        self.bank(h, taus, p, NodeFunctions::phi())
    }

    fn kernel_bank(&self, h: f64, taus: &[f64], n: usize) -> Result<DiagonalBank> {
        self.bank(h, taus, n, NodeFunctions::legendre(taus, n))
    }
}

impl Diagonal {
    /// How the φ- or kernel bank for `len` nodes and the functions `0..=p` is stored and its
    /// bytes, `carried` of the nodes carrying their propagator in double-double (the node
    /// τ = 1 of a kernel bank, none in a φ-bank). O(d log d): it counts the distinct entries.
    pub fn bank_size(&self, len: usize, p: usize, carried: usize) -> DiagonalBankSize {
        let distinct = Distinct::real(&self.diag);
        DiagonalBankSize::new(self.diag.len(), distinct.len(), len, p, carried, true)
    }

    fn bank(&self, h: f64, taus: &[f64], p: usize, f: NodeFunctions) -> Result<DiagonalBank> {
        self.bank_shared(h, taus, p, f, true)
    }

    /// The bank; `share`: whether it may share columns between equal entries.
    fn bank_shared(
        &self,
        h: f64,
        taus: &[f64],
        p: usize,
        f: NodeFunctions,
        share: bool,
    ) -> Result<DiagonalBank> {
        check_bank_scale(
            h,
            taus,
            self.diag.iter().fold(0.0_f64, |m, x| m.max(x.abs())),
        )?;
        let d = self.diag.len();
        // Evaluated once per distinct entry (a diagonal often repeats its entries).
        let entries = Distinct::real(&self.diag);
        let carried = (0..taus.len()).filter(|&i| f.carries_dd(i)).count();
        let size = DiagonalBankSize::new(d, entries.len(), taus.len(), p, carried, share);
        ensure_allocatable_for(
            || {
                format!(
                    "the φ-bank of a diagonal of dimension {d} ({} nodes, {} functions)",
                    taus.len(),
                    p + 1
                )
            },
            size.bytes.map(|b| b.div_ceil(8)),
        )?;
        let carries = |i| f.carries_dd(i);
        let eval = |i: usize, dv: f64, row: &mut [f64]| {
            let x = taus[i] * h * dv;
            f.real(i, x, row);
            if f.carries_dd(i) {
                let e = exp_dd(x);
                row[0] = e.hi;
                e.lo
            } else {
                0.0
            }
        };
        let (phis, lo) = if size.index_bytes == 0 {
            entries.bank_entries(taus.len(), p, 0.0, carries, eval)
        } else {
            entries.distinct_entries(taus.len(), p, 0.0, carries, eval)
        };
        check_bank_values(phis.iter().copied(), || {
            real_overflow_cause(&self.diag, h, taus)
        })?;
        let index = match size.index_bytes {
            0 => EntryIndex::Own,
            1 => EntryIndex::U8(entries.index().iter().map(|&u| u as u8).collect()),
            2 => EntryIndex::U16(entries.index().iter().map(|&u| u as u16).collect()),
            _ => EntryIndex::U32(entries.index().iter().map(|&u| u as u32).collect()),
        };
        Ok(DiagonalBank {
            dim: d,
            len: taus.len(),
            p,
            cols: size.columns,
            phis,
            lo,
            index,
        })
    }
}

#[cfg(test)]
impl DiagonalBank {
    /// The column of entry t.
    fn column(&self, t: usize) -> usize {
        match &self.index {
            EntryIndex::Own => t,
            EntryIndex::U8(ix) => ix[t].col(),
            EntryIndex::U16(ix) => ix[t].col(),
            EntryIndex::U32(ix) => ix[t].col(),
        }
    }
}

/// As [`diagonal_block`] for a bank with shared columns: entry t reads column `index[t]` of
/// each slot (`f` holds the p + 1 slots of one node, `cols` numbers each).
#[inline]
fn indexed_block<I: Column>(
    o: &mut [f64],
    f: &[f64],
    cols: usize,
    index: &[I],
    y0: &[f64],
    g: &[f64],
    coefs: &[f64],
) {
    let d = index.len();
    let f0 = &f[..cols];
    for ((ot, ix), yt) in o.iter_mut().zip(index).zip(y0) {
        *ot = f0[ix.col()] * yt;
    }
    for (k, (gk, c)) in g.chunks_exact(d).zip(coefs).enumerate() {
        let fk = &f[(k + 1) * cols..(k + 2) * cols];
        for ((ot, ix), gt) in o.iter_mut().zip(index).zip(gk) {
            *ot += c * fk[ix.col()] * gt;
        }
    }
}

/// `(hi, lo) = (eh + el) y` entry by entry, entry t reading column `index[t]`.
#[inline]
fn indexed_propagate<I: Column>(
    index: &[I],
    eh: &[f64],
    el: &[f64],
    y0: &[f64],
    hi: &mut [f64],
    lo: &mut [f64],
) {
    for (((h, l), y), ix) in hi.iter_mut().zip(lo.iter_mut()).zip(y0).zip(index) {
        (*h, *l) = mul_dd(eh[ix.col()], el[ix.col()], *y);
    }
}

/// `out = f ⊙ x`, entry t reading column `index[t]` of `f`.
#[inline]
fn indexed_scale<I: Column>(index: &[I], f: &[f64], x: &[f64], out: &mut [f64]) {
    for ((o, xv), ix) in out.iter_mut().zip(x).zip(index) {
        *o = f[ix.col()] * xv;
    }
}

/// `o = f0 ⊙ y0 + Σ_k c_k f_{k+1} ⊙ g_k` for diagonal banks (shared with the symmetric bank).
#[inline(always)]
pub(super) fn diagonal_block(
    o: &mut [f64],
    f: &[f64],
    d: usize,
    y0: &[f64],
    g: &[f64],
    coefs: &[f64],
) {
    for ((ot, ft), yt) in o.iter_mut().zip(&f[..d]).zip(y0) {
        *ot = ft * yt;
    }
    for (k, (gk, c)) in g.chunks_exact(d).zip(coefs).enumerate() {
        let fk = &f[(k + 1) * d..(k + 2) * d];
        for ((ot, ft), gt) in o.iter_mut().zip(fk).zip(gk) {
            *ot += c * ft * gt;
        }
    }
}

impl PhiBank for DiagonalBank {
    type Workspace = ();

    bank_shape!(|b| b.dim, unit);

    fn combine(
        &self,
        indices: Range<usize>,
        y0: &[f64],
        g: &[f64],
        coef: &[f64],
        out: &mut [f64],
        _ws: &mut (),
    ) {
        let d = self.dim;
        let m = combine_shape(d, self.len, self.p, &indices, y0, g, coef, out);
        if d == 0 {
            return;
        }
        let stride = (self.p + 1) * self.cols;
        for ((j, i), o) in indices.enumerate().zip(out.chunks_exact_mut(d)) {
            let f = &self.phis[i * stride..(i + 1) * stride];
            let c = &coef[j * m..(j + 1) * m];
            match &self.index {
                // A known length for d ≤ 4 (the loops of unknown length took a third of a
                // 2 × 2 solve); the same operations in the same order for every d.
                EntryIndex::Own => match d {
                    1 => diagonal_block(o, f, 1, y0, g, c),
                    2 => diagonal_block(o, f, 2, y0, g, c),
                    3 => diagonal_block(o, f, 3, y0, g, c),
                    4 => diagonal_block(o, f, 4, y0, g, c),
                    _ => diagonal_block(o, f, d, y0, g, c),
                },
                EntryIndex::U8(ix) => indexed_block(o, f, self.cols, ix, y0, g, c),
                EntryIndex::U16(ix) => indexed_block(o, f, self.cols, ix, y0, g, c),
                EntryIndex::U32(ix) => indexed_block(o, f, self.cols, ix, y0, g, c),
            }
        }
    }

    fn propagate_dd(
        &self,
        i: usize,
        y0: &[f64],
        hi: &mut [f64],
        lo: &mut [f64],
        _ws: &mut (),
    ) -> bool {
        let Some(el) = &self.lo[i] else {
            return false;
        };
        let d = self.dim;
        assert!(y0.len() == d && hi.len() == d && lo.len() == d);
        let c = self.cols;
        let eh = &self.phis[i * (self.p + 1) * c..(i * (self.p + 1) + 1) * c];
        match &self.index {
            EntryIndex::Own => {
                for ((((h, l), y), a), b) in
                    hi.iter_mut().zip(lo.iter_mut()).zip(y0).zip(eh).zip(el)
                {
                    (*h, *l) = mul_dd(*a, *b, *y);
                }
            }
            EntryIndex::U8(ix) => indexed_propagate(ix, eh, el, y0, hi, lo),
            EntryIndex::U16(ix) => indexed_propagate(ix, eh, el, y0, hi, lo),
            EntryIndex::U32(ix) => indexed_propagate(ix, eh, el, y0, hi, lo),
        }
        true
    }

    fn apply(&self, i: usize, k: usize, x: &[f64], out: &mut [f64], _ws: &mut ()) {
        apply_shape(self.dim, self.len, self.p, i, k, x, out);
        let c = self.cols;
        let f = &self.phis[(i * (self.p + 1) + k) * c..(i * (self.p + 1) + k + 1) * c];
        match &self.index {
            EntryIndex::Own => {
                for ((o, xv), fv) in out.iter_mut().zip(x).zip(f) {
                    *o = fv * xv;
                }
            }
            EntryIndex::U8(ix) => indexed_scale(ix, f, x, out),
            EntryIndex::U16(ix) => indexed_scale(ix, f, x, out),
            EntryIndex::U32(ix) => indexed_scale(ix, f, x, out),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A diagonal with repeated entries (0, −0, a repeated pair, ±d) gives, bit for bit, the bank
    /// evaluated entry by entry.
    #[test]
    fn diagonal_bank_per_distinct_entry_equals_bank_per_entry() {
        let diag = vec![
            0.0, -2.0, -4.0, -2.0, 0.0, -0.0, 3.25, -3.25, 1e-9, -2.0, -300.0,
        ];
        let op = Diagonal::new(diag.clone()).unwrap();
        let (h, taus) = (0.3, [0.0, 0.2, 0.5, 1.0, 1.4]);
        for p in [0, 1, 4] {
            for kernels in [false, true] {
                let (bank, f) = if kernels {
                    (
                        op.kernel_bank(h, &taus, p),
                        NodeFunctions::legendre(&taus, p),
                    )
                } else {
                    (op.phi_bank(h, &taus, p), NodeFunctions::phi())
                };
                let bank = bank.unwrap();
                let mut buf = vec![0.0; p + 1];
                for (i, tau) in taus.iter().enumerate() {
                    for (t, dv) in diag.iter().enumerate() {
                        f.real(i, tau * h * dv, &mut buf);
                        let lo = f.carries_dd(i).then(|| {
                            let e = exp_dd(tau * h * dv);
                            buf[0] = e.hi;
                            e.lo
                        });
                        for (k, v) in buf.iter().enumerate() {
                            let c = bank.column(t);
                            let got = bank.phis[(i * (p + 1) + k) * bank.cols + c];
                            assert_eq!(got.to_bits(), v.to_bits(), "p={p} i={i} t={t} k={k}");
                        }
                        let got = bank.lo[i].as_ref().map(|l| l[bank.column(t)].to_bits());
                        assert_eq!(got, lo.map(f64::to_bits), "p={p} i={i} t={t}: low part");
                    }
                }
            }
        }
    }

    /// A diagonal of many entries taking few values: its bank shares columns (a u8, u16 or u32
    /// index) and is at most half the size of one with a column per entry, and every output
    /// (combine, apply, the double-double propagator) is that of the bank with its own
    /// columns, bit for bit.
    #[test]
    fn shared_columns_give_the_same_steps_bit_for_bit() {
        let mut rng = crate::test_rng::XorShift(44);
        for (d, distinct) in [(3000, 7), (3000, 300), (200_000, 70_000)] {
            let values: Vec<f64> = (0..distinct).map(|_| -50.0 * rng.unit()).collect();
            let diag: Vec<f64> = (0..d).map(|t| values[(t * 7919) % distinct]).collect();
            let op = Diagonal::new(diag).unwrap();
            let (h, taus) = (0.1, [0.2, 0.7, 1.0]);
            let p = 3;
            for kernels in [false, true] {
                let f = || {
                    if kernels {
                        NodeFunctions::legendre(&taus, p)
                    } else {
                        NodeFunctions::phi()
                    }
                };
                let shared = op.bank_shared(h, &taus, p, f(), true).unwrap();
                let own = op.bank_shared(h, &taus, p, f(), false).unwrap();
                let width = match &shared.index {
                    EntryIndex::U8(_) => 1,
                    EntryIndex::U16(_) => 2,
                    EntryIndex::U32(_) => 4,
                    EntryIndex::Own => panic!("d = {d}, {distinct} values: columns not shared"),
                };
                assert_eq!(width, index_width(distinct).unwrap());
                assert_eq!((shared.cols, own.cols), (distinct, d));
                let size = op.bank_size(taus.len(), p, usize::from(kernels));
                assert_eq!((size.columns, size.index_bytes), (distinct, width));
                assert!(2 * size.bytes.unwrap() <= 8 * own.phis.len());
                let lo: usize = shared.lo.iter().flatten().map(Vec::len).sum();
                assert_eq!(size.bytes, Some(8 * (shared.phis.len() + lo) + width * d));
                let y0: Vec<f64> = (0..d).map(|_| rng.mixed(4)).collect();
                let g: Vec<f64> = (0..p * d).map(|_| rng.mixed(4)).collect();
                let coef: Vec<f64> = (0..taus.len() * p).map(|_| rng.mixed(4)).collect();
                let mut a = vec![0.0; taus.len() * d];
                let mut b = a.clone();
                shared.combine(0..taus.len(), &y0, &g, &coef, &mut a, &mut ());
                own.combine(0..taus.len(), &y0, &g, &coef, &mut b, &mut ());
                assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
                for (i, &tau) in taus.iter().enumerate() {
                    for k in 0..=p {
                        let (mut a, mut b) = (vec![0.0; d], vec![0.0; d]);
                        shared.apply(i, k, &y0, &mut a, &mut ());
                        own.apply(i, k, &y0, &mut b, &mut ());
                        assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
                    }
                    let (mut ah, mut al, mut bh, mut bl) =
                        (vec![0.0; d], vec![0.0; d], vec![0.0; d], vec![0.0; d]);
                    let sa = shared.propagate_dd(i, &y0, &mut ah, &mut al, &mut ());
                    let sb = own.propagate_dd(i, &y0, &mut bh, &mut bl, &mut ());
                    assert_eq!(sa, sb);
                    assert_eq!(sa, kernels && tau == 1.0);
                    let same = |x: &[f64], y: &[f64]| {
                        x.iter().zip(y).all(|(u, v)| u.to_bits() == v.to_bits())
                    };
                    assert!(same(&ah, &bh) && same(&al, &bl));
                }
            }
        }
    }

    /// Storage a diagonal's bank cannot get is an `Err` naming it, not an abort.
    #[test]
    fn a_bank_too_large_to_allocate_is_an_error() {
        let op = Diagonal::new((0..1_000_000).map(|t| -(t as f64)).collect()).unwrap();
        let taus: Vec<f64> = (0..1_000_000).map(|i| i as f64 * 1e-6).collect();
        let err = op.phi_bank(1e-3, &taus, 8).unwrap_err().to_string();
        assert!(
            err.contains("the φ-bank of a diagonal of dimension 1000000")
                && err.contains("more than can be allocated"),
            "{err}"
        );
    }
}
