//! `summary.md`: cheapest method per target accuracy (log CPU interpolated linearly in log
//! error between measured points), CPU ratios, and the headline comparisons.

use super::scaling::{self, Scaling};
use super::sweep::{Config, ERROR_CEILING, ERROR_FLOOR, Point, ProblemRun, Results};
use std::fmt::Write;

/// Target accuracies (global error).
pub const TARGETS: [f64; 3] = [1e-6, 1e-8, 1e-10];

/// CPU seconds to reach a target and whether it is only an upper bound (None: not reached).
pub type Cost = Option<(f64, bool)>;

/// CPU seconds a series needs to reach global error ≤ `target`, and whether that is only an
/// upper bound (its cheapest measured point is already below the target). None: not reached.
pub fn cost_to_reach(points: &[&Point], target: f64) -> Cost {
    let mut pts: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| p.cpu > 0.0 && p.error.is_finite())
        .map(|p| (p.cpu, p.error))
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let i = pts.iter().position(|p| p.1 <= target)?;
    if i == 0 {
        return Some((pts[0].0, true));
    }
    let (c0, e0) = pts[i - 1];
    let (c1, e1) = pts[i];
    if e1 <= 0.0 {
        return Some((c1, false));
    }
    let (l0, l1, lt) = (e0.log10(), e1.log10(), target.log10());
    let t = ((l0 - lt) / (l0 - l1)).clamp(0.0, 1.0);
    Some((
        10f64.powf(c0.log10() + t * (c1.log10() - c0.log10())),
        false,
    ))
}

fn series_points<'a>(run: &'a ProblemRun, label: &str) -> Vec<&'a Point> {
    run.points.iter().filter(|p| p.series == label).collect()
}

/// Cost of every series of `run` at `target`.
pub fn costs(run: &ProblemRun, target: f64) -> Vec<(String, &'static str, Cost)> {
    run.series
        .iter()
        .map(|(label, group)| {
            (
                label.clone(),
                *group,
                cost_to_reach(&series_points(run, label), target),
            )
        })
        .collect()
}

