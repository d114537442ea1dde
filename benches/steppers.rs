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
//!
//! Then the speed issue's cases, each paired the same way: Duffing ω = 20, k = 0.07 (the
//! benchmark's problem) with r = 6, h = 1/16 (global error ≈ 5e−12 at T = 1000), macro
//! `Ec6<_, 2>` against the run-time `EcStepper` (dense operator, as `ecr run` builds it) and
//! both against their own g-evaluation cost: the time of as many evaluations of the same g
//! (`Duffing::nonlinear`) on the states of the run; and the FPU chain (m = 3, ω = 50) with
//! TCrP r = 3, h = 0.01: macro `Tc3<_, 6>` against the run-time `TcStepper`.

use criterion::{Criterion, criterion_group, criterion_main};
use ecr::ecr_method;
use ecr::problems::{Duffing, Wind};
use ecr::runtime::operator::{Dense, DenseStatic, PhiBank};
use ecr::runtime::stepper::{EcStepper, Kernel, SolverSettings, gemv_cm};
use ecr::runtime::system::Semilinear;
use nalgebra::{DMatrix, SMatrix};
use std::hint::black_box;
use std::time::Instant;

ecr_method!(r = 3);
ecr_method!(r = 6);
ecr_method!(r = 3, family = tc);

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
    let mut fixed_plain: Ec3<_, 2> =
        Ec3::with_settings(Semilinear::new(DenseStatic::new(sa).unwrap(), g), H, plain).unwrap();
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
    // The linear algebra of a step, from the macro stepper's own maps: once per step e^{cᵢhA} y₀
    // (s nodes) and the predictor, per sweep the stage matrices, at the end the moments, the
    // kernels at τ = 1, the double-double propagator and the propagated carried rounding error.
    let bank = fixed.bank().clone();
    let maps = fixed
        .fused_maps()
        .expect("d = 2, s = r: the stepper fuses its step")
        .clone();
    let (mut props, mut stages, mut moments) = ([0.0; 6], [0.0; 6], [0.1; 6]);
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
            gemv_cm(&maps.props, 6, [black_box(&y0), &[]], None, &mut props);
            gemv_cm(&maps.pred, 6, [black_box(&y0), &moments], None, &mut stages);
        }
        for _ in 0..sweeps {
            // The stepper's own fused sweep, sizes constant (as the fixed-order stepper has them).
            gemv_cm(
                &maps.stage,
                6,
                [black_box(&g_in), &[]],
                Some(&props),
                &mut stages,
            );
        }
        for _ in 0..STEPS {
            Ec3Kernel.legendre_moments(black_box(&g_in), &mut moments, 2);
            let (e, kernels) = maps.end.split_at(4);
            gemv_cm(kernels, 2, [black_box(&moments), &[]], None, &mut gout);
            bank.propagate_dd(3, black_box(&y0), &mut hi, &mut lo, &mut ());
            gemv_cm(e, 2, [black_box(&lo), &[]], None, &mut hi);
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

/// Steps of the issue cases per iteration.
const CASE_STEPS: usize = 1000;

/// Duffing ω = 20, r = 6, h = 1/16 and FPU TCrP r = 3: macro vs run-time vs g-evaluation cost.
fn issue_cases(c: &mut Criterion) {
    use ecr::problems::Fpu;
    use ecr::runtime::second_order::TcStepper;
    let d = Duffing::new(20.0, 0.07).unwrap();
    let h = 1.0 / 16.0;
    let settings = SolverSettings::default();
    let sa: SMatrix<f64, 2, 2> = SMatrix::from_iterator(d.linear_matrix().iter().copied());
    let p = d.clone();
    let g = move |y: &[f64], o: &mut [f64]| p.nonlinear(y, o);
    let mut fixed: Ec6<_, 2> = Ec6::with_settings(
        Semilinear::new(DenseStatic::new(sa).unwrap(), g.clone()),
        h,
        settings,
    )
    .unwrap();
    let mut rt = EcStepper::with_nodes(d.system().unwrap(), 6, 6, h, settings).unwrap();
    // The states of one iteration (for the g cost) and its g-evaluations and sweeps.
    let y0 = d.initial_value();
    let (mut states, mut g_evals, mut sweeps) = (Vec::new(), 0, 0);
    let mut y = [y0[0], y0[1]];
    for _ in 0..CASE_STEPS {
        let rep = fixed.step(&mut y).unwrap();
        g_evals += rep.g_evals;
        sweeps += rep.sweeps;
        states.push(y);
    }
    let start = [y0[0], y0[1]];
    let mut run_macro = move || run_n(start, CASE_STEPS, |y| fixed.step(y).map(drop));
    let mut run_rt = move || run_n(start, CASE_STEPS, |y| rt.step(y).map(drop));
    let per_state = g_evals.div_ceil(states.len());
    let mut run_g = move || {
        let mut o = [0.0; 2];
        let mut left = g_evals;
        for y in states.iter().cycle() {
            for _ in 0..per_state.min(left) {
                g(black_box(y), black_box(&mut o));
            }
            left = left.saturating_sub(per_state);
            if left == 0 {
                break;
            }
        }
        o
    };
    let mut group = c.benchmark_group("duffing_w20_r6");
    group.bench_function("macro Ec6<_, 2>", |b| b.iter(&mut run_macro));
    group.bench_function("run-time EcStepper r=6 (Dense)", |b| b.iter(&mut run_rt));
    group.bench_function("g-evaluation cost", |b| b.iter(&mut run_g));
    group.finish();
    let mut best = [f64::INFINITY; 3];
    for _ in 0..PAIRED_ROUNDS / 10 {
        best[0] = best[0].min(time_once(&mut run_macro));
        best[1] = best[1].min(time_once(&mut run_rt));
        best[2] = best[2].min(time_once(&mut run_g));
    }
    let [mac, rt, gc] = best;
    println!(
        "duffing_w20_r6 paired (fastest of {} rounds, per {CASE_STEPS} steps, {:.2} sweeps and \
         {:.1} g-evaluations per step): macro {mac:.1} µs, run-time {rt:.1} µs, g-evaluations \
         {gc:.1} µs; macro / g cost = {:.2}, run-time / g cost = {:.2}, run-time / macro = {:.2}",
        PAIRED_ROUNDS / 10,
        sweeps as f64 / CASE_STEPS as f64,
        g_evals as f64 / CASE_STEPS as f64,
        mac / gc,
        rt / gc,
        rt / mac
    );

    let fpu = Fpu::default();
    let (q0, p0) = fpu.initial_value();
    let mut fixed: Tc3<_, 6> = Tc3::with_settings(fpu.system().unwrap(), H, settings).unwrap();
    let mut rt = TcStepper::with_nodes(fpu.system().unwrap(), 3, 3, H, settings).unwrap();
    let (qa, pa) = (q0.clone(), p0.clone());
    let mut run_macro = move || {
        let (mut q, mut p) = (qa.clone(), pa.clone());
        for _ in 0..CASE_STEPS {
            fixed.step(black_box(&mut q), black_box(&mut p)).unwrap();
        }
        (q, p)
    };
    let mut run_rt = move || {
        let (mut q, mut p) = (q0.clone(), p0.clone());
        for _ in 0..CASE_STEPS {
            rt.step(black_box(&mut q), black_box(&mut p)).unwrap();
        }
        (q, p)
    };
    let mut group = c.benchmark_group("fpu_tc3");
    group.bench_function("macro Tc3<_, 6>", |b| b.iter(&mut run_macro));
    group.bench_function("run-time TcStepper r=3", |b| b.iter(&mut run_rt));
    group.finish();
    let mut best = [f64::INFINITY; 2];
    for _ in 0..PAIRED_ROUNDS / 10 {
        best[0] = best[0].min(time_once(&mut run_macro));
        best[1] = best[1].min(time_once(&mut run_rt));
    }
    println!(
        "fpu_tc3 paired (fastest of {} rounds, per {CASE_STEPS} steps): macro {:.1} µs, run-time \
         {:.1} µs; run-time / macro = {:.2}",
        PAIRED_ROUNDS / 10,
        best[0],
        best[1],
        best[1] / best[0]
    );
}

/// `n` steps of `step` from y0.
fn run_n(
    y0: [f64; 2],
    n: usize,
    mut step: impl FnMut(&mut [f64]) -> ecr::runtime::Result<()>,
) -> [f64; 2] {
    let mut y = y0;
    for _ in 0..n {
        step(black_box(&mut y)).unwrap();
    }
    y
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
    targets = steppers, issue_cases
}
criterion_main!(benches);
