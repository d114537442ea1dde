//! Procedural macros of ecr: `ecr_method!` emits a fixed-order ECrP stepper whose
//! coefficients were generated exactly at compile time (by `ecr-codegen`) and whose moment and
//! stage loops are unrolled. Use it through `ecr_runtime::ecr_method` (or `ecr::ecr_method`),
//! where it is documented with examples.
#![deny(missing_docs)]

mod args;
mod expand;

use proc_macro::TokenStream;

/// Emits a fixed-order ECrP stepper: `ecr_method!(r = 3)`, options `s = S`, `name = Ident`,
/// `family = ec | tc | rknc`, `runtime = path`, and a leading visibility (`pub`, `pub(crate)`).
/// See `ecr_runtime::ecr_method` for the full documentation and examples.
#[proc_macro]
pub fn ecr_method(input: TokenStream) -> TokenStream {
    let args = syn::parse_macro_input!(input as args::MethodArgs);
    expand::expand(&args)
        .unwrap_or_else(syn::Error::into_compile_error)
        .into()
}
