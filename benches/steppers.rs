//! Fixed-order (`ecr_method!`) vs run-time stepper, and each against its kernel cost: the
//! g-evaluations and operator applications a step performs (φ-bank combines, the fused stage
//! matrices, the double-double propagator), timed alone. All in one run:
//! `cargo bench --bench steppers`. Each iteration is 100 steps of r = 3 (order 6), h = 0.01,
//! from the same start, on Duffing (ω = 5, k = 0.07) and the conservative wind problem (d = 2).
//! The macro stepper is also timed with the plain f64 update (`compensated: false`): the price
//! of the compensated double-double update. After criterion's runs, the ratios are measured
//! again paired: the same iterations interleaved in rounds, the fastest of each kept, printed
//! as one line per problem (robust on a shared machine, where criterion's separate runs of a
//! few seconds each can see different load).

use criterion::{Criterion, criterion_group, criterion_main};
use ecr::ecr_method;
use ecr::runtime::operator::{Dense, DenseStatic, PhiBank};
use ecr::runtime::problems::{Duffing, Wind};
use ecr::runtime::stepper::{EcStepper, SolverSettings, Stepper, gemv_cm};
use ecr::runtime::system::Semilinear;
use nalgebra::{DMatrix, SMatrix};
use std::hint::black_box;
use std::time::Instant;

ecr_method!(r = 3);

const STEPS: usize = 100;
const H: f64 = 0.01;

fn bench_problem<G: Fn(&[f64], &mut [f64]) + Copy>(
    c: &mut Criterion,
    name: &str,
    a: DMatrix<f64>,
    y0: [f64; 2],
    g: G,
) {
    let sa: SMatrix<f64, 2, 2> = SMatrix::from_iterator(a.iter().copied());
    let mut fixed: Ec3<_, 2> =
        Ec3::fixed(Semilinear::new(DenseStatic::new(sa).unwrap(), g), H).unwrap();
    let plain = SolverSettings {
        compensated: false,
        ..SolverSettings::default()
    };
    let mut fixed_plain: Ec3<_, 2> = Stepper::from_kernel(
        Ec3Kernel,
        Semilinear::new(DenseStatic::new(sa).unwrap(), g),
        H,
        plain,
    )
    .unwrap();
    let mut rt_dense =
        EcStepper::new(Semilinear::new(Dense::new(a.clone()).unwrap(), g), 3, H).unwrap();
    let mut rt_static =
        EcStepper::new(Semilinear::new(DenseStatic::new(sa).unwrap(), g), 3, H).unwrap();

    // The work of STEPS steps: g-evaluations and sweeps (each sweep = one combine over s stages).
    let (mut g_evals, mut sweeps) = (0, 0);
    let mut y = y0;
    for _ in 0..STEPS {
        let rep = fixed.step(&mut y).unwrap();
        g_evals += rep.g_evals;
        sweeps += rep.sweeps;
    }
    // The operator applications of a step, from the macro stepper's own bank: once per step
    // e^{cᵢhA} y₀ (s nodes), per sweep the fused stage matrices, at the end the combine at
    // τ = 1, the double-double propagator and the propagated carried rounding error.
    let s = 3;
    let bank = fixed.bank().clone();
    let mats = fixed
        .stage_matrices()
        .expect("d = 2, s = r: the stepper fuses its sweeps")
        .to_vec();
    let coef = [H; 3];
    let (mut props, mut stages, moments) = ([0.0; 6], [0.0; 6], [0.1; 6]);
    let (mut gout, mut hi, mut lo) = ([0.0; 2], [0.0; 2], [0.0; 2]);
    let g_in = [0.3; 6];

    // One iteration of each benchmark: STEPS steps from y0, or the kernel cost of STEPS steps.
    let mut run_macro = move || run_steps(y0, |y| fixed.step(y).map(drop));
    let mut run_plain = move || run_steps(y0, |y| fixed_plain.step(y).map(drop));
    let mut run_rt_dense = move || run_steps(y0, |y| rt_dense.step(y).map(drop));
    let mut run_rt_static = move || run_steps(y0, |y| rt_static.step(y).map(drop));
    let mut run_kernel = move || {
        for _ in 0..g_evals {
            g(black_box(&y0), black_box(&mut gout));
        }
        for _ in 0..STEPS {
            bank.combine(0..s, black_box(&y0), &[], &[], &mut props, &mut ());
        }
        for _ in 0..sweeps {
            // The stepper's own fused sweep, sizes constant (as the fixed-order stepper has them).
            gemv_cm(&mats, 6, [black_box(&g_in), &[]], Some(&props), &mut stages);
        }
        for _ in 0..STEPS {
            bank.combine(
                s..s + 1,
                black_box(&y0),
                &moments,
                &coef,
                &mut gout,
                &mut (),
            );
            bank.propagate_dd(s, black_box(&y0), &mut hi, &mut lo, &mut ());
            bank.apply(s, 0, black_box(&lo), &mut hi, &mut ());
        }
        (stages, gout, hi)
    };

    let mut group = c.benchmark_group(name);
    group.bench_function("macro Ec3<_, 2> (DenseStatic)", |b| b.iter(&mut run_macro));
    group.bench_function("macro Ec3<_, 2> (DenseStatic), plain f64 update", |b| {
        b.iter(&mut run_plain)
    });
    group.bench_function("run-time EcStepper r=3 (Dense)", |b| {
        b.iter(&mut run_rt_dense)
    });
    group.bench_function("run-time EcStepper r=3 (DenseStatic)", |b| {
        b.iter(&mut run_rt_static)
    });
    group.bench_function("kernel cost (g + operator applications)", |b| {
        b.iter(&mut run_kernel)
    });
    group.finish();
    println!("{name}: {STEPS} steps = {g_evals} g-evaluations, {sweeps} sweeps");

    // The ratios again, paired: the iterations above interleaved in rounds, each timed alone,
    // the fastest of PAIRED_ROUNDS kept (a shared machine's interruptions only add time, and
    // interleaving exposes every benchmark to the same conditions).
    let mut best = [f64::INFINITY; 4];
    for _ in 0..PAIRED_ROUNDS {
        best[0] = best[0].min(time_once(&mut run_macro));
        best[1] = best[1].min(time_once(&mut run_rt_dense));
        best[2] = best[2].min(time_once(&mut run_kernel));
        best[3] = best[3].min(time_once(&mut run_plain));
    }
    let [mac, rt, kernel, plain] = best;
    println!(
        "{name} paired (fastest of {PAIRED_ROUNDS} interleaved rounds, per {STEPS} steps): macro \
         {mac:.2} µs, run-time (Dense) {rt:.2} µs, kernel cost {kernel:.2} µs, macro plain \
         update {plain:.2} µs; run-time / macro = {:.2}, macro / kernel cost = {:.2}, \
         compensated / plain = {:.2}",
        rt / mac,
        mac / kernel,
        mac / plain
    );
}

