//! One table model, four renderings: Rust source ([`RustSource`], for build scripts),
//! tokens (`ToTokens`, feature `tokens`, for the proc-macro), JSON ([`to_json`], feature
//! `json`) and Markdown ([`Markdown`]). All print floats so they round-trip exactly.

#[cfg(feature = "json")]
mod json;
mod markdown;
mod rust;
#[cfg(feature = "tokens")]
mod tokens;

#[cfg(feature = "json")]
pub use json::to_json;
pub use markdown::Markdown;
pub use rust::{RustSource, rust_index};

/// A float literal that parses back to the same bits (Rust's shortest round-trip `{:?}`).
pub fn float_literal(x: f64) -> String {
    format!("{x:?}")
}

/// Description of how the nodes were obtained, for provenance comments.
pub(crate) fn node_provenance(t: &crate::MethodTable) -> String {
    match t.quadrature {
        crate::QuadratureKind::GaussLegendre => {
            format!("roots of P̃_{}(x) = {} in (0, 1)", t.s, t.node_polynomial)
        }
        crate::QuadratureKind::GaussLobatto => format!(
            "Gauss–Lobatto: 0, 1 and the roots of P̃'_{}(x) = {} in (0, 1)",
            t.s - 1,
            t.node_polynomial
        ),
    }
}
