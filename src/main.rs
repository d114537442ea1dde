//! The `ecr` command: regenerate coefficient tables (and, as the project grows, run the
//! paper's experiments and benchmarks).
//!
//! Bad input prints one line on stderr and exits with status 2; nothing panics. Standard
//! output that cannot be written or is closed is one line and status 1; a reader that closes
//! the pipe early (`| head`) ends the output silently with status 141 (as SIGPIPE would). A
//! full or closed stderr loses the message, not the status.

mod cli;

use std::process::ExitCode;

fn main() -> ExitCode {
    cli::main()
}
