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

mod engine;
pub mod fingerprint;
mod npy;
mod plan;
mod summary;
pub mod table;

use std::time::Duration;

pub use fingerprint::Fingerprint;
pub use npy::table_to_npy;
pub use plan::{Control, Progress, member_of, part_len, part_of};
pub use summary::{Stat, Summary};
pub use table::{Cell, Column, Kind, Table, TableReport, merge_parts};

use crate::error::Error;
use crate::solve::Stats;
#[cfg(doc)]
use crate::solve::{Options, Problem, SolveError};

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

#[cfg(test)]
mod table_tests;

#[cfg(test)]
mod tests {
    use super::engine::cpu_time;
    use super::*;
    use crate::operator::Dense;
    use crate::solve::{Options, Problem};
    use crate::system::Semilinear;
    use nalgebra::DMatrix;
    use std::sync::atomic::{AtomicUsize, Ordering};

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
