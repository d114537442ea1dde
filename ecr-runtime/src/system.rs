//! Systems y' = Ay + g(y) (paper eq. `IVP1`): the linear part as a structured
//! [`LinearOperator`], the nonlinearity g, and the energy H when it is known.

use crate::error::{Error, Result};
use crate::operator::{Dense, LinearOperator, Symmetric};
use nalgebra::DMatrix;

/// A semilinear system y' = Ay + g(y) with a structured linear part.
///
/// Implement it for your own system, or use [`Semilinear`], [`Hamiltonian`] or
/// [`GradientFlow`]. Steppers call [`nonlinear`](System::nonlinear) on the hot path with a
/// scratch slice of [`scratch_len`](System::scratch_len) entries, so g can be evaluated
/// without allocating.
pub trait System {
    /// The linear operator A.
    type Op: LinearOperator;
    /// The dimension d.
    fn dim(&self) -> usize {
        self.linear().dim()
    }
    /// The linear part A.
    fn linear(&self) -> &Self::Op;
    /// Writes g(y) into `out` (`y.len() == out.len() == dim()`); `scratch` has
    /// [`scratch_len`](System::scratch_len) entries.
    fn nonlinear(&self, y: &[f64], out: &mut [f64], scratch: &mut [f64]);
    /// Scratch entries [`nonlinear`](System::nonlinear) needs (default 0).
    fn scratch_len(&self) -> usize {
        0
    }
    /// g at several states: `ys` holds k states of length d one after another, `out` receives
    /// their k values of g, and block `skip` of `out` is left as it is (g is already there).
    /// `scratch` has `k · scratch_len()` entries, the j-th `scratch_len()` of them for state j.
    /// The ECrP stepper calls it for the s stages of each sweep of a large system (d ≥
    /// [`SolverSettings::parallel_min_dim`](crate::stepper::SolverSettings::parallel_min_dim));
    /// each state's g must be what [`nonlinear`](System::nonlinear) gives.
    ///
    /// The default evaluates the states one after another. A system that may be shared
    /// between threads (`Sync`) can have them evaluated concurrently: override this with a
    /// call of [`nonlinear_concurrent`] (the NLS systems of `ecr::problems` do),
    /// or wrap the system in [`Concurrent`]. It is the system's choice because the steppers
    /// cannot ask for `Sync` without rejecting systems that are not (stable Rust cannot
    /// specialise on it).
    fn nonlinear_stages(
        &self,
        ys: &[f64],
        out: &mut [f64],
        scratch: &mut [f64],
        skip: Option<usize>,
    ) {
        let (d, sl) = (self.dim(), self.scratch_len());
        for (j, (y, o)) in ys.chunks_exact(d).zip(out.chunks_exact_mut(d)).enumerate() {
            if skip != Some(j) {
                self.nonlinear(y, o, &mut scratch[j * sl..(j + 1) * sl]);
            }
        }
    }
    /// The energy H(y) (first integral or Lyapunov function), if known.
    fn energy(&self, _y: &[f64]) -> Option<f64> {
        None
    }
    /// Writes the Jacobian ∂g/∂y at y into `jac` (d × d) and returns `true`, or returns `false`
    /// (the default) if it is not provided: the Newton stage solver then uses forward
    /// differences.
    fn jacobian(&self, _y: &[f64], _jac: &mut DMatrix<f64>, _scratch: &mut [f64]) -> bool {
        false
    }
}

/// Checks what every stepper needs of a system before it allocates for it: a dimension d ≥ 1
/// that agrees with its linear operator's. Called by every constructor that takes a
/// [`System`], so that a system whose `dim()` is wrong fails there, not at the first step.
///
/// # Errors
/// [`Error::DimensionMismatch`] if `system.dim()` differs from `system.linear().dim()`,
/// [`Error::InvalidInput`] if the dimension is 0.
pub fn check_system<S: System + ?Sized>(system: &S) -> Result<()> {
    let (d, op) = (system.dim(), system.linear().dim());
    if d != op {
        return Err(Error::DimensionMismatch {
            what: "system: dim() vs its linear operator's dim()",
            expected: op,
            found: d,
        });
    }
    if d == 0 {
        return Err(Error::InvalidInput(
            "the system has dimension 0: there is nothing to integrate".into(),
        ));
    }
    Ok(())
}

