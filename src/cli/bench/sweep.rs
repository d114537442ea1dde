//! The work–precision runs: for each problem and each method (series), a sweep of step sizes
//! (DOP853: tolerances), each point timed (median of repeated runs) and measured (global error
//! against a reference, max relative energy error).

use crate::cli::reproduce::methods::{
    self as registry, BoxedIntegrator, Dyn, Problem, boxed, ec, on_system,
};
use ecr_runtime::baselines::collocation::{ExpAvf, avf, gauss_collocation, rkepc2};
use ecr_runtime::baselines::dop853::Dop853;
use ecr_runtime::baselines::exponential::HochOst4;
use ecr_runtime::integrate::{IntegrateOptions, integrate};
use ecr_runtime::problems::{Duffing, Nls, Wind};
use ecr_runtime::second_order::{Omega, SecondOrder, TcStepper};
use ecr_runtime::stepper::{EcStepper, Predictor, SolverSettings};
use std::time::Instant;

/// The stage solver of every implicit method in the benchmark (ECrP, TCrP, HBVM family):
/// the defaults (tolerance 1e-15, convergence required) with the extrapolating predictor.
pub fn solver() -> SolverSettings {
    SolverSettings {
        predictor: Predictor::Extrapolate,
        ..SolverSettings::default()
    }
}

/// Stop refining a series once its global error is below this.
pub const ERROR_FLOOR: f64 = 1e-12;
/// Points less accurate than this are not recorded (the sweep goes on to smaller h).
pub const ERROR_CEILING: f64 = 1e-2;
/// Most halvings of h0 tried per series (points too inaccurate to record do not count as
/// attempts, so a method that needs a much smaller h than h0 still gets its points).
pub const MAX_HALVINGS: i32 = 24;
/// Tolerances of the DOP853 sweep (rtol = atol).
pub const DOP_TOLS: [f64; 12] = [
    1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14, 1e-15,
];

/// Sizes of the benchmark (full or `--quick`).
#[derive(Clone, Copy, Debug)]
pub struct Config {
    pub quick: bool,
    /// Timed runs per point (the median is reported).
    pub repeats: usize,
    /// Most points recorded per series.
    pub attempts: usize,
    /// A series stops after a point whose run took longer than this (seconds).
    pub budget: f64,
    pub duffing_t: f64,
    pub wind_t: f64,
    pub nls_t: f64,
    /// Interval of the equal-CPU-budget energy comparison (Duffing ω = 20).
    pub long_t: f64,
}

impl Config {
    pub fn new(quick: bool) -> Self {
        if quick {
            Config {
                quick,
                repeats: 1,
                attempts: 2,
                budget: 0.5,
                duffing_t: 2.0,
                wind_t: 2.0,
                nls_t: 0.2,
                long_t: 10.0,
            }
        } else {
            Config {
                quick,
                repeats: 3,
                attempts: 14,
                budget: 1.5,
                duffing_t: 1000.0,
                wind_t: 100.0,
                nls_t: 10.0,
                long_t: 1e4,
            }
        }
    }
}

/// What a series sweeps over.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Knob {
    /// Step sizes h0/2^i.
    Step { h0: f64 },
    /// DOP853 tolerances with a fixed macro step.
    Tol { macro_h: f64 },
}

type Build = Box<dyn Fn(f64) -> ecr_runtime::Result<BoxedIntegrator>>;
/// A registered method's constructor.
type RegistryBuild = fn(&Problem, f64) -> ecr_runtime::Result<BoxedIntegrator>;

/// One curve: a method with fixed parameters.
pub struct Series {
    pub label: String,
    /// Panel of the figures it is drawn in.
    pub group: &'static str,
    pub r: Option<usize>,
    pub s: Option<usize>,
    pub knob: Knob,
    /// Builds the integrator for h (Step) or tol (Tol).
    pub build: Build,
}

