//! The runs of the paper's §9: global-error studies, energy (Hamiltonian) studies and the
//! Lyapunov-function study, each over every registered method.

use super::methods::{Method, PRIMARY, Problem, ec};
use ecr::problems::{Duffing, Nls, Wind};
use ecr_runtime::integrate::{IntegrateOptions, Report, StepPlan, integrate};
use ecr_runtime::stepper::SolverSettings;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::cell::{Cell, RefCell};
use std::io::{IsTerminal, Write};
use std::time::{Duration, Instant};

/// Points per energy / Lyapunov curve (each the max over its window of steps).
pub const SAMPLES: usize = 1000;

/// Intervals of the experiments (the paper's, or shrunk by `--quick`).
#[derive(Clone, Copy, Debug)]
pub struct Config {
    /// `--quick`.
    pub quick: bool,
    /// Problem 1, global errors: [0, T].
    pub p1_error_t: f64,
    /// Problem 1, energy: [0, T], h = 1/100.
    pub p1_energy_t: f64,
    /// Problem 2, global errors (both θ): [0, T].
    pub p2_error_t: f64,
    /// Problem 2, energy (θ = π/2): [0, T], h = 1/200.
    pub p2_energy_t: f64,
    /// Problem 2, Lyapunov function (θ = π/2 − 1e−4): [0, T], h = 1/20.
    pub p2_lyapunov_t: f64,
    /// Problem 3, global errors: [0, T].
    pub p3_error_t: f64,
    /// Problem 3, energy: [0, T], h = 1/200.
    pub p3_energy_t: f64,
}

impl Config {
    /// The paper's intervals, or (quick) about 1/100 of them.
    pub fn new(quick: bool) -> Self {
        if quick {
            Config {
                quick,
                p1_error_t: 10.0,
                p1_energy_t: 100.0,
                p2_error_t: 10.0,
                p2_energy_t: 100.0,
                p2_lyapunov_t: 10.0,
                p3_error_t: 1.0,
                p3_energy_t: 10.0,
            }
        } else {
            Config {
                quick,
                p1_error_t: 1000.0,
                p1_energy_t: 10000.0,
                p2_error_t: 1000.0,
                p2_energy_t: 10000.0,
                // The paper does not state the interval of its Lyapunov-function figure.
                p2_lyapunov_t: 1000.0,
                p3_error_t: 10.0,
                p3_energy_t: 1000.0,
            }
        }
    }
}

/// Duffing frequencies of Problem 1.
pub const OMEGAS: [f64; 3] = [5.0, 10.0, 20.0];
/// Duffing nonlinearity of Problem 1.
pub const DUFFING_K: f64 = 0.07;
/// Wind radius of Problem 2 (the paper's "r = 20").
pub const WIND_RADIUS: f64 = 20.0;
/// Deviation π/2 − θ of the dissipative wind case.
pub const WIND_DELTA: f64 = 1e-4;
/// NLS grid size of Problem 3.
pub const NLS_N: usize = 128;

/// Step sizes 0.1/2^i for i in `range`.
fn halvings(range: std::ops::RangeInclusive<i32>) -> Vec<f64> {
    range.map(|i| 0.1 / 2f64.powi(i)).collect()
}

/// Number of steps `integrate` takes for [0, t] with step h ([`StepPlan`]; 0 for an interval
/// it refuses).
fn steps_for(t: f64, h: f64) -> u64 {
    StepPlan::new(0.0, t, h).map_or(0, |p| p.steps() as u64)
}

/// How the reference solution of an error study is computed.
#[derive(Clone, Copy, Debug)]
pub enum Reference {
    /// The exact solution (Duffing: Jacobi sn).
    Exact,
    /// ECrP with r = s = `r`, converged stage solver, step `h`; its own error is estimated by
    /// comparing with the same method at 2h.
    Ec { r: usize, h: f64 },
}

impl Reference {
    /// A sentence for the report.
    pub fn describe(&self) -> String {
        match self {
            Reference::Exact => {
                "the exact solution q(t) = sn(ωt; k/ω), p = q' (Jacobi elliptic functions, \
                 modulus k/ω)"
                    .to_string()
            }
            Reference::Ec { r, h } => format!(
                "EC{r}P (r = s = {r}, order {}, stage equations iterated to convergence) with \
                 h = {h:e} = 0.1/2^{}",
                2 * r,
                (0.1 / h).log2().round()
            ),
        }
    }
}

