//! Many trajectories: an [`Ensemble`] of problems made from a template, every member solved
//! with the same [`Options`] on rayon's threads, each member's result kept as a user function
//! maps it.
//!
//! ```
//! use ecr_runtime::prelude::*;
//!
//! // q'' = −q − q³ (H = ½p² + ½q² + ¼q⁴) from 100 amplitudes in [0.1, 2]: the system is shared,
//! // member i starts from (q, p) = (a_i, 0).
//! let grad_v = |y: &[f64], g: &mut [f64]| g[0] = y[0].powi(3);
//! let system = Hamiltonian::canonical(DMatrix::identity(2, 2), grad_v)?
//!     .potential(|y| 0.25 * y[0].powi(4));
//! let template = Problem::new(&system, [0.1, 0.0], (0.0, 10.0))?;
//! let amplitudes = linspace(0.1, 2.0, 100);
//! let ensemble = Ensemble::new(template, amplitudes.len(), |template: &Problem<_>, i| {
//!     Problem::new(*template.system(), [amplitudes[i], 0.0], template.span())
//! });
//! // Kept per member: q at t = 10 and the energy error, not the trajectory.
//! let options = Options::tolerance(1e-8).t_eval([10.0]);
//! let result = ensemble.solve(&options, |_, sol| (sol.last().unwrap()[0], sol.energy_error()))?;
//! assert_eq!(result.members.len(), 100);
//! for member in &result.members {
//!     let (q, energy_error) = member.outcome.as_ref().expect("verified");
//!     assert!(q.abs() <= amplitudes[member.index] + 1e-8);
//!     assert!(energy_error.unwrap() < 1e-8);
//! }
//! assert!(result.stats.steps > 0); // summed over the members
//! # Ok::<(), ecr_runtime::Error>(())
//! ```
//!
//! # What is kept
//!
//! The output function sees each member's solution (a verified answer, or the best solution of
//! an answer that could not be verified) and returns what is kept: a scalar, a Poincaré
//! section, a summary. The solution itself is dropped at once, so that an ensemble of millions
//! of members holds only their outputs. Each member's [`MemberResult`] carries its output or
//! its own [`MemberError`] (not verified, failed, a panic in a user function, not run): one
//! member's failure never ends the others, and [`Ensemble::solve`] returns `Err` only for what
//! concerns them all (invalid options or a part that does not exist).
//!
//! # Determinism
//!
//! Member i's result depends on i alone: the members are independent problems, and every
//! solve computes the same numbers on any thread (the concurrent stage path of large systems
//! too). The results come back in member order, bit for bit the same with any number of
//! threads, and the same in any [part](Control::part) of the ensemble as in the whole. The
//! threads are rayon's: the global pool (`RAYON_NUM_THREADS`, else one per CPU), or a pool of
//! your own when the call runs inside its `install`.
//!
//! # Parts
//!
//! [`Control::part`] solves every n-th member from member k (k, k + n, k + 2n, …): the same
//! deterministic split serves processes of MPI (rank k of n) and the jobs of a job array,
//! whose results joined in member order are those of the whole ensemble. Interleaved parts
//! share the costly regions of a parameter grid between them, where contiguous blocks would
//! give one part all of them.
//!
//! # Streams, tables, summaries
//!
//! [`Ensemble::solve_in_order`] hands each member's result to a function of yours in member
//! order as the members finish, holding at most a window of results (at most 256 per
//! thread) to restore the order: memory does not grow with the members.
//! [`Ensemble::write_table`] writes the rows of a [`Table`] that way into a file (CSV),
//! synced every second, so that a job killed at any moment keeps the rows it finished and a
//! run with [`Control::resume`] solves only the members that are missing; the file appears
//! under its name only once complete ([`table`] says how). [`Ensemble::summarize`] keeps a
//! [`Summary`] (count, mean, variance, extremes and quantiles of every output) instead of
//! the outputs.
//!
//! # Shared φ-banks
//!
//! Each solve builds the φ-functions of its linear operator for every step size it uses
//! (dense operators: O(d³) each). When every member has the same linear operator (members
//! that differ in y₀, or in the nonlinearity only), [`Ensemble::share_banks`] lets them take
//! the banks from one cache: the numbers are the same, bit for bit, as each member building
//! its own.

pub mod fingerprint;
mod npy;
mod summary;
pub mod table;

use std::ops::ControlFlow;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use rayon::prelude::*;

