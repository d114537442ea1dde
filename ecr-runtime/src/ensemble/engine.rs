//! The engine of an ensemble: the members of a part solved on rayon's threads in windows and
//! delivered in member order ([`Ensemble::solve_in_order`] and what is built on it: `solve`,
//! `summarize`, `write_table`), each member made, solved and mapped with a panic of a user
//! function caught.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use rayon::prelude::*;

use super::plan::{check_part, first_of_part};
use super::{
    Cell, Control, Ensemble, EnsembleSolution, Fingerprint, MemberError, MemberResult, Progress,
    Streamed, Summary, SummaryResult, Table, TableReport, fingerprint, member_of, part_len, table,
};
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
                .fingerprint_fields(super::fingerprint::numbers)
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
                index: member_of(k, n, j),
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
                    let index = member_of(k, n, j);
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
pub(super) fn cpu_time() -> Duration {
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
