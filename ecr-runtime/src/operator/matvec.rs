//! Dense matrix–vector products on slices, shared by the dense and oscillator banks: plain
//! (nalgebra's gemv) and in double-double.

use nalgebra::{DMatrix, DVectorView, DVectorViewMut};

use crate::phi::{two_prod, two_sum};

/// `hi + lo = (Mh + Ml) x` in double-double (Dot2 on the high part), without allocation.
///
/// # Panics
/// If the shapes of `mh`, `ml`, `x`, `hi` and `lo` do not agree.
pub(super) fn matvec_dd<R, C, S>(
    mh: &nalgebra::Matrix<f64, R, C, S>,
    ml: &nalgebra::Matrix<f64, R, C, S>,
    x: &[f64],
    hi: &mut [f64],
    lo: &mut [f64],
) where
    R: nalgebra::Dim,
    C: nalgebra::Dim,
    S: nalgebra::RawStorage<f64, R, C> + nalgebra::IsContiguous,
{
    assert!(ml.shape() == mh.shape() && hi.len() == mh.nrows() && x.len() == mh.ncols());
    matvec_dd_slices(mh.as_slice(), ml.as_slice(), x, hi, lo);
}

/// [`matvec_dd`] on column-major slices (`mh`, `ml`: `hi.len() × x.len()`).
///
/// # Panics
/// If the shapes do not agree.
pub(super) fn matvec_dd_slices(mh: &[f64], ml: &[f64], x: &[f64], hi: &mut [f64], lo: &mut [f64]) {
    let rows = hi.len();
    assert!(
        mh.len() == rows * x.len() && ml.len() == mh.len() && lo.len() == rows,
        "matvec_dd_slices: shapes"
    );
    matvec_dd_cm(rows, (mh, ml), x, (hi, lo));
}

/// [`matvec_dd`] on column-major slices, row by row (each entry's sum over k in order).
/// Compiled twice and chosen at run time by the CPU (`multiversion`), as `phi::dense`'s
/// double-double product: with fused multiply-add where the processor has it (`two_prod`'s
/// `mul_add` one instruction instead of a call into the maths library: on Duffing, where the
/// compensated end of every step takes `e^{hA} y₀` in double-double through here, the product
/// was 8 % of `ecr run`), else for the baseline x86-64. `mul_add` rounds correctly either
/// way: the same bits.
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn matvec_dd_cm(
    rows: usize,
    (mh, ml): (&[f64], &[f64]),
    x: &[f64],
    (hi, lo): (&mut [f64], &mut [f64]),
) {
    for (r, (hr, lr)) in hi.iter_mut().zip(lo.iter_mut()).enumerate() {
        let (mut s, mut c) = (0.0, 0.0);
        for (k, &xv) in x.iter().enumerate() {
            let (a, a_lo) = (mh[k * rows + r], ml[k * rows + r]);
            let (p, e) = two_prod(a, xv);
            let (t, q) = two_sum(s, p);
            s = t;
            c += q + e + a_lo * xv;
        }
        (*hr, *lr) = two_sum(s, c);
    }
}

/// `y = M x` (or `y = α M x + β y`) on slices, without allocation.
#[inline]
pub(super) fn gemv(y: &mut [f64], alpha: f64, m: &DMatrix<f64>, x: &[f64], beta: f64) {
    let n = x.len();
    let mut yv = DVectorViewMut::from_slice(y, m.nrows());
    yv.gemv(alpha, m, &DVectorView::from_slice(x, n), beta);
}

/// `y = Mᵀ x` on slices, without allocation.
#[inline]
pub(super) fn gemv_tr(y: &mut [f64], m: &DMatrix<f64>, x: &[f64]) {
    let n = x.len();
    let mut yv = DVectorViewMut::from_slice(y, m.ncols());
    yv.gemv_tr(1.0, m, &DVectorView::from_slice(x, n), 0.0);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `matvec_dd` (the CPU's version) gives every entry bit for bit as the row-by-row Dot2
    /// it replaced, with `mul_add` as it rounds in any build: mixed signs and
    /// magnitudes, shapes not a multiple of a vector width, a fixed-size matrix as the 2 × 2
    /// banks hold them.
    #[test]
    fn matvec_dd_is_row_times_x_bit_for_bit() {
        let mut rng = crate::test_rng::XorShift(0x2545_F491_4F6C_DD1D);
        let mut next = move || rng.mixed(8);
        let reference = |mh: &[f64], ml: &[f64], rows: usize, x: &[f64]| {
            (0..rows)
                .map(|r| {
                    let (mut s, mut c) = (0.0, 0.0);
                    for (k, xv) in x.iter().enumerate() {
                        let (a, a_lo) = (mh[k * rows + r], ml[k * rows + r]);
                        let (p, e) = (a * xv, a.mul_add(*xv, -(a * xv)));
                        let (t, q) = two_sum(s, p);
                        s = t;
                        c += q + e + a_lo * xv;
                    }
                    two_sum(s, c)
                })
                .collect::<Vec<_>>()
        };
        for (rows, cols) in [(1, 1), (2, 2), (7, 3), (19, 19)] {
            let mh: Vec<f64> = (0..rows * cols).map(|_| next()).collect();
            let ml: Vec<f64> = mh
                .iter()
                .map(|h| h * f64::EPSILON * 0.25 * next())
                .collect();
            let x: Vec<f64> = (0..cols).map(|_| next()).collect();
            let (mh_m, ml_m) = (
                DMatrix::from_column_slice(rows, cols, &mh),
                DMatrix::from_column_slice(rows, cols, &ml),
            );
            let (mut hi, mut lo) = (vec![f64::NAN; rows], vec![f64::NAN; rows]);
            matvec_dd(&mh_m, &ml_m, &x, &mut hi, &mut lo);
            for (r, (h, l)) in reference(&mh, &ml, rows, &x).into_iter().enumerate() {
                assert_eq!(hi[r].to_bits(), h.to_bits(), "{rows} × {cols}, row {r}");
                assert_eq!(lo[r].to_bits(), l.to_bits(), "{rows} × {cols}, row {r}");
            }
        }
        let (mh, ml) = ([0.3, -1.7, 2.5e-3, 0.9], [1e-17, -3e-17, 2e-20, 4e-17]);
        let x = [0.7, -1.1];
        let (mut hi, mut lo) = ([0.0; 2], [0.0; 2]);
        matvec_dd(
            &nalgebra::Matrix2::from_column_slice(&mh),
            &nalgebra::Matrix2::from_column_slice(&ml),
            &x,
            &mut hi,
            &mut lo,
        );
        for (r, (h, l)) in reference(&mh, &ml, 2, &x).into_iter().enumerate() {
            assert_eq!(
                (hi[r].to_bits(), lo[r].to_bits()),
                (h.to_bits(), l.to_bits())
            );
        }
    }
}
