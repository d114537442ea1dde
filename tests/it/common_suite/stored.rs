//! The stored references, `tests/data/solve_suite_refs.json`: DO NOT EDIT it, regenerate it
//! with [`COMMAND`] (a few minutes; it also prints the accuracy measured for each).
//!
//! Each entry holds the case's hash ([`Case::hash`]: a stale entry fails the test
//! `stored_references_are_current`), how the reference was obtained, its accuracy measured
//! as max |a − b| / (1 + |b|) over components and output times between two independent
//! computations (the unit the suite measures errors in, divided by the tolerance), the output
//! times, the states as decimal strings (≥ 20 digits), and for the Taylor references the
//! derivative f(y) from the high-precision right-hand side (checked against the f64 system, so
//! that the two codings of one ODE cannot drift apart).

use std::collections::BTreeMap;

use serde_json::{Value, json};

use astro_float::BigFloat;

use super::hp::{Hp, PREC, taylor, to_f64};
use super::{Case, Reference};

/// The data file.
pub const PATH: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/data/solve_suite_refs.json"
);

/// What regenerates it.
pub const COMMAND: &str = "cargo test --release -p ecr --test it solve_suite::generate_references -- --ignored --nocapture";

/// Taylor references: terms per step and step ρ·SHRINK (ρ the estimated radius of
/// convergence), and the independent check run (other order, step, precision).
const TAYLOR: (usize, f64) = (40, 0.135);
const TAYLOR_CHECK: (usize, f64, usize) = (30, 0.08, PREC + 64);

/// Significant digits stored of a high-precision value (cut, not rounded: ≤ 1e−24 relative).
const DIGITS: usize = 25;

/// `x` (a decimal "d.ddd…e±x") cut to `n` significant digits.
fn significant(x: &str, n: usize) -> String {
    let (mantissa, exponent) = x.split_once('e').unwrap_or((x, "0"));
    let mut out = String::new();
    let mut count = 0;
    for ch in mantissa.chars() {
        if ch.is_ascii_digit() {
            if count == n {
                continue;
            }
            count += 1;
        }
        out.push(ch);
    }
    format!("{out}e{exponent}")
}

/// JSON with objects one key a line and arrays of numbers or strings on one line (one state
/// a line).
pub fn render(v: &Value, indent: usize) -> String {
    let pad = " ".repeat(indent + 2);
    match v {
        Value::Object(map) => {
            let body: Vec<String> = map
                .iter()
                .map(|(k, v)| {
                    format!(
                        "{pad}{}: {}",
                        Value::String(k.clone()),
                        render(v, indent + 2)
                    )
                })
                .collect();
            format!("{{\n{}\n{}}}", body.join(",\n"), " ".repeat(indent))
        }
        Value::Array(items) if items.iter().any(|x| x.is_array() || x.is_object()) => {
            let body: Vec<String> = items
                .iter()
                .map(|x| format!("{pad}{}", render(x, indent + 2)))
                .collect();
            format!("[\n{}\n{}]", body.join(",\n"), " ".repeat(indent))
        }
        Value::Array(items) => {
            let body: Vec<String> = items.iter().map(|x| x.to_string()).collect();
            format!("[{}]", body.join(", "))
        }
        other => other.to_string(),
    }
}

/// One stored reference.
pub struct Stored {
    pub hash: String,
    pub method: String,
    pub accuracy: f64,
    pub t: Vec<f64>,
    pub y: Vec<Vec<f64>>,
    /// f(y) (Taylor references only).
    pub dy: Option<Vec<Vec<f64>>>,
}

fn parse_states(v: &Value) -> Vec<Vec<f64>> {
    v.as_array()
        .expect("array of states")
        .iter()
        .map(|s| {
            s.as_array()
                .expect("a state")
                .iter()
                .map(|x| {
                    x.as_str()
                        .expect("decimal string")
                        .parse()
                        .expect("a number")
                })
                .collect()
        })
        .collect()
}

/// The stored references by case name.
///
/// # Panics
/// If the file is missing or malformed.
pub fn load() -> BTreeMap<String, Stored> {
    let text = std::fs::read_to_string(PATH)
        .unwrap_or_else(|e| panic!("{PATH}: {e}; generate it with `{COMMAND}`"));
    let root: Value = serde_json::from_str(&text).expect("valid JSON");
    let mut out = BTreeMap::new();
    for (name, v) in root["cases"].as_object().expect("cases") {
        let t = v["t"]
            .as_array()
            .expect("t")
            .iter()
            .map(|x| x.as_str().expect("t string").parse().expect("t number"))
            .collect();
        out.insert(
            name.clone(),
            Stored {
                hash: v["hash"].as_str().expect("hash").to_string(),
                method: v["method"].as_str().expect("method").to_string(),
                accuracy: v["accuracy"].as_f64().expect("accuracy"),
                t,
                y: parse_states(&v["y"]),
                dy: v.get("dy").map(parse_states),
            },
        );
    }
    out
}

