//! `ecr reproduce`: the numerical experiments of the paper's §9 — global errors, energy
//! (Hamiltonian) errors and the Lyapunov function of Problems 1–3 for every registered method —
//! written as PNG and SVG figures, CSV data and a Markdown report.
//!
//! Methods are registered in [`methods::methods`].

mod experiments;
pub(crate) mod methods;
pub(crate) mod plots;
mod report;

use super::UsageError;
use super::output::OutputDir;
use clap::Args;
use experiments::{Config, Results};
use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `ecr reproduce`.
#[derive(Args, Debug)]
#[command(
    after_help = "Writes p1-1, p1-2, p2-1, p2-2, p3 (.png and .svg), one CSV per sub-panel, \
                  summary.csv and report.md into --out, replacing it whole once every file \
                  is written (staged beside it). A symlink --out stays a symlink (the files go \
                  where it points). An unusable --out (a file, a mount point, a directory \
                  that cannot be renamed, or one that holds files ecr did not write, without \
                  --force) prints one line starting with 'error: ' on stderr and exits with \
                  status 2 before any work."
)]
pub struct ReproduceArgs {
    /// Shrink the intervals (about T/100) so that everything runs in seconds; the output goes
    /// to out/reproduce-quick unless --out says otherwise.
    #[arg(long)]
    quick: bool,
    /// Output directory (created if missing, replaced whole by a complete run) [default:
    /// out/reproduce, with --quick out/reproduce-quick].
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Replace --out even if it holds files that ecr did not write (a non-empty directory
    /// without the .ecr-output file that ecr puts into its output directories).
    #[arg(long)]
    force: bool,
}

/// A CSV table: header and rows of cells.
pub struct Csv {
    pub header: Vec<&'static str>,
    pub rows: Vec<Vec<String>>,
}

impl Csv {
    pub(crate) fn render(&self) -> String {
        let mut s = self.header.join(",");
        s.push('\n');
        for row in &self.rows {
            s.push_str(&row.join(","));
            s.push('\n');
        }
        s
    }
}

/// Formats a number for CSV: shortest round-trip representation.
pub fn num(x: f64) -> String {
    format!("{x:e}")
}

pub(crate) fn write_file(dir: &Path, name: &str, bytes: &[u8]) -> Result<(), UsageError> {
    let path = dir.join(name);
    fs::write(&path, bytes)
        .map_err(|e| UsageError(format!("cannot write '{}': {e}", path.display())))
}

/// Writes every output file; returns their names.
fn write_outputs(
    dir: &Path,
    config: &Config,
    results: &Results,
    methods: &[methods::Method],
    seconds: f64,
) -> Result<Vec<String>, UsageError> {
    let mut names = Vec::new();
    for (name, csv) in report::csv_tables(results) {
        write_file(dir, &name, csv.render().as_bytes())?;
        names.push(name);
    }
    let method_names: Vec<&str> = methods.iter().map(|m| m.name).collect();
    for figure in plots::figures(results, &method_names) {
        let drawn =
            |ext: &str, e: String| UsageError(format!("cannot draw {}.{ext}: {e}", figure.id));
        let png = plots::png(&figure).map_err(|e| drawn("png", e))?;
        let svg = plots::svg(&figure).map_err(|e| drawn("svg", e))?;
        for (ext, bytes) in [("png", png.as_slice()), ("svg", svg.as_bytes())] {
            let name = format!("{}.{ext}", figure.id);
            write_file(dir, &name, bytes)?;
            names.push(name);
        }
    }
    let text = report::markdown(config, results, methods, seconds);
    write_file(dir, "report.md", text.as_bytes())?;
    names.push("report.md".to_string());
    Ok(names)
}

/// The default output directories: a quick run never replaces a full run's files.
const DEFAULT_OUT: &str = "out/reproduce";
const DEFAULT_QUICK_OUT: &str = "out/reproduce-quick";

impl ReproduceArgs {
    /// `--out`, or the default of a full or a quick run.
    fn out_dir(&self) -> PathBuf {
        self.out.clone().unwrap_or_else(|| {
            PathBuf::from(if self.quick {
                DEFAULT_QUICK_OUT
            } else {
                DEFAULT_OUT
            })
        })
    }
}

/// Runs `ecr reproduce`.
pub fn run(args: &ReproduceArgs, out: &mut dyn Write) -> Result<(), UsageError> {
    let out_dir = args.out_dir();
    let staged = OutputDir::stage(&out_dir, args.force, "reproduce")?;
    let config = Config::new(args.quick);
    let methods = methods::methods();
    let start = Instant::now();
    let results = experiments::run_all(&config, &methods).map_err(UsageError)?;
    let seconds = start.elapsed().as_secs_f64();
    let names = write_outputs(staged.path(), &config, &results, &methods, seconds)?;
    let replaced = staged.commit()?;
    writeln!(
        out,
        "ecr reproduce{}: {} methods, computed in {seconds:.1} s; wrote {} files to {}{}:\n  {}",
        if args.quick { " --quick" } else { "" },
        methods.len(),
        names.len(),
        out_dir.display(),
        replaced.describe(),
        names.join(" ")
    )
    .map_err(|e| {
        UsageError(format!(
            "wrote {} files to {}, but cannot write this summary to standard output: {e}",
            names.len(),
            out_dir.display()
        ))
    })
}
