//! The stepper ([`Stepper`]): its construction, the kernel bank for the step size, and the
//! algorithm of one step, whose parts are the methods of [`StepContext`].

use std::marker::PhantomData;
use std::sync::Arc;

use super::buffers::{BufferParts, Buffers, VecBuffers};
use super::cache::{BankCache, BankKey, Built};
use super::context::{Bank, BankWorkspace, StepContext};
use super::fused::{FusedMaps, fused_maps, fuses_stages};
use super::iteration::Effort;
use super::kernel::{FixedKernel, Kernel, RuntimeKernel, kernel_coefficients};
use super::newton::{NewtonState, newton_entries};
use super::parallel::ParallelState;
use super::predictor::GuessBackoff;
use super::settings::{Predictor, SolverSettings, StageScale, StageSolver, StepReport, SweepLimit};
use super::stopping::{Y1_OVERFLOWED, all_finite, g_fault};
use crate::error::{Error, Result};
use crate::operator::{LinearOperator, PhiBank};
use crate::storage::ensure_allocatable_for;
use crate::system::System;

/// ECrP for a [`System`] with kernel `K` and stage storage `B`.
pub struct Stepper<K: Kernel, S: System, B: Buffers> {
    kernel: K,
    system: S,
    settings: SolverSettings,
    h: f64,
    /// The kernel bank for h (nodes c₁..c_s, 1, and 1 + c₁..1 + c_s with the extrapolating
    /// predictor), its combine coefficients (h τ (2j+1) per node τ and j < r) and the step as
    /// dense maps ([`FusedMaps`]) where that is cheaper (see [`fuses_stages`]; otherwise each
    /// sweep forms the moments and combines): built once per step size, shared with the other
    /// steppers of a [`BankCache`].
    built: Arc<Built<Bank<S>>>,
    /// Where banks are shared with other steppers of the same system (a solve's runs).
    cache: Option<Arc<BankCache<Bank<S>>>>,
    /// The bank of the step size before the last change, kept so that changing back (after a
    /// last step shortened to end a span) builds nothing.
    spare: Option<Arc<Built<Bank<S>>>>,
    ws: BankWorkspace<S>,
    scratch: Vec<f64>,
    buf: B,
    /// The buffers hold a completed step (y₀, moments, and its end in `last`) for this h.
    have_previous: bool,
    /// Newton data ([`StageSolver::Newton`], [`StageSolver::SimplifiedNewton`]), built at the
    /// first step for this h.
    newton: Option<Box<NewtonState>>,
    /// The largest ratio of consecutive stage updates in the last completed step (1 when there
    /// is none): the floor of the contraction estimate of [`y1_converged`].
    theta: f64,
    /// The memory of the concurrent stage path, for d ≥
    /// [`SolverSettings::parallel_min_dim`] (else `None`: the serial path).
    par: Option<Box<ParallelState<BankWorkspace<S>>>>,
    /// How the extrapolated guess ([`Predictor::Extrapolate`]) has fared at this h (see
    /// [`GuessBackoff`]).
    guess: GuessBackoff,
    /// Stage values for the next step only ([`seed`](Stepper::seed)), s·d numbers, or empty.
    seed: Vec<f64>,
}

/// ECrP with r and s chosen at run time.
pub type EcStepper<S> = Stepper<RuntimeKernel, S, VecBuffers>;

impl<S: System> Stepper<RuntimeKernel, S, VecBuffers> {
    /// ECrP with s = r (the paper's method) and step size h.
    ///
    /// # Errors
    /// As [`EcStepper::with_nodes`].
    pub fn new(system: S, r: usize, h: f64) -> Result<Self> {
        Self::with_nodes(system, r, r, h, SolverSettings::default())
    }
}

