//! The table model: everything a stepper of one family, order r and s quadrature points needs,
//! exact data and certified `f64` roundings side by side. One model, rendered four ways
//! (Rust source, tokens, JSON, Markdown) by [`crate::render`].

use crate::interval::{Interval, matmul_rounded};
use crate::legendre::{beta, c_matrix, shifted_legendre};
use crate::poly::Poly;
use crate::quadrature::{Quadrature, QuadratureKind, working_bits};
use crate::rat::{Rat, inv_factorial, to_decimal};
use crate::{CodegenError, MAX_R, MAX_S};
use num_bigint::BigInt;
use num_traits::Zero;
use std::fmt;
use std::str::FromStr;

/// Method family.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Family {
    /// ECrP: exponential collocation for y' = Ay + g(y) (paper eq. `PEEPCr`).
    Ec,
    /// TCrP: trigonometric collocation for q'' + Ωq = −∇U(q) (paper eq. `EEPCr of erkn`).
    Tc,
    /// RKNCrP: the Ω = 0 case of TCrP (paper eq. `EEPCr of rkn`), pure rational kernels.
    Rknc,
}

impl Family {
    /// Lower-case name: `ec`, `tc`, `rknc`.
    pub fn name(self) -> &'static str {
        match self {
            Family::Ec => "ec",
            Family::Tc => "tc",
            Family::Rknc => "rknc",
        }
    }
}

impl fmt::Display for Family {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Family {
    type Err = CodegenError;
    fn from_str(s: &str) -> Result<Self, CodegenError> {
        match s {
            "ec" => Ok(Family::Ec),
            "tc" => Ok(Family::Tc),
            "rknc" => Ok(Family::Rknc),
            other => Err(CodegenError::UnknownFamily(other.to_string())),
        }
    }
}

/// An `f64` together with a rigorous enclosure of the exact value it rounds.
#[derive(Clone, Debug, PartialEq)]
pub struct Certified {
    /// The correctly rounded value.
    pub value: f64,
    /// An interval of relative width < 10⁻⁶⁰ that contains the exact value.
    pub enclosure: Interval,
}

impl Certified {
    /// The correctly rounded double-double `(hi, lo)` of the exact value (`hi` is
    /// [`Certified::value`]); see [`Interval::round_dd`]. `None` only if the enclosure cannot
    /// decide the rounding of the low part (not met for any table of this crate: tested).
    pub fn value_dd(&self) -> Option<(f64, f64)> {
        self.enclosure.round_dd()
    }

