//! Command-line interface.

mod bench;
mod ensemble;
mod interrupt;
mod memory;
mod numbers;
mod output;
mod progress;
mod provenance;
mod reproduce;
mod run;
mod tables;

use clap::{Parser, Subcommand};
use std::io::Write;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

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
    /// Integrate a test problem (duffing, wind, wind-dissipative, nls, fpu, henon-heiles) and
    /// print a JSON report.
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
    /// Many trajectories: a test problem (duffing, henon-heiles) over a grid of parameters and
    /// initial values, every member solved on every core; one CSV row per member.
    ///
    /// Bad input prints one line starting with 'error: ' on stderr and exits with status 2; a
    /// member that fails is a row of the table with its status and message.
    Ensemble(ensemble::EnsembleArgs),
}

/// A failure the user can fix: printed as one line, exit status 2.
#[derive(Debug)]
pub struct UsageError(pub String);

/// The exit status of a command that succeeded but has something to tell a script (`ecr
/// ensemble`: 3 when some members are not verified); 0 otherwise.
static EXIT_STATUS: std::sync::atomic::AtomicU8 = std::sync::atomic::AtomicU8::new(0);

/// Sets the exit status of a command that completes (see [`EXIT_STATUS`]).
fn set_exit_status(status: u8) {
    EXIT_STATUS.store(status, Ordering::Relaxed);
}

