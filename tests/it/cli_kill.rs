//! `ecr reproduce` and `ecr bench` killed at random moments (SIGKILL, SIGINT, SIGTERM; a third
//! of the moments in the last fifth of the run, a third while its last files are written and
//! put in place) always leave `--out` holding exactly the previous run's files or the complete
//! new ones, and a complete run afterwards leaves nothing beside it.
//!
//! The test run by CI kills 10 times (about 15 s). The long variant kills 39 times, three
//! times the full `bench --quick` (about 10 minutes on 2 cores):
//! `cargo test -p ecr --test it cli_kill:: -- --ignored --nocapture`; set `ECR_KILL_SEED` to draw
//! other moments.

use crate::common;

use common::{Tally, kill_at_random_moments};

fn seed(default: u64) -> u64 {
    std::env::var("ECR_KILL_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

fn campaign(runs: &[(&[&str], usize)], seed: u64) {
    let mut total = Tally::default();
    for (k, &(args, kills)) in runs.iter().enumerate() {
        let t = kill_at_random_moments(args, kills, seed.wrapping_add(k as u64));
        println!(
            "{args:?}: {} kills (first run {:.2} s): {} old, {} new; {} more runs finished \
             before their signal",
            t.kills, t.run_seconds, t.old, t.new, t.finished
        );
        total.kills += t.kills;
        total.old += t.old;
        total.new += t.new;
        total.finished += t.finished;
    }
    println!(
        "seed {seed}: {} kills: {} old, {} new, none mixed or missing; {} runs finished \
         before their signal",
        total.kills, total.old, total.new, total.finished
    );
}

#[test]
fn killed_runs_leave_the_old_or_the_new_output() {
    campaign(
        &[
            (&["reproduce", "--quick"], 4),
            (&["bench", "--quick", "--only", "scaling"], 6),
        ],
        seed(0x0EC8_0028),
    );
}

#[test]
#[ignore = "about 10 minutes: cargo test -p ecr --test it cli_kill:: -- --ignored --nocapture"]
fn killed_runs_leave_the_old_or_the_new_output_long() {
    campaign(
        &[
            (&["reproduce", "--quick"], 24),
            (&["bench", "--quick", "--only", "scaling"], 12),
            (&["bench", "--quick"], 3),
        ],
        seed(0x0EC8_1028),
    );
}