    /// The exact value to `digits` decimals (truncated midpoint of the enclosure).
    pub fn decimal(&self, digits: usize) -> String {
        to_decimal(&self.enclosure.mid(), digits)
    }
}

/// Number of decimals of the enclosures shown in provenance comments and JSON.
pub const PROVENANCE_DIGITS: usize = 40;

/// Coefficient table of one method.
#[derive(Clone, Debug)]
pub struct MethodTable {
    /// Method family.
    pub family: Family,
    /// Order parameter: the method has order 2r, r moments.
    pub r: usize,
    /// Number of quadrature points (s ≥ r; s = r with Gauss–Legendre is the paper's method).
    pub s: usize,
    /// The quadrature: Gauss–Legendre (ECrP, TCrP, RKNCrP) or Gauss–Lobatto (HBVM baselines).
    pub quadrature: QuadratureKind,
    /// Gauss–Legendre nodes cᵢ on [0, 1].
    pub nodes: Vec<Certified>,
    /// Gauss–Legendre weights bᵢ.
    pub weights: Vec<Certified>,
    /// Moment weights w_{kj} = bⱼ β_k(cⱼ), r rows of s.
    pub w: Vec<Vec<Certified>>,
    /// Legendre moment weights ℓ_{kj} = bⱼ P̃_k(cⱼ), r rows of s: the well-conditioned moments
    /// L_k = Σⱼ ℓ_{kj} g(Yⱼ) of ECrP (|ℓ_{kj}| ≤ bⱼ, where |w_{kj}| grows like 6^r).
    pub lw: Vec<Vec<Certified>>,
    /// P̃ₛ, whose roots are the nodes.
    pub node_polynomial: Poly,
    /// P̃₀ … P̃_{r−1}.
    pub legendre: Vec<Poly>,
    /// c_{jk}, j < r, k ≤ j.
    pub c: Vec<Vec<Rat>>,
    /// β₀ … β_{r−1}.
    pub beta: Vec<Poly>,
    /// RKNC only: ā_{ij} = Σ_k cᵢ^{k+2}/(k+2)! w_{kj} (s × s) — the RKN matrix of RKNCrP.
    pub abar: Vec<Vec<Certified>>,
    /// RKNC only: b̄ⱼ = Σ_k w_{kj}/(k+2)! — the position weights of RKNCrP.
    pub bbar: Vec<Certified>,
    /// Bisection depth that certified every value.
    pub bits: u32,
}

/// 10⁻⁶⁰: every enclosure is at least this tight, relative to its magnitude.
fn digits_60() -> Rat {
    Rat::new(1.into(), BigInt::from(10).pow(60))
}

fn certify(iv: Interval) -> Option<Certified> {
    if !(iv.relative_width_at_most(&digits_60())) {
        return None;
    }
    iv.round_f64().map(|value| Certified {
        value,
        enclosure: iv,
    })
}

fn certify_all(ivs: Vec<Interval>) -> Option<Vec<Certified>> {
    ivs.into_iter().map(certify).collect()
}

/// Checks 1 ≤ r ≤ MAX_R and r ≤ s ≤ MAX_S.
pub fn check_rs(r: usize, s: usize) -> Result<(), CodegenError> {
    if r == 0 || r > MAX_R {
        return Err(CodegenError::ROutOfRange { r });
    }
    if s < r || s > MAX_S {
        return Err(CodegenError::SOutOfRange { r, s });
    }
    Ok(())
}

impl MethodTable {
    /// Generates the table of `family` with order parameter r and s Gauss–Legendre points.
    ///
    /// # Errors
    /// [`CodegenError::ROutOfRange`] unless 1 ≤ r ≤ [`MAX_R`]; [`CodegenError::SOutOfRange`]
    /// unless r ≤ s ≤ [`MAX_S`].
    pub fn generate(family: Family, r: usize, s: usize) -> Result<MethodTable, CodegenError> {
        Self::generate_with(family, r, s, QuadratureKind::GaussLegendre)
    }

    /// As [`MethodTable::generate`] with a choice of quadrature. With Gauss–Lobatto points and
    /// A = 0 the method is HBVM(s, r) on Lobatto abscissae (s = 5, r = 2: RKEPC2, the paper's
    /// "extended Lobatto IIIA of order four").
    ///
    /// # Errors
    /// As [`MethodTable::generate`]; Gauss–Lobatto also needs s ≥ 2.
    pub fn generate_with(
        family: Family,
        r: usize,
        s: usize,
        quadrature: QuadratureKind,
    ) -> Result<MethodTable, CodegenError> {
        check_rs(r, s)?;
        if quadrature == QuadratureKind::GaussLobatto && s < 2 {
            return Err(CodegenError::SOutOfRange { r, s });
        }
        let betas: Vec<Poly> = (0..r).map(|k| beta(r, k)).collect();
        let mut bits = 256;
        loop {
            if let Some(t) = Self::try_generate(family, r, s, quadrature, &betas, bits) {
                return Ok(t);
            }
            bits *= 2;
            if bits > 1 << 14 {
                return Err(CodegenError::Certification { r, s });
            }
        }
    }

