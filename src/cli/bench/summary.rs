//! `summary.md`: per problem and target accuracy, the cheapest method, the best of this
//! project's methods (run-time and `ecr_method!` steppers) against the best peer, and every
//! method's cost (log CPU interpolated linearly in log error between measured points; set-up
//! counted), with each method's round-off floor; for this project's series, the CPU time over
//! the cost of their own evaluations of g, and the run-time stepper's time over the macro
//! stepper's at equal r and h.

use super::c_peer::{Form, RotationC};
use super::scaling::{self, Scaling};
use super::series::{Family, K, OMEGA, solver};
use super::startup::{self, Startup};
use super::sweep::{
    Config, DopOverhead, ERROR_CEILING, ERROR_FLOOR, G_REPEATS, LongRun, Point, ProblemRun, Results,
};
use std::fmt::Write;

/// Target accuracies (global error).
pub const TARGETS: [f64; 4] = [1e-6, 1e-8, 1e-10, 1e-12];

/// A target closer than this factor to the reference's estimated error is not assessed.
pub const REFERENCE_MARGIN: f64 = 10.0;

/// What a series needs to reach a target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Cost {
    /// CPU seconds (set-up included), and whether that is only an upper bound (the cheapest
    /// measured point is already more accurate).
    Reached { cpu: f64, bound: bool },
    /// The target lies below the series' round-off floor: a point there would be luck.
    BelowFloor(f64),
    /// No measured point reaches the target.
    NotReached,
}

impl Cost {
    fn cpu(self) -> Option<f64> {
        match self {
            Cost::Reached { cpu, .. } => Some(cpu),
            _ => None,
        }
    }
}

/// The round-off floor of a series (its points in sweep order, h or tol decreasing): once a
/// refinement no longer halves an error below 1e−7, the error has stopped following the
/// method's order; the floor is the largest error from that point on.
pub fn floor(points: &[&Point]) -> Option<f64> {
    let i = (1..points.len())
        .find(|&i| points[i].error >= 0.5 * points[i - 1].error && points[i].error < 1e-7)?;
    Some(points[i - 1..].iter().map(|p| p.error).fold(0.0, f64::max))
}

/// CPU seconds a series needs to reach global error ≤ `target`.
pub fn cost_to_reach(points: &[&Point], target: f64) -> Cost {
    if let Some(f) = floor(points)
        && target < f
    {
        return Cost::BelowFloor(f);
    }
    let mut pts: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| p.cpu > 0.0 && p.error.is_finite())
        .map(|p| (p.cpu, p.error))
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let Some(i) = pts.iter().position(|p| p.1 <= target) else {
        return Cost::NotReached;
    };
    if i == 0 {
        return Cost::Reached {
            cpu: pts[0].0,
            bound: true,
        };
    }
    let (c0, e0) = pts[i - 1];
    let (c1, e1) = pts[i];
    if e1 <= 0.0 {
        return Cost::Reached {
            cpu: c1,
            bound: false,
        };
    }
    let (l0, l1, lt) = (e0.log10(), e1.log10(), target.log10());
    let t = ((l0 - lt) / (l0 - l1)).clamp(0.0, 1.0);
    Cost::Reached {
        cpu: 10f64.powf(c0.log10() + t * (c1.log10() - c0.log10())),
        bound: false,
    }
}

fn series_points<'a>(run: &'a ProblemRun, label: &str) -> Vec<&'a Point> {
    run.points.iter().filter(|p| p.series == label).collect()
}

/// One series' cost at a target.
pub struct Entry<'a> {
    pub label: &'a str,
    pub family: Family,
    pub cost: Cost,
}

/// Cost of every series of `run` at `target`.
pub fn costs(run: &ProblemRun, target: f64) -> Vec<Entry<'_>> {
    run.series
        .iter()
        .map(|(label, _, family)| Entry {
            label,
            family: *family,
            cost: cost_to_reach(&series_points(run, label), target),
        })
        .collect()
}

