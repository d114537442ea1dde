//! `ecr ensemble`: a test problem over a grid of parameters and initial values, every member
//! solved with the same options on every core, one CSV row per member written as the members
//! finish (`--resume` continues a killed run); `--summary` for statistics instead of rows;
//! `--shard K/N` and `ecr ensemble merge` for the jobs of a job array; the ranks of MPI with
//! the `mpi` feature. A thin layer over the library's `Ensemble::write_table`,
//! `Ensemble::summarize`, `merge_parts` and `ecr::mpi::write_table`.
//!
//! # The table
//!
//! A first line `# ecr ensemble table of M members: …` (the run as a canonical command line),
//! the run's fingerprint (`# NAME: VALUE` lines, `ecr_runtime::ensemble::fingerprint`: what a
//! `--resume` and a `merge` compare), one header row, then one row per member in member order: `member`, the varied values (in
//! the order of the `--vary` options), `status`, `t` (where the solution ends), the final
//! state (`q_end, p_end` or `q1_end, q2_end, p1_end, p2_end`), `error_estimate` (in units of
//! the tolerance; empty for a fixed step), `energy_error` (|H(y(t)) − H(y₀)| / |H(y₀)| at
//! the final time), `g_evals` (every evaluation of g of the member's solve) and `message`
//! (why the answer is not verified, or the failure); with `--cpu-seconds`, `cpu_seconds` (the
//! CPU time of the member, which differs from run to run) last. Numbers are written as Rust's
//! `{:?}` writes them, the shortest text that reads back to the same f64.
//!
//! # Parts
//!
//! A part (`--shard K/N`) holds the members K − 1, K − 1 + N, …: a line `# ecr ensemble part
//! K/N of M members: …` naming the ensemble, the fingerprint, the header row, its rows, and
//! the line `# end of part K/N: R rows, sha256 …` last. `merge` refuses parts that are
//! missing, given twice, of another run, without their end line (a shard killed or still
//! running) or whose rows do not match their digest, and an `--out` that is one of the
//! parts, and writes rows byte for byte those of the single run, in member order.

use super::UsageError;
use super::numbers::{count, finite, non_negative, positive};
use super::output::OutputFile;
use clap::{Args, Subcommand, ValueEnum};
use ecr::problems::{Duffing, DuffingSystem, HenonHeiles, HenonHeilesSystem};
use ecr_runtime::ensemble::{
    Cell, Column, Control, Ensemble, Progress, Summary, Table, TableReport, merge_parts,
    table_to_npy,
};
use ecr_runtime::operator::LinearOperator;
use ecr_runtime::solve::{Options, Problem, Solution};
use ecr_runtime::system::System;
use indicatif::ProgressBar;
use std::io::{IsTerminal, Write};
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// Arguments of `ecr ensemble`.
#[derive(Args, Debug)]
#[command(
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true,
    after_help = "Members: the cartesian product of the --vary values, the first --vary \
                  slowest (member i = (i1 n2 + i2) n3 + i3 for three). Rows are written in \
                  member order as the members finish, synced every second, to a hidden \
                  unfinished file beside FILE, renamed to FILE when complete: FILE holds the \
                  previous table or the complete new one. A killed or interrupted run keeps \
                  the rows it finished: the same command with --resume solves only the \
                  members that are missing. Exit status: 0 every member verified (or ok); 3 \
                  the table is written but some members are not verified (unverified, \
                  failed, panicked: their rows say why); 2 bad input (one line starting \
                  with 'error: ' on stderr); 130 or 143 interrupted (SIGINT, SIGTERM). Job \
                  arrays: run each part with --shard K/N (K = 1..N), then 'ecr ensemble \
                  merge --out FILE PART...'. MPI (an ecr built with --features mpi): \
                  'mpirun -n N ecr ensemble ...' splits the members over the ranks; rank 0 \
                  writes FILE."
)]
pub struct EnsembleArgs {
    #[command(subcommand)]
    command: Option<EnsembleCommand>,
    #[command(flatten)]
    solve: SolveArgs,
}

#[derive(Subcommand, Debug)]
enum EnsembleCommand {
    /// Join the N parts written by --shard K/N into the table of the whole ensemble, byte for
    /// byte the table of one run.
    ///
    /// Parts that are missing, given twice, of different runs (the field that differs named),
    /// without their end line (a shard killed or still running), or whose rows do not match
    /// the digest of their end line (changed since), and an --out that is one of the parts,
    /// are refused with one line starting with 'error: ' on stderr and exit status 2.
    Merge(MergeArgs),
}

/// Arguments of `ecr ensemble merge`.
#[derive(Args, Debug)]
struct MergeArgs {
    /// The table of the whole ensemble (CSV), written atomically.
    #[arg(long)]
    out: PathBuf,
    /// The part files, in any order.
    #[arg(required = true, value_name = "PART")]
    parts: Vec<PathBuf>,
    /// Also write the merged table as NPY (see `ecr ensemble --npy`).
    #[arg(long, value_name = "FILE")]
    npy: Option<PathBuf>,
}

