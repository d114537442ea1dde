use crate::table::{Certified, Family, MethodTable, PROVENANCE_DIGITS};
use proc_macro2::{Literal, TokenStream};
use quote::{ToTokens, quote};

fn lits(v: &[Certified]) -> Vec<Literal> {
    v.iter().map(|c| Literal::f64_suffixed(c.value)).collect()
}

fn provenance(label: &str, v: &[Certified]) -> String {
    v.iter()
        .enumerate()
        .map(|(i, c)| format!("{label}_{} = {}…", i + 1, c.decimal(PROVENANCE_DIGITS)))
        .collect::<Vec<_>>()
        .join(", ")
}

impl ToTokens for MethodTable {
    /// Emits `pub const R, S, NODES: [f64; S], WEIGHTS: [f64; S], W, LW: [[f64; S]; R]` (plus
    /// `ABAR: [[f64; S]; S]`, `BBAR: [f64; S]` for RKNC), with provenance in doc attributes.
    fn to_tokens(&self, out: &mut TokenStream) {
        let (r, s) = (self.r, self.s);
        let nodes = lits(&self.nodes);
        let weights = lits(&self.weights);
        let w_rows = self.w.iter().map(|row| {
            let l = lits(row);
            quote!([#(#l),*])
        });
        let lw_rows = self.lw.iter().map(|row| {
            let l = lits(row);
            quote!([#(#l),*])
        });
        let doc_nodes = format!(
            " Nodes cᵢ, {}: {}.",
            super::node_provenance(self),
            provenance("c", &self.nodes)
        );
        let doc_weights = format!(" Weights bᵢ: {}.", provenance("b", &self.weights));
        let betas: Vec<String> = self
            .beta
            .iter()
            .enumerate()
            .map(|(k, b)| format!("β_{k}(x) = {b}"))
            .collect();
        let doc_w = format!(" Moment weights w_kj = b_j β_k(c_j); {}.", betas.join("; "));
        out.extend(quote! {
            /// Order parameter r (order 2r).
            pub const R: usize = #r;
            /// Number of quadrature points s.
            pub const S: usize = #s;
            #[doc = #doc_nodes]
            pub const NODES: [f64; #s] = [#(#nodes),*];
            #[doc = #doc_weights]
            pub const WEIGHTS: [f64; #s] = [#(#weights),*];
            #[doc = #doc_w]
            pub const W: [[f64; #s]; #r] = [#(#w_rows),*];
            /// Legendre moment weights ℓ_kj = b_j P̃_k(c_j) (the moments of ECrP; |ℓ_kj| ≤ b_j).
            pub const LW: [[f64; #s]; #r] = [#(#lw_rows),*];
        });
        if self.family == Family::Rknc {
            let rows = self.abar.iter().map(|row| {
                let l = lits(row);
                quote!([#(#l),*])
            });
            let bbar = lits(&self.bbar);
            out.extend(quote! {
                /// RKN matrix ā_ij = Σ_k c_i^{k+2}/(k+2)! w_kj.
                pub const ABAR: [[f64; #s]; #s] = [#(#rows),*];
                /// RKN position weights b̄_j = Σ_k w_kj/(k+2)!.
                pub const BBAR: [f64; #s] = [#(#bbar),*];
            });
        }
    }
}