/// The cheapest entry accepted by `keep`: (label, cpu, bound).
fn cheapest<'a>(
    entries: &[Entry<'a>],
    keep: impl Fn(&Entry) -> bool,
) -> Option<(&'a str, f64, bool)> {
    entries
        .iter()
        .filter(|e| keep(e))
        .filter_map(|e| match e.cost {
            Cost::Reached { cpu, bound } => Some((e.label, cpu, bound)),
            _ => None,
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// A ratio to two significant digits (0.63, 0.028, 1.5e-3).
fn ratio(x: f64) -> String {
    if x >= 0.095 {
        format!("{x:.2}")
    } else if x >= 0.001 {
        format!("{:.*}", (1.0 - x.log10().floor()) as usize, x)
    } else {
        format!("{x:.1e}")
    }
}

fn secs(x: f64, bound: bool) -> String {
    format!("{}{x:.2e} s", if bound { "≤ " } else { "" })
}

fn named(c: Option<(&str, f64, bool)>) -> String {
    c.map_or_else(
        || "none reaches it".to_string(),
        |(l, x, b)| format!("{l} {}", secs(x, b)),
    )
}

/// The Markdown summary of what was run; `start` is the process start-up measured apart (run
/// with the work–precision part).
pub fn markdown(
    c: &Config,
    r: Option<&Results>,
    sc: Option<&Scaling>,
    start: Option<&Result<Startup, String>>,
    seconds: f64,
) -> String {
    let mut out = String::new();
    let w = &mut out;
    let _ = writeln!(
        w,
        "# ecr bench{}\n\nComputed in {seconds:.1} s. {}\n",
        if c.quick { " (--quick)" } else { "" },
        crate::cli::provenance::line()
    );
    if c.quick {
        let _ = writeln!(
            w,
            "**--quick**: tiny intervals, sizes and two points per series — the numbers below \
             only exercise the pipeline; they are not the benchmark.\n"
        );
    }
    if let Some(r) = r {
        work_precision(w, c, r);
    }
    if let Some(s) = start {
        startup_section(w, s);
    }
    if let Some(s) = sc {
        scaling_section(w, s);
    }
    out
}

fn scaling_section(w: &mut String, s: &Scaling) {
    let _ = writeln!(
        w,
        "## Scaling of the step cost with the dimension\n\n\
         EC{r}P (r = s = {r}, h = {h}, stage equations iterated to convergence) on the cubic NLS \
         with the linear part as a skew pair of a circulant applied by FFT: 1D (`Nls`, N points, \
         d = 2N) and 2D (`Nls2d`, n × n points, d = 2n², Laplacian D₂ ⊗ I + I ⊗ D₂ by 2D FFT). \
         Seconds per step: median of {rep} run(s) of at least {min} s or {max} steps each \
         (t ≤ {t} per run), after one warm-up step; the φ-bank is built once per run (setup, not timed in the step cost). Data: \
         `scaling.csv`; figure `scaling` (.png, .svg).\n",
        r = scaling::R,
        h = scaling::H,
        rep = s.repeats,
        min = s.min_run,
        max = scaling::MAX_STEPS,
        t = scaling::MAX_STEPS as f64 * scaling::H,
    );
    let _ = writeln!(
        w,
        "| case | grid | d | s/step | sweeps/step | s/step/sweep/(d log₂ d) | relative energy \
         change | setup s |\n|---|---|---|---|---|---|---|---|"
    );
    for p in &s.points {
        let d = p.d as f64;
        let _ = writeln!(
            w,
            "| {} | {} | {} | {:.3e} | {:.2} | {:.2e} | {:.1e} | {:.2e} |",
            p.case,
            p.grid,
            p.d,
            p.seconds_per_step,
            p.sweeps_per_step,
            p.seconds_per_step / p.sweeps_per_step.max(1.0) / (d * d.log2()),
            p.energy_error,
            p.setup_seconds
        );
    }
    let _ = writeln!(
        w,
        "\nFitted exponents (least squares on log–log; target: d log d, i.e. exponent ≈ 1 with \
         the exponent of cost / (d log₂ d) ≈ 0):\n"
    );
    for f in &s.fits {
        let _ = writeln!(
            w,
            "- {} ({} sizes): cost ∝ d^{:.3}; cost / (d log₂ d) ∝ d^{:.3}",
            f.what, f.points, f.exponent, f.exponent_over_dlogd
        );
    }
    let _ = writeln!(w);
}

fn work_precision(w: &mut String, c: &Config, r: &Results) {
    let settings = solver();
    let _ = writeln!(w, "## Work–precision\n");
    let _ = writeln!(
        w,
        "CPU time is the **wall-clock time of a single-threaded run, set-up included**: \
         building the method (coefficient tables, φ-/kernel banks, FFT plans) and integrating \
         over [0, T], the fastest of {} run(s) per point, timed in rounds that run every \
         point of the problem once (a slow phase of the machine falls on every method \
         alike); the set-up alone is reported too \
         (`setup_seconds` in the CSV). Global error: max-norm of y(T) − y_ref(T). Energy \
         error: max over every step of |H(y_n) − H(y_0)| / |H(y_0)|, measured in a separate \
         untimed run. Implicit methods (ECrP, TCrP, RKEPC2, Gauss, AVF, ExpAVF) iterate \
         their stage equations to convergence (estimated error ≤ {:e} or round-off \
         stagnation), starting from the previous step's continuous solution extrapolated to \
         the new nodes. \"EC{{r}}P\" is the run-time-r stepper, what `ecr run` uses \
         (`SizedEcStepper`: for d = 2 and s = r the run-time kernel on fixed-size buffers, \
         otherwise `EcStepper`); \"EC{{r}}P macro\" the fixed-order stepper of \
         `ecr_method!(r = …)` (d = 2: `Ec{{r}}<_, 2>` with a `DenseStatic` operator and g a \
         closure; NLS: `Ec{{r}}Dyn`). Each series halves h from its largest step size until \
         the error is ≤ {ERROR_FLOOR:e}, stagnates at round-off, a run exceeds {} s or {} points were recorded; points with \
         error > {ERROR_CEILING:e} or failures are skipped (listed per problem). DOP853 is \
         one call of `ode_solvers` over [0, T] (fixed-size state, sparse output) per \
         rtol = atol from 1e-4 to 1e-15. Cost to reach a target: log CPU interpolated \
         linearly in log error between the two measured points around it (≤: the cheapest \
         measured point is already more accurate, an upper bound). **Round-off floor**: once \
         a refinement no longer halves an error below 1e-7, the largest error from there on; \
         a target below a method's floor counts as not reached by it, whatever a lucky point \
         shows. Targets within a factor {REFERENCE_MARGIN} of the reference's estimated error \
         are not assessed.\n",
        c.repeats, settings.tolerance, c.budget, c.attempts
    );
    let _ = writeln!(
        w,
        "**Integration, not process start-up.** Every time here is measured inside this one \
         process around set-up and integration: none includes what a command-line run pays \
         besides (loading the executable, parsing arguments, writing its output), which is \
         measured apart under \"Process start-up\" below. The Duffing peers \"Rot{{p}} C\" and \
         \"Rot{{p}} C plain\" are the rotation splitting written in C for speed \
         (`benches/c/rotation_splitting_duffing.c`, compiled into this executable) and called \
         once over [0, T], so ours against them is loop against loop, as against every other \
         peer; \"Rot{{p}}\" is the same method as the library's `RotationSplitting`, stepped by \
         `integrate`.\n"
    );
    if r.problems.len() < 3 {
        let ids: Vec<&str> = r.problems.iter().map(|p| p.id).collect();
        let _ = writeln!(
            w,
            "Problems run (`--problem`): {}.{}\n",
            ids.join(", "),
            if r.long.is_none() {
                " The equal-CPU energy comparison and DOP853's overhead (Duffing) were not run."
            } else {
                ""
            }
        );
    }
    let _ = writeln!(
        w,
        "### Headline: this project's best against the best peer\n"
    );
    let _ = writeln!(
        w,
        "Per problem and target: the cheapest ECrP/TCrP (either stepper) against the cheapest \
         peer (every other method), ratio = CPU(ours) / CPU(peer) (< 1: ours is faster).\n"
    );
    let _ = writeln!(
        w,
        "| problem | target | best ours | best peer | ours / peer | best run-time | best macro |\n|---|---|---|---|---|---|---|"
    );
    for p in &r.problems {
        for t in TARGETS {
            if !assessed(p, t) {
                continue;
            }
            let all = costs(p, t);
            let ours = cheapest(&all, |e| e.family.is_ours());
            let peer = cheapest(&all, |e| e.family == Family::Peer);
            let rt = cheapest(&all, |e| e.family == Family::Runtime);
            let mac = cheapest(&all, |e| e.family == Family::Macro);
            let ratio = match (ours, peer) {
                (Some((_, a, _)), Some((_, b, _))) => format!("**{}**", ratio(a / b)),
                (Some(_), None) => "no peer reaches it".to_string(),
                (None, Some(_)) => "ours do not reach it".to_string(),
                (None, None) => "-".to_string(),
            };
            let _ = writeln!(
                w,
                "| {} | {t:e} | {} | {} | {ratio} | {} | {} |",
                p.id,
                named(ours),
                named(peer),
                named(rt),
                named(mac)
            );
        }
    }
    let _ = writeln!(w);
    if let Some(d) = &r.dop {
        dop_paragraph(w, d);
    }
    if let Some(l) = &r.long {
        long_paragraph(w, l);
    }
    for p in &r.problems {
        problem_section(w, p);
    }
    if let Some(p) = r.problems.iter().find(|p| p.id == "duffing") {
        rotation_loops(w, p);
    }
}

/// CPU(a) / CPU(b) at the step sizes both series have (relative 1e−9): (count, median,
/// smallest, largest).
pub fn ratios_at_equal_h(a: &[&Point], b: &[&Point]) -> Option<(usize, f64, f64, f64)> {
    let mut v: Vec<f64> = a
        .iter()
        .filter_map(|x| {
            let y = b.iter().find(|y| (x.h - y.h).abs() <= 1e-9 * x.h.abs())?;
            (x.cpu > 0.0 && y.cpu > 0.0).then(|| x.cpu / y.cpu)
        })
        .collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let median = if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    };
    Some((n, median, v[0], v[n - 1]))
}

/// Duffing: the rotation splitting in C against the library's `RotationSplitting`, and its
/// plain form against its accurate one, at equal h (the same method, so the same error up to
/// round-off: the time ratio is the implementation's).
fn rotation_loops(w: &mut String, p: &ProblemRun) {
    let find = |prefix: String| {
        p.series
            .iter()
            .find(|s| s.0.starts_with(&format!("{prefix} (")))
            .map(|s| s.0.as_str())
    };
    let mut rows = Vec::new();
    for order in [2, 4, 6, 8] {
        let (Some(lib), Some(c), Some(plain)) = (
            find(format!("Rot{order}")),
            find(format!("Rot{order} C")),
            find(format!("Rot{order} C plain")),
        ) else {
            continue;
        };
        let cell = |a: &str, b: &str| {
            ratios_at_equal_h(&series_points(p, a), &series_points(p, b)).map_or_else(
                || "-".to_string(),
                |(n, med, lo, hi)| format!("{} ({}–{}, {n} h)", ratio(med), ratio(lo), ratio(hi)),
            )
        };
        rows.push(format!(
            "| {order} | {} | {} | {} |",
            cell(c, lib),
            cell(plain, c),
            cell(plain, lib)
        ));
    }
    if rows.is_empty() {
        return;
    }
    let fma = RotationC::new(OMEGA, K, 8, 0.1, Form::Accurate).map_or_else(
        |e| format!("could not be set up ({e})"),
        |m| {
            if m.uses_fma() {
                "ran with fused multiply-add, which this processor has".to_string()
            } else {
                "ran without fused multiply-add, which this processor or build lacks".to_string()
            }
        },
    );
    let _ = writeln!(
        w,
        "### Duffing: the rotation splitting in C against the library's, loop against loop\n\n\
         CPU time (set-up included) at equal h, median over the step sizes both series have \
         (smallest–largest, count); < 1: the first is faster. \"C\": the accurate form \
         (determinant 1 to far below an ulp, as `RotationSplitting`; here it {fma}); \"C \
         plain\": the plain 2 × 2 rotation, one dependent operation less per stage, whose \
         amplitude drifts by about an ulp per rotation (its round-off floor in the table \
         above).\n\n\
         | order | Rot{{p}} C / Rot{{p}} | Rot{{p}} C plain / Rot{{p}} C | Rot{{p}} C plain / Rot{{p}} \
         |\n|---|---|---|---|"
    );
    for row in rows {
        let _ = writeln!(w, "{row}");
    }
    let _ = writeln!(w);
}

fn startup_section(w: &mut String, s: &Result<Startup, String>) {
    let _ = writeln!(w, "## Process start-up (in none of the times above)\n");
    match s {
        Ok(s) => {
            let _ = writeln!(
                w,
                "This executable run as a child process, wall-clock time from spawning it to \
                 its exit, the fastest of {} interleaved runs each: `ecr --version` (start-up \
                 alone) {:.2} ms; `ecr {}` (start-up, one EC6P set-up and step, its JSON \
                 report) {:.2} ms. A program that integrates in its own process pays its \
                 start-up once: compare integration with the tables above, start-up with \
                 these.\n",
                s.runs,
                s.version * 1e3,
                startup::ONE_STEP.join(" "),
                s.one_step * 1e3
            );
        }
        Err(e) => {
            let _ = writeln!(w, "Not measured: {e}.\n");
        }
    }
}

fn dop_paragraph(w: &mut String, d: &DopOverhead) {
    let _ = writeln!(
        w,
        "DOP853's cost per evaluation of f (Duffing ω = 20, T = {}, rtol = atol = {:e}; \
         fastest of several interleaved runs): called directly (a user's own \
         `ode_solvers::System` with an `SVector<f64, 2>` state, f written out) {:.1} ns ({} \
         evaluations); through `Dop853` with the same f (A a static 2 × 2, g written out) \
         {:.1} ns, ratio {:.2}; through `Dop853` as the DOP853 series calls it (g the \
         problem's `Duffing::nonlinear`) {:.1} ns ({} evaluations), ratio {:.2}.\n",
        d.t_end,
        d.tol,
        d.direct_ns_per_eval,
        d.direct_evals,
        d.same_f_ns_per_eval,
        d.same_f_ns_per_eval / d.direct_ns_per_eval,
        d.wrapper_ns_per_eval,
        d.wrapper_evals,
        d.wrapper_ns_per_eval / d.direct_ns_per_eval
    );
}

fn long_paragraph(w: &mut String, l: &LongRun) {
    let _ = writeln!(
        w,
        "Same CPU budget, Duffing ω = 20 over T = {}: {} (h = {}) takes {:.3} s with max \
         energy error {:.2e}; DOP853 (one call, rtol = atol = {:.2e}, chosen by bisection \
         over log tol so that its CPU time matches: {}) takes {:.3} s with max energy error \
         {:.2e}: DOP853 / ECrP energy error = {:.2e}.\n",
        l.t_end,
        l.ec_label,
        l.ec_h,
        l.ec_cpu,
        l.ec_energy,
        l.dop_tol,
        l.search
            .iter()
            .map(|(t, c)| format!("tol {t:.1e} → {c:.3} s"))
            .collect::<Vec<_>>()
            .join(", "),
        l.dop_cpu,
        l.dop_energy,
        l.dop_energy / l.ec_energy,
    );
}

/// Whether a target is assessed on this problem (far enough above the reference's error).
fn assessed(p: &ProblemRun, target: f64) -> bool {
    target >= REFERENCE_MARGIN * p.reference_error
}

fn family_name(f: Family) -> &'static str {
    match f {
        Family::Runtime => "ours, run-time",
        Family::Macro => "ours, macro",
        Family::Peer => "peer",
    }
}

fn problem_section(w: &mut String, p: &ProblemRun) {
    let _ = writeln!(w, "### {}\n", p.title);
    let _ = writeln!(
        w,
        "Interval [0, {}]. Reference: {} (its estimated error: {:.1e}). Data: `{}.csv`; \
         figures `{}-error` and `{}-energy` (.png, .svg).\n",
        p.t_end, p.reference, p.reference_error, p.id, p.id, p.id
    );
    let targets: Vec<f64> = TARGETS
        .iter()
        .copied()
        .filter(|&t| assessed(p, t))
        .collect();
    let all: Vec<_> = targets.iter().map(|&t| costs(p, t)).collect();
    for (ti, &t) in targets.iter().enumerate() {
        let _ = writeln!(
            w,
            "- target {t:e}: cheapest {}; best ours {}; best peer {}",
            named(cheapest(&all[ti], |_| true)),
            named(cheapest(&all[ti], |e| e.family.is_ours())),
            named(cheapest(&all[ti], |e| e.family == Family::Peer)),
        );
    }
    for t in TARGETS.iter().filter(|&&t| !assessed(p, t)) {
        let _ = writeln!(
            w,
            "- target {t:e}: not assessed (within {REFERENCE_MARGIN}× the reference's error)"
        );
    }
    let _ = writeln!(
        w,
        "\nCPU time (set-up included) to reach each target and, in parentheses, its ratio to \
         the cheapest method's; \"floor\": below the method's round-off floor. Set-up: the \
         range of the fastest set-up time over the method's points.\n"
    );
    let _ = write!(w, "| method | kind | round-off floor | set-up s |");
    for t in &targets {
        let _ = write!(w, " {t:e} |");
    }
    let _ = write!(w, "\n|---|---|---|---|");
    for _ in &targets {
        let _ = write!(w, "---|");
    }
    let _ = writeln!(w);
    for (i, (label, _, family)) in p.series.iter().enumerate() {
        let pts = series_points(p, label);
        let fl = floor(&pts).map_or_else(|| "-".to_string(), |f| format!("{f:.1e}"));
        let (lo, hi) = pts.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), q| {
            (lo.min(q.setup), hi.max(q.setup))
        });
        let setup = if pts.is_empty() {
            "-".to_string()
        } else {
            format!("{lo:.1e}–{hi:.1e}")
        };
        let _ = write!(w, "| {label} | {} | {fl} | {setup} |", family_name(*family));
        for per_target in &all {
            let best = per_target
                .iter()
                .filter_map(|e| e.cost.cpu())
                .fold(f64::INFINITY, f64::min);
            let _ = match per_target[i].cost {
                Cost::Reached { cpu, bound } => {
                    write!(w, " {} (×{}) |", secs(cpu, bound), ratio(cpu / best))
                }
                Cost::BelowFloor(_) => write!(w, " floor |"),
                Cost::NotReached => write!(w, " not reached |"),
            };
        }
        let _ = writeln!(w);
    }
    g_cost_table(w, p, &targets);
    runtime_over_macro(w, p);
    if !p.notes.is_empty() {
        let _ = writeln!(w, "\nSkipped points:\n");
        for n in &p.notes {
            let _ = writeln!(w, "- {n}");
        }
    }
    let _ = writeln!(w);
}

