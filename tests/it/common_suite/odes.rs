//! The ordinary differential equations added to the suite for issue 42: a close passage at
//! the end of the span, chaos over long spans, orbits on a separatrix, parametric resonance,
//! predator–prey, a free rigid body, a relaxation oscillator and stiffness in g.

use std::f64::consts::PI;

use astro_float::BigFloat;
use ecr::problems::{Duffing, HenonHeiles};
use ecr::runtime::operator::{Dense, Diagonal, Scalar, Zero};
use ecr::runtime::system::Semilinear;
use nalgebra::DMatrix;

use super::{
    Case, E, G, Hp, KEPLER_V, PREC, Reference, exact_x0, field, kepler_exact_hp, kepler_system,
    lorenz_system, lorenz_taylor, pendulum_system, run, to_f64,
};

// ---------------------------------------------------------------------------------------------
// (12) The end of the span on a close passage: the orbit of `kepler` (e = 0.9375, from
// apoapsis), to its KEPLER_PASSAGE-th periapsis, output at three times just before it and at
// it. There the speed is 7.7 and the acceleration 1000: a phase error δt moves p by 1000 δt.

/// Which periapsis passage ends the span (1 = the first, at half a period).
pub const KEPLER_PASSAGE: usize = 12;

/// The time of the k-th periapsis passage from apoapsis, (2k − 1)π/n, n = (2 − v²)^{3/2},
/// rounded to f64 (the exact solution is evaluated at this f64 time).
pub fn kepler_passage_time(k: usize) -> f64 {
    let x = 2.0 - KEPLER_V * KEPLER_V;
    (2 * k - 1) as f64 * PI / (x * x.sqrt())
}

pub fn kepler_passage() -> Case {
    let t_end = kepler_passage_time(KEPLER_PASSAGE);
    Case {
        name: "kepler_passage",
        class: "close passage at t_end",
        definition: format!(
            "q'' = -q/|q|^3, q0 = (1, 0), p0 = (0, {KEPLER_V:?}), to periapsis passage \
             {KEPLER_PASSAGE}"
        ),
        y0: vec![1.0, 0.0, 0.0, KEPLER_V],
        span: (0.0, t_end),
        t_eval: Some(vec![t_end - 0.02, t_end - 0.01, t_end - 0.005, t_end]),
        reference: Reference::Exact(kepler_exact_hp),
        fine: (8, 1.0 / 4096.0),
        solver: |c, o| run(kepler_system(), c, o),
        field: |y| field(kepler_system(), y),
    }
}

// ---------------------------------------------------------------------------------------------
// (13) Chaos over a longer span: Lorenz to t = 18 (one ulp of y₀ moves the state at t = 14 by
// 2e−9 relative).

pub const LORENZ_LONG_T_END: f64 = 18.0;

pub fn lorenz_long() -> Case {
    let (s, r, b) = super::LORENZ;
    Case {
        name: "lorenz_long",
        class: "chaos (long span)",
        definition: format!(
            "x' = s(y - x), y' = r x - y - x z, z' = x y - b z; s = {s:?}, r = {r:?}, b = {b:?}"
        ),
        y0: vec![-8.0, 8.0, 27.0],
        span: (0.0, LORENZ_LONG_T_END),
        t_eval: Some((1..=9).map(|i| 2.0 * i as f64).collect()),
        reference: Reference::Taylor {
            rhs: lorenz_taylor,
            x0: exact_x0,
        },
        fine: (8, 1.0 / 512.0),
        solver: |c, o| run(lorenz_system(), c, o),
        field: |y| field(lorenz_system(), y),
    }
}

// ---------------------------------------------------------------------------------------------
// (14) Hamiltonian chaos: Hénon–Heiles just below the escape energy 1/6 (H = 0.1659), to
// t = 100 (one ulp of y₀ moves the end state by 4e−10 relative; by 3e−4 at t = 200).

pub const HH_Y0: [f64; 4] = [0.0, 0.1, 0.559, 0.1];
pub const HH_T_END: f64 = 100.0;