#[derive(Clone, Copy, Debug, PartialEq, ValueEnum)]
enum ProblemArg {
    /// Duffing: q'' = −(ω² + k²) q + 2k² q³; parameters omega [5], k [0.07]; initial values
    /// q0 [0], p0 [omega].
    Duffing,
    /// Hénon–Heiles; initial values q1 [0], q2 [0], p1 [1/2], p2 [0] (energy below 1/6).
    HenonHeiles,
}

impl ProblemArg {
    fn name(self) -> &'static str {
        match self {
            ProblemArg::Duffing => "duffing",
            ProblemArg::HenonHeiles => "henon-heiles",
        }
    }

    /// The names --vary takes, in the order of the problem's defaults.
    fn parameters(self) -> &'static [&'static str] {
        match self {
            ProblemArg::Duffing => &["omega", "k", "q0", "p0"],
            ProblemArg::HenonHeiles => &["q1", "q2", "p1", "p2"],
        }
    }

    /// The columns of the final state.
    fn state(self) -> &'static [&'static str] {
        match self {
            ProblemArg::Duffing => &["q_end", "p_end"],
            ProblemArg::HenonHeiles => &["q1_end", "q2_end", "p1_end", "p2_end"],
        }
    }

    /// Whether members with different values of the --vary parameters `varied` have
    /// different linear operators (duffing's A holds ω and k).
    fn operator_varies(self, varied: &[Option<usize>]) -> bool {
        match self {
            ProblemArg::Duffing => varied[0].is_some() || varied[1].is_some(),
            ProblemArg::HenonHeiles => false,
        }
    }
}

/// `NAME=FROM:TO:COUNT`.
#[derive(Clone, Debug, PartialEq)]
struct Vary {
    name: String,
    from: f64,
    to: f64,
    count: usize,
}

impl Vary {
    /// Value `j` of the COUNT values `linspace(FROM, TO, COUNT)` (FROM + (TO − FROM) j /
    /// (COUNT − 1), TO exactly; the values numpy's `linspace` gives), computed when needed:
    /// nothing is stored per value.
    fn value(&self, j: usize) -> f64 {
        if j + 1 == self.count {
            self.to
        } else if self.count == 1 {
            self.from
        } else {
            self.from + (self.to - self.from) * (j as f64 / (self.count - 1) as f64)
        }
    }
}

fn parse_vary(text: &str) -> Result<Vary, String> {
    let (name, range) = text.split_once('=').ok_or("expected NAME=FROM:TO:COUNT")?;
    let parts: Vec<&str> = range.split(':').collect();
    let [from, to, count] = parts[..] else {
        return Err("expected NAME=FROM:TO:COUNT".to_string());
    };
    let number = |s: &str| -> Result<f64, String> {
        match s.trim().parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(format!("'{s}' is not a finite number")),
        }
    };
    let (from, to) = (number(from)?, number(to)?);
    let count: usize = count.trim().parse().map_err(|_| {
        format!(
            "COUNT '{count}' is not a whole number from 1 to {}",
            usize::MAX
        )
    })?;
    if count == 0 {
        return Err("COUNT must be >= 1".to_string());
    }
    if count == 1 && from != to {
        return Err(format!(
            "one value from {from:?} to {to:?}: write FROM:FROM:1, or COUNT >= 2"
        ));
    }
    Ok(Vary {
        name: name.trim().to_string(),
        from,
        to,
        count,
    })
}

/// `K/N`, 1 ≤ K ≤ N.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Shard {
    k: usize,
    n: usize,
}

fn parse_shard(text: &str) -> Result<Shard, String> {
    let usage = "K/N with whole numbers 1 <= K <= N, e.g. 3/8 for the third of eight parts";
    let (k, n) = text
        .split_once('/')
        .ok_or_else(|| format!("--shard {text}: expected {usage}"))?;
    let (k, n): (usize, usize) = match (k.trim().parse(), n.trim().parse()) {
        (Ok(k), Ok(n)) => (k, n),
        _ => return Err(format!("--shard {text}: expected {usage}")),
    };
    if n == 0 || k == 0 || k > n {
        return Err(format!(
            "--shard {text}: part {k} of {n}: K must be in 1..=N"
        ));
    }
    Ok(Shard { k, n })
}

/// A quantile in [0, 1].
fn parse_quantile(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(q) if (0.0..=1.0).contains(&q) => Ok(q),
        _ => Err(format!("'{text}' is not a quantile in [0, 1]")),
    }
}

