//! What the entries of a bank are made of: the functions at each node (φ₀..φ_p, or e^x and
//! the Legendre kernels) and the distinct values of a spectrum, at which they are evaluated
//! once.

use std::sync::Arc;

use crate::error::Result;

/// The node maps `K(τ_i)` of a Legendre bank, shared with every bank of the same nodes.
type NodeMaps = Vec<Arc<[f64]>>;

/// The functions a bank holds at each node: φ₀..φ_p, or `e^x` and the Legendre kernels.
pub(crate) struct NodeFunctions {
    legendre: Option<(Arc<crate::phi::LegendreKernels>, NodeMaps)>,
    /// The nodes (Legendre banks only).
    taus: Vec<f64>,
}

impl NodeFunctions {
    /// φ₀..φ_p.
    pub(crate) fn phi() -> Self {
        NodeFunctions {
            legendre: None,
            taus: Vec::new(),
        }
    }

    /// `true` if the propagator at node i is carried beyond f64 (see
    /// [`PhiBank::propagate_dd`](super::PhiBank::propagate_dd)): τ = 1 in a Legendre bank.
    pub(crate) fn carries_dd(&self, i: usize) -> bool {
        self.legendre.is_some() && self.taus[i] == 1.0
    }

    /// The Legendre kernels and the node map `K(τ_i)` of node i (Legendre banks only).
    pub(crate) fn legendre_map(&self, i: usize) -> Option<(&crate::phi::LegendreKernels, &[f64])> {
        self.legendre.as_ref().map(|(k, maps)| (&**k, &*maps[i]))
    }

    /// `e^x`, `Ψ_0(τ_i, ·) … Ψ_{n−1}(τ_i, ·)` for the nodes `taus`.
    pub(crate) fn legendre(taus: &[f64], n: usize) -> Self {
        let k = crate::phi::LegendreKernels::shared(n);
        let maps = taus.iter().map(|&t| k.node_map_shared(t)).collect();
        NodeFunctions {
            legendre: Some((k, maps)),
            taus: taus.to_vec(),
        }
    }

    /// `out` = the functions at `x = τ_i h λ` (`out.len() = p + 1`).
    pub(crate) fn real(&self, i: usize, x: f64, out: &mut [f64]) {
        match &self.legendre {
            None => crate::phi::phi_real(x, out),
            Some((k, maps)) => k.row_real(&maps[i], x, out),
        }
    }

    /// As [`real`](Self::real) for complex `z = τ_i h λ`.
    pub(crate) fn complex(
        &self,
        i: usize,
        z: num_complex::Complex64,
        out: &mut [num_complex::Complex64],
    ) {
        match &self.legendre {
            None => crate::phi::phi_complex(z, out),
            Some((k, maps)) => k.row_complex(&maps[i], z, out),
        }
    }

    /// The `p + 1` matrix functions at `X = τ_i h A`, and the low part of the propagator
    /// `e^X = out[0] + lo` where it is carried in double-double: at τ = 1 in a Legendre bank,
    /// for `d ≤ DD_PROPAGATOR_MAX_DIM`. The stage nodes of a Legendre bank (τ < 1) take
    /// `out[0]` from the double-double exponential too for `d ≤ DD_STAGE_PROPAGATOR_MAX_DIM`;
    /// the predictor's nodes beyond the step (τ > 1), which only start the next step's stage
    /// iteration, take it in f64. `x_lo`, if
    /// given, is the rounding error of `x` (`X = x + x_lo`), taken into the double-double
    /// propagator only.
    #[allow(clippy::type_complexity)]
    pub(crate) fn dense(
        &self,
        i: usize,
        x: &nalgebra::DMatrix<f64>,
        x_lo: Option<&nalgebra::DMatrix<f64>>,
        p: usize,
    ) -> Result<(Vec<nalgebra::DMatrix<f64>>, Option<nalgebra::DMatrix<f64>>)> {
        self.dense_in(i, x, x_lo, p, true)
    }

