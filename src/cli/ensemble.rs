//! `ecr ensemble`: a test problem over a grid of parameters and initial values, every member
//! solved with the same options on every core, one CSV row per member; `--shard K/N` and
//! `ecr ensemble merge` for the jobs of a job array; the ranks of MPI with the `mpi` feature.
//!
//! # The table
//!
//! One header row, then one row per member in member order: `member`, the varied values (in
//! the order of the `--vary` options), `status`, `t` (where the solution ends), the final
//! state (`q_end, p_end` or `q1_end, q2_end, p1_end, p2_end`), `error_estimate` (in units of
//! the tolerance; empty for a fixed step), `energy_error` (|H(y(t)) − H(y₀)| / |H(y₀)| at
//! the final time), `g_evals` (every evaluation of g of the member's solve), `message` (why
//! the answer is not verified, or the failure) and `cpu_seconds` (the CPU time of the member,
//! last so that tables of two runs compare equal without it). Numbers are written as Rust's
//! `{:?}` writes them, the shortest text that reads back to the same f64.
//!
//! # Parts
//!
//! A part (`--shard K/N`) holds the members K − 1, K − 1 + N, …: a line `# ecr ensemble part
//! K/N of M members: …` naming the ensemble, the header row, its rows, and the line `# end of
//! part K/N: R rows` last. `merge` refuses parts that are missing, given twice, of another
//! ensemble, or without their end line (a shard killed or still running), and writes rows
//! byte for byte those of the single run, in member order.

use super::UsageError;
use super::output::OutputFile;
use clap::{Args, Subcommand, ValueEnum};
use ecr::problems::{Duffing, DuffingSystem, HenonHeiles, HenonHeilesSystem};
use ecr_runtime::ensemble::{Control, Ensemble, MemberError, MemberResult};
use ecr_runtime::solve::{Options, Problem, Solution, linspace};
use std::io::Write;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

#[cfg(feature = "mpi")]
mod mpi;

/// Arguments of `ecr ensemble`.
#[derive(Args, Debug)]
#[command(
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true,
    after_help = "Members: the cartesian product of the --vary values, the first --vary \
                  slowest (member i = (i1 n2 + i2) n3 + i3 for three). The table is written \
                  atomically: FILE holds the previous table or the complete new one. A member \
                  that fails is a row with its status and message; bad input prints one line \
                  starting with 'error: ' on stderr and exits with status 2; an interrupted run \
                  (Ctrl-C) writes no table and exits with status 130. Job arrays: run each \
                  part with --shard K/N (K = 1..N), then 'ecr ensemble merge --out FILE \
                  PART...'. MPI (an ecr built with --features mpi): 'mpirun -n N ecr ensemble \
                  ...' splits the members over the ranks; rank 0 writes FILE."
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
    /// byte the table of one run (its CPU column aside).
    ///
    /// Parts that are missing, given twice, of different ensembles, or without their end line
    /// (a shard killed or still running) are refused with one line starting with 'error: ' on
    /// stderr and exit status 2.
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
    /// The COUNT values: `linspace(FROM, TO, COUNT)` (FROM + (TO − FROM) j / (COUNT − 1), TO
    /// exactly; the values numpy's `linspace` gives).
    fn values(&self) -> Vec<f64> {
        linspace(self.from, self.to, self.count)
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
    let count: usize = count
        .trim()
        .parse()
        .map_err(|_| format!("COUNT '{count}' is not a whole number >= 1"))?;
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
    let (k, n) = text.split_once('/').ok_or("expected K/N, e.g. 3/8")?;
    let (k, n): (usize, usize) = match (k.trim().parse(), n.trim().parse()) {
        (Ok(k), Ok(n)) => (k, n),
        _ => return Err("expected K/N with whole numbers, e.g. 3/8".to_string()),
    };
    if n == 0 || k == 0 || k > n {
        return Err(format!("part {k} of {n}: K must be in 1..=N"));
    }
    Ok(Shard { k, n })
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
    #[arg(long, allow_negative_numbers = true)]
    energy: Option<f64>,
    /// Solve every member to this tolerance (rtol = atol = TOL, verified over the whole span).
    #[arg(long, allow_negative_numbers = true, required_unless_present = "h")]
    tol: Option<f64>,
    /// Order parameter r (order 2r): with --h, required; with --tol, the order used.
    #[arg(long, required_unless_present = "tol")]
    r: Option<usize>,
    /// A fixed step size h > 0 instead of --tol (no verification, no estimate).
    #[arg(
        long,
        allow_negative_numbers = true,
        conflicts_with = "tol",
        requires = "r"
    )]
    h: Option<f64>,
    /// Final time T ≥ 0 (every member from t = 0).
    #[arg(long, allow_negative_numbers = true, required = true)]
    t_end: Option<f64>,
    /// The table (CSV), written atomically.
    #[arg(long, required = true)]
    out: Option<PathBuf>,
    /// Threads [default: RAYON_NUM_THREADS, else one per CPU this process may use].
    #[arg(long)]
    threads: Option<usize>,
    /// Solve only part K of N (K = 1..N: the members K − 1, K − 1 + N, …) and write it as a
    /// part file for 'ecr ensemble merge'.
    #[arg(long, value_name = "K/N", value_parser = parse_shard)]
    shard: Option<Shard>,
}