/// One run of an error study.
#[derive(Clone, Debug)]
pub struct ErrorRun {
    pub method: String,
    /// The step size asked for (for a method that chooses its own steps: the output step).
    pub h: f64,
    /// The steps taken: T/h, or those the method chose.
    pub steps: usize,
    /// The method chose its own steps (DOP853): `steps` is not T/h.
    pub own_steps: bool,
    /// max-norm of y(T) − y_ref(T).
    pub error: f64,
    pub seconds: f64,
    pub sweeps: usize,
    pub g_evals: usize,
    pub unconverged_steps: usize,
}

/// A global-error study (one sub-panel "log10 error vs log10(T/h)").
#[derive(Clone, Debug)]
pub struct ErrorStudy {
    /// Sub-panel id, e.g. "p1-1a".
    pub id: String,
    /// Problem description, e.g. "Duffing ω = 5".
    pub label: String,
    pub t_end: f64,
    pub reference: Reference,
    /// Estimated error of the reference (|ref(2h) − ref(h)|∞, an upper estimate); 0 for the
    /// exact solution.
    pub reference_error: f64,
    pub reference_seconds: f64,
    pub runs: Vec<ErrorRun>,
    /// (method, message) of the methods that failed.
    pub failures: Vec<(String, String)>,
}

/// One run of an energy study.
#[derive(Clone, Debug)]
pub struct EnergyRun {
    pub method: String,
    pub steps: usize,
    pub seconds: f64,
    /// (t at the end of the window, max |H − H0| over the window's steps).
    pub samples: Vec<(f64, f64)>,
    /// max |H − H0| over every step.
    pub max_abs: f64,
    /// |H(T) − H0|.
    pub end_abs: f64,
    pub sweeps: usize,
    pub unconverged_steps: usize,
}

/// An energy study (one sub-panel "log10 |H − H0| vs t").
#[derive(Clone, Debug)]
pub struct EnergyStudy {
    pub id: String,
    pub label: String,
    pub t_end: f64,
    pub h: f64,
    /// H(y0).
    pub h0: f64,
    pub runs: Vec<EnergyRun>,
    pub failures: Vec<(String, String)>,
}

/// One run of the Lyapunov study.
#[derive(Clone, Debug)]
pub struct LyapunovRun {
    pub method: String,
    pub steps: usize,
    pub seconds: f64,
    /// (t, H(y(t))) at the sample times.
    pub samples: Vec<(f64, f64)>,
    /// max over the sample times of |H − H_ref|.
    pub max_dev: f64,
    /// Largest increase of H between consecutive samples (should be ≤ 0 up to round-off).
    pub max_increase: f64,
}

/// The Lyapunov-function study of the dissipative wind problem.
#[derive(Clone, Debug)]
pub struct LyapunovStudy {
    pub id: String,
    pub label: String,
    pub t_end: f64,
    pub h: f64,
    pub reference_h: f64,
    pub reference: LyapunovRun,
    pub runs: Vec<LyapunovRun>,
    pub failures: Vec<(String, String)>,
}

/// Everything `ecr reproduce` computed.
#[derive(Clone, Debug)]
pub struct Results {
    pub p1_errors: Vec<ErrorStudy>,
    pub p1_energy: Vec<EnergyStudy>,
    pub p2_errors: ErrorStudy,
    pub p2_energy: EnergyStudy,
    pub p2d_errors: ErrorStudy,
    pub p2d_lyapunov: LyapunovStudy,
    pub p3_errors: ErrorStudy,
    pub p3_energy: EnergyStudy,
}

/// Expected wall time of one step of `method` on `problem`, in microseconds (measured with a
/// release build, one core; only the ratios matter). The progress bar counts steps weighted by
/// it, so that its position, and the ETA indicatif derives from the rate, track time: counted
/// in plain steps, the bar reached 99 % before the NLS runs, which take most of the time.
/// Methods not listed count as the most expensive of their problem class.
pub fn step_cost(method: &str, problem: &Problem) -> f64 {
    let nls = matches!(problem, Problem::Nls(_));
    // (Duffing / wind: d = 2, NLS: d = 256 with FFTs.)
    let (small, large) = match method {
        "EC2P" => (0.7, 63.0),
        "EC2P-conv" => (0.8, 74.0),
        "RKEPC2" => (1.4, 136.0),
        "RKEPC2-conv" => (3.0, 1000.0),
        "EEI3s4" => (2.0, 300.0),
        "DOP853" => (6.0, 120.0),
        REFERENCE_METHOD => (20.0, 62.0),
        _ => (6.0, 1000.0),
    };
    if nls { large } else { small }
}

