//! The fastest Duffing peer of the benchmark: the rotation splitting written in C for speed
//! (`benches/c/rotation_splitting_duffing.c`, compiled by the build script with the `cc` crate
//! when the `cli` feature is on), called once over [0, T] as its users call it.
//!
//! The same method as [`RotationSplitting`](ecr::baselines::splitting::RotationSplitting) on
//! `q'' + (ω² + k²)q = 2k²q³` with the same composition tables, rounded differently: the
//! kick is folded into the rotation, the half-kicks are merged also across steps, and every
//! coefficient is computed once per step size (the C file's header says why each matters and
//! what it measured). Two forms: [`Form::Accurate`] keeps the rotation's determinant 1 to far
//! below an ulp, as the library's does; [`Form::Plain`] is the plain 2 × 2 product, faster by
//! one dependent operation per stage, whose amplitude drifts by about an ulp per rotation.

use ecr::baselines::splitting::composition;
use ecr_runtime::integrate::StepPlan;
use ecr_runtime::{Error, Result};
use std::os::raw::{c_int, c_long};

use super::series::{Observe, Run};

/// Most sub-steps of a composition (Kahan–Li order 8), as in the C file.
const MAX_STAGES: usize = 15;

/// `struct ecr_rot_duffing` of the C file (a test checks that the sizes agree).
#[repr(C)]
#[derive(Clone, Copy)]
struct Coefficients {
    stages: c_int,
    form: c_int,
    lin: [f64; MAX_STAGES],
    qp: [f64; MAX_STAGES],
    pq: [f64; MAX_STAGES],
    kq: [f64; MAX_STAGES],
    kp: [f64; MAX_STAGES],
    last: f64,
}

// The C file's forms (its enum and ECR_ROT_FASTEST_ACCURATE).
const C_ACCURATE: c_int = 0;
const C_ACCURATE_FMA: c_int = 1;
const C_PLAIN: c_int = 2;
const C_FASTEST_ACCURATE: c_int = -1;

unsafe extern "C" {
    fn ecr_rot_duffing_size() -> usize;
    #[cfg(test)]
    static ecr_rot_kahan_li8: [f64; 15];
    fn ecr_rot_duffing_init(
        m: *mut Coefficients,
        stiffness: f64,
        cubic: f64,
        h: f64,
        gamma: *const f64,
        s: c_int,
        form: c_int,
    ) -> c_int;
    fn ecr_rot_duffing_enter(m: *const Coefficients, y: *mut f64);
    fn ecr_rot_duffing_leave(m: *const Coefficients, y: *const f64, out: *mut f64);
    fn ecr_rot_duffing_steps(m: *const Coefficients, y: *mut f64, n: c_long);
}

/// How a stage rotates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Form {
    /// cos θ = 1 + (cos θ − 1) with cos θ − 1 = −2 sin²(θ/2), q and p added last: the
    /// rotation's determinant is 1 to far below an ulp (no drift of the amplitude); with
    /// fused multiply-add where the processor has it.
    Accurate,
    /// [`Form::Accurate`] without fused multiply-add, on any processor (for the tests).
    #[cfg_attr(not(test), allow(dead_code))]
    AccurateNoFma,
    /// The plain 2 × 2 product with cos θ rounded: one dependent operation less per stage, and
    /// a determinant 1 only to about an ulp, the same every step (the amplitude drifts).
    Plain,
}

/// One step size's coefficients, checked.
#[derive(Clone, Copy)]
struct Table {
    m: Coefficients,
}