/// Points nearer a target than this factor (in error) count for it in the g-cost table: a
/// series halves h, so an order-2r method (r ≤ 6) has a point within a factor 2^r ≤ 64 of any
/// target inside its range.
pub const NEAR: f64 = 100.0;

/// The point whose error is nearest `target` (in log error), if within a factor [`NEAR`].
pub fn nearest<'a>(points: &[&'a Point], target: f64) -> Option<&'a Point> {
    let dist = |p: &Point| (p.error / target).log10().abs();
    points
        .iter()
        .copied()
        .filter(|p| p.error > 0.0 && p.error.is_finite() && dist(p) <= NEAR.log10())
        .min_by(|a, b| dist(a).total_cmp(&dist(b)))
}

/// A multiple to about three significant digits: 2.13×, 21.3×, 213×.
fn times(x: f64) -> String {
    if x < 10.0 {
        format!("{x:.2}×")
    } else if x < 100.0 {
        format!("{x:.1}×")
    } else {
        format!("{x:.0}×")
    }
}

/// Per series of ours and target: its CPU time over its own g-evaluation cost at the point
/// nearest the target.
fn g_cost_table(w: &mut String, p: &ProblemRun, targets: &[f64]) {
    let mut rows = Vec::new();
    for (label, _, family) in p.series.iter().filter(|s| s.2.is_ours()) {
        let pts = series_points(p, label);
        let cells: Vec<Option<String>> = targets
            .iter()
            .map(|&t| {
                let q = nearest(&pts, t)?;
                let g = q.g_seconds.filter(|&g| g > 0.0)?;
                Some(format!(
                    "{} ({}) at {:.1e}, h = {:.2e}",
                    times(q.cpu / g),
                    times((q.cpu - q.setup).max(0.0) / g),
                    q.error,
                    q.h
                ))
            })
            .collect();
        if cells.iter().any(Option::is_some) {
            rows.push((label, *family, cells));
        }
    }
    if rows.is_empty() {
        return;
    }
    let _ = writeln!(
        w,
        "\n**Time over own g-evaluation cost**: a point's CPU time (set-up included; in \
         parentheses without set-up) over the wall time of as many evaluations of its \
         stepper's own g alone as the run made, on states saved from the run (fastest of \
         {G_REPEATS}); at the point nearest each target (its error, h), if within a factor \
         {NEAR} of it. `g_evals`, `g_seconds` in the CSV.\n"
    );
    let _ = write!(w, "| series | kind |");
    for t in targets {
        let _ = write!(w, " {t:e} |");
    }
    let _ = write!(w, "\n|---|---|");
    for _ in targets {
        let _ = write!(w, "---|");
    }
    let _ = writeln!(w);
    for (label, family, cells) in rows {
        let _ = write!(w, "| {label} | {} |", family_name(family));
        for c in cells {
            let _ = write!(w, " {} |", c.as_deref().unwrap_or("-"));
        }
        let _ = writeln!(w);
    }
}

