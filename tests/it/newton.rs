//! The simplified-Newton stage solver on a stiff nonlinearity: Allen–Cahn in 1D,
//!
//! ```text
//! u_t = u_xx + (u − u³)/ε²,   ε = 0.01,   x ∈ [0, 1) periodic,   N = 128 points,
//! ```
//!
//! a gradient flow of `U(u) = Σ [½ ((u_{i+1} − u_i)/Δx)² + (u_i² − 1)²/(4ε²)] Δx`: the linear
//! part (second differences, stiff: ‖hA‖ ≈ 20 at h = 3e−4) is integrated exactly by the
//! exponential, the nonlinearity has `g'(u) = (1 − 3u²)/ε²` up to 2e4 in modulus, so
//! fixed-point sweeps (contraction ≈ h‖g'‖ ≈ 6) diverge while Newton converges, and U must not
//! increase. (At h = 1e−4 fixed point still converges, in ≈ 50 sweeps.)
//!
//! And a stiff reaction–diffusion problem where the Jacobian must follow the stages:
//! `y' = A y + 50 (y − y³)`, A the periodic second-difference Laplacian scaled so that
//! ‖hA‖∞ = 1e4 at h = 0.1. Within one step the diffusion flattens the profile and the reaction
//! drives it towards 1, so g' = 50 (1 − 3y²) changes sign between y₀ and the stages:
//! simplified Newton (Jacobian frozen at y₀) diverges at step 1, Newton with the Jacobian
//! refreshed at the stages converges.

use ecr_runtime::operator::Circulant;
use ecr_runtime::stepper::{EcStepper, SolverSettings, StageSolver, StepReport};
use ecr_runtime::system::System;
use ecr_runtime::{Error, Result};
use nalgebra::DMatrix;

const N: usize = 128;
const EPS: f64 = 0.01;

struct AllenCahn {
    op: Circulant,
    dx: f64,
    /// Whether to offer the analytic Jacobian (else the stepper uses finite differences).
    analytic_jacobian: bool,
    /// A broken Jacobian (NaN entries), for the error test.
    broken_jacobian: bool,
    /// A Jacobian of the wrong size, for the error test.
    resized_jacobian: bool,
}

impl AllenCahn {
    fn new(analytic_jacobian: bool) -> Result<Self> {
        let dx = 1.0 / N as f64;
        let mut c = vec![0.0; N];
        c[0] = -2.0 / (dx * dx);
        c[1] = 1.0 / (dx * dx);
        c[N - 1] = 1.0 / (dx * dx);
        Ok(AllenCahn {
            op: Circulant::new(c)?,
            dx,
            analytic_jacobian,
            broken_jacobian: false,
            resized_jacobian: false,
        })
    }

    /// Two interfaces, at x = 1/4 and 3/4, slightly off their equilibrium profile.
    fn initial_value(&self) -> Vec<f64> {
        (0..N)
            .map(|i| {
                let x = i as f64 * self.dx;
                let w = std::f64::consts::SQRT_2 * EPS * 1.5;
                ((x - 0.25) / w).tanh() * (-(x - 0.75) / w).tanh()
            })
            .collect()
    }

    fn lyapunov(&self, u: &[f64]) -> f64 {
        let mut e = 0.0;
        for i in 0..N {
            let ux = (u[(i + 1) % N] - u[i]) / self.dx;
            e += 0.5 * ux * ux + (u[i] * u[i] - 1.0).powi(2) / (4.0 * EPS * EPS);
        }
        e * self.dx
    }
}

impl System for AllenCahn {
    type Op = Circulant;
    fn linear(&self) -> &Circulant {
        &self.op
    }
    fn nonlinear(&self, y: &[f64], out: &mut [f64], _scratch: &mut [f64]) {
        for (o, u) in out.iter_mut().zip(y) {
            *o = (u - u * u * u) / (EPS * EPS);
        }
    }
    fn jacobian(&self, y: &[f64], jac: &mut DMatrix<f64>, _scratch: &mut [f64]) -> bool {
        if !self.analytic_jacobian {
            return false;
        }
        if self.resized_jacobian {
            *jac = DMatrix::zeros(3, 3);
            return true;
        }
        jac.fill(if self.broken_jacobian { f64::NAN } else { 0.0 });
        for (i, u) in y.iter().enumerate() {
            jac[(i, i)] = (1.0 - 3.0 * u * u) / (EPS * EPS);
        }
        true
    }
}

