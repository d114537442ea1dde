//! The hot paths below a step, each alone: building a φ-bank for one step size (what a user pays
//! once per h) and applying it (`combine`: what a stage or the update costs each sweep), for
//! every operator kind, plus the plain application `y = Ax`. All in one run:
//! `cargo bench --bench hot_paths`.
//!
//! Banks are built as ECrP builds them: r = 3 (φ₀..φ₄), nodes the 3 Gauss points and τ = 1.
//! Dense matrices are non-normal (random entries plus a skew part of size 10 and a diagonal
//! shift), so the dense bank runs scaling-and-squaring rather than an eigendecomposition.
//!
//! The group `setup` times what a run pays before its first step for the spectral problems
//! (`cargo bench --bench hot_paths -- setup`): the whole ECrP stepper construction for the NLS
//! with N = 128 at r = s = 3..6 (its Legendre-kernel bank at the Gauss points and τ = 1, h =
//! 0.01), and the kernel bank alone (r = 3) of a random 1D circulant with N = 2¹⁶ and of the 2D
//! NLS on 512 × 512; and, to compare with, 500 steps of the NLS run (T = 10, r = 5, h = 0.02).

use criterion::{BatchSize, BenchmarkId, Criterion, criterion_group, criterion_main};
use ecr::problems::{Nls, Nls2d};
use ecr::runtime::operator::{
    Circulant, Dense, DenseStatic, Diagonal, LinearOperator, PhiBank, Scalar, SkewPair, Symmetric,
};
use ecr::runtime::stepper::{EcStepper, SolverSettings};
use ecr::runtime::system::System;
use nalgebra::{DMatrix, SMatrix};
use std::hint::black_box;

const H: f64 = 0.01;
const R: usize = 3;
const TAUS: [f64; 4] = [0.112_701_665_379_258_3, 0.5, 0.887_298_334_620_741_7, 1.0];

/// Deterministic numbers in [−1, 1).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        2.0 * ((self.0 >> 11) as f64 / (1u64 << 53) as f64) - 1.0
    }
    fn vec(&mut self, n: usize) -> Vec<f64> {
        (0..n).map(|_| self.next()).collect()
    }
}

fn non_normal(d: usize, rng: &mut Lcg) -> DMatrix<f64> {
    let b = DMatrix::from_fn(d, d, |_, _| rng.next());
    let skew = (&b - b.transpose()) * 5.0;
    DMatrix::from_fn(d, d, |i, j| {
        let upper = if j > i { rng.next() } else { 0.0 };
        skew[(i, j)] + upper - if i == j { 1.0 } else { 0.0 }
    })
}

fn symmetric(d: usize, rng: &mut Lcg) -> DMatrix<f64> {
    let b = DMatrix::from_fn(d, d, |_, _| rng.next());
    -(&b * b.transpose())
}

/// A symmetric circulant kernel (the spectral second derivative's shape: c_j = c_{N−j}).
fn symmetric_kernel(n: usize, rng: &mut Lcg) -> Vec<f64> {
    let half = rng.vec(n / 2 + 1);
    (0..n).map(|j| half[j.min(n - j)]).collect()
}

/// Times `phi_bank` and `combine` (all s + 1 nodes, r moments) of `op`.
fn bank_and_combine<L: LinearOperator>(c: &mut Criterion, group: &str, param: usize, op: &L) {
    let d = op.dim();
    let mut g = c.benchmark_group(group);
    g.bench_with_input(BenchmarkId::new("phi_bank", param), op, |b, op| {
        b.iter(|| op.phi_bank(black_box(H), &TAUS, R + 1).unwrap())
    });
    let bank = op.phi_bank(H, &TAUS, R + 1).unwrap();
    let mut ws = bank.workspace();
    let mut rng = Lcg(7);
    let (y0, moments) = (rng.vec(d), rng.vec(R * d));
    let coef = rng.vec(R * TAUS.len());
    let mut out = vec![0.0; d * TAUS.len()];
    g.bench_function(BenchmarkId::new("combine", param), |b| {
        b.iter(|| {
            bank.combine(0..TAUS.len(), &y0, &moments, &coef, &mut out, &mut ws);
            black_box(&out);
        })
    });
    let mut y = vec![0.0; d];
    g.bench_function(BenchmarkId::new("apply", param), |b| {
        b.iter(|| {
            op.apply(black_box(&y0), &mut y);
            black_box(&y);
        })
    });
    g.finish();
}

