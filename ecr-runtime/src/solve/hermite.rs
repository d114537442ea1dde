//! The solution between grid points: Hermite interpolation of the run's grid states and their
//! derivatives (y' = Ay + g(y) at the grid points), of degree 2m + 1 on m + 1 consecutive grid
//! points around the time asked for. Its weights depend only on where the time falls among the
//! nodes, so a point costs O(m²) scalars and O(d·m) for the state; no φ-bank, no step.

/// The weights of Hermite interpolation at `x` on the nodes `xs` (in any units; the caller
/// passes them scaled by the step, so that they are of order 1): the interpolant is
/// `Σ_j a_j y_j + b_j y'_j`, with `y'` the derivative in the units of `xs`.
pub(super) fn weights(xs: &[f64], x: f64, a: &mut [f64], b: &mut [f64]) {
    let n = xs.len();
    for j in 0..n {
        // ℓ_j(x) and ℓ_j'(x_j) = Σ_{k≠j} 1/(x_j − x_k).
        let mut l = 1.0;
        let mut dl = 0.0;
        for k in 0..n {
            if k != j {
                l *= (x - xs[k]) / (xs[j] - xs[k]);
                dl += 1.0 / (xs[j] - xs[k]);
            }
        }
        let l2 = l * l;
        let dx = x - xs[j];
        a[j] = (1.0 - 2.0 * dx * dl) * l2;
        b[j] = dx * l2;
    }
}

/// `out = Σ_j a_j y_j + h b_j f_j` over the stencil's states `y_j` and derivatives `f_j`
/// (per unit time; the weights are for nodes in units of h).
#[cfg(test)]
fn combine(a: &[f64], b: &[f64], h: f64, ys: &[&[f64]], fs: &[&[f64]], out: &mut [f64]) {
    out.fill(0.0);
    for (j, (y, f)) in ys.iter().zip(fs).enumerate() {
        let (aj, bj) = (a[j], h * b[j]);
        for ((o, yv), fv) in out.iter_mut().zip(y.iter()).zip(f.iter()) {
            *o += aj * yv + bj * fv;
        }
    }
}

/// The stencil for a time between grid points `k` and `k + 1` of a grid of `n + 1` points
/// (0..=n): `width` consecutive points with the interval as central as the grid allows.
/// Returns the first point.
pub(super) fn stencil(k: usize, n: usize, width: usize) -> usize {
    let width = width.min(n + 1);
    // Points k − (width/2 − 1) ..= k + width/2 for an even width: the interval in the middle.
    let back = (width - 1) / 2;
    let first = k.saturating_sub(back);
    first.min(n + 1 - width)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Hermite interpolant of sin on m + 1 nodes of spacing h: its error shrinks as
    /// h^(2m+2) (measured slope), and it reproduces polynomials of degree 2m + 1 exactly.
    #[test]
    fn order_and_exactness() {
        for m in [1usize, 3, 5] {
            let nodes: Vec<f64> = (0..=m).map(|j| j as f64).collect();
            let (mut a, mut b) = (vec![0.0; m + 1], vec![0.0; m + 1]);
            // Exactness for x^(2m+1) at x = m/2 + 0.3 (a quintic for m = 2 …).
            let x = 0.5 * m as f64 + 0.3;
            weights(&nodes, x, &mut a, &mut b);
            let deg = 2 * m + 1;
            let p = |t: f64| t.powi(deg as i32);
            let dp = |t: f64| deg as f64 * t.powi(deg as i32 - 1);
            let v: f64 = (0..=m)
                .map(|j| a[j] * p(nodes[j]) + b[j] * dp(nodes[j]))
                .sum();
            assert!(
                (v - p(x)).abs() <= 1e-12 * p(x).abs().max(1.0),
                "m {m}: {v} vs {}",
                p(x)
            );
            // Order: sin on nodes t0 + j h, evaluated in the middle interval.
            let mut errs = Vec::new();
            let hs = [0.2, 0.1, 0.05];
            for &h in &hs {
                let t0 = 0.3;
                let ys: Vec<[f64; 1]> = (0..=m).map(|j| [(t0 + j as f64 * h).sin()]).collect();
                let fs: Vec<[f64; 1]> = (0..=m).map(|j| [(t0 + j as f64 * h).cos()]).collect();
                let yr: Vec<&[f64]> = ys.iter().map(|v| v.as_slice()).collect();
                let fr: Vec<&[f64]> = fs.iter().map(|v| v.as_slice()).collect();
                weights(&nodes, x, &mut a, &mut b);
                let mut out = [0.0];
                combine(&a, &b, h, &yr, &fr, &mut out);
                errs.push((out[0] - (t0 + x * h).sin()).abs());
            }
            let slope = (errs[0] / errs[2]).ln() / (hs[0] / hs[2]).ln();
            let want = (2 * m + 2) as f64;
            assert!(
                slope > want - 0.3 || errs[2] < 1e-15,
                "m {m}: slope {slope}, errors {errs:?}"
            );
        }
    }

    #[test]
    fn stencils_are_central_and_inside() {
        assert_eq!(stencil(5, 20, 6), 3); // points 3..=8 around the interval 5–6
        assert_eq!(stencil(0, 20, 6), 0);
        assert_eq!(stencil(19, 20, 6), 15); // ends at point 20
        assert_eq!(stencil(2, 3, 6), 0); // fewer points than the width
    }
}
