//! Small systems' steps as dense maps ([`FusedMaps`]): the stage matrices that fuse the moments
//! and the kernels of a sweep into one linear map ([`stage_matrices`], also Newton's
//! `∂Φ/∂g`), when that is cheaper ([`fuses_stages`]), and the other linear maps of a step.

use super::kernel::Kernel;
use crate::operator::PhiBank;

/// The stage matrices of ECrP: `M_ik = Σ_j coef_ij ℓ_jk Ψ_j(cᵢ, hA)` (`coef_ij = h cᵢ (2j+1)`,
/// `ℓ_jk = b_k P̃_j(c_k)`), so that the stage equations read `Y_i = e^{cᵢhA} y₀ + Σ_k M_ik g(Y_k)`:
/// the moments and the kernels fused into one linear map, and `∂Φ_i/∂g_k` for Newton. One
/// column-major `sd × sd` matrix: entry (a, b) of block `M_ik` is at row `i·d + a` of column `k·d +
/// b`, so that a sweep is one matrix–vector product ([`gemv_cm`](super::gemv_cm)); each entry is
/// summed over j = 0, 1, … from 0.0. Built from `s·r·d` applications of the kernel bank (once per
/// step size).
pub fn stage_matrices<K: Kernel, Bk: PhiBank>(
    kernel: &K,
    bank: &Bk,
    coef: &[f64],
    ws: &mut Bk::Workspace,
    d: usize,
) -> Vec<f64> {
    let (s, m) = (kernel.s(), kernel.r());
    // ℓ_jk: the Legendre moments of the unit vectors (d = 1).
    let mut ell = vec![0.0; m * s];
    let (mut unit, mut mom) = (vec![0.0; s], vec![0.0; m]);
    for k in 0..s {
        unit.fill(0.0);
        unit[k] = 1.0;
        kernel.legendre_moments(&unit, &mut mom, 1);
        for j in 0..m {
            ell[j * s + k] = mom[j];
        }
    }
    let sd = s * d;
    let mut q = vec![0.0; sd * sd];
    let (mut e, mut col) = (vec![0.0; d], vec![0.0; d]);
    for i in 0..s {
        for l in 0..d {
            e.fill(0.0);
            e[l] = 1.0;
            for j in 0..m {
                bank.apply(i, j + 1, &e, &mut col, ws);
                for k in 0..s {
                    let c = coef[i * m + j] * ell[j * s + k];
                    let start = (k * d + l) * sd + i * d;
                    for (a, b) in q[start..start + d].iter_mut().zip(&col) {
                        *a += c * b;
                    }
                }
            }
        }
    }
    q
}

/// The most entries (`s²d²`) the fused stage matrices may have: 8 MiB.
pub const FUSED_MAX_ENTRIES: usize = 1 << 20;

/// Whether ECrP fuses its sweeps for this bank: the bank states the cost of its `combine`
/// ([`PhiBank::combine_cost`]: dense matrices, or the 2 × 2 block of a one-mode oscillator),
/// and the fused sweep, `s²d²` multiply-adds, costs no more than the moments and `combine`,
/// `rsd + s · cost` (dense: `sd ≤ (r+1)d + r`, i.e. s = r or r + 1 for most d), within
/// [`FUSED_MAX_ENTRIES`].
pub fn fuses_stages<Bk: PhiBank>(bank: &Bk, r: usize, s: usize) -> bool {
    let d = bank.dim();
    let fused = s.saturating_mul(s).saturating_mul(d).saturating_mul(d);
    bank.combine_cost(r).is_some_and(|c| {
        fused <= s.saturating_mul(c).saturating_add(r * s * d) && fused <= FUSED_MAX_ENTRIES
    })
}

/// A small system's step as dense maps, built with the bank where [`fuses_stages`]: each linear map
/// of a step is one column-major matrix applied by [`gemv_cm`](super::gemv_cm), instead of
/// `combine` calls (whose cost per call dominates at small d). Entries are the bank's functions
/// scaled by the combine coefficients (`h τ (2j+1)` for the kernel of degree j), one rounding each.
#[derive(Clone, Debug)]
pub struct FusedMaps {
    /// The stage matrices ([`stage_matrices`]): `sd × sd`.
    pub stage: Vec<f64>,
    /// `e^{cᵢhA}` stacked: `sd × d`.
    pub props: Vec<f64>,
    /// The end of the step, `d × (d + rd)`: `[e^{hA} | h(2j+1)Ψ_j(1, hA), j < r]`, applied to
    /// `(y₀, L₀..L_{r−1})`.
    pub end: Vec<f64>,
    /// The extrapolating predictor, `sd × (d + rd)`: block row i is `[e^{(1+cᵢ)hA} | h(1+cᵢ)
    /// (2j+1)Ψ_j(1+cᵢ, hA), j < r]`, applied to the previous step's `(y₀, L)`; empty without
    /// the predictor.
    pub pred: Vec<f64>,
}

/// Writes `scale ·` the bank's function `(i, k)` into rows `row0..row0 + d` and columns
/// `col0..col0 + d` of the column-major matrix `mat` with `rows` rows (column l from the bank
/// applied to the unit vector e_l: exact).
#[allow(clippy::too_many_arguments)]
fn bank_block<Bk: PhiBank>(
    bank: &Bk,
    ws: &mut Bk::Workspace,
    (i, k): (usize, usize),
    scale: f64,
    mat: &mut [f64],
    rows: usize,
    (row0, col0): (usize, usize),
    d: usize,
) {
    let (mut e, mut col) = (vec![0.0; d], vec![0.0; d]);
    for l in 0..d {
        e.fill(0.0);
        e[l] = 1.0;
        bank.apply(i, k, &e, &mut col, ws);
        let start = (col0 + l) * rows + row0;
        for (a, c) in mat[start..start + d].iter_mut().zip(&col) {
            *a = scale * c;
        }
    }
}

/// The [`FusedMaps`] of a bank built for the nodes `c₁..c_s`, 1 (and `1 + cᵢ` with the
/// predictor), with its combine coefficients `coef`.
pub(super) fn fused_maps<K: Kernel, Bk: PhiBank>(
    kernel: &K,
    bank: &Bk,
    coef: &[f64],
    ws: &mut Bk::Workspace,
    d: usize,
    predictor: bool,
) -> FusedMaps {
    let (s, m) = (kernel.s(), kernel.r());
    let (sd, cols) = (s * d, d + m * d);
    let mut props = vec![0.0; sd * d];
    for i in 0..s {
        bank_block(bank, ws, (i, 0), 1.0, &mut props, sd, (i * d, 0), d);
    }
    // Rows `row0..row0 + d` of `[e^{τhA} | coef·Ψ_j(τ, hA)]` for the bank's node `node`.
    let mut node_row = |mat: &mut [f64], rows: usize, node: usize, row0: usize| {
        bank_block(bank, ws, (node, 0), 1.0, mat, rows, (row0, 0), d);
        for j in 0..m {
            let c = coef[node * m + j];
            bank_block(bank, ws, (node, j + 1), c, mat, rows, (row0, d + j * d), d);
        }
    };
    let mut end = vec![0.0; d * cols];
    node_row(&mut end, d, s, 0);
    let mut pred = Vec::new();
    if predictor {
        pred = vec![0.0; sd * cols];
        for i in 0..s {
            node_row(&mut pred, sd, s + 1 + i, i * d);
        }
    }
    FusedMaps {
        stage: stage_matrices(kernel, bank, coef, ws, d),
        props,
        end,
        pred,
    }
}