impl Table {
    fn new(stiffness: f64, cubic: f64, h: f64, gammas: &[f64], form: Form) -> Result<Self> {
        // SAFETY: a plain function of no arguments.
        let size = unsafe { ecr_rot_duffing_size() };
        if size != std::mem::size_of::<Coefficients>() {
            return Err(Error::InvalidParameter(format!(
                "the C rotation splitting's coefficients take {size} bytes, not {}: the C \
                 file and src/cli/bench/c_peer.rs disagree",
                std::mem::size_of::<Coefficients>()
            )));
        }
        let form = match form {
            Form::Accurate => C_FASTEST_ACCURATE,
            Form::AccurateNoFma => C_ACCURATE,
            Form::Plain => C_PLAIN,
        };
        let mut m = Coefficients {
            stages: 0,
            form: 0,
            lin: [0.0; MAX_STAGES],
            qp: [0.0; MAX_STAGES],
            pq: [0.0; MAX_STAGES],
            kq: [0.0; MAX_STAGES],
            kp: [0.0; MAX_STAGES],
            last: 0.0,
        };
        // `composition` gives at most 15 sub-steps; the C function checks s again.
        let s = c_int::try_from(gammas.len()).unwrap_or(c_int::MAX);
        // SAFETY: `m` is a valid `struct ecr_rot_duffing` (same layout, size checked above),
        // `gammas` holds s values, and the function reads no further than s.
        let status =
            unsafe { ecr_rot_duffing_init(&mut m, stiffness, cubic, h, gammas.as_ptr(), s, form) };
        if status != 0 {
            return Err(Error::InvalidParameter(format!(
                "C rotation splitting: Ω = {stiffness:e}, cubic coefficient {cubic:e}, h = \
                 {h:e}, {} sub-steps: not a valid set-up",
                gammas.len()
            )));
        }
        Ok(Table { m })
    }

    fn enter(&self, y: &mut [f64; 2]) {
        // SAFETY: `y` holds the two values the function reads and writes.
        unsafe { ecr_rot_duffing_enter(&self.m, y.as_mut_ptr()) }
    }

    fn leave(&self, y: &[f64; 2]) -> [f64; 2] {
        let mut out = [0.0; 2];
        // SAFETY: `y` and `out` hold two values each.
        unsafe { ecr_rot_duffing_leave(&self.m, y.as_ptr(), out.as_mut_ptr()) };
        out
    }

    fn steps(&self, y: &mut [f64; 2], n: usize) {
        // Runs of more than c_long::MAX steps (2^31 − 1 on some targets) in pieces.
        let mut left = n;
        while left > 0 {
            let chunk = left.min(c_long::MAX as usize);
            // SAFETY: `y` holds the two values the function reads and writes; the table was
            // set up by `ecr_rot_duffing_init`.
            unsafe { ecr_rot_duffing_steps(&self.m, y.as_mut_ptr(), chunk as c_long) };
            left -= chunk;
        }
    }
}

/// The C rotation splitting of one order, form and step size for Duffing
/// `q'' + (ω² + k²)q = 2k²q³`, state (q, p).
pub struct RotationC {
    stiffness: f64,
    cubic: f64,
    gammas: &'static [f64],
    form: Form,
    h: f64,
    table: Table,
}

