//! φ-functions of dense matrices: scaling and modified squaring, and the symmetric
//! eigendecomposition path.

use nalgebra::{DMatrix, SMatrix};

use super::factorial::inv_factorial;
use super::scalar::{phi_diagonal, phi_real};
use crate::double_double::{two_prod, two_sum};
use crate::error::{Error, Result};

/// Scaling target: `‖2^{−s} A‖₁ ≤ THETA`.
const THETA: f64 = 1.0;
/// First neglected Taylor term relative to 1: `2⁻⁵⁸ ≈ u/32`.
const TAYLOR_TOL: f64 = 3.469446951953614e-18;
/// `‖A‖₁` above which the scaling `2^{−s}` would leave the normal range.
pub(super) const MAX_NORM: f64 = 1.0e300;
/// Relative asymmetry tolerated by the symmetric paths.
const SYMMETRY_TOL: f64 = 1e-12;

/// `y += a x` entrywise.
#[inline]
pub(super) fn axpy(y: &mut DMatrix<f64>, a: f64, x: &DMatrix<f64>) {
    for (yv, xv) in y.as_mut_slice().iter_mut().zip(x.as_slice()) {
        *yv += a * xv;
    }
}

/// `out = a b` for square matrices of the same size. Up to 5 × 5 by the plain column-major
/// loop (each entry summed in ascending k, the first product not added to 0): the operations
/// nalgebra performs there, without its per-column dispatch (bit for bit `a.mul_to(b, out)`,
/// at a fraction of the cost for the 2 × 2 banks of small systems); larger ones by nalgebra.
pub(super) fn mul_into(a: &DMatrix<f64>, b: &DMatrix<f64>, out: &mut DMatrix<f64>) {
    let n = a.nrows();
    if n > 5 {
        a.mul_to(b, out);
        return;
    }
    let (a, b, o) = (a.as_slice(), b.as_slice(), out.as_mut_slice());
    for j in 0..n {
        let (bj, oj) = (&b[j * n..(j + 1) * n], &mut o[j * n..(j + 1) * n]);
        for (i, oij) in oj.iter_mut().enumerate() {
            let mut acc = a[i] * bj[0];
            for k in 1..n {
                acc += a[k * n + i] * bj[k];
            }
            *oij = acc;
        }
    }
}

/// The 1-norm (maximum absolute column sum).
pub(super) fn norm1(a: &DMatrix<f64>) -> f64 {
    a.column_iter()
        .map(|c| c.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max)
}

pub(crate) fn validate(a: &DMatrix<f64>, what: &'static str) -> Result<()> {
    let (rows, cols) = a.shape();
    if rows != cols {
        return Err(Error::NotSquare { what, rows, cols });
    }
    if a.iter().any(|v| !v.is_finite()) {
        return Err(Error::NonFinite(what));
    }
    Ok(())
}

/// `Err(InvalidInput)` unless `max |a_ij − a_ji| ≤ 1e−12 · max |a_ij|`. `a` must be square.
pub(crate) fn check_symmetric(a: &DMatrix<f64>, what: &str) -> Result<()> {
    let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let n = a.nrows();
    let mut asym = 0.0f64;
    for j in 0..n {
        for i in (j + 1)..n {
            asym = asym.max((a[(i, j)] - a[(j, i)]).abs());
        }
    }
    if asym > SYMMETRY_TOL * scale {
        return Err(Error::InvalidInput(format!(
            "{what} is not symmetric: max |a_ij - a_ji| = {asym:e} > 1e-12 * max |a_ij| = {:e}",
            SYMMETRY_TOL * scale
        )));
    }
    Ok(())
}

/// `Err(Numerical)` if an entry of the φ-functions overflowed, saying why in `cause`.
fn check_finite_result(phis: &[DMatrix<f64>], cause: impl FnOnce() -> String) -> Result<()> {
    if phis.iter().all(|m| m.iter().all(|v| v.is_finite())) {
        Ok(())
    } else {
        Err(Error::Numerical(format!(
            "the phi-functions overflow f64 (an entry beyond {:.1e}): {}; a smaller step \
             size h keeps them finite",
            f64::MAX,
            cause()
        )))
    }
}