pub use fingerprint::Fingerprint;
pub use npy::table_to_npy;
pub use summary::{Stat, Summary};
pub use table::{Cell, Column, Kind, Table, TableReport, merge_parts};

use crate::error::{Error, Result};
use crate::operator::LinearOperator;
use crate::solve::{Options, Problem, SOLVE_CACHE_BANKS, Solution, SolveCache, SolveError, Stats};
use crate::system::System;

/// Members per thread of the window that restores member order at most (see
/// [`Ensemble::solve_in_order`]).
const WINDOW_PER_THREAD: usize = 256;

/// What a window of members should take: windows start at one member per thread and double
/// while they take less than a quarter of this, halve while they take more, so that results
/// come out (and a table's rows reach its file) about this often whatever a member costs.
const WINDOW_TIME: Duration = Duration::from_millis(250);

/// An ensemble of `len` problems: member i is made by `make(&template, i)` (a new y₀, new
/// parameters) and solved with the ensemble's [`Options`].
///
/// The template is whatever the members are made from: usually a [`Problem`], whose system
/// the members share when the template borrows it (`Problem<&S>`, as in the module's example:
/// `*template.system()` is then a `&S` that outlives the call).
#[derive(Clone, Debug)]
pub struct Ensemble<T, M> {
    template: T,
    len: usize,
    make: M,
    share: bool,
}

impl<T, M> Ensemble<T, M> {
    /// The ensemble of `members` problems, member i made by `make(&template, i)`, i in
    /// `0..members`.
    pub fn new(template: T, members: usize, make: M) -> Self {
        Ensemble {
            template,
            len: members,
            make,
            share: false,
        }
    }

    /// Members share their system's linear operator: their solves take the φ-banks from one
    /// cache instead of each building its own (see the module docs). Only for ensembles
    /// whose members all have the same linear operator A (the same y₀-independent matrix,
    /// spectrum, …): the cache's keys are the method and the step size, not the operator,
    /// and a member with another A would be solved with the wrong banks.
    #[must_use]
    pub fn share_banks(mut self) -> Self {
        self.share = true;
        self
    }

    /// Whether the members [share](Self::share_banks) their φ-banks.
    pub fn shares_banks(&self) -> bool {
        self.share
    }

    /// The number of members.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the ensemble has no member.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The template.
    pub fn template(&self) -> &T {
        &self.template
    }
}

/// Which members a solve runs (every member, or a [part](Self::part) of them), and a
/// [progress](Self::progress) callback that may stop the work early.
#[derive(Default)]
pub struct Control<'a> {
    part: (usize, usize),
    progress: Option<ProgressFn<'a>>,
    start: usize,
    resume: bool,
}

type ProgressFn<'a> = Box<dyn Fn(&Progress) -> ControlFlow<()> + Sync + 'a>;

impl std::fmt::Debug for Control<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Control")
            .field("part", &self.part)
            .field("progress", &self.progress.is_some())
            .field("start", &self.start)
            .field("resume", &self.resume)
            .finish()
    }
}

impl<'a> Control<'a> {
    /// Every member, no callback.
    pub fn new() -> Self {
        Control {
            part: (0, 1),
            progress: None,
            start: 0,
            resume: false,
        }
    }

    /// Only the members from index `member` on (of the part): those before are taken as
    /// done, for [`Ensemble::solve_in_order`] continuing a stream that an earlier run
    /// delivered up to `member` (exclusive).
    #[must_use]
    pub fn start_at(mut self, member: usize) -> Self {
        self.start = member;
        self
    }

    /// [`Ensemble::write_table`] continues the table that an earlier run of the same
    /// ensemble left unfinished at the same path, killed or stopped: its rows are kept and
    /// only the members after them are solved. The table is then the one an uninterrupted
    /// run writes, byte for byte (its CPU column aside). Without an unfinished table it
    /// starts from the first member. An unfinished table of another run (another
    /// [fingerprint]: options, span, inputs, member count, columns, key,
    /// description, …) is refused in one line naming the field that differs, and left as it
    /// is; a row that does not read as the table writes it is solved again, with those
    /// after it.
    #[must_use]
    pub fn resume(mut self) -> Self {
        self.resume = true;
        self
    }

    /// The part (k of n) this control asks for.
    pub fn part_of(&self) -> (usize, usize) {
        self.part
    }

    /// Whether this control asks to [resume](Self::resume).
    pub fn resumes(&self) -> bool {
        self.resume
    }

