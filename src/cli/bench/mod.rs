//! `ecr bench`: work–precision data (CPU time against global error and against energy error)
//! for ECrP / TCrP and the baselines on Duffing (ω = 20), the conservative wind problem and the
//! NLS; the scaling of the step cost with the dimension (1D and 2D NLS, FFT operator); CSV,
//! figures (PNG, SVG) and `summary.md`.
//!
//! Reuses the `ecr reproduce` harness: its problem type, method registry, boxed integrators,
//! output-directory and CSV helpers and plotting code.

mod c_peer;
mod macros;
mod peers;
mod scaling;
mod series;
mod startup;
mod summary;
mod sweep;

use super::UsageError;
use super::output::OutputDir;
use super::reproduce::plots::{Curve, Figure, Panel, REFERENCE_KEY, png, svg};
use super::reproduce::{Csv, num, write_file};
use clap::{Args, ValueEnum};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;
use sweep::{Config, Point, ProblemId, ProblemRun};

/// Arguments of `ecr bench`.
#[derive(Args, Debug)]
#[command(
    after_help = "Writes <problem>.csv, <problem>-error and <problem>-energy (.png, .svg) for \
                  duffing, wind and nls (those of --problem), scaling.csv and scaling (.png, \
                  .svg), and summary.md into --out. CPU time is the wall-clock \
                  time of a single-threaded run. --out is replaced whole, as by ecr reproduce \
                  (see its help: symlinks, --force). An unusable --out or a bad --problem \
                  prints one line starting with 'error: ' on stderr and exits with status 2, \
                  before any work."
)]
pub struct BenchArgs {
    /// Tiny intervals and two points per method, one timed run each (seconds in total).
    #[arg(long)]
    quick: bool,
    /// Output directory (created if missing, replaced whole by a complete run: with --only it
    /// then holds that part's files only, none of a previous run's other part).
    #[arg(long, default_value = "out/bench")]
    out: PathBuf,
    /// Replace --out even if it holds files that ecr did not write (a non-empty directory
    /// without the .ecr-output file that ecr puts into its output directories).
    #[arg(long)]
    force: bool,
    /// Run only one part of the benchmark.
    #[arg(long, value_enum)]
    only: Option<Part>,
    /// Restrict the work–precision part to these problems (repeatable or comma-separated;
    /// default: all three). The equal-CPU energy comparison and DOP853's overhead per
    /// evaluation are on Duffing: they run only when duffing is included.
    #[arg(long, value_enum, value_delimiter = ',', value_name = "PROBLEM")]
    problem: Vec<ProblemId>,
}

/// The parts of `ecr bench`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Part {
    /// Work–precision sweeps on Duffing, wind and NLS, and the equal-CPU energy comparison.
    WorkPrecision,
    /// Step cost against dimension: 1D NLS N = 2^7..2^16, 2D NLS up to 512 × 512.
    Scaling,
}

fn opt(x: Option<usize>) -> String {
    x.map_or_else(|| "-".to_string(), |v| v.to_string())
}

fn csv(run: &ProblemRun) -> Csv {
    Csv {
        header: vec![
            "method",
            "r",
            "s",
            "h",
            "tol",
            "cpu_seconds",
            "global_error",
            "max_energy_error",
            "setup_seconds",
            "g_evals",
            "g_seconds",
        ],
        rows: run
            .points
            .iter()
            .map(|p| {
                vec![
                    p.series.clone(),
                    opt(p.r),
                    opt(p.s),
                    num(p.h),
                    p.tol.map_or_else(|| "-".to_string(), num),
                    num(p.cpu),
                    num(p.error),
                    num(p.energy),
                    num(p.setup),
                    opt(p.g_evals),
                    p.g_seconds.map_or_else(|| "-".to_string(), num),
                ]
            })
            .collect(),
    }
}

fn log10(x: f64) -> Option<f64> {
    (x > 0.0 && x.is_finite()).then(|| x.log10())
}

