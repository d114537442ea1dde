//! Ensembles over the ranks of MPI (feature `mpi`; the `mpi` crate, rsmpi, over the system's
//! MPI library): [`write_table`] splits the members of any
//! [`Ensemble`](ecr_runtime::ensemble::Ensemble) over the ranks as the parts of a job array
//! split them (rank k solves the members k, k + n, …) and rank 0 writes the
//! [`Table`] in member order as the rows arrive: byte for byte the table of one process
//! (without the optional CPU column), streamed, synced and resumable as
//! [`Ensemble::write_table`](ecr_runtime::ensemble::Ensemble::write_table) writes it.
//!
//! ```no_run
//! # use ecr::runtime::ensemble::{Cell, Column, Control, Ensemble, Table};
//! # use ecr::runtime::prelude::*;
//! # fn main() -> ecr::runtime::Result<()> {
//! # let grad_v = |y: &[f64], g: &mut [f64]| g[0] = y[0].powi(3);
//! # let system = Hamiltonian::canonical(DMatrix::identity(2, 2), grad_v)?;
//! # let ensemble = Ensemble::new((), 100, |_: &(), i| {
//! #     Problem::new(&system, [0.01 * i as f64, 0.0], (0.0, 10.0))
//! # });
//! let table = Table::new("q'' = -q - q^3, q0 = i/100, T = 10", vec![Column::f64("q_end")]);
//! let options = Options::tolerance(1e-8).t_eval([10.0]);
//! let output = |_: usize, s: &Solution| vec![Cell::F64(s.last().unwrap()[0])];
//! match ecr::mpi::World::from_launcher()? {
//!     // Started by mpirun, srun, mpiexec: every rank calls this, rank 0 writes.
//!     Some(world) => {
//!         ecr::mpi::write_table(&world, &ensemble, &options, &Control::new(), &table, output, "sweep.csv".as_ref())?;
//!     }
//!     // A plain run: MPI is not started at all.
//!     None => {
//!         ensemble.write_table(&options, &Control::new(), &table, output, "sweep.csv".as_ref())?;
//!     }
//! }
//! # Ok(())
//! # }
//! ```
//!
//! # When MPI is started
//!
//! Only when the process was started by an MPI launcher: [`World::from_launcher`] looks for
//! the variables that Open MPI (`OMPI_COMM_WORLD_SIZE`), MPICH and Intel MPI (`PMI_SIZE`,
//! `PMI_RANK`), PMIx launchers such as Slurm's `srun --mpi=pmix` (`PMIX_RANK`) and
//! MVAPICH (`MPI_LOCALNRANKS`) set, and initialises MPI only then: a plain run neither loads
//! the launcher's daemon nor pays MPI's start-up.
//!
//! # Threads and messages
//!
//! Every rank solves its members on rayon's threads (the pool the call runs in). MPI is
//! initialised with `MPI_THREAD_SERIALIZED`: ranks other than 0 send their rows in batches
//! from the calling thread; rank 0 solves its own members on the calling thread and gathers
//! on a second thread of its own, which holds at most a batch per rank and a bounded queue of
//! its own rows. A progress callback of `control` sees the members of its own rank; under
//! MPI it must not stop the work.

use ecr_runtime::ensemble::table::{Status, TableWriter};
use ecr_runtime::ensemble::{
    Control, Ensemble, MemberResult, Table, TableReport, table::RowOutput,
};
use ecr_runtime::operator::LinearOperator;
use ecr_runtime::solve::{Options, Problem, Solution};
use ecr_runtime::system::System;
use ecr_runtime::{Error, Result};
use mpi::Threading;
use mpi::environment::Universe;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::collections::VecDeque;
use std::path::Path;
use std::sync::mpsc;

/// Rows a rank sends at once.
const BATCH_ROWS: usize = 1024;

/// The variables MPI launchers set in the processes they start, with the number of
/// processes where they tell it.
const LAUNCHER_VARIABLES: [&str; 5] = [
    "OMPI_COMM_WORLD_SIZE",
    "PMI_SIZE",
    "PMI_RANK",
    "PMIX_RANK",
    "MPI_LOCALNRANKS",
];

/// Whether an MPI launcher started this process (see the module docs).
pub fn launched_by_mpi() -> bool {
    LAUNCHER_VARIABLES
        .iter()
        .any(|v| std::env::var_os(v).is_some())
}

/// The communicator, shared with rank 0's gathering thread: MPI is initialised with
/// `MPI_THREAD_SERIALIZED`, and the engine never calls MPI from two threads at once (the
/// calling thread makes no MPI call while the gathering thread runs).
struct Comm(SimpleCommunicator);