/// The run-time stepper's CPU time over the macro stepper's at the same r and h.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Paired {
    /// Step sizes both series have a point at.
    pub common: usize,
    pub median: f64,
    /// The largest ratio, and its h.
    pub worst: f64,
    pub worst_h: f64,
}

/// Pairs the points of two series at equal h (relative 1e−9): CPU(run-time) / CPU(macro).
pub fn paired(runtime: &[&Point], macro_: &[&Point]) -> Option<Paired> {
    let mut ratios: Vec<(f64, f64)> = runtime
        .iter()
        .filter_map(|a| {
            let b = macro_
                .iter()
                .find(|b| (a.h - b.h).abs() <= 1e-9 * a.h.abs())?;
            (a.cpu > 0.0 && b.cpu > 0.0).then(|| (a.cpu / b.cpu, a.h))
        })
        .collect();
    if ratios.is_empty() {
        return None;
    }
    let &(worst, worst_h) = ratios.iter().max_by(|x, y| x.0.total_cmp(&y.0))?;
    ratios.sort_by(|x, y| x.0.total_cmp(&y.0));
    let n = ratios.len();
    let median = if n % 2 == 1 {
        ratios[n / 2].0
    } else {
        0.5 * (ratios[n / 2 - 1].0 + ratios[n / 2].0)
    };
    Some(Paired {
        common: n,
        median,
        worst,
        worst_h,
    })
}