fn newton() -> SolverSettings {
    SolverSettings {
        solver: StageSolver::Newton,
        ..SolverSettings::default()
    }
}

#[test]
fn fixed_point_fails_and_newton_converges_on_allen_cahn() {
    let h = 3e-4;
    let steps = 40;
    println!(
        "| solver | Jacobian | steps | iterations per step (mean, max) | g-evaluations | U(0) → U(T) |"
    );
    println!("|---|---|---|---|---|---|");
    // Fixed point: the first step already fails, with an error (no NaN state).
    let p = AllenCahn::new(true).unwrap();
    let mut st = EcStepper::with_nodes(&p, 2, 2, h, SolverSettings::default()).unwrap();
    let mut u = p.initial_value();
    let u0 = u.clone();
    let err = st.step(&mut u).unwrap_err();
    // It diverges (g overflows at the iterates): the error says so, rather than blaming g.
    assert!(
        matches!(err, Error::NoConvergence { .. })
            || matches!(err, Error::NonFinite(w) if w.contains("diverg")),
        "{err}"
    );
    assert_eq!(u, u0, "a failed step leaves the state unchanged");
    println!("| fixed point | — | 0 | fails at step 1: {err} | | |");

    for (analytic, solver) in [
        (true, StageSolver::Newton),
        (false, StageSolver::Newton),
        (true, StageSolver::SimplifiedNewton),
    ] {
        let p = AllenCahn::new(analytic).unwrap();
        let settings = SolverSettings {
            solver,
            ..SolverSettings::default()
        };
        let mut st = EcStepper::with_nodes(&p, 2, 2, h, settings).unwrap();
        let mut u = p.initial_value();
        let mut prev = p.lyapunov(&u);
        let start = prev;
        let (mut total, mut worst, mut g_evals, mut refreshes) = (0, 0, 0, 0);
        for n in 0..steps {
            let rep = st.step(&mut u).unwrap();
            assert!(rep.converged);
            total += rep.sweeps;
            worst = worst.max(rep.sweeps);
            g_evals += rep.g_evals;
            refreshes += rep.newton_refreshes;
            let e = p.lyapunov(&u);
            // Non-increasing up to round-off of U (≈ 1e-13 relative here).
            assert!(
                e <= prev * (1.0 + 1e-13),
                "step {n}: U rose from {prev} to {e}"
            );
            prev = e;
        }
        assert!(prev < start, "the interfaces relax: U decreases");
        // Simplified Newton converges linearly (J frozen at y₀ while u moves by O(1) at the
        // interfaces within a step of 3ε²); the default limit is 100.
        assert!(worst <= 40, "Newton needed {worst} iterations");
        println!(
            "| {solver:?} ({refreshes} refreshes) | {} | {steps} | {:.1}, {worst} | {g_evals} | {start:.6} → {prev:.6} |",
            if analytic {
                "analytic"
            } else {
                "finite differences"
            },
            total as f64 / steps as f64,
        );
    }
}

#[test]
fn newton_agrees_with_fixed_point_where_both_converge() {
    // h = 1e-6: h‖g'‖ = 0.02, both iterations converge to the same stages.
    let p = AllenCahn::new(true).unwrap();
    let h = 1e-6;
    let mut a = EcStepper::with_nodes(&p, 3, 3, h, SolverSettings::default()).unwrap();
    let mut b = EcStepper::with_nodes(&p, 3, 3, h, newton()).unwrap();
    let (mut ua, mut ub) = (p.initial_value(), p.initial_value());
    let (mut sa, mut sb) = (0, 0);
    for _ in 0..20 {
        sa += a.step(&mut ua).unwrap().sweeps;
        sb += b.step(&mut ub).unwrap().sweeps;
    }
    let diff = ua
        .iter()
        .zip(&ub)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    println!(
        "h = 1e-6, 20 steps: fixed point {sa} sweeps, Newton {sb} iterations, max diff {diff:e}"
    );
    assert!(diff <= 1e-13, "{diff:e}");
    assert!(
        sb <= sa,
        "Newton should not need more iterations ({sb} vs {sa})"
    );
}