/// The cheapest series reaching `target` among those accepted by `keep`.
fn cheapest(
    run: &ProblemRun,
    target: f64,
    keep: impl Fn(&str, &str) -> bool,
) -> Option<(String, f64, bool)> {
    costs(run, target)
        .into_iter()
        .filter(|(l, g, _)| keep(l, g))
        .filter_map(|(l, _, c)| c.map(|(s, b)| (l, s, b)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

fn secs(x: f64, bound: bool) -> String {
    format!("{}{x:.2e} s", if bound { "≤ " } else { "" })
}

/// "ratio (target t): met / missed by factor f".
fn verdict(ratio: f64, target: f64) -> String {
    if ratio <= target {
        format!("**met** (target ≤ {})", fraction(target))
    } else {
        format!(
            "**missed** by a factor {:.2} (target ≤ {})",
            ratio / target,
            fraction(target)
        )
    }
}

fn fraction(x: f64) -> String {
    if x < 1.0 {
        format!("1/{}", (1.0 / x).round())
    } else {
        format!("{x}")
    }
}

/// When `label` never reached `target`: the longest of its finished runs (recorded points:
/// median CPU; too inaccurate runs: that run's seconds), each less accurate than the target,
/// and the best error any of them achieved. Its cost to reach the target exceeds that time,
/// since a fixed-step method's cost grows as h shrinks (DOP853's as tol shrinks).
fn unreached(run: &ProblemRun, label: &str) -> Option<(f64, f64)> {
    let recorded = series_points(run, label)
        .into_iter()
        .map(|p| (p.cpu, p.error));
    let skipped = run
        .attempts
        .iter()
        .filter(|a| a.series == label)
        .map(|a| (a.seconds, a.error));
    recorded.chain(skipped).filter(|(_, e)| e.is_finite()).fold(
        None,
        |acc: Option<(f64, f64)>, (t, e)| {
            Some(acc.map_or((t, e), |(t0, e0)| (t0.max(t), e0.min(e))))
        },
    )
}

#[allow(clippy::too_many_arguments)]
fn ratio_line(
    out: &mut String,
    what: &str,
    ec: &Option<(String, f64, bool)>,
    run: &ProblemRun,
    label: &'static str,
    accuracy: f64,
    target: f64,
) {
    let other = by_label(run, label, accuracy);
    let _ = match (ec, &other) {
        (Some((el, ec, eb)), Some((ol, oc, ob))) => writeln!(
            out,
            "- {what}: {el} {} vs {ol} {} → ratio {:.3} — {}{}",
            secs(*ec, *eb),
            secs(*oc, *ob),
            ec / oc,
            verdict(ec / oc, target),
            if *eb || *ob {
                " (≤: the cheapest measured point was already below the target, so that CPU \
                 time is an upper bound)"
            } else {
                ""
            }
        ),
        (None, _) => writeln!(out, "- {what}: no ECrP run reached the target — **missed**"),
        (Some((el, ec, eb)), None) => match unreached(run, label) {
            Some((t, best)) => writeln!(
                out,
                "- {what}: {el} {}; {label} never reached {accuracy:e} (best error {best:.1e}; its \
                 longest run, {t:.3} s, was still less accurate), so its cost exceeds {t:.3} s \
                 and the ratio is below {:.4} — {}",
                secs(*ec, *eb),
                ec / t,
                verdict(ec / t, target)
            ),
            None => writeln!(
                out,
                "- {what}: {el} {}; {label} finished no run (see the skipped points) — no ratio",
                secs(*ec, *eb)
            ),
        },
    };
}

fn is_ec(label: &str) -> bool {
    label.starts_with("EC") && !label.contains("dense")
}

fn by_label(run: &ProblemRun, label: &'static str, target: f64) -> Option<(String, f64, bool)> {
    cheapest(run, target, |l, _| l == label)
}

/// The Markdown summary of what was run.
pub fn markdown(c: &Config, r: Option<&Results>, sc: Option<&Scaling>, seconds: f64) -> String {
    let mut out = String::new();
    let w = &mut out;
    let _ = writeln!(
        w,
        "# ecr bench{}\n\nComputed in {seconds:.1} s.\n",
        if c.quick { " (--quick)" } else { "" }
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
    let _ = writeln!(w, "## Work–precision\n");
    let _ = writeln!(
        w,
        "CPU time is the **wall-clock time of a single-threaded run** (std::time::Instant around \
         the integration only: building the integrator — coefficient tables, φ-functions — is \
         excluded), the median of {} run(s) per point. Global error: max-norm of y(T) − \
         y_ref(T). Energy error: max over every step of |H(y_n) − H(y_0)| / |H(y_0)|, measured in \
         a separate untimed run. Implicit methods (ECrP, TCrP, RKEPC2, Gauss, AVF, ExpAVF) \
         iterate their stage equations to convergence (estimated error ≤ 1e-15 or round-off \
         stagnation), starting from the previous step's continuous solution extrapolated to \
         the new nodes (`Predictor::Extrapolate`). Each series halves h from its largest step \
         size until the error is ≤ {ERROR_FLOOR:e}, stagnates at round-off, a run exceeds \
         {} s or {} points were recorded; points with error > {ERROR_CEILING:e} or failures \
         are skipped (listed per problem). DOP853 sweeps rtol = atol over 1e-4 … 1e-15 with a \
         fixed macro step. Cost to reach a target: log CPU interpolated linearly in log error \
         between the two measured points around the target (≤: the cheapest measured point is \
         already more accurate, an upper bound).\n",
        c.repeats, c.budget, c.attempts
    );
    // Headlines.
    let _ = writeln!(w, "### Headline comparisons (measured side by side)\n");
    let find = |id: &str| r.problems.iter().find(|p| p.id == id);
    if let Some(d) = find("duffing") {
        let ec = cheapest(d, 1e-10, |l, _| is_ec(l));
        let _ = writeln!(w, "(a) {} at global error 1e-10:\n", d.title);
        ratio_line(w, "best ECrP vs DOP853", &ec, d, "DOP853", 1e-10, 1.0 / 3.0);
        ratio_line(w, "best ECrP vs RKEPC2", &ec, d, "RKEPC2", 1e-10, 1.0 / 5.0);
        let _ = writeln!(w);
    }
    if let Some(n) = find("nls") {
        let ec = cheapest(n, 1e-8, |_, g| g == "ECrP circulant");
        let _ = writeln!(w, "(b) {} at global error 1e-8:\n", n.title);
        ratio_line(
            w,
            "best ECrP (circulant) vs DOP853",
            &ec,
            n,
            "DOP853",
            1e-8,
            1.0 / 3.0,
        );
        let dense = cheapest(n, 1e-8, |_, g| g == "ECrP dense");
        if let (Some((cl, cc, _)), Some((dl, dc, _))) = (&ec, &dense) {
            let _ = writeln!(
                w,
                "- for comparison, {cl} (circulant) {cc:.2e} s vs {dl} {dc:.2e} s: dense / \
                 circulant = {:.1}",
                dc / cc
            );
        }
        let _ = writeln!(w);
    }
    let l = &r.long;
    let ratio = l.dop_energy / l.ec_energy;
    let _ = writeln!(
        w,
        "(c) Same CPU budget, Duffing ω = 20 over T = {}: {} (h = {}) takes {:.3} s with max \
         energy error {:.2e}; DOP853 (macro step {}, rtol = atol = {:.2e}, chosen by bisection \
         over log tol so that its CPU time matches: {}) takes {:.3} s with max energy error \
         {:.2e}. DOP853 / ECrP energy error = {:.2e} — {} (target ≥ 1e4).\n",
        l.t_end,
        l.ec_label,
        l.ec_h,
        l.ec_cpu,
        l.ec_energy,
        l.dop_macro_h,
        l.dop_tol,
        l.search
            .iter()
            .map(|(t, c)| format!("tol {t:.1e} → {c:.3} s"))
            .collect::<Vec<_>>()
            .join(", "),
        l.dop_cpu,
        l.dop_energy,
        ratio,
        if ratio >= 1e4 {
            "**met**".to_string()
        } else {
            format!("**missed** by a factor {:.1}", 1e4 / ratio)
        }
    );
    for p in &r.problems {
        problem_section(w, p);
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
    let all: Vec<_> = TARGETS.iter().map(|&t| costs(p, t)).collect();
    for (ti, &t) in TARGETS.iter().enumerate() {
        let best = all[ti]
            .iter()
            .filter_map(|(l, _, c)| c.map(|(s, b)| (l, s, b)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let _ = match best {
            Some((l, s, b)) => writeln!(w, "- target {t:e}: cheapest **{l}**, {}", secs(s, b)),
            None => writeln!(w, "- target {t:e}: not reached by any method"),
        };
    }
    let _ = writeln!(
        w,
        "\nCPU time to reach each target, and in parentheses its ratio to the cheapest \
         method's (CPU(method) / CPU(cheapest)):\n"
    );
    let _ = write!(w, "| method |");
    for t in TARGETS {
        let _ = write!(w, " {t:e} |");
    }
    let _ = writeln!(w, "\n|---|---|---|---|");
    for (i, (label, _)) in p.series.iter().enumerate() {
        let _ = write!(w, "| {label} |");
        for per_target in &all {
            let best = per_target
                .iter()
                .filter_map(|(_, _, c)| c.map(|x| x.0))
                .fold(f64::INFINITY, f64::min);
            let _ = match per_target[i].2 {
                Some((s, b)) => write!(w, " {} (×{:.2}) |", secs(s, b), s / best),
                None => write!(w, " not reached |"),
            };
        }
        let _ = writeln!(w);
    }
    if !p.notes.is_empty() {
        let _ = writeln!(w, "\nSkipped points:\n");
        for n in &p.notes {
            let _ = writeln!(w, "- {n}");
        }
    }
    let _ = writeln!(w);
}
