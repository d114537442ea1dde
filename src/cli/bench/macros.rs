//! The fixed-order steppers of `ecr_method!` in the benchmark: ECrP r = 1..6 (s = r) as a user
//! writes them in a hot loop — `Ec{r}<_, 2>` with the linear part a `DenseStatic` 2 × 2 and g a
//! closure (Duffing, wind), `Ec{r}Dyn<_>` with the NLS's FFT operator — with the benchmark's
//! stage solver. Bit-identical to the run-time stepper's steps (tests/it/macro_stepper.rs), so
//! the two series differ only in time.

use super::series::{
    BuildFn, Family, GCostFn, Knob, Series, solver, static_system, stepped, time_g,
};
use crate::cli::reproduce::methods::boxed;
use ecr::problems::{Duffing, Nls, Wind};
use ecr_runtime::ecr_method;
use ecr_runtime::nalgebra::DMatrix;

ecr_method!(r = 1);
ecr_method!(r = 2);
ecr_method!(r = 3);
ecr_method!(r = 4);
ecr_method!(r = 5);
ecr_method!(r = 6);

fn series(r: usize, h0: f64, group: &'static str, build: BuildFn, g_cost: GCostFn) -> Series {
    Series {
        label: format!("EC{r}P macro"),
        group,
        family: Family::Macro,
        r: Some(r),
        s: Some(r),
        knob: Knob::Step { h0 },
        build,
        g_cost: Some(g_cost),
    }
}

/// `Ec{r}<Semilinear<DenseStatic<2>, G>, 2>` for r = 1..6, g = `$g` (a closure).
macro_rules! static_series {
    ($a:expr, $g:expr, $h0:expr, $group:expr) => {{
        let a: DMatrix<f64> = $a;
        let g = $g;
        let mut v = Vec::new();
        macro_rules! one {
            ($r:literal, $ty:ident) => {{
                let (a, g) = (a.clone(), g.clone());
                let (a2, g2) = (a.clone(), g.clone());
                v.push(series(
                    $r,
                    $h0,
                    $group,
                    Box::new(move |h| {
                        let sys = static_system(&a, g.clone())?;
                        let st: $ty<_, 2> = $ty::with_settings(sys, h, solver())?;
                        stepped(boxed(Ok(st)))
                    }),
                    Box::new(move |states, n, repeats| {
                        let sys = static_system(&a2, g2.clone())?;
                        Ok(time_g(&sys, states, n, repeats))
                    }),
                ));
            }};
        }
        one!(1, Ec1);
        one!(2, Ec2);
        one!(3, Ec3);
        one!(4, Ec4);
        one!(5, Ec5);
        one!(6, Ec6);
        v
    }};
}

/// Duffing: the macro steppers r = 1..6.
pub fn duffing_series(d: &Duffing, h0: f64) -> Vec<Series> {
    let p = d.clone();
    static_series!(
        d.linear_matrix(),
        move |y: &[f64], o: &mut [f64]| p.nonlinear(y, o),
        h0,
        "ECrP macro"
    )
}

/// The conservative wind problem: the macro steppers r = 1..6.
pub fn wind_series(w: &Wind, h0: f64) -> Vec<Series> {
    let p = *w;
    static_series!(
        w.linear_matrix(),
        move |y: &[f64], o: &mut [f64]| p.nonlinear(y, o),
        h0,
        "ECrP macro"
    )
}

/// The NLS with the FFT operator: `Ec{r}Dyn<NlsSystem>` for r = 1..6.
pub fn nls_series(n: &Nls, h0: f64) -> Vec<Series> {
    let mut v = Vec::new();
    macro_rules! one {
        ($r:literal, $ty:ident) => {{
            let (n, m) = (n.clone(), n.clone());
            v.push(series(
                $r,
                h0,
                "ECrP circulant",
                Box::new(move |h| {
                    let st: $ty<_> = $ty::with_settings(n.system()?, h, solver())?;
                    stepped(boxed(Ok(st)))
                }),
                Box::new(move |states, count, repeats| {
                    Ok(time_g(&m.system()?, states, count, repeats))
                }),
            ));
        }};
    }
    one!(1, Ec1Dyn);
    one!(2, Ec2Dyn);
    one!(3, Ec3Dyn);
    one!(4, Ec4Dyn);
    one!(5, Ec5Dyn);
    one!(6, Ec6Dyn);
    v
}