    /// This control's progress callback and resume flag for part `k` of `n`, from member
    /// `start` on: for engines that split an ensemble themselves (the MPI engine of the
    /// `ecr` crate).
    pub fn split(&self, k: usize, n: usize, start: usize) -> Control<'_> {
        Control {
            part: (k, n),
            progress: self
                .progress
                .as_ref()
                .map(|f| Box::new(move |p: &Progress| f(p)) as ProgressFn<'_>),
            start,
            resume: self.resume,
        }
    }

    /// Only part `k` of `n` (k < n): the members k, k + n, k + 2n, … of the ensemble.
    #[must_use]
    pub fn part(mut self, k: usize, n: usize) -> Self {
        self.part = (k, n);
        self
    }

    /// Calls `f` after each member, on the thread that solved it (members finish in any
    /// order; `f` is called from several threads at once). Returning
    /// [`ControlFlow::Break`] stops the work: the members being solved finish, the others
    /// are not started ([`MemberError::NotRun`]).
    #[must_use]
    pub fn progress(mut self, f: impl Fn(&Progress) -> ControlFlow<()> + Sync + 'a) -> Self {
        self.progress = Some(Box::new(f));
        self
    }
}

/// Where the work of [`Ensemble::solve_with`] has got to, for its progress callback.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Progress {
    /// Members finished (this one included), those skipped because they were done before
    /// ([`Control::start_at`], [`Control::resume`]) included.
    pub done: usize,
    /// Members of the part, those skipped included.
    pub total: usize,
    /// Members skipped because they were done before.
    pub skipped: usize,
    /// Of the members finished, those whose answer could not be verified.
    pub unverified: usize,
    /// Of the members finished, those that failed (no solution, or a panic).
    pub failed: usize,
}

/// The results of an ensemble: one [`MemberResult`] per member solved, in member order.
#[derive(Clone, Debug)]
pub struct EnsembleSolution<O> {
    /// The members' results, in member order (of the part, if one was asked for).
    pub members: Vec<MemberResult<O>>,
    /// What the solves cost, summed over the members that have a solution (verified or not).
    pub stats: Stats,
    /// Whether the progress callback stopped the work (some members are then
    /// [`MemberError::NotRun`]).
    pub stopped: bool,
}

impl<O> EnsembleSolution<O> {
    /// The outputs of the verified members (`None` for the others), in member order.
    pub fn outputs(&self) -> impl Iterator<Item = Option<&O>> {
        self.members.iter().map(|m| m.outcome.as_ref().ok())
    }

    /// The number of members whose answer was verified (for a fixed method: completed).
    pub fn verified(&self) -> usize {
        self.members.iter().filter(|m| m.outcome.is_ok()).count()
    }
}

/// One member's result.
#[derive(Clone, Debug)]
pub struct MemberResult<O> {
    /// The member's index in the ensemble.
    pub index: usize,
    /// What the output function kept of its solution, or why there is no verified answer.
    pub outcome: std::result::Result<O, MemberError<O>>,
    /// The CPU time of the thread that made, solved and mapped the member (on Unix; the wall
    /// time elsewhere). The concurrent stage path of large systems also computes on other
    /// threads, which this does not count. Zero for a member not run.
    pub cpu: Duration,
}

/// Why a member has no verified answer.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub enum MemberError<O> {
    /// The answer could not be verified to the tolerance
    /// ([`SolveError::Unverified`]): why, and what the output function kept of the best
    /// solution.
    Unverified {
        /// Why, in words.
        reason: String,
        /// The output of the best solution.
        output: O,
    },
    /// Making the member or solving it failed, with no solution (bad parameters, a failed
    /// step of a fixed method, a tolerance below what f64 can verify, …).
    Failed(Error),
    /// A user function (the member function, the system's, the output function) panicked:
    /// its message.
    Panicked(String),
    /// Not solved: the progress callback stopped the work first.
    NotRun,
}

impl<O> MemberError<O> {
    /// The output of an unverified member's best solution.
    pub fn output(&self) -> Option<&O> {
        match self {
            MemberError::Unverified { output, .. } => Some(output),
            _ => None,
        }
    }
}

impl<O> std::fmt::Display for MemberError<O> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MemberError::Unverified { reason, .. } => write!(f, "not verified: {reason}"),
            MemberError::Failed(e) => write!(f, "failed: {e}"),
            MemberError::Panicked(msg) => write!(f, "panicked: {msg}"),
            MemberError::NotRun => write!(f, "not run: the ensemble was stopped"),
        }
    }
}

