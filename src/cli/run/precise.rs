//! `ecr run --precision double-double`: ECrP in double-double
//! ([`ecr_runtime::precision::GenericStepper`]), the state printed with 34 significant digits.

use super::{PROGRESS, PrecisionArg, ProblemArg, RunArgs, usage};
use crate::cli::{UsageError, progress};
use ecr::exact::duffing_error_dd;
use ecr::problems::{Duffing, HenonHeiles, Wind};
use ecr_runtime::precision::{
    DoubleDouble, GENERIC_MAX_SWEEPS, GenericReport, GenericStepper, GenericSystem, Real,
};
use serde_json::{Value, json};
use std::io::Write;
use std::sync::atomic::Ordering;
use std::time::Instant;

type Dd = DoubleDouble;

/// Marks a string of the JSON value that is to be written as a bare number (serde_json's
/// numbers are f64: 17 digits).
const NUMBER: &str = "\u{1}number:";

/// A double-double as a JSON number with 34 significant digits.
fn number(x: Dd) -> Value {
    Value::String(format!("{NUMBER}{}", x.to_decimal(Dd::DIGITS)))
}

/// The JSON text with the marked strings written as numbers.
fn render(value: &Value) -> Result<String, UsageError> {
    let text = serde_json::to_string_pretty(value).map_err(|e| UsageError(e.to_string()))?;
    // serde_json escapes U+0001 as \u0001.
    let marker = format!("\"{}", NUMBER.replace('\u{1}', "\\u0001"));
    let mut out = String::with_capacity(text.len());
    let mut rest = text.as_str();
    while let Some(i) = rest.find(&marker) {
        out.push_str(&rest[..i]);
        rest = &rest[i + marker.len()..];
        let end = rest.find('"').unwrap_or(rest.len());
        out.push_str(&rest[..end]);
        rest = &rest[(end + 1).min(rest.len())..];
    }
    out.push_str(rest);
    out.push('\n');
    Ok(out)
}

/// What the options of `ecr run` allow with double-double.
fn check(args: &RunArgs) -> Result<(), UsageError> {
    debug_assert_eq!(args.precision, PrecisionArg::DoubleDouble);
    let refuse = |what: &str| -> Result<(), UsageError> {
        Err(UsageError(format!(
            "--precision double-double does not take {what}"
        )))
    };
    if matches!(args.problem, ProblemArg::Nls | ProblemArg::Fpu) {
        return Err(UsageError(format!(
            "--precision double-double runs duffing, wind, wind-dissipative and henon-heiles, \
             not --problem {}",
            args.problem.name()
        )));
    }
    if args.tol.is_some() {
        return refuse("--tol (it runs a fixed step: give --h and --r)");
    }
    if args.paper_solver {
        return refuse("--paper-solver (its stages are converged to double-double round-off)");
    }
    if args.stage_tol.is_some() {
        return refuse("--stage-tol (its stages are converged to double-double round-off)");
    }
    if args.newton {
        return refuse("--newton");
    }
    if args.extrapolate || args.constant_start {
        return refuse(
            "--extrapolate or --constant-start (its stages start from the previous step's \
             continuous solution)",
        );
    }
    Ok(())
}

/// Runs `system` from `y0` with the options of `args`.
fn integrate<P: GenericSystem<Dd>>(
    system: P,
    y0: &[f64],
    args: &RunArgs,
) -> Result<(GenericReport<Dd>, Vec<Dd>, f64), UsageError> {
    let r = args.r();
    let s = args.s.unwrap_or(r);
    let mut stepper =
        GenericStepper::with_nodes(system, r, s, Dd::from(args.h())).map_err(usage)?;
    if let Some(m) = args.max_sweeps {
        stepper.set_max_sweeps(m);
    }
    let mut y: Vec<Dd> = y0.iter().map(|&v| Dd::from(v)).collect();
    let total = (args.t_end / args.h()).round().max(0.0) as u64;
    PROGRESS.total.store(total, Ordering::Relaxed);
    let bar = progress::StepBar::new(
        total,
        &format!(
            "ecr run --problem {} --precision double-double",
            args.problem.name()
        ),
    );
    let start = Instant::now();
    let report = stepper.integrate(Dd::from(0.0), Dd::from(args.t_end), &mut y, |n, t, _| {
        PROGRESS.t_bits.store(t.hi().to_bits(), Ordering::Relaxed);
        PROGRESS.steps.store(n as u64, Ordering::Relaxed);
        bar.set(n as u64);
    });
    bar.finish_and_clear();
    let report = report.map_err(|e| match e.root() {
        // The library's message suggests the Newton solver, which double-double refuses.
        ecr_runtime::Error::NoConvergence {
            sweeps, residual, ..
        } => {
            let at = match &e {
                ecr_runtime::Error::AtStep { step, t, h, .. } => {
                    format!("step {step} from t = {t:?} (h = {h:?}): ")
                }
                _ => String::new(),
            };
            UsageError(format!(
                "integration failed: {at}the stage equations did not converge to double-double \
                 round-off: residual {residual:e} after {sweeps} sweeps; try a smaller --h or \
                 more --max-sweeps (default {GENERIC_MAX_SWEEPS})"
            ))
        }
        _ => UsageError(format!("integration failed: {e}")),
    })?;
    Ok((report, y, start.elapsed().as_secs_f64()))
}

