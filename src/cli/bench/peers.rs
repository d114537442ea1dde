//! The strong peers in the benchmark: what users of each problem class pick instead of an
//! exponential collocation method, each built the way its own users build it (set-up in the
//! constructor, counted in the timings).
//!
//! - Duffing (q'' + (ω² + k²)q = 2k²q³): splitting with the exact linear flow (kick–rotate–kick)
//!   composed to orders 2, 4, 6, 8, with the rotation from the operator's φ-bank
//!   ("Split{p} rot"), written out with cos/sin of the scalar frequency ("Rot{p}", the
//!   library's `RotationSplitting` stepped by `integrate`), and the same method written in C
//!   for speed and called once over [0, T] ("Rot{p} C", and "Rot{p} C plain" with the plain
//!   2 × 2 rotation: [`super::c_peer`]); Störmer–Verlet composed to the same orders; ETDRK4.
//! - Wind: ETDRK4 (its g changes both components, so g's flow is not explicit and the
//!   splittings do not apply).
//! - NLS: split-step Fourier of orders 2, 4, 6, 8 (the exact linear flow by FFT, the nonlinear
//!   substep exact); ETDRK4 with the FFT operator.
//!
//! DOP853 (one call over [0, T]) is added to every problem by the sweep.

use super::c_peer::{Form, RotationC};
use super::series::{BoxedRun, Family, K, Knob, OMEGA, Series, static_system, step_series};
use crate::cli::reproduce::methods::boxed;
use ecr::baselines::etdrk4::Etdrk4;
use ecr::baselines::split_step::SplitStep;
use ecr::baselines::splitting::{LinearFlowSplitting, RotationSplitting, StormerVerlet};
use ecr::problems::{Duffing, Nls, Wind};
use ecr_runtime::second_order::{Omega, SecondOrder};

/// The group (figure panel) of the peers.
pub const GROUP: &str = "peers";

fn composition_name(order: usize) -> &'static str {
    match order {
        2 => "Strang",
        4 => "Yoshida",
        _ => "Kahan–Li",
    }
}

/// Duffing in second-order form: q'' + (ω² + k²) q = 2k²q³, i.e. ∇U = −2k²q³, U = −k²q⁴/2.
/// TCrP's system in the benchmark too.
#[allow(clippy::type_complexity)] // the closures' types are unnameable: impl Trait is the point
pub fn second_order()
-> ecr_runtime::Result<SecondOrder<impl Fn(&[f64], &mut [f64]), impl Fn(&[f64]) -> f64>> {
    let k2 = K * K;
    Ok(SecondOrder::with_potential(
        Omega::scalar(OMEGA * OMEGA + k2, 1)?,
        move |q: &[f64], f: &mut [f64]| f[0] = -2.0 * k2 * q[0].powi(3),
        move |q: &[f64]| -0.5 * k2 * q[0].powi(4),
    ))
}

/// Duffing: rotation splittings and Störmer–Verlet of orders 2, 4, 6, 8, ETDRK4.
pub fn duffing(d: &Duffing, h0: f64) -> Vec<Series> {
    let mut v = Vec::new();
    // The first-order form as a user with a 2 × 2 linear part writes it: A a static matrix
    // (its rotations e^{γhA} are static 2 × 2 products), g a closure.
    let a = d.linear_matrix();
    let g = {
        let d = d.clone();
        move |y: &[f64], o: &mut [f64]| d.nonlinear(y, o)
    };
    for order in [2, 4, 6, 8] {
        let (a, g) = (a.clone(), g.clone());
        v.push(step_series(
            &format!("Split{order} rot ({})", composition_name(order)),
            GROUP,
            h0,
            move |h| {
                boxed(LinearFlowSplitting::new(
                    static_system(&a, g.clone())?,
                    order,
                    h,
                ))
            },
        ));
    }
    for order in [2, 4, 6, 8] {
        v.push(step_series(
            &format!("Rot{order} ({})", composition_name(order)),
            GROUP,
            h0,
            move |h| boxed(RotationSplitting::new(second_order()?, order, h)),
        ));
    }
    let (omega, k) = (d.omega(), d.k());
    for (form, suffix) in [(Form::Accurate, "C"), (Form::Plain, "C plain")] {
        for order in [2, 4, 6, 8] {
            v.push(Series {
                label: format!("Rot{order} {suffix} ({})", composition_name(order)),
                group: GROUP,
                family: Family::Peer,
                r: None,
                s: None,
                knob: Knob::Step { h0 },
                build: Box::new(move |h| {
                    Ok(Box::new(RotationC::new(omega, k, order, h, form)?) as BoxedRun)
                }),
                g_cost: None,
            });
        }
    }
    for order in [2, 4, 6, 8] {
        v.push(step_series(
            &format!("SV{order} ({})", composition_name(order)),
            GROUP,
            h0,
            move |h| boxed(StormerVerlet::new(second_order()?, order, h)),
        ));
    }
    v.push(step_series("ETDRK4", GROUP, h0, move |h| {
        boxed(Etdrk4::new(static_system(&a, g.clone())?, h))
    }));
    v
}

/// The wind problem: ETDRK4 (A static 2 × 2, g a closure).
pub fn wind(w: &Wind, h0: f64) -> Vec<Series> {
    let (a, w) = (w.linear_matrix(), *w);
    vec![step_series("ETDRK4", GROUP, h0, move |h| {
        let g = move |y: &[f64], o: &mut [f64]| w.nonlinear(y, o);
        boxed(Etdrk4::new(static_system(&a, g)?, h))
    })]
}

/// The NLS: split-step Fourier of orders 2, 4, 6, 8 and ETDRK4, all with the FFT operator.
pub fn nls(n: &Nls, h0: f64) -> Vec<Series> {
    let mut v = Vec::new();
    for (order, name) in [
        (2, "Strang"),
        (4, "Blanes–Moan"),
        (6, "Kahan–Li"),
        (8, "Kahan–Li"),
    ] {
        let p = n.clone();
        v.push(step_series(
            &format!("SSF{order} ({name})"),
            GROUP,
            h0,
            move |h| boxed(SplitStep::nls(p.system()?, order, h)),
        ));
    }
    let p = n.clone();
    v.push(step_series("ETDRK4", GROUP, h0, move |h| {
        boxed(Etdrk4::new(p.system()?, h))
    }));
    v
}