impl<O: std::fmt::Debug> std::error::Error for MemberError<O> {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            MemberError::Failed(e) => Some(e),
            _ => None,
        }
    }
}

/// What [`Ensemble::solve_in_order`] did besides delivering the members.
#[derive(Clone, Debug, Default)]
pub struct Streamed {
    /// Members delivered to the sink.
    pub delivered: usize,
    /// Members skipped as done before ([`Control::start_at`]).
    pub skipped: usize,
    /// What the solves cost, summed over the delivered members that have a solution.
    pub stats: Stats,
    /// Whether the progress callback stopped the work (the members after the last one
    /// delivered were not delivered).
    pub stopped: bool,
}

/// What [`Ensemble::summarize`] returns.
#[derive(Clone, Debug)]
pub struct SummaryResult {
    /// The statistics over the verified members (for a fixed method: those that completed).
    pub summary: Summary,
    /// Members whose answer could not be verified (left out of the summary).
    pub unverified: usize,
    /// Members that failed, panicked or were not run (left out of the summary).
    pub failed: usize,
    /// What the solves cost, summed over the members that have a solution.
    pub stats: Stats,
    /// Whether the progress callback stopped the work.
    pub stopped: bool,
}

/// The members of part k of n (0-based k) of `len` members: k, k + n, k + 2n, … below `len`.
pub fn part_len(len: usize, k: usize, n: usize) -> usize {
    if k < len { (len - k).div_ceil(n) } else { 0 }
}

