//! TCrP / RKNCrP (second-order systems): agreement with ECrP on the first-order form,
//! measured orders, bad Ω.

use crate::common_ec;

use common_ec::{fitted_order, max_abs_diff};
use ecr::problems::Duffing;
use ecr_runtime::Error;
use ecr_runtime::operator::Dense;
use ecr_runtime::second_order::{Omega, SecondOrder, SecondOrderSystem, TcStepper};
use ecr_runtime::stepper::{EcStepper, SolverSettings};
use ecr_runtime::system::Semilinear;
use nalgebra::DMatrix;

/// A coupled test system: Ω dense SPD (3 × 3), U = Σ qᵢ⁴/4 + q₀q₁q₂.
fn coupled_omega() -> DMatrix<f64> {
    DMatrix::from_row_slice(3, 3, &[30.0, 4.0, 1.0, 4.0, 20.0, -2.0, 1.0, -2.0, 5.0])
}

fn coupled_force(q: &[f64], f: &mut [f64]) {
    f[0] = q[0].powi(3) + q[1] * q[2];
    f[1] = q[1].powi(3) + q[0] * q[2];
    f[2] = q[2].powi(3) + q[0] * q[1];
}

/// The first-order form y = (q, p): A = [[0, I], [−Ω, 0]], g = (0, −f(q)).
fn first_order(
    omega: &DMatrix<f64>,
    f: fn(&[f64], &mut [f64]),
) -> Semilinear<Dense, impl Fn(&[f64], &mut [f64])> {
    let d = omega.nrows();
    let mut a = DMatrix::zeros(2 * d, 2 * d);
    a.view_mut((0, d), (d, d))
        .copy_from(&DMatrix::<f64>::identity(d, d));
    a.view_mut((d, 0), (d, d)).copy_from(&(-omega));
    Semilinear::new(Dense::new(a).unwrap(), move |y: &[f64], o: &mut [f64]| {
        o[..d].fill(0.0);
        f(&y[..d], &mut o[d..]);
        o[d..].iter_mut().for_each(|x| *x = -*x);
    })
}

#[allow(clippy::too_many_arguments)] // a test helper spelling out one comparison
fn compare_with_ec(
    omega_m: DMatrix<f64>,
    omega: Omega,
    f: fn(&[f64], &mut [f64]),
    q0: &[f64],
    p0: &[f64],
    r: usize,
    s: usize,
    h: f64,
) {
    let d = q0.len();
    let settings = SolverSettings::default();
    let mut tc = TcStepper::with_nodes(SecondOrder::new(omega, f), r, s, h, settings).unwrap();
    let mut ec = EcStepper::with_nodes(first_order(&omega_m, f), r, s, h, settings).unwrap();
    let (mut q, mut p) = (q0.to_vec(), p0.to_vec());
    let mut y: Vec<f64> = q0.iter().chain(p0).copied().collect();
    for n in 1..=1000 {
        tc.step(&mut q, &mut p).unwrap();
        ec.step(&mut y).unwrap();
        if n == 1 || n == 1000 {
            let qp: Vec<f64> = q.iter().chain(&p).copied().collect();
            let scale = y.iter().fold(1.0f64, |m, x| m.max(x.abs()));
            let rel = max_abs_diff(&qp, &y) / scale;
            println!("TC vs EC, d = {d}, r = {r}, s = {s}, step {n}: {rel:.2e}");
            // 1e-13: two algebraically equal evaluations (modal trigonometric φ vs dense φ of the
            // 2d × 2d matrix), each rounding a few ulp per step.
            assert!(rel <= 1e-13, "r = {r}, s = {s}, step {n}: {rel:e}");
        }
    }
}

#[test]
fn tc_equals_ec_on_the_first_order_form() {
    fn duffing_f(q: &[f64], f: &mut [f64]) {
        f[0] = -2.0 * 0.07 * 0.07 * q[0].powi(3);
    }
    let w2 = 25.0 + 0.07 * 0.07;
    for (r, s) in [(1, 1), (2, 2), (3, 3), (2, 4), (4, 4)] {
        compare_with_ec(
            DMatrix::from_element(1, 1, w2),
            Omega::scalar(w2, 1).unwrap(),
            duffing_f,
            &[0.0],
            &[5.0],
            r,
            s,
            0.01,
        );
        let om = coupled_omega();
        compare_with_ec(
            om.clone(),
            Omega::dense(om).unwrap(),
            coupled_force,
            &[0.3, -0.2, 0.5],
            &[0.1, 0.4, -0.3],
            r,
            s,
            0.01,
        );
    }
    // RKNC: Ω = 0.
    compare_with_ec(
        DMatrix::zeros(3, 3),
        Omega::zero(3),
        coupled_force,
        &[0.3, -0.2, 0.5],
        &[0.1, 0.4, -0.3],
        3,
        3,
        0.01,
    );
}

