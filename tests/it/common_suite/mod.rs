//! The problems of the adversarial suite (`tests/it/solve_suite.rs`, issues 25 and 42): each a
//! system, y₀, a span, output times and a reference at them accurate to ≤ 1e−13 relative. The
//! first eleven are here; those added for issue 42 are in [`odes`] and [`pdes`].
//!
//! References (see each case's `reference` and `tests/data/solve_suite_refs.json`):
//! * exact solutions in high precision (astro-float, [`PREC`] bits), computed in the test:
//!   Kepler (Kepler's equation, also at the close passage ending `kepler_passage`), the
//!   blow-up y' = −y + y², the bilinear oscillator, the heteroclinic orbit of the pendulum, the
//!   Duffing separatrix q = tanh 5t, the Bernoulli equation of the stiff nonlinearity;
//! * a Taylor-series integration in high precision of the polynomial vector fields (Lorenz,
//!   the pendulum with s = sin q, c = cos q as variables, the damped Duffing oscillator, the
//!   non-normal system, the FPU chain, the small NLS, Allen–Cahn, Hénon–Heiles, Mathieu with
//!   the forcing as variables, Lotka–Volterra, the rigid body, van der Pol, FitzHugh–Nagumo,
//!   sine-Gordon with sin and cos of each q as variables), stored;
//! * for the large NLS, two independent f64 integrations at tiny steps (EC8P and a peer from
//!   `ecr::baselines`), stored with their measured agreement.
#![allow(dead_code, clippy::needless_range_loop)]

use std::f64::consts::{LN_2, PI};

pub mod hp;
pub mod measure;
pub mod odes;
pub mod pdes;
pub mod stored;

use astro_float::BigFloat;
use ecr::problems::Nls;
use ecr::runtime::operator::{Circulant, Dense, LinearOperator, Scalar};
use ecr::runtime::second_order::{Omega, SecondOrder, SecondOrderForm, SecondOrderSystem};
use ecr::runtime::solve::{Options, Problem, Solution, SolveError};
use ecr::runtime::system::{Hamiltonian, Semilinear, System};
use nalgebra::DMatrix;

pub use hp::{Hp, PREC, TaylorRhs, to_f64};

/// The tolerances of the suite: rtol = atol = tol.
pub const TOLERANCES: [f64; 9] = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11];

/// A nonlinearity g (or a force, a gradient) as a function pointer.
type G = fn(&[f64], &mut [f64]);
/// An energy (or potential).
type E = fn(&[f64]) -> f64;

/// What a solve of a case returns (the solution without its system).
pub type Outcome = Result<Solution, SolveError>;

/// Where a case's reference comes from.
pub enum Reference {
    /// An exact solution, evaluated in high precision at any times (cheap: in the test).
    Exact(fn(&[f64]) -> Vec<Vec<f64>>),
    /// A Taylor-series integration in high precision of the polynomial vector field `rhs`
    /// from the state `x0` (y₀ extended by auxiliary variables: the reference is its first
    /// d components), stored in `tests/data/solve_suite_refs.json` ([`stored`]).
    Taylor {
        rhs: TaylorRhs,
        x0: fn(&mut Hp, &[f64]) -> Vec<BigFloat>,
    },
    /// Two independent f64 integrations at tiny steps (see [`stored::generate`]), stored.
    Runs,
}

/// One problem of the suite.
pub struct Case {
    /// Its name (the key of its stored reference).
    pub name: &'static str,
    /// The difficulty it exercises.
    pub class: &'static str,
    /// The equations and parameters in words: part of the hash of a stored reference.
    pub definition: String,
    pub y0: Vec<f64>,
    pub span: (f64, f64),
    /// Output times; `None`: output at every point the solve verifies.
    pub t_eval: Option<Vec<f64>>,
    pub reference: Reference,
    /// An accurate fixed run, ECrP (r, h): what the sensitivity to one ulp of y₀ is measured
    /// with (`tests/it/solve_suite.rs`, `one_ulp_of_y0_moves_the_sensitive_cases`).
    pub fine: (usize, f64),
    solver: fn(&Case, Request<'_>) -> Reply,
    /// The right-hand side Ay + g(y) of the f64 system.
    field: fn(&[f64]) -> Vec<f64>,
}

impl Case {
    /// Solves the case with `options` (its output times added).
    pub fn solve(&self, options: Options) -> Outcome {
        let options = match &self.t_eval {
            Some(ts) => options.t_eval(ts.clone()),
            None => options,
        };
        match (self.solver)(self, Request::Solve(&options)) {
            Reply::Solved(outcome) => outcome,
            #[cfg(feature = "baselines")]
            Reply::Peer(_) => unreachable!("a solve's request answered by the peer"),
        }
    }

    /// DOP853 (`ecr::baselines`, one call of `ode_solvers` as its users make it) with
    /// rtol = atol = `tol` over the case's span: its states at the case's output times from
    /// the crate's dense output at their common spacing (`None` where the output times have
    /// none, see [`peer_spacing`]), or at its accepted steps for a case without output times.
    #[cfg(feature = "baselines")]
    pub fn dop853(&self, tol: f64) -> Result<PeerRun, String> {
        match (self.solver)(self, Request::Dop853(tol)) {
            Reply::Peer(run) => run,
            Reply::Solved(_) => unreachable!("the peer's request answered by a solve"),
        }
    }

    /// Solves the case from `y0` instead of its own initial value (same system, span and
    /// output times).
    pub fn solve_from(&self, y0: Vec<f64>, options: Options) -> Outcome {
        let case = Case {
            name: self.name,
            class: self.class,
            definition: self.definition.clone(),
            y0,
            span: self.span,
            t_eval: self.t_eval.clone(),
            reference: Reference::Runs,
            fine: self.fine,
            solver: self.solver,
            field: self.field,
        };
        case.solve(options)
    }

    /// The right-hand side Ay + g(y) of the system.
    pub fn rhs(&self, y: &[f64]) -> Vec<f64> {
        (self.field)(y)
    }