impl<S: System, B: Buffers> Stepper<RuntimeKernel, S, B> {
    /// ECrP with r moments, s ≥ r Gauss–Legendre points, step size h and solver settings.
    ///
    /// With [`VecBuffers`] ([`EcStepper`]) any sizes; with fixed-size buffers
    /// (`Stepper::<RuntimeKernel, S, StaticBuffers<D, S, R>>`) the sizes must be theirs, and the
    /// step, bit for bit the same, keeps its stage state in registers and unrolls its loops as
    /// an `ecr_method!` stepper does (Duffing ω = 20, r = 6, d = 2: 35.0M instructions for
    /// 10⁴ steps against 63.1M with `VecBuffers` and 32.4M for `Ec6<_, 2>`).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for r, s out of range or bad settings,
    /// [`Error::InvalidStepSize`] for h, [`Error::DimensionMismatch`] if fixed-size buffers do
    /// not fit (r, s, d), and whatever building the φ-bank reports.
    pub fn with_nodes(
        system: S,
        r: usize,
        s: usize,
        h: f64,
        settings: SolverSettings,
    ) -> Result<Self> {
        check_settings(&settings)?;
        Self::from_kernel(RuntimeKernel::new(r, s)?, system, h, settings)
    }
}

impl<K: FixedKernel, S: System, B: Buffers> Stepper<K, S, B> {
    /// The fixed-order stepper with default solver settings.
    ///
    /// # Errors
    /// As [`Stepper::from_kernel`].
    pub fn fixed(system: S, h: f64) -> Result<Self> {
        Self::from_kernel(K::default(), system, h, SolverSettings::default())
    }
}

fn check_settings(settings: &SolverSettings) -> Result<()> {
    settings.validate()
}

/// A bank that stores more numbers than this is not kept as a stepper's spare.
const SPARE_MAX_STORED: usize = 1 << 22;

impl<K: Kernel, S: System, B: Buffers> Stepper<K, S, B> {
    /// A stepper from its parts: allocates the buffers and builds the φ-bank for h.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for bad settings, [`Error::InvalidStepSize`] for h,
    /// [`Error::DimensionMismatch`] if fixed-size buffers do not fit the system, the errors of
    /// [`check_system`](crate::system::check_system), [`Error::InvalidInput`] naming the size
    /// if [`StageSolver::Newton`]'s `O(s²d²)` matrices cannot be allocated (checked here,
    /// before the first step would abort on them), and whatever building the φ-bank reports.
    pub fn from_kernel(kernel: K, system: S, h: f64, settings: SolverSettings) -> Result<Self> {
        Self::from_kernel_cached(kernel, system, h, settings, None)
    }

    /// [`from_kernel`](Self::from_kernel) taking its banks from `cache` (and putting the ones it
    /// builds there), shared with the other steppers of the cache. The cache must serve only
    /// steppers of this system's operator.
    pub(crate) fn from_kernel_cached(
        kernel: K,
        system: S,
        h: f64,
        settings: SolverSettings,
        cache: Option<Arc<BankCache<Bank<S>>>>,
    ) -> Result<Self> {
        check_settings(&settings)?;
        crate::system::check_system(&system)?;
        if settings.solver != StageSolver::FixedPoint {
            let (s, d) = (kernel.s(), system.dim());
            ensure_allocatable_for(
                || format!("Newton for d = {d}, s = {s} (2s²d² + 2d² + 3sd numbers)"),
                newton_entries(s, d),
            )?;
        }
        let buf = B::with_sizes(kernel.r(), kernel.s(), system.dim())?;
        let built = Self::obtain(&system, &kernel, h, &settings, cache.as_deref())?;
        let ws = built.bank.workspace();
        let par = ParallelState::new(
            &kernel,
            &built.bank,
            settings.parallel_min_dim,
            system.scratch_len(),
        );
        Ok(Stepper {
            scratch: vec![0.0; system.scratch_len()],
            kernel,
            system,
            settings,
            h,
            built,
            cache,
            spare: None,
            ws,
            buf,
            have_previous: false,
            newton: None,
            theta: 1.0,
            par,
            guess: GuessBackoff::FRESH,
            seed: Vec::new(),
        })
    }

