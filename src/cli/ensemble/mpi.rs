//! `mpirun -n N ecr ensemble …`: the members split over the ranks of MPI as the parts of
//! `--shard` split them (rank k solves the members k, k + N, …), the rows sent to rank 0, which
//! writes the table of the whole ensemble in member order: byte for byte the table of one
//! process (its CPU column aside).

use super::{Counts, OutputFile, Plan, SolveArgs, UsageError, part_len, solve_part, with_threads};
use mpi::Threading;
use mpi::environment::Universe;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::io::Write;
use std::path::Path;
use std::time::Instant;

/// The largest message sent at once (MPI counts in `int`).
const CHUNK: usize = 1 << 30;

/// This process's place among the ranks of an MPI launch of more than one process.
pub struct World {
    world: SimpleCommunicator,
    rank: usize,
    size: usize,
    /// Finalizes MPI when dropped.
    _universe: Universe,
}

impl World {
    /// Initializes MPI (only the main thread makes MPI calls; rayon's threads solve): `None`
    /// for a single process, which runs as without MPI.
    ///
    /// # Errors
    /// One line if MPI cannot be initialized.
    pub fn init() -> Result<Option<World>, UsageError> {
        let (universe, _) = mpi::initialize_with_threading(Threading::Funneled)
            .ok_or_else(|| UsageError("MPI could not be initialized".into()))?;
        let world = universe.world();
        let (rank, size) = (world.rank() as usize, world.size() as usize);
        if size < 2 {
            return Ok(None);
        }
        Ok(Some(World {
            world,
            rank,
            size,
            _universe: universe,
        }))
    }

    /// Sends `bytes` to rank 0 (its length first, then chunks of at most [`CHUNK`]).
    fn send(&self, bytes: &[u8]) {
        let root = self.world.process_at_rank(0);
        root.send(&(bytes.len() as u64));
        for chunk in bytes.chunks(CHUNK) {
            root.send(chunk);
        }
    }

    /// What rank `from` [`send`](Self::send)s.
    fn receive(&self, from: usize) -> Vec<u8> {
        let source = self.world.process_at_rank(from as i32);
        let (len, _) = source.receive::<u64>();
        let mut bytes = Vec::with_capacity(len as usize);
        while bytes.len() < len as usize {
            let (chunk, _) = source.receive_vec::<u8>();
            bytes.extend_from_slice(&chunk);
        }
        bytes
    }
}

/// `ecr ensemble` on the ranks of `world`.
pub fn solve(
    world: &World,
    plan: &Plan,
    args: &SolveArgs,
    path: &Path,
    out: &mut dyn Write,
) -> Result<(), UsageError> {
    if args.shard.is_some() {
        return Err(UsageError(
            "--shard splits the members over the jobs of a job array, the ranks of MPI split \
             them already: use one or the other"
                .into(),
        ));
    }
    // Rank 0 checks that it can write the table before anyone works, and says so.
    let root = world.world.process_at_rank(0);
    let staged = (world.rank == 0).then(|| OutputFile::stage(path));
    let mut go = u8::from(!matches!(staged, Some(Err(_))));
    root.broadcast_into(&mut go);
    let file = match staged {
        Some(staged) => Some(staged?),
        None if go == 0 => {
            return Err(UsageError(format!(
                "rank 0 cannot write '{}'",
                path.display()
            )));
        }
        None => None,
    };
    super::report_interrupts();
    let start = Instant::now();
    // The communicator stays on this thread: the threads get the rank and size alone.
    let (rank, size) = (world.rank, world.size);
    let (rows, counts) = with_threads(args.threads, || solve_part(plan, rank, size))??;
    let text = rows.concat();
    drop(rows);
    let Some(mut file) = file else {
        world.send(text.as_bytes());
        world.world.process_at_rank(0).send(
            &[
                counts.verified as u64,
                counts.unverified as u64,
                counts.failed as u64,
            ][..],
        );
        return Ok(());
    };
    let mut texts = vec![text.into_bytes()];
    let mut total = counts;
    for from in 1..world.size {
        texts.push(world.receive(from));
        let (c, _) = world
            .world
            .process_at_rank(from as i32)
            .receive_vec::<u64>();
        let [verified, unverified, failed] = c[..] else {
            return Err(UsageError(format!("rank {from} sent no counts")));
        };
        total = Counts {
            verified: total.verified + verified as usize,
            unverified: total.unverified + unverified as usize,
            failed: total.failed + failed as usize,
        };
    }
    let mut per_rank = Vec::with_capacity(world.size);
    for (k, t) in texts.iter().enumerate() {
        let rows: Vec<&[u8]> = t.split_inclusive(|&b| b == b'\n').collect();
        if rows.len() != part_len(plan.members, k, world.size) {
            return Err(UsageError(format!(
                "rank {k} sent {} rows instead of {}",
                rows.len(),
                part_len(plan.members, k, world.size)
            )));
        }
        per_rank.push(rows);
    }
    let io = |e: std::io::Error| UsageError(format!("cannot write '{}': {e}", path.display()));
    file.write_all(plan.header().as_bytes()).map_err(io)?;
    for i in 0..plan.members {
        file.write_all(per_rank[i % world.size][i / world.size])
            .map_err(io)?;
    }
    file.commit()?;
    writeln!(
        out,
        "wrote {}: {} members on {} MPI ranks: {}; {:.2} s",
        path.display(),
        plan.members,
        world.size,
        total.describe(plan.fixed()),
        start.elapsed().as_secs_f64()
    )
    .map_err(|e| UsageError(format!("cannot write output: {e}")))
}
