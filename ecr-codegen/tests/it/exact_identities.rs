//! Exact identities of the generator, checked in rational arithmetic (or in rigorous interval
//! enclosures of relative width < 1e-60 where the quantities are irrational).

use ecr_codegen::kernels::*;
use ecr_codegen::legendre::{beta, c_jk, check_orthogonality, shifted_legendre};
use ecr_codegen::rat::{Rat, frac, int, inv_factorial, pow};
use ecr_codegen::{Poly, Quadrature};
use num_traits::{One, Zero};

fn sample_points() -> Vec<Rat> {
    vec![Rat::zero(), frac(1, 3), frac(2, 7), frac(5, 8), Rat::one()]
}

#[test]
fn orthonormality_of_shifted_legendre() {
    // ∫₀¹ P̃ᵢ P̃ⱼ = δᵢⱼ/(2j+1), i.e. p̂ⱼ = √(2j+1) P̃ⱼ orthonormal.
    assert!(check_orthogonality(16));
    for j in 0..16 {
        assert_eq!(
            shifted_legendre(j).eval(&Rat::one()),
            Rat::one(),
            "P̃_{j}(1) = 1"
        );
    }
}

#[test]
fn legendre_in_terms_of_c_jk() {
    // P̃ⱼ(x) = Σₖ c_{jk} xᵏ/k!: the identity the kernel's closed form rests on.
    for j in 0..14 {
        let p = Poly::new(
            (0..=j)
                .map(|k| c_jk(j, k) * inv_factorial(k as u64))
                .collect(),
        );
        assert_eq!(p, shifted_legendre(j));
    }
}

#[test]
fn beta_reproduces_projection() {
    // Σ_k β_k(σ) xᵏ/k! = Σⱼ (2j+1) P̃ⱼ(σ) P̃ⱼ(x).
    for r in 1..8 {
        for sigma in sample_points() {
            let lhs = (0..r).fold(Poly::zero(), |acc, k| {
                acc.add(
                    &Poly::monomial(k).scale(&(beta(r, k).eval(&sigma) * inv_factorial(k as u64))),
                )
            });
            let rhs = ecr_codegen::legendre::projection_kernel(r, &sigma);
            assert_eq!(lhs, rhs, "r = {r}");
        }
    }
}

fn tight() -> Rat {
    Rat::new(1.into(), num_bigint::BigInt::from(10).pow(60))
}

#[test]
fn gauss_legendre_exact_to_degree_2s_minus_1_and_not_beyond() {
    for s in 1..=16 {
        let q = Quadrature::gauss_legendre(s, 256);
        let sum = q
            .weights
            .iter()
            .fold(ecr_codegen::Interval::point(Rat::zero()), |a, b| a.add(b));
        assert!(
            sum.contains(&Rat::one()) && sum.width() < tight(),
            "Σb = 1 for s = {s}"
        );
        for m in 0..=2 * s {
            let iv = q.apply_poly(&Poly::monomial(m));
            let exact = frac(1, m as i64 + 1);
            if m < 2 * s {
                assert!(iv.contains(&exact), "s = {s}: x^{m} integrated exactly");
                assert!(iv.width() < tight(), "s = {s}: enclosure tight");
            } else {
                assert!(
                    !iv.contains(&exact),
                    "s = {s}: degree 2s is not integrated exactly"
                );
            }
        }
    }
}

#[test]
fn gauss_lobatto_exact_to_degree_2s_minus_3() {
    for s in 2..=16 {
        let q = Quadrature::gauss_lobatto(s, 256);
        assert_eq!(q.nodes.len(), s);
        for m in 0..=2 * s - 2 {
            let iv = q.apply_poly(&Poly::monomial(m));
            let exact = frac(1, m as i64 + 1);
            if m <= 2 * s - 3 {
                assert!(
                    iv.contains(&exact) && iv.width() < tight(),
                    "s = {s}, m = {m}"
                );
            } else {
                assert!(!iv.contains(&exact), "s = {s}: degree 2s-2 is not exact");
            }
        }
    }
}

#[test]
fn ec_kernel_series_matches_defining_integral() {
    for r in 1..=6 {
        for tau in sample_points() {
            for sigma in sample_points() {
                let by_integral = ec_kernel_by_integral(r, &tau, &sigma, 8);
                assert_eq!(
                    ec_kernel_closed(r, &tau, &sigma, 8),
                    by_integral,
                    "closed form r={r}"
                );
                assert_eq!(
                    ec_kernel_moment(r, &tau, &sigma, 8),
                    by_integral,
                    "moment form r={r}"
                );
            }
        }
    }
}

