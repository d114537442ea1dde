//! The n-point Gauss–Legendre rule on [0, 1] in f64 and the shifted Legendre polynomials, for
//! the node maps of the Legendre kernels ([`LegendreKernels::node_map`](super::LegendreKernels::node_map)).

/// Gauss–Legendre nodes and weights on [0, 1] in f64 (Newton on the three-term recurrence).
pub(super) fn gauss_legendre(q: usize) -> (Vec<f64>, Vec<f64>) {
    let mut nodes = Vec::with_capacity(q);
    let mut weights = Vec::with_capacity(q);
    for i in 0..q {
        let (x, dp) = legendre_root(q, i);
        nodes.push(0.5 * (1.0 + x));
        weights.push(1.0 / ((1.0 - x * x) * dp * dp));
    }
    (nodes, weights)
}

/// One Newton step on P_q at x: (P_q(x)/P_q'(x), P_q'(x)), P_q by its three-term recurrence.
fn newton_step(q: usize, x: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, x);
    for k in 1..q {
        let p2 = ((2 * k + 1) as f64 * x * p1 - k as f64 * p0) / (k + 1) as f64;
        p0 = p1;
        p1 = p2;
    }
    let p = if q == 0 { 1.0 } else { p1 };
    let pm1 = if q <= 1 { 1.0 } else { p0 };
    let dp = q as f64 * (x * p - pm1) / (x * x - 1.0);
    (p / dp, dp)
}

/// The initial guess of root i of P_q (descending, Tricomi type).
fn initial_root(q: usize, i: usize) -> f64 {
    (std::f64::consts::PI * (i as f64 + 0.75) / (q as f64 + 0.5)).cos()
}

/// Newton's iterations on root i of P_q (on [−1, 1], descending, from the Tricomi-type initial
/// guess): the root and P_q' at the iterate before it, as after at most 100 iterations that
/// stop once |dx| ≤ 1e−17. Most roots never meet that test: the iteration settles on a fixed
/// point whose rounded step no longer moves it, or alternates between two neighbouring
/// floats. Both are recognised (the state (x, P_q') repeats with period 1 or 2) and the 100th
/// state is returned without iterating to it: bit for bit the values of the plain loop, at
/// about a tenth of its cost.
fn legendre_root(q: usize, i: usize) -> (f64, f64) {
    const MAX_ITERATIONS: usize = 100;
    let mut x = initial_root(q, i);
    let mut dp = 1.0;
    // The states (x, dp) after the last three iterations, the newest first.
    let mut past = [(f64::NAN, f64::NAN); 3];
    for it in 0..MAX_ITERATIONS {
        let dx;
        (dx, dp) = newton_step(q, x);
        x -= dx;
        if dx.abs() <= 1e-17 {
            break;
        }
        let same = |a: (f64, f64), b: (f64, f64)| {
            a.0.to_bits() == b.0.to_bits() && a.1.to_bits() == b.1.to_bits()
        };
        let state = (x, dp);
        let left = MAX_ITERATIONS - 1 - it;
        if same(state, past[0]) {
            // Period 1: every further iteration gives this state.
            return state;
        }
        if same(state, past[1]) && same(past[0], past[2]) {
            // Period 2: the last iteration ends in this state or in the previous one.
            return if left % 2 == 0 { state } else { past[0] };
        }
        past = [state, past[0], past[1]];
    }
    (x, dp)
}

/// `out[j] = P̃_j(x)`, `j < out.len()` (three-term recurrence).
pub(super) fn shifted_legendre(x: f64, out: &mut [f64]) {
    let t = 2.0 * x - 1.0;
    for j in 0..out.len() {
        out[j] = match j {
            0 => 1.0,
            1 => t,
            _ => {
                let k = (j - 1) as f64;
                ((2.0 * k + 1.0) * t * out[j - 1] - k * out[j - 2]) / (k + 1.0)
            }
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The early exits of `legendre_root` return the plain 100-iteration loop's values, bit
    /// for bit, for every root of every order up to 64.
    #[test]
    fn legendre_roots_match_the_full_newton_loop() {
        fn plain(q: usize, i: usize) -> (f64, f64) {
            let (mut x, mut dp) = (initial_root(q, i), 1.0);
            for _ in 0..100 {
                let dx;
                (dx, dp) = newton_step(q, x);
                x -= dx;
                if dx.abs() <= 1e-17 {
                    break;
                }
            }
            (x, dp)
        }
        for q in 1..=64 {
            for i in 0..q {
                let (a, b) = (legendre_root(q, i), plain(q, i));
                assert_eq!(a.0.to_bits(), b.0.to_bits(), "q = {q}, root {i}");
                assert_eq!(a.1.to_bits(), b.1.to_bits(), "q = {q}, root {i}: P'");
            }
        }
    }

    #[test]
    fn gauss_legendre_integrates_polynomials() {
        let (c, b) = gauss_legendre(7);
        for deg in 0..14 {
            let v: f64 = c.iter().zip(&b).map(|(x, w)| w * x.powi(deg)).sum();
            assert!((v - 1.0 / (deg as f64 + 1.0)).abs() < 1e-15, "{deg}");
        }
    }
}