/// Why the φ-functions of the general matrix `X` (1-norm `norm`) can overflow: `‖e^X‖ ≤
/// e^{‖X‖}`, reached through eigenvalues with a large positive real part or through the
/// transient growth of a non-normal matrix.
pub(crate) fn overflow_cause(norm: f64) -> String {
    format!(
        "the matrix has 1-norm {norm:.3e}, and e^X can grow up to e^{{1-norm}} (e^x passes \
         f64::MAX at x = {:.2}) through eigenvalues with a large positive real part or the \
         transient growth of a non-normal matrix",
        f64::MAX.ln()
    )
}

/// φ₀(A), …, φ_p(A) for a general (possibly non-normal) square matrix.
///
/// Method (Skaflestad & Wright, 2009, "The scaling and modified squaring method for matrix
/// functions related to the exponential"): with `s = ⌈log₂ ‖A‖₁⌉₊` and `X = 2^{−s}A`
/// (`‖X‖₁ ≤ 1`), the truncated Taylor series `φ_k(X) = Σ_{n≤m} Xⁿ/(n+k)!` (m ≤ 18, truncation
/// below `u/32`) from shared powers of X, then `s` times the doubling formula
///
/// ```text
/// φ_k(2X) = 2^{−k} [φ₀(X) φ_k(X) + Σ_{j=1}^{k} φ_j(X)/(k−j)!]
/// ```
///
/// evaluated as `2^{−k} [E φ_k + 2φ_k + Σ_{j=1}^{k−1} φ_j/(k−j)!]` with `E = φ₀ − I`,
/// `E(2X) = E² + 2E`, which keeps the accuracy of eigen-components near `e⁰` through many
/// doublings. φ₀ is returned either as `I + E` or as the plainly squared `φ₀(X)^{2^s}`,
/// whichever has the smaller error estimate (`(s+1)(1 + ‖E‖₁)` vs `2^s ‖φ₀‖₁` units of
/// roundoff): the squared one keeps relative accuracy when every component decays (e.g. φ₀ ≈ 0
/// for a large matrix with spectrum in the left half-plane), `I + E` when some do not.
///
/// Cost: about `m + s(p + 2)` matrix products. The normwise relative error is of the order
/// of the condition number of the φ-functions times the unit roundoff; for `‖A‖` up to `1e8`
/// no NaN appears (tests/it/phi.rs).
///
/// # Errors
/// [`Error::NotSquare`], [`Error::NonFinite`] for NaN/∞ entries, [`Error::Numerical`] if the
/// result overflows (e^A grows up to e^{‖A‖}: eigenvalues with a large positive real part, or
/// the transient growth of a non-normal matrix) or `‖A‖₁ > 1e300`.
pub fn phi_dense(a: &DMatrix<f64>, p: usize) -> Result<Vec<DMatrix<f64>>> {
    validate(a, "matrix")?;
    let d = a.nrows();
    if d == 0 {
        return Ok(vec![DMatrix::zeros(0, 0); p + 1]);
    }
    if d == 1 {
        let mut buf = vec![0.0; p + 1];
        phi_real(a[(0, 0)], &mut buf);
        let phis: Vec<DMatrix<f64>> = buf
            .iter()
            .map(|&v| DMatrix::from_element(1, 1, v))
            .collect();
        let x = a[(0, 0)];
        check_finite_result(&phis, || format!("the 1 × 1 matrix is x = {x:e}"))?;
        return Ok(phis);
    }
    let norm = norm1(a);
    if norm == 0.0 {
        return Ok((0..=p)
            .map(|k| DMatrix::identity(d, d) * inv_factorial(k))
            .collect());
    }
    if norm > MAX_NORM || !norm.is_finite() {
        return Err(Error::Numerical(format!(
            "matrix 1-norm {norm:e} is too large for scaling and squaring"
        )));
    }
    let mut s: i32 = 0;
    while norm * 0.5f64.powi(s) > THETA {
        s += 1;
    }
    let x = a * 0.5f64.powi(s); // exact: a power of two within the normal range
    let xn = norm * 0.5f64.powi(s);

    // Number of Taylor terms: the first neglected term of φ₀ is ‖X‖^{m+1}/(m+1)!.
    let mut m = 0usize;
    let mut t = 1.0;
    while t > TAYLOR_TOL {
        m += 1;
        t *= xn / m as f64;
    }
    let m = m.max(1);
    // powers[n-1] = X^n
    let mut powers: Vec<DMatrix<f64>> = Vec::with_capacity(m);
    powers.push(x.clone());
    for n in 1..m {
        let next = &powers[n - 1] * &x;
        powers.push(next);
    }
    // E = φ₀(X) − I = Σ_{n≥1} Xⁿ/n!;  φ_k(X) = I/k! + Σ_{n≥1} Xⁿ/(n+k)!  (sum small terms first)
    let series = |k: usize| -> DMatrix<f64> {
        let mut acc = DMatrix::zeros(d, d);
        for n in (1..=m).rev() {
            axpy(&mut acc, inv_factorial(n + k), &powers[n - 1]);
        }
        acc
    };
    let mut e = series(0);
    let mut phis: Vec<DMatrix<f64>> = Vec::with_capacity(p + 1);
    phis.push(DMatrix::zeros(0, 0)); // φ₀ is assembled at the end
    for k in 1..=p {
        let mut phk = series(k);
        for i in 0..d {
            phk[(i, i)] += inv_factorial(k);
        }
        phis.push(phk);
    }
    drop(powers);

    let mut f = e.clone();
    for i in 0..d {
        f[(i, i)] += 1.0;
    }
    let mut tmp = DMatrix::zeros(d, d);
    for _ in 0..s {
        // Top-down so that the old φ_j (j < k) are still available.
        for k in (1..=p).rev() {
            tmp.gemm(1.0, &e, &phis[k], 0.0);
            axpy(&mut tmp, 2.0, &phis[k]);
            for (j, phj) in phis.iter().enumerate().take(k).skip(1) {
                axpy(&mut tmp, inv_factorial(k - j), phj);
            }
            tmp *= 0.5f64.powi(k as i32);
            std::mem::swap(&mut phis[k], &mut tmp);
        }
        tmp.gemm(1.0, &f, &f, 0.0);
        std::mem::swap(&mut f, &mut tmp);
        tmp.gemm(1.0, &e, &e, 0.0);
        axpy(&mut tmp, 2.0, &e);
        std::mem::swap(&mut e, &mut tmp);
    }
    let err_e = f64::from(s + 1) * (1.0 + norm1(&e));
    let err_f = 2f64.powi(s) * norm1(&f);
    phis[0] = if s > 0 && err_f < err_e {
        f
    } else {
        for i in 0..d {
            e[(i, i)] += 1.0;
        }
        e
    };
    check_finite_result(&phis, || overflow_cause(norm))?;
    Ok(phis)
}