/// One figure per quantity: one panel per group of series, DOP853 drawn in every panel.
fn figure(run: &ProblemRun, energy: bool) -> Figure {
    let mut groups: Vec<&str> = Vec::new();
    for (_, g, _) in &run.series {
        if !groups.contains(g) {
            groups.push(g);
        }
    }
    let value = |p: &Point| if energy { p.energy } else { p.error };
    let panels = groups
        .iter()
        .map(|&g| {
            let curves = run
                .series
                .iter()
                .filter(|(l, sg, _)| *sg == g || l == "DOP853")
                .map(|(label, _, _)| {
                    Curve::new(
                        label.clone(),
                        run.points
                            .iter()
                            .filter(|p| &p.series == label)
                            .filter_map(|p| Some((log10(p.cpu)?, log10(value(p))?)))
                            .collect(),
                    )
                })
                .collect();
            Panel::new(
                g.to_string(),
                "log10(CPU seconds)",
                if energy {
                    "log10(max relative energy error)"
                } else {
                    "log10(global error)"
                },
                curves,
                true,
            )
            .with_coincidence_notes()
        })
        .collect();
    Figure {
        id: format!("{}-{}", run.id, if energy { "energy" } else { "error" }),
        caption: format!(
            "{}: {} against CPU time (wall clock, single thread)",
            run.title,
            if energy {
                "max energy error"
            } else {
                "global error"
            }
        ),
        panels,
    }
}

fn scaling_csv(s: &scaling::Scaling) -> Csv {
    Csv {
        header: vec![
            "case",
            "grid",
            "d",
            "steps",
            "seconds_per_step",
            "sweeps_per_step",
            "energy_error",
            "setup_seconds",
        ],
        rows: s
            .points
            .iter()
            .map(|p| {
                vec![
                    p.case.to_string(),
                    p.grid.clone(),
                    p.d.to_string(),
                    p.steps.to_string(),
                    num(p.seconds_per_step),
                    num(p.sweeps_per_step),
                    num(p.energy_error),
                    num(p.setup_seconds),
                ]
            })
            .collect(),
    }
}

/// Seconds per step against d (log–log), 1D and 2D, with a d log d line through the largest
/// 1D point for comparison.
fn scaling_figure(s: &scaling::Scaling) -> Figure {
    let mut curves: Vec<Curve> = ["1D", "2D"]
        .iter()
        .map(|case| {
            Curve::labelled(
                format!("{case} NLS"),
                format!("EC{}P, {case} NLS (FFT)", scaling::R),
                s.points
                    .iter()
                    .filter(|p| p.case == *case)
                    .filter_map(|p| Some(((p.d as f64).log10(), log10(p.seconds_per_step)?)))
                    .collect(),
            )
        })
        .collect();
    if let Some(last) = s.points.iter().rfind(|p| p.case == "1D") {
        let (d1, t1) = (last.d as f64, last.seconds_per_step);
        let dmin = s.points.iter().map(|p| p.d).min().unwrap_or(last.d) as f64;
        let dmax = s.points.iter().map(|p| p.d).max().unwrap_or(last.d) as f64;
        let line = |d: f64| t1 * d * d.log2() / (d1 * d1.log2());
        curves.push(Curve::labelled(
            REFERENCE_KEY,
            "c·d·log d".to_string(),
            [dmin, dmax]
                .iter()
                .filter_map(|&d| Some((d.log10(), log10(line(d))?)))
                .collect(),
        ));
    }
    Figure {
        id: "scaling".to_string(),
        // Short: the single-panel figure is one panel wide, and the embedded font has no "∝".
        caption: format!("EC{}P step cost vs dimension d", scaling::R),
        panels: vec![Panel::new(
            "NLS with the circulant (FFT) operator".to_string(),
            "log10(d)",
            "log10(seconds per step)",
            curves,
            true,
        )],
    }
}

fn draw(dir: &Path, fig: &Figure, names: &mut Vec<String>) -> Result<(), UsageError> {
    let drawn = |ext: &str, e: String| UsageError(format!("cannot draw {}.{ext}: {e}", fig.id));
    let png = png(fig).map_err(|e| drawn("png", e))?;
    let svg = svg(fig).map_err(|e| drawn("svg", e))?;
    for (ext, bytes) in [("png", png.as_slice()), ("svg", svg.as_bytes())] {
        let name = format!("{}.{ext}", fig.id);
        write_file(dir, &name, bytes)?;
        names.push(name);
    }
    Ok(())
}

