//! A parameter sweep of your own model on threads, on the jobs of a job array, and on the
//! ranks of MPI: the forced, damped double-well Duffing oscillator
//!
//! ```text
//! q'' + δ q' − q + q³ = γ cos(ω t),   δ = 0.3, ω = 1.2,
//! ```
//!
//! over forcing amplitudes γ ∈ [0.2, 0.65] (period one, period doubling, chaos). Written as
//! y' = Ay + g(y) with the forcing's phase as two more variables (c, s) = (cos ωt, sin ωt),
//! which the linear part rotates exactly: y = (q, p, c, s), A = [[0, 1, 0, 0], [1, −δ, 0, 0],
//! [0, 0, 0, −ω], [0, 0, ω, 0]], g = (0, −q³ + γ c, 0, 0). Every member has the same A (γ is in
//! g), so the members share their φ-banks (`Ensemble::share_banks`). Each member keeps its
//! stroboscopic Poincaré section (the state once per forcing period, over the last
//! `SECTION` periods): its largest |q| and its final state. Members in the chaotic range
//! cannot be verified to the tolerance over many periods (the error of a chaotic orbit grows
//! exponentially): their rows say `unverified` and hold the best solution found.
//!
//! ```sh
//! cargo run --release --example forced_sweep -- sweep.csv                 # every core
//! cargo run --release --example forced_sweep -- --shard 2/4 part2.csv      # one job of four
//! cargo run --release --example forced_sweep -- merge sweep.csv part*.csv  # join the parts
//! cargo run --release --example forced_sweep -- --resume sweep.csv         # after a kill
//! # MPI: build with the feature, start with a launcher; rank 0 writes sweep.csv
//! cargo build --release --features mpi --example forced_sweep
//! mpirun -n 4 target/release/examples/forced_sweep sweep.csv
//! ```
//!
//! Options: `--members N` (default 400), `--periods P` (default 60).

use ecr::runtime::ensemble::{Cell, Column, Control, Ensemble, Table, merge_parts};
use ecr::runtime::nalgebra::DMatrix;
use ecr::runtime::operator::Dense;
use ecr::runtime::solve::{Options, Problem, Solution};
use ecr::runtime::system::Semilinear;
use std::path::PathBuf;

const DELTA: f64 = 0.3;
const OMEGA: f64 = 1.2;
const GAMMA: (f64, f64) = (0.2, 0.65);
/// Forcing periods of the section.
const SECTION: usize = 20;
const TOL: f64 = 1e-8;

/// What a run is asked to do.
#[derive(Debug, PartialEq)]
pub struct Args {
    members: usize,
    periods: usize,
    shard: Option<(usize, usize)>,
    resume: bool,
    out: PathBuf,
    merge: Vec<PathBuf>,
}

/// Parses `[--members N] [--periods P] [--shard K/N] [--resume] OUT` or `merge OUT PART...`.
pub fn parse(args: &[String]) -> Result<Args, String> {
    let mut a = Args {
        members: 400,
        periods: 60,
        shard: None,
        resume: false,
        out: PathBuf::new(),
        merge: Vec::new(),
    };
    let usage = "usage: forced_sweep [--members N] [--periods P] [--shard K/N] [--resume] OUT | \
                 forced_sweep merge OUT PART...";
    if args.first().map(String::as_str) == Some("merge") {
        let (out, parts) = args[1..].split_first().ok_or(usage)?;
        a.out = out.into();
        a.merge = parts.iter().map(PathBuf::from).collect();
        return if a.merge.is_empty() {
            Err(usage.into())
        } else {
            Ok(a)
        };
    }
    let mut it = args.iter();
    let mut out = None;
    while let Some(arg) = it.next() {
        let mut number = |what: &str| -> Result<usize, String> {
            it.next()
                .and_then(|v| v.parse().ok())
                .filter(|&v: &usize| v >= 1)
                .ok_or(format!("{what} takes a whole number >= 1"))
        };
        match arg.as_str() {
            "--members" => a.members = number("--members")?,
            "--periods" => a.periods = number("--periods")?.max(SECTION),
            "--resume" => a.resume = true,
            "--shard" => {
                let kn = it.next().ok_or("--shard takes K/N")?;
                let (k, n) = kn.split_once('/').ok_or("--shard takes K/N")?;
                let (k, n): (usize, usize) = match (k.parse(), n.parse()) {
                    (Ok(k), Ok(n)) if 1 <= k && k <= n => (k, n),
                    _ => return Err(format!("--shard {kn}: K/N with 1 <= K <= N")),
                };
                a.shard = Some((k - 1, n));
            }
            _ if out.is_none() && !arg.starts_with("--") => out = Some(PathBuf::from(arg)),
            _ => return Err(usage.into()),
        }
    }
    a.out = out.ok_or(usage)?;
    Ok(a)
}

