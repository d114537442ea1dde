//! The double-double exponential of a dense matrix ([`expm_dd`], [`expm_dd_split`]): the
//! step's propagator of the default banks, whose f64 rounding repeated every step would be a
//! linear energy drift in long runs (docs/banks.md §1).

use nalgebra::DMatrix;

use super::dense::{MAX_NORM, norm1, overflow_cause, validate};
use crate::double_double::{two_prod, two_sum};
use crate::error::{Error, Result};

/// `C = A B` for double-double matrices `A = (ah, al)`, `B = (bh, bl)` (n × n, column-major
/// slices), written into `(ch, cl)`: the `ah·bh` part by the compensated dot product Dot2
/// (Ogita, Rump & Oishi, 2005: as accurate as if computed in twice the working precision), the
/// cross terms in f64; the low parts are ≤ 2⁻⁵³ of the high ones. With `lower`, only the
/// entries on and below the diagonal are computed and the upper ones copied from them: for a
/// product known to be symmetric (two commuting symmetric matrices), at half the cost.
///
/// Every entry's sum runs over k in order, as a dot product would; the loop over the rows i is
/// the innermost, with `(ch, cl)`'s column as the n running sums: A's columns are read
/// contiguously and the n chains of dependent additions are independent of each other, so they
/// pipeline (and vectorise) instead of waiting on one another, with the same operations on
/// every entry as row-times-column would do (the same bits). Compiled twice and chosen at run
/// time by the CPU (`multiversion`): with fused multiply-add and AVX2 where the processor has
/// them (`two_prod`'s `mul_add` is then one instruction and the chains vectorise), else for the
/// baseline x86-64, where `mul_add` is a call into the maths library. Both round `mul_add`
/// correctly: the same bits either way.
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn mul_dd(
    n: usize,
    (ah, al): (&[f64], &[f64]),
    (bh, bl): (&[f64], &[f64]),
    (ch, cl): (&mut [f64], &mut [f64]),
    lower: bool,
) {
    for j in 0..n {
        let first = if lower { j } else { 0 };
        let (sum, comp) = (
            &mut ch[j * n + first..][..n - first],
            &mut cl[j * n + first..][..n - first],
        );
        sum.fill(0.0);
        comp.fill(0.0);
        for k in 0..n {
            let (b, b_lo) = (bh[j * n + k], bl[j * n + k]);
            let (a_col, a_lo_col) = (
                &ah[k * n + first..][..n - first],
                &al[k * n + first..][..n - first],
            );
            for (((s, c), &a), &a_lo) in
                sum.iter_mut().zip(comp.iter_mut()).zip(a_col).zip(a_lo_col)
            {
                let (p, e) = two_prod(a, b);
                let (t, q) = two_sum(*s, p);
                *s = t;
                *c += q + e + (a * b_lo + a_lo * b);
            }
        }
        for (s, c) in sum.iter_mut().zip(comp.iter_mut()) {
            (*s, *c) = two_sum(*s, *c);
        }
    }
    if lower {
        for j in 0..n {
            for i in j + 1..n {
                ch[i * n + j] = ch[j * n + i];
                cl[i * n + j] = cl[j * n + i];
            }
        }
    }
}

/// `(h, l) += (ch, cl)·(xh, xl)` entrywise for a double-double scalar c and matrix x (the
/// product's low-order cross terms in f64, the sum by two-sum).
fn axpy_dd((h, l): (&mut [f64], &mut [f64]), (ch, cl): (f64, f64), (xh, xl): (&[f64], &[f64])) {
    for (((hv, lv), &x), &x_lo) in h.iter_mut().zip(l.iter_mut()).zip(xh).zip(xl) {
        let (p, e) = two_prod(ch, x);
        let (t, q) = two_sum(*hv, p);
        let low = *lv + q + e + (ch * x_lo + cl * x);
        (*hv, *lv) = two_sum(t, low);
    }
}

/// Degree of the Taylor polynomial of [`expm_dd_split`]: at `‖Y‖₁ ≤ 1/2` the first term left
/// out is below `2⁻²⁷/28! ≈ 2.5e−38`.
const DD_TAYLOR_DEGREE: usize = 27;
/// Block size of the Paterson–Stockmeyer evaluation: powers `Y²…Y⁵`, then Horner in `Y⁵`
/// over six blocks: 9 products for the degree 27 (Horner alone: 27).
const DD_PS_BLOCK: usize = 5;

/// `1/k!`, `k ≤ n`, in double-double (`(1/(k−1)!)/k` with the remainder of each division
/// carried: relative error a few units of 2⁻¹⁰⁶).
fn inv_factorials_dd(n: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(n + 1);
    let (mut h, mut l) = (1.0f64, 0.0f64);
    out.push((h, l));
    for k in 1..=n {
        let kf = k as f64;
        let q = h / kf;
        let rem = (-q).mul_add(kf, h);
        (h, l) = two_sum(q, (rem + l) / kf);
        out.push((h, l));
    }
    out
}