/// Per r: `EC{r}P` (run-time) against `EC{r}P macro` at their common step sizes.
fn runtime_over_macro(w: &mut String, p: &ProblemRun) {
    let mut rows = Vec::new();
    for r in 1..=32 {
        let (rt, mac) = (format!("EC{r}P"), format!("EC{r}P macro"));
        let has = |l: &str, f| p.series.iter().any(|s| s.0 == l && s.2 == f);
        if !has(&rt, Family::Runtime) || !has(&mac, Family::Macro) {
            continue;
        }
        if let Some(x) = paired(&series_points(p, &rt), &series_points(p, &mac)) {
            rows.push((r, x));
        }
    }
    if rows.is_empty() {
        return;
    }
    let _ = writeln!(
        w,
        "\n**Run-time / macro**: CPU time of `EC{{r}}P` (run-time stepper) over `EC{{r}}P macro` \
         at the same h, median and largest over the h both have (> 1: the run-time stepper is \
         slower).\n\n| r | common h | median | largest (h) |\n|---|---|---|---|"
    );
    for (r, x) in rows {
        let _ = writeln!(
            w,
            "| {r} | {} | {} | {} (h = {:.2e}) |",
            x.common,
            ratio(x.median),
            ratio(x.worst),
            x.worst_h
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(error: f64, cpu: f64) -> Point {
        Point {
            series: "m".into(),
            r: None,
            s: None,
            h: 1.0,
            tol: None,
            cpu,
            setup: 0.0,
            error,
            energy: 0.0,
            g_evals: None,
            g_seconds: None,
        }
    }

    /// Errors 1e-6, 1e-8, 9e-9, 5e-10 (lucky), 3e-9: the refinement from 1e-8 no longer
    /// halves the error, so the floor is the largest error from 1e-8 on, and the lucky 5e-10
    /// does not make 1e-9 reached.
    #[test]
    fn floor_and_cost_ignore_lucky_points() {
        let pts = [
            point(1e-6, 1.0),
            point(1e-8, 2.0),
            point(9e-9, 4.0),
            point(5e-10, 8.0),
            point(3e-9, 16.0),
        ];
        let refs: Vec<&Point> = pts.iter().collect();
        assert_eq!(floor(&refs), Some(1e-8));
        assert_eq!(cost_to_reach(&refs, 1e-9), Cost::BelowFloor(1e-8));
        assert!(matches!(
            cost_to_reach(&refs, 1e-7),
            Cost::Reached { bound: false, .. }
        ));
        // Without a stall there is no floor: a steadily converging series.
        let clean: Vec<Point> = (0..5)
            .map(|i| point(10f64.powi(-2 * i), 2f64.powi(i)))
            .collect();
        let refs: Vec<&Point> = clean.iter().collect();
        assert_eq!(floor(&refs), None);
        let Cost::Reached { cpu, bound } = cost_to_reach(&refs, 1e-3) else {
            panic!("1e-3 is reached")
        };
        assert!(!bound && cpu > 2.0 && cpu < 4.0, "{cpu}");
    }

    #[test]
    fn nearest_point_is_within_a_factor_near() {
        let pts = [point(3e-5, 1.0), point(2e-7, 2.0), point(1e-9, 4.0)];
        let refs: Vec<&Point> = pts.iter().collect();
        assert_eq!(nearest(&refs, 1e-6).map(|p| p.cpu), Some(2.0));
        assert_eq!(nearest(&refs, 1e-8).map(|p| p.cpu), Some(4.0));
        assert_eq!(nearest(&refs, 3e-11).map(|p| p.cpu), Some(4.0));
        // 1e-9 is a factor 1000 from 1e-12: too far to stand for it.
        assert!(nearest(&refs, 1e-12).is_none());
    }

    #[test]
    fn runtime_over_macro_pairs_equal_h() {
        let at = |h: f64, cpu: f64| Point {
            h,
            ..point(1e-6, cpu)
        };
        let rt = [at(0.1, 3.0), at(0.05, 4.0), at(0.025, 9.0), at(0.0125, 5.0)];
        let mac = [at(0.1, 2.0), at(0.05, 2.0), at(0.025, 3.0)];
        let (a, b): (Vec<&Point>, Vec<&Point>) = (rt.iter().collect(), mac.iter().collect());
        // Ratios 1.5, 2, 3 at the three common h (0.0125 has no macro point).
        assert_eq!(
            paired(&a, &b),
            Some(Paired {
                common: 3,
                median: 2.0,
                worst: 3.0,
                worst_h: 0.025
            })
        );
        assert_eq!(paired(&a, &b[..0]), None);
    }

    #[test]
    fn ratios_at_equal_h_pair_the_common_step_sizes() {
        let at = |h: f64, cpu: f64| Point {
            h,
            ..point(1e-6, cpu)
        };
        let c = [at(0.1, 1.0), at(0.05, 3.0), at(0.025, 2.0), at(0.0125, 9.0)];
        let lib = [at(0.025, 8.0), at(0.05, 6.0), at(0.1, 4.0)];
        let (a, b): (Vec<&Point>, Vec<&Point>) = (c.iter().collect(), lib.iter().collect());
        // Ratios 0.25, 0.5, 0.25 at the three common h (0.0125 has no partner).
        assert_eq!(ratios_at_equal_h(&a, &b), Some((3, 0.25, 0.25, 0.5)));
        assert_eq!(ratios_at_equal_h(&a, &b[..0]), None);
    }

    #[test]
    fn ratios_have_two_significant_digits() {
        assert_eq!(ratio(0.63), "0.63");
        assert_eq!(ratio(1.234), "1.23");
        assert_eq!(ratio(0.028), "0.028");
        assert_eq!(ratio(0.0029), "0.0029");
        assert_eq!(ratio(0.00042), "4.2e-4");
    }
}