impl<S: System + ?Sized> System for &S {
    type Op = S::Op;
    fn dim(&self) -> usize {
        (**self).dim()
    }
    fn linear(&self) -> &Self::Op {
        (**self).linear()
    }
    fn nonlinear(&self, y: &[f64], out: &mut [f64], scratch: &mut [f64]) {
        (**self).nonlinear(y, out, scratch)
    }
    fn scratch_len(&self) -> usize {
        (**self).scratch_len()
    }
    fn nonlinear_stages(
        &self,
        ys: &[f64],
        out: &mut [f64],
        scratch: &mut [f64],
        skip: Option<usize>,
    ) {
        (**self).nonlinear_stages(ys, out, scratch, skip)
    }
    fn energy(&self, y: &[f64]) -> Option<f64> {
        (**self).energy(y)
    }
    fn jacobian(&self, y: &[f64], jac: &mut DMatrix<f64>, scratch: &mut [f64]) -> bool {
        (**self).jacobian(y, jac, scratch)
    }
}

/// [`System::nonlinear_stages`] with the states evaluated concurrently on rayon's thread pool,
/// one task per state (each by [`System::nonlinear`], so the values are those of the serial
/// evaluation bit for bit). For a `Sync` system's override of `nonlinear_stages`:
///
/// ```
/// use ecr_runtime::operator::Diagonal;
/// use ecr_runtime::system::{System, nonlinear_concurrent};
///
/// struct Cubic(Diagonal);
///
/// impl System for Cubic {
///     type Op = Diagonal;
///     fn linear(&self) -> &Diagonal {
///         &self.0
///     }
///     fn nonlinear(&self, y: &[f64], out: &mut [f64], _scratch: &mut [f64]) {
///         for (o, v) in out.iter_mut().zip(y) {
///             *o = -v * v * v;
///         }
///     }
///     fn nonlinear_stages(&self, ys: &[f64], out: &mut [f64], sc: &mut [f64], skip: Option<usize>) {
///         nonlinear_concurrent(self, ys, out, sc, skip)
///     }
/// }
/// # let sys = Cubic(Diagonal::new(vec![-1.0; 3]).unwrap());
/// # let mut out = [0.0; 6];
/// # sys.nonlinear_stages(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0], &mut out, &mut [], None);
/// # assert_eq!(out, [-1.0, -8.0, -27.0, -64.0, -125.0, -216.0]);
/// ```
///
/// # Panics
/// If `ys`, `out` or `scratch` are shorter than the states in `out` need.
pub fn nonlinear_concurrent<S: System + Sync + ?Sized>(
    system: &S,
    ys: &[f64],
    out: &mut [f64],
    scratch: &mut [f64],
    skip: Option<usize>,
) {
    let (d, sl) = (system.dim(), system.scratch_len());
    crate::concurrent::for_each_block(out, d, scratch, sl, &|j, o, sc| {
        if skip != Some(j) {
            system.nonlinear(&ys[j * d..(j + 1) * d], o, sc);
        }
    });
}

/// Any `Sync` system with its g evaluated at the stages of a sweep concurrently
/// ([`nonlinear_concurrent`]), e.g. a [`Semilinear`] with a `Sync` closure: otherwise the same
/// system (every other method forwards to it).
#[derive(Clone, Debug)]
pub struct Concurrent<S>(pub S);

