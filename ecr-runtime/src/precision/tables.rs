//! The method's coefficients in the scalar `S`, from the exact rationals of `ecr-codegen`.

use super::Real;
use crate::error::{Error, Result};
use ecr_codegen::legendre::c_jk;
use ecr_codegen::table::check_rs;
use ecr_codegen::{Certified, Family, Interval, MethodTable, Rat};
use num_bigint::BigInt;

/// The largest `n` with `1/n!` in [`GenericTables::inv_factorial`]: what the Taylor series of
/// `φ_r` takes for the largest r the generator supports (`1/(M + r)!`, `M` Taylor terms).
pub(crate) const MAX_FACTORIAL: usize = super::kernels::TAYLOR_TERMS + ecr_codegen::MAX_R;

/// The coefficients of ECrP with r moments and s Gauss–Legendre points, each the correctly
/// rounded double-double of its exact value read in `S` ([`Real::from_dd`]): for `f64` the
/// correctly rounded `f64`, the same numbers as [`crate::tables::coefficients`].
#[derive(Clone, Debug)]
pub struct GenericTables<S> {
    /// Order parameter r.
    pub r: usize,
    /// Number of quadrature points s.
    pub s: usize,
    /// Nodes cᵢ (s).
    pub nodes: Vec<S>,
    /// Weights bᵢ (s).
    pub weights: Vec<S>,
    /// Legendre moment weights ℓ_{ji} = bᵢ P̃ⱼ(cᵢ), row-major r × s.
    pub lw: Vec<S>,
    /// The integers c_{jk} of the kernels Ψⱼ(τ, Z) = Σ_{k≤j} c_{jk} τᵏ φ_{k+1}(τZ), row-major
    /// r × r (zero above the diagonal).
    pub c: Vec<S>,
    /// 1/n! for n = 0..=54 (`MAX_FACTORIAL`).
    pub inv_factorial: Vec<S>,
}

/// The exact rational `x` in `S`, correctly rounded to double-double first.
fn rational<S: Real>(x: &Rat) -> Result<S> {
    let (hi, lo) = Interval::point(x.clone())
        .round_dd()
        .ok_or_else(|| Error::Numerical(format!("{x} does not round to a double-double")))?;
    Ok(S::from_dd(hi, lo))
}

fn certified<S: Real>(c: &Certified) -> Result<S> {
    let (hi, lo) = c.value_dd().ok_or_else(|| {
        Error::Numerical("a coefficient's enclosure does not decide its double-double".into())
    })?;
    Ok(S::from_dd(hi, lo))
}

impl<S: Real> GenericTables<S> {
    /// The tables for (r, s), generated exactly by `ecr-codegen`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] unless 1 ≤ r ≤ `ecr_codegen::MAX_R` and
    /// r ≤ s ≤ `ecr_codegen::MAX_S`.
    pub fn new(r: usize, s: usize) -> Result<Self> {
        check_rs(r, s).map_err(|e| Error::InvalidParameter(e.to_string()))?;
        let t = MethodTable::generate(Family::Ec, r, s)
            .map_err(|e| Error::InvalidParameter(e.to_string()))?;
        let nodes = t.nodes.iter().map(certified).collect::<Result<Vec<S>>>()?;
        let weights = t
            .weights
            .iter()
            .map(certified)
            .collect::<Result<Vec<S>>>()?;
        let lw =
            t.lw.iter()
                .flatten()
                .map(certified)
                .collect::<Result<Vec<S>>>()?;
        let mut c = Vec::with_capacity(r * r);
        for j in 0..r {
            for k in 0..r {
                c.push(rational(&c_jk(j, k))?);
            }
        }
        let mut fact = BigInt::from(1);
        let mut inv_factorial = Vec::with_capacity(MAX_FACTORIAL + 1);
        for n in 0..=MAX_FACTORIAL {
            if n > 0 {
                fact *= BigInt::from(n);
            }
            inv_factorial.push(rational(&Rat::new(BigInt::from(1), fact.clone()))?);
        }
        Ok(GenericTables {
            r,
            s,
            nodes,
            weights,
            lw,
            c,
            inv_factorial,
        })
    }
}