impl<T, M, S> Ensemble<T, M>
where
    T: Sync,
    M: Fn(&T, usize) -> Result<Problem<S>> + Sync,
    S: System,
    // The φ-banks of the operator go between threads when shared (every operator of this
    // crate's banks are plain data).
    <S::Op as LinearOperator>::Bank: Send + Sync,
{
    /// Member `index`, made as a solve makes it.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] for an index beyond the ensemble, and what the member function
    /// returns.
    pub fn member(&self, index: usize) -> Result<Problem<S>> {
        if index >= self.len {
            return Err(Error::InvalidInput(format!(
                "member {index} of an ensemble of {} members",
                self.len
            )));
        }
        (self.make)(&self.template, index)
    }

    /// The [fingerprint] of a run of this ensemble with `options` into
    /// `table`: what [`write_table`](Self::write_table) writes at the top of the table and
    /// a resume or a merge compares. Makes member 0 (for its span and y₀) and formats every
    /// member's input cells (for their digest).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] if the table's input function gives another number of cells
    /// than it has input columns.
    pub fn fingerprint(&self, options: &Options, table: &Table<'_>) -> Result<Fingerprint> {
        let mut fields = vec![(
            "version".to_string(),
            format!("ecr-runtime {}", env!("CARGO_PKG_VERSION")),
        )];
        fields.extend(
            options
                .fingerprint_fields()
                .into_iter()
                .map(|(n, v)| (n.to_string(), v)),
        );
        let (span, y0) = if self.len == 0 {
            ("no member".to_string(), "no member".to_string())
        } else {
            match catch_unwind(AssertUnwindSafe(|| self.member(0))) {
                Ok(Ok(p)) => (format!("{:?}", p.span()), fingerprint::numbers(p.y0())),
                Ok(Err(e)) => {
                    let e = format!("member 0 not made: {e}");
                    (e.clone(), e)
                }
                Err(_) => {
                    let e = "member 0 not made: a panic".to_string();
                    (e.clone(), e)
                }
            }
        };
        let header = table.header();
        fields.extend([
            ("span".to_string(), span),
            ("y0".to_string(), y0),
            ("members".to_string(), self.len.to_string()),
            ("columns".to_string(), header.trim_end().to_string()),
            ("inputs".to_string(), table.inputs_digest(self.len)?),
            ("key".to_string(), table.key_text().to_string()),
            ("description".to_string(), table.description().to_string()),
        ]);
        Ok(Fingerprint::new(fields))
    }

    /// Solves every member with `options` on rayon's threads, keeping `output(i, &solution)`
    /// of member i (see the module docs).
    ///
    /// # Errors
    /// Invalid `options` ([`Error::InvalidParameter`], [`Error::InvalidInput`], …), before
    /// any member is solved; [`Error::InvalidInput`] when the results of all the members
    /// cannot be held (use [`solve_in_order`](Self::solve_in_order), whose memory does not
    /// grow with the members). A member's own failure is its [`MemberError`], never an
    /// `Err`.
    pub fn solve<O, F>(&self, options: &Options, output: F) -> Result<EnsembleSolution<O>>
    where
        O: Send,
        F: Fn(usize, &Solution) -> O + Sync,
    {
        self.solve_with(options, &Control::new(), output)
    }

    /// [`solve`](Self::solve) of the members and with the progress callback of `control`
    /// (members before [`Control::start_at`] are left out).
    ///
    /// # Errors
    /// As [`solve`](Self::solve), and [`Error::InvalidParameter`] for a part k of n with
    /// n = 0 or k ≥ n. The vector of results is checked to fit in memory before anything
    /// is solved.
    pub fn solve_with<O, F>(
        &self,
        options: &Options,
        control: &Control<'_>,
        output: F,
    ) -> Result<EnsembleSolution<O>>
    where
        O: Send,
        F: Fn(usize, &Solution) -> O + Sync,
    {
        options.validate()?;
        let (k, n) = check_part(control.part)?;
        let total = part_len(self.len, k, n);
        let first = first_of_part(control.start, k, n).min(total);
        crate::storage::ensure_bytes_allocatable(
            &format!("the results of {} members", total - first),
            (total - first).checked_mul(size_of::<MemberResult<O>>()),
        )?;
        // Grown as the members come (a stopped run holds only what it solved), not allocated
        // in full up front.
        let mut members = Vec::with_capacity((total - first).min(1 << 12));
        let streamed = self.stream(options, control, first, &output, &mut |m| {
            members.push(m);
            Ok(())
        })?;
        for j in first + members.len()..total {
            members.push(MemberResult {
                index: k + j * n,
                outcome: Err(MemberError::NotRun),
                cpu: Duration::ZERO,
            });
        }
        Ok(EnsembleSolution {
            members,
            stats: streamed.stats,
            stopped: streamed.stopped,
        })
    }

    /// Solves the members of `control`'s part on rayon's threads and calls `sink` with each
    /// member's result **in member order**, on the calling thread, as they finish: members
    /// are solved in windows (from one member per thread, doubled while a window takes under
    /// 60 ms and halved while it takes over 250 ms, at most 256 per thread), and a window's
    /// results are handed on in order once it is complete, so that what is held at once does
    /// not depend on the number of members and results come out every quarter of a second or
    /// so. Nothing is kept after `sink` returns.
    ///
    /// A progress callback that stops the work ends the stream after the last member solved
    /// before it in member order ([`Streamed::stopped`]); members not delivered are not
    /// passed to `sink` (neither as [`MemberError::NotRun`]). Members before
    /// [`Control::start_at`] are skipped.
    ///
    /// # Errors
    /// Invalid `options` or part (as [`solve_with`](Self::solve_with)), before any member
    /// is solved, and the first `Err` that `sink` returns (the stream ends there).
    pub fn solve_in_order<O, F, K>(
        &self,
        options: &Options,
        control: &Control<'_>,
        output: F,
        mut sink: K,
    ) -> Result<Streamed>
    where
        O: Send,
        F: Fn(usize, &Solution) -> O + Sync,
        K: FnMut(MemberResult<O>) -> Result<()>,
    {
        options.validate()?;
        let (k, n) = check_part(control.part)?;
        let first = first_of_part(control.start, k, n).min(part_len(self.len, k, n));
        self.stream(options, control, first, &output, &mut sink)
    }

    /// Solves the members and keeps a [`Summary`] of the values that `output` writes for
    /// each verified member (the summary's [`len`](Summary::len) of them, time-major), in
    /// member order, instead of the outputs. `summary` says which quantiles and how many
    /// values.
    ///
    /// # Errors
    /// As [`solve_in_order`](Self::solve_in_order).
    pub fn summarize<F>(
        &self,
        options: &Options,
        control: &Control<'_>,
        mut summary: Summary,
        output: F,
    ) -> Result<SummaryResult>
    where
        F: Fn(usize, &Solution, &mut [f64]) + Sync,
    {
        let len = summary.len();
        let (mut unverified, mut failed) = (0, 0);
        let streamed = self.solve_in_order(
            options,
            control,
            |i, solution| {
                let mut values = vec![f64::NAN; len];
                output(i, solution, &mut values);
                values
            },
            |m| {
                match m.outcome {
                    Ok(values) => summary.add(&values)?,
                    Err(MemberError::Unverified { .. }) => unverified += 1,
                    Err(_) => failed += 1,
                }
                Ok(())
            },
        )?;
        Ok(SummaryResult {
            summary,
            unverified,
            failed,
            stats: streamed.stats,
            stopped: streamed.stopped,
        })
    }

    /// Solves the members of `control`'s part and writes their rows into the [`Table`] at
    /// `path` as they finish (see [`table`]): `output(i, &solution)` gives the cells of
    /// member i's output columns. With [`Control::resume`], the rows an unfinished earlier
    /// run of the same table left are kept and only the missing members are solved.
    ///
    /// # Errors
    /// Invalid options or part, a `path` that cannot be written, a file that another run is
    /// writing (one line each, before any member is solved); a failed write or sync, and
    /// output functions that return another number of cells than the table has output
    /// columns (the table is then left unfinished, to be resumed).
    pub fn write_table<F>(
        &self,
        options: &Options,
        control: &Control<'_>,
        table: &Table<'_>,
        output: F,
        path: &Path,
    ) -> Result<TableReport>
    where
        F: Fn(usize, &Solution) -> Vec<Cell> + Sync,
    {
        options.validate()?;
        let (k, n) = check_part(control.part)?;
        let part = control.part != (0, 1) || table.is_part();
        // The cheap refusal first: the fingerprint formats every member's input cells.
        table::TableWriter::check_fits(path, table, self.len, part.then_some((k, n)))?;
        let fingerprint = self.fingerprint(options, table)?;
        let mut writer = table::TableWriter::open(
            path,
            table,
            &fingerprint,
            part.then_some((k, n)),
            control.resume,
        )?;
        let from = writer.first_missing_member();
        let first = first_of_part(from.max(control.start), k, n).min(part_len(self.len, k, n));
        let mut row = Vec::new();
        let streamed = self.stream(
            options,
            control,
            first,
            &|i, solution: &Solution| (output(i, solution), solution.error_estimate.is_some()),
            &mut |m| {
                row.clear();
                table.format_row(&m, &mut row)?;
                writer.write_row(&row, Table::status_of(&m))
            },
        )?;
        let complete = !streamed.stopped;
        let report = writer.report(streamed.stats, streamed.stopped);
        if complete {
            writer.commit()?;
        } else {
            writer.pause()?;
        }
        Ok(report)
    }

    /// The engine: members `first..` of the part, in windows, delivered in order.
    fn stream<O, F>(
        &self,
        options: &Options,
        control: &Control<'_>,
        first: usize,
        output: &F,
        sink: &mut dyn FnMut(MemberResult<O>) -> Result<()>,
    ) -> Result<Streamed>
    where
        O: Send,
        F: Fn(usize, &Solution) -> O + Sync,
    {
        let (k, n) = control.part;
        let total = part_len(self.len, k, n);
        let cache = self
            .share
            .then(|| Arc::new(SolveCache::<S>::new(SOLVE_CACHE_BANKS)));
        let stats = Mutex::new(Stats::default());
        let stop = AtomicBool::new(false);
        let (done, unverified, failed) = (
            AtomicUsize::new(first),
            AtomicUsize::new(0),
            AtomicUsize::new(0),
        );
        let threads = rayon::current_num_threads().max(1);
        let most = (threads * WINDOW_PER_THREAD).min(1 << 16);
        let mut window = threads;
        let mut results = Vec::new();
        let mut streamed = Streamed {
            skipped: first,
            ..Streamed::default()
        };
        let mut j = first;
        while j < total && !streamed.stopped {
            let end = total.min(j.saturating_add(window));
            let started = std::time::Instant::now();
            (j..end)
                .into_par_iter()
                .map(|j| {
                    let index = k + j * n;
                    if stop.load(Ordering::Relaxed) {
                        return (
                            MemberResult {
                                index,
                                outcome: Err(MemberError::NotRun),
                                cpu: Duration::ZERO,
                            },
                            None,
                        );
                    }
                    let start = cpu_time();
                    let (outcome, member_stats) = self.one(index, options, output, &cache);
                    let cpu = cpu_time().saturating_sub(start);
                    match &outcome {
                        Ok(_) => {}
                        Err(MemberError::Unverified { .. }) => {
                            unverified.fetch_add(1, Ordering::Relaxed);
                        }
                        Err(_) => {
                            failed.fetch_add(1, Ordering::Relaxed);
                        }
                    }
                    let done = done.fetch_add(1, Ordering::Relaxed) + 1;
                    if let Some(progress) = &control.progress {
                        let p = Progress {
                            done,
                            total,
                            skipped: first,
                            unverified: unverified.load(Ordering::Relaxed),
                            failed: failed.load(Ordering::Relaxed),
                        };
                        if progress(&p).is_break() {
                            stop.store(true, Ordering::Relaxed);
                        }
                    }
                    let m = MemberResult {
                        index,
                        outcome,
                        cpu,
                    };
                    (m, member_stats)
                })
                .collect_into_vec(&mut results);
            for (m, member_stats) in results.drain(..) {
                if matches!(m.outcome, Err(MemberError::NotRun)) {
                    streamed.stopped = true;
                    break;
                }
                if let Some(s) = member_stats {
                    add(&mut stats.lock().unwrap_or_else(|e| e.into_inner()), &s);
                }
                sink(m)?;
                streamed.delivered += 1;
            }
            streamed.stopped |= stop.load(Ordering::Relaxed) && end < total;
            j = end;
            let took = started.elapsed();
            if took < WINDOW_TIME / 4 {
                window = (window * 2).min(most);
            } else if took > WINDOW_TIME {
                window = (window / 2).max(threads);
            }
        }
        streamed.stats = stats.into_inner().unwrap_or_else(|e| e.into_inner());
        Ok(streamed)
    }

    /// Member `index` made, solved and mapped, a panic of a user function caught: its outcome
    /// and, if it has a solution, its stats.
    fn one<O, F>(
        &self,
        index: usize,
        options: &Options,
        output: &F,
        cache: &Option<Arc<SolveCache<S>>>,
    ) -> (std::result::Result<O, MemberError<O>>, Option<Stats>)
    where
        F: Fn(usize, &Solution) -> O + Sync,
    {
        // A panic leaves nothing of the member's behind but what its own closures share with
        // the others, which they were given only by shared reference (the bank cache is
        // filled under its lock with complete banks only).
        let run = catch_unwind(AssertUnwindSafe(|| {
            let problem = match (self.make)(&self.template, index) {
                Ok(p) => p,
                Err(e) => return (Err(MemberError::Failed(e)), None),
            };
            let solved = match cache {
                Some(cache) => problem.solve_sharing(options, cache),
                None => problem.solve(options),
            };
            match solved {
                Ok(solution) => {
                    let solution = solution.into_data();
                    (Ok(output(index, &solution)), Some(solution.stats))
                }
                Err(SolveError::Unverified { reason, solution }) => {
                    let kept = output(index, &solution);
                    let error = MemberError::Unverified {
                        reason,
                        output: kept,
                    };
                    (Err(error), Some(solution.stats))
                }
                Err(e) => (Err(MemberError::Failed(Error::from(e))), None),
            }
        }));
        run.unwrap_or_else(|payload| (Err(MemberError::Panicked(panic_message(&*payload))), None))
    }
}