    /// [`dense`](Self::dense), with the stage propagators (τ < 1) from the double-double
    /// exponential only if `dd_stages` (else in f64; τ = 1 as in `dense`).
    #[allow(clippy::type_complexity)]
    pub(crate) fn dense_in(
        &self,
        i: usize,
        x: &nalgebra::DMatrix<f64>,
        x_lo: Option<&nalgebra::DMatrix<f64>>,
        p: usize,
        dd_stages: bool,
    ) -> Result<(Vec<nalgebra::DMatrix<f64>>, Option<nalgebra::DMatrix<f64>>)> {
        match &self.legendre {
            None => Ok((crate::phi::phi_dense(x, p)?, None)),
            Some((k, maps)) => {
                let d = x.nrows();
                let (mut out, lo) = if self.carries_dd(i) && d <= DD_PROPAGATOR_MAX_DIM {
                    let (hi, lo) = crate::phi::expm_dd_split(x, x_lo, false)?;
                    (vec![hi], Some(lo))
                } else if dd_stages && d <= DD_STAGE_PROPAGATOR_MAX_DIM && self.taus[i] <= 1.0 {
                    (vec![crate::phi::expm_dd(x)?.0], None)
                } else {
                    (crate::phi::phi_dense(x, 0)?, None)
                };
                out.extend(k.rows_dense(&maps[i], x)?);
                Ok((out, lo))
            }
        }
    }
}

impl NodeFunctions {
    /// As [`dense`](Self::dense) in f64 only: no double-double propagator.
    pub(crate) fn dense_f64(
        &self,
        i: usize,
        x: &nalgebra::DMatrix<f64>,
        p: usize,
    ) -> Result<Vec<nalgebra::DMatrix<f64>>> {
        match &self.legendre {
            None => crate::phi::phi_dense(x, p),
            Some((k, maps)) => {
                let mut out = crate::phi::phi_dense(x, 0)?;
                out.extend(k.rows_dense(&maps[i], x)?);
                Ok(out)
            }
        }
    }
}

/// Dense operators up to this dimension carry the step's propagator `e^{hA}` in double-double
/// (high and low part) in their kernel banks: O(d³) more set-up, O(d²) per step
/// ([`PhiBank::propagate_dd`](super::PhiBank::propagate_dd)).
pub const DD_PROPAGATOR_MAX_DIM: usize = 256;

/// Dense kernel banks up to this dimension also take the stage propagators `e^{τ_i hA}` (τ < 1)
/// from the double-double exponential, rounded to f64: the f64 scaling and squaring leaves
/// their row sums off by up to 5e−13 at `‖hA‖ = 1e4` (a stage value that does not keep a
/// conserved mean), the rounded double-double by an ulp. The set-up costs about (d/64)³·0.05 s
/// per node more, so larger operators keep the f64 algorithm for the stages. The predictor's
/// nodes beyond the step (τ > 1) are f64 at every dimension: they only start the next step's
/// stage iteration, whose converged values do not depend on how they were started beyond the
/// iteration's tolerance.
pub const DD_STAGE_PROPAGATOR_MAX_DIM: usize = 64;

/// The distinct values of a spectrum (eigenvalues or diagonal entries), so that a bank
/// evaluates its scalar functions once per distinct value and copies them to every mode that
/// shares it. Values are the same when their bits are: the copies are bit for bit what a
/// separate evaluation would give (`-0.0` and `0.0`, or NaNs with different payloads, count as
/// different; a symmetric spectrum whose mirrored values differ in the last bit is not merged).
pub(crate) struct Distinct<T> {
    /// The distinct values (in the order of their bits).
    values: Vec<T>,
    /// `index[mode]`: the position of the mode's value in `values`.
    index: Vec<usize>,
}

impl<T: Copy> Distinct<T> {
    /// The distinct values of `spectrum`, told apart by `key` (the value's bits): O(n log n).
    pub(crate) fn new<K: Ord + Copy>(spectrum: &[T], key: impl Fn(&T) -> K) -> Self {
        let mut order: Vec<(K, usize)> = spectrum
            .iter()
            .enumerate()
            .map(|(mode, v)| (key(v), mode))
            .collect();
        order.sort_unstable();
        let mut values = Vec::new();
        let mut index = vec![0; spectrum.len()];
        let mut last = None;
        for (k, mode) in order {
            if last != Some(k) {
                values.push(spectrum[mode]);
                last = Some(k);
            }
            index[mode] = values.len() - 1;
        }
        Distinct { values, index }
    }

    /// The number of distinct values.
    pub(crate) fn len(&self) -> usize {
        self.values.len()
    }

    /// The distinct values.
    pub(crate) fn values(&self) -> &[T] {
        &self.values
    }

    /// `index[mode]`: the position of the mode's value among the distinct values.
    pub(crate) fn index(&self) -> &[usize] {
        &self.index
    }