fn phi_banks(c: &mut Criterion) {
    let mut rng = Lcg(1);
    bank_and_combine(c, "scalar", 1024, &Scalar::new(-3.0, 1024).unwrap());
    bank_and_combine(c, "diagonal", 1024, &Diagonal::new(rng.vec(1024)).unwrap());
    let a2: SMatrix<f64, 2, 2> = SMatrix::from_iterator(non_normal(2, &mut rng).iter().copied());
    bank_and_combine(c, "dense_static", 2, &DenseStatic::new(a2).unwrap());
    for d in [2, 8, 32, 128, 512] {
        bank_and_combine(c, "dense", d, &Dense::new(non_normal(d, &mut rng)).unwrap());
    }
    for d in [32, 128, 512] {
        bank_and_combine(
            c,
            "symmetric",
            d,
            &Symmetric::new(symmetric(d, &mut rng)).unwrap(),
        );
    }
    for n in [128, 1024, 16384] {
        bank_and_combine(c, "circulant", n, &Circulant::new(rng.vec(n)).unwrap());
        let skew = SkewPair::new(Circulant::new(symmetric_kernel(n, &mut rng)).unwrap()).unwrap();
        bank_and_combine(c, "skew_pair_circulant", 2 * n, &skew);
    }
}

/// Set-up before the first step: ECrP stepper construction for the NLS (N = 128), kernel banks
/// of a large 1D circulant and of the 2D NLS.
fn setup(c: &mut Criterion) {
    let mut g = c.benchmark_group("setup");
    let nls = Nls::new(128).unwrap().system().unwrap();
    for r in 3..=6 {
        g.bench_with_input(BenchmarkId::new("nls128_ecrp_stepper_r", r), &r, |b, &r| {
            b.iter_batched(
                || nls.clone(),
                |sys| EcStepper::with_nodes(sys, r, r, H, SolverSettings::default()).unwrap(),
                BatchSize::SmallInput,
            )
        });
    }
    // What the set-up is compared with: the NLS run to T = 10 at r = s = 5, h = 0.02 (500
    // steps from the paper's initial value), construction excluded.
    let y0 = Nls::new(128).unwrap().initial_value();
    g.bench_function("nls128_ecrp_r5_h0.02_500_steps", |b| {
        b.iter_batched(
            || {
                let settings = SolverSettings::default();
                let stepper = EcStepper::with_nodes(nls.clone(), 5, 5, 0.02, settings).unwrap();
                (stepper, y0.clone())
            },
            |(mut stepper, mut y)| {
                for _ in 0..500 {
                    stepper.step(&mut y).unwrap();
                }
                y
            },
            BatchSize::PerIteration,
        )
    });
    g.sample_size(10);
    let circulant = Circulant::new(Lcg(3).vec(1 << 16)).unwrap();
    g.bench_function(BenchmarkId::new("circulant_kernel_bank_r3", 1 << 16), |b| {
        b.iter(|| circulant.kernel_bank(black_box(H), &TAUS, R).unwrap())
    });
    let nls2d = Nls2d::new(512).unwrap().system().unwrap();
    g.bench_function(BenchmarkId::new("nls2d_kernel_bank_r3", 512), |b| {
        b.iter(|| nls2d.linear().kernel_bank(black_box(H), &TAUS, R).unwrap())
    });
    g.finish();
}

criterion_group! {
    name = benches;
    // No plots: criterion's plotting backend needs system fonts, which a fresh machine may lack.
    config = Criterion::default().sample_size(20).without_plots();
    targets = phi_banks, setup
}
criterion_main!(benches);