/// The name [`step_cost`] knows the reference runs of the error studies by.
const REFERENCE_METHOD: &str = "reference";

/// Progress over all the runs of the reproduction, each step weighted by its expected cost
/// ([`step_cost`]), on stderr: a bar when stderr is a terminal, otherwise plain lines (CI logs,
/// pipes), one at the start, then at most one every [`LINE_EVERY`], and one at the end. The
/// time left is the time so far scaled by the work left ([`Eta`]), shown once a share of the
/// work is done, rather than indicatif's estimate from the recent rate, which read 47 minutes
/// at the start of a three-minute run.
pub struct Progress {
    bar: Option<ProgressBar>,
    lines: Option<RefCell<Lines>>,
    eta: Eta,
    done: Cell<u64>,
}

/// Plain progress lines: when the last one was printed, and the message of the current run.
struct Lines {
    last: Instant,
    message: String,
}

/// At most one plain progress line per this interval.
pub const LINE_EVERY: Duration = Duration::from_secs(15);

/// Every plain progress line starts with this.
pub const LINE_PREFIX: &str = "progress: ";

/// The time left, from the time so far and the share of the (weighted) work done.
#[derive(Clone, Copy, Debug)]
pub struct Eta {
    start: Instant,
    total: u64,
}

impl Eta {
    /// No estimate before this share of the work is done.
    const MIN_SHARE: f64 = 0.02;

    /// The time left after `done` of `total`, or None while the share done is below
    /// [`Eta::MIN_SHARE`].
    pub fn left(&self, done: u64, elapsed: Duration) -> Option<Duration> {
        let share = done as f64 / self.total.max(1) as f64;
        (share >= Self::MIN_SHARE).then(|| {
            Duration::from_secs_f64(elapsed.as_secs_f64() * (1.0 - share.min(1.0)) / share)
        })
    }
}

/// "42s", "3m05s", "1h02m".
pub fn duration_text(d: Duration) -> String {
    let s = d.as_secs_f64().round() as u64;
    match s {
        0..60 => format!("{s}s"),
        60..3600 => format!("{}m{:02}s", s / 60, s % 60),
        _ => format!("{}h{:02}m", s / 3600, s % 3600 / 60),
    }
}

impl Progress {
    fn new(total: u64) -> Self {
        let eta = Eta {
            start: Instant::now(),
            total,
        };
        let terminal = std::io::stderr().is_terminal();
        let bar = terminal.then(|| {
            let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
            if let Ok(style) = ProgressStyle::with_template(
                "{elapsed_precise} [{bar:30}] {percent:>3}% {prefix} {msg}",
            ) {
                bar.set_style(style.progress_chars("=> "));
            }
            bar.set_prefix("eta  …");
            bar
        });
        let lines = (!terminal).then(|| {
            RefCell::new(Lines {
                last: eta.start,
                message: String::new(),
            })
        });
        let progress = Progress {
            bar,
            lines,
            eta,
            done: Cell::new(0),
        };
        if progress.lines.is_some() {
            progress.line("starting");
        }
        progress
    }

    /// A plain line (not on a terminal): "progress: 37% after 1m05s, about 1m50s left: …".
    fn line(&self, what: &str) {
        let elapsed = self.eta.start.elapsed();
        let done = self.done.get();
        let share = 100.0 * done as f64 / self.eta.total.max(1) as f64;
        let left = self.eta.left(done, elapsed).map_or_else(
            || "time left not yet known".to_string(),
            |d| format!("about {} left", duration_text(d)),
        );
        // A failed write to stderr (full, closed) is ignored: the run goes on.
        let _ = writeln!(
            std::io::stderr(),
            "{LINE_PREFIX}{share:3.0}% after {}, {left}: {what}",
            duration_text(elapsed)
        );
    }

    /// Prints a plain line if the last one is [`LINE_EVERY`] old.
    fn maybe_line(&self) {
        let Some(lines) = &self.lines else { return };
        let due = lines.borrow().last.elapsed() >= LINE_EVERY;
        if due {
            let message = {
                let mut l = lines.borrow_mut();
                l.last = Instant::now();
                l.message.clone()
            };
            self.line(&message);
        }
    }