impl<S: System + Sync> System for Concurrent<S> {
    type Op = S::Op;
    fn dim(&self) -> usize {
        self.0.dim()
    }
    fn linear(&self) -> &Self::Op {
        self.0.linear()
    }
    fn nonlinear(&self, y: &[f64], out: &mut [f64], scratch: &mut [f64]) {
        self.0.nonlinear(y, out, scratch)
    }
    fn scratch_len(&self) -> usize {
        self.0.scratch_len()
    }
    fn nonlinear_stages(
        &self,
        ys: &[f64],
        out: &mut [f64],
        scratch: &mut [f64],
        skip: Option<usize>,
    ) {
        nonlinear_concurrent(&self.0, ys, out, scratch, skip)
    }
    fn energy(&self, y: &[f64]) -> Option<f64> {
        self.0.energy(y)
    }
    fn jacobian(&self, y: &[f64], jac: &mut DMatrix<f64>, scratch: &mut [f64]) -> bool {
        self.0.jacobian(y, jac, scratch)
    }
}

/// Plain semilinear system: an operator A, a closure for g and optionally one for H.
pub struct Semilinear<A, G, H = fn(&[f64]) -> f64> {
    op: A,
    g: G,
    h: Option<H>,
}

impl<A: LinearOperator, G: Fn(&[f64], &mut [f64])> Semilinear<A, G> {
    /// y' = Ay + g(y) without a known energy.
    pub fn new(op: A, g: G) -> Self {
        Semilinear { op, g, h: None }
    }
}

impl<A: LinearOperator, G: Fn(&[f64], &mut [f64]), H: Fn(&[f64]) -> f64> Semilinear<A, G, H> {
    /// y' = Ay + g(y) with energy H.
    pub fn with_energy(op: A, g: G, h: H) -> Self {
        Semilinear { op, g, h: Some(h) }
    }
}

impl<A: LinearOperator, G: Fn(&[f64], &mut [f64]), H: Fn(&[f64]) -> f64> System
    for Semilinear<A, G, H>
{
    type Op = A;
    fn linear(&self) -> &A {
        &self.op
    }
    fn nonlinear(&self, y: &[f64], out: &mut [f64], _scratch: &mut [f64]) {
        (self.g)(y, out)
    }
    fn energy(&self, y: &[f64]) -> Option<f64> {
        self.h.as_ref().map(|h| h(y))
    }
}

/// yᵀMy.
fn quadratic_form(m: &DMatrix<f64>, y: &[f64]) -> f64 {
    m.column_iter()
        .zip(y)
        .map(|(col, yj)| yj * col.iter().zip(y).map(|(a, yi)| a * yi).sum::<f64>())
        .sum()
}

fn check_square(what: &'static str, m: &DMatrix<f64>) -> Result<()> {
    if m.nrows() != m.ncols() {
        return Err(Error::NotSquare {
            what,
            rows: m.nrows(),
            cols: m.ncols(),
        });
    }
    if m.iter().any(|x| !x.is_finite()) {
        return Err(Error::NonFinite(what));
    }
    Ok(())
}

fn check_symmetric(what: &'static str, m: &DMatrix<f64>) -> Result<()> {
    let scale = m.amax().max(f64::MIN_POSITIVE);
    let asym = (m - m.transpose()).amax();
    if asym > 1e-12 * scale {
        return Err(Error::InvalidInput(format!(
            "{what} must be symmetric (max |M - Mᵀ| = {asym:e})"
        )));
    }
    Ok(())
}

/// y' = Q∇H(y), H(y) = ½yᵀMy + V(y) (paper eqs. `IVPPP`, `H`): A = QM, g = Q∇V.
///
/// Q skew-symmetric: H is a first integral; Q negative semidefinite: H is a Lyapunov function.
pub struct Hamiltonian<GV, V = fn(&[f64]) -> f64> {
    op: Dense,
    q: DMatrix<f64>,
    m: DMatrix<f64>,
    grad_v: GV,
    v: Option<V>,
}

impl<GV: Fn(&[f64], &mut [f64])> Hamiltonian<GV> {
    /// From Q, M (symmetric) and ∇V, without V (no energy).
    ///
    /// # Errors
    /// [`Error::NotSquare`], [`Error::DimensionMismatch`], [`Error::NonFinite`], or
    /// [`Error::InvalidInput`] if M is not symmetric.
    pub fn new(q: DMatrix<f64>, m: DMatrix<f64>, grad_v: GV) -> Result<Self> {
        Self::build(q, m, grad_v, None)
    }
}

