//! The partial differential equations added to the suite for issue 42: a reaction–diffusion
//! system (FitzHugh–Nagumo pulses) and a second-order semilinear wave equation (sine-Gordon
//! kink and antikink), both on periodic lattices.

use astro_float::BigFloat;
use ecr::runtime::operator::Dense;
use ecr::runtime::second_order::Omega;
use ecr::runtime::system::Semilinear;
use nalgebra::DMatrix;

use super::{Case, E, G, Hp, Reference, So, exact_x0, field, run, second_order};

/// The periodic second difference: (L u)_j = u_{j+1} − 2u_j + u_{j−1}, as a dense matrix.
fn periodic_laplacian(n: usize) -> DMatrix<f64> {
    let mut l = DMatrix::zeros(n, n);
    for j in 0..n {
        l[(j, j)] = -2.0;
        l[(j, (j + 1) % n)] = 1.0;
        l[(j, (j + n - 1) % n)] = 1.0;
    }
    l
}

// ---------------------------------------------------------------------------------------------
// (22) Reaction–diffusion: FitzHugh–Nagumo on a ring of N points (Δx = 1),
//   u_j' = D(u_{j+1} − 2u_j + u_{j−1}) + u_j − u_j³/3 − v_j,   v_j' = ε(u_j + a − b v_j),
// from the rest state with a bump: two excitation pulses run apart around the ring, meet on
// the far side and annihilate. y = (u, v), A = [[D L + I, −I], [εI, −εbI]] dense (2N × 2N,
// not normal), g = (−u³/3, εa).

pub const FHN_N: usize = 32;
pub const FHN_D: f64 = 1.0;
/// (a, b, ε).
pub const FHN: (f64, f64, f64) = (0.7, 0.8, 0.08);
pub const FHN_T_END: f64 = 40.0;

fn fhn_g(y: &[f64], g: &mut [f64]) {
    let n = FHN_N;
    let (a, _, eps) = FHN;
    for j in 0..n {
        g[j] = -y[j] * y[j] * y[j] / 3.0;
        g[n + j] = eps * a;
    }
}

pub fn fhn_matrix() -> DMatrix<f64> {
    let n = FHN_N;
    let (_, b, eps) = FHN;
    let mut m = DMatrix::zeros(2 * n, 2 * n);
    let l = periodic_laplacian(n);
    for i in 0..n {
        for j in 0..n {
            m[(i, j)] = FHN_D * l[(i, j)];
        }
        m[(i, i)] += 1.0;
        m[(i, n + i)] = -1.0;
        m[(n + i, i)] = eps;
        m[(n + i, n + i)] = -eps * b;
    }
    m
}

pub fn fhn_system() -> Semilinear<Dense, G> {
    Semilinear::new(Dense::new(fhn_matrix()).unwrap(), fhn_g)
}

/// u = −1.2 + 2.2 exp(−(j − N/4)²/8), v = −0.62.
pub fn fhn_initial_value() -> Vec<f64> {
    let n = FHN_N;
    let mut y = vec![-0.62; 2 * n];
    for (j, u) in y.iter_mut().take(n).enumerate() {
        let x = j as f64 - (n / 4) as f64;
        *u = -1.2 + 2.2 * (-x * x / 8.0).exp();
    }
    y
}

pub fn fitzhugh_nagumo() -> Case {
    let (a, b, eps) = FHN;
    Case {
        name: "fitzhugh_nagumo",
        class: "reaction-diffusion",
        definition: format!(
            "u' = D L u + u - u^3/3 - v, v' = eps (u + a - b v), periodic L, N = {FHN_N}, \
             D = {FHN_D:?}, a = {a:?}, b = {b:?}, eps = {eps:?}, u0 = -1.2 + 2.2 \
             exp(-(j - N/4)^2/8), v0 = -0.62"
        ),
        y0: fhn_initial_value(),
        span: (0.0, FHN_T_END),
        t_eval: Some((1..=10).map(|i| 4.0 * i as f64).collect()),
        reference: Reference::Taylor {
            rhs: fhn_taylor,
            x0: exact_x0,
        },
        fine: (8, 1.0 / 64.0),
        solver: |c, o| run(fhn_system(), c, o),
        field: |y| field(fhn_system(), y),
    }
}

pub fn fhn_taylor(
    hp: &Hp,
    x: &[Vec<BigFloat>],
    aux: &mut Vec<Vec<BigFloat>>,
    k: usize,
) -> Vec<BigFloat> {
    let n = FHN_N;
    let (a, b, eps) = FHN;
    let (a, b, eps, d) = (hp.f(a), hp.f(b), hp.f(eps), hp.f(FHN_D));
    let (two, three) = (hp.f(2.0), hp.f(3.0));
    // aux[j] = u_j².
    if aux.is_empty() {
        aux.resize(n, Vec::new());
    }
    for j in 0..n {
        let sq = hp.cauchy(&x[j], &x[j], k);
        aux[j].push(sq);
    }
    let mut f = Vec::with_capacity(2 * n);
    for j in 0..n {
        let (l, r) = (&x[(j + n - 1) % n][k], &x[(j + 1) % n][k]);
        let lap = hp.sub(&hp.add(l, r), &hp.mul(&two, &x[j][k]));
        let cube = hp.div(&hp.cauchy(&aux[j], &x[j], k), &three);
        let lin = hp.sub(&hp.add(&hp.mul(&d, &lap), &x[j][k]), &x[n + j][k]);
        f.push(hp.sub(&lin, &cube));
    }
    for j in 0..n {
        let mut v = hp.sub(&x[j][k], &hp.mul(&b, &x[n + j][k]));
        if k == 0 {
            v = hp.add(&v, &a);
        }
        f.push(hp.mul(&eps, &v));
    }
    f
}