/// `e^X` in double-double: `(hi, lo)` with `hi + lo = e^X` to about `2⁻¹⁰⁴ ‖e^X‖` for `X`
/// taken as exact, by scaling (`‖2^{−s}X‖₁ ≤ 1/2`), the Taylor polynomial of degree 27
/// (truncation below 1e−36) by Paterson–Stockmeyer and s double-double squarings: about
/// (9 + s) products, each a few times the price of an f64 product. For the propagator of small
/// dense operators, whose f64 rounding, repeated every step, is a linear energy drift in long
/// runs.
///
/// # Errors
/// As [`phi_dense`](super::phi_dense) (a validated square matrix with `‖X‖₁ ≤ 1e300`; overflow is an error).
pub(crate) fn expm_dd(x: &DMatrix<f64>) -> Result<(DMatrix<f64>, DMatrix<f64>)> {
    expm_dd_split(x, None, false)
}

/// [`expm_dd`] of `X = x + x_lo` (a double-double argument, `x_lo` zero if `None`): for
/// `X = hA` whose f64 product `fl(h·A)` is off by a relative ε/2 in each entry, the same
/// rounding every step, a systematic error of the propagator (a frequency off by ε/2: a
/// phase error ε/2·ωT after T, 2e−12 on Duffing ω = 20 over T = 1000; issue 27). With
/// `symmetric` (x and x_lo symmetric: every matrix formed is a polynomial in X, symmetric too)
/// each product computes half of its entries; the result is exactly symmetric.
///
/// # Errors
/// As [`expm_dd`].
pub(crate) fn expm_dd_split(
    x: &DMatrix<f64>,
    x_lo: Option<&DMatrix<f64>>,
    symmetric: bool,
) -> Result<(DMatrix<f64>, DMatrix<f64>)> {
    validate(x, "matrix")?;
    let n = x.nrows();
    let norm = norm1(x);
    if norm > MAX_NORM {
        return Err(Error::Numerical(format!(
            "matrix 1-norm {norm:e} too large for scaling and squaring"
        )));
    }
    let s = if norm <= 0.5 {
        0
    } else {
        (norm / 0.5).log2().ceil() as i32
    };
    let nn = n * n;
    // Column-major (high, low) buffers, allocated once: Y (scaled exactly: a power of 2) and
    // its powers Y²…Y^q, the result R, a product P and the block B.
    let scale = (-s as f64).exp2();
    let q = DD_PS_BLOCK;
    let mut pw_h = vec![0.0; q * nn];
    let mut pw_l = vec![0.0; q * nn];
    for (p, v) in pw_h[..nn].iter_mut().zip(x.iter()) {
        *p = v * scale;
    }
    if let Some(l) = x_lo {
        for (p, v) in pw_l[..nn].iter_mut().zip(l.iter()) {
            *p = v * scale;
        }
    }
    for k in 1..q {
        let (done_h, rest_h) = pw_h.split_at_mut(k * nn);
        let (done_l, rest_l) = pw_l.split_at_mut(k * nn);
        mul_dd(
            n,
            (&done_h[(k - 1) * nn..], &done_l[(k - 1) * nn..]),
            (&done_h[..nn], &done_l[..nn]),
            (&mut rest_h[..nn], &mut rest_l[..nn]),
            symmetric,
        );
    }
    let c = inv_factorials_dd(DD_TAYLOR_DEGREE);
    // B_j = Σ_{i<q} c_{jq+i} Y^i (the identity's coefficient on the diagonal), highest i first.
    let block = |j: usize, bh: &mut [f64], bl: &mut [f64]| {
        bh.fill(0.0);
        bl.fill(0.0);
        for i in (1..q).rev() {
            if let Some(&ci) = c.get(j * q + i) {
                let (ph, pl) = (&pw_h[(i - 1) * nn..i * nn], &pw_l[(i - 1) * nn..i * nn]);
                axpy_dd((&mut *bh, &mut *bl), ci, (ph, pl));
            }
        }
        if let Some(&(c0h, c0l)) = c.get(j * q) {
            for d in 0..n {
                let (t, e) = two_sum(bh[d * n + d], c0h);
                (bh[d * n + d], bl[d * n + d]) = two_sum(t, e + bl[d * n + d] + c0l);
            }
        }
    };
    let blocks = DD_TAYLOR_DEGREE / q + 1;
    let (mut rh, mut rl) = (vec![0.0; nn], vec![0.0; nn]);
    let (mut ph, mut pl) = (vec![0.0; nn], vec![0.0; nn]);
    let (mut bh, mut bl) = (vec![0.0; nn], vec![0.0; nn]);
    block(blocks - 1, &mut rh, &mut rl);
    let (yq_h, yq_l) = (&pw_h[(q - 1) * nn..], &pw_l[(q - 1) * nn..]);
    for j in (0..blocks - 1).rev() {
        // R ← R Y^q + B_j
        mul_dd(n, (&rh, &rl), (yq_h, yq_l), (&mut ph, &mut pl), symmetric);
        block(j, &mut bh, &mut bl);
        for ((((r, rlo), p), plo), (b, blo)) in rh
            .iter_mut()
            .zip(rl.iter_mut())
            .zip(&ph)
            .zip(&pl)
            .zip(bh.iter().zip(&bl))
        {
            let (t, e) = two_sum(*p, *b);
            (*r, *rlo) = two_sum(t, e + plo + blo);
        }
    }
    for _ in 0..s {
        mul_dd(n, (&rh, &rl), (&rh, &rl), (&mut ph, &mut pl), symmetric);
        std::mem::swap(&mut rh, &mut ph);
        std::mem::swap(&mut rl, &mut pl);
    }
    let (th, tl) = (DMatrix::from_vec(n, n, rh), DMatrix::from_vec(n, n, rl));
    if th.iter().chain(tl.iter()).any(|v| !v.is_finite()) {
        return Err(Error::Numerical(format!(
            "the exponential overflows f64: {}; a smaller step size h keeps it finite",
            overflow_cause(norm)
        )));
    }
    Ok((th, tl))
}