/// The checked inputs of a run.
struct Plan {
    problem: ProblemArg,
    vary: Vec<Vary>,
    /// The values of each --vary.
    values: Vec<Vec<f64>>,
    /// For each of the problem's parameters, the --vary that sets it.
    source: Vec<Option<usize>>,
    energy: Option<f64>,
    options: OptionsSpec,
    t_end: f64,
    members: usize,
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
            .ok_or_else(|| UsageError("the --vary counts multiply beyond 2^64 members".into()))?;
        let values = args.vary.iter().map(Vary::values).collect();
        Ok(Plan {
            problem,
            vary: args.vary.clone(),
            values,
            source,
            energy: args.energy,
            options,
            t_end,
            members,
        })
    }

    /// The values of member `i`'s --vary options, in their order (the first slowest).
    fn point(&self, mut i: usize) -> Vec<f64> {
        let mut point = vec![0.0; self.vary.len()];
        for (j, values) in self.values.iter().enumerate().rev() {
            point[j] = values[i % values.len()];
            i /= values.len();
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

    fn header(&self) -> String {
        let mut h = vec!["member".to_string()];
        h.extend(self.vary.iter().map(|v| v.name.clone()));
        h.push("status".into());
        h.push("t".into());
        h.extend(self.problem.state().iter().map(|s| s.to_string()));
        for c in [
            "error_estimate",
            "energy_error",
            "g_evals",
            "message",
            "cpu_seconds",
        ] {
            h.push(c.into());
        }
        h.join(",") + "\n"
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

/// What is kept of a member's solution.
#[derive(Clone, Copy, Debug)]
struct Kept {
    t: f64,
    y: [f64; 4],
    error_estimate: Option<f64>,
    energy_error: Option<f64>,
    g_evals: usize,
}

fn keep(solution: &Solution) -> Kept {
    let mut y = [f64::NAN; 4];
    if let Some(last) = solution.last() {
        for (a, b) in y.iter_mut().zip(last) {
            *a = *b;
        }
    }
    Kept {
        t: solution.t.last().copied().unwrap_or(f64::NAN),
        y,
        error_estimate: solution.error_estimate,
        energy_error: solution.energy_error(),
        g_evals: solution.stats.total_g_evals(),
    }
}

/// A field of a CSV row: as it is, or quoted (RFC 4180) where it holds a comma or a quote;
/// line breaks become spaces, so that every row is one line.
fn csv_field(text: &str) -> String {
    let text = text.replace(['\r', '\n'], " ");
    if text.contains([',', '"']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text
    }
}

fn number(x: Option<f64>) -> String {
    x.map_or_else(String::new, |x| format!("{x:?}"))
}

/// The row of a member (with its line break).
fn row(plan: &Plan, fixed: bool, m: &MemberResult<Kept>) -> String {
    let dim = plan.problem.state().len();
    let mut fields = vec![m.index.to_string()];
    fields.extend(plan.point(m.index).iter().map(|v| format!("{v:?}")));
    let (status, kept, message) = match &m.outcome {
        Ok(k) => (
            if fixed { "ok" } else { "verified" },
            Some(k),
            String::new(),
        ),
        Err(MemberError::Unverified { reason, output }) => {
            ("unverified", Some(output), reason.clone())
        }
        Err(MemberError::Failed(e)) => ("failed", None, e.to_string()),
        Err(MemberError::Panicked(msg)) => ("panicked", None, msg.clone()),
        Err(e) => ("not-run", None, e.to_string()),
    };
    fields.push(status.to_string());
    match kept {
        Some(k) => {
            fields.push(format!("{:?}", k.t));
            fields.extend(k.y[..dim].iter().map(|v| format!("{v:?}")));
            fields.push(number(k.error_estimate));
            fields.push(number(k.energy_error));
            fields.push(k.g_evals.to_string());
        }
        None => fields.extend(std::iter::repeat_n(String::new(), dim + 4)),
    }
    fields.push(csv_field(&message));
    fields.push(format!("{:?}", m.cpu.as_secs_f64()));
    fields.join(",") + "\n"
}

/// Where the run has got to, for the interrupt handler.
static DONE: AtomicUsize = AtomicUsize::new(0);
static TOTAL: AtomicUsize = AtomicUsize::new(0);

/// On SIGINT or SIGTERM: one line on stderr saying how far the run got, exit status 130 or
/// 143, no table (it is written only at the end, atomically).
fn report_interrupts() {
    super::interrupt::on_interrupt(|what| {
        format!(
            "{what} after {} of {} members; no table written",
            DONE.load(Ordering::Relaxed),
            TOTAL.load(Ordering::Relaxed)
        )
    });
}

/// The members of part k of n (0-based) of `members`, as the library splits them.
fn part_len(members: usize, k: usize, n: usize) -> usize {
    if k < members {
        (members - k).div_ceil(n)
    } else {
        0
    }
}

/// How the outcomes were, for the summary line.
#[derive(Default)]
struct Counts {
    verified: usize,
    unverified: usize,
    failed: usize,
}

impl Counts {
    fn add(&mut self, m: &MemberResult<Kept>) {
        match &m.outcome {
            Ok(_) => self.verified += 1,
            Err(MemberError::Unverified { .. }) => self.unverified += 1,
            Err(_) => self.failed += 1,
        }
    }

    fn describe(&self, fixed: bool) -> String {
        format!(
            "{} {}, {} unverified, {} failed",
            self.verified,
            if fixed { "ok" } else { "verified" },
            self.unverified,
            self.failed
        )
    }
}

/// Solves part k of n (0-based) of the plan's members on the current rayon pool: the rows,
/// in member order, and the counts.
fn solve_part(plan: &Plan, k: usize, n: usize) -> Result<(Vec<String>, Counts), UsageError> {
    let total = part_len(plan.members, k, n);
    TOTAL.store(total, Ordering::Relaxed);
    let bar = super::progress::count_bar(total as u64, "members");
    let control = Control::new().part(k, n).progress(|p| {
        DONE.store(p.done, Ordering::Relaxed);
        bar.set_position(p.done as u64);
        ControlFlow::Continue(())
    });
    let options = plan.options.options(plan.t_end);
    let fixed = plan.fixed();
    let t_end = plan.t_end;
    let result = match plan.problem {
        ProblemArg::Duffing => {
            let ensemble = Ensemble::new(plan, plan.members, |plan: &&Plan, i| {
                duffing_member(&plan.parameters(i), t_end)
            });
            ensemble.solve_with(&options, &control, |_, s| keep(s))
        }
        ProblemArg::HenonHeiles => {
            let ensemble = Ensemble::new(plan, plan.members, |plan: &&Plan, i| {
                henon_heiles_member(&plan.parameters(i), plan.energy, t_end)
            });
            ensemble.solve_with(&options, &control, |_, s| keep(s))
        }
    }
    .map_err(|e| UsageError(e.to_string()))?;
    bar.finish_and_clear();
    let mut counts = Counts::default();
    let rows = result
        .members
        .iter()
        .map(|m| {
            counts.add(m);
            row(plan, fixed, m)
        })
        .collect();
    Ok((rows, counts))
}

/// The first line of a part file.
fn part_head(plan: &Plan, shard: Shard) -> String {
    format!(
        "# ecr ensemble part {}/{} of {} members: {}\n",
        shard.k,
        shard.n,
        plan.members,
        plan.describe()
    )
}

/// The last line of a part file.
fn part_end(shard: Shard, rows: usize) -> String {
    format!("# end of part {}/{}: {rows} rows\n", shard.k, shard.n)
}

/// Runs `ecr ensemble` (or `merge`).
pub fn run(args: &EnsembleArgs, out: &mut dyn Write) -> Result<(), UsageError> {
    match &args.command {
        Some(EnsembleCommand::Merge(m)) => merge(m, out),
        None => solve(&args.solve, out),
    }
}

/// Runs `f` on a pool of `threads` threads, or on rayon's global pool.
fn with_threads<R: Send>(
    threads: Option<usize>,
    f: impl FnOnce() -> R + Send,
) -> Result<R, UsageError> {
    match threads {
        None => Ok(f()),
        Some(0) => Err(UsageError("--threads must be >= 1".into())),
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

fn solve(args: &SolveArgs, out: &mut dyn Write) -> Result<(), UsageError> {
    let plan = Plan::new(args)?;
    let path = args
        .out
        .as_deref()
        .ok_or_else(|| UsageError("--out is required".into()))?;
    // The rows held until the end: a row is about 200 bytes of text, and what the library
    // keeps per member about as much again.
    super::memory::check(
        &format!("an ensemble of {} members", plan.members),
        32.0 * 1024.0 * 1024.0 + 512.0 * plan.members as f64,
    )?;
    #[cfg(feature = "mpi")]
    if let Some(world) = mpi::World::init()? {
        return mpi::solve(&world, &plan, args, path, out);
    }
    #[cfg(not(feature = "mpi"))]
    if let Some(n) = mpi_launch_without_mpi() {
        return Err(UsageError(format!(
            "ecr was started as {n} MPI processes but built without the mpi feature: each \
             would solve the whole ensemble (build with --features mpi, or run one process)"
        )));
    }
    let mut file = OutputFile::stage(path)?;
    report_interrupts();
    let start = Instant::now();
    let (k, n) = args.shard.map_or((0, 1), |s| (s.k - 1, s.n));
    let (rows, counts) = with_threads(args.threads, || solve_part(&plan, k, n))??;
    let io = |e: std::io::Error| UsageError(format!("cannot write '{}': {e}", path.display()));
    if let Some(shard) = args.shard {
        file.write_all(part_head(&plan, shard).as_bytes())
            .map_err(io)?;
    }
    file.write_all(plan.header().as_bytes()).map_err(io)?;
    for r in &rows {
        file.write_all(r.as_bytes()).map_err(io)?;
    }
    if let Some(shard) = args.shard {
        file.write_all(part_end(shard, rows.len()).as_bytes())
            .map_err(io)?;
    }
    file.commit()?;
    let what = match args.shard {
        Some(s) => format!(
            "part {}/{} ({} of {} members)",
            s.k,
            s.n,
            rows.len(),
            plan.members
        ),
        None => format!("{} members", plan.members),
    };
    writeln!(
        out,
        "wrote {}: {what}: {}; {:.2} s",
        path.display(),
        counts.describe(plan.fixed()),
        start.elapsed().as_secs_f64()
    )
    .map_err(|e| UsageError(format!("cannot write output: {e}")))
}

/// A part file read and checked.
struct Part {
    path: PathBuf,
    shard: Shard,
    members: usize,
    description: String,
    header: String,
    /// Its rows, each with its line break.
    rows: Vec<String>,
}

fn read_part(path: &Path) -> Result<Part, UsageError> {
    let shown = path.display();
    let text = std::fs::read_to_string(path)
        .map_err(|e| UsageError(format!("cannot read part '{shown}': {e}")))?;
    let not_a_part = || {
        UsageError(format!(
            "'{shown}' is not a part written by 'ecr ensemble --shard K/N'"
        ))
    };
    let mut lines: Vec<&str> = text.split_inclusive('\n').collect();
    let first = lines.first().copied().ok_or_else(not_a_part)?;
    let head = first
        .strip_prefix("# ecr ensemble part ")
        .and_then(|h| h.strip_suffix('\n'))
        .ok_or_else(not_a_part)?;
    let (kn, rest) = head.split_once(" of ").ok_or_else(not_a_part)?;
    let (members, description) = rest.split_once(" members: ").ok_or_else(not_a_part)?;
    let shard = parse_shard(kn).map_err(|_| not_a_part())?;
    let members: usize = members.parse().map_err(|_| not_a_part())?;
    let end = part_end(shard, part_len(members, shard.k - 1, shard.n));
    let unfinished = || {
        UsageError(format!(
            "part '{shown}' ({}/{}) does not end with '{}': its shard was killed or has not \
             finished; run it again",
            shard.k,
            shard.n,
            end.trim_end()
        ))
    };
    if lines.len() < 3 || lines.last() != Some(&end.as_str()) {
        return Err(unfinished());
    }
    lines.pop();
    let header = lines[1].to_string();
    let rows: Vec<String> = lines[2..].iter().map(|l| l.to_string()).collect();
    let expected = part_len(members, shard.k - 1, shard.n);
    if rows.len() != expected {
        return Err(UsageError(format!(
            "part '{shown}' ({}/{}) has {} rows instead of {expected}: the file was changed \
             after its shard wrote it",
            shard.k,
            shard.n,
            rows.len()
        )));
    }
    for (j, r) in rows.iter().enumerate() {
        let expect = shard.k - 1 + j * shard.n;
        let index = r.split(',').next().and_then(|f| f.parse::<usize>().ok());
        if index != Some(expect) || !r.ends_with('\n') {
            return Err(UsageError(format!(
                "part '{shown}' ({}/{}): row {} should be member {expect}: the file was \
                 changed after its shard wrote it",
                shard.k,
                shard.n,
                j + 1
            )));
        }
    }
    Ok(Part {
        path: path.to_path_buf(),
        shard,
        members,
        description: description.to_string(),
        header,
        rows,
    })
}

fn merge(args: &MergeArgs, out: &mut dyn Write) -> Result<(), UsageError> {
    let mut parts = args
        .parts
        .iter()
        .map(|p| read_part(p))
        .collect::<Result<Vec<_>, _>>()?;
    let first = &parts[0];
    for p in &parts[1..] {
        let same = p.shard.n == first.shard.n
            && p.members == first.members
            && p.description == first.description
            && p.header == first.header;
        if !same {
            return Err(UsageError(format!(
                "'{}' and '{}' are parts of different ensembles ({}/{} of {} members: {}; \
                 {}/{} of {} members: {})",
                first.path.display(),
                p.path.display(),
                first.shard.k,
                first.shard.n,
                first.members,
                first.description,
                p.shard.k,
                p.shard.n,
                p.members,
                p.description
            )));
        }
    }
    let n = first.shard.n;
    parts.sort_by_key(|p| p.shard.k);
    for w in parts.windows(2) {
        if w[0].shard.k == w[1].shard.k {
            return Err(UsageError(format!(
                "part {}/{n} is given twice ('{}', '{}')",
                w[0].shard.k,
                w[0].path.display(),
                w[1].path.display()
            )));
        }
    }
    let missing: Vec<String> = (1..=n)
        .filter(|k| parts.iter().all(|p| p.shard.k != *k))
        .map(|k| k.to_string())
        .collect();
    if !missing.is_empty() {
        return Err(UsageError(format!(
            "{} of {n} parts missing: {} (each part is one 'ecr ensemble --shard K/{n}' run)",
            missing.len(),
            missing.join(", ")
        )));
    }
    let mut file = OutputFile::stage(&args.out)?;
    let io = |e: std::io::Error| UsageError(format!("cannot write '{}': {e}", args.out.display()));
    file.write_all(parts[0].header.as_bytes()).map_err(io)?;
    let members = parts[0].members;
    for i in 0..members {
        file.write_all(parts[i % n].rows[i / n].as_bytes())
            .map_err(io)?;
    }
    file.commit()?;
    writeln!(
        out,
        "wrote {}: {members} members from {n} parts",
        args.out.display()
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
        ] {
            assert!(parse_vary(bad).is_err(), "{bad}");
        }
        let grid = parse_vary("p2=-0.4:0.4:5").unwrap().values();
        assert_eq!(grid, [-0.4, -0.2, 0.0, -0.4 + 0.8 * 0.75, 0.4]);
        assert_eq!(parse_vary("k=1e-3:1e-3:1").unwrap().values(), [1e-3]);
        assert_eq!(parse_shard("2/3").unwrap(), Shard { k: 2, n: 3 });
        for bad in ["0/3", "4/3", "1/0", "1", "a/b"] {
            assert!(parse_shard(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn fields_with_commas_quotes_or_line_breaks_stay_in_one_field_on_one_line() {
        assert_eq!(csv_field("plain text"), "plain text");
        assert_eq!(csv_field("a, b"), "\"a, b\"");
        assert_eq!(csv_field("say \"x\""), "\"say \"\"x\"\"\"");
        assert_eq!(csv_field("two\nlines"), "two lines");
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