/// Arguments of `ecr ensemble` (without `merge`).
#[derive(Args, Debug)]
struct SolveArgs {
    /// Test problem.
    #[arg(long, value_enum, required = true)]
    problem: Option<ProblemArg>,
    /// A parameter or initial value over COUNT evenly spaced values from FROM to TO, both
    /// included (duffing: omega, k, q0, p0; henon-heiles: q1, q2, p1, p2). Several --vary
    /// span their cartesian product, the first slowest.
    #[arg(
        long = "vary",
        value_name = "NAME=FROM:TO:COUNT",
        required = true,
        allow_hyphen_values = true,
        value_parser = parse_vary
    )]
    vary: Vec<Vary>,
    /// henon-heiles: p1 ≥ 0 such that H(y0) = ENERGY (below 1/6), from the other values; a
    /// member where no real p1 reaches ENERGY is a failed row.
    #[arg(long, allow_hyphen_values = true, value_parser = finite)]
    energy: Option<f64>,
    /// Solve every member to this tolerance (rtol = atol = TOL, verified over the whole span).
    #[arg(long, allow_hyphen_values = true, value_parser = positive, required_unless_present = "h")]
    tol: Option<f64>,
    /// Order parameter r (order 2r): with --h, required; with --tol, the order used.
    #[arg(long, allow_hyphen_values = true, value_parser = count, required_unless_present = "tol")]
    r: Option<usize>,
    /// A fixed step size h > 0 instead of --tol (no verification, no estimate).
    #[arg(
        long,
        allow_hyphen_values = true,
        value_parser = positive,
        conflicts_with = "tol",
        requires = "r"
    )]
    h: Option<f64>,
    /// Final time T ≥ 0 (every member from t = 0).
    #[arg(long, allow_hyphen_values = true, value_parser = non_negative, required = true)]
    t_end: Option<f64>,
    /// The table (CSV), or with --summary the summary (CSV), put in place when complete.
    #[arg(long, required = true)]
    out: Option<PathBuf>,
    /// Threads [default: RAYON_NUM_THREADS, else one per CPU this process may use; at most
    /// four per CPU].
    #[arg(long, allow_hyphen_values = true)]
    threads: Option<i64>,
    /// Solve only part K of N (K = 1..N: the members K − 1, K − 1 + N, …) and write it as a
    /// part file for 'ecr ensemble merge'.
    #[arg(long, value_name = "K/N", allow_hyphen_values = true, value_parser = parse_shard)]
    shard: Option<Shard>,
    /// Continue the unfinished table that a killed or interrupted run of the same command
    /// left beside --out: keep its rows, solve only the members that are missing (the
    /// unfinished table of another command is refused, naming what differs).
    #[arg(long)]
    resume: bool,
    /// Write statistics over the members instead of a row per member: per output column,
    /// count, mean, variance, min, max and the --quantiles (memory independent of the
    /// members; not with --shard, --resume or MPI).
    #[arg(long)]
    summary: bool,
    /// The quantiles of --summary [default: 0.05,0.25,0.5,0.75,0.95].
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        value_parser = parse_quantile,
        requires = "summary"
    )]
    quantiles: Vec<f64>,
    /// No progress lines on stderr.
    #[arg(long)]
    quiet: bool,
    /// A last column cpu_seconds, each member's CPU time (it differs from run to run: the
    /// tables of two runs are then no longer the same bytes).
    #[arg(long)]
    cpu_seconds: bool,
    /// Also write the table as NPY (a structured array, every number's bits kept; see
    /// docs/ensembles.md), converted from the complete CSV table.
    #[arg(long, value_name = "FILE")]
    npy: Option<PathBuf>,
}

/// The checked inputs of a run.
struct Plan {
    problem: ProblemArg,
    vary: Vec<Vary>,
    /// For each of the problem's parameters, the --vary that sets it.
    source: Vec<Option<usize>>,
    energy: Option<f64>,
    options: OptionsSpec,
    t_end: f64,
    members: usize,
    cpu_seconds: bool,
}

/// What the options are made from (an `Options` is made per call: it is not `Clone`).
#[derive(Clone, Copy)]
enum OptionsSpec {
    Tolerance { tol: f64, r: Option<usize> },
    Fixed { r: usize, h: f64 },
}

impl OptionsSpec {
    fn options(self, t_end: f64) -> Options {
        match self {
            OptionsSpec::Tolerance { tol, r } => {
                let o = Options::tolerance(tol).t_eval([t_end]);
                match r {
                    Some(r) => o.orders(r..=r),
                    None => o,
                }
            }
            OptionsSpec::Fixed { r, h } => Options::fixed(r, h).t_eval([t_end]),
        }
    }

    fn describe(self) -> String {
        match self {
            OptionsSpec::Tolerance { tol, r: None } => format!("--tol {tol:?}"),
            OptionsSpec::Tolerance { tol, r: Some(r) } => format!("--tol {tol:?} --r {r}"),
            OptionsSpec::Fixed { r, h } => format!("--r {r} --h {h:?}"),
        }
    }
}