/// The forcing amplitude of member `i` of `n`.
pub fn gamma(i: usize, n: usize) -> f64 {
    if n == 1 {
        GAMMA.0
    } else {
        GAMMA.0 + (GAMMA.1 - GAMMA.0) * (i as f64 / (n - 1) as f64)
    }
}

/// Runs the sweep (or the merge) as `args` asks; the line to print.
pub fn run(args: &[String]) -> Result<String, Box<dyn std::error::Error>> {
    let a = parse(args)?;
    if !a.merge.is_empty() {
        let r = merge_parts(&a.merge, &a.out)?;
        return Ok(format!(
            "wrote {}: {} members from {} parts",
            a.out.display(),
            r.members,
            r.parts
        ));
    }
    let period = 2.0 * std::f64::consts::PI / OMEGA;
    let t_end = a.periods as f64 * period;
    // The stroboscopic section: once per period over the last SECTION periods.
    let section: Vec<f64> = (a.periods - SECTION + 1..=a.periods)
        .map(|k| k as f64 * period)
        .collect();
    #[rustfmt::skip]
    let matrix = DMatrix::from_row_slice(4, 4, &[
        0.0, 1.0, 0.0, 0.0,
        1.0, -DELTA, 0.0, 0.0,
        0.0, 0.0, 0.0, -OMEGA,
        0.0, 0.0, OMEGA, 0.0,
    ]);
    let members = a.members;
    let ensemble = Ensemble::new(matrix, members, |matrix: &DMatrix<f64>, i| {
        let g = gamma(i, members);
        let system = Semilinear::new(
            Dense::new(matrix.clone())?,
            move |y: &[f64], out: &mut [f64]| {
                out[0] = 0.0;
                out[1] = -y[0].powi(3) + g * y[2];
                out[2] = 0.0;
                out[3] = 0.0;
            },
        );
        Problem::new(system, [1.0, 0.0, 1.0, 0.0], (0.0, t_end))
    })
    .share_banks(); // γ is in g: every member has the same A
    let options = Options::tolerance(TOL).t_eval(section.iter().copied());
    let table = Table::new(
        format!(
            "forced_sweep: q'' + {DELTA} q' - q + q^3 = gamma cos({OMEGA} t), gamma in \
             [{}, {}] over {members} members, {} periods, section of {SECTION}, tol {TOL:e}",
            GAMMA.0, GAMMA.1, a.periods
        ),
        vec![
            Column::f64("amplitude"),
            Column::f64("q_end"),
            Column::f64("p_end"),
        ],
    )
    .inputs(vec![Column::f64("gamma")], move |i, cells| {
        cells.push(Cell::F64(gamma(i, members)));
    });
    let output = |_: usize, s: &Solution| {
        let amplitude = s.y.iter().map(|y| y[0].abs()).fold(0.0, f64::max);
        let last = s.last().map_or([f64::NAN; 2], |y| [y[0], y[1]]);
        vec![Cell::F64(amplitude), Cell::F64(last[0]), Cell::F64(last[1])]
    };
    let mut control = Control::new();
    if a.resume {
        control = control.resume();
    }
    #[cfg(feature = "mpi")]
    if let Some(world) = ecr::mpi::World::from_launcher()? {
        let r = ecr::mpi::write_table(
            &world, &ensemble, &options, &control, &table, output, &a.out,
        )?;
        return Ok(if world.rank() == 0 {
            format!(
                "wrote {}: {} members on {} MPI ranks, {} verified ({} kept)",
                a.out.display(),
                r.members,
                world.size(),
                r.verified,
                r.kept
            )
        } else {
            String::new()
        });
    }
    let (table, what) = match a.shard {
        Some((k, n)) => {
            control = control.part(k, n);
            (table.as_part(), format!("part {}/{n}", k + 1))
        }
        None => (table, "table".to_string()),
    };
    let r = ensemble.write_table(&options, &control, &table, output, &a.out)?;
    Ok(format!(
        "wrote {}: {what} of {} members, {} verified ({} kept)",
        a.out.display(),
        r.members,
        r.verified,
        r.kept
    ))
}

#[allow(dead_code)] // a module of the tests, which call `run`
fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match run(&args) {
        Ok(line) if line.is_empty() => {}
        Ok(line) => println!("{line}"),
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(2);
        }
    }
}
