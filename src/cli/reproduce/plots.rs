//! The figures: PNG (plotters' pure-Rust bitmap backend) and SVG, text laid out with ab_glyph
//! and an embedded font (no system font libraries).

use super::experiments::{EnergyStudy, ErrorStudy, LyapunovStudy, Results};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::path::Path;
use std::sync::OnceLock;

/// One curve of a panel.
pub struct Curve {
    pub label: String,
    pub points: Vec<(f64, f64)>,
}

/// One sub-panel.
pub struct Panel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub curves: Vec<Curve>,
    /// Draw a marker at every point (error studies: few points).
    pub markers: bool,
    pub legend: SeriesLabelPosition,
}

/// One figure of the paper (one file), with its sub-panels side by side.
pub struct Figure {
    pub id: String,
    pub caption: String,
    pub panels: Vec<Panel>,
}

const FONT: &str = "sans-serif";
const PANEL_W: u32 = 560;
const PANEL_H: u32 = 480;
const CAPTION_H: u32 = 40;

/// Registers the embedded font once (plotters looks fonts up by family name).
fn register_font() -> Result<(), String> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        for style in [
            FontStyle::Normal,
            FontStyle::Bold,
            FontStyle::Italic,
            FontStyle::Oblique,
        ] {
            plotters::style::register_font(FONT, style, epaint_default_fonts::UBUNTU_LIGHT)
                .map_err(|_| "the embedded font is invalid".to_string())?;
        }
        Ok(())
    })
    .clone()
}

fn color(i: usize) -> RGBColor {
    const COLORS: [RGBColor; 8] = [
        RGBColor(214, 39, 40),
        RGBColor(31, 119, 180),
        RGBColor(44, 160, 44),
        RGBColor(255, 127, 14),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(23, 190, 207),
    ];
    COLORS[i % COLORS.len()]
}

/// log10 of a positive value; None for 0 (not drawable on a log scale).
fn log10(x: f64) -> Option<f64> {
    (x > 0.0 && x.is_finite()).then(|| x.log10())
}

fn error_panel(s: &ErrorStudy, title: String) -> Panel {
    let mut curves: Vec<Curve> = Vec::new();
    for run in &s.runs {
        let Some(y) = log10(run.error) else { continue };
        let x = (s.t_end / run.h).log10();
        match curves.iter_mut().find(|c| c.label == run.method) {
            Some(c) => c.points.push((x, y)),
            None => curves.push(Curve {
                label: run.method.clone(),
                points: vec![(x, y)],
            }),
        }
    }
    Panel {
        title,
        x_label: "log10(T/h)".to_string(),
        y_label: "log10(global error)".to_string(),
        curves,
        markers: true,
        legend: SeriesLabelPosition::UpperRight,
    }
}

fn energy_panel(s: &EnergyStudy, title: String) -> Panel {
    let curves = s
        .runs
        .iter()
        .map(|run| Curve {
            label: run.method.clone(),
            points: run
                .samples
                .iter()
                .filter_map(|&(t, e)| log10(e).map(|y| (t, y)))
                .collect(),
        })
        .collect();
    Panel {
        title,
        x_label: "t".to_string(),
        y_label: "log10 |H - H0|".to_string(),
        curves,
        markers: false,
        legend: SeriesLabelPosition::LowerRight,
    }
}

fn lyapunov_panel(s: &LyapunovStudy, title: String) -> Panel {
    let mut curves = vec![Curve {
        label: format!(
            "{} h = 1/{} ('exact')",
            s.reference.method,
            (1.0 / s.reference_h).round()
        ),
        points: s.reference.samples.clone(),
    }];
    curves.extend(s.runs.iter().map(|run| Curve {
        label: format!("{} h = 1/{}", run.method, (1.0 / s.h).round()),
        points: run.samples.clone(),
    }));
    Panel {
        title,
        x_label: "t".to_string(),
        y_label: "H".to_string(),
        curves,
        markers: false,
        legend: SeriesLabelPosition::UpperRight,
    }
}