impl Plan {
    fn new(args: &SolveArgs) -> Result<Plan, UsageError> {
        let problem = args
            .problem
            .ok_or_else(|| UsageError("--problem is required".into()))?;
        let t_end = args
            .t_end
            .ok_or_else(|| UsageError("--t-end is required".into()))?;
        if !(t_end.is_finite() && t_end >= 0.0) {
            return Err(UsageError(format!(
                "--t-end {t_end} must be finite and >= 0"
            )));
        }
        let names = problem.parameters();
        let mut source = vec![None; names.len()];
        for (j, v) in args.vary.iter().enumerate() {
            let Some(p) = names.iter().position(|n| *n == v.name) else {
                return Err(UsageError(format!(
                    "--vary {}: --problem {} has {}",
                    v.name,
                    problem.name(),
                    names.join(", ")
                )));
            };
            if source[p].is_some() {
                return Err(UsageError(format!("--vary {} is given twice", v.name)));
            }
            source[p] = Some(j);
        }
        if let Some(energy) = args.energy {
            if problem != ProblemArg::HenonHeiles {
                return Err(UsageError(format!(
                    "--energy applies only to henon-heiles, not to --problem {}",
                    problem.name()
                )));
            }
            if !energy.is_finite() {
                return Err(UsageError(format!("--energy {energy} must be finite")));
            }
            if source[2].is_some() {
                return Err(UsageError(
                    "--energy sets p1: it cannot be varied too".into(),
                ));
            }
        }
        let options = match (args.tol, args.r, args.h) {
            (Some(tol), r, None) => OptionsSpec::Tolerance { tol, r },
            (None, Some(r), Some(h)) => OptionsSpec::Fixed { r, h },
            _ => {
                return Err(UsageError("give --tol TOL, or --r R and --h H".into()));
            }
        };
        let r = match options {
            OptionsSpec::Tolerance { r, .. } => r,
            OptionsSpec::Fixed { r, .. } => Some(r),
        };
        if let Some(r) = r {
            if !(1..=ecr_codegen::MAX_R).contains(&r) {
                return Err(UsageError(format!(
                    "--r {r} must be in 1..={}",
                    ecr_codegen::MAX_R
                )));
            }
        }
        let members = args
            .vary
            .iter()
            .try_fold(1usize, |m, v| m.checked_mul(v.count))
            .ok_or_else(|| {
                UsageError(format!(
                    "the --vary counts multiply to more than {} members",
                    usize::MAX
                ))
            })?;
        Ok(Plan {
            problem,
            vary: args.vary.clone(),
            source,
            energy: args.energy,
            options,
            t_end,
            members,
            cpu_seconds: args.cpu_seconds,
        })
    }

    /// The values of member `i`'s --vary options, in their order (the first slowest).
    fn point(&self, mut i: usize) -> Vec<f64> {
        let mut point = vec![0.0; self.vary.len()];
        for (j, v) in self.vary.iter().enumerate().rev() {
            point[j] = v.value(i % v.count);
            i /= v.count;
        }
        point
    }

    /// The problem's parameters for member `i` (varied or default; p0 of duffing defaults to
    /// omega, p1 of henon-heiles follows --energy).
    fn parameters(&self, i: usize) -> Vec<Option<f64>> {
        let point = self.point(i);
        self.source.iter().map(|s| s.map(|j| point[j])).collect()
    }

    /// The run as a canonical command line (for the part files, where it identifies the
    /// ensemble).
    fn describe(&self) -> String {
        let mut d = format!(
            "ecr {}; --problem {}",
            env!("CARGO_PKG_VERSION"),
            self.problem.name()
        );
        for v in &self.vary {
            d += &format!(" --vary {}={:?}:{:?}:{}", v.name, v.from, v.to, v.count);
        }
        if let Some(e) = self.energy {
            d += &format!(" --energy {e:?}");
        }
        d += &format!(" {} --t-end {:?}", self.options.describe(), self.t_end);
        d
    }

    /// Whether the members run with a fixed step (status "ok" rather than "verified").
    fn fixed(&self) -> bool {
        matches!(self.options, OptionsSpec::Fixed { .. })
    }

    /// The output columns: t, the final state, the estimate, the energy error, the count of
    /// evaluations of g.
    fn outputs(&self) -> Vec<Column> {
        let mut c = vec![Column::f64("t")];
        c.extend(self.problem.state().iter().map(|s| Column::f64(*s)));
        c.push(Column::f64("error_estimate"));
        c.push(Column::f64("energy_error"));
        c.push(Column::u64("g_evals"));
        c
    }

    /// The table of the run (a part file for --shard).
    fn table(&self, part: bool) -> Table<'_> {
        let inputs = self
            .vary
            .iter()
            .map(|v| Column::f64(v.name.clone()))
            .collect();
        let table = Table::new(self.describe(), self.outputs()).inputs(inputs, |i, cells| {
            cells.extend(self.point(i).into_iter().map(Cell::F64));
        });
        let table = if self.cpu_seconds {
            table.cpu_seconds()
        } else {
            table
        };
        if part { table.as_part() } else { table }
    }
}