    fn message(&self, msg: String) {
        if let Some(bar) = &self.bar {
            bar.set_message(msg);
        } else if let Some(lines) = &self.lines {
            lines.borrow_mut().message = msg;
            self.maybe_line();
        }
    }

    /// Advances by `steps` steps of `cost` µs each (the bar counts nanoseconds).
    fn inc(&self, steps: u64, cost: f64) {
        let n = (steps as f64 * cost * 1e3) as u64;
        self.done.set(self.done.get() + n);
        if let Some(bar) = &self.bar {
            bar.inc(n);
            let eta = self.eta.left(self.done.get(), self.eta.start.elapsed());
            bar.set_prefix(eta.map_or_else(
                || "eta  …".to_string(),
                |d| format!("eta {}", duration_text(d)),
            ));
        } else {
            self.maybe_line();
        }
    }

    fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        } else {
            let _ = writeln!(
                std::io::stderr(),
                "{LINE_PREFIX}done in {}",
                duration_text(self.eta.start.elapsed())
            );
        }
    }
}

/// What one integration produced.
struct Outcome {
    report: Report,
    y: Vec<f64>,
    seconds: f64,
    /// The steps a method that chooses its own took ([`Harness::own_steps`](super::methods::Harness::own_steps)).
    own_steps: Option<usize>,
}

/// Integrates `problem` on [0, t_end] with a built integrator, calling `observer(t, y, H)`
/// every `observe_every` steps (0: never) and advancing the progress bar by `cost` per step.
// One flat list of the run's parameters reads better here than a one-use struct.
#[allow(clippy::too_many_arguments)]
fn run_one(
    mut stepper: super::methods::BoxedIntegrator,
    problem: &Problem,
    t_end: f64,
    observe_every: usize,
    progress: &Progress,
    cost: f64,
    mut observer: impl FnMut(f64, &[f64], Option<f64>),
) -> Result<Outcome, String> {
    let h = stepper.step_size();
    let mut y = problem.initial_value();
    let total = steps_for(t_end, h);
    // Observe at least every ~1/200 of the run so the bar moves.
    let tick = (total / 200).max(1) as usize;
    let every = if observe_every == 0 {
        tick
    } else {
        observe_every
    };
    let mut done = 0u64;
    let start = Instant::now();
    let report = integrate(
        &mut stepper,
        0.0,
        t_end,
        &mut y,
        IntegrateOptions {
            energy_every: 0,
            observe_every: every,
        },
        |t, y, e| {
            let n = ((t / h).round() as u64).min(total);
            if n >= done + tick as u64 || n == total {
                progress.inc(n - done, cost);
                done = n;
            }
            if observe_every > 0 {
                observer(t, y, e);
            }
        },
    )
    .map_err(|e| e.to_string());
    progress.inc(total.saturating_sub(done), cost);
    let report = report?;
    if y.iter().any(|v| !v.is_finite()) {
        return Err(format!(
            "the solution is not finite at t = {}",
            report.t_end
        ));
    }
    Ok(Outcome {
        report,
        y,
        seconds: start.elapsed().as_secs_f64(),
        own_steps: stepper.own_steps(),
    })
}

fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
}

/// The reference state at t_end and its estimated error.
fn reference_state(
    problem: &Problem,
    reference: Reference,
    t_end: f64,
    progress: &Progress,
) -> Result<(Vec<f64>, f64, f64), String> {
    match (reference, problem) {
        (Reference::Exact, Problem::Duffing(d)) => {
            let y = d.exact(t_end).map_err(|e| e.to_string())?;
            Ok((y.to_vec(), 0.0, 0.0))
        }
        (Reference::Exact, _) => Err("no exact solution known".to_string()),
        (Reference::Ec { r, h }, _) => {
            let build =
                |h| ec(problem, r, r, h, SolverSettings::default()).map_err(|e| e.to_string());
            let cost = step_cost(REFERENCE_METHOD, problem);
            let coarse = run_one(
                build(2.0 * h)?,
                problem,
                t_end,
                0,
                progress,
                cost,
                |_, _, _| {},
            )?;
            let fine = run_one(build(h)?, problem, t_end, 0, progress, cost, |_, _, _| {})?;
            // |ref(2h) − ref(h)| estimates the error of the coarser run: an upper estimate for
            // the reference (unless both sit at the round-off floor).
            let estimate = max_diff(&coarse.y, &fine.y);
            Ok((fine.y, estimate, coarse.seconds + fine.seconds))
        }
    }
}

