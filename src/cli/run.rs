//! `ecr run`: integrate one of the paper's test problems and report the run as JSON.

use super::numbers::{count, finite, non_negative, positive};
use super::{UsageError, memory, progress};
use clap::{Args, ValueEnum};
use ecr::problems::{Duffing, Fpu, HenonHeiles, Nls, Wind};
use ecr_runtime::integrate::{IntegrateOptions, Integrator, Report, StepPlan, integrate};
use ecr_runtime::second_order::TcStepper;
use ecr_runtime::solve::{Options, Problem, Solution, SolveError, solve_stepper_bytes};
use ecr_runtime::stepper::{
    EcStepper, PARALLEL_MIN_DIM, Predictor, SizedEcStepper, SolverSettings, StageSolver,
};
use ecr_runtime::system::System;
use serde_json::{Value, json};
use std::io::Write;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

mod precise;

/// Refuse runs with more steps than this (h far too small for the interval).
const MAX_STEPS: f64 = 1e9;

#[derive(Clone, Copy, Debug, PartialEq, ValueEnum)]
enum ProblemArg {
    /// Problem 1: Duffing equation (exact solution known).
    Duffing,
    /// Problem 2: wind-induced oscillation, conservative (θ = π/2).
    Wind,
    /// Problem 2: wind-induced oscillation, dissipative (θ = π/2 − 1e−4).
    WindDissipative,
    /// Problem 3: cubic nonlinear Schrödinger equation, pseudospectral (FFT linear part).
    Nls,
    /// Fermi–Pasta–Ulam chain with stiff springs (Hairer–Lubich–Wanner), q'' + Ωq = −∇U(q).
    Fpu,
    /// Hénon–Heiles: two oscillators with a cubic coupling, from (q, p) = (0, 0, 1/2, 0) (energy
    /// 1/8, chaotic).
    HenonHeiles,
}

impl ProblemArg {
    fn name(self) -> &'static str {
        match self {
            ProblemArg::Duffing => "duffing",
            ProblemArg::Wind => "wind",
            ProblemArg::WindDissipative => "wind-dissipative",
            ProblemArg::Nls => "nls",
            ProblemArg::Fpu => "fpu",
            ProblemArg::HenonHeiles => "henon-heiles",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, ValueEnum)]
enum PrecisionArg {
    /// f64 (the fast steppers).
    Double,
    /// Double-double, about 32 significant digits (ECrP; duffing, wind, wind-dissipative,
    /// henon-heiles; fixed step).
    DoubleDouble,
}

#[derive(Clone, Copy, Debug, PartialEq, ValueEnum)]
enum MethodArg {
    /// Exponential collocation ECrP (first-order systems).
    Ec,
    /// Trigonometric collocation TCrP (second-order problems: fpu).
    Tc,
    /// RKN collocation RKNCrP (second-order problems with Ω = 0: fpu --omega 0).
    Rknc,
}

impl MethodArg {
    fn name(self) -> &'static str {
        match self {
            MethodArg::Ec => "ec",
            MethodArg::Tc => "tc",
            MethodArg::Rknc => "rknc",
        }
    }
}

