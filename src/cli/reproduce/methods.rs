//! The problems and the named methods that `ecr reproduce` compares.
//!
//! # Adding a method
//!
//! Append one [`Method`] to [`methods`]. Its `build` gets the [`Problem`] and the step size and
//! returns any [`Integrator`] boxed. Use [`on_system!`] when the constructor takes the
//! problem's `System` (y' = Ay + g(y), A structured: dense 2 × 2 or the FFT skew pair for NLS),
//! or match on the [`Problem`] directly when it wants the problem itself. For example:
//!
//! ```ignore
//! Method {
//!     name: "RKEPC2",
//!     about: "HBVM(5,2): energy-preserving collocation, 5-point Lobatto quadrature",
//!     build: |p, h| on_system!(p, sys => boxed(Hbvm::new(sys, 5, 2, h, SolverSettings::paper()))),
//! },
//! ```
//!
//! A method that fails to build or to integrate a problem is reported in `report.md` and left
//! out of that problem's panels; the other methods still run.

use ecr::baselines::collocation::rkepc2;
use ecr::baselines::dop853::Dop853Stepper;
use ecr::baselines::exponential::Exprb43;
use ecr::baselines::krylov::Exprb43Krylov;
use ecr::problems::{Duffing, Nls, Wind};
use ecr_runtime::integrate::Integrator;
use ecr_runtime::stepper::{EcStepper, SizedEcStepper, SolverSettings, StepReport};
use ecr_runtime::system::System;

/// One of the paper's test problems, as the harness hands it to a method's constructor.
// A handful of values, built once per study: the size difference does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Problem {
    /// Problem 1.
    Duffing(Duffing),
    /// Problem 2 (conservative or dissipative).
    Wind(Wind),
    /// Problem 3 (FFT skew-pair linear part).
    Nls(Nls),
}

impl Problem {
    /// The paper's initial value.
    pub fn initial_value(&self) -> Vec<f64> {
        match self {
            Problem::Duffing(p) => p.initial_value(),
            Problem::Wind(p) => p.initial_value(),
            Problem::Nls(p) => p.initial_value(),
        }
    }

    /// The energy H(y) (first integral or Lyapunov function).
    pub fn energy(&self, y: &[f64]) -> f64 {
        match self {
            Problem::Duffing(p) => p.energy(y),
            Problem::Wind(p) => p.energy(y),
            Problem::Nls(p) => p.energy(y),
        }
    }
}

/// Evaluates `$body` with `$sys` bound to the problem's `System` (`DuffingSystem`,
/// `WindSystem` or `NlsSystem`); the body is instantiated once per system type, so it may call
/// generic constructors. `?` inside propagates `ecr_runtime::Error`.
macro_rules! on_system {
    ($problem:expr, $sys:ident => $body:expr) => {
        match $problem {
            Problem::Duffing(p) => {
                let $sys = p.system()?;
                $body
            }
            Problem::Wind(p) => {
                let $sys = p.system()?;
                $body
            }
            Problem::Nls(p) => {
                let $sys = p.system()?;
                $body
            }
        }
    };
}
pub(crate) use on_system;

/// An integrator as the harness drives it: one step of size h at a time, and, for a method
/// that chooses its own steps inside each of them (DOP853), how many it took, so that the
/// error studies plot it against the steps it used rather than against h.
pub trait Harness: Integrator {
    /// Steps chosen by the method itself so far; None for a method that steps with h.
    fn own_steps(&self) -> Option<usize> {
        None
    }
}

/// A method that steps with h.
struct WithH<I>(I);

impl<I: Integrator> Integrator for WithH<I> {
    fn step_size(&self) -> f64 {
        self.0.step_size()
    }
    fn set_step_size(&mut self, h: f64) -> ecr_runtime::Result<()> {
        self.0.set_step_size(h)
    }
    fn step_state(&mut self, y: &mut [f64]) -> ecr_runtime::Result<StepReport> {
        self.0.step_state(y)
    }
    fn energy_of(&self, y: &[f64]) -> Option<f64> {
        self.0.energy_of(y)
    }
}

impl<I: Integrator> Harness for WithH<I> {}

impl<S: System> Harness for Dop853Stepper<S> {
    fn own_steps(&self) -> Option<usize> {
        Some(self.stats().accepted)
    }
}

/// A boxed integrator of any type.
pub type BoxedIntegrator = Box<dyn Harness>;

