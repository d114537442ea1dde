//! The memory a command may use, checked before it allocates: a run whose estimate exceeds it
//! is refused with one line (exit status 2) instead of aborting when an allocation fails.
//!
//! The budget is [`FRACTION`] of the smaller of the memory available (`MemAvailable` in
//! `/proc/meminfo`) and the address space left under `ulimit -v` (`Max address space` in
//! `/proc/self/limits` less the current `VmSize`); where neither can be read (not Linux),
//! [`FALLBACK_BYTES`].

use super::UsageError;
use std::fs;

/// Under an address-space limit (`ulimit -v`), keeps glibc's malloc to its main arena.
///
/// glibc gives each thread that allocates its own arena, and reserves 64 MiB of address space
/// for each (128 MiB while it aligns one): the two threads of rayon's pool and the signal
/// thread reserved 192 MiB that no estimate of the memory a run uses counts, and under
/// `ulimit -v 200000` an NLS run with N = 65536 aborted when a worker's arena won the race for
/// the address space its own buffers needed. Reservations cost nothing where the address space
/// is not limited, so this changes nothing there; with one arena the threads share the main
/// one (they allocate only while a stepper is set up). To be called before any thread starts.
pub fn limit_malloc_arenas() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        let mut limit = libc::rlimit {
            rlim_cur: 0,
            rlim_max: 0,
        };
        // SAFETY: getrlimit writes the struct it is given; mallopt takes plain integers and is
        // called before any other thread exists.
        unsafe {
            if libc::getrlimit(libc::RLIMIT_AS, &mut limit) == 0
                && limit.rlim_cur != libc::RLIM_INFINITY
            {
                libc::mallopt(libc::M_ARENA_MAX, 1);
            }
        }
    }
}

/// The share of the available memory a run may take: room for what the estimate leaves out
/// and for the rest of the system.
pub const FRACTION: f64 = 0.75;

/// The budget where `/proc` cannot be read: 4 GiB.
pub const FALLBACK_BYTES: f64 = 4.0 * GIB;

const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

/// How much memory a run may use, and why.
#[derive(Debug)]
pub struct Budget {
    /// Bytes.
    pub bytes: f64,
    /// Where the figure comes from, for the error message.
    pub source: String,
}

/// The `kB` figure of the line `key:` in a `/proc` status-like text, in bytes.
fn proc_kb(text: &str, key: &str) -> Option<f64> {
    let rest = text.lines().find_map(|l| l.strip_prefix(key))?;
    let kb: f64 = rest
        .trim_start_matches(':')
        .split_whitespace()
        .next()?
        .parse()
        .ok()?;
    Some(kb * 1024.0)
}

/// The soft address-space limit from `/proc/self/limits`: `None` if unlimited or unreadable.
fn address_space_limit(limits: &str) -> Option<f64> {
    let line = limits
        .lines()
        .find(|l| l.starts_with("Max address space"))?;
    line["Max address space".len()..]
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// The budget of this process now.
pub fn budget() -> Budget {
    let available = fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|t| proc_kb(&t, "MemAvailable"));
    let address_space = fs::read_to_string("/proc/self/limits")
        .ok()
        .and_then(|t| address_space_limit(&t))
        .map(|limit| {
            let used = fs::read_to_string("/proc/self/status")
                .ok()
                .and_then(|t| proc_kb(&t, "VmSize"))
                .unwrap_or(0.0);
            (limit - used).max(0.0)
        });
    let (bytes, source) = match (available, address_space) {
        (Some(m), Some(a)) if a < m => (a, format!("{} of address space left (ulimit -v)", gib(a))),
        (Some(m), _) => (m, format!("{} available (MemAvailable)", gib(m))),
        (None, Some(a)) => (a, format!("{} of address space left (ulimit -v)", gib(a))),
        (None, None) => (FALLBACK_BYTES / FRACTION, "no /proc/meminfo".to_string()),
    };
    Budget {
        bytes: FRACTION * bytes,
        source,
    }
}

/// `bytes` in GiB, three significant digits at most.
pub fn gib(bytes: f64) -> String {
    let g = bytes / GIB;
    if g >= 100.0 {
        format!("{g:.0} GiB")
    } else if g >= 0.1 {
        format!("{g:.2} GiB")
    } else {
        format!("{:.1} MiB", bytes / (1024.0 * 1024.0))
    }
}

/// `Err` with one line naming `what` if `need` bytes exceed [`budget`], or if they cannot be
/// reserved at once: the rule of the library's `ensure_allocatable` (`try_reserve_exact` of the
/// whole need, freed at once), which under `ulimit -v` proves the address space is there.
pub fn check(what: &str, need: f64) -> Result<(), UsageError> {
    let budget = budget();
    if need > budget.bytes || !need.is_finite() {
        return Err(UsageError(format!(
            "{what} needs about {} of memory (estimate), more than the {} a run may use \
             ({:.0}% of {})",
            gib(need),
            gib(budget.bytes),
            FRACTION * 100.0,
            budget.source
        )));
    }
    if ecr_runtime::storage::ensure_bytes_allocatable(what, Some(need as usize)).is_err() {
        return Err(UsageError(format!(
            "{what} needs about {} of memory (estimate), which the system does not grant at \
             once (address space or overcommit limit)",
            gib(need)
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_proc_files() {
        let meminfo = "MemTotal:       24000000 kB\nMemAvailable:   16000000 kB\n";
        assert_eq!(
            proc_kb(meminfo, "MemAvailable"),
            Some(16_000_000.0 * 1024.0)
        );
        assert_eq!(proc_kb(meminfo, "VmSize"), None);
        let limits = "Limit                     Soft Limit           Hard Limit           Units\n\
                      Max address space         8589934592           unlimited            bytes\n";
        assert_eq!(address_space_limit(limits), Some(8589934592.0));
        let unlimited =
            "Max address space         unlimited            unlimited            bytes\n";
        assert_eq!(address_space_limit(unlimited), None);
        assert_eq!(gib(16.0 * GIB), "16.00 GiB");
        assert_eq!(gib(550.0 * GIB), "550 GiB");
        assert_eq!(gib(3.0 * 1024.0 * 1024.0), "3.0 MiB");
    }

    #[test]
    fn absurd_needs_are_refused_in_one_line() {
        let msg = check("--n 2147483648", 1e15).unwrap_err().0;
        assert!(msg.starts_with("--n 2147483648 needs about"), "{msg}");
        assert!(!msg.contains('\n'));
        assert!(check("a small run", 1e6).is_ok());
    }
}