#[test]
fn measured_order_is_2r_on_second_order_duffing() {
    // q'' + (ω² + k²) q = 2k² q³, ω = 1, k = 0.5 (as in the first-order order test), T = 10.
    let p = Duffing::new(1.0, 0.5).unwrap();
    let (w2, k2) = (1.0 + 0.25, 0.25);
    let sys = SecondOrder::new(
        Omega::scalar(w2, 1).unwrap(),
        move |q: &[f64], f: &mut [f64]| f[0] = -2.0 * k2 * q[0].powi(3),
    );
    let t_end = 10.0;
    let exact = p.exact(t_end).unwrap();
    for (r, h_max, within) in [
        (1, 0.01, true),
        (2, 0.25, true),
        (3, 0.5, true),
        (4, 0.5, true),
        (5, 1.0, false),
    ] {
        let mut pts = Vec::new();
        let mut last = 0;
        for i in 0..40 {
            let n = ((t_end / h_max) * 2f64.powf(i as f64 / 8.0)).round() as usize;
            if n == last {
                continue;
            }
            last = n;
            let h = t_end / n as f64;
            let mut st = TcStepper::new(&sys, r, h).unwrap();
            let (mut q, mut v) = (vec![0.0], vec![1.0]);
            for _ in 0..n {
                st.step(&mut q, &mut v).unwrap();
            }
            let e = (q[0] - exact[0]).abs().max((v[0] - exact[1]).abs());
            if e > 30.0 * n as f64 * f64::EPSILON {
                pts.push((h, e));
            }
        }
        let tail = &pts[pts.len().saturating_sub(8)..];
        let (hs, es): (Vec<f64>, Vec<f64>) = tail.iter().copied().unzip();
        let (o, n) = fitted_order(&hs, &es, 0.0, f64::INFINITY);
        println!("TC Duffing r = {r}: order {o:.3} from {n} points");
        assert!(n >= 4);
        if within {
            assert!((o - 2.0 * r as f64).abs() <= 0.15, "r = {r}: {o}");
        } else {
            assert!(o >= 2.0 * r as f64 - 0.15, "r = {r}: {o}");
        }
    }
}

#[test]
fn bad_omega_is_an_error() {
    assert!(matches!(
        Omega::dense(DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 0.0, 1.0])),
        Err(Error::InvalidInput(_))
    ));
    assert!(matches!(
        Omega::dense(DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0])),
        Err(Error::InvalidInput(_))
    ));
    assert!(matches!(
        Omega::dense(DMatrix::zeros(2, 3)),
        Err(Error::NotSquare { .. })
    ));
    assert!(matches!(
        Omega::diagonal(vec![1.0, -1.0]),
        Err(Error::InvalidInput(_))
    ));
    assert!(matches!(
        Omega::scalar(f64::NAN, 2),
        Err(Error::InvalidInput(_))
    ));
    let sys = SecondOrder::new(Omega::zero(2), |_: &[f64], f: &mut [f64]| f.fill(0.0));
    let mut st = TcStepper::new(&sys, 2, 0.1).unwrap();
    assert!(matches!(
        st.step(&mut [0.0; 3], &mut [0.0; 2]),
        Err(Error::DimensionMismatch { .. })
    ));
    assert!(matches!(
        st.step(&mut [0.0, f64::NAN], &mut [0.0; 2]),
        Err(Error::NonFinite(_))
    ));
    assert!(matches!(
        TcStepper::new(&sys, 2, -1.0),
        Err(Error::InvalidStepSize(_))
    ));
    // Semidefinite with round-off: accepted, eigenvalues clamped at 0.
    let om = Omega::dense(DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0])).unwrap();
    assert!(om.eigenvalues().iter().all(|&l| l >= 0.0));
    let _ = sys.energy(&[0.0, 0.0], &[0.0, 0.0]);
}

