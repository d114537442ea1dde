//! Arguments of `ecr_method!`: `[vis,] key = value, …`.

use proc_macro2::Span;
use syn::parse::{Parse, ParseStream};
use syn::{Ident, LitInt, Path, Token, Visibility};

/// Method family requested with `family = …`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Family {
    /// ECrP (first-order systems).
    Ec,
    /// TCrP (q'' + Ωq = −∇U).
    Tc,
    /// RKNCrP (Ω = 0).
    Rknc,
}

/// Parsed and validated arguments.
pub struct MethodArgs {
    /// Visibility of every emitted item.
    pub vis: Visibility,
    /// r, with the span of its literal.
    pub r: usize,
    /// s (defaults to r).
    pub s: usize,
    /// Name of the stepper type alias.
    pub name: Ident,
    /// Family.
    pub family: Family,
    /// Path of the runtime crate, if given.
    pub runtime: Option<Path>,
}

/// The value of an integer literal for `key`, whose supported maximum is `max`. (syn reads
/// `-1` as one negative literal, refused here as negative; otherwise `base10_parse` fails only
/// when the number does not fit a usize.)
fn parse_usize(lit: &LitInt, key: &str, max: usize) -> syn::Result<usize> {
    if !lit.suffix().is_empty() && lit.suffix() != "usize" {
        return Err(syn::Error::new(
            lit.span(),
            format!("`{key}` takes an unsuffixed integer"),
        ));
    }
    if lit.base10_digits().starts_with('-') {
        let least = if key == "r" { "1" } else { "r" };
        return Err(syn::Error::new(
            lit.span(),
            format!(
                "{key} = {} is negative: {key} must be an integer from {least} to {max}",
                lit.base10_digits()
            ),
        ));
    }
    lit.base10_parse::<usize>().map_err(|_| {
        syn::Error::new(
            lit.span(),
            format!(
                "{key} = {} is too large: the supported maximum is {max}",
                lit.base10_digits()
            ),
        )
    })
}

/// The identifier value of `key`, or an error on the token that stands there instead (consumed,
/// so that the remaining keys still parse) saying what `key` expects.
fn value_ident(input: ParseStream, key: &Ident, expects: &str) -> syn::Result<Ident> {
    if input.peek(Ident) {
        input.parse()
    } else {
        let tt: proc_macro2::TokenTree = input.parse()?;
        Err(syn::Error::new(
            tt.span(),
            format!("`{key}` expects {expects}, found `{tt}`"),
        ))
    }
}

fn value_int(input: ParseStream, key: &Ident) -> syn::Result<LitInt> {
    if input.peek(LitInt) {
        input.parse()
    } else {
        // Consume whatever stands there so that the remaining keys still parse.
        let tt: proc_macro2::TokenTree = input.parse()?;
        Err(syn::Error::new(
            tt.span(),
            format!("`{key}` must be an integer literal, e.g. `{key} = 3`"),
        ))
    }
}