#[test]
fn a_bad_jacobian_is_an_error_naming_it() {
    let mut p = AllenCahn::new(true).unwrap();
    p.broken_jacobian = true;
    let mut st = EcStepper::with_nodes(&p, 2, 2, 3e-4, newton()).unwrap();
    let mut u = p.initial_value();
    let u0 = u.clone();
    match st.step(&mut u) {
        Err(Error::NonFinite(what)) => assert!(what.contains("Jacobian"), "{what}"),
        other => panic!("expected NonFinite(Jacobian …), got {other:?}"),
    }
    assert_eq!(u, u0);
    // A Jacobian of the wrong shape: a dimension error, not a panic.
    let mut p = AllenCahn::new(true).unwrap();
    p.resized_jacobian = true;
    let mut st = EcStepper::with_nodes(&p, 2, 2, 3e-4, newton()).unwrap();
    assert!(matches!(
        st.step(&mut u),
        Err(Error::DimensionMismatch { expected, found: 9, .. }) if expected == N * N
    ));
    assert_eq!(u, u0);
}

#[test]
fn newton_is_rejected_where_it_is_not_implemented() {
    // The exponential AVF baseline has no Newton iteration: asking for one is an error, not
    // ignored.
    use ecr::baselines::collocation::ExpAvf;
    let p = AllenCahn::new(true).unwrap();
    let r = ExpAvf::new(&p, 3, 1e-4, newton());
    assert!(matches!(r, Err(Error::InvalidParameter(_))));
}

#[test]
fn newton_runs_for_the_second_order_methods() {
    // TCrP is the ECrP stepper on the oscillator operator, Newton included (forward
    // differences of the force: FPU provides no Jacobian).
    use ecr::problems::Fpu;
    use ecr_runtime::second_order::TcStepper;
    let f = Fpu::default();
    let mut st = TcStepper::with_nodes(f.system().unwrap(), 2, 2, 0.01, newton()).unwrap();
    let (mut q, mut p) = f.initial_value();
    for _ in 0..10 {
        let rep = st.step(&mut q, &mut p).unwrap();
        assert!(rep.converged);
    }
}

/// Newton's `O(s²d²)` matrices are refused at construction, with their size, when they cannot
/// be allocated (they used to abort the process at the first step): d = 2²² needs 2⁴⁹ bytes,
/// more than a 64-bit address space maps (47 bits for user space on x86-64 and AArch64), and
/// d = 2⁴⁰ overflows the count. Fixed-point sweeps (O(d) storage) are not affected.
#[test]
fn newton_storage_that_cannot_exist_is_an_error_naming_its_size() {
    use ecr_runtime::operator::Zero;
    use ecr_runtime::system::Semilinear;
    let newton = SolverSettings {
        solver: StageSolver::Newton,
        ..SolverSettings::default()
    };
    for d in [1usize << 22, 1 << 40] {
        let system = Semilinear::new(Zero::new(d), |_: &[f64], out: &mut [f64]| out.fill(0.0));
        let err = EcStepper::with_nodes(system, 2, 2, 0.1, newton)
            .err()
            .unwrap_or_else(|| panic!("d = {d}: accepted"));
        let msg = err.to_string();
        assert!(matches!(err, Error::InvalidInput(_)), "{msg}");
        assert!(
            msg.contains(&format!("d = {d}, s = 2")) && msg.contains("more than can be allocated"),
            "{msg}"
        );
    }
    let system = Semilinear::new(Zero::new(4), |_: &[f64], out: &mut [f64]| out.fill(0.0));
    assert!(EcStepper::with_nodes(system, 2, 2, 0.1, newton).is_ok());
}

/// `y' = κ D₂ y + 50 (y − y³)` on n periodic points of [0, 1), κ chosen so that
/// ‖A‖∞ = 4κ/Δx² = 1e5 (‖hA‖∞ = 1e4 at h = 0.1); a gradient flow of
/// `U(y) = Σ [κ/2 ((y_{i+1} − y_i)/Δx)² + 12.5 (y_i² − 1)²] Δx`.
struct ReactionDiffusion {
    op: Circulant,
    n: usize,
    dx: f64,
    kappa: f64,
    analytic_jacobian: bool,
}

