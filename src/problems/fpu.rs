//! The Fermi–Pasta–Ulam problem with stiff springs (Hairer–Lubich–Wanner, *Geometric Numerical
//! Integration*, 2nd ed., §I.5.1 and §XIII.2.1), as a second-order system `q'' + Ωq = −∇U(q)`.

use nalgebra::DMatrix;

use super::check_len;
use ecr_runtime::{Error, Result};

/// The Fermi–Pasta–Ulam problem with stiff springs (GNI §I.5.1, §XIII.2.1) as the second-order
/// system of paper §3,
///
/// ```text
/// q'' + Ω q = −∇U(q),   q = (x₀,₁ … x₀,ₘ, x₁,₁ … x₁,ₘ) ∈ R²ᵐ,   Ω = diag(0,…,0, ω²,…,ω²).
/// ```
///
/// A chain of `2m` unit masses with fixed ends, alternating soft nonlinear springs (potential
/// `s⁴` in the elongation `s`) and stiff linear springs (stiffness `ω²/2`). In the coordinates of
/// GNI (I.5.2), `x₀,ᵢ = (q₂ᵢ + q₂ᵢ₋₁)/√2` is the (scaled) centre and `x₁,ᵢ = (q₂ᵢ − q₂ᵢ₋₁)/√2`
/// the (scaled) elongation of the `i`-th stiff spring; `y₀ = x₀'`, `y₁ = x₁'` are the momenta.
/// The Hamiltonian is (GNI (I.5.2)/(XIII.2.2))
///
/// ```text
/// H(x, y) = ½ Σᵢ (y₀,ᵢ² + y₁,ᵢ²) + (ω²/2) Σᵢ x₁,ᵢ²
///         + ¼ [ (x₀,₁ − x₁,₁)⁴ + Σ_{i=1}^{m−1} (x₀,ᵢ₊₁ − x₁,ᵢ₊₁ − x₀,ᵢ − x₁,ᵢ)⁴ + (x₀,ₘ + x₁,ₘ)⁴ ],
/// ```
///
/// and `U(q)` is the bracket term `¼[…]`: the sum of `¼sₖ⁴` over the `m + 1` soft springs
/// `k = 0..=m`, with the elongations (in the scaled coordinates)
/// `sₖ = (x₀,ₖ₊₁ − x₁,ₖ₊₁) − (x₀,ₖ + x₁,ₖ)` where terms with an index outside `1..=m` are 0
/// (the fixed walls); so `sₘ = −(x₀,ₘ + x₁,ₘ)`, which GNI writes with the opposite sign
/// (immaterial under the fourth power). With `q = (x₀, x₁)` and `p = (y₀, y₁)` the slices of every method below are
/// laid out in exactly that order: entries `0..m` are `x₀`, entries `m..2m` are `x₁`.
///
/// The first-order form (paper §3; `docs/method.md#second-order`) is `y' = Ay + g(y)` with
/// `y = (q, p)`, `A = [[0, I], [−Ω, 0]]` and `g(y) = (0, −∇U(q))`, i.e. `y' = Q∇H` with
/// `Q = [[0, I], [−I, 0]]`, `M = diag(Ω, I)`, `V(q, p) = U(q)`.
///
/// The oscillatory energy `I = Σⱼ Iⱼ`, `Iⱼ = ½(y₁,ⱼ² + ω²x₁,ⱼ²)` (GNI (I.5.3), §XIII.2.1), is an
/// adiabatic invariant: it is conserved up to `O(ω⁻¹)` over exponentially long times
/// (GNI §XIII.6), while the `Iⱼ` exchange energy on the time scale `ω`.
///
/// The default is GNI's choice `m = 3`, `ω = 50`. `ω = 0` is allowed: then `Ω = 0` and the
/// problem is a plain `q'' = −∇U(q)` (a problem for RKN methods; RKNCr is TCr at `K = 0`).
#[derive(Clone, Debug, PartialEq)]
pub struct Fpu {
    m: usize,
    omega: f64,
}

impl Default for Fpu {
    /// GNI §XIII.2.1: `m = 3` (six masses), `ω = 50`.
    fn default() -> Self {
        Fpu::new(3, 50.0).expect("m = 3, ω = 50 are valid")
    }
}

