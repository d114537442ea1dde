//! The argument checks shared by the operators and their banks.

use std::ops::Range;

use crate::error::{Error, Result};

/// Validates the arguments of [`LinearOperator::phi_bank`](super::LinearOperator::phi_bank).
pub(crate) fn check_bank_args(h: f64, taus: &[f64]) -> Result<()> {
    if !(h.is_finite() && h > 0.0) {
        return Err(Error::InvalidStepSize(h));
    }
    if taus.iter().any(|t| !t.is_finite()) {
        return Err(Error::NonFinite("taus"));
    }
    Ok(())
}

/// Validates [`check_bank_args`] and that τ·h·A stays in the f64 range for an operator whose
/// largest entry (or eigenvalue) in magnitude is `amax`: otherwise an overflow there would be
/// reported later as a non-finite matrix, without naming its cause (a step size far too large
/// for the operator).
pub(crate) fn check_bank_scale(h: f64, taus: &[f64], amax: f64) -> Result<()> {
    check_bank_args(h, taus)?;
    let tmax = taus.iter().fold(0.0_f64, |m, t| m.max(t.abs()));
    if !(tmax * h * amax).is_finite() {
        return Err(Error::InvalidInput(format!(
            "the step size h = {h:?} is too large for the linear part A (max |entry| {amax:?}): \
             τ·h·A overflows the f64 range"
        )));
    }
    Ok(())
}

/// `Err(Numerical)` if a bank entry overflowed, saying why in `cause` (the numbers of τhA
/// that make it overflow).
pub(crate) fn check_bank_values(
    values: impl IntoIterator<Item = f64>,
    cause: impl FnOnce() -> String,
) -> Result<()> {
    if values.into_iter().all(f64::is_finite) {
        Ok(())
    } else {
        Err(Error::Numerical(format!(
            "phi-function overflow in the bank (an entry beyond {:.1e}): {}; a smaller step \
             size h keeps it finite",
            f64::MAX,
            cause()
        )))
    }
}

/// The cause of an overflow for real eigenvalues (or diagonal entries) `values` of A at the
/// nodes `taus` and step `h`: the largest `τ h λ`, against `ln f64::MAX`.
pub(crate) fn real_overflow_cause(values: &[f64], h: f64, taus: &[f64]) -> String {
    let top = taus
        .iter()
        .flat_map(|t| values.iter().map(move |l| t * h * l))
        .fold(f64::NEG_INFINITY, f64::max);
    format!(
        "the largest τ·h·λ over the eigenvalues λ of A is {top:.3e}, and e^x passes f64::MAX \
         at x = {:.2}",
        f64::MAX.ln()
    )
}

/// Validates the shapes of a [`PhiBank::combine`](super::PhiBank::combine) call and returns
/// `m` (see [`PhiBank::validate_combine`](super::PhiBank::validate_combine)). Allocates only
/// when returning an error.
#[allow(clippy::too_many_arguments)]
pub(crate) fn combine_shape_checked(
    d: usize,
    len: usize,
    p: usize,
    indices: &Range<usize>,
    y0: &[f64],
    g: &[f64],
    coef: &[f64],
    out: &[f64],
) -> Result<usize> {
    if indices.start > indices.end || indices.end > len {
        return Err(Error::InvalidInput(format!(
            "combine: node indices {indices:?} outside 0..{len}"
        )));
    }
    let nb = indices.len();
    if y0.len() != d {
        return Err(Error::DimensionMismatch {
            what: "combine: y0",
            expected: d,
            found: y0.len(),
        });
    }
    if out.len() != d * nb {
        return Err(Error::DimensionMismatch {
            what: "combine: out (dim * number of nodes)",
            expected: d * nb,
            found: out.len(),
        });
    }
    if d == 0 {
        return Ok(0);
    }
    if g.len() % d != 0 {
        return Err(Error::InvalidInput(format!(
            "combine: g has length {}, not a multiple of the dimension {d}",
            g.len()
        )));
    }
    let m = g.len() / d;
    if m > p {
        return Err(Error::InvalidParameter(format!(
            "combine: {m} g-blocks, but the bank holds phi_1..phi_{p} only"
        )));
    }
    if coef.len() != m * nb {
        return Err(Error::DimensionMismatch {
            what: "combine: coef (g-blocks * number of nodes)",
            expected: m * nb,
            found: coef.len(),
        });
    }
    Ok(m)
}

/// [`combine_shape_checked`], panicking on error (for
/// [`PhiBank::combine`](super::PhiBank::combine)).
#[inline]
#[allow(clippy::too_many_arguments)]
pub(crate) fn combine_shape(
    d: usize,
    len: usize,
    p: usize,
    indices: &Range<usize>,
    y0: &[f64],
    g: &[f64],
    coef: &[f64],
    out: &[f64],
) -> usize {
    match combine_shape_checked(d, len, p, indices, y0, g, coef, out) {
        Ok(m) => m,
        Err(e) => panic!("{e}"),
    }
}

/// Checks the arguments of [`PhiBank::apply`](super::PhiBank::apply).
#[inline]
pub(crate) fn apply_shape(
    d: usize,
    len: usize,
    p: usize,
    i: usize,
    k: usize,
    x: &[f64],
    out: &[f64],
) {
    assert!(i < len, "apply: node index {i} outside 0..{len}");
    assert!(
        k <= p,
        "apply: phi_{k} requested, the bank holds phi_0..phi_{p}"
    );
    assert_eq!(x.len(), d, "apply: x has length {}, expected {d}", x.len());
    assert_eq!(
        out.len(),
        d,
        "apply: out has length {}, expected {d}",
        out.len()
    );
}