/// `ecr run --precision double-double`.
pub(super) fn run(args: &RunArgs, out: &mut dyn Write) -> Result<(), UsageError> {
    check(args)?;
    let (report, y, seconds, parameters, global_error) = match args.problem {
        ProblemArg::Duffing => {
            let problem =
                Duffing::new(args.omega.unwrap_or(5.0), args.k.unwrap_or(0.07)).map_err(usage)?;
            let (rep, y, secs) = integrate(&problem, &problem.initial_value(), args)?;
            let err = duffing_error_dd(&problem, rep.t_end, &[y[0], y[1]]);
            let params = json!({ "omega": problem.omega(), "k": problem.k() });
            (rep, y, secs, params, Some(err))
        }
        ProblemArg::Wind | ProblemArg::WindDissipative => {
            let radius = args.amplitude.unwrap_or(20.0);
            let problem = match (args.theta, args.problem) {
                (Some(theta), _) => Wind::new(theta, radius),
                (None, ProblemArg::WindDissipative) => Wind::from_deviation(1e-4, radius),
                (None, _) => Wind::new(std::f64::consts::FRAC_PI_2, radius),
            }
            .map_err(usage)?;
            let (rep, y, secs) = integrate(problem, &problem.initial_value(), args)?;
            let params = json!({
                "theta": problem.theta(),
                "amplitude": problem.radius(),
                "conservative": problem.is_conservative(),
            });
            (rep, y, secs, params, None)
        }
        ProblemArg::HenonHeiles => {
            let problem = HenonHeiles::default();
            let y0 = problem.initial_value();
            let (rep, y, secs) = integrate(problem, &y0, args)?;
            (rep, y, secs, json!({ "y0": y0 }), None)
        }
        ProblemArg::Nls | ProblemArg::Fpu => unreachable!("refused by check"),
    };
    // As the f64 path's check_finite: no success with an overflowed energy or error (the
    // stepper has already refused non-finite states).
    let finite = |v: Option<f64>| v.is_none_or(f64::is_finite);
    let energies = [report.energy_start, report.energy_end].map(|e| e.map(|e| e.hi()));
    if !(energies.into_iter().all(finite)
        && finite(report.max_energy_error)
        && finite(global_error))
    {
        return Err(UsageError(format!(
            "integration failed: the energy or the global error is not finite at t = {}",
            report.t_end
        )));
    }
    let value = json!({
        "problem": args.problem.name(),
        "parameters": parameters,
        "method": "ec",
        "precision": Dd::NAME,
        "r": args.r(),
        "s": args.s.unwrap_or(args.r()),
        "h": number(report.h),
        "h_last": report.h_last.map(number),
        "t_end": number(report.t_end),
        "steps": report.steps,
        "y": y.iter().map(|&v| number(v)).collect::<Vec<_>>(),
        "energy_start": report.energy_start.map(number),
        "energy_end": report.energy_end.map(number),
        "max_energy_error": report.max_energy_error,
        "energy_error_units": "relative: max over the steps of |H - H0| / |H0|",
        "global_error": global_error,
        "global_error_reference": global_error.map(|_| "exact solution at 256 bits"),
        "sweeps": report.sweeps,
        "max_sweeps_per_step": report.max_sweeps,
        "g_evals": report.g_evals,
        "wall_seconds": seconds,
    });
    out.write_all(render(&value)?.as_bytes())
        .map_err(|e| UsageError(format!("cannot write output: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_written_bare() {
        let v = json!({ "a": number(Dd::from(0.5)), "b": [number(Dd::from(-2.0))], "c": "x\"y" });
        let text = render(&v).unwrap();
        let back: Value = serde_json::from_str(&text).unwrap();
        assert_eq!(back["a"].as_f64(), Some(0.5));
        assert_eq!(back["b"][0].as_f64(), Some(-2.0));
        assert_eq!(back["c"].as_str(), Some("x\"y"));
        assert!(text.contains("5.000000000000000000000000000000000e-1"));
    }
}