/// Duffing member: (ω, k, q0, p0).
fn duffing_member(p: &[Option<f64>], t_end: f64) -> ecr_runtime::Result<Problem<DuffingSystem>> {
    let omega = p[0].unwrap_or(5.0);
    let k = p[1].unwrap_or(0.07);
    let y0 = [p[2].unwrap_or(0.0), p[3].unwrap_or(omega)];
    Problem::new(Duffing::new(omega, k)?.system()?, y0, (0.0, t_end))
}

/// Hénon–Heiles member: (q1, q2, p1, p2), p1 from the energy if given.
fn henon_heiles_member(
    p: &[Option<f64>],
    energy: Option<f64>,
    t_end: f64,
) -> ecr_runtime::Result<Problem<HenonHeilesSystem>> {
    let (q1, q2, p2) = (
        p[0].unwrap_or(0.0),
        p[1].unwrap_or(0.0),
        p[3].unwrap_or(0.0),
    );
    let p1 = match energy {
        None => p[2].unwrap_or(0.5),
        Some(e) => {
            let rest = HenonHeiles::default().energy(&[q1, q2, 0.0, p2]);
            let twice = 2.0 * (e - rest);
            if twice < 0.0 {
                return Err(ecr_runtime::Error::InvalidInput(format!(
                    "no real p1 gives H = {e:?} at (q1, q2, p2) = ({q1:?}, {q2:?}, {p2:?}): \
                     H is already {rest:?} with p1 = 0"
                )));
            }
            twice.sqrt()
        }
    };
    Problem::new(
        HenonHeiles::new([q1, q2, p1, p2])?.system()?,
        [q1, q2, p1, p2],
        (0.0, t_end),
    )
}

/// The output cells of a member's solution: t, the final state (`dim` values), the estimate,
/// the energy error, the evaluations of g.
fn output_cells(dim: usize, solution: &Solution) -> Vec<Cell> {
    let mut cells = Vec::with_capacity(dim + 4);
    cells.push(Cell::F64(solution.t.last().copied().unwrap_or(f64::NAN)));
    let last = solution.last();
    cells.extend((0..dim).map(|c| Cell::F64(last.map_or(f64::NAN, |y| y[c]))));
    cells.push(solution.error_estimate.into());
    cells.push(solution.energy_error().into());
    cells.push(Cell::U64(solution.stats.total_g_evals() as u64));
    cells
}

/// Where the run has got to, for the interrupt handler.
static DONE: AtomicUsize = AtomicUsize::new(0);
static TOTAL: AtomicUsize = AtomicUsize::new(0);

/// On SIGINT or SIGTERM: one line on stderr saying how far the run got and that its rows are
/// kept for --resume, exit status 130 or 143.
fn report_interrupts() {
    super::interrupt::on_interrupt(|what| {
        format!(
            "{what} after {} of {} members; the rows finished are kept: run the same command \
             with --resume to solve the rest",
            DONE.load(Ordering::Relaxed),
            TOTAL.load(Ordering::Relaxed)
        )
    });
}

/// How often a progress line is printed where stderr is not a terminal (the environment
/// variable `ECR_PROGRESS_SECONDS` changes it).
const PROGRESS_EVERY: Duration = Duration::from_secs(5);

/// Progress: a bar on a terminal, a line every few seconds elsewhere (batch logs), nothing
/// with --quiet.
struct Reporter {
    bar: Option<ProgressBar>,
    every: Option<Duration>,
    start: Instant,
    last: Mutex<Instant>,
}

impl Reporter {
    fn new(total: usize, quiet: bool) -> Reporter {
        TOTAL.store(total, Ordering::Relaxed);
        let terminal = std::io::stderr().is_terminal();
        let every = std::env::var("ECR_PROGRESS_SECONDS")
            .ok()
            .and_then(|s| s.parse::<f64>().ok())
            .filter(|s| s.is_finite() && *s >= 0.0)
            .map_or(PROGRESS_EVERY, Duration::from_secs_f64);
        let now = Instant::now();
        Reporter {
            bar: (!quiet && terminal).then(|| super::progress::count_bar(total as u64, "members")),
            every: (!quiet && !terminal).then_some(every),
            start: now,
            last: Mutex::new(now),
        }
    }

    fn update(&self, p: &Progress) -> ControlFlow<()> {
        DONE.store(p.done, Ordering::Relaxed);
        if let Some(bar) = &self.bar {
            bar.set_position(p.done as u64);
        }
        if let Some(every) = self.every {
            let now = Instant::now();
            let mut last = self.last.lock().unwrap_or_else(|e| e.into_inner());
            if now.duration_since(*last) >= every || p.done == p.total {
                *last = now;
                let seconds = now.duration_since(self.start).as_secs_f64();
                let rate = (p.done - p.skipped) as f64 / seconds.max(1e-9);
                let left = (p.total - p.done) as f64 / rate.max(1e-300);
                let _ = writeln!(
                    std::io::stderr(),
                    "ecr ensemble: {} of {} members ({:.1} %), {:.3} members/s, about {} left",
                    p.done,
                    p.total,
                    100.0 * p.done as f64 / p.total.max(1) as f64,
                    rate,
                    duration(left)
                );
            }
        }
        ControlFlow::Continue(())
    }

    fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

/// Seconds as "3 h 12 min", "4 min 05 s", "12 s".
fn duration(seconds: f64) -> String {
    if !seconds.is_finite() {
        return "an unknown time".into();
    }
    let s = seconds.round() as u64;
    match s {
        0..60 => format!("{s} s"),
        60..3600 => format!("{} min {:02} s", s / 60, s % 60),
        _ => format!("{} h {:02} min", s / 3600, (s % 3600) / 60),
    }
}

/// The members of part k of n (0-based) of `members`.
fn part_len(members: usize, k: usize, n: usize) -> usize {
    ecr_runtime::ensemble::part_len(members, k, n)
}

/// Runs `ecr ensemble` (or `merge`).
pub fn run(args: &EnsembleArgs, out: &mut dyn Write) -> Result<(), UsageError> {
    match &args.command {
        Some(EnsembleCommand::Merge(m)) => merge(m, out),
        None => solve(&args.solve, out),
    }
}

/// The threads: `--threads` checked against four per CPU this process may use.
fn threads(threads: Option<i64>) -> Result<Option<usize>, UsageError> {
    let Some(n) = threads else {
        return Ok(None);
    };
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    let most = 4 * cpus;
    if n < 1 || n as u64 > most as u64 {
        return Err(UsageError(format!(
            "--threads {n}: between 1 and {most} (four per CPU this process may use: {cpus})"
        )));
    }
    Ok(Some(n as usize))
}

/// Runs `f` on a pool of `threads` threads, or on rayon's global pool.
fn with_threads<R: Send>(
    threads: Option<usize>,
    f: impl FnOnce() -> R + Send,
) -> Result<R, UsageError> {
    match threads {
        None => Ok(f()),
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map(|pool| pool.install(f))
            .map_err(|e| UsageError(format!("cannot start {n} threads: {e}"))),
    }
}

/// The processes of an MPI launch of an ecr built without the `mpi` feature: each would solve
/// the whole ensemble and write the same file.
#[cfg(not(feature = "mpi"))]
fn mpi_launch_without_mpi() -> Option<usize> {
    [
        "OMPI_COMM_WORLD_SIZE",
        "PMI_SIZE",
        "PMIX_SIZE",
        "MPI_LOCALNRANKS",
    ]
    .iter()
    .filter_map(|v| std::env::var(v).ok()?.parse::<usize>().ok())
    .find(|&n| n > 1)
}

/// How a run writes: a table (whole or part), a summary, or a table over MPI ranks.
enum Mode<'a> {
    Table {
        path: &'a Path,
        shard: Option<Shard>,
        resume: bool,
    },
    Summary {
        path: &'a Path,
        quantiles: &'a [f64],
    },
    #[cfg(feature = "mpi")]
    Mpi {
        world: &'a ecr::mpi::World,
        path: &'a Path,
        resume: bool,
    },
}

/// What a run did, for its summary line and exit status.
struct Outcome {
    report: TableReport,
}