/// Arguments of `ecr run`.
///
/// Prints a JSON report on stdout. Bad input and runtime failures (for example stage
/// equations that do not converge within --max-sweeps without --paper-solver) are reported as
/// one line on stderr with exit status 2.
#[derive(Args, Debug)]
#[command(
    after_help = "Bad input and runtime failures (e.g. non-convergence of the stage equations) \
                  print one line starting with 'error: ' on stderr and exit with status 2. \
                  On a terminal, a progress bar shows the steps on stderr. An interrupted run \
                  (Ctrl-C, SIGINT) prints the time t and the steps it reached on stderr and \
                  exits with status 130; one terminated by SIGTERM does the same with status \
                  143."
)]
pub struct RunArgs {
    /// Test problem.
    #[arg(long, value_enum)]
    problem: ProblemArg,
    /// Frequency ω: Duffing [default: 5]; FPU stiff-spring frequency [default: 50; 0 gives
    /// Ω = 0, a problem for --method rknc].
    #[arg(long, allow_hyphen_values = true, value_parser = non_negative)]
    omega: Option<f64>,
    /// Duffing nonlinearity k, |k| ≤ ω [default: 0.07].
    #[arg(long, allow_hyphen_values = true, value_parser = finite)]
    k: Option<f64>,
    /// Wind angle θ in [0, π/2] [default: π/2 for wind, π/2 − 1e−4 for wind-dissipative].
    #[arg(long, allow_hyphen_values = true, value_parser = non_negative)]
    theta: Option<f64>,
    /// Wind radius r (the paper's "r = 20") [default: 20].
    #[arg(long, allow_hyphen_values = true, value_parser = positive)]
    amplitude: Option<f64>,
    /// NLS grid size N (even) [default: 128]. A run whose memory, estimated from N, r, s and
    /// --newton, exceeds 3/4 of the memory available (MemAvailable, ulimit -v) is refused.
    #[arg(long, allow_hyphen_values = true, value_parser = count)]
    n: Option<usize>,
    /// Method family: ec (any problem; fpu in first-order form), tc or rknc (fpu).
    #[arg(long, value_enum, default_value = "ec")]
    method: MethodArg,
    /// Order parameter r (the method has order 2r); required with --h, with --tol it fixes
    /// the order the solver may use (default: chosen by the solver).
    #[arg(long, allow_hyphen_values = true, value_parser = count)]
    r: Option<usize>,
    /// Number of Gauss–Legendre points, s ≥ r [default: r].
    #[arg(long, allow_hyphen_values = true, value_parser = count)]
    s: Option<usize>,
    /// Step size h > 0 of a fixed-step run (with --r); or solve to a tolerance with --tol.
    #[arg(long, allow_hyphen_values = true, value_parser = positive)]
    h: Option<f64>,
    /// Solve to this tolerance instead of a fixed step (rtol = atol = TOL, ECrP with the
    /// order and step the solver chooses, the answer verified over the whole span): the
    /// report gives the solver's error estimate and the error achieved, both in units of the
    /// tolerance, measured against the exact solution (duffing) or a verified solve to
    /// TOL/1000. An answer that could not be verified is reported with its reason and exit
    /// status 2.
    #[arg(long, allow_hyphen_values = true, value_parser = positive, conflicts_with_all = ["h", "s", "paper_solver", "max_sweeps", "constant_start", "extrapolate", "newton", "stage_tol"])]
    tol: Option<f64>,
    /// Final time T ≥ 0 (the last step makes the step sizes add up to T exactly: shortened if
    /// h does not divide T, or h corrected by round-off; the report's `h_last`).
    #[arg(long, allow_hyphen_values = true, value_parser = non_negative)]
    t_end: f64,
    /// The paper's stage solver: tolerance 1e−16, at most 5 sweeps, accepted at the limit.
    #[arg(long)]
    paper_solver: bool,
    /// Tolerance of the stage equations' solver in a fixed-step run (scaled max-norm of the
    /// update) [default: 1e−15, or 1e−16 with --paper-solver]; not the accuracy of the run
    /// (that is --tol).
    #[arg(long, allow_hyphen_values = true, value_parser = non_negative)]
    stage_tol: Option<f64>,
    /// The former name of --stage-tol, easily taken for --tol: refused with a line that says
    /// which is which.
    #[arg(long, hide = true, allow_hyphen_values = true)]
    tolerance: Option<String>,
    /// Maximum fixed-point sweeps per step [default: 100, or 5 with --paper-solver].
    #[arg(long, allow_hyphen_values = true, value_parser = count)]
    max_sweeps: Option<usize>,
    /// Start each step's stage iteration from the previous step's continuous solution
    /// extrapolated to the new nodes: the default (without --paper-solver); kept for scripts.
    #[arg(long, conflicts_with = "constant_start")]
    extrapolate: bool,
    /// Start each step's stage iteration at y₀ (every stage), as the paper does, instead of
    /// extrapolating the previous step (more sweeps; the same steps up to the tolerance).
    #[arg(long)]
    constant_start: bool,
    /// Solve the stage equations by simplified Newton (Jacobian of g by forward differences)
    /// instead of fixed-point sweeps: for stiff nonlinearities. ECrP only.
    #[arg(long)]
    newton: bool,
    /// Arithmetic: double (f64) or double-double (about 32 significant digits: the state is
    /// printed with 34, the Duffing error measured against its exact solution at 256 bits).
    /// Double-double runs ECrP with a fixed step on duffing, wind, wind-dissipative and
    /// henon-heiles; a step that does not divide --t-end is rounded to one that does when
    /// they differ by at most 1e−9 relative (else the last step is shortened).
    #[arg(long, value_enum, default_value = "double")]
    precision: PrecisionArg,
}

impl RunArgs {
    /// r of a fixed-step run (checked present by `check_inputs`); with --tol the largest r
    /// the solver may choose.
    fn r(&self) -> usize {
        self.r.unwrap_or(8)
    }

    /// h of a fixed-step run (present unless --tol).
    fn h(&self) -> f64 {
        self.h.unwrap_or(f64::NAN)
    }
}

fn usage(e: ecr_runtime::Error) -> UsageError {
    UsageError(e.to_string())
}

/// The wind problem of `args`: --theta, or θ = π/2 (wind) or π/2 − 1e−4 (wind-dissipative,
/// made from δ = 1e−4), radius --amplitude (default 20).
fn wind_problem(args: &RunArgs) -> Result<Wind, UsageError> {
    let radius = args.amplitude.unwrap_or(20.0);
    match (args.theta, args.problem) {
        (Some(theta), _) => Wind::new(theta, radius),
        (None, ProblemArg::WindDissipative) => Wind::from_deviation(1e-4, radius),
        (None, _) => Wind::new(std::f64::consts::FRAC_PI_2, radius),
    }
    .map_err(usage)
}

