//! The collocation-type baselines: measured orders and the energy behaviour theory predicts.

use crate::common_ec;

use common_ec::{fitted_order, max_abs_diff};
use ecr::baselines::collocation::{ExpAvf, avf, gauss_collocation, hbvm, rkepc2};
use ecr::problems::Duffing;
use ecr_runtime::Error;
use ecr_runtime::integrate::{IntegrateOptions, Integrator, integrate};
use ecr_runtime::stepper::SolverSettings;
use ecr_runtime::tables::QuadratureKind;

/// Order: slope over the 8 finest h = T/N above the 30·N·ε floor, Duffing ω = 1, k = 0.5, T = 10.
fn order_of<I: Integrator>(make: impl Fn(f64) -> I, n0: usize) -> (f64, usize) {
    let p = Duffing::new(1.0, 0.5).unwrap();
    let t_end = 10.0;
    let exact = p.exact(t_end).unwrap();
    let mut pts = Vec::new();
    let mut last = 0;
    for i in 0..40 {
        let n = (n0 as f64 * 2f64.powf(i as f64 / 8.0)).round() as usize;
        if n == last {
            continue;
        }
        last = n;
        let mut st = make(t_end / n as f64);
        let mut y = p.initial_value();
        let opts = IntegrateOptions {
            energy_every: 0,
            observe_every: 0,
        };
        integrate(&mut st, 0.0, t_end, &mut y, opts, |_, _, _| {}).unwrap();
        let e = max_abs_diff(&y, &exact);
        if e > 30.0 * n as f64 * f64::EPSILON && e < 1e-3 {
            pts.push((t_end / n as f64, e));
        }
    }
    let tail = &pts[pts.len().saturating_sub(8)..];
    let (hs, es): (Vec<f64>, Vec<f64>) = tail.iter().copied().unzip();
    fitted_order(&hs, &es, 0.0, f64::INFINITY)
}

fn sys() -> impl ecr_runtime::system::System<Op = ecr_runtime::operator::Dense> {
    Duffing::new(1.0, 0.5).unwrap().system().unwrap()
}

#[test]
fn measured_orders() {
    let s = SolverSettings::default();
    let cases: Vec<(&str, f64, (f64, usize))> = vec![
        (
            "RKEPC2 = HBVM(5,2) Lobatto",
            4.0,
            order_of(|h| rkepc2(sys(), h, s).unwrap(), 40),
        ),
        (
            "HBVM(4,3) Gauss",
            6.0,
            order_of(
                |h| hbvm(sys(), 4, 3, QuadratureKind::GaussLegendre, h, s).unwrap(),
                20,
            ),
        ),
        (
            "Gauss collocation r = 1",
            2.0,
            order_of(|h| gauss_collocation(sys(), 1, h, s).unwrap(), 200),
        ),
        (
            "Gauss collocation r = 2",
            4.0,
            order_of(|h| gauss_collocation(sys(), 2, h, s).unwrap(), 40),
        ),
        (
            "Gauss collocation r = 3",
            6.0,
            order_of(|h| gauss_collocation(sys(), 3, h, s).unwrap(), 20),
        ),
        (
            "AVF (k = 3)",
            2.0,
            order_of(|h| avf(sys(), 3, h, s).unwrap(), 200),
        ),
        (
            "exponential AVF (k = 3)",
            2.0,
            order_of(|h| ExpAvf::new(sys(), 3, h, s).unwrap(), 200),
        ),
    ];
    for (name, expected, (o, n)) in cases {
        println!("{name}: order {o:.3} ({n} points)");
        assert!(n >= 4 && (o - expected).abs() <= 0.15, "{name}: {o}");
    }
}

#[test]
fn energy_preserving_baselines_conserve_the_quartic_duffing_energy() {
    // H is quartic (ν = 4): RKEPC2 (5 Lobatto points, exact to degree 7 ≥ νs − 1 = 7), AVF with
    // k ≥ 2 and the exponential AVF (Q skew) conserve it to round-off; Gauss collocation does not.
    let p = Duffing::default();
    let s = SolverSettings::default();
    let run = |st: &mut dyn FnMut(&mut [f64])| {
        let mut y = p.initial_value();
        let h0 = p.energy(&y);
        let mut max = 0.0f64;
        for _ in 0..2000 {
            st(&mut y);
            max = max.max((p.energy(&y) - h0).abs() / h0);
        }
        max
    };
    let mut a = rkepc2(p.system().unwrap(), 0.05, s).unwrap();
    let e_rkepc = run(&mut |y| {
        a.step(y).unwrap();
    });
    let mut b = avf(p.system().unwrap(), 2, 0.05, s).unwrap();
    let e_avf = run(&mut |y| {
        b.step(y).unwrap();
    });
    let mut c = ExpAvf::new(p.system().unwrap(), 2, 0.05, s).unwrap();
    let e_eavf = run(&mut |y| {
        c.step(y).unwrap();
    });
    let mut g = gauss_collocation(p.system().unwrap(), 2, 0.05, s).unwrap();
    let e_gauss = run(&mut |y| {
        g.step(y).unwrap();
    });
    println!(
        "max |ΔH|/H over 2000 steps, h = 0.05: RKEPC2 {e_rkepc:.2e}, AVF {e_avf:.2e}, EAVF {e_eavf:.2e}, Gauss(2) {e_gauss:.2e}"
    );
    // Round-off: a few ulp per step over 2000 steps.
    for (name, e) in [("RKEPC2", e_rkepc), ("AVF", e_avf), ("EAVF", e_eavf)] {
        assert!(e <= 1e-13, "{name}: {e:e}");
    }
    assert!(
        e_gauss > 1e-10,
        "Gauss collocation is not energy-preserving: {e_gauss:e}"
    );
}

#[test]
fn bad_input() {
    let s = SolverSettings::default();
    assert!(matches!(
        hbvm(sys(), 1, 2, QuadratureKind::GaussLegendre, 0.1, s),
        Err(Error::InvalidParameter(_))
    ));
    assert!(matches!(
        hbvm(sys(), 1, 1, QuadratureKind::GaussLobatto, 0.1, s),
        Err(Error::InvalidParameter(_))
    ));
    assert!(matches!(
        ExpAvf::new(sys(), 0, 0.1, s),
        Err(Error::InvalidParameter(_))
    ));
    assert!(matches!(
        ExpAvf::new(sys(), 2, -0.1, s),
        Err(Error::InvalidStepSize(_))
    ));
    let mut e = ExpAvf::new(sys(), 2, 0.1, s).unwrap();
    assert!(matches!(
        e.step(&mut [f64::NAN, 0.0]),
        Err(Error::NonFinite(_))
    ));
    assert!(matches!(
        e.step(&mut [0.0]),
        Err(Error::DimensionMismatch { .. })
    ));
}
