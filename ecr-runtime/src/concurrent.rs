//! Scheduling of independent pieces of work on rayon's thread pool, for the concurrent stage
//! path of the ECrP stepper on large systems (see
//! [`SolverSettings::parallel_min_dim`](crate::stepper::SolverSettings::parallel_min_dim)).
//!
//! Both helpers split their work recursively with `rayon::join`, which keeps the two halves'
//! jobs on the stack: after the pool has started, they allocate nothing. Every piece is
//! computed by the same call whatever the split, so results do not depend on the number of
//! threads or on the schedule (as long as the work does not depend on what a workspace held on
//! entry).

/// Runs `f` on a thread of rayon's pool (this one if it is one) and returns its result: the
/// concurrent sections inside `f` then hand their jobs between the pool's threads, and a
/// thread outside the pool hands over one job for all of them instead of one per section.
pub(crate) fn in_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    rayon::scope(|_| f())
}

/// The two phases of a spectral bank's concurrent `combine`: `input(k, spec_k, w)` transforms
/// input k into chunk k (of `n`) of `spec`, then `output(j, spec, out_j, w)` forms output block j
/// (chunks of `block`) from all of them; each phase split over the workspaces `wss` as by
/// [`for_each_chunk`].
pub(crate) fn two_phase_combine<W, I, O>(
    spec: &mut [num_complex::Complex64],
    n: usize,
    out: &mut [f64],
    block: usize,
    wss: &mut [W],
    input: &I,
    output: &O,
) where
    W: Send,
    I: Fn(usize, &mut [num_complex::Complex64], &mut W) + Sync,
    O: Fn(usize, &[num_complex::Complex64], &mut [f64], &mut W) + Sync,
{
    in_pool(|| {
        for_each_chunk(spec, n, wss, input);
        let spec = &*spec;
        for_each_chunk(out, block, wss, &|j, o, w| output(j, spec, o, w));
    });
}

/// Calls `f(k, chunk_k, w)` for every chunk `k` of `out` (chunks of `len` ≥ 1, `out.len()` a
/// multiple of it), with the chunks split into contiguous groups, one per workspace of `wss`
/// (at least one), the groups run concurrently and each group's chunks in order.
pub(crate) fn for_each_chunk<T, W, F>(out: &mut [T], len: usize, wss: &mut [W], f: &F)
where
    T: Send,
    W: Send,
    F: Fn(usize, &mut [T], &mut W) + Sync,
{
    split_chunks(0, out, len, wss, f);
}

fn split_chunks<T, W, F>(first: usize, out: &mut [T], len: usize, wss: &mut [W], f: &F)
where
    T: Send,
    W: Send,
    F: Fn(usize, &mut [T], &mut W) + Sync,
{
    let chunks = out.len() / len;
    if chunks < 2 || wss.len() < 2 {
        let w = &mut wss[0];
        for (k, c) in out.chunks_exact_mut(len).enumerate() {
            f(first + k, c, w);
        }
        return;
    }
    // Chunks in proportion to the workspaces (rounded up on the left): 3 chunks on 2
    // workspaces as 2 + 1, 2 on 3 as 1 + 1 (the right one with 2 workspaces).
    let left_ws = wss.len() / 2;
    let left = (chunks * left_ws).div_ceil(wss.len());
    let (oa, ob) = out.split_at_mut(left * len);
    let (wa, wb) = wss.split_at_mut(left_ws);
    rayon::join(
        || split_chunks(first, oa, len, wa, f),
        || split_chunks(first + left, ob, len, wb, f),
    );
}

/// Calls `f(j, out_j, scratch_j)` for every block `j` of `out` (blocks of `d` ≥ 1) with the
/// matching block of `scratch` (blocks of `scratch_len`, which may be 0), each block a task of
/// its own, run concurrently.
pub(crate) fn for_each_block<F>(
    out: &mut [f64],
    d: usize,
    scratch: &mut [f64],
    scratch_len: usize,
    f: &F,
) where
    F: Fn(usize, &mut [f64], &mut [f64]) + Sync,
{
    split_blocks(0, out, d, scratch, scratch_len, f);
}

fn split_blocks<F>(
    first: usize,
    out: &mut [f64],
    d: usize,
    scratch: &mut [f64],
    scratch_len: usize,
    f: &F,
) where
    F: Fn(usize, &mut [f64], &mut [f64]) + Sync,
{
    let blocks = out.len() / d;
    if blocks == 0 {
        return;
    }
    if blocks == 1 {
        f(first, out, &mut scratch[..scratch_len]);
        return;
    }
    let half = blocks / 2;
    let (oa, ob) = out.split_at_mut(half * d);
    let (sa, sb) = scratch.split_at_mut(half * scratch_len);
    rayon::join(
        || split_blocks(first, oa, d, sa, scratch_len, f),
        || split_blocks(first + half, ob, d, sb, scratch_len, f),
    );
}

#[cfg(test)]
mod tests {
    use super::{for_each_block, for_each_chunk};

    #[test]
    fn every_chunk_once_with_its_index() {
        for chunks in 0..7 {
            for workspaces in 1..5 {
                let mut out = vec![0usize; 3 * chunks];
                let mut wss = vec![0usize; workspaces];
                for_each_chunk(
                    &mut out,
                    3,
                    &mut wss,
                    &|k, c: &mut [usize], w: &mut usize| {
                        c.fill(k + 1);
                        *w += 1;
                    },
                );
                let expected: Vec<usize> = (0..chunks).flat_map(|k| [k + 1; 3]).collect();
                assert_eq!(out, expected, "{chunks} chunks, {workspaces} workspaces");
                assert_eq!(wss.iter().sum::<usize>(), chunks);
            }
        }
    }

    #[test]
    fn every_block_once_with_its_scratch() {
        for blocks in 0..6 {
            for scratch_len in [0, 2] {
                let mut out = vec![0.0; 2 * blocks];
                let mut scratch = vec![0.0; scratch_len * blocks];
                for_each_block(&mut out, 2, &mut scratch, scratch_len, &|j, o, s| {
                    o.fill(j as f64);
                    s.fill(-(j as f64));
                    assert_eq!(s.len(), scratch_len);
                });
                let expected: Vec<f64> = (0..blocks).flat_map(|j| [j as f64; 2]).collect();
                assert_eq!(out, expected);
                let expected: Vec<f64> = (0..blocks)
                    .flat_map(|j| vec![-(j as f64); scratch_len])
                    .collect();
                assert_eq!(scratch, expected);
            }
        }
    }
}