/// [`phi_dense`] for a statically sized matrix: `result[k] = φ_k(A)`, `k = 0..=p`.
///
/// Computed through the dynamic path (the result is a `Vec` anyway); same method, accuracy and
/// errors.
///
/// # Errors
/// As [`phi_dense`].
pub fn phi_dense_static<const D: usize>(
    a: &SMatrix<f64, D, D>,
    p: usize,
) -> Result<Vec<SMatrix<f64, D, D>>> {
    let dyn_a = DMatrix::from_column_slice(D, D, a.as_slice());
    let phis = phi_dense(&dyn_a, p)?;
    Ok(phis
        .iter()
        .map(|m| SMatrix::<f64, D, D>::from_column_slice(m.as_slice()))
        .collect())
}

/// Eigendecomposition `A = Q Λ Qᵀ` of a validated symmetric matrix (symmetrised first).
pub(crate) fn symmetric_eigen(a: &DMatrix<f64>) -> Result<(Vec<f64>, DMatrix<f64>)> {
    let d = a.nrows();
    if d == 0 {
        return Ok((Vec::new(), DMatrix::zeros(0, 0)));
    }
    let sym = (a + a.transpose()) * 0.5;
    let max_iter = 1000 * d.max(10);
    let eig = nalgebra::SymmetricEigen::try_new(sym.clone(), f64::EPSILON, max_iter)
        .ok_or_else(|| Error::Numerical("symmetric eigendecomposition did not converge".into()))?;
    let q = eig.eigenvectors;
    let lambda = q
        .column_iter()
        .map(|c| rayleigh_dd(&sym, c.as_slice()))
        .collect();
    Ok((lambda, q))
}