fn write_outputs(
    dir: &Path,
    c: &Config,
    results: Option<&sweep::Results>,
    scaling: Option<&scaling::Scaling>,
    start: Option<&Result<startup::Startup, String>>,
    seconds: f64,
) -> Result<Vec<String>, UsageError> {
    let mut names = Vec::new();
    for run in results.iter().flat_map(|r| &r.problems) {
        let name = format!("{}.csv", run.id);
        write_file(dir, &name, csv(run).render().as_bytes())?;
        names.push(name);
        for energy in [false, true] {
            draw(dir, &figure(run, energy), &mut names)?;
        }
    }
    if let Some(s) = scaling {
        write_file(dir, "scaling.csv", scaling_csv(s).render().as_bytes())?;
        names.push("scaling.csv".to_string());
        draw(dir, &scaling_figure(s), &mut names)?;
    }
    write_file(
        dir,
        "summary.md",
        summary::markdown(c, results, scaling, start, seconds).as_bytes(),
    )?;
    names.push("summary.md".to_string());
    Ok(names)
}

/// Runs `ecr bench`.
pub fn run(args: &BenchArgs, out: &mut dyn Write) -> Result<(), UsageError> {
    if args.only == Some(Part::Scaling) && !args.problem.is_empty() {
        return Err(UsageError(
            "--problem restricts the work–precision part, which --only scaling does not run"
                .to_string(),
        ));
    }
    let mut problems = if args.problem.is_empty() {
        ProblemId::value_variants().to_vec()
    } else {
        args.problem.clone()
    };
    problems.sort();
    problems.dedup();
    let staged = OutputDir::stage(&args.out, args.force, "bench")?;
    let c = Config::new(args.quick);
    let start = Instant::now();
    let results = match args.only {
        Some(Part::Scaling) => None,
        _ => Some(sweep::run_all(&c, &problems).map_err(UsageError)?),
    };
    // With the work–precision part, whose times it is kept out of.
    let start_up = results
        .as_ref()
        .map(|_| startup::measure(if args.quick { 3 } else { 20 }));
    let bar = indicatif::ProgressBar::new_spinner();
    let scaling = match args.only {
        Some(Part::WorkPrecision) => None,
        _ => Some(
            scaling::run(args.quick, &mut |m| bar.set_message(m.to_string()))
                .map_err(UsageError)?,
        ),
    };
    bar.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    let names = write_outputs(
        staged.path(),
        &c,
        results.as_ref(),
        scaling.as_ref(),
        start_up.as_ref(),
        seconds,
    )?;
    let replaced = staged.commit()?;
    let points = results
        .iter()
        .flat_map(|r| &r.problems)
        .map(|p| p.points.len())
        .sum::<usize>()
        + scaling.as_ref().map_or(0, |s| s.points.len());
    writeln!(
        out,
        "ecr bench{}: {points} points, computed in {seconds:.1} s; wrote {} files to {}{}:\n  {}",
        if args.quick { " --quick" } else { "" },
        names.len(),
        args.out.display(),
        replaced.describe(),
        names.join(" ")
    )
    .map_err(|e| {
        UsageError(format!(
            "wrote {} files to {}, but cannot write this summary to standard output: {e}",
            names.len(),
            args.out.display()
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cmd {
        #[command(flatten)]
        bench: BenchArgs,
    }

    fn problems(args: &[&str]) -> Result<Vec<ProblemId>, clap::Error> {
        Cmd::try_parse_from(std::iter::once("bench").chain(args.iter().copied()))
            .map(|c| c.bench.problem)
    }

    #[test]
    fn problem_is_repeatable_and_comma_separated() {
        use ProblemId::{Duffing, Nls, Wind};
        assert_eq!(problems(&[]).unwrap(), vec![]);
        assert_eq!(problems(&["--problem", "wind"]).unwrap(), vec![Wind]);
        assert_eq!(
            problems(&["--problem", "nls,duffing", "--problem", "wind"]).unwrap(),
            vec![Nls, Duffing, Wind]
        );
        assert!(problems(&["--problem", "wind,heat"]).is_err());
        assert!(problems(&["--problem", "heat"]).is_err());
    }
}