/// One measured point.
#[derive(Clone, Debug)]
pub struct Point {
    pub series: String,
    pub r: Option<usize>,
    pub s: Option<usize>,
    pub h: f64,
    pub tol: Option<f64>,
    /// Median wall-clock seconds of the integration (single-threaded).
    pub cpu: f64,
    /// max-norm of y(T) − y_ref(T).
    pub error: f64,
    /// max over every step of |H − H0| / |H0|.
    pub energy: f64,
}

/// One finished but unrecorded run of a series: its global error and its seconds.
#[derive(Clone, Debug)]
pub struct Attempt {
    pub series: String,
    pub error: f64,
    pub seconds: f64,
}

/// Everything measured for one problem.
pub struct ProblemRun {
    pub id: &'static str,
    pub title: String,
    pub t_end: f64,
    pub reference: String,
    pub reference_error: f64,
    /// (label, group) of every series, in order.
    pub series: Vec<(String, &'static str)>,
    pub points: Vec<Point>,
    /// Skipped points and failures, one line each.
    pub notes: Vec<String>,
    /// Finished runs too inaccurate to record (error > ERROR_CEILING), with the seconds of that
    /// run (including its per-step energy check).
    pub attempts: Vec<Attempt>,
}

/// Result of the equal-CPU-budget energy comparison.
pub struct LongRun {
    pub t_end: f64,
    pub ec_label: String,
    pub ec_h: f64,
    pub ec_cpu: f64,
    pub ec_energy: f64,
    pub dop_macro_h: f64,
    pub dop_tol: f64,
    pub dop_cpu: f64,
    pub dop_energy: f64,
    /// (tol, cpu) of every DOP853 run of the search.
    pub search: Vec<(f64, f64)>,
}

/// Everything `ecr bench` measured.
pub struct Results {
    pub problems: Vec<ProblemRun>,
    pub long: LongRun,
}

/// Duffing of the benchmark.
pub const OMEGA: f64 = 20.0;
pub const K: f64 = 0.07;
/// NLS grid.
pub const NLS_N: usize = 128;
/// EC reference (r, h) of the wind and NLS problems.
pub const WIND_REF: (usize, f64) = (6, 0.1 / 128.0);
pub const NLS_REF: (usize, f64) = (6, 0.1 / 256.0);

fn err_s(e: ecr_runtime::Error) -> String {
    e.to_string()
}

fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
}

/// Integrates from y0 over [0, t_end]; returns (y(T), seconds). Only the integration is timed.
fn timed(integrator: BoxedIntegrator, y0: &[f64], t_end: f64) -> Result<(Vec<f64>, f64), String> {
    let mut stepper = Dyn(integrator);
    let mut y = y0.to_vec();
    let options = IntegrateOptions {
        energy_every: 0,
        observe_every: 0,
    };
    let start = Instant::now();
    let result = integrate(&mut stepper, 0.0, t_end, &mut y, options, |_, _, _| {});
    let seconds = start.elapsed().as_secs_f64();
    result.map_err(err_s)?;
    if y.iter().any(|v| !v.is_finite()) {
        return Err("the solution is not finite".to_string());
    }
    Ok((y, seconds))
}