// One flat list of the study's parameters reads better here than a one-use struct.
#[allow(clippy::too_many_arguments)]
fn error_study(
    id: &str,
    label: String,
    problem: &Problem,
    reference: Reference,
    t_end: f64,
    hs: &[f64],
    methods: &[Method],
    progress: &Progress,
) -> Result<ErrorStudy, String> {
    progress.message(format!("{id} {label}: reference"));
    let (y_ref, reference_error, reference_seconds) =
        reference_state(problem, reference, t_end, progress)
            .map_err(|e| format!("{id} ({label}): reference run failed: {e}"))?;
    let mut study = ErrorStudy {
        id: id.to_string(),
        label: label.clone(),
        t_end,
        reference,
        reference_error,
        reference_seconds,
        runs: Vec::new(),
        failures: Vec::new(),
    };
    for m in methods {
        for &h in hs {
            progress.message(format!("{id} {label}: {} h = {h}", m.name));
            let outcome = (m.build)(problem, h)
                .map_err(|e| e.to_string())
                .and_then(|i| {
                    let cost = step_cost(m.name, problem);
                    run_one(i, problem, t_end, 0, progress, cost, |_, _, _| {})
                });
            match outcome {
                Ok(o) => study.runs.push(ErrorRun {
                    method: m.name.to_string(),
                    h,
                    steps: o.own_steps.unwrap_or(o.report.steps),
                    own_steps: o.own_steps.is_some(),
                    error: max_diff(&o.y, &y_ref),
                    seconds: o.seconds,
                    sweeps: o.report.sweeps,
                    g_evals: o.report.g_evals,
                    unconverged_steps: o.report.unconverged_steps,
                }),
                Err(e) => {
                    study
                        .failures
                        .push((m.name.to_string(), format!("h = {h}: {e}")));
                    // Skip the method's remaining step sizes: don't mix partial curves.
                    study.runs.retain(|r| r.method != m.name);
                    break;
                }
            }
        }
    }
    Ok(study)
}

fn energy_study(
    id: &str,
    label: String,
    problem: &Problem,
    t_end: f64,
    h: f64,
    methods: &[Method],
    progress: &Progress,
) -> EnergyStudy {
    let y0 = problem.initial_value();
    let h0 = problem.energy(&y0);
    let total = steps_for(t_end, h) as usize;
    let window = total.div_ceil(SAMPLES).max(1);
    let mut study = EnergyStudy {
        id: id.to_string(),
        label: label.clone(),
        t_end,
        h,
        h0,
        runs: Vec::new(),
        failures: Vec::new(),
    };
    for m in methods {
        progress.message(format!("{id} {label}: {} h = {h}", m.name));
        let mut samples = Vec::with_capacity(SAMPLES + 1);
        let (mut window_max, mut count, mut max_abs) = (0.0f64, 0usize, 0.0f64);
        let outcome = (m.build)(problem, h)
            .map_err(|e| e.to_string())
            .and_then(|i| {
                let cost = step_cost(m.name, problem);
                run_one(i, problem, t_end, 1, progress, cost, |t, y, e| {
                    if t == 0.0 {
                        return;
                    }
                    let e = e.unwrap_or_else(|| problem.energy(y));
                    let err = (e - h0).abs();
                    let err = if err.is_finite() { err } else { f64::MAX };
                    window_max = window_max.max(err);
                    max_abs = max_abs.max(err);
                    count += 1;
                    if count == window || t >= t_end {
                        samples.push((t, window_max));
                        window_max = 0.0;
                        count = 0;
                    }
                })
            });
        match outcome {
            Ok(o) => {
                let end_abs = (problem.energy(&o.y) - h0).abs();
                study.runs.push(EnergyRun {
                    method: m.name.to_string(),
                    steps: o.report.steps,
                    seconds: o.seconds,
                    samples,
                    max_abs,
                    end_abs,
                    sweeps: o.report.sweeps,
                    unconverged_steps: o.report.unconverged_steps,
                });
            }
            Err(e) => study.failures.push((m.name.to_string(), e)),
        }
    }
    study
}

