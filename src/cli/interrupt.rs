//! SIGINT and SIGTERM for the commands that run long: one line on stderr, then the shell's
//! status 128 + the signal's number (130, 143).

use std::io::{IsTerminal, Write};
use std::sync::Once;

/// Installs, once per process, a handler for SIGINT and SIGTERM that writes
/// `error: <describe(what)>` on stderr (`what`: "interrupted" or "terminated (SIGTERM)") and
/// exits with 130 or 143. The signals are received on a thread of their own (signal-hook's
/// iterator), where printing is safe; a full or closed stderr loses the line, not the status.
/// If the handlers cannot be installed, the signals keep their default behaviour.
pub(super) fn on_interrupt(describe: fn(&str) -> String) {
    use signal_hook::consts::{SIGINT, SIGTERM};
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM]) else {
            return;
        };
        let _ = std::thread::Builder::new()
            .name("ecr-signals".into())
            .spawn(move || {
                let Some(signal) = signals.forever().next() else {
                    return;
                };
                let (what, status) = if signal == SIGTERM {
                    ("terminated (SIGTERM)", 128 + SIGTERM)
                } else {
                    ("interrupted", 128 + SIGINT)
                };
                let newline = if std::io::stderr().is_terminal() {
                    "\n"
                } else {
                    ""
                };
                let _ = writeln!(std::io::stderr(), "{newline}error: {}", describe(what));
                std::process::exit(status);
            });
    });
}