/// Integrates with H checked after every step; returns (y(T), max |H − H0|/|H0|, seconds).
fn with_energy(
    integrator: BoxedIntegrator,
    problem: &Problem,
    t_end: f64,
) -> Result<(Vec<f64>, f64, f64), String> {
    let mut stepper = Dyn(integrator);
    let mut y = problem.initial_value();
    let h0 = problem.energy(&y);
    let scale = h0.abs().max(f64::MIN_POSITIVE);
    let mut max_e = 0.0f64;
    let options = IntegrateOptions {
        energy_every: 0,
        observe_every: 1,
    };
    let start = Instant::now();
    let result = integrate(&mut stepper, 0.0, t_end, &mut y, options, |_, y, _| {
        let e = (problem.energy(y) - h0).abs() / scale;
        max_e = max_e.max(if e.is_finite() { e } else { f64::INFINITY });
    });
    let seconds = start.elapsed().as_secs_f64();
    result.map_err(err_s)?;
    if y.iter().any(|v| !v.is_finite()) {
        return Err("the solution is not finite".to_string());
    }
    Ok((y, max_e, seconds))
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Sweeps one series: step sizes h0/2^i (or the DOP853 tolerances) until the error is below
/// [`ERROR_FLOOR`], stagnates at round-off, a run exceeds the time budget, or `attempts`
/// points are recorded. Failed or too inaccurate points are skipped (noted).
#[allow(clippy::too_many_arguments)]
fn sweep(
    series: &Series,
    problem: &Problem,
    t_end: f64,
    y_ref: &[f64],
    c: &Config,
    points: &mut Vec<Point>,
    notes: &mut Vec<String>,
    attempts: &mut Vec<Attempt>,
) {
    let params: Vec<f64> = match series.knob {
        Knob::Step { h0 } => (0..MAX_HALVINGS).map(|i| h0 / 2f64.powi(i)).collect(),
        Knob::Tol { .. } if c.quick => vec![1e-5, 1e-9],
        Knob::Tol { .. } => DOP_TOLS.to_vec(),
    };
    let y0 = problem.initial_value();
    let mut last_error: Option<f64> = None;
    let mut skipped = Vec::new();
    for &x in &params {
        let what = match series.knob {
            Knob::Step { .. } => format!("h = {x:e}"),
            Knob::Tol { .. } => format!("tol = {x:e}"),
        };
        let measured = (series.build)(x)
            .map_err(err_s)
            .and_then(|i| with_energy(i, problem, t_end));
        let (y, energy, seconds) = match measured {
            Ok(m) => m,
            Err(e) => {
                skipped.push(format!("{what} ({e})"));
                continue;
            }
        };
        let error = max_diff(&y, y_ref);
        if error.is_nan() || error > ERROR_CEILING {
            attempts.push(Attempt {
                series: series.label.clone(),
                error,
                seconds,
            });
            skipped.push(format!("{what} (error {error:.1e})"));
            if seconds > c.budget {
                break;
            }
            continue;
        }
        let mut times = Vec::with_capacity(c.repeats);
        for _ in 0..c.repeats {
            match (series.build)(x)
                .map_err(err_s)
                .and_then(|i| timed(i, &y0, t_end))
            {
                Ok((_, t)) => times.push(t),
                Err(e) => {
                    skipped.push(format!("{what} (timed run: {e})"));
                    break;
                }
            }
        }
        if times.len() < c.repeats {
            continue;
        }
        let (h, tol) = match series.knob {
            Knob::Step { .. } => (x, None),
            Knob::Tol { macro_h } => (macro_h, Some(x)),
        };
        points.push(Point {
            series: series.label.clone(),
            r: series.r,
            s: series.s,
            h,
            tol,
            cpu: median(times),
            error,
            energy,
        });
        let stagnating = last_error.is_some_and(|p| error >= 0.5 * p && error < 1e-7);
        let recorded = points.iter().filter(|p| p.series == series.label).count();
        if error <= ERROR_FLOOR || stagnating || seconds > c.budget || recorded >= c.attempts {
            break;
        }
        last_error = Some(error);
    }
    if !skipped.is_empty() {
        notes.push(format!("{}: skipped {}", series.label, skipped.join("; ")));
    }
}

/// The reference y(T): EC r with step h, and its estimated error |ref(2h) − ref(h)|∞.
fn ec_reference(
    problem: &Problem,
    r: usize,
    h: f64,
    t_end: f64,
) -> Result<(Vec<f64>, f64), String> {
    let y0 = problem.initial_value();
    let run = |h| {
        ec(problem, r, r, h, solver())
            .map_err(err_s)
            .and_then(|i| timed(i, &y0, t_end))
            .map(|(y, _)| y)
    };
    let fine = run(h)?;
    let coarse = run(2.0 * h)?;
    let estimate = max_diff(&fine, &coarse);
    Ok((fine, estimate))
}

fn registry_build(name: &'static str) -> Result<RegistryBuild, String> {
    registry::methods()
        .into_iter()
        .find(|m| m.name == name)
        .map(|m| m.build)
        .ok_or_else(|| format!("method {name} is not registered"))
}

fn ec_series(problem: &Problem, r: usize, s: usize, h0: f64, group: &'static str) -> Series {
    let p = problem.clone();
    Series {
        label: if s == r {
            format!("EC{r}P")
        } else {
            format!("EC{r}P s={s}")
        },
        group,
        r: Some(r),
        s: Some(s),
        knob: Knob::Step { h0 },
        build: Box::new(move |h| ec(&p, r, s, h, solver())),
    }
}

fn step_series(
    label: &str,
    group: &'static str,
    h0: f64,
    build: impl Fn(f64) -> ecr_runtime::Result<BoxedIntegrator> + 'static,
) -> Series {
    Series {
        label: label.to_string(),
        group,
        r: None,
        s: None,
        knob: Knob::Step { h0 },
        build: Box::new(build),
    }
}

fn dop_series(problem: &Problem, macro_h: f64) -> Series {
    let p = problem.clone();
    Series {
        label: "DOP853".to_string(),
        group: "baselines",
        r: None,
        s: None,
        knob: Knob::Tol { macro_h },
        build: Box::new(
            move |tol| on_system!(&p, sys => boxed(Dop853::with_tolerances(sys, macro_h, tol, tol))),
        ),
    }
}

/// The baselines run on Duffing and wind (dense 2 × 2 / small systems).
fn dense_baselines(problem: &Problem, h0: f64) -> Result<Vec<Series>, String> {
    let settings = solver();
    let eei = registry_build("EEI3s4")?;
    let mut v = Vec::new();
    let p = problem.clone();
    v.push(step_series(
        "RKEPC2",
        "baselines",
        h0,
        move |h| on_system!(&p, sys => boxed(rkepc2(sys, h, settings))),
    ));
    let p = problem.clone();
    v.push(step_series("EEI3s4", "baselines", h0, move |h| eei(&p, h)));
    let p = problem.clone();
    v.push(step_series(
        "HochOst4",
        "baselines",
        h0,
        move |h| on_system!(&p, sys => boxed(HochOst4::new(sys, h))),
    ));
    let p = problem.clone();
    v.push(step_series(
        "Gauss2",
        "baselines",
        h0,
        move |h| on_system!(&p, sys => boxed(gauss_collocation(sys, 2, h, settings))),
    ));
    let p = problem.clone();
    v.push(step_series(
        "AVF",
        "baselines",
        h0,
        move |h| on_system!(&p, sys => boxed(avf(sys, 3, h, settings))),
    ));
    let p = problem.clone();
    v.push(step_series(
        "ExpAVF",
        "baselines",
        h0,
        move |h| on_system!(&p, sys => boxed(ExpAvf::new(sys, 3, h, settings))),
    ));
    Ok(v)
}

/// TCrP on the second-order form of Duffing: q'' + (ω² + k²) q = 2k²q³, i.e. ∇U = −2k²q³,
/// U = −k²q⁴/2.
fn tc_series(r: usize, h0: f64) -> Series {
    step_series(&format!("TC{r}P"), "TCrP", h0, move |h| {
        let k2 = K * K;
        let sys = SecondOrder::with_potential(
            Omega::scalar(OMEGA * OMEGA + k2, 1)?,
            move |q: &[f64], f: &mut [f64]| f[0] = -2.0 * k2 * q[0].powi(3),
            move |q: &[f64]| -0.5 * k2 * q[0].powi(4),
        );
        boxed(TcStepper::with_nodes(sys, r, r, h, solver()))
    })
    .with_rs(r, r)
}

impl Series {
    fn with_rs(mut self, r: usize, s: usize) -> Self {
        self.r = Some(r);
        self.s = Some(s);
        self
    }
}

#[allow(clippy::too_many_arguments)]
fn run_problem(
    id: &'static str,
    title: String,
    problem: &Problem,
    t_end: f64,
    reference: String,
    y_ref: Vec<f64>,
    reference_error: f64,
    series: &[Series],
    c: &Config,
) -> ProblemRun {
    let mut points = Vec::new();
    let mut notes = Vec::new();
    let mut attempts = Vec::new();
    for s in series {
        sweep(
            s,
            problem,
            t_end,
            &y_ref,
            c,
            &mut points,
            &mut notes,
            &mut attempts,
        );
        if !points.iter().any(|p| p.series == s.label) {
            notes.push(format!(
                "{}: no point with error ≤ {ERROR_CEILING:e}",
                s.label
            ));
        }
    }
    ProblemRun {
        id,
        title,
        t_end,
        reference,
        reference_error,
        series: series.iter().map(|s| (s.label.clone(), s.group)).collect(),
        points,
        notes,
        attempts,
    }
}

fn duffing(c: &Config) -> Result<ProblemRun, String> {
    let d = Duffing::new(OMEGA, K).map_err(err_s)?;
    let problem = Problem::Duffing(d.clone());
    let t = c.duffing_t;
    let y_ref = d.exact(t).map_err(err_s)?.to_vec();
    let h0 = if c.quick { 0.05 } else { 0.5 };
    let mut series = Vec::new();
    for r in 1..=6 {
        series.push(ec_series(&problem, r, r, h0, "ECrP, s = r"));
    }
    for r in 1..=6 {
        series.push(ec_series(&problem, r, r + 2, h0, "ECrP, s = r + 2"));
    }
    for r in 1..=6 {
        series.push(tc_series(r, h0));
    }
    series.extend(dense_baselines(&problem, h0)?);
    series.push(dop_series(&problem, 1.0));
    Ok(run_problem(
        "duffing",
        format!("Duffing ω = {OMEGA}, k = {K}, T = {t}"),
        &problem,
        t,
        "the exact solution (Jacobi sn, cn, dn)".to_string(),
        y_ref,
        0.0,
        &series,
        c,
    ))
}

fn wind(c: &Config) -> Result<ProblemRun, String> {
    let problem = Problem::Wind(Wind::conservative());
    let t = c.wind_t;
    let (r, h) = WIND_REF;
    let h = if c.quick { h * 4.0 } else { h };
    let (y_ref, est) = ec_reference(&problem, r, h, t)?;
    let h0 = if c.quick { 0.05 } else { 0.4 };
    let mut series = Vec::new();
    for r in 1..=6 {
        series.push(ec_series(&problem, r, r, h0, "ECrP"));
    }
    series.extend(dense_baselines(&problem, h0)?);
    series.push(dop_series(&problem, 1.0));
    Ok(run_problem(
        "wind",
        format!("conservative wind (θ = π/2), T = {t}"),
        &problem,
        t,
        format!(
            "EC{r}P (r = s = {r}, converged stage solver) with h = {h:e}; estimated error \
             |ref(2h) − ref(h)|∞ = {est:.1e}"
        ),
        y_ref,
        est,
        &series,
        c,
    ))
}

fn nls(c: &Config) -> Result<ProblemRun, String> {
    let n = Nls::new(NLS_N).map_err(err_s)?;
    let problem = Problem::Nls(n.clone());
    let t = c.nls_t;
    let (r, h) = NLS_REF;
    let h = if c.quick { h * 8.0 } else { h };
    let (y_ref, est) = ec_reference(&problem, r, h, t)?;
    let h0 = if c.quick { 0.05 } else { 0.2 };
    let mut series = Vec::new();
    for r in 1..=4 {
        series.push(ec_series(&problem, r, r, h0, "ECrP circulant"));
    }
    for r in 1..=4 {
        let n = n.clone();
        series.push(
            step_series(&format!("EC{r}P dense"), "ECrP dense", h0, move |h| {
                boxed(EcStepper::with_nodes(n.dense_system()?, r, r, h, solver()))
            })
            .with_rs(r, r),
        );
    }
    let eei = registry_build("EEI3s4")?;
    let p = problem.clone();
    series.push(step_series("EEI3s4", "baselines", h0, move |h| eei(&p, h)));
    let p = problem.clone();
    series.push(step_series(
        "RKEPC2",
        "baselines",
        h0,
        move |h| on_system!(&p, sys => boxed(rkepc2(sys, h, solver()))),
    ));
    series.push(dop_series(&problem, 0.5));
    Ok(run_problem(
        "nls",
        format!("NLS N = {NLS_N}, T = {t}"),
        &problem,
        t,
        format!(
            "EC{r}P (r = s = {r}, FFT operator, converged stage solver) with h = {h:e} = \
             0.1/2^{}; estimated error |ref(2h) − ref(h)|∞ = {est:.1e}",
            (0.1 / h).log2().round()
        ),
        y_ref,
        est,
        &series,
        c,
    ))
}

/// The equal-CPU-budget comparison on Duffing ω = 20 over [0, long_t]: EC2P with h = 0.01
/// against DOP853 with the tolerance whose CPU time is closest to EC2P's.
fn long_run(c: &Config) -> Result<LongRun, String> {
    let d = Duffing::new(OMEGA, K).map_err(err_s)?;
    let problem = Problem::Duffing(d);
    let t = c.long_t;
    let (r, ec_h) = (2, 0.01);
    let y0 = problem.initial_value();
    let build_ec = || ec(&problem, r, r, ec_h, solver()).map_err(err_s);
    let mut times = Vec::new();
    for _ in 0..c.repeats {
        times.push(timed(build_ec()?, &y0, t)?.1);
    }
    let ec_cpu = median(times);
    let (_, ec_energy, _) = with_energy(build_ec()?, &problem, t)?;
    let macro_h = 1.0;
    let build_dop = |tol: f64| {
        let build = || -> ecr_runtime::Result<BoxedIntegrator> {
            on_system!(&problem, sys => boxed(Dop853::with_tolerances(sys, macro_h, tol, tol)))
        };
        build().map_err(err_s)
    };
    // Bisection on log10(tol) in [−14, −3]: the CPU time falls as tol grows.
    let (mut lo, mut hi) = (-14.0f64, -3.0f64);
    let mut search = Vec::new();
    for _ in 0..if c.quick { 3 } else { 6 } {
        let mid = 0.5 * (lo + hi);
        let tol = 10f64.powf(mid);
        let cpu = timed(build_dop(tol)?, &y0, t)?.1;
        search.push((tol, cpu));
        if cpu > ec_cpu {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let &(dop_tol, _) = search
        .iter()
        .min_by(|a, b| {
            (a.1 / ec_cpu)
                .ln()
                .abs()
                .total_cmp(&(b.1 / ec_cpu).ln().abs())
        })
        .ok_or("no DOP853 run")?;
    let mut times = Vec::new();
    for _ in 0..c.repeats {
        times.push(timed(build_dop(dop_tol)?, &y0, t)?.1);
    }
    let dop_cpu = median(times);
    let (_, dop_energy, _) = with_energy(build_dop(dop_tol)?, &problem, t)?;
    Ok(LongRun {
        t_end: t,
        ec_label: format!("EC{r}P"),
        ec_h,
        ec_cpu,
        ec_energy,
        dop_macro_h: macro_h,
        dop_tol,
        dop_cpu,
        dop_energy,
        search,
    })
}

/// Runs the whole benchmark.
pub fn run_all(c: &Config) -> Result<Results, String> {
    let problems = vec![duffing(c)?, wind(c)?, nls(c)?];
    let long = long_run(c)?;
    Ok(Results { problems, long })
}