/// Collapses clap's multi-line report into one line, without its tips (clap's guesses at
/// what was meant, such as passing an unknown option as a value) and usage.
fn one_line(e: &clap::Error) -> String {
    e.render()
        .to_string()
        .lines()
        .map(str::trim)
        .filter(|l| {
            !l.is_empty()
                && !l.starts_with("For more information")
                && !l.starts_with("Usage:")
                && !l.starts_with("tip:")
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
        Command::Ensemble(args) => ensemble::run(&args, out),
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

/// Whether file descriptor 1 was closed when the process started: the standard library then
/// opens /dev/null on it (before `main`), and whatever the command prints is lost. Recorded by
/// [`CHECK_STDOUT`], which runs before the standard library's start-up.
static STDOUT_CLOSED: AtomicBool = AtomicBool::new(false);

/// Records in [`STDOUT_CLOSED`] whether descriptor 1 is open, from the program's constructors
/// (`.init_array`, run by the C runtime before Rust's start-up code reopens closed standard
/// descriptors on /dev/null). Linux only: elsewhere a closed stdout goes undetected.
#[cfg(target_os = "linux")]
#[used]
#[unsafe(link_section = ".init_array")]
static CHECK_STDOUT: extern "C" fn() = {
    extern "C" fn check() {
        // SAFETY: F_GETFD only reads the descriptor's flags.
        if unsafe { libc::fcntl(1, libc::F_GETFD) } == -1 {
            STDOUT_CLOSED.store(true, Ordering::Relaxed);
        }
    }
    check
};

/// Writes `error: <msg>` on stderr, ignoring a failure (a full or broken stderr): the exit
/// status still tells.
fn report(msg: &str) {
    let msg = msg.strip_prefix("error: ").unwrap_or(msg);
    let _ = writeln!(std::io::stderr(), "error: {msg}");
}

/// The exit status after standard output failed with EPIPE (the reader went away): what a
/// shell reports for a command killed by SIGPIPE (128 + 13), which is what a C program would
/// have been.
const BROKEN_PIPE_STATUS: u8 = 141;

/// Entry point of the binary.
///
/// Exit status: 0 on success (`ecr ensemble`: 3 when some members are not verified); 2 with
/// one line on stderr for bad input or a failed command;
/// 1 with one line on stderr if standard output cannot be written (e.g. `> /dev/full`; the
/// command's files, if it writes any, are complete, and the line says so) or was closed when
/// the command started (`>&-`; then before any work); 141, silently, if the reader of a pipe
/// went away (`ecr tables … | head`): the output is cut short, as for a program killed by
/// SIGPIPE. A message that cannot be written to stderr is dropped; the status is the same.
pub fn main() -> ExitCode {
    memory::limit_malloc_arenas();
    if STDOUT_CLOSED.load(Ordering::Relaxed) {
        report(
            "standard output is closed: the command's output would be lost (redirect it to \
             /dev/null to discard it)",
        );
        return ExitCode::from(1);
    }
    let stdout = std::io::stdout();
    let mut out = Stdout {
        inner: stdout.lock(),
        error: None,
    };
    let result = run(std::env::args_os(), &mut out);
    let flushed = std::io::Write::flush(&mut out);
    match (out.error, result) {
        (Some(std::io::ErrorKind::BrokenPipe), _) => ExitCode::from(BROKEN_PIPE_STATUS),
        (Some(_), Err(UsageError(msg))) => {
            report(&msg);
            ExitCode::from(1)
        }
        (Some(_), Ok(())) => {
            let e = flushed.err().map_or_else(String::new, |e| e.to_string());
            report(&format!("cannot write output: {e}"));
            ExitCode::from(1)
        }
        (None, Ok(())) => ExitCode::from(EXIT_STATUS.load(Ordering::Relaxed)),
        (None, Err(UsageError(msg))) => {
            report(&msg);
            ExitCode::from(2)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Cli;
    use clap::CommandFactory;
    use std::collections::BTreeSet;

    /// The subcommands as `ecr` names them, with their clap definitions (nested ones such as
    /// `ensemble merge` included).
    fn commands() -> Vec<(String, clap::Command)> {
        fn walk(prefix: &str, cmd: &clap::Command, out: &mut Vec<(String, clap::Command)>) {
            for sub in cmd.get_subcommands().filter(|s| s.get_name() != "help") {
                let name = format!("{prefix}{}", sub.get_name()).trim().to_string();
                out.push((name.clone(), sub.clone()));
                walk(&format!("{name} "), sub, out);
            }
        }
        let mut out = Vec::new();
        walk("", &Cli::command(), &mut out);
        out
    }

    /// The long options of a command (not --help): those `--help` lists, or with `hidden`
    /// also the hidden ones (a former name that is refused with a line saying what to use).
    fn options(cmd: &clap::Command, hidden: bool) -> BTreeSet<String> {
        cmd.get_arguments()
            .filter(|a| hidden || !a.is_hide_set())
            .filter_map(|a| a.get_long())
            .filter(|l| *l != "help" && *l != "version")
            .map(|l| format!("--{l}"))
            .collect()
    }

    /// The `--option` tokens of a text, without those of cargo commands (up to the end of their
    /// code span or line; of `cargo run … -- ARGS` only ARGS count: `cargo run --release --
    /// run --tol 1e-8` gives `--tol`).
    fn tokens(text: &str) -> BTreeSet<String> {
        let mut kept = String::new();
        let mut rest = text;
        while let Some(at) = rest.find("cargo ") {
            kept.push_str(&rest[..at]);
            let tail = &rest[at..];
            let end = tail.find(['`', '\n']).unwrap_or(tail.len());
            let command = &tail[..end];
            if command.starts_with("cargo run") {
                if let Some((_, args)) = command.split_once(" -- ") {
                    kept.push(' ');
                    kept.push_str(args);
                }
            }
            rest = &tail[end..];
        }
        kept.push_str(rest);
        let mut found = BTreeSet::new();
        let bytes = kept.as_bytes();
        for (at, _) in kept.match_indices("--") {
            let before = at.checked_sub(1).map(|b| bytes[b]);
            if before.is_some_and(|b| b.is_ascii_alphanumeric() || b == b'-') {
                continue;
            }
            let name: String = kept[at + 2..]
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '-')
                .collect();
            if name.starts_with(|c: char| c.is_ascii_lowercase()) && name != "help" {
                found.insert(format!("--{}", name.trim_end_matches('-')));
            }
        }
        found
    }

    /// The sections of docs/cli.md headed by `` `ecr NAME` ``: (NAME, text up to the next
    /// heading of the same or a higher level).
    fn sections(doc: &str) -> Vec<(String, String)> {
        let mut out: Vec<(String, usize, String)> = Vec::new();
        let mut current: Option<usize> = None;
        for line in doc.lines() {
            let level = line.chars().take_while(|&c| c == '#').count();
            if level > 0 && line[level..].starts_with(' ') {
                if current.is_some_and(|k| level <= out[k].1) {
                    current = None;
                }
                let title = line[level..].trim();
                if let Some(name) = title
                    .strip_prefix("`ecr ")
                    .and_then(|t| t.split_once('`'))
                    .map(|(name, _)| name.to_string())
                {
                    out.push((name, level, String::new()));
                    current = Some(out.len() - 1);
                    continue;
                }
            }
            if let Some(k) = current {
                out[k].2.push_str(line);
                out[k].2.push('\n');
            }
        }
        out.into_iter().map(|(n, _, t)| (n, t)).collect()
    }

    /// docs/cli.md has a section for every command and names there every option the command's
    /// `--help` lists; every option the document names anywhere is one that `ecr` has (a hidden
    /// former name included: the docs say it is refused).
    #[test]
    fn docs_cli_md_and_help_name_the_same_options() {
        let doc = include_str!("../../docs/cli.md");
        let sections = sections(doc);
        let mut known = BTreeSet::new();
        for (name, cmd) in commands() {
            let Some((_, text)) = sections.iter().find(|(n, _)| *n == name) else {
                panic!("docs/cli.md has no section `ecr {name}`");
            };
            let documented = tokens(text);
            let listed = options(&cmd, false);
            let missing: Vec<_> = listed.difference(&documented).collect();
            assert!(
                missing.is_empty(),
                "`ecr {name}`: its section of docs/cli.md does not name {missing:?}"
            );
            known.extend(options(&cmd, true));
        }
        let unknown: Vec<_> = tokens(doc)
            .into_iter()
            .filter(|t| !known.contains(t))
            .collect();
        assert!(
            unknown.is_empty(),
            "docs/cli.md names {unknown:?}, which no `ecr` command has"
        );
    }

    /// Where a command's description lists the problems in parentheses, the list is the set of
    /// values its `--problem` accepts, in the same order.
    #[test]
    fn problem_lists_agree_with_the_values_accepted() {
        for (name, cmd) in commands() {
            let Some(arg) = cmd
                .get_arguments()
                .find(|a| a.get_long() == Some("problem"))
            else {
                continue;
            };
            let values: Vec<String> = arg
                .get_possible_values()
                .iter()
                .map(|v| v.get_name().to_string())
                .collect();
            let about = cmd.get_about().map(|a| a.to_string()).unwrap_or_default();
            let listed = about
                .split_once('(')
                .and_then(|(_, rest)| rest.split_once(')'))
                .map(|(list, _)| list.split(", ").map(str::to_string).collect::<Vec<_>>());
            if let Some(listed) = listed.filter(|l| l.iter().any(|p| values.contains(p))) {
                assert_eq!(
                    listed, values,
                    "`ecr {name}`: its description lists other problems than --problem takes"
                );
            }
        }
    }
}