impl Fpu {
    /// The FPU problem with `2m` masses (`m` stiff springs) and stiff frequency `omega` (`ω`).
    ///
    /// # Errors
    ///
    /// [`Error::NonFinite`] if `omega` is NaN or infinite; [`Error::InvalidParameter`] if `m = 0`,
    /// if `4m` (the first-order dimension) overflows `usize`, or if `ω < 0`.
    pub fn new(m: usize, omega: f64) -> Result<Self> {
        if m == 0 {
            return Err(Error::InvalidParameter(
                "FPU: the number m of stiff springs must be ≥ 1".to_string(),
            ));
        }
        if m.checked_mul(4).is_none() {
            return Err(Error::InvalidParameter(format!(
                "FPU: m = {m} is too large (4m overflows usize)"
            )));
        }
        if !omega.is_finite() {
            return Err(Error::NonFinite("FPU frequency ω"));
        }
        if omega < 0.0 {
            return Err(Error::InvalidParameter(format!(
                "FPU frequency ω = {omega:?} must be ≥ 0"
            )));
        }
        if !(omega * omega).is_finite() {
            return Err(Error::InvalidParameter(format!(
                "FPU frequency ω = {omega:?} is too large: ω² overflows f64"
            )));
        }
        Ok(Fpu { m, omega })
    }

    /// The number `m` of stiff springs (the chain has `2m` masses).
    pub fn m(&self) -> usize {
        self.m
    }

    /// The stiff frequency `ω`.
    pub fn omega(&self) -> f64 {
        self.omega
    }

    /// The dimension `d = 2m` of `q` (and of `p`).
    pub fn dim(&self) -> usize {
        2 * self.m
    }

    /// The dimension `4m` of the first-order state `y = (q, p)`.
    pub fn first_order_dim(&self) -> usize {
        4 * self.m
    }

    /// `ω²`, the diagonal entry of `Ω` for the elongations.
    fn omega2(&self) -> f64 {
        self.omega * self.omega
    }

    /// The diagonal of `Ω`: `m` zeros (centres `x₀`), then `m` times `ω²` (elongations `x₁`).
    pub fn omega_diagonal(&self) -> Vec<f64> {
        let mut diag = vec![0.0; 2 * self.m];
        diag[self.m..].fill(self.omega2());
        diag
    }

    /// The elongation `sₖ` of the `k`-th soft spring, `k = 0..=m` (see the type docs):
    /// `sₖ = (x₀,ₖ₊₁ − x₁,ₖ₊₁) − (x₀,ₖ + x₁,ₖ)` in GNI's 1-based indices, missing terms 0.
    #[inline]
    fn soft_elongation(&self, q: &[f64], k: usize) -> f64 {
        let m = self.m;
        // 0-based: the right neighbour is stiff spring k, the left one is stiff spring k − 1.
        let right = if k < m { q[k] - q[m + k] } else { 0.0 };
        let left = if k > 0 { q[k - 1] + q[m + k - 1] } else { 0.0 };
        right - left
    }

    /// The gradient `f(q) = ∇U(q)`, written into `out`, without allocation.
    ///
    /// With `σₖ = sₖ³` (`k = 0..=m`, 0-based stiff springs `i = 0..m`):
    /// `∂U/∂x₀,ᵢ = σᵢ − σᵢ₊₁`, `∂U/∂x₁,ᵢ = −σᵢ − σᵢ₊₁`.
    ///
    /// # Panics
    ///
    /// If `q` or `out` does not have length [`dim`](Fpu::dim) `= 2m`.
    pub fn grad_u(&self, q: &[f64], out: &mut [f64]) {
        let m = self.m;
        check_len("q", q.len(), 2 * m);
        check_len("out", out.len(), 2 * m);
        let mut sigma_left = self.soft_elongation(q, 0).powi(3);
        for i in 0..m {
            let sigma_right = self.soft_elongation(q, i + 1).powi(3);
            out[i] = sigma_left - sigma_right;
            out[m + i] = -sigma_left - sigma_right;
            sigma_left = sigma_right;
        }
    }

