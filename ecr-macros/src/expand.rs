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

/// The stepper types of a family: newtypes (not aliases) around the runtime's steppers, so that
/// a type error names the type the user wrote (`Ec3<_, _>`), not the runtime's generic
/// `Stepper<…, StaticBuffers<…>>` behind it.
fn stepper_aliases(args: &MethodArgs, rt: &TokenStream, kernel: &Ident) -> TokenStream {
    let (r, s, name) = (args.r, args.s, &args.name);
    let dyn_name = format_ident!("{}Dyn", name);
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
        let system = quote!(#rt::second_order::SecondOrderSystem);
        let stepper = quote!(#rt::second_order::TcStepper);
        let fixed = newtype(
            args,
            rt,
            &Newtype {
                name: name.clone(),
                doc,
                dim: Some(format_ident!("N")),
                system: system.clone(),
                stepper: stepper.clone(),
                inner: quote!(#stepper<Sys, #kernel, #rt::stepper::StaticBuffers<N, #s, #r, 2>>),
                kernel: kernel.clone(),
            },
        );
        let dynamic = newtype(
            args,
            rt,
            &Newtype {
                name: dyn_name,
                doc: doc_dyn,
                dim: None,
                system,
                stepper: stepper.clone(),
                inner: quote!(#stepper<Sys, #kernel, #rt::stepper::VecBuffers>),
                kernel: kernel.clone(),
            },
        );
        return quote!(#fixed #dynamic);
    }
    let doc = format!(
        " ECrP of order {} (r = {r}, s = {s}) for a system of dimension `D` known at compile time: \
         stage state in fixed-size arrays, no heap use per step.",
        2 * r
    );
    let doc_dyn = format!(
        " ECrP of order {} (r = {r}, s = {s}) for a dimension known at run time: stage state \
         allocated once at construction.",
        2 * r
    );
    let system = quote!(#rt::system::System);
    let stepper = quote!(#rt::stepper::Stepper);
    let fixed = newtype(
        args,
        rt,
        &Newtype {
            name: name.clone(),
            doc,
            dim: Some(format_ident!("D")),
            system: system.clone(),
            stepper: stepper.clone(),
            inner: quote!(#stepper<#kernel, Sys, #rt::stepper::StaticBuffers<D, #s, #r>>),
            kernel: kernel.clone(),
        },
    );
    let dynamic = newtype(
        args,
        rt,
        &Newtype {
            name: dyn_name,
            doc: doc_dyn,
            dim: None,
            system,
            stepper: stepper.clone(),
            inner: quote!(#stepper<#kernel, Sys, #rt::stepper::VecBuffers>),
            kernel: kernel.clone(),
        },
    );
    quote!(#fixed #dynamic)
}

/// One emitted stepper type.
struct Newtype {
    /// The type's name (`Ec3`, `Ec3Dyn`, `Tc2`, …).
    name: Ident,
    /// Its doc comment (first paragraph).
    doc: String,
    /// The const parameter of the dimension (`D`, or `N` positions), if the size is static.
    dim: Option<Ident>,
    /// The trait bound of `Sys`.
    system: TokenStream,
    /// The runtime stepper type without parameters (its associated functions `fixed` and
    /// `from_kernel` build the inner value).
    stepper: TokenStream,
    /// The wrapped runtime stepper type.
    inner: TokenStream,
    /// The kernel type.
    kernel: Ident,
}

/// A newtype around a runtime stepper: `fixed` and `with_settings` constructors, `Deref` and
/// `DerefMut` to the stepper (its methods, e.g. `step`, are called as before), conversions from
/// and into it, and `Integrator` (so that `integrate` drives it). `#[repr(transparent)]`, and
/// every method a forwarding call marked `#[inline]` (`deref_mut` `#[inline(always)]`): a
/// step is the runtime stepper's own `step`, the same monomorphised function as behind the
/// former type alias, bit for bit and at its cost.
fn newtype(args: &MethodArgs, rt: &TokenStream, t: &Newtype) -> TokenStream {
    let vis = &args.vis;
    let Newtype {
        name,
        doc,
        dim,
        system,
        stepper,
        inner,
        kernel,
    } = t;
    let (params, args_) = match dim {
        Some(d) => (quote!(<Sys: #system, const #d: usize>), quote!(<Sys, #d>)),
        None => (quote!(<Sys: #system>), quote!(<Sys>)),
    };
    let doc_more = format!(
        " A newtype around [`{}`]: it dereferences to it (`step`, `step_size`, `dense_output`, … \
         are the stepper's), converts from and into it, and implements \
         [`Integrator`]. Build it with [`fixed`](Self::fixed) or \
         [`with_settings`](Self::with_settings).",
        inner_name(args.family),
    );
    let doc_link = format!(
        " [`{}`]: {}\n [`Integrator`]: {}::integrate::Integrator",
        inner_name(args.family),
        inner_path(args.family, rt),
        rt
    );
    quote! {
        #[doc = #doc]
        ///
        #[doc = #doc_more]
        ///
        #[doc = #doc_link]
        #[repr(transparent)]
        #vis struct #name #params(#inner);

        impl #params #name #args_ {
            /// The stepper with step size `h` and the default solver settings.
            ///
            /// # Errors
            /// As the runtime stepper's `from_kernel`: bad `h`, a system whose dimension does
            /// not fit, or whatever building the φ-bank reports.
            #[inline]
            pub fn fixed(system: Sys, h: f64) -> #rt::Result<Self> {
                #stepper::fixed(system, h).map(Self)
            }

            /// The stepper with step size `h` and the given solver settings.
            ///
            /// # Errors
            /// As [`fixed`](Self::fixed), and bad settings.
            #[inline]
            pub fn with_settings(
                system: Sys,
                h: f64,
                settings: #rt::stepper::SolverSettings,
            ) -> #rt::Result<Self> {
                #stepper::from_kernel(#kernel, system, h, settings).map(Self)
            }

            /// The runtime stepper inside.
            #[inline]
            pub fn into_inner(self) -> #inner {
                self.0
            }
        }

        impl #params ::core::ops::Deref for #name #args_ {
            type Target = #inner;
            #[inline(always)]
            fn deref(&self) -> &Self::Target {
                &self.0
            }
        }

        impl #params ::core::ops::DerefMut for #name #args_ {
            #[inline(always)]
            fn deref_mut(&mut self) -> &mut Self::Target {
                &mut self.0
            }
        }

        impl #params ::core::convert::From<#inner> for #name #args_ {
            #[inline]
            fn from(stepper: #inner) -> Self {
                Self(stepper)
            }
        }

        impl #params #rt::integrate::Integrator for #name #args_ {
            #[inline]
            fn step_size(&self) -> f64 {
                #rt::integrate::Integrator::step_size(&self.0)
            }
            #[inline]
            fn set_step_size(&mut self, h: f64) -> #rt::Result<()> {
                #rt::integrate::Integrator::set_step_size(&mut self.0, h)
            }
            #[inline]
            fn step_state(&mut self, y: &mut [f64]) -> #rt::Result<#rt::stepper::StepReport> {
                #rt::integrate::Integrator::step_state(&mut self.0, y)
            }
            #[inline]
            fn energy_of(&self, y: &[f64]) -> ::core::option::Option<f64> {
                #rt::integrate::Integrator::energy_of(&self.0, y)
            }
        }
    }
}

/// The name of the runtime stepper a family's types wrap.
fn inner_name(family: Family) -> &'static str {
    match family {
        Family::Ec => "Stepper",
        Family::Tc | Family::Rknc => "TcStepper",
    }
}

/// The path of the runtime stepper a family's types wrap, for doc links.
fn inner_path(family: Family, rt: &TokenStream) -> String {
    let rt = rt.to_string().replace(' ', "");
    match family {
        Family::Ec => format!("{rt}::stepper::Stepper"),
        Family::Tc | Family::Rknc => format!("{rt}::second_order::TcStepper"),
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
        // Newtypes, not aliases: type errors name `Ec2`, not the runtime's `Stepper`.
        assert!(out.contains(
            "pub struct Ec2 < Sys : :: rt :: system :: System , const D : usize > (:: rt :: \
             stepper :: Stepper < Ec2Kernel , Sys , :: rt :: stepper :: StaticBuffers < D , \
             2usize , 2usize >>) ;"
        ));
        assert!(out.contains(
            "pub struct Ec2Dyn < Sys : :: rt :: system :: System > (:: rt :: stepper :: Stepper \
             < Ec2Kernel , Sys , :: rt :: stepper :: VecBuffers >) ;"
        ));
        assert!(!out.contains("type Ec2"));
        // Constructors, the way to the stepper, and the integrator.
        assert!(out.contains(
            "pub fn fixed (system : Sys , h : f64) -> :: rt :: Result < Self > { :: rt :: \
             stepper :: Stepper :: fixed (system , h) . map (Self) }"
        ));
        assert!(out.contains(":: rt :: stepper :: Stepper :: from_kernel (Ec2Kernel , system"));
        for ty in ["Ec2 < Sys , D >", "Ec2Dyn < Sys >"] {
            for tr in [
                ":: core :: ops :: Deref for",
                ":: core :: ops :: DerefMut for",
                ":: rt :: integrate :: Integrator for",
            ] {
                assert!(out.contains(&format!("{tr} {ty}")), "{tr} {ty}");
            }
        }
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
        assert!(out.contains("pub (crate) struct Foo < Sys"));
        assert!(out.contains("pub (crate) struct FooDyn < Sys"));
        assert!(out.contains("StaticBuffers < D , 5usize , 3usize >"));
        let args: MethodArgs = parse_quote!(r = 3, s = 5, runtime = ::rt);
        assert_eq!(args.name.to_string(), "Ec3S5");
        assert!(matches!(args.vis, syn::Visibility::Inherited));
    }

    #[test]
    fn second_order_families() {
        let out = expand_str(parse_quote!(r = 2, family = tc, runtime = ::rt));
        assert!(out.contains(
            "struct Tc2 < Sys : :: rt :: second_order :: SecondOrderSystem , const N : usize > \
             (:: rt :: second_order :: TcStepper < Sys , Tc2Kernel , :: rt :: stepper :: \
             StaticBuffers < N , 2usize , 2usize , 2 >>) ;"
        ));
        assert!(out.contains(
            "struct Tc2Dyn < Sys : :: rt :: second_order :: SecondOrderSystem > (:: rt :: \
             second_order :: TcStepper < Sys , Tc2Kernel , :: rt :: stepper :: VecBuffers >) ;"
        ));
        assert!(out.contains(":: rt :: second_order :: TcStepper :: fixed (system , h)"));
        assert!(out.contains(":: rt :: integrate :: Integrator for Tc2 < Sys , N >"));
        let out = expand_str(parse_quote!(r = 2, family = rknc, runtime = ::rt));
        assert!(out.contains(
            "struct Rknc2 < Sys : :: rt :: second_order :: SecondOrderSystem , const N : usize >"
        ));
        assert!(out.contains("struct Rknc2Dyn < Sys"));
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