#[cfg(test)]
mod dd_tests {
    use super::super::dense::phi_dense;
    use super::*;

    /// A matrix with every eigenvalue at −1 whose φ-functions overflow all the same (a Jordan
    /// block with superdiagonal 1e40: e^A has entries up to 1e40⁹/9!): the error gives the
    /// 1-norm and the cause, not "eigenvalues far in the right half-plane" (there are none).
    #[test]
    fn overflow_without_right_half_plane_eigenvalues_names_the_norm() {
        let d = 10;
        let mut a = DMatrix::<f64>::zeros(d, d);
        for i in 0..d {
            a[(i, i)] = -1.0;
            if i + 1 < d {
                a[(i, i + 1)] = 1e40;
            }
        }
        let msg = phi_dense(&a, 2).unwrap_err().to_string();
        assert!(!msg.contains("right half-plane"), "{msg}");
        assert!(
            msg.contains("overflow f64") && msg.contains("1-norm 1.000e40"),
            "{msg}"
        );
        let msg = expm_dd(&a).unwrap_err().to_string();
        assert!(
            !msg.contains("right half-plane") && msg.contains("1-norm 1.000e40"),
            "{msg}"
        );
    }

    #[test]
    fn expm_dd_of_a_rotation_generator() {
        // X = [[0, θ], [−θ, 0]]: e^X = [[cos θ, sin θ], [−sin θ, cos θ]]; the double-double
        // result must satisfy cos² + sin² = 1 far below f64 rounding.
        for &theta in &[1e-3, 0.05, 0.4, 1.7, 30.0] {
            let x = DMatrix::from_row_slice(2, 2, &[0.0, theta, -theta, 0.0]);
            let (h, l) = expm_dd(&x).unwrap();
            let f = phi_dense(&x, 0).unwrap().swap_remove(0);
            // hi agrees with the f64 algorithm to its accuracy (which degrades with squarings).
            let diff = (&h - &f).abs().max();
            assert!(
                diff < 4.0 * f64::EPSILON * theta.max(1.0),
                "θ = {theta}: {diff:e}"
            );
            let (c, cl, sn, sl) = (h[(0, 0)], l[(0, 0)], h[(0, 1)], l[(0, 1)]);
            let (cc, ce) = two_prod(c, c);
            let (ss, se) = two_prod(sn, sn);
            let (t, te) = two_sum(cc, ss);
            let det = (t - 1.0) + (te + ce + se + 2.0 * (c * cl + sn * sl));
            let tol = if theta > 10.0 { 1e-28 } else { 1e-30 };
            assert!(det.abs() < tol, "θ = {theta}: {det:e}");
            // The low part is below an ulp of the high one.
            assert!(l.abs().max() <= f64::EPSILON);
        }
    }