    /// As [`bank_entries`](Self::bank_entries), but one column per distinct value instead of
    /// one per mode: `entries[(i (p+1) + k) nu + u]` for the nu distinct values, and per node
    /// the carried numbers per distinct value. The caller maps a mode to its column with
    /// [`index`](Self::index).
    #[allow(clippy::type_complexity)]
    pub(crate) fn distinct_entries<F: Copy, E: Copy>(
        &self,
        len: usize,
        p: usize,
        zero: F,
        carries: impl Fn(usize) -> bool,
        mut eval: impl FnMut(usize, T, &mut [F]) -> E,
    ) -> (Vec<F>, Vec<Option<Vec<E>>>) {
        let nu = self.values.len();
        let mut entries = vec![zero; len * (p + 1) * nu];
        let mut carried = Vec::with_capacity(len);
        let mut extra = Vec::with_capacity(nu);
        let mut row = vec![zero; p + 1];
        for i in 0..len {
            extra.clear();
            let block = &mut entries[i * (p + 1) * nu..(i + 1) * (p + 1) * nu];
            for (u, v) in self.values.iter().enumerate() {
                extra.push(eval(i, *v, &mut row));
                for (k, r) in row.iter().enumerate() {
                    block[k * nu + u] = *r;
                }
            }
            carried.push(carries(i).then(|| extra.clone()));
        }
        (entries, carried)
    }

    /// The entries of a bank with `len` nodes and the slots `0..=p`, evaluated once per node and
    /// distinct value: `eval(i, v, row)` fills `row` (the p + 1 slots at node i and value v) and
    /// returns a number carried at the nodes where `carries(i)` (the propagator's low part or
    /// increment; ignored elsewhere). Returns `entries[(i (p+1) + k) n + mode]` for the n modes
    /// and, per node, the carried numbers per mode where `carries(i)`.
    #[allow(clippy::type_complexity)]
    pub(crate) fn bank_entries<F: Copy, E: Copy>(
        &self,
        len: usize,
        p: usize,
        zero: F,
        carries: impl Fn(usize) -> bool,
        mut eval: impl FnMut(usize, T, &mut [F]) -> E,
    ) -> (Vec<F>, Vec<Option<Vec<E>>>) {
        let (n, nu) = (self.index.len(), self.values.len());
        let mut entries = Vec::with_capacity(len * (p + 1) * n);
        let mut carried = Vec::with_capacity(len);
        // rows[k·nu + u]: slot k at the distinct value u; extra[u]: its carried number.
        let mut rows = vec![zero; (p + 1) * nu];
        let mut extra = Vec::with_capacity(nu);
        let mut row = vec![zero; p + 1];
        for i in 0..len {
            extra.clear();
            for (u, v) in self.values.iter().enumerate() {
                extra.push(eval(i, *v, &mut row));
                for (k, r) in row.iter().enumerate() {
                    rows[k * nu + u] = *r;
                }
            }
            for slot in rows.chunks_exact(nu.max(1)).take(p + 1) {
                entries.extend(self.index.iter().map(|&u| slot[u]));
            }
            carried.push(carries(i).then(|| self.index.iter().map(|&u| extra[u]).collect()));
        }
        (entries, carried)
    }
}

impl Distinct<f64> {
    /// The distinct real values of `spectrum`.
    pub(crate) fn real(spectrum: &[f64]) -> Self {
        Self::new(spectrum, |v| v.to_bits())
    }
}

impl Distinct<num_complex::Complex64> {
    /// The distinct complex values of `spectrum`.
    pub(crate) fn complex(spectrum: &[num_complex::Complex64]) -> Self {
        Self::new(spectrum, |v| (v.re.to_bits(), v.im.to_bits()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distinct_values_are_told_apart_by_their_bits() {
        let spectrum = [
            0.0,
            -2.0,
            -4.0,
            -2.0,
            0.0,
            -0.0,
            3.0,
            -3.0,
            f64::MIN_POSITIVE,
        ];
        let d = Distinct::real(&spectrum);
        // 0 and −0 are different values; each mode maps to a value with its bits.
        assert_eq!(d.values.len(), 7);
        for (mode, v) in spectrum.iter().enumerate() {
            assert_eq!(d.values[d.index[mode]].to_bits(), v.to_bits());
        }
        let d = Distinct::real(&[]);
        assert!(d.values.is_empty() && d.index.is_empty());
        let (entries, carried) = d.bank_entries(2, 1, 0.0, |_| true, |_, _, _| 0.0);
        assert!(entries.is_empty());
        assert_eq!(carried, vec![Some(vec![]), Some(vec![])]);
    }
}