mod fixed {
    use ecr_runtime::ecr_method;
    ecr_method!(pub r = 3, family = tc);
    ecr_method!(pub r = 2, s = 4, family = rknc);
    ecr_method!(pub r = 5, s = 7, family = tc, name = Tc5Wide);
}

#[test]
fn macro_tc_and_rknc_steppers_equal_the_run_time_stepper() {
    let om = coupled_omega();
    let cases: Vec<(Omega, usize, usize)> = vec![
        (Omega::dense(om.clone()).unwrap(), 3, 3),
        (Omega::zero(3), 2, 4),
        (Omega::diagonal(vec![4.0, 9.0, 100.0]).unwrap(), 5, 7),
    ];
    for (omega, r, s) in cases {
        let sys = SecondOrder::new(omega, coupled_force);
        let h = 0.02;
        macro_rules! run {
            ($ty:ty) => {{
                let mut rt =
                    TcStepper::with_nodes(&sys, r, s, h, SolverSettings::default()).unwrap();
                let (mut q1, mut p1) = (vec![0.3, -0.2, 0.5], vec![0.1, 0.4, -0.3]);
                let (mut q2, mut p2) = (q1.clone(), p1.clone());
                let mut st: $ty = <$ty>::fixed(&sys, h).unwrap();
                for n in 0..300 {
                    st.step(&mut q1, &mut p1).unwrap();
                    rt.step(&mut q2, &mut p2).unwrap();
                    assert_eq!(q1, q2, "r = {r}, s = {s}, step {n}");
                    assert_eq!(p1, p2, "r = {r}, s = {s}, step {n}");
                }
            }};
        }
        // Fixed-size (N = 3 positions) and run-time-size storage.
        match (r, s) {
            (3, 3) => {
                run!(fixed::Tc3<_, 3>);
                run!(fixed::Tc3Dyn<_>);
            }
            (2, 4) => {
                run!(fixed::Rknc2S4<_, 3>);
                run!(fixed::Rknc2S4Dyn<_>);
            }
            _ => {
                run!(fixed::Tc5Wide<_, 3>);
                run!(fixed::Tc5WideDyn<_>);
            }
        }
    }
}

#[test]
fn damped_form_dissipates_and_n_zero_conserves() {
    use ecr_runtime::second_order::damped_first_order;
    use ecr_runtime::system::System;
    let om = coupled_omega();
    let u = |q: &[f64]| q.iter().map(|x| x.powi(4) / 4.0).sum::<f64>() + q[0] * q[1] * q[2];
    let y0 = [0.3, -0.2, 0.5, 0.1, 0.4, -0.3];
    // N = −0.1 I: H strictly decreases.
    let n = DMatrix::<f64>::identity(3, 3) * -0.1;
    let sys = damped_first_order(om.clone(), n, coupled_force, u).unwrap();
    let mut st = EcStepper::new(&sys, 2, 0.01).unwrap();
    let mut y = y0.to_vec();
    let mut e = sys.energy(&y).unwrap();
    for _ in 0..2000 {
        st.step(&mut y).unwrap();
        let en = sys.energy(&y).unwrap();
        assert!(en < e, "H rose: {e} -> {en}");
        e = en;
    }
    // N = 0: conservative, and the same steps as TCrP.
    let sys = damped_first_order(om.clone(), DMatrix::zeros(3, 3), coupled_force, u).unwrap();
    let mut st = EcStepper::new(&sys, 2, 0.01).unwrap();
    let mut tc = TcStepper::new(
        SecondOrder::new(Omega::dense(om.clone()).unwrap(), coupled_force),
        2,
        0.01,
    )
    .unwrap();
    let (mut y, mut q, mut p) = (y0.to_vec(), y0[..3].to_vec(), y0[3..].to_vec());
    for _ in 0..100 {
        st.step(&mut y).unwrap();
        tc.step(&mut q, &mut p).unwrap();
    }
    let qp: Vec<f64> = q.iter().chain(&p).copied().collect();
    assert!(max_abs_diff(&qp, &y) <= 1e-13);
    // Bad N.
    let bad = damped_first_order(om.clone(), DMatrix::<f64>::identity(3, 3), coupled_force, u);
    assert!(matches!(bad, Err(Error::InvalidInput(_))));
    let bad = damped_first_order(om, DMatrix::zeros(2, 2), coupled_force, u);
    assert!(matches!(bad, Err(Error::DimensionMismatch { .. })));
}
