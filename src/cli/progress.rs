//! Progress of long work, shown on a terminal only (stderr); hidden in pipes and CI logs.

use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::time::Duration;

/// A bar of `len` steps labelled `what`, drawn on stderr if stderr is a terminal.
///
/// Updated once every [`StepBar::EVERY`] steps, and not at all where it is not drawn:
/// indicatif reads the clock on every update, hidden bar or not, and once per step that was
/// 5–6 % of a short-step run (`ecr run --problem duffing --r 5 --h 0.09`, `perf record`).
pub struct StepBar(Option<ProgressBar>);

impl StepBar {
    /// Steps between two updates of a drawn bar.
    pub const EVERY: u64 = 64;

    /// The bar of `len` steps, labelled `what`.
    pub fn new(len: u64, what: &str) -> Self {
        if !std::io::stderr().is_terminal() {
            return StepBar(None);
        }
        let bar = ProgressBar::new(len);
        if let Ok(style) = ProgressStyle::with_template(
            "{msg} [{wide_bar}] {human_pos}/{human_len} steps, {eta} left",
        ) {
            bar.set_style(style);
        }
        bar.set_message(what.to_string());
        StepBar(Some(bar))
    }

    /// Records that `steps` steps are done.
    #[inline]
    pub fn set(&self, steps: u64) {
        if let Some(bar) = &self.0 {
            if steps % Self::EVERY == 0 {
                bar.set_position(steps);
            }
        }
    }

    /// Removes the bar from the terminal.
    pub fn finish_and_clear(&self) {
        if let Some(bar) = &self.0 {
            bar.finish_and_clear();
        }
    }
}

/// A spinner saying `what` while a phase of unknown length runs, if stderr is a terminal.
pub fn spinner(what: &str) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let spinner = ProgressBar::new_spinner();
    spinner.set_message(what.to_string());
    spinner.enable_steady_tick(Duration::from_millis(120));
    spinner
}

/// A bar of `len` items called `unit` (drawn on stderr if stderr is a terminal, else hidden),
/// for work whose items take long enough to update it after each one.
pub fn count_bar(len: u64, unit: &str) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len);
    if let Ok(style) = ProgressStyle::with_template(&format!(
        "[{{wide_bar}}] {{human_pos}}/{{human_len}} {unit}, {{eta}} left"
    )) {
        bar.set_style(style);
    }
    bar
}