    /// The potential `U(q) = ¼ Σ_{k=0}^{m} sₖ⁴` (the bracket of GNI (I.5.2)).
    ///
    /// # Panics
    ///
    /// If `q` does not have length `2m`.
    pub fn potential_u(&self, q: &[f64]) -> f64 {
        check_len("q", q.len(), 2 * self.m);
        let sum: f64 = (0..=self.m)
            .map(|k| {
                let s2 = self.soft_elongation(q, k).powi(2);
                s2 * s2
            })
            .sum();
        0.25 * sum
    }

    /// The Hamiltonian `H(q, p) = ½pᵀp + ½qᵀΩq + U(q)` (GNI (I.5.2)), a first integral.
    ///
    /// # Panics
    ///
    /// If `q` or `p` does not have length `2m`.
    pub fn energy(&self, q: &[f64], p: &[f64]) -> f64 {
        let m = self.m;
        check_len("q", q.len(), 2 * m);
        check_len("p", p.len(), 2 * m);
        let kinetic: f64 = p.iter().map(|v| v * v).sum();
        let elastic: f64 = q[m..].iter().map(|v| v * v).sum();
        0.5 * kinetic + 0.5 * self.omega2() * elastic + self.potential_u(q)
    }

    /// The oscillatory energy `I(q, p) = Σⱼ ½(y₁,ⱼ² + ω²x₁,ⱼ²)` (GNI (I.5.3), §XIII.2.1), the
    /// total energy of the stiff springs: an adiabatic invariant, `I(t) = I(0) + O(ω⁻¹)` for
    /// long times (GNI §XIII.6), not a first integral.
    ///
    /// # Panics
    ///
    /// If `q` or `p` does not have length `2m`.
    pub fn oscillatory_energy(&self, q: &[f64], p: &[f64]) -> f64 {
        let m = self.m;
        check_len("q", q.len(), 2 * m);
        check_len("p", p.len(), 2 * m);
        let w2 = self.omega2();
        q[m..]
            .iter()
            .zip(&p[m..])
            .map(|(x, y)| 0.5 * (y * y + w2 * x * x))
            .sum()
    }

    /// The initial value `(q₀, p₀)` of GNI §XIII.2.1 (also Fig. I.5.1):
    /// `x₀,₁ = 1`, `y₀,₁ = 1`, `x₁,₁ = ω⁻¹`, `y₁,₁ = 1`, all other entries 0.
    ///
    /// For `ω = 0` the entry `x₁,₁` would be infinite; it is set to 0 instead (so
    /// `q₀ = (1, 0, …, 0)`, `p₀` as above). For `ω > 0`, `I(q₀, p₀) = 1` and
    /// `H(q₀, p₀) = 2 + 3ω⁻² + ω⁻⁴/2` (any `m`); for `ω = 0`, `H = 3/2`.
    pub fn initial_value(&self) -> (Vec<f64>, Vec<f64>) {
        let m = self.m;
        let mut q = vec![0.0; 2 * m];
        let mut p = vec![0.0; 2 * m];
        q[0] = 1.0;
        q[m] = if self.omega > 0.0 {
            1.0 / self.omega
        } else {
            0.0
        };
        p[0] = 1.0;
        p[m] = 1.0;
        (q, p)
    }

    /// The initial value of the first-order form, `y₀ = (q₀, p₀)` (see
    /// [`initial_value`](Fpu::initial_value)), length `4m`.
    pub fn initial_value_first_order(&self) -> Vec<f64> {
        let (mut q, p) = self.initial_value();
        q.extend_from_slice(&p);
        q
    }

    /// The linear part of the first-order form, `A = [[0, I], [−Ω, 0]]` (`4m × 4m`).
    pub fn linear_matrix(&self) -> DMatrix<f64> {
        let d = 2 * self.m;
        let mut a = DMatrix::zeros(2 * d, 2 * d);
        for i in 0..d {
            a[(i, d + i)] = 1.0;
        }
        for (i, w) in self.omega_diagonal().into_iter().enumerate() {
            // Written only where Ω ≠ 0, so that A has no −0.0 entries.
            if w != 0.0 {
                a[(d + i, i)] = -w;
            }
        }
        a
    }