/// max over components and states of |a − b| / (1 + |b|).
pub fn agreement(a: &[Vec<f64>], b: &[Vec<f64>]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(a, b)| {
            a.iter()
                .zip(b)
                .map(|(x, y)| (x - y).abs() / (1.0 + y.abs()))
        })
        .fold(0.0, f64::max)
}

fn f64_strings(ys: &[Vec<f64>]) -> Value {
    ys.iter()
        .map(|y| y.iter().map(|v| format!("{v:.20e}")).collect::<Vec<_>>())
        .collect()
}

/// The reference of a Taylor case: the states, as decimal strings, f(y), the steps.
fn taylor_reference(case: &Case, order: usize, shrink: f64, prec: usize) -> TaylorRun {
    let Reference::Taylor { rhs, x0 } = case.reference else {
        unreachable!()
    };
    let d = case.y0.len();
    let mut hp = Hp::new(prec);
    let x = x0(&mut hp, &case.y0);
    let ts = case
        .t_eval
        .as_ref()
        .expect("a stored reference needs t_eval");
    let (states, steps) = taylor(&hp, rhs, &x, case.span.0, ts, order, shrink);
    let mut decimal = Vec::new();
    let mut dy = Vec::new();
    for s in &states {
        let dec: Vec<String> = s[..d]
            .iter()
            .map(|v| significant(&hp.decimal(v), DIGITS))
            .collect();
        decimal.push(dec);
        let series: Vec<Vec<_>> = s.iter().map(|v| vec![v.clone()]).collect();
        let f = rhs(&hp, &series, &mut Vec::new(), 0);
        dy.push(
            f[..d]
                .iter()
                .map(|v| format!("{:.20e}", hp.decimal(v).parse::<f64>().unwrap()))
                .collect::<Vec<_>>(),
        );
    }
    TaylorRun {
        states: states
            .into_iter()
            .map(|mut s| {
                s.truncate(d);
                s
            })
            .collect(),
        decimal,
        dy,
        steps,
    }
}

struct TaylorRun {
    states: Vec<Vec<BigFloat>>,
    decimal: Vec<Vec<String>>,
    dy: Vec<Vec<String>>,
    steps: usize,
}

/// [`agreement`] in high precision.
fn agreement_hp(hp: &Hp, a: &[Vec<BigFloat>], b: &[Vec<BigFloat>]) -> f64 {
    let one = hp.f(1.0);
    a.iter()
        .zip(b)
        .flat_map(|(a, b)| a.iter().zip(b))
        .map(|(x, y)| {
            let diff = hp.sub(x, y);
            to_f64(&hp.div(&diff, &hp.add(&one, y))).abs()
        })
        .fold(0.0, f64::max)
}

/// The stored file as JSON, if there is one that parses.
pub fn load_json() -> Option<Value> {
    let text = std::fs::read_to_string(PATH).ok()?;
    serde_json::from_str(&text).ok()
}