/// The ensemble of `make` (shared φ-banks unless the operator varies) run in `mode`.
fn execute<S, M>(
    plan: &Plan,
    make: M,
    mode: &Mode<'_>,
    reporter: &Reporter,
) -> Result<Outcome, UsageError>
where
    S: System,
    <S::Op as LinearOperator>::Bank: Send + Sync,
    M: Fn(&(), usize) -> ecr_runtime::Result<Problem<S>> + Sync,
{
    let mut ensemble = Ensemble::new((), plan.members, make);
    if !plan.problem.operator_varies(&plan.source) {
        ensemble = ensemble.share_banks();
    }
    let options = plan.options.options(plan.t_end);
    let dim = plan.problem.state().len();
    let output = |_: usize, s: &Solution| output_cells(dim, s);
    let error = |e: ecr_runtime::Error| UsageError(e.to_string());
    let report = match *mode {
        Mode::Table {
            path,
            shard,
            resume,
        } => {
            let (k, n) = shard.map_or((0, 1), |s| (s.k - 1, s.n));
            let mut control = Control::new().part(k, n).progress(|p| reporter.update(p));
            if resume {
                control = control.resume();
            }
            let table = plan.table(shard.is_some());
            ensemble
                .write_table(&options, &control, &table, output, path)
                .map_err(error)?
        }
        Mode::Summary { path, quantiles } => {
            let mut file = OutputFile::stage(path)?;
            let outputs = plan.outputs();
            let summary = Summary::new(1, outputs.len(), quantiles).map_err(error)?;
            let control = Control::new().progress(|p| reporter.update(p));
            let result = ensemble
                .summarize(&options, &control, summary, |i, s, values| {
                    for (v, c) in values.iter_mut().zip(output(i, s)) {
                        *v = match c {
                            Cell::F64(x) => x,
                            Cell::U64(n) => n as f64,
                            Cell::Empty => f64::NAN,
                        };
                    }
                })
                .map_err(error)?;
            let io =
                |e: std::io::Error| UsageError(format!("cannot write '{}': {e}", path.display()));
            let mut text = "output,count,non_finite,mean,variance,min,max".to_string();
            for q in quantiles {
                text += &format!(",q{q:?}");
            }
            text.push('\n');
            for (c, column) in outputs.iter().enumerate() {
                let s = result.summary.get(0, c);
                text += &format!(
                    "{},{},{},{:?},{:?},{:?},{:?}",
                    column.name, s.count, s.non_finite, s.mean, s.variance, s.min, s.max
                );
                for (_, v) in &s.quantiles {
                    text += &format!(",{v:?}");
                }
                text.push('\n');
            }
            file.write_all(text.as_bytes()).map_err(io)?;
            file.commit()?;
            TableReport {
                members: plan.members,
                written: plan.members,
                verified: result.summary.members() as usize,
                unverified: result.unverified,
                failed: result.failed,
                stats: result.stats,
                complete: !result.stopped,
                ..TableReport::default()
            }
        }
        #[cfg(feature = "mpi")]
        Mode::Mpi {
            world,
            path,
            resume,
        } => {
            let mut control = Control::new().progress(|p| reporter.update(p));
            if resume {
                control = control.resume();
            }
            let table = plan.table(false);
            ecr::mpi::write_table(world, &ensemble, &options, &control, &table, output, path)
                .map_err(error)?
        }
    };
    Ok(Outcome { report })
}

fn solve(args: &SolveArgs, out: &mut dyn Write) -> Result<(), UsageError> {
    let plan = Plan::new(args)?;
    let path = args
        .out
        .as_deref()
        .ok_or_else(|| UsageError("--out is required".into()))?;
    let threads = threads(args.threads)?;
    let quantiles: Vec<f64> = if args.quantiles.is_empty() {
        vec![0.05, 0.25, 0.5, 0.75, 0.95]
    } else {
        args.quantiles.clone()
    };
    if args.npy.is_some() && (args.summary || args.shard.is_some()) {
        return Err(UsageError(
            "--npy writes the table of the whole ensemble: not with --summary, and for \
             --shard give it to 'ecr ensemble merge'"
                .into(),
        ));
    }
    if args.summary && (args.shard.is_some() || args.resume) {
        return Err(UsageError(
            "--summary keeps statistics in one process, not rows: it does not go with \
             --shard or --resume (write the table, or summarise in one run)"
                .into(),
        ));
    }
    #[cfg(feature = "mpi")]
    let world = ecr::mpi::World::from_launcher().map_err(|e| UsageError(e.to_string()))?;
    #[cfg(feature = "mpi")]
    let world = world.filter(|w| w.size() > 1);
    #[cfg(not(feature = "mpi"))]
    if let Some(n) = mpi_launch_without_mpi() {
        return Err(UsageError(format!(
            "ecr was started as {n} MPI processes but built without the mpi feature: each \
             would solve the whole ensemble (build with --features mpi, or run one process)"
        )));
    }
    let mode = match () {
        #[cfg(feature = "mpi")]
        () if world.is_some() => {
            if args.shard.is_some() || args.summary {
                return Err(UsageError(
                    "the ranks of MPI split the members already: --shard and --summary are \
                     for one process"
                        .into(),
                ));
            }
            Mode::Mpi {
                world: world.as_ref().expect("checked"),
                path,
                resume: args.resume,
            }
        }
        () if args.summary => Mode::Summary {
            path,
            quantiles: &quantiles,
        },
        () => Mode::Table {
            path,
            shard: args.shard,
            resume: args.resume,
        },
    };
    #[cfg(feature = "mpi")]
    let (rank, ranks) = world.as_ref().map_or((0, 1), |w| (w.rank(), w.size()));
    #[cfg(not(feature = "mpi"))]
    let (rank, ranks) = (0, 1);
    let (k, n) = args.shard.map_or((rank, ranks), |s| (s.k - 1, s.n));
    let reporter = Reporter::new(part_len(plan.members, k, n), args.quiet || rank > 0);
    report_interrupts();
    let start = Instant::now();
    let t_end = plan.t_end;
    let outcome = with_threads(threads, || match plan.problem {
        ProblemArg::Duffing => execute(
            &plan,
            |_: &(), i| duffing_member(&plan.parameters(i), t_end),
            &mode,
            &reporter,
        ),
        ProblemArg::HenonHeiles => execute(
            &plan,
            |_: &(), i| henon_heiles_member(&plan.parameters(i), plan.energy, t_end),
            &mode,
            &reporter,
        ),
    })??;
    reporter.finish();
    let r = &outcome.report;
    if rank > 0 {
        return Ok(());
    }
    if let (Some(npy), true) = (&args.npy, r.complete) {
        table_to_npy(path, npy).map_err(|e| UsageError(e.to_string()))?;
    }
    let what = match (&mode, args.shard) {
        (Mode::Summary { .. }, _) => format!("summary of {} members", plan.members),
        (_, Some(s)) => format!(
            "part {}/{} ({} of {} members)",
            s.k, s.n, r.members, plan.members
        ),
        _ if ranks > 1 => format!("{} members on {ranks} MPI ranks", plan.members),
        _ => format!("{} members", plan.members),
    };
    let kept = if r.kept > 0 {
        format!(
            " ({} rows kept from the unfinished run, {} solved now)",
            r.kept, r.written
        )
    } else {
        String::new()
    };
    let fixed = plan.fixed();
    writeln!(
        out,
        "wrote {}: {what}{kept}: {} {}, {} unverified, {} failed; {:.2} s",
        path.display(),
        r.verified,
        if fixed { "ok" } else { "verified" },
        r.unverified,
        r.failed,
        start.elapsed().as_secs_f64()
    )
    .map_err(|e| UsageError(format!("cannot write output: {e}")))?;
    if r.unverified + r.failed > 0 {
        super::set_exit_status(FAILED_MEMBERS_STATUS);
    }
    Ok(())
}