/// `(k, n)` if part k of n exists.
fn check_part((k, n): (usize, usize)) -> Result<(usize, usize)> {
    if n == 0 || k >= n {
        return Err(Error::InvalidParameter(format!(
            "part {k} of {n}: the parts are 0..n, n >= 1"
        )));
    }
    Ok((k, n))
}

/// The position in part k of n of the first member whose index is at least `member`.
fn first_of_part(member: usize, k: usize, n: usize) -> usize {
    if member <= k {
        0
    } else {
        (member - k).div_ceil(n)
    }
}

/// The message of a panic's payload (`panic!` with a literal or a formatted string).
fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".to_string())
}

/// `total += s`, field by field (every field named: a new one is a compile error here).
fn add(total: &mut Stats, s: &Stats) {
    let Stats {
        steps,
        g_evals,
        sweeps,
        check_steps,
        check_g_evals,
        pilot_steps,
        pilot_g_evals,
        discarded_steps,
        discarded_g_evals,
        retries,
        dense_evals,
        dense_g_evals,
    } = *s;
    total.steps += steps;
    total.g_evals += g_evals;
    total.sweeps += sweeps;
    total.check_steps += check_steps;
    total.check_g_evals += check_g_evals;
    total.pilot_steps += pilot_steps;
    total.pilot_g_evals += pilot_g_evals;
    total.discarded_steps += discarded_steps;
    total.discarded_g_evals += discarded_g_evals;
    total.retries += retries;
    total.dense_evals += dense_evals;
    total.dense_g_evals += dense_g_evals;
}