impl RotationC {
    /// Order 2, 4, 6 or 8 (the tables of [`composition`]) with step size h.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for another order, non-finite or negative ω² + k², a
    /// non-finite k, or a form the processor cannot run; [`Error::InvalidStepSize`].
    pub fn new(omega: f64, k: f64, order: usize, h: f64, form: Form) -> Result<Self> {
        let gammas = composition(order)?;
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidStepSize(h));
        }
        let (stiffness, cubic) = (omega * omega + k * k, 2.0 * k * k);
        let table = Table::new(stiffness, cubic, h, gammas, form)?;
        Ok(RotationC {
            stiffness,
            cubic,
            gammas,
            form,
            h,
            table,
        })
    }

    /// Whether the accurate form runs with fused multiply-add here.
    pub fn uses_fma(&self) -> bool {
        self.table.m.form == C_ACCURATE_FMA
    }

    /// Integrates (q, p) over [0, t_end] in place with the steps [`integrate`] takes for this
    /// h (a last step of another size where h does not divide t_end), calling `observe` with
    /// (q, p) after every step. Returns the number of steps.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] unless y has length 2, [`Error::NonFinite`] for a
    /// non-finite y or result (y is then unchanged), [`Error::InvalidInput`] for a bad t_end.
    ///
    /// [`integrate`]: ecr_runtime::integrate::integrate
    pub fn integrate(
        &self,
        y: &mut [f64],
        t_end: f64,
        mut observe: Option<Observe<'_>>,
    ) -> Result<usize> {
        let &mut [q, p] = y else {
            return Err(Error::DimensionMismatch {
                what: "state (q, p)",
                expected: 2,
                found: y.len(),
            });
        };
        if !(q.is_finite() && p.is_finite()) {
            return Err(Error::NonFinite("state (q, p)"));
        }
        let plan = StepPlan::new(0.0, t_end, self.h)?;
        if plan.steps() == 0 {
            return Ok(0);
        }
        let mut state = [q, p];
        self.table.enter(&mut state);
        match observe.as_mut() {
            None => self.table.steps(&mut state, plan.full_steps),
            Some(f) => {
                for _ in 0..plan.full_steps {
                    self.table.steps(&mut state, 1);
                    f(&self.table.leave(&state));
                }
            }
        }
        let out = match plan.last {
            None => self.table.leave(&state),
            Some(last) => {
                // The last step has its own size: its own coefficients, built here (once per
                // run, as `integrate` builds the stepper's φ-bank for it).
                let table = Table::new(self.stiffness, self.cubic, last, self.gammas, self.form)?;
                let mut s = self.table.leave(&state);
                table.enter(&mut s);
                table.steps(&mut s, 1);
                let end = table.leave(&s);
                if let Some(f) = observe.as_mut() {
                    f(&end);
                }
                end
            }
        };
        if !(out[0].is_finite() && out[1].is_finite()) {
            return Err(Error::NonFinite("C rotation splitting result"));
        }
        y.copy_from_slice(&out);
        Ok(plan.steps())
    }
}

