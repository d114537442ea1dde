use super::{float_literal, node_provenance};
use crate::quadrature::QuadratureKind;
use crate::table::{Certified, Family, MethodTable, PROVENANCE_DIGITS};
use std::fmt;

/// Rust source of one table: a module `<family>_r<r>_s<s>` (`…_lobatto` on Gauss–Lobatto
/// points) with fixed-size `const` arrays,
/// each constant followed by its exact provenance (libm style).
pub struct RustSource<'a>(pub &'a MethodTable);

fn write_array(
    f: &mut fmt::Formatter<'_>,
    doc: &str,
    name: &str,
    values: &[(String, Certified)],
) -> fmt::Result {
    writeln!(f, "    /// {doc}")?;
    writeln!(f, "    pub const {name}: [f64; {}] = [", values.len())?;
    for (label, c) in values {
        writeln!(
            f,
            "        {}_f64, // {label} = {}…",
            float_literal(c.value),
            c.decimal(PROVENANCE_DIGITS)
        )?;
    }
    writeln!(f, "    ];")
}

impl fmt::Display for RustSource<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let t = self.0;
        writeln!(
            f,
            "/// {} coefficients, r = {}, s = {} Gauss–Legendre points (order {}).",
            match t.family {
                Family::Ec => "ECrP",
                Family::Tc => "TCrP",
                Family::Rknc => "RKNCrP",
            },
            t.r,
            t.s,
            2 * t.r
        )?;
        writeln!(
            f,
            "#[allow(clippy::excessive_precision, clippy::unreadable_literal)]"
        )?;
        writeln!(f, "pub mod {} {{", t.ident())?;
        writeln!(f, "    /// Order parameter r (the method has order 2r).")?;
        writeln!(f, "    pub const R: usize = {};", t.r)?;
        writeln!(f, "    /// Number of quadrature points s.")?;
        writeln!(f, "    pub const S: usize = {};", t.s)?;
        let lab = |p: &str, v: &[Certified]| -> Vec<(String, Certified)> {
            v.iter()
                .enumerate()
                .map(|(i, c)| (format!("{p}_{}", i + 1), c.clone()))
                .collect()
        };
        let nodes = lab("c", &t.nodes);
        write_array(
            f,
            &format!("Nodes cᵢ: {}.", node_provenance(t)),
            "NODES",
            &nodes,
        )?;
        let weights = lab("b", &t.weights);
        write_array(
            f,
            &match t.quadrature {
                crate::QuadratureKind::GaussLegendre => {
                    format!("Weights bᵢ = 1 / (cᵢ (1 − cᵢ) P̃_{}'(cᵢ)²).", t.s)
                }
                crate::QuadratureKind::GaussLobatto => {
                    format!("Weights bᵢ = 1 / (s (s − 1) P̃_{}(cᵢ)²).", t.s - 1)
                }
            },
            "WEIGHTS",
            &weights,
        )?;
        let w: Vec<(String, Certified)> =
            t.w.iter()
                .enumerate()
                .flat_map(|(k, row)| {
                    row.iter().enumerate().map(move |(j, c)| {
                        (
                            format!("w_{{{k},{}}} = b_{} β_{k}(c_{})", j + 1, j + 1, j + 1),
                            c.clone(),
                        )
                    })
                })
                .collect();
        let betas: Vec<String> = t
            .beta
            .iter()
            .enumerate()
            .map(|(k, b)| format!("β_{k}(x) = {b}"))
            .collect();
        write_array(
            f,
            &format!(
                "Moment weights w_{{kj}} = bⱼ β_k(cⱼ), row-major r × s; {}.",
                betas.join("; ")
            ),
            "W",
            &w,
        )?;
        let lw: Vec<(String, Certified)> =
            t.lw.iter()
                .enumerate()
                .flat_map(|(k, row)| {
                    row.iter().enumerate().map(move |(j, c)| {
                        (
                            format!("ℓ_{{{k},{}}} = b_{} P̃_{k}(c_{})", j + 1, j + 1, j + 1),
                            c.clone(),
                        )
                    })
                })
                .collect();
        write_array(
            f,
            "Legendre moment weights ℓ_{kj} = bⱼ P̃_k(cⱼ), row-major r × s.",
            "LW",
            &lw,
        )?;
        if t.family == Family::Rknc {
            let abar: Vec<(String, Certified)> = t
                .abar
                .iter()
                .enumerate()
                .flat_map(|(i, row)| {
                    row.iter()
                        .enumerate()
                        .map(move |(j, c)| (format!("ā_{{{},{}}}", i + 1, j + 1), c.clone()))
                })
                .collect();
            write_array(
                f,
                "RKN matrix āᵢⱼ = Σ_k cᵢ^{k+2}/(k+2)! w_{kj}, row-major s × s.",
                "ABAR",
                &abar,
            )?;
            let bbar = lab("b̄", &t.bbar);
            write_array(
                f,
                "RKN position weights b̄ⱼ = Σ_k w_{kj}/(k+2)!.",
                "BBAR",
                &bbar,
            )?;
        }
        writeln!(f, "}}")
    }
}

/// Source of a whole generated file: a header, every table's module and two indexes for
/// run-time lookup, `TABLES` (Gauss–Legendre) and `LOBATTO_TABLES` (Gauss–Lobatto):
/// `&[(r, s, nodes, weights, w, ℓ)]`.
pub fn rust_index(tables: &[MethodTable], command: &str) -> String {
    let mut out = format!(
        "// DO NOT EDIT: generated by {command} (ecr-codegen {}).\n\n",
        env!("CARGO_PKG_VERSION")
    );
    for t in tables {
        out.push_str(&RustSource(t).to_string());
        out.push('\n');
    }
    for (name, kind, what) in [
        ("TABLES", QuadratureKind::GaussLegendre, "Gauss–Legendre"),
        (
            "LOBATTO_TABLES",
            QuadratureKind::GaussLobatto,
            "Gauss–Lobatto",
        ),
    ] {
        out.push_str(&format!(
            "/// Every built-in {what} table as (r, s, nodes, weights, row-major moment weights w,\n\
             /// row-major Legendre moment weights ℓ).\n\
             #[allow(clippy::type_complexity)]\n\
             pub static {name}: &[(usize, usize, &[f64], &[f64], &[f64], &[f64])] = &[\n"
        ));
        for t in tables.iter().filter(|t| t.quadrature == kind) {
            let m = t.ident();
            out.push_str(&format!(
                "    ({}, {}, &{m}::NODES, &{m}::WEIGHTS, &{m}::W, &{m}::LW),\n",
                t.r, t.s
            ));
        }
        out.push_str("];\n");
    }
    out
}
