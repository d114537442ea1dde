//! Expansion of `ecr_method!`.

use crate::args::{Family, MethodArgs};
use proc_macro2::{Span, TokenStream};
use quote::{format_ident, quote};
use syn::Ident;

/// The path of the runtime crate: the `runtime = …` override, else `ecr-runtime` or the `ecr`
/// facade (whichever the calling crate depends on), else `::ecr_runtime`.
fn runtime_path(args: &MethodArgs) -> TokenStream {
    if let Some(p) = &args.runtime {
        return quote!(#p);
    }
    use proc_macro_crate::{FoundCrate, crate_name};
    match crate_name("ecr-runtime") {
        // Inside ecr-runtime (its tests, examples and doctests included) the crate is
        // reachable as `::ecr_runtime` (the library declares `extern crate self as ecr_runtime`).
        Ok(FoundCrate::Itself) => quote!(::ecr_runtime),
        Ok(FoundCrate::Name(n)) => {
            let id = Ident::new(&n, Span::call_site());
            quote!(::#id)
        }
        Err(_) => match crate_name("ecr") {
            Ok(FoundCrate::Name(n)) => {
                let id = Ident::new(&n, Span::call_site());
                quote!(::#id::runtime)
            }
            Ok(FoundCrate::Itself) => quote!(crate::runtime),
            Err(_) => quote!(::ecr_runtime),
        },
    }
}

/// The unrolled moment accumulation m_k = 0.0 + Σ_j C[k][j] g_j (left to right, as the
/// run-time kernel rounds) over the constant table `C` (`LW`).
fn moments_body(r: usize, s: usize, table: &Ident) -> TokenStream {
    let loads = (0..s).map(|j| {
        let gj = format_ident!("__ecr_g{}", j);
        quote!(let #gj = __ecr_g[#j * __ecr_d + __ecr_l];)
    });
    let stores = (0..r).map(|k| {
        let terms = (0..s).map(|j| {
            let gj = format_ident!("__ecr_g{}", j);
            quote!(+ Self::#table[#k][#j] * #gj)
        });
        quote!(__ecr_m[#k * __ecr_d + __ecr_l] = 0.0 #(#terms)*;)
    });
    quote! {
        assert!(__ecr_g.len() >= #s * __ecr_d && __ecr_m.len() >= #r * __ecr_d);
        for __ecr_l in 0..__ecr_d {
            #(#loads)*
            #(#stores)*
        }
    }
}

/// Expands validated arguments into the kernel type, its `Kernel` impl and the stepper aliases.
pub fn expand(args: &MethodArgs) -> syn::Result<TokenStream> {
    let (r, s, vis, name) = (args.r, args.s, &args.vis, &args.name);
    let family = match args.family {
        Family::Ec => ecr_codegen::Family::Ec,
        Family::Tc => ecr_codegen::Family::Tc,
        Family::Rknc => ecr_codegen::Family::Rknc,
    };
    let table = ecr_codegen::MethodTable::generate(family, r, s)
        .map_err(|e| syn::Error::new(Span::call_site(), e.to_string()))?;
    let rt = runtime_path(args);
    let kernel = format_ident!("{}Kernel", name);
    let legendre_moments = moments_body(r, s, &format_ident!("LW"));
    let stages = (0..s).map(|j| quote!(__ecr_f(#j)?;));
    let method = match args.family {
        Family::Ec => "ECrP",
        Family::Tc => "TCrP",
        Family::Rknc => "RKNCrP",
    };
    let doc_kernel = format!(
        " Coefficients of {method} with r = {r}, s = {s} (order {}), generated exactly at compile \
         time by `ecr_method!`; moment and stage loops unrolled.",
        2 * r
    );
    let steppers = stepper_aliases(args, &rt, &kernel);
    Ok(quote! {
        #[doc = #doc_kernel]
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
        #vis struct #kernel;

        #[allow(clippy::excessive_precision, clippy::unreadable_literal)]
        impl #kernel {
            #table
        }

        impl #rt::stepper::Kernel for #kernel {
            #[inline]
            fn r(&self) -> usize {
                #r
            }
            #[inline]
            fn s(&self) -> usize {
                #s
            }
            #[inline]
            fn nodes(&self) -> &[f64] {
                &Self::NODES
            }
            #[inline(always)]
            #[allow(clippy::identity_op, clippy::erasing_op)]
            fn legendre_moments(&self, __ecr_g: &[f64], __ecr_m: &mut [f64], __ecr_d: usize) {
                #legendre_moments
            }
            #[inline(always)]
            fn each_stage<F: FnMut(usize) -> #rt::Result<()>>(&self, mut __ecr_f: F) -> #rt::Result<()> {
                #(#stages)*
                Ok(())
            }
        }

        impl #rt::stepper::FixedKernel for #kernel {}

        #steppers
    })
}

/// The stepper aliases of a family.
fn stepper_aliases(args: &MethodArgs, rt: &TokenStream, kernel: &Ident) -> TokenStream {
    let (r, s, vis, name) = (args.r, args.s, &args.vis, &args.name);
    let dyn_name = format_ident!("{}Dyn", name);
    let doc_static = format!(
        " ECrP of order {} (r = {r}, s = {s}) for a system of dimension `D` known at compile time: \
         stage state in fixed-size arrays, no heap use per step.",
        2 * r
    );
    let doc_dyn = format!(
        " ECrP of order {} (r = {r}, s = {s}) for a dimension known at run time: stage state \
         allocated once at construction.",
        2 * r
    );
    if args.family != Family::Ec {
        let what = if args.family == Family::Tc {
            "TCrP, for q'' + Ωq = −∇U(q)"
        } else {
            "RKNCrP, for q'' = −∇U(q) (Ω = 0)"
        };
        let doc = format!(
            " {what}: order {} (r = {r}, s = {s}) for `N` positions known at compile time (state \
             (q, p) in fixed-size arrays, no heap use per step); the ECrP stepper on the \
             first-order form.",
            2 * r
        );
        let doc_dyn = format!(
            " {what}: order {} (r = {r}, s = {s}) for a dimension known at run time; stage state \
             allocated once at construction.",
            2 * r
        );
        return quote! {
            #[doc = #doc]
            #vis type #name<Sys, const N: usize> = #rt::second_order::TcStepper<
                Sys,
                #kernel,
                #rt::stepper::StaticBuffers<N, #s, #r, 2>,
            >;

            #[doc = #doc_dyn]
            #vis type #dyn_name<Sys> =
                #rt::second_order::TcStepper<Sys, #kernel, #rt::stepper::VecBuffers>;
        };
    }
    quote! {
        #[doc = #doc_static]
        #vis type #name<Sys, const D: usize> =
            #rt::stepper::Stepper<#kernel, Sys, #rt::stepper::StaticBuffers<D, #s, #r>>;

        #[doc = #doc_dyn]
        #vis type #dyn_name<Sys> = #rt::stepper::Stepper<#kernel, Sys, #rt::stepper::VecBuffers>;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use syn::parse_quote;

    fn expand_str(args: MethodArgs) -> String {
        expand(&args).unwrap().to_string()
    }

    #[test]
    fn expansion_of_r2() {
        let args: MethodArgs = parse_quote!(pub r = 2, runtime = ::rt);
        let out = expand_str(args);
        assert!(out.contains("pub struct Ec2Kernel"));
        assert!(out.contains(
            "pub type Ec2 < Sys , const D : usize > = :: rt :: stepper :: Stepper < Ec2Kernel"
        ));
        assert!(out.contains("StaticBuffers < D , 2usize , 2usize >"));
        assert!(out.contains("pub type Ec2Dyn < Sys >"));
        // Constants emitted bit-exactly.
        assert!(out.contains("0.2113248654051871f64"));
        // Unrolled moments: W[1][1] appears, no loop over j.
        assert!(out.contains("Self :: LW [1usize] [1usize] * __ecr_g1"));
        assert!(out.contains("__ecr_f (1usize) ?"));
    }

    #[test]
    fn options_name_s_and_visibility() {
        let args: MethodArgs =
            parse_quote!(pub(crate), r = 3, s = 5, name = Foo, family = ec, runtime = ::rt);
        assert_eq!((args.r, args.s), (3, 5));
        let out = expand_str(args);
        assert!(out.contains("pub (crate) struct FooKernel"));
        assert!(out.contains("StaticBuffers < D , 5usize , 3usize >"));
        let args: MethodArgs = parse_quote!(r = 3, s = 5, runtime = ::rt);
        assert_eq!(args.name.to_string(), "Ec3S5");
        assert!(matches!(args.vis, syn::Visibility::Inherited));
    }

    #[test]
    fn second_order_families() {
        let out = expand_str(parse_quote!(r = 2, family = tc, runtime = ::rt));
        assert!(out.contains(
            "type Tc2 < Sys , const N : usize > = :: rt :: second_order :: TcStepper < Sys , \
             Tc2Kernel , :: rt :: stepper :: StaticBuffers < N , 2usize , 2usize , 2 > , >"
        ));
        assert!(out.contains("type Tc2Dyn < Sys >"));
        let out = expand_str(parse_quote!(r = 2, family = rknc, runtime = ::rt));
        assert!(out.contains("type Rknc2 < Sys , const N : usize >"));
        // The RKN tableau comes with the RKNC kernel.
        assert!(out.contains("pub const ABAR"));
    }

    #[test]
    fn errors_are_collected() {
        let e = syn::parse2::<MethodArgs>(quote!(r = 0, q = 1, r = 2))
            .err()
            .unwrap();
        let msgs: Vec<String> = e.into_iter().map(|e| e.to_string()).collect();
        assert!(
            msgs.iter().any(|m| m.contains("unknown key `q`")),
            "{msgs:?}"
        );
        assert!(
            msgs.iter().any(|m| m.contains("duplicate key `r`")),
            "{msgs:?}"
        );
    }
}
