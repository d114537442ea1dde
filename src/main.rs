//! The `ecr` command: regenerate coefficient tables (and, as the project grows, run the
//! paper's experiments and benchmarks).
//!
//! Bad input prints one line on stderr and exits with status 2; nothing panics.

mod cli;

use std::process::ExitCode;

fn main() -> ExitCode {
    cli::main()
}
