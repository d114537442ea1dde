//! The concurrent stage path of large systems
//! ([`SolverSettings::parallel_min_dim`](super::SolverSettings::parallel_min_dim)): the memory it
//! needs besides the serial path's buffers, and the moments computed concurrently. The bank's
//! concurrent operations are the bank's own ([`PhiBank::combine_concurrent`], [`PhiBank::join`]).

use super::kernel::Kernel;
use crate::concurrent::for_each_chunk;
use crate::operator::PhiBank;

/// What the concurrent stage path
/// ([`SolverSettings::parallel_min_dim`](super::SolverSettings::parallel_min_dim)) uses besides the
/// serial path's buffers, allocated with the bank (never per step).
pub(super) struct ParallelState<W> {
    /// One workspace per concurrent task of the bank's operations: as many as rayon's pool has
    /// threads, at least 2 (the end of a step runs two tasks) and at most max(s, r + 1) (the
    /// pieces of a `combine` over the stage nodes).
    pub(super) helpers: Vec<W>,
    /// A scratch of [`System::scratch_len`](crate::system::System::scratch_len) per stage, for g at
    /// the stages.
    pub(super) scratch: Vec<f64>,
    /// The kernel's ℓ_kj (k < r, j < s, at `k·s + j`), for the moments.
    ell: Vec<f64>,
    /// s.
    s: usize,
    /// As many units as `helpers`: the tasks of the moments, which need no workspace.
    tasks: Vec<()>,
}

impl<W> ParallelState<W> {
    /// The state for a system of dimension d with scratch `scratch_len`, s stages and r
    /// moments, if d ≥ `min_dim`. Starts rayon's pool (once per process), so that steps do
    /// not allocate.
    pub(super) fn new<K: Kernel, Bk: PhiBank<Workspace = W>>(
        kernel: &K,
        bank: &Bk,
        min_dim: usize,
        scratch_len: usize,
    ) -> Option<Box<Self>> {
        let (s, r) = (kernel.s(), kernel.r());
        (bank.dim() >= min_dim).then(|| {
            let tasks = rayon::current_num_threads().clamp(2, s.max(r + 1));
            // ℓ_kj: the moments of the unit vectors (d = 1), exact (one term is ℓ_kj · 1, the
            // others ℓ · 0).
            let mut ell = vec![0.0; r * s];
            let (mut unit, mut mom) = (vec![0.0; s], vec![0.0; r]);
            for j in 0..s {
                unit.fill(0.0);
                unit[j] = 1.0;
                kernel.legendre_moments(&unit, &mut mom, 1);
                for k in 0..r {
                    ell[k * s + j] = mom[k];
                }
            }
            Box::new(ParallelState {
                helpers: (0..tasks).map(|_| bank.workspace()).collect(),
                scratch: vec![0.0; s * scratch_len],
                ell,
                s,
                tasks: vec![(); tasks],
            })
        })
    }

    /// [`Kernel::legendre_moments`] with the moments (each in two halves where d is even)
    /// computed concurrently: bit for bit the kernel's, whose contract fixes the arithmetic
    /// (each sum from 0.0, terms `ℓ_kj g_j` in the order j = 0, 1, …).
    pub(super) fn moments(&mut self, g: &[f64], m: &mut [f64], d: usize) {
        let (ell, s) = (&self.ell, self.s);
        let parts = if d % 2 == 0 { 2 } else { 1 };
        let len = d / parts;
        for_each_chunk(m, len, &mut self.tasks, &|q, mk: &mut [f64], _: &mut ()| {
            let (k, at) = (q / parts, (q % parts) * len);
            mk.fill(0.0);
            for j in 0..s {
                let w = ell[k * s + j];
                for (x, gv) in mk.iter_mut().zip(&g[j * d + at..j * d + at + len]) {
                    *x += w * gv;
                }
            }
        });
    }
}