/// Boxes a constructed integrator that steps with h (helper for [`Method::build`]).
pub fn boxed<I: Integrator + 'static>(
    integrator: ecr_runtime::Result<I>,
) -> ecr_runtime::Result<BoxedIntegrator> {
    Ok(Box::new(WithH(integrator?)))
}

/// A named method: how to build it for a problem and a step size.
pub struct Method {
    /// Short name used in legends, CSV files and the report.
    pub name: &'static str,
    /// One-line description for the report.
    pub about: &'static str,
    /// Constructor.
    pub build: fn(&Problem, f64) -> ecr_runtime::Result<BoxedIntegrator>,
}

/// ECrP with `r` moments on `s` Gauss points: what `ecr bench`'s run-time series use
/// ([`SizedEcStepper`] for the planar problems).
pub fn ec(
    problem: &Problem,
    r: usize,
    s: usize,
    h: f64,
    settings: SolverSettings,
) -> ecr_runtime::Result<BoxedIntegrator> {
    // Planar problems on fixed-size buffers (bit for bit EcStepper); the NLS is never planar,
    // so it takes EcStepper directly rather than compiling the fixed-size forms for its system.
    match problem {
        Problem::Duffing(p) => boxed(SizedEcStepper::with_nodes(p.system()?, r, s, h, settings)),
        Problem::Wind(p) => boxed(SizedEcStepper::with_nodes(p.system()?, r, s, h, settings)),
        Problem::Nls(p) => boxed(EcStepper::with_nodes(p.system()?, r, s, h, settings)),
    }
}

/// The name of the paper's method; the comparisons in the report are made against it.
pub const PRIMARY: &str = "EC2P";

/// The methods compared, in legend order. The first is [`PRIMARY`].
pub fn methods() -> Vec<Method> {
    vec![
        Method {
            name: PRIMARY,
            about: "ECrP, r = s = 2 (order 4), paper's stage solver: fixed-point iteration, \
                    tolerance 1e-16, at most 5 sweeps, accepted at the limit",
            build: |p, h| ec(p, 2, 2, h, SolverSettings::paper()),
        },
        Method {
            name: "EC2P-conv",
            about: "ECrP, r = s = 2, stage equations iterated to convergence (tolerance 1e-15 \
                    or round-off stagnation, at most 100 sweeps, error otherwise)",
            build: |p, h| ec(p, 2, 2, h, SolverSettings::default()),
        },
        Method {
            name: "RKEPC2",
            about: "HBVM(5,2) = energy-preserving collocation of order 4, integral by 5-point \
                    Lobatto quadrature, applied to f = Ay + g; paper's stage solver (1e-16, \
                    at most 5 sweeps). Its fixed-point iteration on the whole field diverges \
                    once h‖A‖ is well above 1 (NLS: ‖A‖ = μ²(N/2)² = 512, so h = 0.0125 fails)",
            build: |p, h| on_system!(p, sys => boxed(rkepc2(sys, h, SolverSettings::paper()))),
        },
        Method {
            name: "RKEPC2-conv",
            about: "RKEPC2 with its stage equations iterated to convergence (tolerance 1e-15 \
                    or round-off stagnation, at most 100 sweeps): exactly energy-preserving \
                    for polynomial H",
            build: |p, h| on_system!(p, sys => boxed(rkepc2(sys, h, SolverSettings::default()))),
        },
        Method {
            name: "EEI3s4",
            about: "exprb43 (Hochbruck–Ostermann–Schweitzer 2009), explicit, 3 stages, order 4, \
                    Jacobian J = A + g'(y_n) refreshed every step (g' by central differences; \
                    for the NLS matrix-free, φ-functions by Krylov projection)",
            build: |p, h| match p {
                // For the NLS, J = A + g'(y) is dense (not circulant): its φ-functions are
                // applied matrix-free by Krylov projection (J·x = FFT product + g'(y)·x).
                Problem::Nls(n) => boxed(Exprb43Krylov::new(n.system()?, h)),
                _ => on_system!(p, sys => boxed(Exprb43::new(sys, h))),
            },
        },
        Method {
            name: "DOP853",
            about: "Dormand–Prince 8(5,3) (ode_solvers), adaptive inside each output step h, \
                    rtol = atol = 1e-12: what many users pick instead. It chooses its own \
                    steps, so the error studies plot it against the steps it took",
            build: |p, h| on_system!(p, sys => Ok(Box::new(Dop853Stepper::new(sys, h)?) as BoxedIntegrator)),
        },
    ]
}