const RD_NORM_A: f64 = 1e5;

impl ReactionDiffusion {
    fn new(n: usize, analytic_jacobian: bool) -> Result<Self> {
        let dx = 1.0 / n as f64;
        let kappa = RD_NORM_A * dx * dx / 4.0;
        let mut c = vec![0.0; n];
        c[0] = -2.0 * kappa / (dx * dx);
        c[1] = kappa / (dx * dx);
        c[n - 1] = kappa / (dx * dx);
        Ok(ReactionDiffusion {
            op: Circulant::new(c)?,
            n,
            dx,
            kappa,
            analytic_jacobian,
        })
    }

    /// ‖A‖∞: the largest absolute row sum of the second-difference stencil.
    fn norm_a(&self) -> f64 {
        4.0 * self.kappa / (self.dx * self.dx)
    }

    /// a + b cos 2πx.
    fn initial_value(&self, a: f64, b: f64) -> Vec<f64> {
        (0..self.n)
            .map(|i| a + b * (2.0 * std::f64::consts::PI * i as f64 * self.dx).cos())
            .collect()
    }

    fn lyapunov(&self, u: &[f64]) -> f64 {
        let mut e = 0.0;
        let n = self.n;
        for i in 0..n {
            let ux = (u[(i + 1) % n] - u[i]) / self.dx;
            e += 0.5 * self.kappa * ux * ux + 12.5 * (u[i] * u[i] - 1.0).powi(2);
        }
        e * self.dx
    }
}

impl System for ReactionDiffusion {
    type Op = Circulant;
    fn linear(&self) -> &Circulant {
        &self.op
    }
    fn nonlinear(&self, y: &[f64], out: &mut [f64], _scratch: &mut [f64]) {
        for (o, u) in out.iter_mut().zip(y) {
            *o = 50.0 * (u - u * u * u);
        }
    }
    fn jacobian(&self, y: &[f64], jac: &mut DMatrix<f64>, _scratch: &mut [f64]) -> bool {
        if !self.analytic_jacobian {
            return false;
        }
        jac.fill(0.0);
        for (i, u) in y.iter().enumerate() {
            jac[(i, i)] = 50.0 * (1.0 - 3.0 * u * u);
        }
        true
    }
}

fn solver(solver: StageSolver) -> SolverSettings {
    SolverSettings {
        solver,
        ..SolverSettings::default()
    }
}

#[test]
fn newton_refreshes_its_jacobian_where_simplified_newton_diverges() {
    let h = 0.1;
    let steps = 10;
    let n = 64;
    let p = ReactionDiffusion::new(n, true).unwrap();
    let stiffness = h * p.norm_a();
    assert!((stiffness - 1e4).abs() <= 1e-9, "‖hA‖ = {stiffness}");
    // 0.3 + 0.7 cos 2πx: smooth, values in [−0.4, 1].
    let u0 = p.initial_value(0.3, 0.7);
    println!(
        "‖hA‖∞ = {stiffness:e}, h = {h}, N = {n}, U(y₀) = {:.6}",
        p.lyapunov(&u0)
    );

    // Fixed-point sweeps and simplified Newton both fail at step 1, saying the iteration
    // diverged; the state is left as it was.
    for s in [StageSolver::FixedPoint, StageSolver::SimplifiedNewton] {
        let mut st = EcStepper::with_nodes(&p, 2, 2, h, solver(s)).unwrap();
        let mut u = u0.clone();
        let err = st.step(&mut u).unwrap_err();
        println!("{s:?}: step 1 fails: {err}");
        assert!(
            matches!(err, Error::NonFinite(w) if w.contains("diverg")),
            "{s:?}: {err}"
        );
        assert_eq!(u, u0, "a failed step leaves the state unchanged");
    }

    // Newton: the step-1 iteration stops contracting with J(y₀), refreshes the Jacobian at the
    // stages, and converges; U does not increase.
    for analytic in [true, false] {
        let p = ReactionDiffusion::new(n, analytic).unwrap();
        let mut st = EcStepper::with_nodes(&p, 2, 2, h, solver(StageSolver::Newton)).unwrap();
        let mut u = u0.clone();
        let mut prev = p.lyapunov(&u);
        let start = prev;
        let mut reports: Vec<StepReport> = Vec::new();
        for n in 0..steps {
            let rep = st.step(&mut u).unwrap();
            assert!(rep.converged, "step {n}: {rep:?}");
            assert_eq!(rep.jacobian_evals, 1 + 2 * rep.newton_refreshes, "{rep:?}");
            let e = p.lyapunov(&u);
            assert!(
                e <= prev * (1.0 + 1e-13),
                "step {n}: U rose from {prev} to {e}"
            );
            prev = e;
            reports.push(rep);
        }
        assert!(
            reports[0].newton_refreshes >= 1,
            "step 1 should need a refresh: {:?}",
            reports[0]
        );
        assert!(prev < start);
        let line: Vec<String> = reports
            .iter()
            .map(|r| format!("{}/{}/{}", r.sweeps, r.jacobian_evals, r.newton_refreshes))
            .collect();
        println!(
            "Newton ({} Jacobian): per step iterations/Jacobians/refreshes {}; g-evaluations {}; \
             U {start:.6} → {prev:.3e}; mean y {:.6}",
            if analytic {
                "analytic"
            } else {
                "finite-difference"
            },
            line.join(" "),
            reports.iter().map(|r| r.g_evals).sum::<usize>(),
            u.iter().sum::<f64>() / n as f64
        );
    }
}