/// Runs with samples of H every `dt` (which must be a multiple of h).
fn lyapunov_run(
    name: &str,
    integrator: super::methods::BoxedIntegrator,
    problem: &Problem,
    t_end: f64,
    dt: f64,
    progress: &Progress,
) -> Result<LyapunovRun, String> {
    let h = integrator.step_size();
    let every = (dt / h).round().max(1.0) as usize;
    let mut samples = Vec::new();
    let cost = step_cost(name, problem);
    let o = run_one(
        integrator,
        problem,
        t_end,
        every,
        progress,
        cost,
        |t, y, e| {
            samples.push((t, e.unwrap_or_else(|| problem.energy(y))));
        },
    )?;
    let max_increase = samples
        .windows(2)
        .fold(f64::NEG_INFINITY, |m, w| m.max(w[1].1 - w[0].1));
    Ok(LyapunovRun {
        method: name.to_string(),
        steps: o.report.steps,
        seconds: o.seconds,
        samples,
        max_dev: 0.0,
        max_increase: if max_increase.is_finite() {
            max_increase
        } else {
            0.0
        },
    })
}

// One flat list of the study's parameters reads better here than a one-use struct.
#[allow(clippy::too_many_arguments)]
fn lyapunov_study(
    id: &str,
    label: String,
    problem: &Problem,
    t_end: f64,
    h: f64,
    reference_h: f64,
    methods: &[Method],
    progress: &Progress,
) -> Result<LyapunovStudy, String> {
    // Sample times: multiples of dt, a multiple of both step sizes (h = 1/20, h_ref = 1/1000).
    let dt = (t_end / SAMPLES as f64 / h).round().max(1.0) * h;
    progress.message(format!(
        "{id} {label}: reference {PRIMARY} h = {reference_h}"
    ));
    let primary = methods
        .iter()
        .find(|m| m.name == PRIMARY)
        .ok_or_else(|| format!("method {PRIMARY} is not registered"))?;
    let reference = (primary.build)(problem, reference_h)
        .map_err(|e| e.to_string())
        .and_then(|i| lyapunov_run(PRIMARY, i, problem, t_end, dt, progress))
        .map_err(|e| format!("{id}: reference run failed: {e}"))?;
    let mut study = LyapunovStudy {
        id: id.to_string(),
        label: label.clone(),
        t_end,
        h,
        reference_h,
        reference,
        runs: Vec::new(),
        failures: Vec::new(),
    };
    for m in methods {
        progress.message(format!("{id} {label}: {} h = {h}", m.name));
        match (m.build)(problem, h)
            .map_err(|e| e.to_string())
            .and_then(|i| lyapunov_run(m.name, i, problem, t_end, dt, progress))
        {
            Ok(mut run) => {
                run.max_dev = run
                    .samples
                    .iter()
                    .zip(&study.reference.samples)
                    .fold(0.0f64, |acc, (a, b)| acc.max((a.1 - b.1).abs()));
                study.runs.push(run);
            }
            Err(e) => study.failures.push((m.name.to_string(), e)),
        }
    }
    Ok(study)
}

/// Step sizes of the error studies.
pub fn p1_error_steps() -> Vec<f64> {
    halvings(0..=3)
}
/// Step sizes of the wind error studies.
pub fn p2_error_steps() -> Vec<f64> {
    halvings(1..=4)
}
/// Step sizes of the NLS error study.
pub fn p3_error_steps() -> Vec<f64> {
    halvings(3..=6)
}
/// Energy / Lyapunov step sizes.
pub const P1_ENERGY_H: f64 = 0.01;
pub const P2_ENERGY_H: f64 = 1.0 / 200.0;
pub const P2_LYAPUNOV_H: f64 = 1.0 / 20.0;
pub const P2_LYAPUNOV_REF_H: f64 = 1.0 / 1000.0;
pub const P3_ENERGY_H: f64 = 1.0 / 200.0;
/// References of the wind and NLS error studies.
pub const P2_REFERENCE: Reference = Reference::Ec {
    r: 4,
    h: 0.1 / 64.0,
};
pub const P3_REFERENCE: Reference = Reference::Ec {
    r: 4,
    h: 0.1 / 256.0,
};

