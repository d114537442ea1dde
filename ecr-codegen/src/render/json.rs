use crate::kernels::phi_trig_series;
use crate::rat::to_text;
use crate::table::{Certified, Family, MethodTable, PROVENANCE_DIGITS};
use serde_json::{Value, json};

fn floats(v: &[Certified]) -> Value {
    Value::Array(v.iter().map(|c| json!(c.value)).collect())
}

fn decimals(v: &[Certified]) -> Value {
    Value::Array(
        v.iter()
            .map(|c| json!(c.decimal(PROVENANCE_DIGITS)))
            .collect(),
    )
}

fn poly_text(p: &crate::Poly) -> Value {
    Value::Array(p.coeffs().iter().map(|a| json!(to_text(a))).collect())
}

/// JSON rendering: `family`, `r`, `s`, `nodes`, `weights`, `w` (r × s), `lw` (r × s, Legendre moment weights), `exact` {`legendre`,
/// `c`, `beta`, `node_polynomial`} as `"p/q"` strings (ascending coefficients), `decimal`
/// (40-digit values of every float), and per family `abar`/`bbar` (rknc) or
/// `phi_trig_series` (tc). Floats are printed by serde_json's shortest round-trip format.
pub fn to_json(t: &MethodTable) -> Value {
    let mut v = json!({
        "family": t.family.name(),
        "r": t.r,
        "s": t.s,
        "order": 2 * t.r,
        "nodes": floats(&t.nodes),
        "weights": floats(&t.weights),
        "w": t.w.iter().map(|row| floats(row)).collect::<Vec<_>>(),
        "lw": t.lw.iter().map(|row| floats(row)).collect::<Vec<_>>(),
        "exact": {
            "legendre": t.legendre.iter().map(poly_text).collect::<Vec<_>>(),
            "c": t.c.iter().map(|row| row.iter().map(to_text).collect::<Vec<_>>()).collect::<Vec<_>>(),
            "beta": t.beta.iter().map(poly_text).collect::<Vec<_>>(),
            "node_polynomial": poly_text(&t.node_polynomial),
        },
        "decimal": {
            "nodes": decimals(&t.nodes),
            "weights": decimals(&t.weights),
            "w": t.w.iter().map(|row| decimals(row)).collect::<Vec<_>>(),
            "lw": t.lw.iter().map(|row| decimals(row)).collect::<Vec<_>>(),
        },
        "certified_relative_width": "1e-60",
    });
    match t.family {
        Family::Rknc => {
            v["abar"] = Value::Array(t.abar.iter().map(|row| floats(row)).collect());
            v["bbar"] = floats(&t.bbar);
        }
        Family::Tc => {
            // φᵗ_m(K) = Σ_l (−K)^l/(2l+m)!, m = 0..=r+1, 12 terms each.
            v["phi_trig_series"] = Value::Array(
                (0..=t.r + 1)
                    .map(|m| {
                        Value::Array(
                            phi_trig_series(m, 12)
                                .iter()
                                .map(|a| json!(to_text(a)))
                                .collect(),
                        )
                    })
                    .collect(),
            );
        }
        Family::Ec => {}
    }
    v
}