impl<GV: Fn(&[f64], &mut [f64])> Hamiltonian<GV> {
    /// A canonical system in y = (q, p) (d = 2n): Q = [[0, I], [−I, 0]], so q' = ∂H/∂p and
    /// p' = −∂H/∂q, with H(y) = ½yᵀMy + V(y) and ∇V written for all of y into a slice of
    /// zeros (components V does not depend on may be left alone). Add V with
    /// [`potential`](Self::potential) to have the energy reported.
    ///
    /// # Errors
    /// As [`Hamiltonian::new`], and [`Error::InvalidInput`] for an odd dimension.
    pub fn canonical(m: DMatrix<f64>, grad_v: GV) -> Result<Self> {
        let d = m.nrows();
        if d % 2 != 0 {
            return Err(Error::InvalidInput(format!(
                "a canonical system has y = (q, p), an even dimension (M is {d} × {})",
                m.ncols()
            )));
        }
        let n = d / 2;
        let mut q = DMatrix::zeros(d, d);
        for i in 0..n {
            q[(i, n + i)] = 1.0;
            q[(n + i, i)] = -1.0;
        }
        Self::new(q, m, grad_v)
    }

    /// The same system with the potential V, so that the energy H = ½yᵀMy + V is reported.
    pub fn potential<V: Fn(&[f64]) -> f64>(self, v: V) -> Hamiltonian<GV, V> {
        Hamiltonian {
            op: self.op,
            q: self.q,
            m: self.m,
            grad_v: self.grad_v,
            v: Some(v),
        }
    }
}

impl<GV: Fn(&[f64], &mut [f64]), V: Fn(&[f64]) -> f64> Hamiltonian<GV, V> {
    /// From Q, M, ∇V and V: the energy H = ½yᵀMy + V is reported.
    ///
    /// # Errors
    /// As [`Hamiltonian::new`].
    pub fn with_potential(q: DMatrix<f64>, m: DMatrix<f64>, grad_v: GV, v: V) -> Result<Self> {
        Self::build(q, m, grad_v, Some(v))
    }

    fn build(q: DMatrix<f64>, m: DMatrix<f64>, grad_v: GV, v: Option<V>) -> Result<Self> {
        check_square("Q", &q)?;
        check_square("M", &m)?;
        if q.nrows() != m.nrows() {
            return Err(Error::DimensionMismatch {
                what: "Q and M",
                expected: q.nrows(),
                found: m.nrows(),
            });
        }
        check_symmetric("M", &m)?;
        let op = Dense::new(&q * &m)?;
        Ok(Hamiltonian {
            op,
            q,
            m,
            grad_v,
            v,
        })
    }

    /// Q.
    pub fn q(&self) -> &DMatrix<f64> {
        &self.q
    }

    /// M.
    pub fn m(&self) -> &DMatrix<f64> {
        &self.m
    }
}

impl<GV: Fn(&[f64], &mut [f64]), V: Fn(&[f64]) -> f64> System for Hamiltonian<GV, V> {
    type Op = Dense;
    fn linear(&self) -> &Dense {
        &self.op
    }
    fn nonlinear(&self, y: &[f64], out: &mut [f64], scratch: &mut [f64]) {
        // ∇V is written into zeros: components V does not depend on may be left alone.
        scratch.fill(0.0);
        (self.grad_v)(y, scratch);
        // out = Q ∇V(y)
        for (i, o) in out.iter_mut().enumerate() {
            *o = self
                .q
                .row(i)
                .iter()
                .zip(scratch.iter())
                .map(|(a, b)| a * b)
                .sum();
        }
    }
    fn scratch_len(&self) -> usize {
        self.q.nrows()
    }
    fn energy(&self, y: &[f64]) -> Option<f64> {
        let v = self.v.as_ref()?;
        Some(0.5 * quadratic_form(&self.m, y) + v(y))
    }
}