    /// The nonlinear part of the first-order form, `g(y) = (0, −∇U(q))` for `y = (q, p)`,
    /// written into `out`, without allocation.
    ///
    /// # Panics
    ///
    /// If `y` or `out` does not have length [`first_order_dim`](Fpu::first_order_dim) `= 4m`.
    pub fn nonlinear_first_order(&self, y: &[f64], out: &mut [f64]) {
        let d = 2 * self.m;
        check_len("y", y.len(), 2 * d);
        check_len("out", out.len(), 2 * d);
        let (head, tail) = out.split_at_mut(d);
        head.fill(0.0);
        self.grad_u(&y[..d], tail);
        for v in tail.iter_mut() {
            *v = -*v;
        }
    }

    /// The Hamiltonian of the first-order state `y = (q, p)`: `H(y) = energy(q, p)`
    /// (`= ½yᵀ diag(Ω, I) y + U(q)`).
    ///
    /// # Panics
    ///
    /// If `y` does not have length `4m`.
    pub fn energy_first_order(&self, y: &[f64]) -> f64 {
        let d = 2 * self.m;
        check_len("y", y.len(), 2 * d);
        self.energy(&y[..d], &y[d..])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problems::TestProblem;
    use crate::problems::testutil::{Rng, check_structure};
    use nalgebra::DVector;

    fn max_abs(v: &[f64]) -> f64 {
        v.iter().fold(0.0, |m, x| m.max(x.abs()))
    }

    fn random_state(rng: &mut Rng, fpu: &Fpu, scale: f64) -> Vec<f64> {
        (0..fpu.first_order_dim()).map(|_| rng.sym(scale)).collect()
    }

    #[test]
    fn constructor_validates() {
        assert!(matches!(Fpu::new(0, 50.0), Err(Error::InvalidParameter(_))));
        assert!(matches!(
            Fpu::new(usize::MAX / 2, 50.0),
            Err(Error::InvalidParameter(_))
        ));
        assert!(matches!(Fpu::new(3, -1.0), Err(Error::InvalidParameter(_))));
        assert!(matches!(
            Fpu::new(3, -f64::MIN_POSITIVE),
            Err(Error::InvalidParameter(_))
        ));
        assert!(matches!(Fpu::new(3, f64::NAN), Err(Error::NonFinite(_))));
        assert!(matches!(
            Fpu::new(3, f64::INFINITY),
            Err(Error::NonFinite(_))
        ));
        assert!(Fpu::new(1, 0.0).is_ok());
        let f = Fpu::default();
        assert_eq!(
            (f.m(), f.omega(), f.dim(), f.first_order_dim()),
            (3, 50.0, 6, 12)
        );
        assert_eq!(
            f.omega_diagonal(),
            vec![0.0, 0.0, 0.0, 2500.0, 2500.0, 2500.0]
        );
        assert_eq!(Fpu::new(2, 0.0).unwrap().omega_diagonal(), vec![0.0; 4]);
    }

    /// ∇U against the fourth-order centred difference
    /// `(8(U(q+he) − U(q−he)) − (U(q+2he) − U(q−2he)))/(12h)` with `h = 2⁻¹⁰`.
    /// `U` is a quartic polynomial, for which this stencil is exact (its truncation error
    /// involves the fifth derivative), so the difference is round-off only: each `U` value is
    /// within a few ε·|U| (≤ 2m+2 terms, each a handful of roundings), amplified by
    /// `18/(12h)`; tolerance `1e-14·max|∇U| + 16ε·max|U|/h` (≈ 4e-12 for |U| ≈ 1). Also the
    /// second-order centred difference `(U(q+he) − U(q−he))/(2h)` with `h = 1e-5`, whose
    /// truncation `h²/6·|∂³U|` is below 1e-8 here: tolerance 1e-7, which still fails for a
    /// single wrong sign or index (errors of order |∇U| ≈ 1).
    #[test]
    fn gradient_matches_finite_differences() {
        let mut rng = Rng(21);
        for (m, omega) in [(1, 50.0), (2, 0.0), (3, 50.0), (5, 7.0)] {
            let fpu = Fpu::new(m, omega).unwrap();
            let d = fpu.dim();
            let mut grad = vec![0.0; d];
            let mut points: Vec<Vec<f64>> = (0..20)
                .map(|_| (0..d).map(|_| rng.sym(1.5)).collect())
                .collect();
            points.push(fpu.initial_value().0);
            for q in points {
                fpu.grad_u(&q, &mut grad);
                let mut qq = q.clone();
                // Fourth order, exact for quartics.
                let h = 1.0 / 1024.0;
                for i in 0..d {
                    let mut u = [0.0; 4];
                    for (slot, shift) in u.iter_mut().zip([h, -h, 2.0 * h, -2.0 * h]) {
                        qq[i] = q[i] + shift;
                        *slot = fpu.potential_u(&qq);
                    }
                    qq[i] = q[i];
                    let fd = (8.0 * (u[0] - u[1]) - (u[2] - u[3])) / (12.0 * h);
                    let tol = 1e-14 * max_abs(&grad) + 16.0 * f64::EPSILON * max_abs(&u) / h;
                    assert!(
                        (fd - grad[i]).abs() <= tol,
                        "m={m} ω={omega}: ∂U/∂q{i} = {} vs fd4 {fd} (tol {tol:e})",
                        grad[i]
                    );
                }
                // Second order, truncation-limited.
                let h = 1e-5;
                for i in 0..d {
                    qq[i] = q[i] + h;
                    let up = fpu.potential_u(&qq);
                    qq[i] = q[i] - h;
                    let um = fpu.potential_u(&qq);
                    qq[i] = q[i];
                    let fd = (up - um) / (2.0 * h);
                    assert!(
                        (fd - grad[i]).abs() <= 1e-7,
                        "m={m} ω={omega}: ∂U/∂q{i} = {} vs fd2 {fd}",
                        grad[i]
                    );
                }
            }
        }
    }

    /// U and ∇U at hand-checked points, differentiating GNI's bracket
    /// `U = ¼[(x₀,₁ − x₁,₁)⁴ + (x₀,₂ − x₁,₂ − x₀,₁ − x₁,₁)⁴ + (x₀,₂ + x₁,₂)⁴]` (m = 2) directly,
    /// with `q = (x₀,₁, x₀,₂, x₁,₁, x₁,₂)`.
    ///
    /// At q = (1, 2, 0, 0) the three brackets are 1, 1, 2: U = ¼(1 + 1 + 16) = 4.5,
    /// ∂/∂x₀,₁ = 1 − 1 = 0, ∂/∂x₀,₂ = 1 + 8 = 9, ∂/∂x₁,₁ = −1 − 1 = −2, ∂/∂x₁,₂ = −1 + 8 = 7.
    /// At q = (0, 0, 1, 0) they are −1, −1, 0: U = ½, ∇U = (−1 + 1, −1, 1 + 1, 1) = (0, −1, 2, 1).
    #[test]
    fn potential_and_gradient_by_hand() {
        let fpu = Fpu::new(2, 3.0).unwrap();
        let q = [1.0, 2.0, 0.0, 0.0];
        assert_eq!(fpu.potential_u(&q), 4.5);
        let mut g = [0.0; 4];
        fpu.grad_u(&q, &mut g);
        assert_eq!(g, [0.0, 9.0, -2.0, 7.0]);
        // Pure elongation of the first stiff spring.
        let q = [0.0, 0.0, 1.0, 0.0];
        assert_eq!(fpu.potential_u(&q), 0.5);
        fpu.grad_u(&q, &mut g);
        assert_eq!(g, [0.0, -1.0, 2.0, 1.0]);
        assert_eq!(fpu.energy(&q, &[0.0; 4]), 0.5 * 9.0 + 0.5);
    }

    /// H(q₀, p₀) = ½(1 + 1) + (ω²/2)ω⁻² + ¼[(1 − ω⁻¹)⁴ + (1 + ω⁻¹)⁴]
    ///           = 2 + 3ω⁻² + ω⁻⁴/2  (the other soft springs are at rest),
    /// = 2.00120008 for ω = 50, for every m; 3/2 for ω = 0 (x₁,₁ = 0). Tolerance 4ε·H (a few
    /// roundings of terms of size ≤ 1). I(q₀, p₀) = ½(1 + ω²ω⁻²) = 1 (½ for ω = 0).
    #[test]
    fn initial_energy_by_hand() {
        for m in [1, 2, 3, 8] {
            for (omega, h_exact) in [(50.0, 2.00120008), (10.0, 2.03005), (0.0, 1.5)] {
                let fpu = Fpu::new(m, omega).unwrap();
                let (q0, p0) = fpu.initial_value();
                assert_eq!((q0.len(), p0.len()), (2 * m, 2 * m));
                let x11 = if omega > 0.0 { 1.0 / omega } else { 0.0 };
                let mut q_expected = vec![0.0; 2 * m];
                q_expected[0] = 1.0;
                q_expected[m] = x11;
                let mut p_expected = vec![0.0; 2 * m];
                p_expected[0] = 1.0;
                p_expected[m] = 1.0;
                assert_eq!((q0.clone(), p0.clone()), (q_expected, p_expected));
                let h = fpu.energy(&q0, &p0);
                assert!(
                    (h - h_exact).abs() <= 4.0 * f64::EPSILON * h_exact,
                    "m={m} ω={omega}: H(y0) = {h} vs {h_exact}"
                );
                let y0 = fpu.initial_value_first_order();
                assert_eq!(fpu.energy_first_order(&y0), h);
                let i0 = fpu.oscillatory_energy(&q0, &p0);
                let i_exact = if omega > 0.0 { 1.0 } else { 0.5 };
                assert!(
                    (i0 - i_exact).abs() <= 2.0 * f64::EPSILON,
                    "m={m} ω={omega}: I(y0) = {i0}"
                );
            }
        }
    }

    /// The first-order form against the second-order one at random states:
    /// `A` has exactly the block structure `[[0, I], [−Ω, 0]]`; `Ay + g(y)` equals
    /// `(p, −Ωq − ∇U(q))` exactly (one product and one sum per entry, the same operations in
    /// both), and `energy_first_order(y) == energy(q, p)`.
    #[test]
    fn first_order_form_matches_second_order() {
        let mut rng = Rng(22);
        for (m, omega) in [(1, 50.0), (3, 50.0), (4, 0.0), (2, 3.5)] {
            let fpu = Fpu::new(m, omega).unwrap();
            let d = fpu.dim();
            let a = fpu.linear_matrix();
            assert_eq!((a.nrows(), a.ncols()), (2 * d, 2 * d));
            let w = fpu.omega_diagonal();
            for i in 0..2 * d {
                for j in 0..2 * d {
                    let expected = if i < d && j == d + i {
                        1.0
                    } else if i >= d && j == i - d {
                        -w[j]
                    } else {
                        0.0
                    };
                    assert_eq!(a[(i, j)], expected, "A[{i},{j}], m={m} ω={omega}");
                }
            }
            let mut g = vec![0.0; 2 * d];
            let mut f = vec![0.0; d];
            for _ in 0..20 {
                let y = random_state(&mut rng, &fpu, 1.5);
                let (q, p) = y.split_at(d);
                fpu.nonlinear_first_order(&y, &mut g);
                fpu.grad_u(q, &mut f);
                assert!(g[..d].iter().all(|&v| v == 0.0));
                let rhs = &a * DVector::from_column_slice(&y) + DVector::from_column_slice(&g);
                for i in 0..d {
                    assert_eq!(rhs[i], p[i], "q'_{i}");
                    let expected = -w[i] * q[i] - f[i];
                    let tol = 2.0 * f64::EPSILON * (w[i] * q[i].abs() + f[i].abs());
                    assert!(
                        (rhs[d + i] - expected).abs() <= tol,
                        "p'_{i}: {} vs {expected}",
                        rhs[d + i]
                    );
                }
                assert_eq!(fpu.energy_first_order(&y), fpu.energy(q, p));
                // H splits as ½pᵀp + ½qᵀΩq + U and I is the x₁/y₁ part of the quadratic terms.
                let quad_x1: f64 = (m..d)
                    .map(|i| 0.5 * (p[i] * p[i] + w[i] * q[i] * q[i]))
                    .sum();
                let i_val = fpu.oscillatory_energy(q, p);
                assert!((i_val - quad_x1).abs() <= 4.0 * f64::EPSILON * quad_x1);
            }
        }
    }

    /// The first-order form as a [`TestProblem`] (`Q = [[0, I], [−I, 0]]`, `M = diag(Ω, I)`,
    /// `V(q, p) = U(q)`), to run the shared structural checks (`A = QM`, `g = Q∇V`, `∇V` by
    /// finite differences, `H = ½yᵀMy + V`, `∇H·(Ay + g) = 0`).
    struct FirstOrder(Fpu);

    impl TestProblem for FirstOrder {
        fn dim(&self) -> usize {
            self.0.first_order_dim()
        }
        fn q_matrix(&self) -> DMatrix<f64> {
            let d = self.0.dim();
            let mut q = DMatrix::zeros(2 * d, 2 * d);
            for i in 0..d {
                q[(i, d + i)] = 1.0;
                q[(d + i, i)] = -1.0;
            }
            q
        }
        fn m_matrix(&self) -> DMatrix<f64> {
            let mut diag = self.0.omega_diagonal();
            diag.resize(2 * self.0.dim(), 1.0);
            DMatrix::from_diagonal(&DVector::from_vec(diag))
        }
        fn linear_matrix(&self) -> DMatrix<f64> {
            self.0.linear_matrix()
        }
        fn nonlinear(&self, y: &[f64], out: &mut [f64]) {
            self.0.nonlinear_first_order(y, out)
        }
        fn grad_v(&self, y: &[f64], out: &mut [f64]) {
            let d = self.0.dim();
            self.0.grad_u(&y[..d], &mut out[..d]);
            out[d..].fill(0.0);
        }
        fn potential_v(&self, y: &[f64]) -> f64 {
            self.0.potential_u(&y[..self.0.dim()])
        }
        fn energy(&self, y: &[f64]) -> f64 {
            self.0.energy_first_order(y)
        }
        fn initial_value(&self) -> Vec<f64> {
            self.0.initial_value_first_order()
        }
    }

    #[test]
    fn first_order_structure() {
        let mut rng = Rng(23);
        for (m, omega) in [(1, 50.0), (3, 50.0), (3, 0.0), (4, 5.0)] {
            let fpu = Fpu::new(m, omega).unwrap();
            let mut ys: Vec<Vec<f64>> =
                (0..20).map(|_| random_state(&mut rng, &fpu, 1.5)).collect();
            ys.push(fpu.initial_value_first_order());
            check_structure(&FirstOrder(fpu), &ys, true);
        }
    }

    /// The problem in motion: Störmer–Verlet (GNI §I.1.4) with `h = 10⁻³` (`hω = 0.05`) for the
    /// default problem up to `t = 1`. Its energy error is `O(h²ω²)`-bounded: `|ΔH| ≤ 2e-3` here
    /// (a wrong sign in `∇U` or `Ω` makes the motion unbounded or H drift by O(1)); the
    /// oscillatory energy stays near `I(0) = 1` (`|ΔI| ≤ 0.05`, GNI Fig. XIII.2.2 shows
    /// variations of a few percent).
    #[test]
    fn verlet_keeps_energy_and_oscillatory_energy() {
        let fpu = Fpu::default();
        let d = fpu.dim();
        let w = fpu.omega_diagonal();
        let (mut q, mut p) = fpu.initial_value();
        let (h0, i0) = (fpu.energy(&q, &p), fpu.oscillatory_energy(&q, &p));
        let mut f = vec![0.0; d];
        let h = 1e-3;
        let accel = |q: &[f64], f: &mut [f64]| {
            fpu.grad_u(q, f);
            for i in 0..d {
                f[i] = -f[i] - w[i] * q[i];
            }
        };
        accel(&q, &mut f);
        let (mut dh, mut di): (f64, f64) = (0.0, 0.0);
        for _ in 0..1000 {
            for i in 0..d {
                p[i] += 0.5 * h * f[i];
                q[i] += h * p[i];
            }
            accel(&q, &mut f);
            for i in 0..d {
                p[i] += 0.5 * h * f[i];
            }
            dh = dh.max((fpu.energy(&q, &p) - h0).abs());
            di = di.max((fpu.oscillatory_energy(&q, &p) - i0).abs());
        }
        eprintln!("FPU Verlet h=1e-3, t ≤ 1: max |ΔH| = {dh:e}, max |ΔI| = {di:e}");
        assert!(dh <= 2e-3, "max |ΔH| = {dh}");
        assert!(di <= 5e-2, "max |ΔI| = {di}");
    }

    #[test]
    #[should_panic(expected = "q has length 3, expected 6")]
    fn wrong_length_panics() {
        let mut out = [0.0; 6];
        Fpu::default().grad_u(&[0.0; 3], &mut out);
    }
}