/// The limit of undamped Newton: with 128 points (‖hA‖ still 1e4) and y₀ = 0.1 + 0.9 cos 2πx,
/// the first iterate overshoots far (g'(y₀) = 50 where y₀ ≈ 0) and the refreshed iteration
/// does not get back within the sweep limit; the step is an error naming it, the state is left
/// as it was. From 0.3 + 0.7 cos 2πx it converges, after many refreshes.
#[test]
fn newton_from_a_poor_start_is_an_error_not_a_wrong_step() {
    let p = ReactionDiffusion::new(128, true).unwrap();
    let mut st = EcStepper::with_nodes(&p, 2, 2, 0.1, solver(StageSolver::Newton)).unwrap();
    let u0 = p.initial_value(0.1, 0.9);
    let mut u = u0.clone();
    let err = st.step(&mut u).unwrap_err();
    println!("N = 128, y₀ = 0.1 + 0.9 cos 2πx: {err}");
    assert!(matches!(err, Error::NoConvergence { .. }), "{err}");
    assert_eq!(u, u0);
    let mut u = p.initial_value(0.3, 0.7);
    let rep = st.step(&mut u).unwrap();
    println!("N = 128, y₀ = 0.3 + 0.7 cos 2πx: {rep:?}");
    assert!(rep.converged && rep.newton_refreshes >= 1, "{rep:?}");
}

#[test]
fn newton_is_simplified_newton_while_that_contracts() {
    // Allen–Cahn at h = 1e-5: the frozen Jacobian contracts fast; Newton never refreshes and
    // gives the same steps, bit for bit, with one Jacobian per step.
    let p = AllenCahn::new(true).unwrap();
    let h = 1e-5;
    let mut a = EcStepper::with_nodes(&p, 2, 2, h, solver(StageSolver::Newton)).unwrap();
    let mut b = EcStepper::with_nodes(&p, 2, 2, h, solver(StageSolver::SimplifiedNewton)).unwrap();
    let (mut ua, mut ub) = (p.initial_value(), p.initial_value());
    for n in 0..20 {
        let ra = a.step(&mut ua).unwrap();
        let rb = b.step(&mut ub).unwrap();
        assert_eq!(ra, rb, "step {n}");
        assert_eq!((ra.jacobian_evals, ra.newton_refreshes), (1, 0), "step {n}");
        assert_eq!(ua, ub, "step {n}");
    }
    // Fixed-point sweeps form no Jacobian.
    let mut c = EcStepper::with_nodes(&p, 2, 2, h, SolverSettings::default()).unwrap();
    let mut uc = p.initial_value();
    assert_eq!(c.step(&mut uc).unwrap().jacobian_evals, 0);
}
