//! TCrP/RKNCrP on the one ECrP stepper: the oscillator operator's banks against their defining
//! integrals and against the dense 2n × 2n matrix, per-step agreement with ECrP on the
//! first-order form, and what the first-order stepper brings with it (fused sweeps for one
//! mode, Newton, the predictor, dense output, fixed-size storage), and the damped form.
// Loops over bank nodes index the bank and the node list alike; the Duffing builder returns
// closures (unnameable types).
#![allow(clippy::needless_range_loop, clippy::type_complexity)]

use crate::common_ec;

use ecr::problems::{Duffing, Fpu};
use ecr_runtime::ecr_method;
use ecr_runtime::operator::{Dense, LinearOperator, Oscillator, PhiBank};
use ecr_runtime::second_order::{Omega, SecondOrder, SecondOrderForm, TcStepper};
use ecr_runtime::stepper::{
    EcStepper, Predictor, RuntimeKernel, SolverSettings, StageSolver, fuses_stages,
};
use ecr_runtime::system::{Semilinear, System};
use nalgebra::DMatrix;

/// Gauss–Legendre nodes and weights on [0, 1] (Newton on the three-term recurrence).
fn gauss(q: usize) -> Vec<(f64, f64)> {
    (0..q)
        .map(|i| {
            let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (q as f64 + 0.5)).cos();
            let mut dp = 1.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for k in 1..q {
                    let p2 = ((2 * k + 1) as f64 * x * p1 - k as f64 * p0) / (k + 1) as f64;
                    p0 = p1;
                    p1 = p2;
                }
                dp = q as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-17 {
                    break;
                }
            }
            (0.5 * (1.0 + x), 1.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

/// P̃_j(x), the shifted Legendre polynomial.
fn legendre(j: usize, x: f64) -> f64 {
    let t = 2.0 * x - 1.0;
    let (mut a, mut b) = (1.0, t);
    if j == 0 {
        return 1.0;
    }
    for k in 1..j {
        let c = ((2 * k + 1) as f64 * t * b - k as f64 * a) / (k + 1) as f64;
        a = b;
        b = c;
    }
    b
}

/// The defining integrals of the kernel block of one mode: with θ = τh√λ,
/// `a = ∫₀¹ cos((1−ξ)θ) P̃_j(τξ) dξ`, `b/(τh) = ∫₀¹ sin((1−ξ)θ)/θ P̃_j(τξ) dξ` (the limit
/// (1 − ξ) at θ = 0), by a 200-point Gauss rule on subintervals (the integrands are smooth).
fn kernel_integrals(j: usize, tau: f64, theta: f64) -> (f64, f64) {
    let rule = gauss(50);
    let parts = 8;
    let (mut a, mut s) = (0.0, 0.0);
    for part in 0..parts {
        let (lo, w) = (part as f64 / parts as f64, 1.0 / parts as f64);
        for &(x, wq) in &rule {
            let xi = lo + w * x;
            let pj = legendre(j, tau * xi);
            let u = (1.0 - xi) * theta;
            let sinc = if theta == 0.0 {
                1.0 - xi
            } else {
                u.sin() / theta
            };
            a += w * wq * u.cos() * pj;
            s += w * wq * sinc * pj;
        }
    }
    (a, s)
}

#[test]
fn kernel_banks_agree_with_their_defining_integrals() {
    let lambdas = [0.0, 1e-20, 1e-8, 0.09, 1.0, 25.0, 400.0, 2500.0];
    let omega = Omega::diagonal(lambdas.to_vec()).unwrap();
    let n = lambdas.len();
    let op = Oscillator::new(omega);
    let h = 0.1;
    let r = 6;
    let kernel = RuntimeKernel::new(r, r).unwrap();
    let mut taus = kernel.coefficients().nodes.clone();
    taus.push(1.0);
    taus.push(1.4); // an extrapolation node of the predictor
    let bank = op.kernel_bank(h, &taus, r).unwrap();
    let mut ws = bank.workspace();
    let (mut e, mut col) = (vec![0.0; 2 * n], vec![0.0; 2 * n]);
    let mut worst: f64 = 0.0;
    for (i, &tau) in taus.iter().enumerate() {
        let t = tau * h;
        for j in 0..r {
            for (l, &lam) in lambdas.iter().enumerate() {
                let theta = t * lam.sqrt();
                let (a, s) = kernel_integrals(j, tau, theta);
                // Column l (unit q_l) gives (a, c); column n + l (unit p_l) gives (b, a).
                e.fill(0.0);
                e[l] = 1.0;
                bank.apply(i, j + 1, &e, &mut col, &mut ws);
                let (ga, gc) = (col[l], col[n + l]);
                e.fill(0.0);
                e[n + l] = 1.0;
                bank.apply(i, j + 1, &e, &mut col, &mut ws);
                let gb = col[l];
                // Natural bounds: |a| ≤ 1, |b| ≤ t, |c| ≤ λ t (times the size of P̃_j on [0, τ]).
                let errs = [
                    (ga - a).abs(),
                    (gb - t * s).abs() / t,
                    (gc + lam * t * s).abs() / (lam * t).max(f64::MIN_POSITIVE),
                ];
                // Relative accuracy of b as θ → 0 (no loss from dividing by θ), where the
                // kernel itself is not a cancelling sum (|b/t| ≥ 0.05).
                let rel_b = ((gb - t * s) / (t * s)).abs();
                let scale = legendre(j, tau).abs().max(1.0);
                for err in errs {
                    worst = worst.max(err / scale);
                    assert!(
                        err <= 2e-14 * scale,
                        "τ = {tau}, j = {j}, λ = {lam}: {errs:?}"
                    );
                }
                if theta < 0.5 && s.abs() >= 0.05 {
                    assert!(rel_b <= 1e-14, "τ = {tau}, j = {j}, λ = {lam}: {rel_b:e}");
                }
            }
        }
    }
    println!("largest kernel error against the integrals: {worst:.2e}");
}

#[test]
fn oscillator_banks_equal_the_dense_first_order_matrix() {
    // The banks of [[0, I], [−Ω, 0]] formed as a dense 2n × 2n matrix (scaling and squaring)
    // and of the oscillator operator (modal, trigonometric): φ-banks and Legendre banks, for
    // diagonal and dense Ω.
    let om = DMatrix::from_row_slice(3, 3, &[2.0, -1.0, 0.0, -1.0, 2.0, -1.0, 0.0, -1.0, 30.0]);
    for omega in [
        Omega::dense(om.clone()).unwrap(),
        Omega::diagonal(vec![0.0, 4.0, 90.0]).unwrap(),
    ] {
        let n = omega.dim();
        let mut a = DMatrix::zeros(2 * n, 2 * n);
        for i in 0..n {
            a[(i, n + i)] = 1.0;
        }
        let omat = match omega.matrix() {
            Some(m) => m.clone(),
            None => {
                DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(omega.eigenvalues()))
            }
        };
        a.view_mut((n, 0), (n, n)).copy_from(&(-omat));
        let dense = Dense::new(a).unwrap();
        let osc = Oscillator::new(omega);
        let taus = [0.0, 0.21, 0.5, 1.0, 1.3];
        let h = 0.07;
        for legendre_bank in [false, true] {
            let (bo, bd) = if legendre_bank {
                (
                    osc.kernel_bank(h, &taus, 4).unwrap(),
                    dense.kernel_bank(h, &taus, 4).unwrap(),
                )
            } else {
                (
                    osc.phi_bank(h, &taus, 4).unwrap(),
                    dense.phi_bank(h, &taus, 4).unwrap(),
                )
            };
            assert_banks_agree(&bo, &bd, &taus, &format!("legendre {legendre_bank}"));
        }
    }
}

/// Applies every function of two banks over the same nodes to the unit vectors and asserts
/// that they agree to `1e−13` relative to the largest entry of the column (the dense bank's
/// scaling and squaring is the reference).
fn assert_banks_agree<B1: PhiBank, B2: PhiBank>(bo: &B1, bd: &B2, taus: &[f64], label: &str) {
    let d = bo.dim();
    let (mut wo, mut wd) = (bo.workspace(), bd.workspace());
    let (mut e, mut x, mut y) = (vec![0.0; d], vec![0.0; d], vec![0.0; d]);
    for (i, tau) in taus.iter().enumerate() {
        for k in 0..=bo.p() {
            for c in 0..d {
                e.fill(0.0);
                e[c] = 1.0;
                bo.apply(i, k, &e, &mut x, &mut wo);
                bd.apply(i, k, &e, &mut y, &mut wd);
                let scale = y.iter().fold(1.0f64, |m, v| m.max(v.abs()));
                let diff = common_ec::max_abs_diff(&x, &y) / scale;
                assert!(
                    diff <= 1e-13,
                    "{label}, τ = {tau}, k = {k}, column {c}: {diff:e}"
                );
            }
        }
    }
}

/// The Duffing problem (ω, k) in second-order form: q'' + (ω² + k²) q = 2k² q³.
fn duffing_second_order(
    w: f64,
    k: f64,
) -> SecondOrder<impl Fn(&[f64], &mut [f64]), impl Fn(&[f64]) -> f64> {
    let k2 = k * k;
    SecondOrder::with_potential(
        Omega::scalar(w * w + k2, 1).unwrap(),
        move |q: &[f64], f: &mut [f64]| f[0] = -2.0 * k2 * q[0].powi(3),
        move |q: &[f64]| -0.5 * k2 * q[0].powi(4),
    )
}

/// Largest relative difference of one step of TCrP and of ECrP on the dense first-order form,
/// from the same state, over `steps` steps of TCrP.
fn per_step_agreement<S: System>(
    tc: &mut TcStepper<impl ecr_runtime::second_order::SecondOrderSystem>,
    ec: &mut EcStepper<S>,
    y0: &[f64],
    steps: usize,
) -> f64 {
    let mut y = y0.to_vec();
    let mut worst: f64 = 0.0;
    for _ in 0..steps {
        let mut z = y.clone();
        tc.stepper_mut().step(&mut y).unwrap();
        ec.step(&mut z).unwrap();
        let scale = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        worst = worst.max(common_ec::max_abs_diff(&y, &z) / scale);
    }
    worst
}

#[test]
fn one_step_agrees_with_ecrp_on_the_first_order_form() {
    // Acceptance: ≤ 1e−15 per step (relative to the state's max-norm).
    for r in 2..=6 {
        let settings = SolverSettings::default();
        // Duffing (one mode, fused sweeps on both sides).
        let d = Duffing::new(5.0, 0.07).unwrap();
        let mut tc =
            TcStepper::with_nodes(duffing_second_order(5.0, 0.07), r, r, 0.05, settings).unwrap();
        let mut ec = EcStepper::with_nodes(d.system().unwrap(), r, r, 0.05, settings).unwrap();
        let duff = per_step_agreement(&mut tc, &mut ec, &d.initial_value(), 400);
        // FPU (m = 3, ω = 50: six modes, three of them stiff).
        let fpu = Fpu::new(3, 50.0).unwrap();
        let mut tc = TcStepper::with_nodes(fpu.system().unwrap(), r, r, 0.01, settings).unwrap();
        let mut ec =
            EcStepper::with_nodes(fpu.first_order_system().unwrap(), r, r, 0.01, settings).unwrap();
        let fp = per_step_agreement(&mut tc, &mut ec, &fpu.initial_value_first_order(), 400);
        println!("r = {r}: per-step difference TCrP vs ECrP: Duffing {duff:.2e}, FPU {fp:.2e}");
        assert!(duff <= 1e-15 && fp <= 1e-15, "r = {r}: {duff:e}, {fp:e}");
    }
}

#[test]
fn one_mode_fuses_its_sweeps() {
    let form = SecondOrderForm::new(duffing_second_order(5.0, 0.07)).unwrap();
    let bank = form
        .linear()
        .kernel_bank(0.05, &[0.2, 0.8, 1.0], 3)
        .unwrap();
    assert!(fuses_stages(&bank, 3, 3));
    let fpu = Fpu::new(3, 50.0).unwrap();
    let form = SecondOrderForm::new(fpu.system().unwrap()).unwrap();
    let bank = form
        .linear()
        .kernel_bank(0.05, &[0.2, 0.8, 1.0], 3)
        .unwrap();
    assert!(!fuses_stages(&bank, 3, 3));
    let st = TcStepper::new(duffing_second_order(5.0, 0.07), 3, 0.05).unwrap();
    assert!(st.stepper().stage_matrices().is_some());
}

#[test]
fn newton_predictor_and_dense_output_come_with_the_stepper() {
    let fpu = Fpu::new(3, 50.0).unwrap();
    let (q0, p0) = fpu.initial_value();
    let h = 0.02;
    let run = |settings: SolverSettings| {
        let mut st = TcStepper::with_nodes(fpu.system().unwrap(), 3, 3, h, settings).unwrap();
        let (mut q, mut p) = (q0.clone(), p0.clone());
        let mut sweeps = 0;
        for _ in 0..200 {
            sweeps += st.step(&mut q, &mut p).unwrap().sweeps;
        }
        (q, p, sweeps, st)
    };
    // Fixed point from y₀, then Newton from y₀, then the default (fixed point, extrapolated).
    let constant = SolverSettings {
        predictor: Predictor::Constant,
        ..SolverSettings::default()
    };
    let (q, p, fixed_sweeps, st) = run(constant);
    let (qn, pn, newton_sweeps, _) = run(SolverSettings {
        solver: StageSolver::Newton,
        ..constant
    });
    let (qx, px, pred_sweeps, _) = run(SolverSettings::default());
    for (a, b) in [(&q, &qn), (&p, &pn), (&q, &qx), (&p, &px)] {
        assert!(common_ec::max_abs_diff(a, b) <= 1e-13);
    }
    println!(
        "sweeps over 200 steps: fixed point {fixed_sweeps}, Newton {newton_sweeps}, predictor {pred_sweeps}"
    );
    assert!(newton_sweeps < fixed_sweeps && pred_sweeps < fixed_sweeps);
    // Dense output: the end of the step at τ = 1, and between the ends a state close to both.
    let end = st.dense_output(1.0).unwrap();
    let qp: Vec<f64> = q.iter().chain(&p).copied().collect();
    assert!(common_ec::max_abs_diff(&end, &qp) <= 1e-14);
    assert_eq!(st.dense_output(0.5).unwrap().len(), 12);
}

mod fixed {
    use super::ecr_method;
    ecr_method!(pub r = 4, family = tc);
    ecr_method!(pub r = 3, family = rknc);
}

#[test]
fn fixed_size_steppers_are_bit_identical_to_the_run_time_one() {
    // Duffing: one mode, fused sweeps with compile-time sizes (N = 1, state (q, p)).
    let h = 0.05;
    let mut st: fixed::Tc4<_, 1> = fixed::Tc4::fixed(duffing_second_order(5.0, 0.07), h).unwrap();
    let mut rt = TcStepper::new(duffing_second_order(5.0, 0.07), 4, h).unwrap();
    let (mut q1, mut p1) = ([0.0], [5.0]);
    let (mut q2, mut p2) = ([0.0], [5.0]);
    for n in 0..2000 {
        st.step(&mut q1, &mut p1).unwrap();
        rt.step(&mut q2, &mut p2).unwrap();
        assert_eq!((q1, p1), (q2, p2), "step {n}");
    }
    // RKNC (Ω = 0) on the same problem written as q'' = −(ω² + k²) q + 2k² q³.
    let k2 = 0.07 * 0.07;
    let w2 = 25.0 + k2;
    let force = move |q: &[f64], f: &mut [f64]| f[0] = w2 * q[0] - 2.0 * k2 * q[0].powi(3);
    let mut st: fixed::Rknc3<_, 1> =
        fixed::Rknc3::fixed(SecondOrder::new(Omega::zero(1), force), 0.01).unwrap();
    let mut rt = TcStepper::new(SecondOrder::new(Omega::zero(1), force), 3, 0.01).unwrap();
    let (mut q1, mut p1) = ([0.0], [5.0]);
    let (mut q2, mut p2) = ([0.0], [5.0]);
    for n in 0..2000 {
        st.step(&mut q1, &mut p1).unwrap();
        rt.step(&mut q2, &mut p2).unwrap();
        assert_eq!((q1, p1), (q2, p2), "step {n}");
    }
    // The same stepper as ECrP on the first-order form with the oscillator operator.
    let form = SecondOrderForm::new(duffing_second_order(5.0, 0.07)).unwrap();
    let mut ec = EcStepper::new(&form, 4, h).unwrap();
    let mut tc = TcStepper::new(duffing_second_order(5.0, 0.07), 4, h).unwrap();
    let mut y = vec![0.0, 5.0];
    let (mut q, mut p) = ([0.0], [5.0]);
    for _ in 0..100 {
        ec.step(&mut y).unwrap();
        tc.step(&mut q, &mut p).unwrap();
    }
    assert_eq!(y, vec![q[0], p[0]]);
}

#[test]
fn damped_oscillator_equals_the_dense_damped_matrix_and_dissipates() {
    // q'' − Nq' + Ωq = −∇U with N = V diag(ν) Vᵀ sharing Ω's eigenvectors.
    let om = DMatrix::from_row_slice(3, 3, &[2.0, -1.0, 0.0, -1.0, 2.0, -1.0, 0.0, -1.0, 30.0]);
    let nu = vec![-0.3, 0.0, -2.0];
    for dense_omega in [true, false] {
        let omega = if dense_omega {
            Omega::dense(om.clone()).unwrap()
        } else {
            Omega::diagonal(vec![0.0, 4.0, 900.0]).unwrap()
        };
        let n = omega.dim();
        let (omat, nmat) = match omega.basis() {
            Some(v) => (
                om.clone(),
                v * DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(&nu))
                    * v.transpose(),
            ),
            None => (
                DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(omega.eigenvalues())),
                DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(&nu)),
            ),
        };
        let mut a = DMatrix::zeros(2 * n, 2 * n);
        for i in 0..n {
            a[(i, n + i)] = 1.0;
        }
        a.view_mut((n, 0), (n, n)).copy_from(&(-omat));
        a.view_mut((n, n), (n, n)).copy_from(&nmat);
        let dense = Dense::new(a).unwrap();
        let osc = Oscillator::damped(omega, nu.clone()).unwrap();
        let taus = [0.0, 0.3, 1.0, 1.2];
        let h = 0.05;
        for legendre_bank in [false, true] {
            let (bo, bd) = if legendre_bank {
                (
                    osc.kernel_bank(h, &taus, 3).unwrap(),
                    dense.kernel_bank(h, &taus, 3).unwrap(),
                )
            } else {
                (
                    osc.phi_bank(h, &taus, 3).unwrap(),
                    dense.phi_bank(h, &taus, 3).unwrap(),
                )
            };
            let label = format!("dense Ω {dense_omega}, legendre {legendre_bank}");
            assert_banks_agree(&bo, &bd, &taus, &label);
        }
        // A run: H = ½|p|² + ½qᵀΩq + ¼Σq⁴ decreases every step.
        let om2 = osc.omega().clone();
        let sys = Semilinear::with_energy(
            osc,
            |y: &[f64], o: &mut [f64]| {
                let n = y.len() / 2;
                o[..n].fill(0.0);
                for i in 0..n {
                    o[n + i] = -y[i].powi(3);
                }
            },
            move |y: &[f64]| {
                let n = y.len() / 2;
                0.5 * y[n..].iter().map(|v| v * v).sum::<f64>()
                    + om2.half_quadratic(&y[..n])
                    + 0.25 * y[..n].iter().map(|v| v.powi(4)).sum::<f64>()
            },
        );
        let mut st = EcStepper::new(&sys, 3, 0.01).unwrap();
        let mut y = vec![0.3, -0.2, 0.5, 0.1, 0.4, -0.3];
        let mut energy = sys.energy(&y).unwrap();
        for _ in 0..500 {
            st.step(&mut y).unwrap();
            let e = sys.energy(&y).unwrap();
            assert!(e <= energy, "H rose: {energy} -> {e}");
            energy = e;
        }
    }
    assert!(Oscillator::damped(Omega::zero(2), vec![0.1, 0.0]).is_err());
    assert!(Oscillator::damped(Omega::zero(2), vec![0.0]).is_err());
}