/// The paper's five figures.
pub fn figures(r: &Results) -> Vec<Figure> {
    vec![
        Figure {
            id: "p1-1".to_string(),
            caption: format!(
                "Problem 1 (Duffing, k = 0.07): global error at T = {} against T/h",
                r.p1_errors[0].t_end
            ),
            panels: r
                .p1_errors
                .iter()
                .map(|s| error_panel(s, format!("({}) {}", &s.id[4..], s.label)))
                .collect(),
        },
        Figure {
            id: "p1-2".to_string(),
            caption: format!(
                "Problem 1 (Duffing): energy error, h = {}, [0, {}]",
                r.p1_energy[0].h, r.p1_energy[0].t_end
            ),
            panels: r
                .p1_energy
                .iter()
                .map(|s| energy_panel(s, format!("({}) {}", &s.id[4..], s.label)))
                .collect(),
        },
        Figure {
            id: "p2-1".to_string(),
            caption: "Problem 2 (wind, θ = π/2, radius 20)".to_string(),
            panels: vec![
                error_panel(
                    &r.p2_errors,
                    format!("(a) global error at T = {}", r.p2_errors.t_end),
                ),
                energy_panel(
                    &r.p2_energy,
                    format!("(b) energy error, h = 1/200, [0, {}]", r.p2_energy.t_end),
                ),
            ],
        },
        Figure {
            id: "p2-2".to_string(),
            caption: "Problem 2 (wind, θ = π/2 − 1e-4, radius 20: dissipative)".to_string(),
            panels: vec![
                error_panel(
                    &r.p2d_errors,
                    format!("(a) global error at T = {}", r.p2d_errors.t_end),
                ),
                lyapunov_panel(&r.p2d_lyapunov, "(b) Lyapunov function H(t)".to_string()),
            ],
        },
        Figure {
            id: "p3".to_string(),
            caption: "Problem 3 (NLS, N = 128)".to_string(),
            panels: vec![
                error_panel(
                    &r.p3_errors,
                    format!("(a) global error at T = {}", r.p3_errors.t_end),
                ),
                energy_panel(
                    &r.p3_energy,
                    format!("(b) energy error, h = 1/200, [0, {}]", r.p3_energy.t_end),
                ),
            ],
        },
    ]
}

/// Axis range of the panel's points, padded by 5 %.
fn range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !(lo.is_finite() && hi.is_finite()) {
        return 0.0..1.0;
    }
    let span = hi - lo;
    let pad = if span > 1e-12 * lo.abs().max(hi.abs()) && span > 0.0 {
        0.05 * span
    } else {
        0.5 * lo.abs().max(1e-3)
    };
    (lo - pad)..(hi + pad)
}

fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &Panel) -> Result<(), String> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| format!("{e:?}");
    let xs = range(p.curves.iter().flat_map(|c| c.points.iter().map(|q| q.0)));
    let ys = range(p.curves.iter().flat_map(|c| c.points.iter().map(|q| q.1)));
    let mut chart = ChartBuilder::on(area)
        .caption(&p.title, (FONT, 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(xs, ys)
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc(p.x_label.as_str())
        .y_desc(p.y_label.as_str())
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 15))
        .x_labels(8)
        .y_labels(8)
        .draw()
        .map_err(e)?;
    for (i, c) in p.curves.iter().enumerate() {
        let col = color(i);
        // Width 1 for dense curves: plotters' thick polylines grow spikes at sharp turns.
        let width = if p.markers { 2 } else { 1 };
        chart
            .draw_series(LineSeries::new(
                c.points.iter().copied(),
                col.stroke_width(width),
            ))
            .map_err(e)?
            .label(c.label.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2)));
        if p.markers {
            // Distinct marker shapes, so that coinciding curves stay visible.
            let pts = c.points.iter().copied();
            match i % 4 {
                0 => chart.draw_series(pts.map(|q| Circle::new(q, 4, col.filled()))),
                1 => chart.draw_series(pts.map(|q| Circle::new(q, 8, col.stroke_width(2)))),
                2 => chart.draw_series(pts.map(|q| TriangleMarker::new(q, 7, col.filled()))),
                _ => chart.draw_series(pts.map(|q| Cross::new(q, 7, col.stroke_width(2)))),
            }
            .map_err(e)?;
        }
    }
    if p.curves.iter().any(|c| !c.points.is_empty()) {
        chart
            .configure_series_labels()
            .position(p.legend.clone())
            .label_font((FONT, 13))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(e)?;
    }
    Ok(())
}

fn draw<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, fig: &Figure) -> Result<(), String> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| format!("{e:?}");
    root.fill(&WHITE).map_err(e)?;
    let body = root.titled(&fig.caption, (FONT, 22)).map_err(e)?;
    let n = fig.panels.len().max(1);
    for (area, panel) in body.split_evenly((1, n)).iter().zip(&fig.panels) {
        draw_panel(area, panel)?;
    }
    root.present().map_err(e)
}

fn size(fig: &Figure) -> (u32, u32) {
    (
        PANEL_W * fig.panels.len().max(1) as u32,
        PANEL_H + CAPTION_H,
    )
}

/// Writes the figure as PNG.
pub fn write_png(fig: &Figure, path: &Path) -> Result<(), String> {
    register_font()?;
    draw(BitMapBackend::new(path, size(fig)).into_drawing_area(), fig)
}

/// Writes the figure as SVG.
pub fn write_svg(fig: &Figure, path: &Path) -> Result<(), String> {
    register_font()?;
    draw(SVGBackend::new(path, size(fig)).into_drawing_area(), fig)
}