/// Rejects an option that does not belong to the chosen problem.
fn only_for(
    value: bool,
    option: &str,
    problems: &str,
    chosen: ProblemArg,
) -> Result<(), UsageError> {
    if value {
        return Err(UsageError(format!(
            "--{option} applies only to {problems}, not to --problem {}",
            chosen.name()
        )));
    }
    Ok(())
}

/// What one integration produced.
struct Outcome {
    report: Report,
    y: Vec<f64>,
    seconds: f64,
}

/// Where the current integration has got to, for the report of an interrupted run (read by
/// the signal handler, written by the integration's observer).
struct Progress {
    t_bits: AtomicU64,
    steps: AtomicU64,
    total: AtomicU64,
}

static PROGRESS: Progress = Progress {
    t_bits: AtomicU64::new(0),
    steps: AtomicU64::new(0),
    total: AtomicU64::new(0),
};

/// On SIGINT (Ctrl-C) or SIGTERM: one line on stderr saying where the run got to, exit
/// status 130 or 143 (the shell's 128 + the signal's number).
fn report_interrupts() {
    super::interrupt::on_interrupt(|what| {
        let t = f64::from_bits(PROGRESS.t_bits.load(Ordering::Relaxed));
        let steps = PROGRESS.steps.load(Ordering::Relaxed);
        let total = PROGRESS.total.load(Ordering::Relaxed);
        if total == u64::MAX {
            format!("{what} during the solve; no report written")
        } else {
            format!("{what} at t = {t} after {steps} of {total} steps; no report written")
        }
    });
}

