use super::{float_literal, node_provenance};
use crate::rat::to_text;
use crate::table::{Family, MethodTable, PROVENANCE_DIGITS};
use std::fmt;

/// Markdown rendering of one table, for people.
pub struct Markdown<'a>(pub &'a MethodTable);

impl fmt::Display for Markdown<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let t = self.0;
        writeln!(
            f,
            "# {} tables: r = {}, s = {} (order {})\n",
            t.family.name().to_uppercase(),
            t.r,
            t.s,
            2 * t.r
        )?;
        writeln!(
            f,
            "Nodes: {}. Every float is the correctly rounded value of an enclosure of relative width < 1e-60.\n",
            node_provenance(t)
        )?;
        writeln!(
            f,
            "| i | c_i (f64) | c_i (exact, {PROVENANCE_DIGITS} digits) | b_i (f64) | b_i (exact) |"
        )?;
        writeln!(f, "|---|---|---|---|---|")?;
        for (i, (c, b)) in t.nodes.iter().zip(&t.weights).enumerate() {
            writeln!(
                f,
                "| {} | {} | {} | {} | {} |",
                i + 1,
                float_literal(c.value),
                c.decimal(PROVENANCE_DIGITS),
                float_literal(b.value),
                b.decimal(PROVENANCE_DIGITS)
            )?;
        }
        writeln!(f, "\n## Moment weights w_kj = b_j β_k(c_j)\n")?;
        write!(f, "| k |")?;
        for j in 1..=t.s {
            write!(f, " j = {j} |")?;
        }
        writeln!(f)?;
        writeln!(f, "|---|{}", "---|".repeat(t.s))?;
        for (k, row) in t.w.iter().enumerate() {
            write!(f, "| {k} |")?;
            for c in row {
                write!(f, " {} |", float_literal(c.value))?;
            }
            writeln!(f)?;
        }
        writeln!(f, "\n## Exact data\n")?;
        writeln!(f, "| j | shifted Legendre P̃_j | β_j |")?;
        writeln!(f, "|---|---|---|")?;
        for (j, (p, b)) in t.legendre.iter().zip(&t.beta).enumerate() {
            writeln!(f, "| {j} | {p} | {b} |")?;
        }
        writeln!(f, "\nc_jk = (−1)^(j+k) (j+k)! / (k! (j−k)!):\n")?;
        for (j, row) in t.c.iter().enumerate() {
            let txt: Vec<String> = row.iter().map(to_text).collect();
            writeln!(f, "- j = {j}: {}", txt.join(", "))?;
        }
        if t.family == Family::Rknc {
            writeln!(f, "\n## RKN coefficients (K = 0)\n")?;
            writeln!(f, "| i | ā_i1 … ā_is | b̄_i |")?;
            writeln!(f, "|---|---|---|")?;
            for (i, (row, bb)) in t.abar.iter().zip(&t.bbar).enumerate() {
                let txt: Vec<String> = row.iter().map(|c| float_literal(c.value)).collect();
                writeln!(
                    f,
                    "| {} | {} | {} |",
                    i + 1,
                    txt.join(", "),
                    float_literal(bb.value)
                )?;
            }
        }
        Ok(())
    }
}