/// Expected cost of all runs, in the progress bar's unit (steps × [`step_cost`] in ns).
fn total_cost(
    c: &Config,
    methods: &[Method],
    duffing: &Problem,
    wind: &Problem,
    nls: &Problem,
) -> u64 {
    let steps = |t: f64, hs: &[f64]| hs.iter().map(|&h| steps_for(t, h)).sum::<u64>() as f64;
    // Every method for `n` steps of `p`.
    let all = |p: &Problem, n: f64| {
        methods
            .iter()
            .map(|m| n * step_cost(m.name, p))
            .sum::<f64>()
    };
    let reference = |p: &Problem, t: f64, r: Reference| match r {
        Reference::Exact => 0.0,
        Reference::Ec { h, .. } => steps(t, &[h, 2.0 * h]) * step_cost(REFERENCE_METHOD, p),
    };
    let mut total = 0.0;
    total += 3.0 * all(duffing, steps(c.p1_error_t, &p1_error_steps()));
    total += 3.0 * all(duffing, steps(c.p1_energy_t, &[P1_ENERGY_H]));
    total += 2.0
        * (all(wind, steps(c.p2_error_t, &p2_error_steps()))
            + reference(wind, c.p2_error_t, P2_REFERENCE));
    total += all(wind, steps(c.p2_energy_t, &[P2_ENERGY_H]));
    total += all(wind, steps(c.p2_lyapunov_t, &[P2_LYAPUNOV_H]))
        + steps(c.p2_lyapunov_t, &[P2_LYAPUNOV_REF_H]) * step_cost(PRIMARY, wind);
    total += all(nls, steps(c.p3_error_t, &p3_error_steps()))
        + reference(nls, c.p3_error_t, P3_REFERENCE);
    total += all(nls, steps(c.p3_energy_t, &[P3_ENERGY_H]));
    (total * 1e3) as u64
}

/// Runs every experiment of §9 with every method.
pub fn run_all(c: &Config, methods: &[Method]) -> Result<Results, String> {
    let err = |e: ecr_runtime::Error| e.to_string();
    let duffings = OMEGAS
        .iter()
        .map(|&omega| Duffing::new(omega, DUFFING_K).map(Problem::Duffing))
        .collect::<Result<Vec<_>, _>>()
        .map_err(err)?;
    let wind = Problem::Wind(Wind::conservative());
    let nls = Problem::Nls(Nls::new(NLS_N).map_err(err)?);
    let progress = Progress::new(total_cost(c, methods, &duffings[0], &wind, &nls));
    let mut p1_errors = Vec::new();
    let mut p1_energy = Vec::new();
    for (i, &omega) in OMEGAS.iter().enumerate() {
        let sub = ['a', 'b', 'c'][i];
        let problem = &duffings[i];
        let label = format!("Duffing, ω = {omega}");
        p1_errors.push(error_study(
            &format!("p1-1{sub}"),
            label.clone(),
            problem,
            Reference::Exact,
            c.p1_error_t,
            &p1_error_steps(),
            methods,
            &progress,
        )?);
        p1_energy.push(energy_study(
            &format!("p1-2{sub}"),
            label,
            problem,
            c.p1_energy_t,
            P1_ENERGY_H,
            methods,
            &progress,
        ));
    }
    let p2_errors = error_study(
        "p2-1a",
        "wind, θ = π/2".to_string(),
        &wind,
        P2_REFERENCE,
        c.p2_error_t,
        &p2_error_steps(),
        methods,
        &progress,
    )?;
    let p2_energy = energy_study(
        "p2-1b",
        "wind, θ = π/2".to_string(),
        &wind,
        c.p2_energy_t,
        P2_ENERGY_H,
        methods,
        &progress,
    );
    let dissipative = Problem::Wind(Wind::from_deviation(WIND_DELTA, WIND_RADIUS).map_err(err)?);
    let p2d_errors = error_study(
        "p2-2a",
        "wind, θ = π/2 − 1e-4".to_string(),
        &dissipative,
        P2_REFERENCE,
        c.p2_error_t,
        &p2_error_steps(),
        methods,
        &progress,
    )?;
    let p2d_lyapunov = lyapunov_study(
        "p2-2b",
        "wind, θ = π/2 − 1e-4".to_string(),
        &dissipative,
        c.p2_lyapunov_t,
        P2_LYAPUNOV_H,
        P2_LYAPUNOV_REF_H,
        methods,
        &progress,
    )?;
    let p3_errors = error_study(
        "p3a",
        format!("NLS, N = {NLS_N}"),
        &nls,
        P3_REFERENCE,
        c.p3_error_t,
        &p3_error_steps(),
        methods,
        &progress,
    )?;
    let p3_energy = energy_study(
        "p3b",
        format!("NLS, N = {NLS_N}"),
        &nls,
        c.p3_energy_t,
        P3_ENERGY_H,
        methods,
        &progress,
    );
    progress.finish();
    Ok(Results {
        p1_errors,
        p1_energy,
        p2_errors,
        p2_energy,
        p2d_errors,
        p2d_lyapunov,
        p3_errors,
        p3_energy,
    })
}

