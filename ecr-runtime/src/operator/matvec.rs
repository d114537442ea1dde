//! Dense matrix–vector products on slices, shared by the dense and oscillator banks: plain
//! (nalgebra's gemv) and in double-double.

use nalgebra::{DMatrix, DVectorView, DVectorViewMut};

use crate::phi::{two_prod, two_sum};

/// `hi + lo = (Mh + Ml) x` in double-double (Dot2 on the high part), without allocation.
pub(super) fn matvec_dd<R: nalgebra::Dim, C: nalgebra::Dim, S: nalgebra::RawStorage<f64, R, C>>(
    mh: &nalgebra::Matrix<f64, R, C, S>,
    ml: &nalgebra::Matrix<f64, R, C, S>,
    x: &[f64],
    hi: &mut [f64],
    lo: &mut [f64],
) {
    let (rows, cols) = mh.shape();
    assert!(x.len() == cols && hi.len() == rows && lo.len() == rows);
    for r in 0..rows {
        let (mut s, mut c) = (0.0, 0.0);
        for (k, xv) in x.iter().enumerate() {
            let (p, e) = two_prod(mh[(r, k)], *xv);
            let (t, q) = two_sum(s, p);
            s = t;
            c += q + e + ml[(r, k)] * xv;
        }
        let (h, l) = two_sum(s, c);
        hi[r] = h;
        lo[r] = l;
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
