//! The numeric options of the commands, read by clap with their rule: a value that breaks it
//! (negative, zero where it must be positive, NaN, infinite, not a number) is refused naming
//! the option, with the rule, in the same words for every command (`error: invalid value
//! '-1e-8' for '--tol <TOL>': must be finite and > 0`). Every numeric option also takes
//! values that start with a hyphen (`allow_hyphen_values`), so that `--tol -1e-8` reaches its
//! rule rather than being taken for an unknown option.

/// A number, or why it is not one.
fn number(text: &str) -> Result<f64, String> {
    text.trim()
        .parse::<f64>()
        .map_err(|_| "not a number".to_string())
}

/// A number that is finite and > 0.
pub fn positive(text: &str) -> Result<f64, String> {
    match number(text)? {
        x if x.is_finite() && x > 0.0 => Ok(x),
        _ => Err("must be finite and > 0".to_string()),
    }
}

/// A number that is finite and ≥ 0.
pub fn non_negative(text: &str) -> Result<f64, String> {
    match number(text)? {
        x if x.is_finite() && x >= 0.0 => Ok(x),
        _ => Err("must be finite and >= 0".to_string()),
    }
}

/// A finite number (of either sign).
pub fn finite(text: &str) -> Result<f64, String> {
    match number(text)? {
        x if x.is_finite() => Ok(x),
        _ => Err("must be finite".to_string()),
    }
}

/// A whole number ≥ 1.
pub fn count(text: &str) -> Result<usize, String> {
    match text.trim().parse::<usize>() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err(format!("must be a whole number from 1 to {}", usize::MAX)),
    }
}
