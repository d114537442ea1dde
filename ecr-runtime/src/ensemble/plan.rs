//! Which members a solve runs: [`Control`] (the whole ensemble or part k of n, from which
//! member, resumed or not, with a progress callback), [`Progress`], and the split of the
//! members into parts (member i is in part i mod n), which the threads, the parts of a job
//! array and the ranks of MPI share ([`part_len`]).

use std::ops::ControlFlow;

#[cfg(doc)]
use super::{Ensemble, MemberError, fingerprint};
use crate::error::{Error, Result};

/// Which members a solve runs (every member, or a [part](Self::part) of them), and a
/// [progress](Self::progress) callback that may stop the work early.
#[derive(Default)]
pub struct Control<'a> {
    pub(super) part: (usize, usize),
    pub(super) progress: Option<ProgressFn<'a>>,
    pub(super) start: usize,
    pub(super) resume: bool,
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

/// Member `j` of part k of n (0-based k, j): k + j n.
pub fn member_of(k: usize, n: usize, j: usize) -> usize {
    k + j * n
}

/// The part of n (0-based) that holds member `i`, and its position in that part: (i mod n,
/// i / n). The one split of the members that the threads, the parts of a job array and the
/// ranks of MPI share (see [`member_of`]).
pub fn part_of(i: usize, n: usize) -> (usize, usize) {
    (i % n, i / n)
}

/// The members of part k of n (0-based k) of `len` members: k, k + n, k + 2n, … below `len`.
pub fn part_len(len: usize, k: usize, n: usize) -> usize {
    if k < len { (len - k).div_ceil(n) } else { 0 }
}

/// `(k, n)` if part k of n exists.
pub(super) fn check_part((k, n): (usize, usize)) -> Result<(usize, usize)> {
    if n == 0 || k >= n {
        return Err(Error::InvalidParameter(format!(
            "part {k} of {n}: the parts are 0..n, n >= 1"
        )));
    }
    Ok((k, n))
}

/// The position in part k of n of the first member whose index is at least `member`.
pub(super) fn first_of_part(member: usize, k: usize, n: usize) -> usize {
    if member <= k {
        0
    } else {
        (member - k).div_ceil(n)
    }
}