// SAFETY: see `Comm`: serialized use of a communicator from several threads is what
// MPI_THREAD_SERIALIZED allows.
unsafe impl Send for Comm {}
// SAFETY: as above; the only concurrent access is none.
unsafe impl Sync for Comm {}

/// This process's place among the ranks of an MPI launch.
pub struct World {
    comm: Comm,
    rank: usize,
    size: usize,
    /// Finalizes MPI when dropped.
    _universe: Universe,
}

impl std::fmt::Debug for World {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("World")
            .field("rank", &self.rank)
            .field("size", &self.size)
            .finish()
    }
}

impl World {
    /// MPI's world if an MPI launcher started this process (MPI is initialised then, and
    /// finalised when the `World` is dropped); `None` for a plain run, where MPI is not
    /// touched.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] if MPI cannot be initialised, or not with
    /// `MPI_THREAD_SERIALIZED`.
    pub fn from_launcher() -> Result<Option<World>> {
        if !launched_by_mpi() {
            return Ok(None);
        }
        let (universe, threading) = mpi::initialize_with_threading(Threading::Serialized)
            .ok_or_else(|| Error::InvalidInput("MPI could not be initialized".into()))?;
        if threading < Threading::Serialized {
            return Err(Error::InvalidInput(format!(
                "the MPI library gives {threading:?} thread support; the ensemble needs \
                 Serialized"
            )));
        }
        let world = universe.world();
        let (rank, size) = (world.rank() as usize, world.size() as usize);
        Ok(Some(World {
            comm: Comm(world),
            rank,
            size,
            _universe: universe,
        }))
    }

    /// This process's rank.
    pub fn rank(&self) -> usize {
        self.rank
    }

    /// The number of ranks.
    pub fn size(&self) -> usize {
        self.size
    }

    /// Ends every rank of the launch with `status` (`MPI_Abort`).
    pub fn abort(&self, status: i32) -> ! {
        self.comm.0.abort(status)
    }
}

/// A batch of rows: their bytes and statuses (empty: the rank is done).
fn send_batch(comm: &SimpleCommunicator, bytes: &[u8], statuses: &[u8]) {
    let root = comm.process_at_rank(0);
    root.send(&[statuses.len() as u64, bytes.len() as u64][..]);
    if !statuses.is_empty() {
        root.send(statuses);
        root.send(bytes);
    }
}

/// The rows rank 0 has received from one rank and not written yet.
#[derive(Default)]
struct Queue {
    rows: VecDeque<(Vec<u8>, Status)>,
    done: bool,
}