    /// The bank for h: from the cache if it has it, else built (and put there).
    fn obtain(
        system: &S,
        kernel: &K,
        h: f64,
        settings: &SolverSettings,
        cache: Option<&BankCache<Bank<S>>>,
    ) -> Result<Arc<Built<Bank<S>>>> {
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidStepSize(h));
        }
        let extrapolate = settings.predictor == Predictor::Extrapolate;
        let banks = settings.banks;
        let build = || Self::build_bank(system, kernel, h, extrapolate, banks);
        match cache {
            Some(cache) => {
                let key = BankKey::new(h, kernel.r(), kernel.nodes(), extrapolate, banks);
                cache.get_or_build(key, build)
            }
            None => build().map(Arc::new),
        }
    }

    /// The kernel bank for h, its combine coefficients and the step as dense maps (where
    /// [`fuses_stages`]).
    fn build_bank(
        system: &S,
        kernel: &K,
        h: f64,
        extrapolate: bool,
        banks: crate::operator::BankArithmetic,
    ) -> Result<Built<Bank<S>>> {
        let r = kernel.r();
        let mut taus = kernel.nodes().to_vec();
        taus.push(1.0);
        if extrapolate {
            taus.extend(kernel.nodes().iter().map(|c| 1.0 + c));
        }
        let bank = system.linear().kernel_bank_in(h, &taus, r, banks)?;
        let coef = kernel_coefficients(h, &taus, r);
        // f64 banks serve a step or a few (a value between grid points, a step size tried):
        // the fused stage matrices, O(s²d²·r) to build, would cost more than they save.
        let one_off = banks == crate::operator::BankArithmetic::F64;
        let fused = (!one_off && fuses_stages(&bank, r, kernel.s())).then(|| {
            let mut ws = bank.workspace();
            fused_maps(kernel, &bank, &coef, &mut ws, system.dim(), extrapolate)
        });
        Ok(Built {
            h,
            bank,
            coef,
            fused,
        })
    }

    /// Changes the step size (builds the φ-bank for it unless this stepper's cache has it, or it
    /// is the step size before the last change: call it rarely).
    ///
    /// # Errors
    /// [`Error::InvalidStepSize`] and whatever building the φ-bank reports.
    pub fn set_step_size(&mut self, h: f64) -> Result<()> {
        if h == self.h {
            return Ok(());
        }
        let built = match self.spare.take().filter(|b| b.h == h) {
            Some(b) => b,
            None => Self::obtain(
                &self.system,
                &self.kernel,
                h,
                &self.settings,
                self.cache.as_deref(),
            )?,
        };
        // The concurrent path's workspaces are the new bank's (the old ones go first).
        self.par = None;
        self.par = ParallelState::new(
            &self.kernel,
            &built.bank,
            self.settings.parallel_min_dim,
            self.system.scratch_len(),
        );
        self.ws = built.bank.workspace();
        let old = std::mem::replace(&mut self.built, built);
        // Kept for changing back, unless it is large (then the memory counts more).
        self.spare = (old.bank.stored() <= SPARE_MAX_STORED).then_some(old);
        self.h = h;
        self.have_previous = false;
        self.newton = None;
        self.theta = 1.0;
        self.guess = GuessBackoff::FRESH;
        Ok(())
    }

    /// The step size.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// r (order 2r).
    pub fn r(&self) -> usize {
        self.kernel.r()
    }

    /// Number of quadrature points.
    pub fn s(&self) -> usize {
        self.kernel.s()
    }

    /// The fused stage matrices ([`stage_matrices`](super::stage_matrices): one column-major `sd ×
    /// sd` matrix, for [`gemv_cm`](super::gemv_cm)) if this stepper fuses its step
    /// ([`fuses_stages`]).
    pub fn stage_matrices(&self) -> Option<&[f64]> {
        self.built.fused.as_ref().map(|f| f.stage.as_slice())
    }

    /// The step as dense maps, if this stepper fuses it ([`fuses_stages`]).
    pub fn fused_maps(&self) -> Option<&FusedMaps> {
        self.built.fused.as_ref()
    }

    /// The φ-bank (kernel bank) of the step size: nodes c₁..c_s, then 1 (then 1 + cᵢ with the
    /// extrapolating predictor).
    pub fn bank(&self) -> &<S::Op as LinearOperator>::Bank {
        &self.built.bank
    }

    /// The kernel.
    pub fn kernel(&self) -> &K {
        &self.kernel
    }

    /// The system.
    pub fn system(&self) -> &S {
        &self.system
    }

    /// The solver settings.
    pub fn settings(&self) -> SolverSettings {
        self.settings
    }

    /// The stage values the next step's iteration starts from (s·d numbers: the state at
    /// t + cⱼh for each node cⱼ of the kernel, in order), for that step only, in place of the
    /// predictor's guess. A stage at a node c = 0 is taken as y whatever the seed says. Where
    /// the iteration from the seed fails (diverges, or reaches the sweep limit with
    /// [`SweepLimit::Error`]), the step starts again from y. The first call allocates.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] for a seed of another length.
    pub(crate) fn seed(&mut self, stages: &[f64]) -> Result<()> {
        let expected = self.kernel.s() * self.buf.dim();
        if stages.len() != expected {
            return Err(Error::DimensionMismatch {
                what: "stage seed",
                expected,
                found: stages.len(),
            });
        }
        self.seed.clear();
        self.seed.extend_from_slice(stages);
        Ok(())
    }

    /// The last completed step as the storage keeps it: its start y₀, its stage values (s·d,
    /// in node order) and the state it returned, or `None` where the storage does not keep
    /// the stages. After a failed step or [`set_step_size`](Self::set_step_size) these are
    /// what the buffers hold, not necessarily a completed step of this h: the caller knows
    /// which step they belong to.
    pub(crate) fn last_step(&self) -> Option<(&[f64], &[f64], &[f64])> {
        Some((self.buf.y0(), self.buf.stages()?, self.buf.last_state()?))
    }

    /// Moves the state `y` that the last step returned to `f(y₀ᵢ, yᵢ)` for each component
    /// (y₀ the state that step started from), and the stepper's record of it alike, so that the
    /// next step still continues this one (the predictor, the compensated update). A `y` that is
    /// not what the last step returned is left as it is. Allocation-free.
    pub(crate) fn perturb(&mut self, y: &mut [f64], mut f: impl FnMut(f64, f64) -> f64) {
        self.buf.with_parts(|parts| {
            if *parts.last == *y {
                for ((v, l), &v0) in y.iter_mut().zip(parts.last.iter_mut()).zip(parts.y0.iter()) {
                    *v = f(v0, *v);
                    *l = *v;
                }
            }
        });
    }

    /// Advances y by one step of size h in place. Allocation-free.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] for a wrong length, [`Error::NonFinite`] if y or g(Y) is
    /// NaN/infinite or the iteration diverges, [`Error::Overflow`] if the stage values or y₁
    /// overflow while the iteration is not diverging (the solution leaves the f64 range within
    /// the step, or h is unstable for it), [`Error::NoConvergence`] if the sweeps do not
    /// converge and [`SweepLimit::Error`] is set. On error, y is unchanged.
    pub fn step(&mut self, y: &mut [f64]) -> Result<StepReport> {
        // Two compiled steps: the fixed-point sweeps in the global scale on the serial path
        // (the small steppers' hot path), which carries no code of the others, and one for
        // everything else (Newton, the per-component scale, the concurrent path of large
        // systems), which reads those choices at run time. Up to eight specialised copies (one
        // per combination) made every stepper type several times dearer to compile (the
        // ecr package's test binaries: 1166 s against 432 s of build) for little off the hot
        // path, where the step's work is a factorisation, a second pass or a thread handshake
        // (Newton on Duffing, EC4P: 0.6 % more instructions with the flags read at run time).
        let plain = self.settings.solver == StageSolver::FixedPoint
            && matches!(
                self.settings.scale,
                StageScale::Global | StageScale::GlobalFloor { .. }
            )
            && (B::LOCAL_STAGES || self.par.is_none());
        if plain {
            self.step_plain(y)
        } else {
            self.step_general(y)
        }
    }

    /// [`step`](Self::step) on the hot path, compiled as its own function (a few instructions
    /// per step fewer than inlined into `step`: Duffing ω = 20, EC6P, h = 0.1, T = 1000,
    /// 47.52M against 47.59M instructions for the whole `ecr run`).
    #[inline(never)]
    fn step_plain(&mut self, y: &mut [f64]) -> Result<StepReport> {
        self.step_with::<true>(y)
    }

    /// [`step`](Self::step) off the hot path: compiled apart, so that the plain steps carry
    /// none of its code.
    #[inline(never)]
    fn step_general(&mut self, y: &mut [f64]) -> Result<StepReport> {
        self.step_with::<false>(y)
    }

    /// [`step`](Self::step): with `PLAIN`, fixed-point sweeps in the global scale on the serial
    /// path, known at compile time; otherwise Newton, the per-component scale and the
    /// concurrent stage path as the settings and the stepper say.
    ///
    /// The algorithm of one step: the start of the stage iteration ([`StepContext::start`]),
    /// sweeps until the stopping rule holds ([`StepContext::iterate`]), the step formula
    /// ([`StepContext::finish`]). Each part is always inlined, so that fixed-size stage state
    /// stays in registers.
    fn step_with<const PLAIN: bool>(&mut self, y: &mut [f64]) -> Result<StepReport> {
        // Compile-time constants for fixed-size storage (checked against the kernel and the
        // system when the buffers were made).
        let (m, s, d) = B::SIZES.unwrap_or((self.kernel.r(), self.kernel.s(), self.buf.dim()));
        if y.len() != d || !all_finite(y) {
            // A seed is for this step only, whatever becomes of it.
            self.seed.clear();
        }
        if y.len() != d {
            return Err(Error::DimensionMismatch {
                what: "state y",
                expected: d,
                found: y.len(),
            });
        }
        if !all_finite(y) {
            return Err(Error::NonFinite("state y"));
        }
        let Stepper {
            kernel,
            system,
            settings,
            built,
            ws,
            scratch,
            buf,
            have_previous,
            newton,
            theta,
            par,
            guess,
            seed,
            ..
        } = self;
        let report = buf.with_parts(|parts| {
            let BufferParts {
                y0,
                stages,
                new_stages,
                props,
                g,
                moments,
                last,
                comp,
                tmp,
            } = parts;
            // Newton and the per-component scale: constant false on the plain path. Decided
            // here, not captured: a captured flag is not a constant when the inliner weighs
            // this closure, and left out of line it keeps fixed-size stages out of registers
            // (the Duffing run above: 76.8M instructions against 47.5M).
            let use_newton = !PLAIN && settings.solver != StageSolver::FixedPoint;
            let per_component = !PLAIN && matches!(settings.scale, StageScale::PerComponent { .. });
            // Only a completed step that ended exactly at y may seed the predictor or hand on its
            // rounding error; a failed step leaves no usable previous step.
            let continuing = std::mem::take(have_previous) && *last == *y;
            if !continuing {
                comp.fill(0.0);
            }
            // The contraction seen in the step before (none known after a jump).
            let theta_floor = if continuing { *theta } else { 1.0 };
            let mut cx = StepContext::<K, S, B> {
                kernel,
                system,
                settings,
                bank: &built.bank,
                ws,
                coef: &built.coef,
                scratch,
                fused: built.fused.as_ref(),
                // The concurrent path (large d; never with fixed-size buffers, which are for
                // small systems). `None` at compile time on the serial path.
                par: if B::LOCAL_STAGES || PLAIN {
                    None
                } else {
                    par.as_deref_mut()
                },
                sizes: (m, s, d),
                buffers: PhantomData,
            };
            // The first iterate: the previous step extrapolated (unless the guess is waiting
            // after a failure), or y₀ at every stage.
            let predict = continuing && settings.predictor == Predictor::Extrapolate;
            // A seed (stage values given for this step) comes before the predictor.
            let mut seeded = !seed.is_empty();
            let mut extrapolate = !seeded && predict && guess.try_guess();
            // The work of an iteration from the guess that failed (restarted from y₀).
            let mut failed = Effort::default();
            let mut failed_newton = (0, 0, 0);
            let (start_evals, it, effort, newton_counts) = loop {
                // Newton: the Newton matrix at y₀, factorised.
                let mut nt = if use_newton {
                    Some(cx.newton_start(newton, y)?)
                } else {
                    None
                };
                let mut effort = Effort::default();
                let started = if seeded {
                    cx.start_seeded(seed, y, y0, stages, g)
                } else {
                    cx.start(extrapolate, y, y0, moments, stages, props, g)
                };
                let attempt = match started {
                    // Sweeps until the stopping rule holds.
                    Ok(start_evals) => cx
                        .iterate(
                            per_component,
                            y0,
                            stages,
                            new_stages,
                            props,
                            g,
                            moments,
                            theta_floor,
                            nt.as_mut(),
                            &mut effort,
                        )
                        .map(|it| (start_evals, it)),
                    Err(e) => Err(e),
                };
                let newton_counts =
                    nt.map_or((0, 0, 0), |n| (n.jacobian_evals, n.refreshes, n.g_evals));
                if extrapolate || seeded {
                    let accepted = attempt.as_ref().is_ok_and(|(_, it)| {
                        it.converged || settings.on_limit == SweepLimit::Accept
                    });
                    if !accepted {
                        // The guess failed: this step again from y₀ (counting the work done).
                        let start_evals = attempt.as_ref().map_or(s, |(e, _)| *e);
                        failed.sweeps += effort.sweeps;
                        failed.g_evals += start_evals + effort.g_evals;
                        failed_newton = newton_counts;
                        if extrapolate {
                            guess.failed();
                        }
                        (extrapolate, seeded) = (false, false);
                        continue;
                    }
                    if extrapolate {
                        guess.converged();
                    }
                }
                let (start_evals, it) = attempt?;
                break (start_evals, it, effort, newton_counts);
            };
            if !it.converged && settings.on_limit == SweepLimit::Error {
                if let Some(what) = g_fault(g, it.global) {
                    return Err(Error::NonFinite(what));
                }
                return Err(Error::NoConvergence {
                    sweeps: failed.sweeps + effort.sweeps,
                    residual: it.residual,
                    tolerance: settings.tolerance,
                });
            }
            // y₁ from g at the stages.
            cx.finish(y0, g, moments, y, last, comp, tmp);
            if !all_finite(y) {
                y.copy_from_slice(y0);
                // g is not checked per sweep: a non-finite g makes the next stages non-finite
                // (caught by the residual) or, at the last sweep, y₁.
                return Err(
                    g_fault(g, it.global).map_or(Error::Overflow(Y1_OVERFLOWED), Error::NonFinite)
                );
            }
            last.copy_from_slice(y);
            *have_previous = true;
            *theta = if it.theta_step > 0.0 {
                it.theta_step
            } else {
                theta_floor
            };
            let (jacobian_evals, newton_refreshes, newton_evals) = newton_counts;
            Ok(StepReport {
                sweeps: failed.sweeps + effort.sweeps,
                residual: it.residual,
                g_evals: failed.g_evals
                    + failed_newton.2
                    + start_evals
                    + newton_evals
                    + effort.g_evals,
                converged: it.converged,
                jacobian_evals: failed_newton.0 + jacobian_evals,
                newton_refreshes: failed_newton.1 + newton_refreshes,
            })
        });
        // A seed is for this step only, whatever became of it (an error of the Newton start).
        seed.clear();
        report
    }

    /// Dense output of the last step: ũ(τ) = φ₀(τhA)y₀ + h Σ_k τ^{k+1} φ_{k+1}(τhA) G_k, for
    /// τ ∈ [0, 1] (the method's continuous solution, paper eq. `EEPCr`; evaluated in the
    /// Legendre form of the module docs). Builds a kernel bank for τ, so it allocates: use it
    /// for output, not in a hot loop.
    ///
    /// # Errors
    /// [`Error::NoCompletedStep`] before the first step, after a failed step and after
    /// [`set_step_size`](Self::set_step_size) (the buffers then hold no step of this h),
    /// [`Error::InvalidInput`] for τ outside [0, 1], and whatever building the bank reports.
    pub fn dense_output(&self, tau: f64) -> Result<Vec<f64>> {
        if !self.have_previous {
            return Err(Error::NoCompletedStep);
        }
        if !(0.0..=1.0).contains(&tau) {
            return Err(Error::InvalidInput(format!(
                "dense output needs 0 <= tau <= 1, got {tau:?}"
            )));
        }
        let y0 = self.buf.y0();
        if tau == 0.0 {
            return Ok(y0.to_vec());
        }
        let r = self.kernel.r();
        let mut out = vec![0.0; y0.len()];
        let bank = self
            .system
            .linear()
            .kernel_bank_in(self.h, &[tau], r, self.settings.banks)?;
        let mut ws = bank.workspace();
        let coef = kernel_coefficients(self.h, &[tau], r);
        bank.combine(0..1, y0, self.buf.moments(), &coef, &mut out, &mut ws);
        Ok(out)
    }
}