/// Gradient flow y' = −∇U(y), U(y) = ½yᵀMy + V(y) (paper §7, with Q = −I:
/// `docs/errata.md#e3-gradient-flow-sign`):
/// A = −M (symmetric, so its φ-functions come from one eigendecomposition), g = −∇V,
/// and U is a Lyapunov function.
///
/// M is a dense matrix here: its [`Symmetric`] operator costs O(d²) per application and an
/// O(d³) eigendecomposition. For a structured M, state the same flow as a [`Semilinear`]
/// system with a structured operator for A = −M: a periodic Laplacian is a
/// [`Circulant`](crate::operator::Circulant) (O(d log d) by FFT: on Allen–Cahn with d = 128,
/// 20 steps of EC4P with the set-up took 7.6 ms against 2.3 s dense; `examples/allen_cahn.rs`
/// times both), a diagonal M a
/// [`Diagonal`](crate::operator::Diagonal).
///
/// ```
/// use ecr_runtime::prelude::*;
///
/// // U = ½yᵀMy + V, V = Σ yᵢ⁴/4, ∇V written into `g`; without V no energy is reported.
/// let m = DMatrix::from_row_slice(2, 2, &[2.0, -1.0, -1.0, 2.0]);
/// let grad_v = |y: &[f64], g: &mut [f64]| g.iter_mut().zip(y).for_each(|(g, y)| *g = y.powi(3));
/// let flow = GradientFlow::new(m.clone(), grad_v, None)?;
/// assert_eq!(flow.energy(&[1.0, 0.0]), None);
/// let flow = GradientFlow::with_potential(m, grad_v, |y: &[f64]| {
///     y.iter().map(|y| y.powi(4) / 4.0).sum::<f64>()
/// })?;
/// assert_eq!(flow.energy(&[1.0, 0.0]), Some(1.25));
/// # Ok::<(), ecr_runtime::Error>(())
/// ```
pub struct GradientFlow<GV, V = fn(&[f64]) -> f64> {
    op: Symmetric,
    m: DMatrix<f64>,
    grad_v: GV,
    v: Option<V>,
}

impl<GV: Fn(&[f64], &mut [f64])> GradientFlow<GV> {
    /// From M (symmetric), ∇V and optionally V as a function (a closure that captures
    /// nothing, or a `fn`; `None`: no Lyapunov function reported). For a V that captures
    /// data, use [`with_potential`](GradientFlow::with_potential).
    ///
    /// # Errors
    /// [`Error::NotSquare`], [`Error::NonFinite`], [`Error::InvalidInput`] (M not symmetric).
    pub fn new(m: DMatrix<f64>, grad_v: GV, v: Option<fn(&[f64]) -> f64>) -> Result<Self> {
        GradientFlow::build(m, grad_v, v)
    }
}

impl<GV: Fn(&[f64], &mut [f64]), V: Fn(&[f64]) -> f64> GradientFlow<GV, V> {
    /// From M (symmetric), ∇V and V: the Lyapunov function U = ½yᵀMy + V is reported.
    ///
    /// # Errors
    /// As [`GradientFlow::new`].
    pub fn with_potential(m: DMatrix<f64>, grad_v: GV, v: V) -> Result<Self> {
        GradientFlow::build(m, grad_v, Some(v))
    }

    fn build(m: DMatrix<f64>, grad_v: GV, v: Option<V>) -> Result<Self> {
        check_square("M", &m)?;
        check_symmetric("M", &m)?;
        let op = Symmetric::new(-m.clone())?;
        Ok(GradientFlow { op, m, grad_v, v })
    }
}

impl<GV: Fn(&[f64], &mut [f64]), V: Fn(&[f64]) -> f64> System for GradientFlow<GV, V> {
    type Op = Symmetric;
    fn linear(&self) -> &Symmetric {
        &self.op
    }
    fn nonlinear(&self, y: &[f64], out: &mut [f64], _scratch: &mut [f64]) {
        (self.grad_v)(y, out);
        for o in out.iter_mut() {
            *o = -*o;
        }
    }
    fn energy(&self, y: &[f64]) -> Option<f64> {
        let v = self.v.as_ref()?;
        Some(0.5 * quadratic_form(&self.m, y) + v(y))
    }
}