/// [`Ensemble::write_table`] over the ranks of `world` (see the module docs): every rank
/// calls it with the same arguments; rank 0 writes `path` and returns the table's report,
/// the other ranks return the report of their own rows (`members` and `written` only).
/// With [`Control::resume`], rank 0 keeps the rows of an unfinished table of the same
/// ensemble and every rank solves only its members after them.
///
/// # Errors
/// As [`Ensemble::write_table`] on rank 0 (a path rank 0 cannot write is an error on every
/// rank, before any member is solved); [`Error::InvalidInput`] for a `control` with a part
/// (the ranks are the parts).
pub fn write_table<T, M, S, F>(
    world: &World,
    ensemble: &Ensemble<T, M>,
    options: &Options,
    control: &Control<'_>,
    table: &Table<'_>,
    output: F,
    path: &Path,
) -> Result<TableReport>
where
    T: Sync,
    M: Fn(&T, usize) -> Result<Problem<S>> + Sync,
    S: System,
    <S::Op as LinearOperator>::Bank: Send + Sync,
    F: Fn(usize, &Solution) -> Vec<ecr_runtime::ensemble::Cell> + Sync,
{
    if control.part_of() != (0, 1) {
        return Err(Error::InvalidInput(
            "a part of an ensemble over MPI ranks: the ranks are the parts already".into(),
        ));
    }
    let comm = &world.comm.0;
    let (rank, size) = (world.rank, world.size);
    let len = ensemble.len();
    let opened = (rank == 0).then(|| {
        // The cheap refusal first: the fingerprint formats every member's input cells.
        TableWriter::check_fits(path, table, len, None)?;
        let fingerprint = ensemble.fingerprint(options, table)?;
        TableWriter::open(path, table, &fingerprint, None, control_resume(control))
    });
    let mut msg = [0u64; 2];
    if let Some(Ok(w)) = &opened {
        msg = [1, w.first_missing_member() as u64];
    }
    comm.process_at_rank(0).broadcast_into(&mut msg[..]);
    let writer = match opened {
        Some(w) => Some(w?),
        None if msg[0] == 0 => {
            return Err(Error::InvalidInput(format!(
                "rank 0 cannot write '{}'",
                path.display()
            )));
        }
        None => None,
    };
    let from = msg[1] as usize;
    let mine = control.split(rank, size, from);
    let keep = |i: usize, s: &Solution| -> RowOutput { (output(i, s), s.error_estimate.is_some()) };
    let Some(mut writer) = writer else {
        // Ranks other than 0: rows in batches to rank 0.
        let (mut bytes, mut statuses, mut row) = (Vec::new(), Vec::new(), Vec::new());
        let mut written = 0;
        let streamed =
            ensemble.solve_in_order(options, &mine, keep, |m: MemberResult<RowOutput>| {
                row.clear();
                table.format_row(&m, &mut row)?;
                bytes.extend_from_slice(&row);
                statuses.push(Table::status_of(&m).code());
                written += 1;
                if statuses.len() == BATCH_ROWS {
                    send_batch(comm, &bytes, &statuses);
                    bytes.clear();
                    statuses.clear();
                }
                Ok(())
            })?;
        if !statuses.is_empty() {
            send_batch(comm, &bytes, &statuses);
        }
        send_batch(comm, &[], &[]);
        return Ok(TableReport {
            members: ecr_runtime::ensemble::part_len(len, rank, size),
            written,
            stats: streamed.stats,
            complete: !streamed.stopped,
            ..TableReport::default()
        });
    };
    // Rank 0: its own rows through a bounded queue to the gathering thread, which writes
    // every row in member order.
    let (tx, rx) = mpsc::sync_channel::<(Vec<u8>, Status)>(4 * BATCH_ROWS);
    let comm_shared = &world.comm;
    let gathered = std::thread::scope(|scope| {
        let gather = scope.spawn(move || -> Result<TableWriter> {
            let comm = &comm_shared.0;
            let mut queues: Vec<Queue> = (0..size).map(|_| Queue::default()).collect();
            for i in from..len {
                let (r, _) = ecr_runtime::ensemble::part_of(i, size);
                let (row, status) = if r == 0 {
                    rx.recv().map_err(|_| {
                        Error::InvalidInput(format!("rank 0 stopped before member {i}"))
                    })?
                } else {
                    let q = &mut queues[r];
                    while q.rows.is_empty() && !q.done {
                        let source = comm.process_at_rank(r as i32);
                        let (head, _) = source.receive_vec::<u64>();
                        let [count, nbytes] = head[..] else {
                            return Err(Error::InvalidInput(format!("rank {r} sent no batch")));
                        };
                        if count == 0 {
                            q.done = true;
                            break;
                        }
                        let (codes, _) = source.receive_vec::<u8>();
                        let (bytes, _) = source.receive_vec::<u8>();
                        if codes.len() as u64 != count || bytes.len() as u64 != nbytes {
                            return Err(Error::InvalidInput(format!(
                                "rank {r} sent a broken batch"
                            )));
                        }
                        let rows = bytes.split_inclusive(|&b| b == b'\n');
                        for (row, &code) in rows.zip(&codes) {
                            let status = Status::from_code(code).ok_or_else(|| {
                                Error::InvalidInput(format!("rank {r} sent a broken batch"))
                            })?;
                            q.rows.push_back((row.to_vec(), status));
                        }
                    }
                    q.rows.pop_front().ok_or_else(|| {
                        Error::InvalidInput(format!("rank {r} ended before member {i}"))
                    })?
                };
                writer.write_row(&row, status)?;
            }
            // The end markers of the ranks that had no members left to send.
            for (r, q) in queues.iter_mut().enumerate().skip(1) {
                if !q.done {
                    let (head, _) = comm.process_at_rank(r as i32).receive_vec::<u64>();
                    if head.first() != Some(&0) {
                        return Err(Error::InvalidInput(format!(
                            "rank {r} sent more rows than its members"
                        )));
                    }
                }
            }
            Ok(writer)
        });
        let mut row = Vec::new();
        let streamed =
            ensemble.solve_in_order(options, &mine, keep, |m: MemberResult<RowOutput>| {
                row.clear();
                table.format_row(&m, &mut row)?;
                tx.send((row.clone(), Table::status_of(&m)))
                    .map_err(|_| Error::InvalidInput("the gathering of rank 0 stopped".into()))
            });
        drop(tx);
        let writer = gather
            .join()
            .map_err(|_| Error::InvalidInput("rank 0's gathering thread panicked".into()))?;
        Ok::<_, Error>((streamed?, writer?))
    });
    let (streamed, writer) = gathered?;
    let report = writer.report(streamed.stats, streamed.stopped);
    if report.complete {
        writer.commit()?;
    } else {
        writer.pause()?;
    }
    Ok(report)
}

fn control_resume(control: &Control<'_>) -> bool {
    control.resumes()
}
