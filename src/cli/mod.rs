//! Command-line interface.

mod bench;
#[cfg(test)]
mod fuzz;
mod memory;
mod reproduce;
mod run;
mod tables;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Exponential collocation methods: coefficient tables, integration, the paper's experiments.
#[derive(Parser, Debug)]
#[command(name = "ecr", version, about)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Regenerate the exact coefficient tables of a method (nodes, weights, moment weights).
    Tables(tables::TablesArgs),
    /// Integrate a test problem (duffing, wind, wind-dissipative, nls) and print a JSON report.
    ///
    /// Bad input and runtime failures (such as stage equations that do not converge) print one
    /// line starting with 'error: ' on stderr and exit with status 2.
    Run(run::RunArgs),
    /// Reproduce the paper's numerical experiments (§9): figures (PNG, SVG), CSV data and
    /// report.md.
    ///
    /// An unusable --out directory prints one line starting with 'error: ' on stderr and exits
    /// with status 2.
    Reproduce(reproduce::ReproduceArgs),
    /// Work–precision benchmark: CPU time (wall clock, single thread) against global and
    /// energy error for ECrP, TCrP and the baselines; CSV, figures (PNG, SVG) and summary.md.
    ///
    /// An unusable --out directory prints one line starting with 'error: ' on stderr and exits
    /// with status 2.
    Bench(bench::BenchArgs),
}

/// A failure the user can fix: printed as one line, exit status 2.
#[derive(Debug)]
pub struct UsageError(pub String);

/// Collapses clap's multi-line report into one line.
fn one_line(e: &clap::Error) -> String {
    e.render()
        .to_string()
        .lines()
        .map(str::trim)
        .filter(|l| {
            !l.is_empty() && !l.starts_with("For more information") && !l.starts_with("Usage:")
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// Runs the command line in `args` (first element: program name), writing to `out`.
pub fn run<I, T>(args: I, out: &mut dyn std::io::Write) -> Result<(), UsageError>
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) => {
            use clap::error::ErrorKind;
            return match e.kind() {
                ErrorKind::DisplayHelp | ErrorKind::DisplayVersion => {
                    write!(out, "{}", e.render()).map_err(|io| UsageError(io.to_string()))
                }
                ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
                    Err(UsageError("missing command: try 'ecr --help'".to_string()))
                }
                _ => Err(UsageError(one_line(&e))),
            };
        }
    };
    match cli.command {
        Command::Tables(args) => tables::run(&args, out),
        Command::Run(args) => run::run(&args, out),
        Command::Reproduce(args) => reproduce::run(&args, out),
        Command::Bench(args) => bench::run(&args, out),
    }
}

/// Entry point of the binary.
pub fn main() -> ExitCode {
    let stdout = std::io::stdout();
    let mut lock = stdout.lock();
    match run(std::env::args_os(), &mut lock) {
        Ok(()) => ExitCode::SUCCESS,
        Err(UsageError(msg)) => {
            let msg = msg.strip_prefix("error: ").unwrap_or(&msg);
            eprintln!("error: {msg}");
            ExitCode::from(2)
        }
    }
}