    fn try_generate(
        family: Family,
        r: usize,
        s: usize,
        quadrature: QuadratureKind,
        betas: &[Poly],
        bits: u32,
    ) -> Option<MethodTable> {
        let q = match quadrature {
            QuadratureKind::GaussLegendre => Quadrature::gauss_legendre(s, bits),
            QuadratureKind::GaussLobatto => Quadrature::gauss_lobatto(s, bits),
        };
        let work = working_bits(bits);
        let w_iv: Vec<Vec<Interval>> = betas
            .iter()
            .map(|bk| {
                q.nodes
                    .iter()
                    .zip(&q.weights)
                    .map(|(c, b)| b.mul(&bk.eval_interval(c, work)).rounded(work))
                    .collect()
            })
            .collect();
        // The moment weights lose the most digits to cancellation (|w_kj| grows like 6^r):
        // if they cannot be certified at this depth, stop before the rest is computed.
        let w = w_iv
            .iter()
            .cloned()
            .map(certify_all)
            .collect::<Option<Vec<_>>>()?;
        let legendre: Vec<Poly> = (0..r).map(shifted_legendre).collect();
        let lw_iv: Vec<Vec<Interval>> = legendre
            .iter()
            .map(|pk| {
                q.nodes
                    .iter()
                    .zip(&q.weights)
                    .map(|(c, b)| b.mul(&pk.eval_interval(c, work)).rounded(work))
                    .collect()
            })
            .collect();
        let (abar, bbar) = if family == Family::Rknc {
            // c_i^{k+2}/(k+2)!, i < s, k < r: the same operations for every j, done once;
            // then Ā = C W as one product of interval matrices.
            let powers: Vec<Vec<Interval>> = q
                .nodes
                .iter()
                .map(|ci| {
                    (0..r)
                        .map(|k| {
                            (0..k + 2).fold(Interval::point(inv_factorial(k as u64 + 2)), |p, _| {
                                p.mul(ci).rounded(work)
                            })
                        })
                        .collect()
                })
                .collect();
            let abar = matmul_rounded(&powers, &w_iv, work)
                .into_iter()
                .map(certify_all)
                .collect::<Option<Vec<_>>>()?;
            let bbar = certify_all(
                (0..s)
                    .map(|j| {
                        (0..r).fold(Interval::point(Rat::zero()), |acc, k| {
                            acc.add(
                                &w_iv[k][j]
                                    .mul(&Interval::point(inv_factorial(k as u64 + 2)))
                                    .rounded(work),
                            )
                        })
                    })
                    .collect(),
            )?;
            (abar, bbar)
        } else {
            (Vec::new(), Vec::new())
        };
        Some(MethodTable {
            family,
            r,
            s,
            quadrature,
            nodes: certify_all(q.nodes.clone())?,
            weights: certify_all(q.weights.clone())?,
            w,
            lw: lw_iv
                .into_iter()
                .map(certify_all)
                .collect::<Option<Vec<_>>>()?,
            node_polynomial: q.node_polynomial.clone(),
            legendre,
            c: c_matrix(r),
            beta: betas.to_vec(),
            abar,
            bbar,
            bits,
        })
    }

    /// Identifier used for generated modules and constants, e.g. `ec_r3_s3`.
    pub fn ident(&self) -> String {
        let kind = match self.quadrature {
            QuadratureKind::GaussLegendre => "",
            QuadratureKind::GaussLobatto => "_lobatto",
        };
        format!("{}_r{}_s{}{kind}", self.family.name(), self.r, self.s)
    }

    /// Nodes as `f64`.
    pub fn nodes_f64(&self) -> Vec<f64> {
        self.nodes.iter().map(|c| c.value).collect()
    }

    /// Weights as `f64`.
    pub fn weights_f64(&self) -> Vec<f64> {
        self.weights.iter().map(|c| c.value).collect()
    }

    /// Moment weights as `f64`, row-major r × s.
    pub fn w_f64(&self) -> Vec<f64> {
        self.w.iter().flatten().map(|c| c.value).collect()
    }

