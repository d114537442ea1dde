//! Command-line interface.

mod bench;
#[cfg(test)]
mod fuzz;
mod memory;
mod output;
mod progress;
mod provenance;
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

/// Standard output that remembers its first write error, so that [`main`] can tell a reader
/// that went away from a failed command.
struct Stdout<W> {
    inner: W,
    error: Option<std::io::ErrorKind>,
}

impl<W: std::io::Write> std::io::Write for Stdout<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let result = self.inner.write(buf);
        if let Err(e) = &result {
            self.error.get_or_insert(e.kind());
        }
        result
    }

    fn flush(&mut self) -> std::io::Result<()> {
        let result = self.inner.flush();
        if let Err(e) = &result {
            self.error.get_or_insert(e.kind());
        }
        result
    }
}

/// Entry point of the binary.
///
/// Exit status: 0 on success; 2 with one line on stderr for bad input or a failed command;
/// 1 with one line on stderr if standard output cannot be written (e.g. `> /dev/full`): the
/// command's files, if it writes any, are complete, and the line says so. A reader that
/// closes the pipe early (`ecr tables … | head`) is not an error: the output stops there,
/// silently, with status 0.
pub fn main() -> ExitCode {
    let stdout = std::io::stdout();
    let mut out = Stdout {
        inner: stdout.lock(),
        error: None,
    };
    let result = run(std::env::args_os(), &mut out);
    let flushed = std::io::Write::flush(&mut out);
    match (out.error, result) {
        (Some(std::io::ErrorKind::BrokenPipe), _) => ExitCode::SUCCESS,
        (Some(_), Err(UsageError(msg))) => {
            let msg = msg.strip_prefix("error: ").unwrap_or(&msg);
            eprintln!("error: {msg}");
            ExitCode::from(1)
        }
        (Some(_), Ok(())) => {
            let e = flushed.err().map_or_else(String::new, |e| e.to_string());
            eprintln!("error: cannot write output: {e}");
            ExitCode::from(1)
        }
        (None, Ok(())) => ExitCode::SUCCESS,
        (None, Err(UsageError(msg))) => {
            let msg = msg.strip_prefix("error: ").unwrap_or(&msg);
            eprintln!("error: {msg}");
            ExitCode::from(2)
        }
    }
}
