//! Refusing storage that cannot exist: an `Err` naming the size instead of an abort.

use crate::error::{Error, Result};

/// `Ok` if `entries` numbers (`f64`) can be allocated: their byte count fits in `isize` and
/// the allocator grants it once (`try_reserve_exact`, freed at once: on an overcommitting
/// system this reserves address space only). Otherwise [`Error::InvalidInput`] naming `what`
/// and the size. `None` stands for a count that overflowed `usize`.
///
/// For the `O(d²)` and larger storage that constructors would otherwise allocate with
/// `vec!`/`DMatrix::zeros`, which abort the process when the allocation fails.
pub fn ensure_allocatable(what: &str, entries: Option<usize>) -> Result<()> {
    ensure_allocatable_for(|| what.to_string(), entries)
}

/// Storage this small (bytes) is granted without asking the allocator: if it fails, so would
/// everything after it. The banks of partial steps (a value between grid points) ask for
/// a few hundred bytes each, thousands of times.
const SMALL: usize = 1 << 20;

/// [`ensure_allocatable`] with the description made only for an error.
pub(crate) fn ensure_allocatable_for(
    what: impl FnOnce() -> String,
    entries: Option<usize>,
) -> Result<()> {
    if entries.is_some_and(|e| e <= SMALL / size_of::<f64>()) {
        return Ok(());
    }
    let bytes = entries.and_then(|e| e.checked_mul(size_of::<f64>()));
    let granted = bytes.is_some_and(|b| {
        isize::try_from(b).is_ok() && Vec::<u8>::new().try_reserve_exact(b).is_ok()
    });
    if granted {
        return Ok(());
    }
    let what = what();
    let size = match entries {
        Some(e) => format!("{e} numbers, {}", format_bytes(e as f64 * 8.0)),
        None => "more numbers than a usize counts".to_string(),
    };
    Err(Error::InvalidInput(format!(
        "{what} would need {size}: more than can be allocated"
    )))
}

/// As [`ensure_allocatable`] for a count of bytes: `Ok` if `bytes` can be allocated at once
/// (`try_reserve_exact`, freed at once). For the total of several allocations a run makes (for
/// example [`ec_stepper_bytes`](crate::stepper::ec_stepper_bytes) of each stepper a solve
/// holds), so that a run that cannot get them is refused before it starts. `None` stands for a
/// count that overflowed `usize`.
///
/// # Errors
/// [`Error::InvalidInput`] naming `what` and the size.
pub fn ensure_bytes_allocatable(what: &str, bytes: Option<usize>) -> Result<()> {
    let granted = bytes.is_some_and(|b| {
        isize::try_from(b).is_ok() && Vec::<u8>::new().try_reserve_exact(b).is_ok()
    });
    if granted {
        return Ok(());
    }
    let size = match bytes {
        Some(b) => format_bytes(b as f64),
        None => "more bytes than a usize counts".to_string(),
    };
    Err(Error::InvalidInput(format!(
        "{what} would need {size}: more than can be allocated"
    )))
}

/// `bytes` with a binary-prefixed unit and three decimals: "1.500 GiB".
pub(crate) fn format_bytes(bytes: f64) -> String {
    const UNITS: [&str; 7] = ["B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    let mut value = bytes;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{value:.0} B")
    } else {
        format!("{value:.3} {}", UNITS[unit])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_storage_is_granted_absurd_storage_is_named() {
        assert!(ensure_allocatable("x", Some(1000)).is_ok());
        let msg = ensure_allocatable("the Jacobian", Some(1 << 60))
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("the Jacobian") && msg.contains("8.000 EiB"),
            "{msg}"
        );
        let msg = ensure_allocatable("the Jacobian", None)
            .unwrap_err()
            .to_string();
        assert!(msg.contains("more numbers than a usize counts"), "{msg}");
        assert_eq!(format_bytes(512.0), "512 B");
        assert_eq!(format_bytes(1.5 * 1024.0 * 1024.0 * 1024.0), "1.500 GiB");
    }
}