/// The Rayleigh quotient `qᵀAq` (‖q‖ = 1) with `Aq` and the dot product in double-double,
/// rounded once. For a computed eigenvector q (an exact eigenvector of `A + E`, `‖E‖ ≈ ε‖A‖`)
/// it is within `O(ε²‖A‖²/gap)` of the eigenvalue, where the eigensolver's own value is only
/// within `O(ε‖A‖)`: a zero eigenvalue (a conserved quantity) stays 0 to ~ε²‖A‖ instead of
/// ~ε‖A‖, so `e^{hλ}` does not decay it at ‖hA‖ ≫ 1.
fn rayleigh_dd(a: &DMatrix<f64>, q: &[f64]) -> f64 {
    let (mut s, mut c) = (0.0, 0.0);
    for (r, qr) in q.iter().enumerate() {
        // (Aq)_r = rh + rl by Dot2.
        let (mut rh, mut rl) = (0.0, 0.0);
        for (k, qk) in q.iter().enumerate() {
            let (p, e) = two_prod(a[(r, k)], *qk);
            let (t, u) = two_sum(rh, p);
            rh = t;
            rl += u + e;
        }
        let (p, e) = two_prod(*qr, rh);
        let (t, u) = two_sum(s, p);
        s = t;
        c += u + e + qr * rl;
    }
    s + c
}

/// φ₀(A), …, φ_p(A) for a symmetric matrix via `A = QΛQᵀ`, `φ_k(A) = Q φ_k(Λ) Qᵀ`.
///
/// Every eigenvalue goes through [`phi_real`], so stiff eigenvalues (`λ ≪ 0`) cost nothing
/// extra and keep full relative accuracy; the result carries the eigenvector error
/// (orthogonality of Q to a few `d·u`). Faster than [`phi_dense`] for large `‖A‖`.
///
/// # Errors
/// [`Error::NotSquare`], [`Error::NonFinite`], [`Error::InvalidInput`] if
/// `max |a_ij − a_ji| > 1e−12 max |a_ij|`, [`Error::Numerical`] if the eigensolver fails or the
/// result overflows.
pub fn phi_symmetric(a: &DMatrix<f64>, p: usize) -> Result<Vec<DMatrix<f64>>> {
    validate(a, "matrix")?;
    check_symmetric(a, "matrix")?;
    let d = a.nrows();
    let (lambda, q) = symmetric_eigen(a)?;
    let vals = phi_diagonal(&lambda, p);
    let mut phis = Vec::with_capacity(p + 1);
    let qt = q.transpose();
    let mut qd = q.clone();
    for vk in &vals {
        for (j, mut col) in qd.column_iter_mut().enumerate() {
            col.copy_from(&q.column(j));
            col *= vk[j];
        }
        let mut out = DMatrix::zeros(d, d);
        out.gemm(1.0, &qd, &qt, 0.0);
        phis.push(out);
    }
    check_finite_result(&phis, || {
        let top = lambda.iter().fold(f64::NEG_INFINITY, |m, &l| m.max(l));
        format!("the symmetric matrix's largest eigenvalue is {top:.3e}")
    })?;
    Ok(phis)
}