    /// `mul_dd` with `lower` (a product known to be symmetric: two commuting symmetric
    /// matrices, here a symmetric S and S²) gives the entries on and below the diagonal bit
    /// for bit as the full product does and mirrors them above it: the result is exactly
    /// symmetric, and within a few units of 2⁻¹⁰⁶ of the full product's upper entries.
    #[test]
    fn mul_dd_lower_half_of_a_symmetric_product() {
        let mut rng = crate::test_rng::XorShift(0x51_0dd5_eed5);
        let mut next = move || rng.mixed(4);
        for n in [1, 2, 5, 19] {
            let mut s = vec![0.0; n * n];
            for j in 0..n {
                for i in j..n {
                    let v = next();
                    s[j * n + i] = v;
                    s[i * n + j] = v;
                }
            }
            let zero = vec![0.0; n * n];
            let (mut s2h, mut s2l) = (vec![f64::NAN; n * n], vec![f64::NAN; n * n]);
            mul_dd(n, (&s, &zero), (&s, &zero), (&mut s2h, &mut s2l), false);
            // S² exactly symmetric (its upper entries from the lower ones), so that S·S² is.
            for j in 0..n {
                for i in j + 1..n {
                    s2h[i * n + j] = s2h[j * n + i];
                    s2l[i * n + j] = s2l[j * n + i];
                }
            }
            let (mut fh, mut fl) = (vec![f64::NAN; n * n], vec![f64::NAN; n * n]);
            mul_dd(n, (&s, &zero), (&s2h, &s2l), (&mut fh, &mut fl), false);
            let (mut hh, mut hl) = (vec![f64::NAN; n * n], vec![f64::NAN; n * n]);
            mul_dd(n, (&s, &zero), (&s2h, &s2l), (&mut hh, &mut hl), true);
            // Dot2's error bound (Ogita, Rump & Oishi, Prop. 4.5 with the f64 cross terms):
            // a few n·u² of Σ_k |s_ik| |(S²)_kj| ≤ n max|S| max|S²|.
            let amax = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let u = f64::EPSILON / 2.0;
            let bound = 4.0 * (n * n) as f64 * u * u * amax(&s) * amax(&s2h);
            for j in 0..n {
                for i in 0..n {
                    let (k, m) = (j * n + i, i * n + j);
                    assert_eq!(hh[k].to_bits(), hh[m].to_bits(), "n = {n}, ({i}, {j})");
                    assert_eq!(hl[k].to_bits(), hl[m].to_bits(), "n = {n}, ({i}, {j})");
                    if i >= j {
                        assert_eq!(hh[k].to_bits(), fh[k].to_bits(), "n = {n}, ({i}, {j})");
                        assert_eq!(hl[k].to_bits(), fl[k].to_bits(), "n = {n}, ({i}, {j})");
                    } else {
                        // (S·S²)_{ij} and (S·S²)_{ji} are the same number in exact arithmetic,
                        // summed in different orders: each within the bound of it.
                        let diff = (hh[k] - fh[k]) + (hl[k] - fl[k]);
                        assert!(diff.abs() <= 2.0 * bound, "n = {n}, ({i}, {j}): {diff:e}");
                    }
                }
            }
        }
    }

    /// `mul_dd` (rows innermost, the CPU's version) gives every entry bit for bit as the dot
    /// product of a row and a column, each sum over k in order, with `mul_add` as it rounds
    /// in any build: the loop order and the dispatch change no bit. Entries of mixed signs and
    /// magnitudes (cancellation in the compensated sums), n not a multiple of a vector width.
    #[test]
    fn mul_dd_is_row_times_column_bit_for_bit() {
        // In (−1, 1) times a power of two between 2⁻⁸ and 2⁸.
        let mut rng = crate::test_rng::XorShift(0x9E37_79B9_7F4A_7C15);
        let mut next = move || rng.mixed(8);
        for n in [1, 2, 7, 19] {
            let mut m = || {
                let hi: Vec<f64> = (0..n * n).map(|_| next()).collect();
                let lo: Vec<f64> = hi
                    .iter()
                    .map(|h| h * f64::EPSILON * 0.25 * next())
                    .collect();
                (hi, lo)
            };
            let ((ah, al), (bh, bl)) = (m(), m());
            let (mut ch, mut cl) = (vec![f64::NAN; n * n], vec![f64::NAN; n * n]);
            mul_dd(n, (&ah, &al), (&bh, &bl), (&mut ch, &mut cl), false);
            for j in 0..n {
                for i in 0..n {
                    let (mut s, mut c) = (0.0, 0.0);
                    for k in 0..n {
                        let (a, b) = (ah[k * n + i], bh[j * n + k]);
                        let (p, e) = (a * b, a.mul_add(b, -(a * b)));
                        let (t, q) = two_sum(s, p);
                        s = t;
                        c += q + e + (a * bl[j * n + k] + al[k * n + i] * b);
                    }
                    let (h, l) = two_sum(s, c);
                    assert_eq!(ch[j * n + i].to_bits(), h.to_bits(), "n = {n}, ({i}, {j})");
                    assert_eq!(cl[j * n + i].to_bits(), l.to_bits(), "n = {n}, ({i}, {j})");
                }
            }
        }
    }
}