impl Run for RotationC {
    fn run(
        &mut self,
        y: &mut [f64],
        t_end: f64,
        observe: Option<Observe<'_>>,
    ) -> std::result::Result<usize, String> {
        let steps = self
            .integrate(y, t_end, observe)
            .map_err(|e| e.to_string())?;
        // Evaluations of the force: one per stage, and one each to enter and leave the merged
        // state.
        Ok(steps * self.gammas.len() + 2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ecr::baselines::splitting::{KAHAN_LI8, RotationSplitting};
    use ecr::problems::Duffing;
    use ecr_runtime::integrate::{IntegrateOptions, integrate};
    use ecr_runtime::second_order::{Omega, SecondOrder, SecondOrderSystem};

    /// The forms this processor runs (the accurate one twice where it has fused multiply-add:
    /// with and without).
    const FORMS: [Form; 3] = [Form::Accurate, Form::AccurateNoFma, Form::Plain];

    /// The library's `RotationSplitting` on the same Duffing, y = (q, p).
    fn library(d: &Duffing, order: usize, h: f64) -> RotationSplitting<impl SecondOrderSystem> {
        let k2 = d.k() * d.k();
        let system = SecondOrder::with_potential(
            Omega::scalar(d.omega() * d.omega() + k2, 1).unwrap(),
            move |q: &[f64], f: &mut [f64]| f[0] = -2.0 * k2 * q[0].powi(3),
            move |q: &[f64]| -0.5 * k2 * q[0].powi(4),
        );
        RotationSplitting::new(system, order, h).unwrap()
    }

    fn with_library(d: &Duffing, order: usize, h: f64, t_end: f64) -> Vec<f64> {
        let mut m = library(d, order, h);
        let mut y = d.initial_value();
        let options = IntegrateOptions {
            energy_every: 0,
            observe_every: 0,
        };
        integrate(&mut m, 0.0, t_end, &mut y, options, |_, _, _| {}).unwrap();
        y
    }

    fn with_c(d: &Duffing, order: usize, h: f64, t_end: f64, form: Form) -> Vec<f64> {
        let m = RotationC::new(d.omega(), d.k(), order, h, form).unwrap();
        let mut y = d.initial_value();
        m.integrate(&mut y, t_end, None).unwrap();
        y
    }

    fn max_diff(a: &[f64], b: &[f64]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
    }

    /// The C file's layout and its order-8 table are the ones this file and the library use.
    #[test]
    fn c_layout_and_table_match() {
        // SAFETY: plain functions and a constant array of the C file.
        let (size, table) = unsafe { (ecr_rot_duffing_size(), ecr_rot_kahan_li8) };
        assert_eq!(size, std::mem::size_of::<Coefficients>());
        for (c, r) in table.iter().zip(KAHAN_LI8) {
            assert_eq!(c.to_bits(), r.to_bits(), "{c:e} ≠ {r:e}");
        }
    }

    /// The same method as `RotationSplitting`: the same final state to round-off, for every
    /// order and form, on a strongly nonlinear Duffing (ω = 1, k = 0.9: the splitting error
    /// ≈ 1e−3..1e−9 is far above the difference) and on the benchmark's (ω = 20, k = 0.07, 320
    /// steps), also when h does not divide T (a last step of another size, as `integrate`).
    /// The two round differently (merged kicks, the kick folded into the rotation); the
    /// difference is a few hundred ulps of the state after hundreds of steps, where a wrong
    /// coefficient would show at the splitting error's size.
    #[test]
    fn same_trajectory_as_the_library_to_round_off() {
        let cases = [
            (Duffing::new(1.0, 0.9).unwrap(), 0.1, 2.0),
            (Duffing::new(1.0, 0.9).unwrap(), 0.15, 2.0),
            (Duffing::new(20.0, 0.07).unwrap(), 1.0 / 32.0, 10.0),
        ];
        for (d, h, t_end) in &cases {
            let scale = d.omega(); // |p| ≤ ω along the orbit, |q| ≤ 1
            for order in [2, 4, 6, 8] {
                let lib = with_library(d, order, *h, *t_end);
                for form in FORMS {
                    let c = with_c(d, order, *h, *t_end, form);
                    let diff = max_diff(&c, &lib);
                    println!(
                        "ω = {}, h = {h}, order {order}, {form:?}: {diff:.1e}",
                        d.omega()
                    );
                    assert!(
                        diff <= 1e-12 * scale,
                        "ω = {}, h = {h}, order {order}, {form:?}: {diff:e}",
                        d.omega()
                    );
                }
            }
        }
    }

    /// Least-squares slope of log(error) against log(h).
    fn slope(hs: &[f64], errs: &[f64]) -> f64 {
        let pts: Vec<(f64, f64)> = hs.iter().zip(errs).map(|(h, e)| (h.ln(), e.ln())).collect();
        let n = pts.len() as f64;
        let (mx, my) = pts
            .iter()
            .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
        let sxy: f64 = pts.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
        let sxx: f64 = pts.iter().map(|(x, _)| (x - mx) * (x - mx)).sum();
        sxy / sxx
    }

    /// Measured orders 2, 4, 6, 8 against Duffing's exact solution (ω = 1, k = 0.9, T = 2; the
    /// step counts of the library's own test, errors 1e−3..1e−10, far above round-off), within
    /// 0.15 of nominal, for every form.
    #[test]
    fn measured_orders() {
        let d = Duffing::new(1.0, 0.9).unwrap();
        let t_end = 2.0;
        let exact = d.exact(t_end).unwrap();
        for (order, ns) in [
            (2, [16, 32, 64, 128, 256]),
            (4, [8, 16, 32, 64, 128]),
            (6, [4, 8, 16, 32, 64]),
            (8, [8, 12, 16, 20, 24]),
        ] {
            for form in FORMS {
                let hs: Vec<f64> = ns.iter().map(|&n| t_end / n as f64).collect();
                let errs: Vec<f64> = hs
                    .iter()
                    .map(|&h| max_diff(&with_c(&d, order, h, t_end, form), &exact))
                    .collect();
                assert!(errs.iter().all(|&e| e > 1e-12), "{errs:?}");
                let p = slope(&hs, &errs);
                let shown: Vec<String> = errs.iter().map(|e| format!("{e:.2e}")).collect();
                println!("order {order}, {form:?}: measured {p:.3}, errors {shown:?}");
                assert!(
                    (p - order as f64).abs() <= 0.15,
                    "order {order}, {form:?}: {p}"
                );
            }
        }
    }

    /// Observed step by step (the energy runs of the benchmark) it is the same trajectory, bit
    /// for bit, as one call over [0, T]; the observer sees every step, the last one included.
    #[test]
    fn observed_run_is_the_same_run() {
        let d = Duffing::new(20.0, 0.07).unwrap();
        for (h, steps) in [(1.0 / 16.0, 32), (0.3, 7)] {
            for form in FORMS {
                let m = RotationC::new(d.omega(), d.k(), 8, h, form).unwrap();
                let mut once = d.initial_value();
                assert_eq!(m.integrate(&mut once, 2.0, None).unwrap(), steps);
                let mut seen = Vec::new();
                let mut y = d.initial_value();
                let mut f = |y: &[f64]| seen.push(y.to_vec());
                assert_eq!(m.integrate(&mut y, 2.0, Some(&mut f)).unwrap(), steps);
                assert_eq!(seen.len(), steps);
                assert_eq!(seen.last().unwrap(), &y);
                for (a, b) in y.iter().zip(&once) {
                    assert_eq!(a.to_bits(), b.to_bits(), "h = {h}, {form:?}");
                }
            }
        }
    }

    /// The accurate form keeps the amplitude of a pure oscillator (k = 0, ω = 20, order 8,
    /// h = 0.0123, 10⁵ steps of 15 rotations by 0.1–0.2 rad): its relative energy error stays
    /// below 5e−12 (measured: 3.5e−13 without fused multiply-add, 4.6e−13 with). The plain
    /// form's rotations have determinants 1 + O(ulp), the same every step, and its energy drifts
    /// to 3.3e−11 here: what raises its round-off floor on Duffing (the summary's table). (For
    /// rotations by about 1 rad, h = 0.0625, the two drift alike, 1e−11 to 3e−11.)
    #[test]
    fn accurate_form_keeps_the_amplitude() {
        let (omega, h, n) = (20.0, 0.0123, 100_000usize);
        let energy = |y: &[f64]| 0.5 * (y[1] * y[1] + omega * omega * y[0] * y[0]);
        for form in FORMS {
            let m = RotationC::new(omega, 0.0, 8, h, form).unwrap();
            let mut y = vec![1.0, 0.3];
            let e0 = energy(&y);
            let mut last = 0.0f64;
            let mut i = 0;
            let mut f = |y: &[f64]| {
                i += 1;
                if i > n - n / 10 {
                    last = last.max((energy(y) - e0).abs() / e0);
                }
            };
            m.integrate(&mut y, h * n as f64, Some(&mut f)).unwrap();
            println!(
                "pure oscillator, {form:?}: relative energy error in the last tenth {last:.2e}"
            );
            if form != Form::Plain {
                assert!(last < 5e-12, "{form:?}: {last:e}");
            }
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(matches!(
            RotationC::new(20.0, 0.07, 3, 0.1, Form::Accurate),
            Err(Error::InvalidParameter(_))
        ));
        for h in [0.0, -0.1, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                RotationC::new(20.0, 0.07, 8, h, Form::Accurate),
                Err(Error::InvalidStepSize(_))
            ));
        }
        for (omega, k) in [(f64::NAN, 0.07), (20.0, f64::INFINITY)] {
            assert!(matches!(
                RotationC::new(omega, k, 8, 0.1, Form::Plain),
                Err(Error::InvalidParameter(_))
            ));
        }
        let m = RotationC::new(20.0, 0.07, 8, 0.1, Form::Accurate).unwrap();
        let mut y = vec![0.0, 20.0, 1.0];
        assert!(matches!(
            m.integrate(&mut y, 1.0, None),
            Err(Error::DimensionMismatch { .. })
        ));
        let mut y = vec![f64::NAN, 20.0];
        assert!(matches!(
            m.integrate(&mut y, 1.0, None),
            Err(Error::NonFinite(_))
        ));
        let mut y = vec![0.0, 20.0];
        assert!(m.integrate(&mut y, -1.0, None).is_err());
        assert_eq!(y, vec![0.0, 20.0]);
        // A state that overflows: an error, y as it was.
        let mut y = vec![1e200, 1e200];
        assert!(matches!(
            m.integrate(&mut y, 1.0, None),
            Err(Error::NonFinite(_))
        ));
        assert_eq!(y, vec![1e200, 1e200]);
    }
}
