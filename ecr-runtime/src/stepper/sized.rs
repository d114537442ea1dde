//! [`SizedEcStepper`]: the run-time stepper on the storage its sizes call for.

use super::buffers::StaticBuffers;
use super::kernel::RuntimeKernel;
use super::settings::{SolverSettings, StepReport};
use super::step::{EcStepper, Stepper};
use crate::error::Result;
use crate::system::System;

/// The run-time stepper on fixed-size storage for d = 2.
type Fixed<S, const N: usize> = Stepper<RuntimeKernel, S, StaticBuffers<2, N, N>>;

/// ECrP with r and s chosen at run time, on the stage storage its sizes call for: for d = 2
/// and s = r ≤ [`SizedEcStepper::MAX_FIXED_R`] (planar problems at the paper's nodes) fixed-size
/// arrays, whose step keeps its stage state in registers and unrolls its loops over r and s
/// (about half the instructions of [`EcStepper`]'s step, nearly those of the `ecr_method!`
/// stepper of that r); for other sizes [`EcStepper`] itself. The results are bit for bit
/// [`EcStepper`]'s either way.
///
/// What it costs: the fixed-size steppers are compiled for every system type it is used with
/// (eight of them, whatever the system's dimension), so use it where small planar systems meet
/// a run-time r; with r known when writing the program, `ecr_method!` is the cheaper choice.
///
/// ```
/// use ecr_runtime::nalgebra::SMatrix;
/// use ecr_runtime::operator::DenseStatic;
/// use ecr_runtime::stepper::{SizedEcStepper, SolverSettings};
/// use ecr_runtime::system::Semilinear;
///
/// // q'' + q = −q³ as y' = [[0, 1], [−1, 0]] y + (0, −q³).
/// let a = DenseStatic::new(SMatrix::<f64, 2, 2>::new(0.0, 1.0, -1.0, 0.0))?;
/// let system = Semilinear::new(a, |y: &[f64], g: &mut [f64]| {
///     g[0] = 0.0;
///     g[1] = -y[0] * y[0] * y[0];
/// });
/// let mut stepper = SizedEcStepper::with_nodes(system, 4, 4, 0.1, SolverSettings::default())?;
/// assert!(stepper.is_fixed_size());
/// let mut y = [1.0, 0.0];
/// stepper.step(&mut y)?;
/// # Ok::<(), ecr_runtime::Error>(())
/// ```
pub enum SizedEcStepper<S: System> {
    /// Any sizes: heap buffers.
    Heap(EcStepper<S>),
    /// d = 2, r = s = 1.
    Fixed1(Fixed<S, 1>),
    /// d = 2, r = s = 2.
    Fixed2(Fixed<S, 2>),
    /// d = 2, r = s = 3.
    Fixed3(Fixed<S, 3>),
    /// d = 2, r = s = 4.
    Fixed4(Fixed<S, 4>),
    /// d = 2, r = s = 5.
    Fixed5(Fixed<S, 5>),
    /// d = 2, r = s = 6.
    Fixed6(Fixed<S, 6>),
    /// d = 2, r = s = 7.
    Fixed7(Fixed<S, 7>),
    /// d = 2, r = s = 8.
    Fixed8(Fixed<S, 8>),
}

/// Evaluates `$body` with `$st` bound to the stepper inside `$self`, whichever variant it is.
macro_rules! each {
    ($self:expr, $st:ident => $body:expr) => {
        match $self {
            SizedEcStepper::Heap($st) => $body,
            SizedEcStepper::Fixed1($st) => $body,
            SizedEcStepper::Fixed2($st) => $body,
            SizedEcStepper::Fixed3($st) => $body,
            SizedEcStepper::Fixed4($st) => $body,
            SizedEcStepper::Fixed5($st) => $body,
            SizedEcStepper::Fixed6($st) => $body,
            SizedEcStepper::Fixed7($st) => $body,
            SizedEcStepper::Fixed8($st) => $body,
        }
    };
}

impl<S: System> SizedEcStepper<S> {
    /// The largest r = s with fixed-size storage (for d = 2).
    pub const MAX_FIXED_R: usize = 8;

    /// ECrP with s = r (the paper's method), step size h and default solver settings.
    ///
    /// # Errors
    /// As [`EcStepper::with_nodes`].
    pub fn new(system: S, r: usize, h: f64) -> Result<Self> {
        Self::with_nodes(system, r, r, h, SolverSettings::default())
    }

    /// ECrP with r moments, s ≥ r Gauss–Legendre points, step size h and solver settings, as
    /// [`EcStepper::with_nodes`].
    ///
    /// # Errors
    /// As [`EcStepper::with_nodes`].
    pub fn with_nodes(
        system: S,
        r: usize,
        s: usize,
        h: f64,
        settings: SolverSettings,
    ) -> Result<Self> {
        let fixed_r = if system.dim() == 2 && s == r { r } else { 0 };
        Ok(match fixed_r {
            1 => Self::Fixed1(Stepper::with_nodes(system, r, s, h, settings)?),
            2 => Self::Fixed2(Stepper::with_nodes(system, r, s, h, settings)?),
            3 => Self::Fixed3(Stepper::with_nodes(system, r, s, h, settings)?),
            4 => Self::Fixed4(Stepper::with_nodes(system, r, s, h, settings)?),
            5 => Self::Fixed5(Stepper::with_nodes(system, r, s, h, settings)?),
            6 => Self::Fixed6(Stepper::with_nodes(system, r, s, h, settings)?),
            7 => Self::Fixed7(Stepper::with_nodes(system, r, s, h, settings)?),
            8 => Self::Fixed8(Stepper::with_nodes(system, r, s, h, settings)?),
            _ => Self::Heap(EcStepper::with_nodes(system, r, s, h, settings)?),
        })
    }

    /// Whether the stage state is in fixed-size arrays (else in [`EcStepper`]'s heap buffers).
    pub fn is_fixed_size(&self) -> bool {
        !matches!(self, Self::Heap(_))
    }

    /// Advances y by one step of size h in place, as [`Stepper::step`]. Allocation-free.
    ///
    /// # Errors
    /// As [`Stepper::step`].
    pub fn step(&mut self, y: &mut [f64]) -> Result<StepReport> {
        each!(self, st => st.step(y))
    }

    /// Changes the step size, as [`Stepper::set_step_size`].
    ///
    /// # Errors
    /// As [`Stepper::set_step_size`].
    pub fn set_step_size(&mut self, h: f64) -> Result<()> {
        each!(self, st => st.set_step_size(h))
    }

    /// The step size.
    pub fn step_size(&self) -> f64 {
        each!(self, st => st.step_size())
    }

    /// r (order 2r).
    pub fn r(&self) -> usize {
        each!(self, st => st.r())
    }

    /// Number of quadrature points.
    pub fn s(&self) -> usize {
        each!(self, st => st.s())
    }

    /// The system.
    pub fn system(&self) -> &S {
        each!(self, st => st.system())
    }

    /// The solver settings.
    pub fn settings(&self) -> SolverSettings {
        each!(self, st => st.settings())
    }

    /// Dense output of the last step, as [`Stepper::dense_output`].
    ///
    /// # Errors
    /// As [`Stepper::dense_output`].
    pub fn dense_output(&self, tau: f64) -> Result<Vec<f64>> {
        each!(self, st => st.dense_output(tau))
    }
}