// ---------------------------------------------------------------------------------------------
// (23) A second-order PDE: the sine-Gordon lattice q_j'' = c(q_{j+1} − 2q_j + q_{j−1}) − sin q_j
// on a ring of N points (Δx = 0.625 on [−10, 10), c = 1/Δx²), q'' + Ωq = −∇U with Ω = −cL dense
// symmetric and U = Σ(1 − cos q_j), through `SecondOrder`: a kink and an antikink at ∓4
// running toward each other at speed 1/2, colliding at t ≈ 8.

pub const SG_N: usize = 32;
pub const SG_C: f64 = 2.56;
pub const SG_T_END: f64 = 16.0;
const SG_X0: f64 = 4.0;
const SG_V: f64 = 0.5;

fn sg_force(q: &[f64], f: &mut [f64]) {
    for (f, q) in f.iter_mut().zip(q) {
        *f = q.sin();
    }
}

fn sg_potential(q: &[f64]) -> f64 {
    q.iter().map(|q| 1.0 - q.cos()).sum()
}

pub fn sg_omega() -> DMatrix<f64> {
    -SG_C * periodic_laplacian(SG_N)
}

pub fn sine_gordon_system() -> So {
    second_order(
        Omega::dense(sg_omega()).unwrap(),
        sg_force as G,
        sg_potential as E,
    )
}

/// A kink at −x₀ and an antikink at +x₀ (their continuum profiles), x_j = −10 + 0.625 j:
/// q = 4 atan e^{γ(x+x₀)} + 4 atan e^{−γ(x−x₀)} − 2π, p = −2γv [sech γ(x+x₀) + sech γ(x−x₀)],
/// γ = 1/√(1 − v²).
pub fn sg_initial_value() -> Vec<f64> {
    let n = SG_N;
    let gamma = 1.0 / (1.0 - SG_V * SG_V).sqrt();
    let mut y = vec![0.0; 2 * n];
    for j in 0..n {
        let x = -10.0 + 0.625 * j as f64;
        let (a, b) = (gamma * (x + SG_X0), gamma * (x - SG_X0));
        y[j] = 4.0 * a.exp().atan() + 4.0 * (-b).exp().atan() - 2.0 * std::f64::consts::PI;
        y[n + j] = -2.0 * gamma * SG_V * (1.0 / a.cosh() + 1.0 / b.cosh());
    }
    y
}

pub fn sine_gordon() -> Case {
    Case {
        name: "sine_gordon",
        class: "second-order PDE",
        definition: format!(
            "q_j'' = c (q_j+1 - 2 q_j + q_j-1) - sin q_j, periodic, N = {SG_N}, c = {SG_C:?}, \
             kink at -{SG_X0:?} and antikink at {SG_X0:?}, speeds +-{SG_V:?}, x_j = -10 + \
             0.625 j"
        ),
        y0: sg_initial_value(),
        span: (0.0, SG_T_END),
        t_eval: Some((1..=8).map(|i| 2.0 * i as f64).collect()),
        reference: Reference::Taylor {
            rhs: sg_taylor,
            x0: sg_x0,
        },
        fine: (8, 1.0 / 64.0),
        solver: |c, o| run(sine_gordon_system(), c, o),
        field: |y| field(sine_gordon_system(), y),
    }
}

/// (q, p, sin q, cos q).
pub fn sg_x0(hp: &mut Hp, y0: &[f64]) -> Vec<BigFloat> {
    let n = SG_N;
    let q: Vec<BigFloat> = y0[..n].iter().map(|&v| hp.f(v)).collect();
    let mut x: Vec<BigFloat> = y0.iter().map(|&v| hp.f(v)).collect();
    for v in &q {
        let s = hp.sin(v);
        x.push(s);
    }
    for v in &q {
        let c = hp.cos(v);
        x.push(c);
    }
    x
}

/// q' = p, p' = c(q_{j+1} − 2q_j + q_{j−1}) − s, s' = c p (c = cos q), cos' = −s p.
pub fn sg_taylor(
    hp: &Hp,
    x: &[Vec<BigFloat>],
    _aux: &mut Vec<Vec<BigFloat>>,
    k: usize,
) -> Vec<BigFloat> {
    let n = SG_N;
    let (c, two) = (hp.f(SG_C), hp.f(2.0));
    let mut f = Vec::with_capacity(4 * n);
    for j in 0..n {
        f.push(x[n + j][k].clone());
    }
    for j in 0..n {
        let (l, r) = (&x[(j + n - 1) % n][k], &x[(j + 1) % n][k]);
        let lap = hp.sub(&hp.add(l, r), &hp.mul(&two, &x[j][k]));
        f.push(hp.sub(&hp.mul(&c, &lap), &x[2 * n + j][k]));
    }
    for j in 0..n {
        f.push(hp.cauchy(&x[3 * n + j], &x[n + j], k));
    }
    for j in 0..n {
        f.push(hp.neg(&hp.cauchy(&x[2 * n + j], &x[n + j], k)));
    }
    f
}
