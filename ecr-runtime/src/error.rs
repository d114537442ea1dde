//! The error type of the runtime.

use std::fmt;

/// Everything that can go wrong in `ecr-runtime`, reported instead of panicking.
///
/// The enum is `#[non_exhaustive]`: match with a wildcard arm.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Error {
    /// A step size that is zero, negative, NaN or infinite.
    InvalidStepSize(f64),
    /// A value that is NaN or infinite where a finite number is required; the string names it.
    NonFinite(&'static str),
    /// Two sizes that must agree do not; `what` names the pair.
    DimensionMismatch {
        /// Which quantity was checked.
        what: &'static str,
        /// The size that was required.
        expected: usize,
        /// The size that was given.
        found: usize,
    },
    /// A matrix that must be square is not.
    NotSquare {
        /// Which matrix.
        what: &'static str,
        /// Its number of rows.
        rows: usize,
        /// Its number of columns.
        cols: usize,
    },
    /// A method parameter (r, s, p, ...) outside its supported range.
    InvalidParameter(String),
    /// Any other invalid input, described in words.
    InvalidInput(String),
    /// The stage equations did not converge within the allowed sweeps.
    NoConvergence {
        /// Sweeps performed.
        sweeps: usize,
        /// Last residual (max-norm of the last stage update).
        residual: f64,
        /// Tolerance that was asked for.
        tolerance: f64,
    },
    /// A numerical failure (overflow, failed decomposition, ...), described in words.
    Numerical(String),
    /// Dense output asked of a stepper that holds no completed step for its step size: no step
    /// yet, the last step failed, or the step size changed since.
    NoCompletedStep,
    /// Values of a step overflowed to infinity or NaN while the stage iteration was not
    /// diverging: the solution grows beyond the f64 range within the step, or the step size is
    /// unstable for the problem. The string names the values.
    Overflow(&'static str),
    /// A solve could not verify its answer to the tolerance; why, in words (the best
    /// solution is in the `SolveError` this came from).
    Unverified(String),
    /// Reading or writing a file failed (an ensemble's table); what and why, in words.
    Io(String),
    /// A step of an integration failed; where, and why (`source`).
    AtStep {
        /// The number of the failed step (1 for the first).
        step: usize,
        /// The time at which the failed step started.
        t: f64,
        /// Its step size.
        h: f64,
        /// What went wrong.
        source: Box<Error>,
    },
}

impl Error {
    /// The error itself, or for [`Error::AtStep`] the error of the failed step.
    pub fn root(&self) -> &Error {
        match self {
            Error::AtStep { source, .. } => source.root(),
            e => e,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::InvalidStepSize(h) => {
                write!(f, "invalid step size h = {h:?}: it must be finite and > 0")
            }
            Error::NonFinite(what) => write!(f, "{what} contains NaN or infinity"),
            Error::DimensionMismatch {
                what,
                expected,
                found,
            } => write!(
                f,
                "dimension mismatch in {what}: expected {expected}, found {found}"
            ),
            Error::NotSquare { what, rows, cols } => {
                write!(f, "{what} must be square, but is {rows} x {cols}")
            }
            Error::InvalidParameter(msg) => write!(f, "invalid parameter: {msg}"),
            Error::InvalidInput(msg) => write!(f, "invalid input: {msg}"),
            Error::NoConvergence {
                sweeps,
                residual,
                tolerance,
            } => write!(
                f,
                "stage equations did not converge: residual {residual:e} after {sweeps} sweeps \
                 (tolerance {tolerance:e}); try a smaller h, more sweeps, or the Newton stage \
                 solver"
            ),
            Error::Numerical(msg) => write!(f, "numerical failure: {msg}"),
            Error::NoCompletedStep => write!(
                f,
                "no completed step to interpolate: dense output needs a successful step with \
                 the current step size (there was none yet, the last step failed, or the step \
                 size changed since)"
            ),
            Error::Overflow(what) => write!(
                f,
                "{what} overflowed to infinity or NaN: the solution grows beyond the f64 range \
                 within the step, or the step size is unstable for the problem; try a smaller h"
            ),
            Error::Unverified(msg) => write!(f, "the answer could not be verified: {msg}"),
            Error::Io(msg) => write!(f, "{msg}"),
            Error::AtStep { step, t, h, source } => {
                write!(f, "step {step} from t = {t:?} (h = {h:?}) failed: {source}")
            }
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::AtStep { source, .. } => Some(source.as_ref()),
            _ => None,
        }
    }
}

/// Shorthand for `Result<T, ecr_runtime::Error>`.
pub type Result<T> = std::result::Result<T, Error>;
