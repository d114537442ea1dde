//! The matrix–vector product of the fused step ([`gemv_cm`]): one order of operations whatever
//! the compiler knows of the sizes, so that fixed-size and run-time steppers round alike.

/// `out = init + M x` for a column-major matrix `M` with `rows` rows and `x = (x₁, x₂)` (two
/// slices, read as one vector: `M` has `x₁.len() + x₂.len()` columns); `init` absent is zero.
/// Each entry is summed from `init` over the columns in order, one product and one addition
/// per column (no fused multiply-add), so that every caller rounds identically whatever it
/// knows of the sizes at compile time. The rows go in blocks of 8, 4, 2 and 1 whose sums stay
/// in registers. Does not allocate.
///
/// Every linear map of a fused step is one call: the sweep (`M` the stage matrices, `x` = g at
/// the stages, `init` = `e^{cᵢhA} y₀`), the propagated starts, the predictor and the end of the
/// step ([`FusedMaps`](super::FusedMaps)).
///
/// # Panics
/// If `mat` has fewer than `rows · cols` entries, or `out` (and `init`) fewer than `rows`.
// Always inlined: in a fixed-order stepper the sizes are constants and the loops unroll.
#[inline(always)]
pub fn gemv_cm(mat: &[f64], rows: usize, xs: [&[f64]; 2], init: Option<&[f64]>, out: &mut [f64]) {
    let cols = xs[0].len() + xs[1].len();
    let (mat, out) = (&mat[..rows * cols], &mut out[..rows]);
    let init = init.map(|v| &v[..rows]);
    let mut r0 = 0;
    while r0 < rows {
        r0 += match rows - r0 {
            8.. => gemv_rows::<8>(mat, rows, r0, xs, init, out),
            4.. => gemv_rows::<4>(mat, rows, r0, xs, init, out),
            2.. => gemv_rows::<2>(mat, rows, r0, xs, init, out),
            _ => gemv_rows::<1>(mat, rows, r0, xs, init, out),
        };
    }
}

/// Rows `r0..r0 + N` of [`gemv_cm`]; returns N.
#[inline(always)]
fn gemv_rows<const N: usize>(
    mat: &[f64],
    rows: usize,
    r0: usize,
    xs: [&[f64]; 2],
    init: Option<&[f64]>,
    out: &mut [f64],
) -> usize {
    let mut acc = [0.0_f64; N];
    if let Some(init) = init {
        acc.copy_from_slice(&init[r0..r0 + N]);
    }
    let mut col = r0;
    for x in xs {
        for &xc in x {
            let m: &[f64; N] = mat[col..col + N].try_into().expect("N rows");
            for (a, mv) in acc.iter_mut().zip(m) {
                *a += mv * xc;
            }
            col += rows;
        }
    }
    out[r0..r0 + N].copy_from_slice(&acc);
    N
}