#[test]
fn erratum_1_the_printed_bar_a_is_wrong_inside_the_step() {
    // The paper's eq. `barA` without τᵏ agrees at τ = 1 (and τ = 0 trivially for r = 1) but not
    // at interior nodes: the check above would fail on it.
    let sigma = frac(1, 3);
    for r in 2..=5 {
        assert_eq!(
            ec_kernel_as_printed(r, &Rat::one(), &sigma, 6),
            ec_kernel_by_integral(r, &Rat::one(), &sigma, 6)
        );
        assert_ne!(
            ec_kernel_as_printed(r, &frac(1, 3), &sigma, 6),
            ec_kernel_by_integral(r, &frac(1, 3), &sigma, 6),
            "r = {r}"
        );
    }
}

#[test]
fn tc_kernel_a_closed_form_matches_defining_integral() {
    for r in 1..=6 {
        for tau in sample_points() {
            for sigma in sample_points() {
                let by_integral = tc_a_by_integral(r, &tau, &sigma, 7);
                assert_eq!(
                    tc_a_hypergeometric(r, &tau, &sigma, 7),
                    by_integral,
                    "₂F₁ form r={r}"
                );
                assert_eq!(
                    tc_a_moment(r, &tau, &sigma, 7),
                    by_integral,
                    "moment form r={r}"
                );
            }
        }
    }
}

#[test]
fn tc_s_and_b_closed_forms_match_defining_integrals() {
    for j in 0..=12 {
        assert_eq!(tc_s_closed(j, 14), tc_s_by_integral(j, 14), "S_{j}");
    }
    for r in 1..=6 {
        for sigma in sample_points() {
            let by_integral = tc_b1_by_integral(r, &sigma, 10);
            assert_eq!(tc_b1_closed(r, &sigma, 10), by_integral, "ℬ closed r={r}");
            assert_eq!(tc_b1_moment(r, &sigma, 10), by_integral, "ℬ moment r={r}");
        }
    }
}

#[test]
fn trig_phi_series_is_even_part_of_phi() {
    // φᵗ_m(θ²) = Re φ_m(iθ): [K^l] φᵗ_m = (−1)^l [z^{2l}] φ_m.
    for m in 0..8 {
        let t = phi_trig_series(m, 10);
        let p = phi_taylor(m, 20);
        for l in 0..10 {
            let sgn = if l % 2 == 0 { Rat::one() } else { -Rat::one() };
            assert_eq!(t[l], sgn * &p[2 * l]);
        }
    }
}

#[test]
fn pade_approximants_of_phi() {
    for k in 0..=8 {
        for m in 1..=8 {
            let (num, den) = phi_pade(k, m);
            assert_eq!(den.coeff(0), Rat::one());
            // D φ_k − N = O(z^{2m+1}).
            let t = Poly::new(phi_taylor(k, 2 * m + 1));
            let resid = den.mul(&t).add(&num.scale(&-Rat::one()));
            for n in 0..=2 * m {
                assert!(resid.coeff(n).is_zero(), "k={k} m={m} n={n}");
            }
            // Skaflestad–Wright (2009), closed form of the [m/m] approximant of φ_k.
            let f = |n: usize| Rat::from_integer(ecr_codegen::rat::factorial(n as u64));
            let scale = f(m) / f(2 * m + k);
            let d_sw = Poly::new(
                (0..=m)
                    .map(|i| {
                        let sg = if i % 2 == 0 { Rat::one() } else { -Rat::one() };
                        &scale * f(2 * m + k - i) * sg / (f(i) * f(m - i))
                    })
                    .collect(),
            );
            let n_sw = Poly::new(
                (0..=m)
                    .map(|i| {
                        (0..=i).fold(Rat::zero(), |acc, j| {
                            let sg = if j % 2 == 0 { Rat::one() } else { -Rat::one() };
                            acc + f(2 * m + k - j) * sg / (f(j) * f(m - j) * f(k + i - j))
                        }) * &scale
                    })
                    .collect(),
            );
            assert_eq!(den, d_sw, "denominator k={k} m={m}");
            assert_eq!(num, n_sw, "numerator k={k} m={m}");
        }
    }
}

#[test]
fn small_sanity_values() {
    assert_eq!(c_jk(2, 1), int(-6));
    assert_eq!(
        shifted_legendre(2),
        Poly::new(vec![int(1), int(-6), int(6)])
    );
    assert_eq!(beta(1, 0), Poly::constant(int(1)));
    assert_eq!(pow(&frac(1, 2), 3), frac(1, 8));
}