fn hh() -> HenonHeiles {
    HenonHeiles::new(HH_Y0).expect("below the escape energy")
}

pub fn henon_heiles() -> Case {
    Case {
        name: "henon_heiles",
        class: "chaos (Hamiltonian)",
        definition: format!(
            "Henon-Heiles H = (p1^2 + p2^2 + q1^2 + q2^2)/2 + q1^2 q2 - q2^3/3, y0 = {HH_Y0:?} \
             (H = {:.6})",
            hh().energy(&HH_Y0)
        ),
        y0: HH_Y0.to_vec(),
        span: (0.0, HH_T_END),
        t_eval: Some((1..=10).map(|i| 10.0 * i as f64).collect()),
        reference: Reference::Taylor {
            rhs: hh_taylor,
            x0: exact_x0,
        },
        fine: (8, 1.0 / 64.0),
        solver: |c, o| run(hh().system().unwrap(), c, o),
        field: |y| field(hh().system().unwrap(), y),
    }
}

/// q' = p, p₁' = −q₁ − 2q₁q₂, p₂' = −q₂ − q₁² + q₂².
pub fn hh_taylor(
    hp: &Hp,
    x: &[Vec<BigFloat>],
    _aux: &mut Vec<Vec<BigFloat>>,
    k: usize,
) -> Vec<BigFloat> {
    let two = hp.f(2.0);
    let q1q2 = hp.cauchy(&x[0], &x[1], k);
    let q1q1 = hp.cauchy(&x[0], &x[0], k);
    let q2q2 = hp.cauchy(&x[1], &x[1], k);
    vec![
        x[2][k].clone(),
        x[3][k].clone(),
        hp.neg(&hp.add(&x[0][k], &hp.mul(&two, &q1q2))),
        hp.sub(&q2q2, &hp.add(&x[1][k], &q1q1)),
    ]
}

// ---------------------------------------------------------------------------------------------
// (15) On a separatrix: the pendulum's heteroclinic orbit from the bottom, (q, p)(0) = (0, 2)
// (H = 2, the energy of the upright position), q = π − 4 atan(e^{−t}), p = 2 sech t: it creeps
// toward the top, where perturbations grow like eᵗ.

pub const PENDULUM_SEP_T_END: f64 = 20.0;

pub fn pendulum_separatrix() -> Case {
    Case {
        name: "pendulum_sep",
        class: "on a separatrix",
        definition: "q'' = -sin q, q0 = 0, p0 = 2".into(),
        y0: vec![0.0, 2.0],
        span: (0.0, PENDULUM_SEP_T_END),
        t_eval: Some((1..=10).map(|i| 2.0 * i as f64).collect()),
        reference: Reference::Exact(pendulum_separatrix_exact),
        fine: (8, 1.0 / 64.0),
        solver: |c, o| run(pendulum_system(), c, o),
        field: |y| field(pendulum_system(), y),
    }
}