impl Parse for MethodArgs {
    fn parse(input: ParseStream) -> syn::Result<Self> {
        let call_site = Span::call_site();
        let vis: Visibility = input.parse()?;
        if !matches!(vis, Visibility::Inherited) && input.peek(Token![,]) {
            input.parse::<Token![,]>()?;
        }
        let mut errors: Option<syn::Error> = None;
        let mut push = |e: syn::Error| match &mut errors {
            Some(all) => all.combine(e),
            None => errors = Some(e),
        };
        let mut r: Option<(usize, Span)> = None;
        let mut s: Option<(usize, Span)> = None;
        let mut name: Option<Ident> = None;
        let mut family: Option<Family> = None;
        let mut runtime: Option<Path> = None;
        let mut seen: Vec<String> = Vec::new();
        while !input.is_empty() {
            let key: Ident = input.parse()?;
            input.parse::<Token![=]>()?;
            let k = key.to_string();
            if seen.contains(&k) {
                push(syn::Error::new(key.span(), format!("duplicate key `{k}`")));
            }
            seen.push(k.clone());
            match k.as_str() {
                "r" | "s" => match value_int(input, &key).and_then(|lit| {
                    let max = if k == "r" {
                        ecr_codegen::MAX_R
                    } else {
                        ecr_codegen::MAX_S
                    };
                    Ok((parse_usize(&lit, &k, max)?, lit.span()))
                }) {
                    Ok(v) if k == "r" => r = Some(v),
                    Ok(v) => s = Some(v),
                    Err(e) => push(e),
                },
                "name" => match value_ident(
                    input,
                    &key,
                    "an identifier (the name of the stepper type, e.g. `name = MyStepper`)",
                ) {
                    Ok(n) => name = Some(n),
                    Err(e) => push(e),
                },
                "family" => {
                    let f = match value_ident(input, &key, "one of `ec`, `tc` or `rknc`") {
                        Ok(f) => f,
                        Err(e) => {
                            push(e);
                            if !input.is_empty() {
                                input.parse::<Token![,]>()?;
                            }
                            continue;
                        }
                    };
                    match f.to_string().as_str() {
                        "ec" => family = Some(Family::Ec),
                        "tc" => family = Some(Family::Tc),
                        "rknc" => family = Some(Family::Rknc),
                        other => push(syn::Error::new(
                            f.span(),
                            format!("unknown family `{other}`: expected `ec`, `tc` or `rknc`"),
                        )),
                    }
                }
                "runtime" => runtime = Some(input.parse()?),
                other => {
                    // Skip the value so that later keys are still checked.
                    let _: proc_macro2::TokenTree = input.parse()?;
                    push(syn::Error::new(
                        key.span(),
                        format!(
                            "unknown key `{other}`: expected one of r, s, name, family, runtime"
                        ),
                    ))
                }
            }
            if !input.is_empty() {
                input.parse::<Token![,]>()?;
            }
        }
        let r_checked = match r {
            // Given but invalid: that error is already reported.
            None if seen.iter().any(|k| k == "r") => None,
            None => {
                push(syn::Error::new(
                    call_site,
                    "missing `r = …`: the order parameter (order 2r)",
                ));
                None
            }
            Some((0, span)) => {
                push(syn::Error::new(span, "r must be at least 1"));
                None
            }
            Some((v, span)) if v > ecr_codegen::MAX_R => {
                push(syn::Error::new(
                    span,
                    format!(
                        "r = {v} is above the supported maximum {}",
                        ecr_codegen::MAX_R
                    ),
                ));
                None
            }
            Some((v, _)) => Some(v),
        };
        let s_checked = match (s, r_checked) {
            (Some((sv, span)), Some(rv)) if sv < rv => {
                push(syn::Error::new(
                    span,
                    format!("s = {sv} is below r = {rv}: the method needs s >= r points"),
                ));
                None
            }
            (Some((sv, span)), _) if sv > ecr_codegen::MAX_S => {
                push(syn::Error::new(
                    span,
                    format!(
                        "s = {sv} is above the supported maximum {}",
                        ecr_codegen::MAX_S
                    ),
                ));
                None
            }
            (Some((sv, _)), _) => Some(sv),
            (None, rv) => rv,
        };
        if let Some(e) = errors {
            return Err(e);
        }
        let (r, s) = (r_checked.expect("checked"), s_checked.expect("checked"));
        let family = family.unwrap_or(Family::Ec);
        let name = name.unwrap_or_else(|| {
            let prefix = match family {
                Family::Ec => "Ec",
                Family::Tc => "Tc",
                Family::Rknc => "Rknc",
            };
            let n = if s == r {
                format!("{prefix}{r}")
            } else {
                format!("{prefix}{r}S{s}")
            };
            Ident::new(&n, call_site)
        });
        Ok(MethodArgs {
            vis,
            r,
            s,
            name,
            family,
            runtime,
        })
    }
}