/// The CPU time of the calling thread (Unix: `CLOCK_THREAD_CPUTIME_ID`); elsewhere, or if the
/// clock cannot be read, the time since the first call.
fn cpu_time() -> Duration {
    #[cfg(unix)]
    {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: clock_gettime writes the timespec it is given.
        if unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) } == 0 {
            return Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32);
        }
    }
    static START: std::sync::OnceLock<std::time::Instant> = std::sync::OnceLock::new();
    START.get_or_init(std::time::Instant::now).elapsed()
}

#[cfg(test)]
mod table_tests;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::operator::Dense;
    use crate::system::Semilinear;
    use nalgebra::DMatrix;

    fn oscillator() -> Semilinear<Dense, impl Fn(&[f64], &mut [f64]) + Sync> {
        let a = Dense::new(DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -1.0, 0.0])).unwrap();
        Semilinear::new(a, |y: &[f64], g: &mut [f64]| {
            g[0] = 0.0;
            g[1] = -y[0].powi(3);
        })
    }

    #[test]
    fn parts_hold_every_member_once_in_order() {
        let system = oscillator();
        let template = Problem::new(&system, [0.0, 1.0], (0.0, 0.5)).unwrap();
        let ensemble = Ensemble::new(template, 10, |t: &Problem<_>, i| {
            Problem::new(*t.system(), [0.0, 1.0 + i as f64 / 10.0], t.span())
        });
        let options = Options::fixed(2, 0.1);
        let whole = ensemble.solve(&options, |i, _| i).unwrap();
        let indices: Vec<usize> = whole.members.iter().map(|m| m.index).collect();
        assert_eq!(indices, (0..10).collect::<Vec<_>>());
        let mut seen = Vec::new();
        for k in 0..3 {
            let part = ensemble
                .solve_with(&options, &Control::new().part(k, 3), |i, _| i)
                .unwrap();
            for m in &part.members {
                assert_eq!(m.index % 3, k);
                assert_eq!(*m.outcome.as_ref().unwrap(), m.index);
            }
            seen.extend(part.members.iter().map(|m| m.index));
        }
        seen.sort_unstable();
        assert_eq!(seen, indices);
        // A part beyond the members is empty; parts that do not exist are refused.
        let empty = Ensemble::new((), 2, |_: &(), _| {
            Problem::new(&system, [0.0, 1.0], (0.0, 1.0))
        });
        let part = empty
            .solve_with(&options, &Control::new().part(4, 5), |_, _| ())
            .unwrap();
        assert!(part.members.is_empty());
        for (k, n) in [(0, 0), (3, 3)] {
            let e = empty.solve_with(&options, &Control::new().part(k, n), |_, _| ());
            assert!(matches!(e, Err(Error::InvalidParameter(_))), "{k} of {n}");
        }
    }

    #[test]
    fn stats_are_summed_over_the_members() {
        let system = oscillator();
        let ensemble = Ensemble::new(3, 3, |&steps: &usize, i| {
            let t_end = (i + 1) as f64 * 0.1 * steps as f64;
            Problem::new(&system, [0.0, 1.0], (0.0, t_end))
        });
        let result = ensemble
            .solve(&Options::fixed(2, 0.1), |_, s| s.stats.steps)
            .unwrap();
        let steps: Vec<usize> = result.outputs().map(|s| *s.unwrap()).collect();
        assert_eq!(steps, [3, 6, 9]);
        assert_eq!(result.stats.steps, 18);
    }

    #[test]
    fn bad_options_are_refused_before_any_member() {
        let system = oscillator();
        let made = AtomicUsize::new(0);
        let ensemble = Ensemble::new((), 4, |_: &(), _| {
            made.fetch_add(1, Ordering::Relaxed);
            Problem::new(&system, [0.0, 1.0], (0.0, 1.0))
        });
        let e = ensemble.solve(&Options::tolerance(-1.0), |_, _| ());
        assert!(matches!(e, Err(Error::InvalidParameter(_))));
        assert_eq!(made.load(Ordering::Relaxed), 0);
    }

    #[test]
    fn the_cpu_clock_advances() {
        let start = cpu_time();
        let mut x = 0.0_f64;
        for i in 0..2_000_000 {
            x = (x + i as f64).sqrt();
        }
        assert!(x > 0.0);
        assert!(cpu_time() > start);
    }
}
