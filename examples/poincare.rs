//! A Poincaré section of the Hénon–Heiles system over a grid of initial conditions, one
//! ensemble member per initial condition, solved on every core: `cargo run --release
//! --example poincare [-- OUT.png]` (a few seconds; writes `poincare.png` by default).
//!
//! At the energy E = 1/8 every member starts on the section q1 = 0 with (q2, p2) from a grid
//! and p1 > 0 from the energy; its crossings of q1 = 0 with p1 > 0 (the zeros of the event
//! function q1, rising) are its points of the section. Regular orbits draw closed curves
//! (invariant tori), chaotic ones scatter over the chaotic sea. The second panel shows each
//! member's energy error: the largest |H − E| / E over its crossings.

use ecr::problems::HenonHeiles;
use ecr::runtime::ensemble::{Ensemble, MemberError};
use ecr::runtime::solve::{Direction, Event, Options, Problem};
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::time::Instant;

const ENERGY: f64 = 0.125;
const T_END: f64 = 400.0;
const TOL: f64 = 1e-9;
/// Grid points per axis (the members are those inside the energy's allowed region).
const GRID: usize = 9;
const FONT: &str = "sans-serif";

/// p1 ≥ 0 with H(0, q2, p1, p2) = E, if there is one.
fn p1(q2: f64, p2: f64) -> Option<f64> {
    let rest = HenonHeiles::default().energy(&[0.0, q2, 0.0, p2]);
    let twice = 2.0 * (ENERGY - rest);
    (twice > 0.0).then(|| twice.sqrt())
}

/// What a member keeps: its section points (q2, p2) and its largest relative energy error
/// over them.
struct Section {
    points: Vec<(f64, f64)>,
    energy_error: f64,
}

/// A colour per member, around the hue circle.
fn colour(k: usize, n: usize) -> RGBColor {
    let (r, g, b) = HSLColor(k as f64 / n.max(1) as f64 * 0.85, 0.8, 0.45).rgb();
    RGBColor(r, g, b)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "poincare.png".into());
    // The initial conditions inside the allowed region q2 ∈ [−0.45, 0.7], p2 ∈ [−0.5, 0.5].
    let mut starts = Vec::new();
    for i in 0..GRID {
        for j in 0..GRID {
            let q2 = -0.45 + 1.15 * i as f64 / (GRID - 1) as f64;
            let p2 = -0.5 + 1.0 * j as f64 / (GRID - 1) as f64;
            if let Some(p1) = p1(q2, p2) {
                starts.push([0.0, q2, p1, p2]);
            }
        }
    }
    let hh = HenonHeiles::default();
    let system = hh.system()?;
    let template = Problem::new(&system, starts[0], (0.0, T_END))?;
    let ensemble = Ensemble::new(template, starts.len(), |t: &Problem<_>, i| {
        Problem::new(*t.system(), starts[i], t.span())
    });
    // q1 = 0 with q1 rising (p1 = q1' > 0); the output only at T (the events are kept).
    let section = Event::new(|_, y| y[0]).direction(Direction::Rising);
    let options = Options::tolerance(TOL).t_eval([T_END]).event(section);
    let start = Instant::now();
    let result = ensemble.solve(&options, |_, sol| {
        let energy_error = sol
            .events
            .iter()
            .map(|hit| (hh.energy(&hit.y) - ENERGY).abs() / ENERGY)
            .fold(0.0, f64::max);
        Section {
            points: sol.events.iter().map(|hit| (hit.y[1], hit.y[3])).collect(),
            energy_error,
        }
    })?;
    let seconds = start.elapsed().as_secs_f64();

    let n = result.members.len();
    let mut worst = 0.0_f64;
    let mut crossings = 0;
    let mut kept = Vec::new();
    for m in &result.members {
        let s = match &m.outcome {
            Ok(s) => s,
            Err(MemberError::Unverified { output, reason }) => {
                println!(
                    "member {} not verified ({reason}); drawn all the same",
                    m.index
                );
                output
            }
            Err(e) => {
                println!("member {}: {e}", m.index);
                continue;
            }
        };
        worst = worst.max(s.energy_error);
        crossings += s.points.len();
        kept.push((m.index, s));
    }
    println!(
        "{n} members ({} verified) to t = {T_END} at tolerance {TOL:e}: {crossings} crossings \
         in {seconds:.2} s; largest energy error {worst:.1e}",
        result.verified()
    );

    for style in [FontStyle::Normal, FontStyle::Bold] {
        plotters::style::register_font(FONT, style, epaint_default_fonts::UBUNTU_LIGHT)
            .map_err(|_| "the embedded font is invalid")?;
    }
    let root = BitMapBackend::new(&out, (1400, 720)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(
        &format!(
            "Hénon–Heiles at E = 1/8: {n} orbits from the section, t ≤ {T_END}, tolerance {TOL:e}"
        ),
        (FONT, 24),
    )?;
    let (left, right) = root.split_horizontally(760);
    let mut chart = ChartBuilder::on(&left)
        .caption(
            "Poincaré section q1 = 0, p1 > 0 (a colour per orbit)",
            (FONT, 18),
        )
        .margin(14)
        .x_label_area_size(44)
        .y_label_area_size(56)
        .build_cartesian_2d(-0.5..0.75, -0.55..0.55)?;
    chart
        .configure_mesh()
        .x_desc("q2")
        .y_desc("p2")
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .draw()?;
    for (index, s) in &kept {
        let c = colour(*index, n);
        chart.draw_series(s.points.iter().map(|&p| Circle::new(p, 1, c.filled())))?;
    }
    let ymax = worst.max(TOL).log10().ceil() + 0.5;
    let mut errors = ChartBuilder::on(&right)
        .caption("Energy error of every orbit", (FONT, 18))
        .margin(14)
        .x_label_area_size(44)
        .y_label_area_size(64)
        .build_cartesian_2d(0.0..n as f64, -16.5..ymax)?;
    errors
        .configure_mesh()
        .x_desc("orbit (member)")
        .y_desc("log10 max |H − E| / E at the crossings")
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .draw()?;
    errors.draw_series(kept.iter().map(|(index, s)| {
        let y = s.energy_error.max(1e-16).log10();
        Circle::new((*index as f64 + 0.5, y), 4, colour(*index, n).filled())
    }))?;
    errors.draw_series(LineSeries::new(
        [(0.0, TOL.log10()), (n as f64, TOL.log10())],
        BLACK.mix(0.5),
    ))?;
    errors.draw_series(std::iter::once(Text::new(
        format!("tolerance {TOL:e}"),
        (0.5, TOL.log10() + 0.25),
        (FONT, 14),
    )))?;
    root.present()?;
    println!("wrote {out}");
    Ok(())
}