    /// The fingerprint of what a stored reference depends on: name, definition, y₀ (to 13
    /// digits, so that a last-bit difference of libm's sin/cos between platforms does not
    /// count), span and output times (bits).
    pub fn hash(&self) -> String {
        let mut s = format!("{}|{}|", self.name, self.definition);
        for v in &self.y0 {
            s.push_str(&format!("{v:.13e},"));
        }
        s.push_str(&format!(
            "|{:016x}|{:016x}|",
            self.span.0.to_bits(),
            self.span.1.to_bits()
        ));
        for t in self.t_eval.iter().flatten() {
            s.push_str(&format!("{:016x},", t.to_bits()));
        }
        format!("{:016x}", fnv1a(s.as_bytes()))
    }
}

/// FNV-1a, 64 bits.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

fn field<S: System>(system: S, y: &[f64]) -> Vec<f64> {
    let mut f = vec![0.0; y.len()];
    system.linear().apply(y, &mut f);
    let mut g = vec![0.0; y.len()];
    let mut scratch = vec![0.0; system.scratch_len()];
    system.nonlinear(y, &mut g, &mut scratch);
    f.iter().zip(&g).map(|(a, b)| a + b).collect()
}

/// What a case's solver is asked to do: a solve, or (for the comparisons) a peer's run.
#[derive(Clone, Copy)]
pub enum Request<'a> {
    Solve(&'a Options),
    /// DOP853 with rtol = atol = the value.
    #[cfg(feature = "baselines")]
    Dop853(f64),
}

/// The answer to a [`Request`] (made once per solve: the size of a `Solution` by value is
/// no cost here).
#[allow(clippy::large_enum_variant)]
pub enum Reply {
    Solved(Outcome),
    #[cfg(feature = "baselines")]
    Peer(Result<PeerRun, String>),
}

/// A peer's run of a case: its states at its output times and its evaluations of the
/// right-hand side.
#[cfg(feature = "baselines")]
pub struct PeerRun {
    pub t: Vec<f64>,
    pub y: Vec<Vec<f64>>,
    pub f_evals: usize,
}

fn run<S: System>(system: S, case: &Case, request: Request<'_>) -> Reply {
    match request {
        Request::Solve(options) => Reply::Solved(
            Problem::new(system, case.y0.clone(), case.span)
                .map_err(SolveError::Failed)
                .and_then(|problem| problem.solve(options).map(Solution::into_data)),
        ),
        #[cfg(feature = "baselines")]
        Request::Dop853(tol) => Reply::Peer(dop853(system, case, tol)),
    }
}

/// The spacing dx of the output times `ts` from t0 (every t_k a multiple of dx from t0 to
/// within 1e−9 dx, the last at t_end): the largest of (t_1 − t0)/m over m = 1 … 64 that fits;
/// `None` if none does.
pub fn peer_spacing(t0: f64, t_end: f64, ts: &[f64]) -> Option<f64> {
    if *ts.last()? != t_end {
        return None;
    }
    let fits = |dx: f64| {
        ts.iter().all(|&t| {
            let k = ((t - t0) / dx).round();
            k >= 1.0 && ((t - t0) - k * dx).abs() <= 1e-9 * dx
        })
    };
    let smallest = smallest_gap(t0, ts);
    (1..=64)
        .map(|m| smallest / m as f64)
        .find(|&dx| dx > 0.0 && fits(dx))
}

/// The smallest of t_1 − t0 and the gaps between the output times `ts`.
fn smallest_gap(t0: f64, ts: &[f64]) -> f64 {
    ts.windows(2)
        .map(|w| w[1] - w[0])
        .fold(ts[0] - t0, f64::min)
}

#[cfg(feature = "baselines")]
fn dop853<S: System>(system: S, case: &Case, tol: f64) -> Result<PeerRun, String> {
    use ecr::baselines::dop853::Dop853;
    let (t0, t_end) = case.span;
    let peer = Dop853::new(system, tol, tol).map_err(|e| e.to_string())?;
    let mut y = case.y0.clone();
    match &case.t_eval {
        None => {
            let mut t = Vec::new();
            let mut ys = Vec::new();
            let stats = peer
                .integrate_observed(t0, t_end, &mut y, &mut |s, v| {
                    t.push(s);
                    ys.push(v.to_vec());
                })
                .map_err(|e| e.to_string())?;
            Ok(PeerRun {
                t,
                y: ys,
                f_evals: stats.f_evals,
            })
        }
        Some(ts) => {
            let spacing = peer_spacing(t0, t_end, ts);
            // Output times without a common spacing (kepler_passage's, just before t_end):
            // where the reference is exact at any time, the dense outputs at the smallest gap
            // dividing the span, over the stretch of the case's output times.
            let dx = match (spacing, &case.reference) {
                (Some(dx), _) => dx,
                (None, Reference::Exact(_)) => {
                    (t_end - t0) / ((t_end - t0) / smallest_gap(t0, ts)).ceil()
                }
                (None, _) => {
                    return Err(format!(
                        "{}: no common spacing of the output times",
                        case.name
                    ));
                }
            };
            let (out_t, out_y, stats) = peer
                .integrate_dense(t0, t_end, dx, &mut y)
                .map_err(|e| e.to_string())?;
            let (t, picked) = if spacing.is_some() {
                // The case's output times among the dense outputs (theirs, to within the
                // crate's accumulated rounding of t += dx).
                let mut picked = Vec::with_capacity(ts.len());
                for &t in ts {
                    let k = out_t
                        .iter()
                        .position(|&s| (s - t).abs() <= 1e-9 * dx)
                        .ok_or_else(|| format!("{}: no dense output at t = {t}", case.name))?;
                    picked.push(out_y[k].clone());
                }
                (ts.clone(), picked)
            } else {
                out_t
                    .into_iter()
                    .zip(out_y)
                    .filter(|(t, _)| *t >= ts[0] - dx)
                    .unzip()
            };
            Ok(PeerRun {
                t,
                y: picked,
                f_evals: stats.f_evals,
            })
        }
    }
}

/// Every case of the suite.
pub fn cases() -> Vec<Case> {
    vec![
        kepler(),
        lorenz(),
        pendulum(),
        blow_up(),
        nls_breather(),
        allen_cahn(),
        damped(),
        non_normal(),
        fpu(),
        nls_solitons(),
        bilinear(),
        odes::kepler_passage(),
        odes::lorenz_long(),
        odes::henon_heiles(),
        odes::pendulum_separatrix(),
        odes::duffing_separatrix(),
        odes::mathieu(),
        odes::lotka_volterra(),
        odes::rigid_body(),
        odes::van_der_pol(),
        odes::stiff_in_g(),
        pdes::fitzhugh_nagumo(),
        pdes::sine_gordon(),
    ]
}

// ---------------------------------------------------------------------------------------------
// (1) A late close passage: Kepler, e = 0.9375 (periapsis 0.032, speed there 7.7), from
// apoapsis (speed 0.25); the passage at t = 1.17 of the span [0, 1.6].

/// The speed at apoapsis (r = 1, μ = 1): a = 1/(2 − v²), e = 1 − v².
pub const KEPLER_V: f64 = 0.25;
pub const KEPLER_T_END: f64 = 1.6;

fn kepler_force(q: &[f64], f: &mut [f64]) {
    let r2 = q[0] * q[0] + q[1] * q[1];
    let r3 = r2 * r2.sqrt();
    f[0] = q[0] / r3;
    f[1] = q[1] / r3;
}

fn kepler_potential(q: &[f64]) -> f64 {
    -1.0 / q[0].hypot(q[1])
}

type So = SecondOrderForm<SecondOrder<G, E>>;

fn second_order(omega: Omega, force: G, potential: E) -> So {
    SecondOrderForm::new(SecondOrder::with_potential(omega, force, potential)).unwrap()
}

pub fn kepler_system() -> So {
    second_order(Omega::zero(2), kepler_force, kepler_potential)
}

fn kepler() -> Case {
    Case {
        name: "kepler",
        class: "late close passage",
        definition: format!("q'' = -q/|q|^3, q0 = (1, 0), p0 = (0, {KEPLER_V:?})"),
        y0: vec![1.0, 0.0, 0.0, KEPLER_V],
        span: (0.0, KEPLER_T_END),
        t_eval: None,
        reference: Reference::Exact(kepler_exact),
        fine: (8, 1.0 / 4096.0),
        solver: |c, o| run(kepler_system(), c, o),
        field: |y| field(kepler_system(), y),
    }
}

/// [`kepler_exact_hp`] in f64 (for the many outputs of a run without `t_eval`): the elements
/// rounded from their exact values, the mean anomaly reduced to [−π, π) in double-double,
/// Kepler's equation by Newton, and 1 − e cos E, cos E − e without cancellation near the
/// periapsis. Agrees with it to ≤ 1e−14 (test `exact_solutions_in_f64_match_high_precision`).
pub fn kepler_exact(ts: &[f64]) -> Vec<Vec<f64>> {
    let v = KEPLER_V;
    let v2 = v * v; // exact: v has few bits
    let a = 1.0 / (2.0 - v2);
    let e = 1.0 - v2; // exact
    // n = x√x, x = 2 − v² (exact), as hi + lo: the phase n t needs it beyond f64.
    let x = 2.0 - v2;
    let r = x.sqrt();
    let r_lo = (-r).mul_add(r, x) / (2.0 * r);
    let n = x * r;
    let n_lo = x.mul_add(r, -n) + x * r_lo;
    let b = a * (1.0 - e * e).sqrt();
    let (pi_hi, pi_lo) = (PI, 1.2246467991473532e-16);
    let two_sum = |x: f64, y: f64| {
        let s = x + y;
        let z = s - x;
        (s, (x - (s - z)) + (y - z))
    };
    ts.iter()
        .map(|&t| {
            // M = π + n t − 2πk = n t + (1 − 2k)π ∈ [−π, π), as hi + lo.
            let nt = n * t;
            let nt_err = n.mul_add(t, -nt) + n_lo * t;
            let j = 1.0 - 2.0 * ((nt + pi_hi) / (2.0 * pi_hi)).floor();
            let c = j * pi_hi;
            let c_err = j.mul_add(pi_hi, -c) + j * pi_lo;
            let (m, m_err) = two_sum(nt, c);
            let m_lo = m_err + nt_err + c_err;
            let mut ee = m + 0.85 * e * m.sin().signum();
            for _ in 0..100 {
                let d = (ee - e * ee.sin() - m) / (1.0 - e * ee.cos());
                ee -= d;
                if d.abs() < 1e-15 {
                    break;
                }
            }
            let (s, c) = ee.sin_cos();
            let half = (0.5 * ee).sin();
            let one_minus_cos = 2.0 * half * half;
            let den = v2 + e * one_minus_cos; // 1 − e cos E
            let f = ((ee - m) - e * s) - m_lo;
            ee -= f / den;
            let (s, c) = if f == 0.0 { (s, c) } else { ee.sin_cos() };
            let half = (0.5 * ee).sin();
            let one_minus_cos = 2.0 * half * half;
            let den = v2 + e * one_minus_cos;
            vec![
                -a * (v2 - one_minus_cos), // −a(cos E − e)
                -b * s,
                a * n * s / den,
                -b * n * c / den,
            ]
        })
        .collect()
}

/// The orbit through (1, 0) with velocity (0, v) (apoapsis) in high precision: the eccentric
/// anomaly E from Kepler's equation E − e sin E = π + n t (Newton in f64, then in high
/// precision), with a = 1/(2 − v²), e = 1 − v², n = a^{−3/2}, b = a√(1 − e²).
pub fn kepler_exact_hp(ts: &[f64]) -> Vec<Vec<f64>> {
    let mut hp = Hp::new(PREC);
    let v = hp.f(KEPLER_V);
    let one = hp.f(1.0);
    let v2 = hp.mul(&v, &v);
    let a = hp.div(&one, &hp.sub(&hp.f(2.0), &v2));
    let e = hp.sub(&one, &v2);
    let n = {
        let inv = hp.div(&one, &a);
        hp.mul(&inv, &hp.sqrt(&inv))
    };
    let b = hp.mul(&a, &hp.sqrt(&hp.sub(&one, &hp.mul(&e, &e))));
    let pi = hp.pi();
    let two_pi = hp.mul(&hp.f(2.0), &pi);
    let ef = to_f64(&e);
    ts.iter()
        .map(|&t| {
            // M = π + n t, reduced to [0, 2π).
            let m = hp.add(&pi, &hp.mul(&n, &hp.f(t)));
            let k = hp.floor(&hp.div(&m, &two_pi));
            let m = hp.sub(&m, &hp.mul(&k, &two_pi));
            let mf = to_f64(&m);
            let mut ee = mf + 0.85 * ef * mf.sin().signum();
            for _ in 0..100 {
                let d = (ee - ef * ee.sin() - mf) / (1.0 - ef * ee.cos());
                ee -= d;
                if d.abs() < 1e-15 {
                    break;
                }
            }
            let mut eb = hp.f(ee);
            for _ in 0..4 {
                let (s, c) = (hp.sin(&eb), hp.cos(&eb));
                let f = hp.sub(&hp.sub(&eb, &hp.mul(&e, &s)), &m);
                let fp = hp.sub(&one, &hp.mul(&e, &c));
                eb = hp.sub(&eb, &hp.div(&f, &fp));
            }
            let (s, c) = (hp.sin(&eb), hp.cos(&eb));
            let den = hp.sub(&one, &hp.mul(&e, &c));
            let q1 = hp.neg(&hp.mul(&a, &hp.sub(&c, &e)));
            let q2 = hp.neg(&hp.mul(&b, &s));
            let p1 = hp.div(&hp.mul(&hp.mul(&a, &n), &s), &den);
            let p2 = hp.neg(&hp.div(&hp.mul(&hp.mul(&b, &n), &c), &den));
            vec![to_f64(&q1), to_f64(&q2), to_f64(&p1), to_f64(&p2)]
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// (2) Chaos over a long span: Lorenz.

pub const LORENZ: (f64, f64, f64) = (10.0, 28.0, 8.0 / 3.0);
pub const LORENZ_T_END: f64 = 12.0;

fn lorenz_g(y: &[f64], g: &mut [f64]) {
    g[0] = 0.0;
    g[1] = -y[0] * y[2];
    g[2] = y[0] * y[1];
}

pub fn lorenz_system() -> Semilinear<Dense, G> {
    let (s, r, b) = LORENZ;
    let a = DMatrix::from_row_slice(3, 3, &[-s, s, 0.0, r, -1.0, 0.0, 0.0, 0.0, -b]);
    Semilinear::new(Dense::new(a).unwrap(), lorenz_g)
}

fn lorenz() -> Case {
    let (s, r, b) = LORENZ;
    Case {
        name: "lorenz",
        class: "chaos",
        definition: format!(
            "x' = s(y - x), y' = r x - y - x z, z' = x y - b z; s = {s:?}, r = {r:?}, b = {b:?}"
        ),
        y0: vec![-8.0, 8.0, 27.0],
        span: (0.0, LORENZ_T_END),
        t_eval: Some((1..=12).map(|i| i as f64).collect()),
        reference: Reference::Taylor {
            rhs: lorenz_taylor,
            x0: exact_x0,
        },
        fine: (8, 1.0 / 512.0),
        solver: |c, o| run(lorenz_system(), c, o),
        field: |y| field(lorenz_system(), y),
    }
}

/// Lorenz: the k-th Taylor coefficient of the right-hand side.
pub fn lorenz_taylor(
    hp: &Hp,
    x: &[Vec<BigFloat>],
    _aux: &mut Vec<Vec<BigFloat>>,
    k: usize,
) -> Vec<BigFloat> {
    let (s, r, b) = LORENZ;
    let (s, r, b) = (hp.f(s), hp.f(r), hp.f(b));
    let xz = hp.cauchy(&x[0], &x[2], k);
    let xy = hp.cauchy(&x[0], &x[1], k);
    vec![
        hp.mul(&s, &hp.sub(&x[1][k], &x[0][k])),
        hp.sub(&hp.sub(&hp.mul(&r, &x[0][k]), &x[1][k]), &xz),
        hp.sub(&xy, &hp.mul(&b, &x[2][k])),
    ]
}

// ---------------------------------------------------------------------------------------------
// (3) Next to a separatrix: the pendulum from just below the top.

pub const PENDULUM_DELTA: f64 = 1e-3;
pub const PENDULUM_T_END: f64 = 40.0;

fn pendulum_force(q: &[f64], f: &mut [f64]) {
    f[0] = q[0].sin();
}

fn pendulum_potential(q: &[f64]) -> f64 {
    1.0 - q[0].cos()
}

pub fn pendulum_system() -> So {
    second_order(Omega::zero(1), pendulum_force, pendulum_potential)
}

fn pendulum() -> Case {
    Case {
        name: "pendulum",
        class: "separatrix",
        definition: "q'' = -sin q, q0 = pi - delta (f64), p0 = 0".into(),
        y0: vec![PI - PENDULUM_DELTA, 0.0],
        span: (0.0, PENDULUM_T_END),
        t_eval: Some((1..=10).map(|i| 4.0 * i as f64).collect()),
        reference: Reference::Taylor {
            rhs: pendulum_taylor,
            x0: pendulum_x0,
        },
        fine: (8, 1.0 / 64.0),
        solver: |c, o| run(pendulum_system(), c, o),
        field: |y| field(pendulum_system(), y),
    }
}

/// y₀ converted exactly.
pub fn exact_x0(hp: &mut Hp, y0: &[f64]) -> Vec<BigFloat> {
    y0.iter().map(|&v| hp.f(v)).collect()
}

/// (q₀, p₀, sin q₀, cos q₀).
pub fn pendulum_x0(hp: &mut Hp, y0: &[f64]) -> Vec<BigFloat> {
    let q = hp.f(y0[0]);
    let (s, c) = (hp.sin(&q), hp.cos(&q));
    vec![q, hp.f(y0[1]), s, c]
}

/// The pendulum as (q, p, s, c), s = sin q, c = cos q: q' = p, p' = −s, s' = c p, c' = −s p.
pub fn pendulum_taylor(
    hp: &Hp,
    x: &[Vec<BigFloat>],
    _aux: &mut Vec<Vec<BigFloat>>,
    k: usize,
) -> Vec<BigFloat> {
    vec![
        x[1][k].clone(),
        hp.neg(&x[2][k]),
        hp.cauchy(&x[3], &x[1], k),
        hp.neg(&hp.cauchy(&x[2], &x[1], k)),
    ]
}

// ---------------------------------------------------------------------------------------------
// (4) Toward a finite-time singularity: y' = −y + y², y(0) = 2, y = 2/(2 − eᵗ), blow-up at ln 2.

/// The distances to the blow-up of the output times (the last is the end of the span).
pub const BLOW_UP_GAPS: [f64; 8] = [0.4, 0.2, 0.1, 0.05, 0.02, 0.01, 0.005, 0.002];

fn blow_up_g(y: &[f64], g: &mut [f64]) {
    g[0] = y[0] * y[0];
}

pub fn blow_up_system() -> Semilinear<Scalar, G> {
    Semilinear::new(Scalar::new(-1.0, 1).unwrap(), blow_up_g)
}

fn blow_up() -> Case {
    let ts: Vec<f64> = BLOW_UP_GAPS.iter().map(|g| LN_2 - g).collect();
    Case {
        name: "blow_up",
        class: "finite-time singularity",
        definition: "y' = -y + y^2, y0 = 2".into(),
        y0: vec![2.0],
        span: (0.0, *ts.last().unwrap()),
        t_eval: Some(ts),
        reference: Reference::Exact(blow_up_exact),
        fine: (8, 1.0 / 131072.0),
        solver: |c, o| run(blow_up_system(), c, o),
        field: |y| field(blow_up_system(), y),
    }
}

pub fn blow_up_exact(ts: &[f64]) -> Vec<Vec<f64>> {
    let mut hp = Hp::new(PREC);
    ts.iter()
        .map(|&t| {
            let two = hp.f(2.0);
            let et = hp.exp(&hp.f(t));
            vec![to_f64(&hp.div(&two, &hp.sub(&two, &et)))]
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// (4') NLS whose error grows late: the paper's NLS (modulational instability, breathers).

pub const NLS_BREATHER_N: usize = 16;
pub const NLS_BREATHER_T_END: f64 = 20.0;

fn nls_breather() -> Case {
    let nls = Nls::new(NLS_BREATHER_N).unwrap();
    Case {
        name: "nls_breather",
        class: "late error growth (NLS)",
        definition: format!(
            "paper NLS i psi_t + psi_xx + 2|psi|^2 psi = 0, N = {NLS_BREATHER_N}, \
             psi0 = 0.5 + 0.025 cos(mu x)"
        ),
        y0: nls.initial_value(),
        span: (0.0, NLS_BREATHER_T_END),
        t_eval: Some((1..=10).map(|i| 2.0 * i as f64).collect()),
        reference: Reference::Taylor {
            rhs: nls_taylor,
            x0: exact_x0,
        },
        fine: (8, 1.0 / 64.0),
        solver: |c, o| run(Nls::new(NLS_BREATHER_N).unwrap().system().unwrap(), c, o),
        field: |y| field(Nls::new(NLS_BREATHER_N).unwrap().system().unwrap(), y),
    }
}

/// The NLS of N = [`NLS_BREATHER_N`] in y = (p, q): p' = −D₂q − 2(p² + q²)q,
/// q' = D₂p + 2(p² + q²)p, D₂ the circulant of the f64 column of [`Nls::d2_first_column`].
pub fn nls_taylor(
    hp: &Hp,
    x: &[Vec<BigFloat>],
    aux: &mut Vec<Vec<BigFloat>>,
    k: usize,
) -> Vec<BigFloat> {
    let n = x.len() / 2;
    let column: Vec<BigFloat> = Nls::new(n)
        .unwrap()
        .d2_first_column()
        .iter()
        .map(|&c| hp.f(c))
        .collect();
    // aux[i] = p_i² + q_i².
    if aux.is_empty() {
        aux.resize(n, Vec::new());
    }
    for i in 0..n {
        let s = hp.add(
            &hp.cauchy(&x[i], &x[i], k),
            &hp.cauchy(&x[n + i], &x[n + i], k),
        );
        aux[i].push(s);
    }
    let two = hp.f(2.0);
    let mut f = vec![hp.f(0.0); 2 * n];
    for i in 0..n {
        let (mut dp, mut dq) = (hp.f(0.0), hp.f(0.0));
        for j in 0..n {
            let c = &column[(i + n - j) % n];
            dp = hp.add(&dp, &hp.mul(c, &x[j][k]));
            dq = hp.add(&dq, &hp.mul(c, &x[n + j][k]));
        }
        let sq = hp.mul(&two, &hp.cauchy(&aux[i], &x[n + i], k));
        let sp = hp.mul(&two, &hp.cauchy(&aux[i], &x[i], k));
        f[i] = hp.neg(&hp.add(&dq, &sq));
        f[n + i] = hp.add(&dp, &sp);
    }
    f
}

// ---------------------------------------------------------------------------------------------
// (5) Stiff: Allen–Cahn (a gradient flow) on a periodic lattice of N points,
// u_j' = κ(u_{j+1} − 2u_j + u_{j−1}) + u_j − u_j³ (the finite-difference u_t = ν u_xx + u − u³
// with κ = ν/Δx²): A = −κL has eigenvalues 0 … −4κ = −1024 against an O(1) nonlinearity, and
// rough data (modes up to 60) make a stiff initial layer; afterwards the one unstable mode
// (k = 1, rate 0.38) grows into a pair of interfaces.

pub const AC_N: usize = 128;
pub const AC_KAPPA: f64 = 256.0;
pub const AC_T_END: f64 = 4.0;

/// The first column of A = −κL, L the periodic second difference with 2 on the diagonal
/// (exact entries; the solve applies it by FFT).
pub fn ac_column() -> Vec<f64> {
    let mut c = vec![0.0; AC_N];
    c[0] = -2.0 * AC_KAPPA;
    c[1] = AC_KAPPA;
    c[AC_N - 1] = AC_KAPPA;
    c
}

fn ac_g(u: &[f64], g: &mut [f64]) {
    for (g, u) in g.iter_mut().zip(u) {
        *g = u - u * u * u;
    }
}

/// The Lyapunov function ½κ Σ(u_{j+1} − u_j)² + Σ(u_j⁴/4 − u_j²/2).
fn ac_energy(u: &[f64]) -> f64 {
    let n = u.len();
    (0..n)
        .map(|j| {
            let d = u[(j + 1) % n] - u[j];
            0.5 * AC_KAPPA * d * d + 0.25 * u[j].powi(4) - 0.5 * u[j] * u[j]
        })
        .sum()
}

pub fn allen_cahn_system() -> Semilinear<Circulant, G, E> {
    Semilinear::with_energy(
        Circulant::new(ac_column()).unwrap(),
        ac_g as _,
        ac_energy as _,
    )
}

/// A smooth part and "noise": modes 5..60 with amplitude 0.1/k^½ and fixed phases.
pub fn ac_initial_value() -> Vec<f64> {
    (0..AC_N)
        .map(|j| {
            let x = 2.0 * PI * j as f64 / AC_N as f64;
            let mut u = 0.5 * x.sin() + 0.3 * (2.0 * x + 1.0).cos();
            for k in 5..=60 {
                let phase = 0.7 * (k * k) as f64;
                u += 0.1 / (k as f64).sqrt() * (k as f64 * x + phase).cos();
            }
            u
        })
        .collect()
}

fn allen_cahn() -> Case {
    Case {
        name: "allen_cahn",
        class: "stiff",
        definition: format!(
            "u_j' = kappa (u_j+1 - 2 u_j + u_j-1) + u_j - u_j^3, periodic, N = {AC_N}, \
             kappa = {AC_KAPPA:?}, u0 = 0.5 sin x + 0.3 cos(2x + 1) + sum_k=5..60 0.1/sqrt(k) \
             cos(k x + 0.7 k^2), x = 2 pi j/N"
        ),
        y0: ac_initial_value(),
        span: (0.0, AC_T_END),
        t_eval: Some(vec![0.0625, 0.125, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0]),
        reference: Reference::Taylor {
            rhs: ac_taylor,
            x0: exact_x0,
        },
        fine: (8, 1.0 / 256.0),
        solver: |c, o| run(allen_cahn_system(), c, o),
        field: |y| field(allen_cahn_system(), y),
    }
}

pub fn ac_taylor(
    hp: &Hp,
    x: &[Vec<BigFloat>],
    aux: &mut Vec<Vec<BigFloat>>,
    k: usize,
) -> Vec<BigFloat> {
    let n = x.len();
    // aux[i] = u_i².
    if aux.is_empty() {
        aux.resize(n, Vec::new());
    }
    for i in 0..n {
        let sq = hp.cauchy(&x[i], &x[i], k);
        aux[i].push(sq);
    }
    let kappa = hp.f(AC_KAPPA);
    (0..n)
        .map(|i| {
            let (l, r) = (&x[(i + n - 1) % n][k], &x[(i + 1) % n][k]);
            let lap = hp.sub(&hp.add(l, r), &hp.mul(&hp.f(2.0), &x[i][k]));
            let cube = hp.cauchy(&aux[i], &x[i], k);
            hp.add(&hp.mul(&kappa, &lap), &hp.sub(&x[i][k], &cube))
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// (6) Dissipative: the damped hard-spring oscillator q'' + 2ζq' + q + q³ = 0.

pub const DAMPED_ZETA: f64 = 0.05;
pub const DAMPED_T_END: f64 = 30.0;

fn damped_grad_v(y: &[f64], g: &mut [f64]) {
    g[0] = y[0] * y[0] * y[0];
}

fn damped_v(y: &[f64]) -> f64 {
    0.25 * y[0].powi(4)
}

pub fn damped_system() -> Hamiltonian<G, E> {
    // y' = Q∇H, Q = [[0, 1], [−1, −2ζ]] (negative semidefinite), H = ½(q² + p²) + ¼q⁴.
    let q = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -1.0, -2.0 * DAMPED_ZETA]);
    Hamiltonian::with_potential(
        q,
        DMatrix::identity(2, 2),
        damped_grad_v as _,
        damped_v as _,
    )
    .unwrap()
}

fn damped() -> Case {
    Case {
        name: "damped",
        class: "dissipative",
        definition: format!(
            "q'' + 2 zeta q' + q + q^3 = 0, zeta = {DAMPED_ZETA:?}, q0 = 4, p0 = 0"
        ),
        y0: vec![4.0, 0.0],
        span: (0.0, DAMPED_T_END),
        t_eval: Some((1..=15).map(|i| 2.0 * i as f64).collect()),
        reference: Reference::Taylor {
            rhs: damped_taylor,
            x0: exact_x0,
        },
        fine: (8, 1.0 / 64.0),
        solver: |c, o| run(damped_system(), c, o),
        field: |y| field(damped_system(), y),
    }
}

pub fn damped_taylor(
    hp: &Hp,
    x: &[Vec<BigFloat>],
    aux: &mut Vec<Vec<BigFloat>>,
    k: usize,
) -> Vec<BigFloat> {
    if aux.is_empty() {
        aux.push(Vec::new());
    }
    aux[0].push(hp.cauchy(&x[0], &x[0], k)); // q²
    let q3 = hp.cauchy(&aux[0], &x[0], k);
    let two_zeta = hp.f(2.0 * DAMPED_ZETA);
    vec![
        x[1][k].clone(),
        hp.neg(&hp.add(&hp.add(&x[0][k], &hp.mul(&two_zeta, &x[1][k])), &q3)),
    ]
}

// ---------------------------------------------------------------------------------------------
// (7) Non-normal linear part: A = −αI + νN (N the shift, d = 5), transient growth ~800 (all
// eigenvalues −α), and a componentwise cubic damping −κu³ that is strong at the peak.

pub const NN_D: usize = 5;
pub const NN_ALPHA: f64 = 0.5;
pub const NN_NU: f64 = 4.0;
pub const NN_KAPPA: f64 = 1e-3;
pub const NN_T_END: f64 = 30.0;

pub fn nn_matrix() -> DMatrix<f64> {
    let mut a = DMatrix::zeros(NN_D, NN_D);
    for i in 0..NN_D {
        a[(i, i)] = -NN_ALPHA;
        if i + 1 < NN_D {
            a[(i, i + 1)] = NN_NU;
        }
    }
    a
}

/// −κu³ (componentwise).
fn nn_g(u: &[f64], g: &mut [f64]) {
    for (g, u) in g.iter_mut().zip(u) {
        *g = -NN_KAPPA * u * u * u;
    }
}

pub fn non_normal_system() -> Semilinear<Dense, G> {
    Semilinear::new(Dense::new(nn_matrix()).unwrap(), nn_g)
}

fn non_normal() -> Case {
    let mut y0 = vec![0.0; NN_D];
    y0[NN_D - 1] = 1.0;
    Case {
        name: "non_normal",
        class: "non-normal",
        definition: format!(
            "u' = (-alpha I + nu N) u - kappa u^3 (componentwise), d = {NN_D}, alpha = {NN_ALPHA:?}, \
             nu = {NN_NU:?}, kappa = {NN_KAPPA:?}, N the upper shift, u0 = e_d"
        ),
        y0,
        span: (0.0, NN_T_END),
        t_eval: Some((1..=15).map(|i| 2.0 * i as f64).collect()),
        reference: Reference::Taylor {
            rhs: non_normal_taylor,
            x0: exact_x0,
        },
        fine: (8, 1.0 / 64.0),
        solver: |c, o| run(non_normal_system(), c, o),
        field: |y| field(non_normal_system(), y),
    }
}

pub fn non_normal_taylor(
    hp: &Hp,
    x: &[Vec<BigFloat>],
    aux: &mut Vec<Vec<BigFloat>>,
    k: usize,
) -> Vec<BigFloat> {
    let d = x.len();
    // aux[i] = u_i².
    if aux.is_empty() {
        aux.resize(d, Vec::new());
    }
    for i in 0..d {
        let sq = hp.cauchy(&x[i], &x[i], k);
        aux[i].push(sq);
    }
    let (alpha, nu, kappa) = (hp.f(NN_ALPHA), hp.f(NN_NU), hp.f(NN_KAPPA));
    (0..d)
        .map(|i| {
            let mut f = hp.neg(&hp.mul(&alpha, &x[i][k]));
            if i + 1 < d {
                f = hp.add(&f, &hp.mul(&nu, &x[i + 1][k]));
            }
            hp.sub(&f, &hp.mul(&kappa, &hp.cauchy(&aux[i], &x[i], k)))
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// (8) Second order: the FPU chain with stiff springs (GNI §I.5.1), q'' + Ωq = −∇U.

pub const FPU_M: usize = 3;
pub const FPU_OMEGA: f64 = 30.0;
pub const FPU_T_END: f64 = 10.0;

pub fn fpu_system() -> SecondOrderForm<impl SecondOrderSystem> {
    let fpu = ecr::problems::Fpu::new(FPU_M, FPU_OMEGA).unwrap();
    SecondOrderForm::new(fpu.system().unwrap()).unwrap()
}

fn fpu() -> Case {
    let fpu = ecr::problems::Fpu::new(FPU_M, FPU_OMEGA).unwrap();
    Case {
        name: "fpu",
        class: "second order",
        definition: format!(
            "FPU with stiff springs (GNI I.5.1), m = {FPU_M}, omega = {FPU_OMEGA:?}, GNI's y0"
        ),
        y0: fpu.initial_value_first_order(),
        span: (0.0, FPU_T_END),
        t_eval: Some((1..=10).map(|i| i as f64).collect()),
        reference: Reference::Taylor {
            rhs: fpu_taylor,
            x0: exact_x0,
        },
        fine: (8, 1.0 / 256.0),
        solver: |c, o| run(fpu_system(), c, o),
        field: |y| field(fpu_system(), y),
    }
}

/// FPU in y = (q, p): q' = p, p' = −Ωq − ∇U(q), ∇U from the cubes of the soft elongations
/// s_k = (x0_{k} − x1_{k}) − (x0_{k−1} + x1_{k−1}) (0-based; terms outside the chain are 0).
pub fn fpu_taylor(
    hp: &Hp,
    x: &[Vec<BigFloat>],
    aux: &mut Vec<Vec<BigFloat>>,
    k: usize,
) -> Vec<BigFloat> {
    let m = FPU_M;
    // aux[0..=m]: s_k; aux[m+1..=2m+1]: s_k².
    if aux.is_empty() {
        aux.resize(2 * (m + 1), Vec::new());
    }
    for j in 0..=m {
        let mut s = hp.f(0.0);
        if j < m {
            s = hp.add(&s, &hp.sub(&x[j][k], &x[m + j][k]));
        }
        if j > 0 {
            s = hp.sub(&s, &hp.add(&x[j - 1][k], &x[m + j - 1][k]));
        }
        aux[j].push(s);
    }
    for j in 0..=m {
        let sq = hp.cauchy(&aux[j], &aux[j], k);
        aux[m + 1 + j].push(sq);
    }
    let sigma: Vec<BigFloat> = (0..=m)
        .map(|j| hp.cauchy(&aux[m + 1 + j], &aux[j], k))
        .collect();
    let w2 = hp.f(FPU_OMEGA * FPU_OMEGA);
    let n = 2 * m;
    let mut f = Vec::with_capacity(2 * n);
    for i in 0..n {
        f.push(x[n + i][k].clone());
    }
    for i in 0..m {
        // ∂U/∂x0_i = σ_i − σ_{i+1}, ∂U/∂x1_i = −σ_i − σ_{i+1}; Ω = diag(0, ω²).
        f.push(hp.neg(&hp.sub(&sigma[i], &sigma[i + 1])));
    }
    for i in 0..m {
        let grad = hp.neg(&hp.add(&sigma[i], &sigma[i + 1]));
        f.push(hp.neg(&hp.add(&hp.mul(&w2, &x[m + i][k]), &grad)));
    }
    f
}

// ---------------------------------------------------------------------------------------------
// (9) Large d: two colliding NLS solitons, N = 256 (d = 512).

pub const NLS_SOLITONS_N: usize = 256;
pub const NLS_SOLITONS_T_END: f64 = 4.0;

/// ψ₀ = Σ_images [sech(η(x − L/4)) e^{ivx} + sech(η(x − 3L/4)) e^{−ivx}], η = 1.5, v = 2μ
/// (periodic: v is a wavenumber of the grid), as y = (Re ψ, Im ψ).
pub fn nls_solitons_initial_value() -> Vec<f64> {
    let n = NLS_SOLITONS_N;
    let l = Nls::LENGTH;
    let (eta, v) = (1.5, 2.0 * Nls::MU);
    let mut y = vec![0.0; 2 * n];
    for j in 0..n {
        let x = l * j as f64 / n as f64;
        let (mut re, mut im) = (0.0, 0.0);
        for img in -3..=3 {
            let shift = img as f64 * l;
            let a = 1.0 / (eta * (x - 0.25 * l - shift)).cosh();
            let b = 1.0 / (eta * (x - 0.75 * l - shift)).cosh();
            re += (a + b) * (v * x).cos();
            im += (a - b) * (v * x).sin();
        }
        y[j] = re;
        y[n + j] = im;
    }
    y
}

fn nls_solitons() -> Case {
    Case {
        name: "nls_solitons",
        class: "large d",
        definition: format!(
            "paper NLS, N = {NLS_SOLITONS_N}, two periodised sech solitons eta = 1.5, \
             v = +-2 mu at L/4, 3L/4"
        ),
        y0: nls_solitons_initial_value(),
        span: (0.0, NLS_SOLITONS_T_END),
        t_eval: Some((1..=8).map(|i| 0.5 * i as f64).collect()),
        reference: Reference::Runs,
        fine: (8, 1.0 / 512.0),
        solver: |c, o| run(Nls::new(NLS_SOLITONS_N).unwrap().system().unwrap(), c, o),
        field: |y| field(Nls::new(NLS_SOLITONS_N).unwrap().system().unwrap(), y),
    }
}

// ---------------------------------------------------------------------------------------------
// (10) Non-smooth: the bilinear oscillator q'' = −ω₊²q (q > 0), −ω₋²q (q < 0).

pub const BILINEAR_W: (f64, f64) = (1.0, 3.0);
pub const BILINEAR_T_END: f64 = 20.0;

fn bilinear_force(q: &[f64], f: &mut [f64]) {
    let (wp, wm) = BILINEAR_W;
    f[0] = (wm * wm - wp * wp) * q[0].min(0.0);
}

fn bilinear_potential(q: &[f64]) -> f64 {
    let (wp, wm) = BILINEAR_W;
    0.5 * (wm * wm - wp * wp) * q[0].min(0.0).powi(2)
}

pub fn bilinear_system() -> So {
    let (wp, _) = BILINEAR_W;
    second_order(
        Omega::scalar(wp * wp, 1).unwrap(),
        bilinear_force,
        bilinear_potential,
    )
}

fn bilinear() -> Case {
    Case {
        name: "bilinear",
        class: "non-smooth",
        definition: "q'' = -w+^2 q (q > 0), -w-^2 q (q < 0), q0 = 1, p0 = 0".into(),
        y0: vec![1.0, 0.0],
        span: (0.0, BILINEAR_T_END),
        t_eval: None,
        reference: Reference::Exact(bilinear_exact),
        fine: (8, 1.0 / 1024.0),
        solver: |c, o| run(bilinear_system(), c, o),
        field: |y| field(bilinear_system(), y),
    }
}

/// [`bilinear_exact_hp`] in f64 (for the many outputs of a run without `t_eval`): the phase
/// t mod T reduced with T as two doubles. Agrees with it to ≤ 1e−14 (test
/// `exact_solutions_in_f64_match_high_precision`).
pub fn bilinear_exact(ts: &[f64]) -> Vec<Vec<f64>> {
    let (wp, wm) = BILINEAR_W;
    // The quarter period π/(2ω₊), the time below 0 π/ω₋ and the period, as (hi, lo), from
    // π = PI + 1.2246467991473532e−16 (ω± are small integers: the divisions are exact to
    // within the rounding of the hi parts, whose error goes into lo).
    let pi_lo = 1.2246467991473532e-16;
    let split = |num_hi: f64, num_lo: f64, den: f64| {
        let hi = num_hi / den;
        let lo = ((-hi).mul_add(den, num_hi) + num_lo) / den;
        (hi, lo)
    };
    let quarter = split(PI, pi_lo, 2.0 * wp);
    let below = split(PI, pi_lo, wm);
    let period = (2.0 * quarter.0 + below.0, 2.0 * quarter.1 + below.1);
    ts.iter()
        .map(|&t| {
            let k = (t / period.0).floor();
            let mut phi = (-k).mul_add(period.0, t) - k * period.1;
            let mut k = k;
            if phi < 0.0 {
                k -= 1.0;
                phi = (-k).mul_add(period.0, t) - k * period.1;
            }
            let q_end = quarter.0 + quarter.1;
            if phi <= q_end {
                let (s, c) = (wp * phi).sin_cos();
                vec![c, -wp * s]
            } else if phi <= q_end + below.0 + below.1 {
                let x = wm * ((phi - quarter.0) - quarter.1);
                let (s, c) = x.sin_cos();
                vec![-(wp / wm) * s, -wp * c]
            } else {
                let x = wp * ((((phi - quarter.0) - below.0) - quarter.1) - below.1);
                let (s, c) = x.sin_cos();
                vec![s, wp * c]
            }
        })
        .collect()
}

/// From q = 1, p = 0: a quarter period of cos(ω₊t), a half period of the ω₋ oscillation
/// below 0 (amplitude ω₊/ω₋), a quarter period of sin(ω₊t) back to q = 1; in high precision.
pub fn bilinear_exact_hp(ts: &[f64]) -> Vec<Vec<f64>> {
    let mut hp = Hp::new(PREC);
    let (wp, wm) = (hp.f(BILINEAR_W.0), hp.f(BILINEAR_W.1));
    let pi = hp.pi();
    let quarter = hp.div(&hp.div(&pi, &wp), &hp.f(2.0));
    let below = hp.div(&pi, &wm);
    let period = hp.add(&hp.add(&quarter, &quarter), &below);
    ts.iter()
        .map(|&t| {
            let t = hp.f(t);
            let k = hp.floor(&hp.div(&t, &period));
            let phi = hp.sub(&t, &hp.mul(&k, &period));
            let (q, p);
            if phi.cmp(&quarter).is_some_and(|c| c <= 0) {
                let x = hp.mul(&wp, &phi);
                let (s, c) = (hp.sin(&x), hp.cos(&x));
                q = c;
                p = hp.neg(&hp.mul(&wp, &s));
            } else if phi.cmp(&hp.add(&quarter, &below)).is_some_and(|c| c <= 0) {
                let x = hp.mul(&wm, &hp.sub(&phi, &quarter));
                let (s, c) = (hp.sin(&x), hp.cos(&x));
                q = hp.neg(&hp.mul(&hp.div(&wp, &wm), &s));
                p = hp.neg(&hp.mul(&wp, &c));
            } else {
                let x = hp.mul(&wp, &hp.sub(&phi, &hp.add(&quarter, &below)));
                let (s, c) = (hp.sin(&x), hp.cos(&x));
                q = s;
                p = hp.mul(&wp, &c);
            }
            vec![to_f64(&q), to_f64(&p)]
        })
        .collect()
}