/// STEPS steps of `step` from y0: one iteration of a stepper's benchmark.
fn run_steps(
    y0: [f64; 2],
    mut step: impl FnMut(&mut [f64]) -> ecr::runtime::Result<()>,
) -> [f64; 2] {
    let mut y = y0;
    for _ in 0..STEPS {
        step(black_box(&mut y)).unwrap();
    }
    y
}

/// Rounds of the paired measurement.
const PAIRED_ROUNDS: usize = 2000;

/// Microseconds of one call of `f`.
fn time_once<R>(f: &mut impl FnMut() -> R) -> f64 {
    let t = Instant::now();
    black_box(f());
    t.elapsed().as_secs_f64() * 1e6
}

fn steppers(c: &mut Criterion) {
    // g written out (k = 0.07; wind: (x1 x2, (x1² − x2²)/2)), so that the benchmark times the
    // steppers, not the construction of problem structs; passed as the functions themselves
    // (not as `fn` pointers), so that, like the closures users write, they can be inlined into
    // the steppers and the kernel cost alike.
    fn duffing_g(y: &[f64], o: &mut [f64]) {
        o[0] = 0.0;
        o[1] = 2.0 * 0.07 * 0.07 * y[0] * y[0] * y[0];
    }
    fn wind_g(y: &[f64], o: &mut [f64]) {
        o[0] = y[0] * y[1];
        o[1] = 0.5 * (y[0] * y[0] - y[1] * y[1]);
    }
    let d = Duffing::default();
    let dy = d.initial_value();
    bench_problem(
        c,
        "duffing_d2",
        d.linear_matrix(),
        [dy[0], dy[1]],
        duffing_g,
    );
    let w = Wind::conservative();
    let wy = w.initial_value();
    bench_problem(c, "wind_d2", w.linear_matrix(), [wy[0], wy[1]], wind_g);
}

// No plots: criterion's plotting backend needs system fonts, which a fresh machine may lack.
criterion_group! {
    name = benches;
    config = Criterion::default().without_plots();
    targets = steppers
}
criterion_main!(benches);