    /// Legendre moment weights as `f64`, row-major r × s.
    pub fn lw_f64(&self) -> Vec<f64> {
        self.lw.iter().flatten().map(|c| c.value).collect()
    }

    /// Whether the rounded exact data is consistent (used by tests): every β_k is non-zero.
    pub fn is_well_formed(&self) -> bool {
        self.beta.iter().all(|b| b.degree().is_some())
            && self.nodes.len() == self.s
            && self.w.iter().all(|row| row.len() == self.s)
            && self.lw.iter().all(|row| row.len() == self.s)
            && !self.weights.iter().any(|b| b.enclosure.lo.is_zero())
    }
}

#[cfg(test)]
mod double_double_tests {
    use super::*;
    use crate::rat::to_f64;

    /// Every coefficient of every table r ≤ 10, s ∈ {r, r+2}, has a double-double, and it is
    /// within ulp(lo)/2 of the enclosure (the midpoint: the width is below 1e−60 relative).
    #[test]
    fn every_coefficient_rounds_to_a_double_double() {
        for r in 1..=10 {
            for s in [r, r + 2] {
                let t = MethodTable::generate(Family::Ec, r, s).unwrap();
                for c in t
                    .nodes
                    .iter()
                    .chain(&t.weights)
                    .chain(t.lw.iter().flatten())
                {
                    let (hi, lo) = c.value_dd().expect("a double-double");
                    assert_eq!(hi, c.value);
                    let exact = c.enclosure.mid();
                    let pair = Rat::from_float(hi).unwrap() + Rat::from_float(lo).unwrap();
                    let err = to_f64(&(exact - pair)).abs();
                    let ulp_lo = if lo == 0.0 {
                        f64::MIN_POSITIVE
                    } else {
                        f64::EPSILON * lo.abs()
                    };
                    assert!(
                        err <= ulp_lo.max(1e-45 * hi.abs()),
                        "r = {r}, s = {s}: {hi} + {lo} off by {err:e}"
                    );
                    // lo is below half an ulp of hi (a normalised pair).
                    assert!(lo.abs() <= 0.5 * f64::EPSILON * hi.abs());
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Ā of RKNC as the generator computed it before the powers c_i^{k+2}/(k+2)! were taken
    /// out of the loop over j (issue 44: 260 s for r = 32, s = 64), at the depth `bits` the
    /// table was certified at.
    fn abar_before(t: &MethodTable) -> Vec<Vec<Certified>> {
        let (r, s) = (t.r, t.s);
        let q = Quadrature::gauss_legendre(s, t.bits);
        let work = working_bits(t.bits);
        let w_iv: Vec<Vec<Interval>> = t
            .beta
            .iter()
            .map(|bk| {
                q.nodes
                    .iter()
                    .zip(&q.weights)
                    .map(|(c, b)| b.mul(&bk.eval_interval(c, work)).rounded(work))
                    .collect()
            })
            .collect();
        q.nodes
            .iter()
            .map(|ci| {
                certify_all(
                    (0..s)
                        .map(|j| {
                            (0..r).fold(Interval::point(Rat::zero()), |acc, k| {
                                let ck = (0..k + 2)
                                    .fold(Interval::point(inv_factorial(k as u64 + 2)), |p, _| {
                                        p.mul(ci).rounded(work)
                                    });
                                acc.add(&ck.mul(&w_iv[k][j]).rounded(work))
                            })
                        })
                        .collect(),
                )
                .unwrap()
            })
            .collect()
    }

    /// The faster Ā is the same, enclosures included, as the one computed the old way.
    #[test]
    fn rknc_abar_equals_the_old_computation() {
        for (r, s) in [(1, 1), (2, 3), (4, 4), (5, 9), (8, 8)] {
            let t = MethodTable::generate(Family::Rknc, r, s).unwrap();
            assert_eq!(t.abar, abar_before(&t), "r = {r}, s = {s}");
        }
    }
}