/// q = π − 4 atan(e^{−t}), p = 4e^{−t}/(1 + e^{−2t}) in high precision.
pub fn pendulum_separatrix_exact(ts: &[f64]) -> Vec<Vec<f64>> {
    let mut hp = Hp::new(PREC);
    let pi = hp.pi();
    let (one, four) = (hp.f(1.0), hp.f(4.0));
    ts.iter()
        .map(|&t| {
            let e = hp.exp(&hp.f(-t));
            let atan = hp.atan(&e);
            let q = hp.sub(&pi, &hp.mul(&four, &atan));
            let p = hp.div(&hp.mul(&four, &e), &hp.add(&one, &hp.mul(&e, &e)));
            vec![to_f64(&q), to_f64(&p)]
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// (16) On a separatrix: Duffing with m = (k/ω)² = 1, ω = k = 5, from (0, 5): the orbit
// q = tanh 5t, p = 5 sech² 5t toward the saddle q = 1, where perturbations grow like e^{10t}.

pub const DUFFING_SEP: (f64, f64) = (5.0, 5.0);
pub const DUFFING_SEP_T_END: f64 = 3.0;

fn duffing_sep() -> Duffing {
    Duffing::new(DUFFING_SEP.0, DUFFING_SEP.1).expect("m = 1 is allowed")
}

pub fn duffing_separatrix() -> Case {
    let (omega, k) = DUFFING_SEP;
    Case {
        name: "duffing_sep",
        class: "on a separatrix",
        definition: format!(
            "q'' = -(w^2 + k^2) q + 2 k^2 q^3, w = {omega:?}, k = {k:?}, q0 = 0, p0 = w"
        ),
        y0: duffing_sep().initial_value(),
        span: (0.0, DUFFING_SEP_T_END),
        t_eval: Some((1..=12).map(|i| 0.25 * i as f64).collect()),
        reference: Reference::Exact(duffing_separatrix_exact),
        fine: (8, 1.0 / 512.0),
        solver: |c, o| run(duffing_sep().system().unwrap(), c, o),
        field: |y| field(duffing_sep().system().unwrap(), y),
    }
}

/// q = tanh ωt = (1 − e^{−2ωt})/(1 + e^{−2ωt}), p = ω sech² ωt = 4ω e^{−2ωt}/(1 + e^{−2ωt})²
/// in high precision (ω = k).
pub fn duffing_separatrix_exact(ts: &[f64]) -> Vec<Vec<f64>> {
    let mut hp = Hp::new(PREC);
    let omega = hp.f(DUFFING_SEP.0);
    let (one, four) = (hp.f(1.0), hp.f(4.0));
    ts.iter()
        .map(|&t| {
            let x = hp.mul(&hp.f(-2.0), &hp.mul(&omega, &hp.f(t)));
            let e = hp.exp(&x);
            let den = hp.add(&one, &e);
            let q = hp.div(&hp.sub(&one, &e), &den);
            let p = hp.div(&hp.mul(&hp.mul(&four, &omega), &e), &hp.mul(&den, &den));
            vec![to_f64(&q), to_f64(&p)]
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// (17) Parametric resonance: Mathieu's q'' + (a − 2b cos 2t) q = 0 in its first instability
// tongue (a = 1, b = 0.2: growth ~e^{bt/2}), autonomous with the forcing as two more
// variables (c, s) = (cos 2t, sin 2t): y = (q, p, c, s), A = [[0, 1], [−a, 0]] ⊕ 2[[0, −1],
// [1, 0]] (the forcing is the linear part's exact rotation), g = (0, 2b c q, 0, 0).

pub const MATHIEU: (f64, f64) = (1.0, 0.2);
pub const MATHIEU_T_END: f64 = 50.0;

fn mathieu_g(y: &[f64], g: &mut [f64]) {
    g[0] = 0.0;
    g[1] = 2.0 * MATHIEU.1 * y[2] * y[0];
    g[2] = 0.0;
    g[3] = 0.0;
}

pub fn mathieu_system() -> Semilinear<Dense, G> {
    let a = MATHIEU.0;
    #[rustfmt::skip]
    let m = DMatrix::from_row_slice(4, 4, &[
        0.0, 1.0, 0.0, 0.0,
        -a, 0.0, 0.0, 0.0,
        0.0, 0.0, 0.0, -2.0,
        0.0, 0.0, 2.0, 0.0,
    ]);
    Semilinear::new(Dense::new(m).unwrap(), mathieu_g)
}

pub fn mathieu() -> Case {
    let (a, b) = MATHIEU;
    Case {
        name: "mathieu",
        class: "parametric resonance",
        definition: format!(
            "q'' + (a - 2 b cos 2t) q = 0 as (q, p, cos 2t, sin 2t), a = {a:?}, b = {b:?}, \
             q0 = 1, p0 = 0"
        ),
        y0: vec![1.0, 0.0, 1.0, 0.0],
        span: (0.0, MATHIEU_T_END),
        t_eval: Some((1..=10).map(|i| 5.0 * i as f64).collect()),
        reference: Reference::Taylor {
            rhs: mathieu_taylor,
            x0: exact_x0,
        },
        fine: (8, 1.0 / 64.0),
        solver: |c, o| run(mathieu_system(), c, o),
        field: |y| field(mathieu_system(), y),
    }
}

pub fn mathieu_taylor(
    hp: &Hp,
    x: &[Vec<BigFloat>],
    _aux: &mut Vec<Vec<BigFloat>>,
    k: usize,
) -> Vec<BigFloat> {
    let (a, b) = (hp.f(MATHIEU.0), hp.f(MATHIEU.1));
    let two = hp.f(2.0);
    let cq = hp.cauchy(&x[2], &x[0], k);
    vec![
        x[1][k].clone(),
        hp.sub(&hp.mul(&hp.mul(&two, &b), &cq), &hp.mul(&a, &x[0][k])),
        hp.neg(&hp.mul(&two, &x[3][k])),
        hp.mul(&two, &x[2][k]),
    ]
}

// ---------------------------------------------------------------------------------------------
// (18) Predator–prey: Lotka–Volterra u' = u(α − βv), v' = v(δu − γ) on a large orbit (u from
// 6 down to ~0.2, v up to ~7), A = diag(α, −γ), g = (−βuv, δuv); its first integral
// V = δu − γ ln u + βv − α ln v is the system's energy.

pub const LV: (f64, f64, f64, f64) = (1.0, 0.5, 1.0, 0.5);
pub const LV_T_END: f64 = 30.0;

fn lv_g(y: &[f64], g: &mut [f64]) {
    let (_, beta, _, delta) = LV;
    let uv = y[0] * y[1];
    g[0] = -beta * uv;
    g[1] = delta * uv;
}

fn lv_invariant(y: &[f64]) -> f64 {
    let (alpha, beta, gamma, delta) = LV;
    delta * y[0] - gamma * y[0].ln() + beta * y[1] - alpha * y[1].ln()
}

pub fn lotka_volterra_system() -> Semilinear<Diagonal, G, E> {
    let (alpha, _, gamma, _) = LV;
    Semilinear::with_energy(
        Diagonal::new(vec![alpha, -gamma]).unwrap(),
        lv_g as G,
        lv_invariant as E,
    )
}

pub fn lotka_volterra() -> Case {
    let (alpha, beta, gamma, delta) = LV;
    Case {
        name: "lotka_volterra",
        class: "predator-prey",
        definition: format!(
            "u' = u (alpha - beta v), v' = v (delta u - gamma), alpha = {alpha:?}, \
             beta = {beta:?}, gamma = {gamma:?}, delta = {delta:?}, u0 = 6, v0 = 0.5"
        ),
        y0: vec![6.0, 0.5],
        span: (0.0, LV_T_END),
        t_eval: Some((1..=15).map(|i| 2.0 * i as f64).collect()),
        reference: Reference::Taylor {
            rhs: lv_taylor,
            x0: exact_x0,
        },
        fine: (8, 1.0 / 128.0),
        solver: |c, o| run(lotka_volterra_system(), c, o),
        field: |y| field(lotka_volterra_system(), y),
    }
}

pub fn lv_taylor(
    hp: &Hp,
    x: &[Vec<BigFloat>],
    _aux: &mut Vec<Vec<BigFloat>>,
    k: usize,
) -> Vec<BigFloat> {
    let (alpha, beta, gamma, delta) = LV;
    let (alpha, beta, gamma, delta) = (hp.f(alpha), hp.f(beta), hp.f(gamma), hp.f(delta));
    let uv = hp.cauchy(&x[0], &x[1], k);
    vec![
        hp.sub(&hp.mul(&alpha, &x[0][k]), &hp.mul(&beta, &uv)),
        hp.sub(&hp.mul(&delta, &uv), &hp.mul(&gamma, &x[1][k])),
    ]
}

// ---------------------------------------------------------------------------------------------
// (19) A free rigid body (Euler's equations for the angular momentum m, moments of inertia
// I = (2, 1, 2/3), GNI §IV.1) started near the unstable intermediate axis: it tumbles, flipping
// m₂ between ±|m| in fast turns after long slow stretches. A = 0, g = (m₂m₃(1/I₃ − 1/I₂),
// m₃m₁(1/I₁ − 1/I₃), m₁m₂(1/I₂ − 1/I₁)) = (m₂m₃/2, −m₃m₁, m₁m₂/2); energy
// ½ Σ mᵢ²/Iᵢ.

/// 1/I₃ − 1/I₂, 1/I₁ − 1/I₃, 1/I₂ − 1/I₁ (exact in f64).
pub const RIGID: [f64; 3] = [0.5, -1.0, 0.5];
pub const RIGID_Y0: [f64; 3] = [0.05, 1.0, 0.1];
pub const RIGID_T_END: f64 = 40.0;

fn rigid_g(m: &[f64], g: &mut [f64]) {
    g[0] = RIGID[0] * m[1] * m[2];
    g[1] = RIGID[1] * m[2] * m[0];
    g[2] = RIGID[2] * m[0] * m[1];
}

fn rigid_energy(m: &[f64]) -> f64 {
    0.5 * (m[0] * m[0] / 2.0 + m[1] * m[1] + 1.5 * m[2] * m[2])
}

pub fn rigid_body_system() -> Semilinear<Zero, G, E> {
    Semilinear::with_energy(Zero::new(3), rigid_g as G, rigid_energy as E)
}

pub fn rigid_body() -> Case {
    Case {
        name: "rigid_body",
        class: "free rigid body",
        definition: format!(
            "m' = m x I^-1 m (Euler), I = (2, 1, 2/3), coefficients {RIGID:?}, m0 = {RIGID_Y0:?}"
        ),
        y0: RIGID_Y0.to_vec(),
        span: (0.0, RIGID_T_END),
        t_eval: Some((1..=10).map(|i| 4.0 * i as f64).collect()),
        reference: Reference::Taylor {
            rhs: rigid_taylor,
            x0: exact_x0,
        },
        fine: (8, 1.0 / 64.0),
        solver: |c, o| run(rigid_body_system(), c, o),
        field: |y| field(rigid_body_system(), y),
    }
}

pub fn rigid_taylor(
    hp: &Hp,
    x: &[Vec<BigFloat>],
    _aux: &mut Vec<Vec<BigFloat>>,
    k: usize,
) -> Vec<BigFloat> {
    let c: Vec<BigFloat> = RIGID.iter().map(|&v| hp.f(v)).collect();
    vec![
        hp.mul(&c[0], &hp.cauchy(&x[1], &x[2], k)),
        hp.mul(&c[1], &hp.cauchy(&x[2], &x[0], k)),
        hp.mul(&c[2], &hp.cauchy(&x[0], &x[1], k)),
    ]
}

// ---------------------------------------------------------------------------------------------
// (20) A relaxation oscillator: van der Pol, q'' − μ(1 − q²)q' + q = 0 with μ = 8 (slow drifts
// and fast jumps, period ≈ 14), A = [[0, 1], [−1, 0]], g = (0, μ(1 − q²)p): the stiffness is
// in g (Lipschitz constant up to μ(1 + 2|qp|)).

pub const VDP_MU: f64 = 8.0;
pub const VDP_T_END: f64 = 20.0;

fn vdp_g(y: &[f64], g: &mut [f64]) {
    g[0] = 0.0;
    g[1] = VDP_MU * (1.0 - y[0] * y[0]) * y[1];
}

pub fn van_der_pol_system() -> Semilinear<Dense, G> {
    let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -1.0, 0.0]);
    Semilinear::new(Dense::new(a).unwrap(), vdp_g)
}

pub fn van_der_pol() -> Case {
    Case {
        name: "van_der_pol",
        class: "relaxation oscillator",
        definition: format!("q'' - mu (1 - q^2) q' + q = 0, mu = {VDP_MU:?}, q0 = 2, p0 = 0"),
        y0: vec![2.0, 0.0],
        span: (0.0, VDP_T_END),
        t_eval: Some((1..=10).map(|i| 2.0 * i as f64).collect()),
        reference: Reference::Taylor {
            rhs: vdp_taylor,
            x0: exact_x0,
        },
        fine: (8, 1.0 / 1024.0),
        solver: |c, o| run(van_der_pol_system(), c, o),
        field: |y| field(van_der_pol_system(), y),
    }
}

pub fn vdp_taylor(
    hp: &Hp,
    x: &[Vec<BigFloat>],
    aux: &mut Vec<Vec<BigFloat>>,
    k: usize,
) -> Vec<BigFloat> {
    if aux.is_empty() {
        aux.push(Vec::new());
    }
    aux[0].push(hp.cauchy(&x[0], &x[0], k)); // q²
    let q2p = hp.cauchy(&aux[0], &x[1], k);
    let mu = hp.f(VDP_MU);
    vec![
        x[1][k].clone(),
        hp.sub(&hp.mul(&mu, &hp.sub(&x[1][k], &q2p)), &x[0][k]),
    ]
}

// ---------------------------------------------------------------------------------------------
// (21) Stiffness in g: y' = −y + λ(y − y³) componentwise, λ = 100, four components from
// either side of the stable states ±√(1 − 1/λ) and from near the unstable 0. After a layer of
// width ~1/λ the solution rests where g' = −2λ: a step is limited by the stage iteration, not
// by accuracy. A Bernoulli equation: y = y₀e^{at}/√(1 + (λ/a)y₀²(e^{2at} − 1)), a = λ − 1.

pub const STIFF_LAMBDA: f64 = 100.0;
pub const STIFF_Y0: [f64; 4] = [0.01, 0.5, 2.0, -1.5];
pub const STIFF_T_END: f64 = 5.0;

fn stiff_g(y: &[f64], g: &mut [f64]) {
    for (g, y) in g.iter_mut().zip(y) {
        *g = STIFF_LAMBDA * (y - y * y * y);
    }
}

pub fn stiff_g_system() -> Semilinear<Scalar, G> {
    Semilinear::new(Scalar::new(-1.0, STIFF_Y0.len()).unwrap(), stiff_g)
}

pub fn stiff_in_g() -> Case {
    Case {
        name: "stiff_g",
        class: "stiffness in g",
        definition: format!(
            "y' = -y + lambda (y - y^3) componentwise, lambda = {STIFF_LAMBDA:?}, \
             y0 = {STIFF_Y0:?}"
        ),
        y0: STIFF_Y0.to_vec(),
        span: (0.0, STIFF_T_END),
        t_eval: Some(vec![0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0]),
        reference: Reference::Exact(stiff_g_exact),
        fine: (8, 1.0 / 4096.0),
        solver: |c, o| run(stiff_g_system(), c, o),
        field: |y| field(stiff_g_system(), y),
    }
}

pub fn stiff_g_exact(ts: &[f64]) -> Vec<Vec<f64>> {
    let mut hp = Hp::new(PREC);
    let one = hp.f(1.0);
    let lambda = hp.f(STIFF_LAMBDA);
    let a = hp.sub(&lambda, &one);
    let ratio = hp.div(&lambda, &a);
    ts.iter()
        .map(|&t| {
            let at = hp.mul(&a, &hp.f(t));
            let e = hp.exp(&at);
            let e2 = hp.mul(&e, &e);
            STIFF_Y0
                .iter()
                .map(|&y0| {
                    let y0 = hp.f(y0);
                    let den = hp.add(
                        &one,
                        &hp.mul(&hp.mul(&ratio, &hp.mul(&y0, &y0)), &hp.sub(&e2, &one)),
                    );
                    to_f64(&hp.div(&hp.mul(&y0, &e), &hp.sqrt(&den)))
                })
                .collect()
        })
        .collect()
}