/// The exit status of a run whose table (or summary) is written but where some members have
/// no verified answer.
pub const FAILED_MEMBERS_STATUS: u8 = 3;

fn merge(args: &MergeArgs, out: &mut dyn Write) -> Result<(), UsageError> {
    let report = merge_parts(&args.parts, &args.out).map_err(|e| UsageError(e.to_string()))?;
    if let Some(npy) = &args.npy {
        table_to_npy(&args.out, npy).map_err(|e| UsageError(e.to_string()))?;
    }
    writeln!(
        out,
        "wrote {}: {} members from {} parts",
        args.out.display(),
        report.members,
        report.parts
    )
    .map_err(|e| UsageError(format!("cannot write output: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vary_and_shard_parse_or_say_why_not() {
        assert_eq!(
            parse_vary("q2=-0.5:0.5:11").unwrap(),
            Vary {
                name: "q2".into(),
                from: -0.5,
                to: 0.5,
                count: 11
            }
        );
        for bad in [
            "q2",
            "q2=1:2",
            "q2=a:1:2",
            "q2=0:1:0",
            "q2=0:1:1",
            "q2=0:inf:3",
            "q2=0:1:18446744073709551616",
        ] {
            assert!(parse_vary(bad).is_err(), "{bad}");
        }
        let v = parse_vary("p2=-0.4:0.4:5").unwrap();
        let grid: Vec<f64> = (0..5).map(|j| v.value(j)).collect();
        assert_eq!(grid, [-0.4, -0.2, 0.0, -0.4 + 0.8 * 0.75, 0.4]);
        assert_eq!(grid, ecr_runtime::solve::linspace(-0.4, 0.4, 5));
        assert_eq!(parse_vary("k=1e-3:1e-3:1").unwrap().value(0), 1e-3);
        assert_eq!(parse_shard("2/3").unwrap(), Shard { k: 2, n: 3 });
        for bad in ["0/3", "4/3", "1/0", "1", "a/b", "-1/3"] {
            let e = parse_shard(bad).unwrap_err();
            assert!(e.starts_with(&format!("--shard {bad}: ")), "{e}");
        }
    }

    #[test]
    fn the_first_vary_is_the_slowest() {
        let args = SolveArgs {
            problem: Some(ProblemArg::HenonHeiles),
            vary: vec![
                parse_vary("q2=0:0.2:3").unwrap(),
                parse_vary("p2=0:0.1:2").unwrap(),
            ],
            energy: Some(0.1),
            tol: Some(1e-6),
            r: None,
            h: None,
            t_end: Some(1.0),
            out: None,
            threads: None,
            shard: None,
            resume: false,
            summary: false,
            quantiles: Vec::new(),
            quiet: false,
            cpu_seconds: false,
            npy: None,
        };
        let plan = Plan::new(&args).unwrap();
        assert_eq!(plan.members, 6);
        let points: Vec<Vec<f64>> = (0..6).map(|i| plan.point(i)).collect();
        assert_eq!(
            points,
            [
                [0.0, 0.0],
                [0.0, 0.1],
                [0.1, 0.0],
                [0.1, 0.1],
                [0.2, 0.0],
                [0.2, 0.1]
            ]
        );
        assert_eq!(plan.parameters(3), [None, Some(0.1), None, Some(0.1)]);
    }
}