fn run_system<I: Integrator>(
    stepper: Result<I, ecr_runtime::Error>,
    y0: Vec<f64>,
    args: &RunArgs,
) -> Result<Outcome, UsageError> {
    let mut stepper = stepper.map_err(usage)?;
    let mut y = y0;
    // integrate's count: ⌈T/h⌉ up to its 1e−9 relative slack.
    let total = (args.t_end / args.h() * (1.0 - 1e-9)).ceil().max(0.0) as u64;
    PROGRESS.total.store(total, Ordering::Relaxed);
    PROGRESS.steps.store(0, Ordering::Relaxed);
    PROGRESS.t_bits.store(0.0f64.to_bits(), Ordering::Relaxed);
    let bar = progress::StepBar::new(total, &format!("ecr run --problem {}", args.problem.name()));
    let mut calls = 0u64;
    let start = Instant::now();
    let report = integrate(
        &mut stepper,
        0.0,
        args.t_end,
        &mut y,
        IntegrateOptions {
            // The report's max_energy_error is over every step. H costs less than a step for
            // every problem (the NLS: one FFT against 2·s per sweep), so this stays cheap.
            energy_every: 1,
            // The observer records the progress (it is called at t0, then after every step).
            observe_every: 1,
        },
        |t, _, _| {
            let steps = calls;
            calls += 1;
            PROGRESS.t_bits.store(t.to_bits(), Ordering::Relaxed);
            PROGRESS.steps.store(steps, Ordering::Relaxed);
            bar.set(steps);
        },
    );
    bar.finish_and_clear();
    let report = report.map_err(|e| UsageError(format!("integration failed: {e}")))?;
    Ok(Outcome {
        report,
        y,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// A fixed-step ECrP run of `system` from `y0` (r, s and h from `args`), stepped by what
/// `build` makes of them: [`SizedEcStepper`] for the planar problems (fixed-size buffers, bit
/// for bit [`EcStepper`]), `EcStepper` for the others (whose systems then do not compile the
/// fixed-size forms).
fn run_ec<S: System, I: Integrator>(
    system: ecr_runtime::Result<S>,
    y0: Vec<f64>,
    args: &RunArgs,
    settings: SolverSettings,
    build: fn(S, usize, usize, f64, SolverSettings) -> ecr_runtime::Result<I>,
) -> Result<Outcome, UsageError> {
    let s = args.s.unwrap_or(args.r());
    let system = system.map_err(usage)?;
    run_system(build(system, args.r(), s, args.h(), settings), y0, args)
}

fn check_inputs(args: &RunArgs) -> Result<(), UsageError> {
    if args.method != MethodArg::Ec && args.problem != ProblemArg::Fpu {
        return Err(UsageError(format!(
            "method '{}' integrates second-order problems (fpu); use --method ec for {}",
            args.method.name(),
            args.problem.name()
        )));
    }
    if args.method == MethodArg::Rknc && args.omega.unwrap_or(50.0) != 0.0 {
        return Err(UsageError(
            "method 'rknc' is for Ω = 0: use --problem fpu --omega 0 (or --method tc)".to_string(),
        ));
    }
    if args.tolerance.is_some() {
        return Err(UsageError(
            "--tolerance is ambiguous and no longer accepted: --tol TOL solves to a tolerance \
             (the accuracy of the run); --stage-tol TOL sets the stage solver's tolerance of a \
             fixed-step run"
                .to_string(),
        ));
    }
    if args.tol.is_none() && args.h.is_none() {
        return Err(UsageError(
            "say how to run: --tol TOL (the order and step chosen by the solver, the answer \
             verified to TOL) or --r R --h H (a fixed method and step)"
                .to_string(),
        ));
    }
    if let Some(tol) = args.tol {
        if !(tol.is_finite() && tol > 0.0) {
            return Err(UsageError(format!("--tol {tol:?} must be finite and > 0")));
        }
        if args.method != MethodArg::Ec {
            return Err(UsageError(
                "--tol solves with ECrP: use --method ec (fpu in first-order form)".to_string(),
            ));
        }
    } else {
        if args.r.is_none() {
            return Err(UsageError("--r is required with --h".to_string()));
        }
        if !(args.h().is_finite() && args.h() > 0.0) {
            return Err(UsageError(format!(
                "step size --h {:?} must be finite and > 0",
                args.h()
            )));
        }
    }
    if !(args.t_end.is_finite() && args.t_end >= 0.0) {
        return Err(UsageError(format!(
            "final time --t-end {:?} must be finite and >= 0",
            args.t_end
        )));
    }
    if args.tol.is_none() && args.t_end / args.h() > MAX_STEPS {
        return Err(UsageError(format!(
            "--t-end {:?} / --h {:?} needs more than {MAX_STEPS:e} steps",
            args.t_end,
            args.h()
        )));
    }
    if let Some(tol) = args.stage_tol {
        if !(tol.is_finite() && tol >= 0.0) {
            return Err(UsageError(format!(
                "--stage-tol {tol:?} must be finite and >= 0"
            )));
        }
    }
    if args.max_sweeps == Some(0) {
        return Err(UsageError("--max-sweeps must be >= 1".to_string()));
    }
    let p = args.problem;
    let duffing = p == ProblemArg::Duffing;
    let wind = matches!(p, ProblemArg::Wind | ProblemArg::WindDissipative);
    let with_omega = duffing || p == ProblemArg::Fpu;
    only_for(
        !with_omega && args.omega.is_some(),
        "omega",
        "duffing and fpu",
        p,
    )?;
    only_for(!duffing && args.k.is_some(), "k", "duffing", p)?;
    let winds = "wind and wind-dissipative";
    only_for(!wind && args.theta.is_some(), "theta", winds, p)?;
    only_for(!wind && args.amplitude.is_some(), "amplitude", winds, p)?;
    only_for(p != ProblemArg::Nls && args.n.is_some(), "n", "nls", p)?;
    Ok(())
}

fn solver_settings(args: &RunArgs) -> SolverSettings {
    let mut settings = if args.paper_solver {
        SolverSettings::paper()
    } else {
        SolverSettings::default()
    };
    if let Some(tol) = args.stage_tol {
        settings.tolerance = tol;
    }
    if let Some(m) = args.max_sweeps {
        settings.max_sweeps = m;
    }
    if args.extrapolate {
        settings.predictor = Predictor::Extrapolate;
    }
    if args.constant_start {
        settings.predictor = Predictor::Constant;
    }
    if args.newton {
        settings.solver = StageSolver::Newton;
    }
    settings
}

/// A bound on the bytes (address space) `ecr run` needs. Per component of the state
/// (dimension d): the stepper's buffers (4s + r + 6 vectors), the φ-bank (τ nodes × (r + 1)
/// functions, a complex number per Fourier mode, d/2 modes) and 320 bytes for the rest: the
/// FFT plans, eigenvalues and scratch, y, and later the JSON report (measured, as the smallest
/// `ulimit -v` a run passes, for the NLS with N = 2²⁰: 135 bytes for N a power of two, 250 for
/// N = 2p with p prime, which rustfft transforms by Rader's or Bluestein's algorithm). With
/// --newton, the Newton matrices (2s²d² + 2d² numbers). From d = `PARALLEL_MIN_DIM` on, the
/// workspaces of the concurrent stage path: at most max(s, r + 1), each the spectra of r + 1
/// inputs, a buffer and the FFT scratch (r + 3 complex numbers per mode). r and s are clamped
/// to the tables' range: larger ones are refused later with their own message. The stacks of
/// the threads, 2 MiB each (the standard library's default): the signal thread's and, from
/// d = `PARALLEL_MIN_DIM` on, rayon's pool ([`pool_threads`]). Their malloc arenas are not
/// counted: under `ulimit -v` the threads share one ([`memory::limit_malloc_arenas`]).
fn memory_estimate(args: &RunArgs) -> f64 {
    const BASE: f64 = 32.0 * 1024.0 * 1024.0;
    const STACK: f64 = 2.0 * 1024.0 * 1024.0;
    let d = match args.problem {
        ProblemArg::Nls => 2.0 * args.n.unwrap_or(128) as f64,
        // Duffing and wind: 2; FPU (m = 3) in first-order form: 12.
        _ => 16.0,
    };
    let r = args.r().min(ecr_codegen::MAX_R) as f64;
    let s = args.s.unwrap_or(args.r()).min(ecr_codegen::MAX_S) as f64;
    let taus = if solver_settings(args).predictor == Predictor::Extrapolate {
        2.0 * s + 1.0
    } else {
        s + 1.0
    };
    let helpers = if d >= PARALLEL_MIN_DIM as f64 {
        s.max(r + 1.0) * 8.0 * (r + 3.0)
    } else {
        0.0
    };
    let per_component = 8.0 * (4.0 * s + r + 6.0) + 8.0 * taus * (r + 1.0) + 320.0 + helpers;
    let newton = if args.newton {
        16.0 * (s * s + 1.0) * d * d
    } else {
        0.0
    };
    let pool = if d >= PARALLEL_MIN_DIM as f64 {
        pool_threads() as f64
    } else {
        0.0
    };
    BASE + (1.0 + pool) * STACK + d * per_component + newton
}

/// The largest r that `ecr run --tol` lets the solve choose without --r (`Options`' default
/// orders, r = 1..=8).
const SOLVE_MAX_R: usize = 8;

/// A bound on the bytes `ecr run --tol` needs: the peak of the steppers the solve holds at
/// once ([`solve_stepper_bytes`]: the answer, its three checks and the output stepper, and
/// the banks the solve keeps) for the largest r the solve may choose; the stacks of the
/// threads, a base of 32 MiB, and 200 bytes per component for the system itself (its
/// spectrum, FFT plans and scratch), the initial value, the solution and the JSON report
/// (measured, as the peak resident memory of NLS solves, docs/solve.md#memory). The solves to
/// the tolerance and to tolerance/1000 (the reference) run one after the other.
fn solve_memory_estimate(args: &RunArgs) -> Result<f64, UsageError> {
    fn of<S: System>(system: S, r: usize) -> f64 {
        solve_stepper_bytes(&system, r, true, &SolverSettings::default())
            .map_or(f64::INFINITY, |b| b as f64)
            + 200.0 * system.dim() as f64
    }
    let r = args.r.unwrap_or(SOLVE_MAX_R).min(ecr_codegen::MAX_R);
    let steppers = match args.problem {
        ProblemArg::Duffing => {
            let problem =
                Duffing::new(args.omega.unwrap_or(5.0), args.k.unwrap_or(0.07)).map_err(usage)?;
            of(problem.system().map_err(usage)?, r)
        }
        ProblemArg::Wind | ProblemArg::WindDissipative => {
            of(wind_problem(args)?.system().map_err(usage)?, r)
        }
        ProblemArg::HenonHeiles => of(HenonHeiles::default().system().map_err(usage)?, r),
        ProblemArg::Nls => {
            let problem = Nls::new(args.n.unwrap_or(128)).map_err(usage)?;
            of(problem.system().map_err(usage)?, r)
        }
        ProblemArg::Fpu => {
            let problem = Fpu::new(3, args.omega.unwrap_or(50.0)).map_err(usage)?;
            of(problem.first_order_system().map_err(usage)?, r)
        }
    };
    const BASE: f64 = 32.0 * 1024.0 * 1024.0;
    const STACK: f64 = 2.0 * 1024.0 * 1024.0;
    Ok(BASE + (1.0 + pool_threads() as f64) * STACK + steppers)
}

/// The threads of rayon's pool: `RAYON_NUM_THREADS` if set (and > 0), else one per CPU (what
/// rayon starts; asking rayon would start it).
fn pool_threads() -> usize {
    std::env::var("RAYON_NUM_THREADS")
        .ok()
        .and_then(|v| v.parse().ok())
        .filter(|&n| n > 0)
        .or_else(|| std::thread::available_parallelism().ok().map(|n| n.get()))
        .unwrap_or(1)
}

/// `Err` naming the first non-finite number of the report, if any: a run does not report
/// success with a state or an energy that overflowed. (The stepper refuses non-finite
/// steps, so this is a last line of defence.)
fn check_finite(report: &Report, y: &[f64], global_error: Option<f64>) -> Result<(), UsageError> {
    let bad = if let Some(i) = y.iter().position(|v| !v.is_finite()) {
        Some(format!("component {i} of the state"))
    } else {
        [
            ("the initial energy", report.energy_start),
            ("the final energy", report.energy_end),
            ("the maximum energy error", report.max_energy_error),
            ("the global error", global_error),
        ]
        .into_iter()
        .find(|(_, v)| v.is_some_and(|v| !v.is_finite()))
        .map(|(what, _)| what.to_string())
    };
    match bad {
        Some(what) => Err(UsageError(format!(
            "integration failed: {what} is not finite at t = {}; try a smaller --h",
            report.t_end
        ))),
        None => Ok(()),
    }
}

/// Runs `ecr run`.
pub fn run(args: &RunArgs, out: &mut dyn Write) -> Result<(), UsageError> {
    check_inputs(args)?;
    let what = match (args.problem, args.n) {
        (ProblemArg::Nls, Some(n)) => format!("--problem nls --n {n}"),
        _ => format!("--problem {}", args.problem.name()),
    };
    let what = format!(
        "{what} with r = {}, s = {}{}",
        args.r(),
        args.s.unwrap_or(args.r()),
        if args.newton { " and --newton" } else { "" }
    );
    memory::check(&what, memory_estimate(args))?;
    if args.tol.is_some() && args.precision == PrecisionArg::Double {
        let what = format!(
            "{} --tol with r up to {}",
            what.split(" with r").next().unwrap_or(&what),
            args.r.unwrap_or(SOLVE_MAX_R)
        );
        memory::check(&what, solve_memory_estimate(args)?)?;
    }
    report_interrupts();
    if args.precision == PrecisionArg::DoubleDouble {
        return precise::run(args, out);
    }
    if let Some(tol) = args.tol {
        return run_tolerance(args, tol, out);
    }
    let settings = solver_settings(args);
    let s = args.s.unwrap_or(args.r());
    let (outcome, parameters, global_error) = match args.problem {
        ProblemArg::Duffing => {
            let problem =
                Duffing::new(args.omega.unwrap_or(5.0), args.k.unwrap_or(0.07)).map_err(usage)?;
            let o = run_ec(
                problem.system(),
                problem.initial_value(),
                args,
                settings,
                SizedEcStepper::with_nodes,
            )?;
            let exact = problem.exact(o.report.t_end).map_err(usage)?;
            let err =
                o.y.iter()
                    .zip(exact)
                    .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            let params = json!({ "omega": problem.omega(), "k": problem.k() });
            (o, params, Some(err))
        }
        ProblemArg::Wind | ProblemArg::WindDissipative => {
            let problem = wind_problem(args)?;
            let o = run_ec(
                problem.system(),
                problem.initial_value(),
                args,
                settings,
                SizedEcStepper::with_nodes,
            )?;
            let params = json!({
                "theta": problem.theta(),
                "amplitude": problem.radius(),
                "conservative": problem.is_conservative(),
            });
            (o, params, None)
        }
        ProblemArg::HenonHeiles => {
            let problem = HenonHeiles::default();
            let o = run_ec(
                problem.system(),
                problem.initial_value(),
                args,
                settings,
                EcStepper::with_nodes,
            )?;
            (o, json!({ "y0": problem.initial_value() }), None)
        }
        ProblemArg::Nls => {
            let problem = Nls::new(args.n.unwrap_or(128)).map_err(usage)?;
            let o = run_ec(
                problem.system(),
                problem.initial_value(),
                args,
                settings,
                EcStepper::with_nodes,
            )?;
            (o, json!({ "n": problem.n() }), None)
        }
        ProblemArg::Fpu => {
            let problem = Fpu::new(3, args.omega.unwrap_or(50.0)).map_err(usage)?;
            let y0 = problem.initial_value_first_order();
            let o = match args.method {
                MethodArg::Ec => run_system(
                    EcStepper::with_nodes(
                        problem.first_order_system().map_err(usage)?,
                        args.r(),
                        s,
                        args.h(),
                        settings,
                    ),
                    y0,
                    args,
                )?,
                MethodArg::Tc | MethodArg::Rknc => run_system(
                    TcStepper::with_nodes(
                        problem.system().map_err(usage)?,
                        args.r(),
                        s,
                        args.h(),
                        settings,
                    ),
                    y0,
                    args,
                )?,
            };
            (
                o,
                json!({ "m": problem.m(), "omega": problem.omega() }),
                None,
            )
        }
    };
    let Outcome { report, y, seconds } = outcome;
    check_finite(&report, &y, global_error)?;
    let value: Value = json!({
        "problem": args.problem.name(),
        "parameters": parameters,
        "method": args.method.name(),
        "r": args.r(),
        "s": args.s.unwrap_or(args.r()),
        "h": args.h(),
        "h_last": last_step(args),
        "t_end": report.t_end,
        "steps": report.steps,
        "solver": {
            "tolerance": settings.tolerance,
            "max_sweeps": settings.max_sweeps,
            "paper": args.paper_solver,
            "extrapolate": settings.predictor == Predictor::Extrapolate,
            "newton": args.newton,
        },
        "y": y,
        "energy_start": report.energy_start,
        "energy_end": report.energy_end,
        "max_energy_error": report.max_energy_error,
        "energy_error_units": "relative: max over the steps of |H - H0| / |H0|",
        "global_error": global_error,
        "sweeps": report.sweeps,
        "max_sweeps_per_step": report.max_sweeps,
        "g_evals": report.g_evals,
        "unconverged_steps": report.unconverged_steps,
        "wall_seconds": seconds,
    });
    let mut text = serde_json::to_string_pretty(&value).map_err(|e| UsageError(e.to_string()))?;
    text.push('\n');
    out.write_all(text.as_bytes())
        .map_err(|e| UsageError(format!("cannot write output: {e}")))
}

/// The size of the run's last step ([`StepPlan`]: h, or the step that makes the sizes add up
/// to T exactly, shortened or h corrected by round-off); `None` for an empty run.
fn last_step(args: &RunArgs) -> Option<f64> {
    let plan = StepPlan::new(0.0, args.t_end, args.h()).ok()?;
    (plan.steps() > 0).then(|| plan.last.unwrap_or(args.h()))
}

/// What a solve to a tolerance produced, for the report.
struct Solved {
    solution: Solution,
    /// The reason, if the answer could not be verified.
    unverified: Option<String>,
    seconds: f64,
}

/// Solves `system` from `y0` over [0, t_end] to `tol` (output at t_end), the order fixed by
/// `r` if given.
fn solve_to<S: System>(
    system: S,
    y0: Vec<f64>,
    t_end: f64,
    tol: f64,
    r: Option<usize>,
) -> Result<Solved, UsageError> {
    let start = Instant::now();
    let problem = Problem::new(system, y0, (0.0, t_end)).map_err(usage)?;
    let mut options = Options::tolerance(tol).t_eval([t_end]);
    if let Some(r) = r {
        options = options.orders(r..=r);
    }
    if trace_requested() {
        // A diagnostic: a stderr that cannot be written to (closed, full) loses the trace,
        // not the run.
        options = options.trace(|line| {
            let _ = writeln!(std::io::stderr(), "{line}");
        });
    }
    let (solution, unverified) = match problem.solve(&options) {
        Ok(sol) => (sol.into_data(), None),
        Err(SolveError::Unverified { reason, solution }) => (*solution, Some(reason)),
        Err(SolveError::Failed(e)) => return Err(UsageError(format!("solve failed: {e}"))),
        Err(e) => return Err(UsageError(format!("solve failed: {e}"))),
    };
    Ok(Solved {
        solution,
        unverified,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Whether `ECR_SOLVE_TRACE` asks for the solver's trace on stderr: set to anything but
/// empty, `0`, `false`, `no` or `off`.
fn trace_requested() -> bool {
    std::env::var_os("ECR_SOLVE_TRACE").is_some_and(|v| {
        let v = v.to_string_lossy().trim().to_ascii_lowercase();
        !matches!(v.as_str(), "" | "0" | "false" | "no" | "off")
    })
}

/// The solve of `system()` to `tol` and, for the error achieved, its solve to tol/1000.
fn solve_and_reference<S: System>(
    system: impl Fn() -> ecr_runtime::Result<S>,
    y0: &[f64],
    t_end: f64,
    tol: f64,
    r: Option<usize>,
) -> Result<(Solved, Result<Solved, UsageError>), UsageError> {
    let solved = solve_to(system().map_err(usage)?, y0.to_vec(), t_end, tol, r)?;
    let reference = system()
        .map_err(usage)
        .and_then(|s| solve_to(s, y0.to_vec(), t_end, tol * 1e-3, None));
    Ok((solved, reference))
}

/// max_i |a_i − b_i| / (tol (1 + |b_i|)): an error in units of the tolerance.
fn in_tolerance_units(a: &[f64], b: &[f64], tol: f64) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / (tol + tol * y.abs()))
        .fold(0.0, f64::max)
}

/// `ecr run --tol TOL`: the problem solved to a tolerance, the estimate beside the error
/// achieved (against the exact solution, or a verified solve to TOL/1000).
fn run_tolerance(args: &RunArgs, tol: f64, out: &mut dyn Write) -> Result<(), UsageError> {
    // The progress of a solve is not reported step by step; an interrupt says so.
    PROGRESS.total.store(u64::MAX, Ordering::Relaxed);
    let t_end = args.t_end;
    let reference_tol = tol * 1e-3;
    // (the solve, the parameters, the reference: its state, what it is, its estimate)
    type Reference = (Option<Vec<f64>>, String, Option<f64>);
    let reference_of = |r: Result<Solved, UsageError>| -> Reference {
        match r {
            Ok(s) if s.unverified.is_none() => (
                s.solution.last().map(<[f64]>::to_vec),
                format!("solve to {reference_tol:e}"),
                s.solution.error_estimate,
            ),
            Ok(s) => (
                None,
                format!(
                    "none: a solve to {reference_tol:e} was not verified ({})",
                    s.unverified.unwrap_or_default()
                ),
                None,
            ),
            Err(e) => (None, format!("none: {}", e.0), None),
        }
    };
    let (solved, parameters, reference): (Solved, Value, Reference) = match args.problem {
        ProblemArg::Duffing => {
            let problem =
                Duffing::new(args.omega.unwrap_or(5.0), args.k.unwrap_or(0.07)).map_err(usage)?;
            let y0 = problem.initial_value();
            let solved = solve_to(problem.system().map_err(usage)?, y0, t_end, tol, args.r)?;
            let exact = problem.exact(t_end).map_err(usage)?;
            let params = json!({ "omega": problem.omega(), "k": problem.k() });
            (
                solved,
                params,
                (Some(exact.to_vec()), "exact".to_string(), Some(0.0)),
            )
        }
        ProblemArg::Wind | ProblemArg::WindDissipative => {
            let problem = wind_problem(args)?;
            let y0 = problem.initial_value();
            let (solved, reference) =
                solve_and_reference(|| problem.system(), &y0, t_end, tol, args.r)?;
            let reference = reference_of(reference);
            let params = json!({
                "theta": problem.theta(),
                "amplitude": problem.radius(),
                "conservative": problem.is_conservative(),
            });
            (solved, params, reference)
        }
        ProblemArg::HenonHeiles => {
            let problem = HenonHeiles::default();
            let y0 = problem.initial_value();
            let (solved, reference) =
                solve_and_reference(|| problem.system(), &y0, t_end, tol, args.r)?;
            let reference = reference_of(reference);
            (solved, json!({ "y0": y0 }), reference)
        }
        ProblemArg::Nls => {
            let problem = Nls::new(args.n.unwrap_or(128)).map_err(usage)?;
            let y0 = problem.initial_value();
            let (solved, reference) =
                solve_and_reference(|| problem.system(), &y0, t_end, tol, args.r)?;
            let reference = reference_of(reference);
            (solved, json!({ "n": problem.n() }), reference)
        }
        ProblemArg::Fpu => {
            let problem = Fpu::new(3, args.omega.unwrap_or(50.0)).map_err(usage)?;
            let y0 = problem.initial_value_first_order();
            let (solved, reference) =
                solve_and_reference(|| problem.first_order_system(), &y0, t_end, tol, args.r)?;
            let reference = reference_of(reference);
            (
                solved,
                json!({ "m": problem.m(), "omega": problem.omega() }),
                reference,
            )
        }
    };
    let Solved {
        solution,
        unverified,
        seconds,
    } = solved;
    // A solve that kept no output (an unverified one may not) has no state, no error and no
    // energy error to report: those are null, and `missing` says why (not made-up zeros).
    let y = solution.last().map(<[f64]>::to_vec);
    let (reference_y, reference_what, reference_estimate) = reference;
    let achieved = y
        .as_ref()
        .zip(reference_y.as_ref())
        .map(|(y, r)| in_tolerance_units(y, r, tol));
    let (error_estimate, energy_error) = if y.is_some() {
        (solution.error_estimate, solution.energy_error())
    } else {
        (None, None)
    };
    let missing = y.is_none().then_some(
        "the solve returned no output: y, t_end, error_estimate, achieved_error and \
         energy_error are null",
    );
    let stats = &solution.stats;
    let value: Value = json!({
        "problem": args.problem.name(),
        "parameters": parameters,
        "method": "ec",
        "tolerance": tol,
        "verified": unverified.is_none(),
        "reason": unverified,
        "missing": missing,
        "error_estimate": error_estimate,
        "achieved_error": achieved,
        "reference": reference_what,
        "reference_estimate": reference_estimate.map(|e| e * 1e-3),
        "error_units": "max_i |y_i - y_ref,i| / (tol (1 + |y_ref,i|)); the reference's estimate in the same units",
        "r": solution.r,
        "s": solution.s,
        "segments": solution.segments.iter().map(|s| json!({"t": s.t, "h": s.h})).collect::<Vec<_>>(),
        "t_end": solution.t.last(),
        "status": format!("{:?}", solution.status),
        "y": y,
        "energy_error": energy_error,
        "energy_error_units": "relative: max over the output times of |H - H0| / |H0|",
        "steps": stats.steps,
        "g_evals": stats.g_evals,
        "total_g_evals": stats.total_g_evals(),
        "stats": {
            "check_g_evals": stats.check_g_evals,
            "pilot_g_evals": stats.pilot_g_evals,
            "discarded_g_evals": stats.discarded_g_evals,
            "retries": stats.retries,
        },
        "wall_seconds": seconds,
    });
    let mut text = serde_json::to_string_pretty(&value).map_err(|e| UsageError(e.to_string()))?;
    text.push('\n');
    out.write_all(text.as_bytes())
        .map_err(|e| UsageError(format!("cannot write output: {e}")))?;
    match unverified {
        None => Ok(()),
        Some(reason) => Err(UsageError(format!(
            "the answer could not be verified to --tol {tol:e}: {reason} (the report above \
             holds the best solution and its estimate)"
        ))),
    }
}