/// An observed order and the points it rests on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrderFit {
    /// The slope; None with fewer than two usable points.
    pub order: Option<f64>,
    /// Points fitted.
    pub used: usize,
    /// Points left out: at or below the floor (reference error or round-off).
    pub excluded: usize,
}

impl OrderFit {
    /// A table cell: "4.01", "4.01 (3 h)" when points were left out, "—" otherwise.
    pub fn cell(&self) -> String {
        match (self.order, self.excluded) {
            (Some(p), 0) => format!("{p:.2}"),
            (Some(p), _) => format!("{p:.2} ({} h)", self.used),
            (None, 0) => "—".to_string(),
            (None, _) => "— (at floor)".to_string(),
        }
    }
}

/// Least-squares slope of log10(error) against log10(h) (the observed order), over the runs
/// of `method` with a finite error above `floor` (points at the reference's error or at
/// round-off would flatten the slope); no order with fewer than two such points.
pub fn observed_order(runs: &[ErrorRun], method: &str, floor: f64) -> OrderFit {
    let mine = runs
        .iter()
        .filter(|r| r.method == method && r.error.is_finite());
    let pts: Vec<(f64, f64)> = mine
        .clone()
        .filter(|r| r.error > floor && r.error > 0.0)
        .map(|r| (r.h.log10(), r.error.log10()))
        .collect();
    let excluded = mine.count() - pts.len();
    let fit = |order| OrderFit {
        order,
        used: pts.len(),
        excluded,
    };
    if pts.len() < 2 {
        return fit(None);
    }
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    fit((sxx > 0.0).then(|| sxy / sxx))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(h: f64, error: f64) -> ErrorRun {
        ErrorRun {
            method: "M".to_string(),
            h,
            steps: 1,
            own_steps: false,
            error,
            seconds: 0.0,
            sweeps: 0,
            g_evals: 0,
            unconverged_steps: 0,
        }
    }

    /// A point at the floor (reference error or round-off) is left out of the fitted order
    /// and counted as such.
    #[test]
    fn observed_order_leaves_out_points_at_the_floor() {
        let runs: Vec<ErrorRun> = [(0.1, 1e-5), (0.05, 6.25e-7), (0.025, 3.90625e-8)]
            .iter()
            .map(|&(h, e)| run(h, e))
            .chain([run(0.0125, 5e-9)])
            .collect();
        let fit = observed_order(&runs, "M", 1e-8);
        assert_eq!((fit.used, fit.excluded), (3, 1));
        // Exact powers of 2 and 10: the slope is 4 up to round-off (1e-12 is generous).
        assert!((fit.order.unwrap() - 4.0).abs() < 1e-12, "{fit:?}");
        assert_eq!(fit.cell(), "4.00 (3 h)");
        let all = observed_order(&runs, "M", 0.0);
        assert_eq!((all.used, all.excluded), (4, 0));
        assert!(
            all.order.unwrap() < 3.8,
            "the floor point flattens the slope (3.69)"
        );
        let none = observed_order(&runs, "M", 1.0);
        assert_eq!((none.order, none.cell().as_str()), (None, "— (at floor)"));
    }

    /// The progress weights: the NLS costs more per step than the 2 × 2 problems for every
    /// method, and RKEPC2-conv on the NLS is the most expensive run per step.
    #[test]
    fn step_costs_rank_the_runs() {
        let duffing = Problem::Duffing(Duffing::new(5.0, DUFFING_K).unwrap());
        let nls = Problem::Nls(Nls::new(NLS_N).unwrap());
        let names: Vec<&str> = super::super::methods::methods()
            .iter()
            .map(|m| m.name)
            .collect();
        for m in &names {
            assert!(step_cost(m, &nls) > 10.0 * step_cost(m, &duffing), "{m}");
        }
        let worst = names
            .iter()
            .max_by(|a, b| step_cost(a, &nls).total_cmp(&step_cost(b, &nls)))
            .unwrap();
        assert_eq!(*worst, "RKEPC2-conv");
    }
}