/// Generates the stored references (see [`COMMAND`]): every one, or with `previous` (the
/// file as it is) only those missing or stale there, keeping the others as they are.
pub fn generate(cases: &[Case], previous: Option<&Value>) -> Value {
    let mut entries = serde_json::Map::new();
    for case in cases {
        let current = previous
            .and_then(|p| p["cases"].get(case.name))
            .filter(|old| old["hash"].as_str() == Some(case.hash().as_str()));
        if let Some(old) = current {
            eprintln!("{}: current, kept", case.name);
            entries.insert(case.name.to_string(), old.clone());
            continue;
        }
        let start = std::time::Instant::now();
        let ts = case.t_eval.clone().unwrap_or_default();
        let entry = match case.reference {
            Reference::Exact(_) => continue,
            Reference::Taylor { .. } => {
                let (order, shrink) = TAYLOR;
                let main = taylor_reference(case, order, shrink, PREC);
                let (order2, shrink2, prec2) = TAYLOR_CHECK;
                let check = taylor_reference(case, order2, shrink2, prec2);
                let accuracy = agreement_hp(&Hp::new(prec2), &main.states, &check.states);
                let method = format!(
                    "Taylor series in {PREC}-bit arithmetic (astro-float), {order} terms, step \
                     {shrink} x the estimated radius of convergence, {} steps; checked against \
                     {order2} terms, step {shrink2} x radius, {prec2} bits ({} steps)",
                    main.steps, check.steps
                );
                json!({
                    "hash": case.hash(),
                    "method": method,
                    "accuracy": accuracy,
                    "t": ts.iter().map(|t| format!("{t:.20e}")).collect::<Vec<_>>(),
                    "y": main.decimal,
                    "dy": main.dy,
                })
            }
            Reference::Runs => {
                let (values, method, accuracy) = runs::generate(case);
                json!({
                    "hash": case.hash(),
                    "method": method,
                    "accuracy": accuracy,
                    "t": ts.iter().map(|t| format!("{t:.20e}")).collect::<Vec<_>>(),
                    "y": f64_strings(&values),
                })
            }
        };
        eprintln!(
            "{}: accuracy {:.3e} ({:.1} s): {}",
            case.name,
            entry["accuracy"].as_f64().unwrap(),
            start.elapsed().as_secs_f64(),
            entry["method"].as_str().unwrap()
        );
        entries.insert(case.name.to_string(), entry);
    }
    json!({
        "note": format!("DO NOT EDIT: generated by `{COMMAND}` (tests/it/common_suite/stored.rs)"),
        "cases": entries,
    })
}

/// The two-run reference of the large NLS: EC8P at a tiny fixed step (stored) against EC8P at
/// twice the step and split-step Fourier of order 8. All take the linear flow from the f64
/// system's circulant operator (its FFT eigenvalues), as the solve does.
#[cfg(feature = "baselines")]
mod runs {
    use ecr::baselines::split_step::SplitStep;
    use ecr::problems::Nls;
    use ecr::runtime::integrate::Integrator;
    use ecr::runtime::stepper::EcStepper;

    use super::super::{Case, NLS_SOLITONS_N};
    use super::agreement;

    /// Steps of h from t0 to each output time (multiples of h).
    fn run(
        mut step: impl FnMut(&mut [f64]),
        y0: &[f64],
        t0: f64,
        h: f64,
        ts: &[f64],
    ) -> Vec<Vec<f64>> {
        let mut y = y0.to_vec();
        let mut t = t0;
        ts.iter()
            .map(|&te| {
                let n = (te - t) / h;
                assert!(n.fract() == 0.0, "{te} is not on the grid of h = {h}");
                for _ in 0..n as usize {
                    step(&mut y);
                }
                t = te;
                y.clone()
            })
            .collect()
    }

    fn stepper(mut m: impl Integrator) -> impl FnMut(&mut [f64]) {
        move |y| {
            m.step_state(y).expect("a reference step");
        }
    }

    pub fn generate(case: &Case) -> (Vec<Vec<f64>>, String, f64) {
        let ts = case.t_eval.as_ref().unwrap();
        let (t0, y0) = (case.span.0, &case.y0);
        let nls = || Nls::new(NLS_SOLITONS_N).unwrap().system().unwrap();
        let ec = |h: f64| run(stepper(EcStepper::new(nls(), 8, h).unwrap()), y0, t0, h, ts);
        let (h_ec, h_peer, peer, other) = match case.name {
            "nls_solitons" => {
                let h = 1.0 / 256.0;
                let ys = run(stepper(SplitStep::nls(nls(), 8, h).unwrap()), y0, t0, h, ts);
                (1.0 / 512.0, h, "split-step Fourier of order 8", ys)
            }
            other => panic!("no two-run reference for {other}"),
        };
        let main = ec(h_ec);
        let half = ec(2.0 * h_ec);
        let peer_gap = agreement(&other, &main);
        let self_gap = agreement(&half, &main);
        let method = format!(
            "EC8P (f64) with h = {h_ec:e}; agrees with {peer} at h = {h_peer:e} to {peer_gap:.2e} \
             and with EC8P at h = {:e} to {self_gap:.2e}",
            2.0 * h_ec
        );
        (main, method, peer_gap.max(self_gap))
    }
}

#[cfg(not(feature = "baselines"))]
mod runs {
    pub fn generate(_: &super::Case) -> (Vec<Vec<f64>>, String, f64) {
        panic!("the two-run references need the peers of the `baselines` feature")
    }
}
