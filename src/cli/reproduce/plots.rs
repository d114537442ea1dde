//! The figures: PNG (plotters' pure-Rust bitmap backend) and SVG, text laid out with ab_glyph
//! and an embedded font (no system font libraries).
//!
//! Every curve takes its colour, marker and line pattern from [`style`], keyed by the method's
//! name, so a method looks the same in every panel of every figure (also in `ecr bench`).
//! Legends and notes sit below each panel's plotting area, never over the data.

use super::experiments::{EnergyStudy, ErrorStudy, LyapunovStudy, Reference, Results};
use plotters::coord::Shift;
use plotters::element::{DashedPathElement, DynElement, IntoDynElement};
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::sync::OnceLock;

/// One curve of a panel.
pub struct Curve {
    /// What picks the style (see [`style`]): the method's name.
    pub key: String,
    /// Legend text.
    pub label: String,
    pub points: Vec<(f64, f64)>,
}

impl Curve {
    /// A curve labelled with its key.
    pub fn new(key: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        let key = key.into();
        Curve {
            label: key.clone(),
            key,
            points,
        }
    }

    /// A curve styled as `key` with its own legend text.
    pub fn labelled(key: impl Into<String>, label: String, points: Vec<(f64, f64)>) -> Self {
        Curve {
            key: key.into(),
            label,
            points,
        }
    }
}

/// A horizontal dashed line, e.g. the estimated error of a reference solution.
pub struct Floor {
    pub y: f64,
    pub label: String,
}

/// One sub-panel.
pub struct Panel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub curves: Vec<Curve>,
    /// Draw a marker at every point (error studies: few points); otherwise a few markers per
    /// curve, at a phase that differs between methods.
    pub markers: bool,
    pub floor: Option<Floor>,
    /// Lines printed below the legend (omitted methods, coinciding curves, …).
    pub notes: Vec<String>,
}

impl Panel {
    /// A panel without floor or notes.
    pub fn new(
        title: String,
        x_label: &str,
        y_label: &str,
        curves: Vec<Curve>,
        markers: bool,
    ) -> Self {
        Panel {
            title,
            x_label: x_label.to_string(),
            y_label: y_label.to_string(),
            curves,
            markers,
            floor: None,
            notes: Vec::new(),
        }
    }

    /// The y range drawn (every curve and the floor, padded).
    fn y_range(&self) -> std::ops::Range<f64> {
        range(
            self.curves
                .iter()
                .flat_map(|c| c.points.iter().map(|q| q.1))
                .chain(self.floor.as_ref().map(|f| f.y)),
        )
    }

    /// Curves (same abscissae) that coincide to plotting precision: groups of curves linked by
    /// pairs whose largest difference is below one pixel, so that the later ones hide the
    /// earlier where drawn alike. One note per group.
    pub fn coincidences(&self) -> Vec<String> {
        let ys = self.y_range();
        let pixel = (ys.end - ys.start) / f64::from(PLOT_H);
        let n = self.curves.len();
        // Union–find over the pairs within a pixel; per group the largest such difference.
        let mut group: Vec<usize> = (0..n).collect();
        fn root(group: &mut [usize], mut i: usize) -> usize {
            while group[i] != i {
                group[i] = group[group[i]];
                i = group[i];
            }
            i
        }
        let mut linked = vec![false; n];
        let mut pairs = Vec::new();
        for (i, a) in self.curves.iter().enumerate() {
            for (j, b) in self.curves.iter().enumerate().skip(i + 1) {
                if a.points.len() < 2
                    || a.points.len() != b.points.len()
                    || a.points.iter().zip(&b.points).any(|(p, q)| p.0 != q.0)
                {
                    continue;
                }
                let d = a
                    .points
                    .iter()
                    .zip(&b.points)
                    .fold(0.0f64, |m, (p, q)| m.max((p.1 - q.1).abs()));
                if d <= pixel {
                    let (ri, rj) = (root(&mut group, i), root(&mut group, j));
                    group[rj] = ri;
                    linked[i] = true;
                    linked[j] = true;
                    pairs.push((i, j, d));
                }
            }
        }
        let mut notes = Vec::new();
        for r in 0..n {
            let members: Vec<usize> = (0..n)
                .filter(|&i| linked[i] && root(&mut group, i) == r)
                .collect();
            if members.len() < 2 {
                continue;
            }
            let largest = pairs
                .iter()
                .filter(|p| root(&mut group, p.0) == r)
                .fold(0.0f64, |m, p| m.max(p.2));
            let labels: Vec<&str> = members
                .iter()
                .map(|&i| self.curves[i].label.as_str())
                .collect();
            let names = match labels.split_last() {
                Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
                _ => labels.join(""),
            };
            notes.push(if largest == 0.0 {
                format!(
                    "{names} are identical at every point (drawn with different line pattern \
                     and marker)."
                )
            } else {
                format!(
                    "{names} coincide to plotting precision (differences up to {} in {}, \
                     under one pixel).",
                    sig(largest),
                    self.y_label
                )
            });
        }
        notes
    }

    /// Adds the [`Panel::coincidences`] notes.
    pub fn with_coincidence_notes(mut self) -> Self {
        let notes = self.coincidences();
        self.notes.extend(notes);
        self
    }
}

/// A number with 2 significant digits ("0" for 0).
fn sig(x: f64) -> String {
    if x == 0.0 {
        "0".to_string()
    } else {
        format!("{x:.1e}")
    }
}

/// One figure of the paper (one file), with its sub-panels side by side.
pub struct Figure {
    pub id: String,
    pub caption: String,
    pub panels: Vec<Panel>,
}

/// Marker shapes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Marker {
    Dot,
    Ring,
    Triangle,
    OpenSquare,
    Diamond,
    Cross,
    Square,
    OpenDiamond,
    None,
}

/// How a method is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Style {
    pub color: RGBColor,
    pub marker: Marker,
    pub dashed: bool,
    /// Where the sparse markers of a dense curve start (in 1/8 of their spacing), so that
    /// coinciding curves show both sets of markers.
    pub phase: usize,
}

/// The fixed method → style map (name, colour, marker, dashed). A "-conv" variant shares its
/// method's hue family but is dashed with an open marker, so it stays visible on top of it.
const STYLES: [(&str, RGBColor, Marker, bool); 22] = [
    ("EC2P", RGBColor(214, 39, 40), Marker::Dot, false),
    ("EC2P-conv", RGBColor(255, 127, 14), Marker::Ring, true),
    ("RKEPC2", RGBColor(31, 119, 180), Marker::Triangle, false),
    (
        "RKEPC2-conv",
        RGBColor(23, 190, 207),
        Marker::OpenSquare,
        true,
    ),
    ("EEI3s4", RGBColor(44, 160, 44), Marker::Diamond, false),
    ("DOP853", RGBColor(148, 103, 189), Marker::Cross, false),
    ("reference", RGBColor(0, 0, 0), Marker::None, false),
    // Further names used by `ecr bench`.
    ("EC1P", RGBColor(140, 86, 75), Marker::Square, false),
    ("EC3P", RGBColor(227, 119, 194), Marker::OpenDiamond, false),
    ("EC4P", RGBColor(127, 127, 127), Marker::Square, false),
    ("HochOst4", RGBColor(188, 189, 34), Marker::Ring, false),
    ("Gauss2", RGBColor(140, 86, 75), Marker::Triangle, true),
    ("AVF", RGBColor(227, 119, 194), Marker::Cross, true),
    ("ExpAVF", RGBColor(127, 127, 127), Marker::Diamond, true),
    ("TC1P", RGBColor(140, 86, 75), Marker::OpenSquare, false),
    ("TC2P", RGBColor(214, 39, 40), Marker::OpenDiamond, true),
    ("TC3P", RGBColor(31, 119, 180), Marker::Ring, true),
    ("TC4P", RGBColor(44, 160, 44), Marker::Square, true),
    ("EC5P", RGBColor(188, 189, 34), Marker::OpenDiamond, true),
    ("EC6P", RGBColor(23, 190, 207), Marker::Ring, false),
    ("TC5P", RGBColor(148, 103, 189), Marker::Triangle, true),
    ("TC6P", RGBColor(255, 127, 14), Marker::Square, false),
];

/// Fallback colours and markers for names outside [`STYLES`], chosen by a hash of the name
/// (stable across runs and figures).
const FALLBACK_COLORS: [RGBColor; 4] = [
    RGBColor(188, 189, 34),
    RGBColor(31, 119, 180),
    RGBColor(140, 86, 75),
    RGBColor(23, 190, 207),
];
const FALLBACK_MARKERS: [Marker; 5] = [
    Marker::Square,
    Marker::OpenDiamond,
    Marker::Ring,
    Marker::Triangle,
    Marker::Cross,
];

/// The style of `key`, the same wherever it is drawn. Keys are looked up in [`STYLES`]
/// whole, then by their first word ("EC2P, 1D NLS" → "EC2P"; "EC3P s=2" → "EC3P").
pub fn style(key: &str) -> Style {
    let head = key.split([',', ' ']).next().unwrap_or(key);
    if let Some(i) = STYLES
        .iter()
        .position(|s| s.0 == key)
        .or_else(|| STYLES.iter().position(|s| s.0 == head))
    {
        let (_, color, marker, dashed) = STYLES[i];
        return Style {
            color,
            marker,
            dashed,
            phase: i % 8,
        };
    }
    // FNV-1a: stable, unlike the standard library's randomly seeded hasher.
    let h = key.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
    });
    Style {
        color: FALLBACK_COLORS[(h % 4) as usize],
        marker: FALLBACK_MARKERS[((h >> 8) % 5) as usize],
        dashed: (h >> 16) % 2 == 1,
        phase: ((h >> 24) % 8) as usize,
    }
}

/// The style keys of `ecr reproduce`'s figures besides the methods: the 'exact' run of the
/// Lyapunov panel.
pub const REFERENCE_KEY: &str = "reference";

const FONT: &str = "sans-serif";
const PANEL_W: u32 = 560;
const PANEL_H: u32 = 440;
/// Approximate height of a panel's plotting area (for "one pixel").
const PLOT_H: u32 = 340;
const CAPTION_H: u32 = 40;
const LEGEND_ROW_H: u32 = 20;
const NOTE_ROW_H: u32 = 16;
/// Characters per note line (font size 12 in a panel PANEL_W wide).
const NOTE_CHARS: usize = 104;
const FLOOR_COLOR: RGBColor = RGBColor(110, 110, 110);

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

/// log10 of a positive value; None for 0 (not drawable on a log scale).
pub fn log10(x: f64) -> Option<f64> {
    (x > 0.0 && x.is_finite()).then(|| x.log10())
}

/// Shortens a message to `n` characters.
fn shorten(msg: &str, n: usize) -> String {
    if msg.chars().count() <= n {
        msg.to_string()
    } else {
        format!("{}…", msg.chars().take(n - 1).collect::<String>())
    }
}

/// Notes for the methods of `names` that have no curve in the panel, each with its reason.
fn omitted_notes(
    curves: &[Curve],
    names: &[&str],
    failures: &[(String, String)],
    zero: &dyn Fn(&str) -> bool,
) -> Vec<String> {
    let mut notes = Vec::new();
    for &name in names {
        if curves.iter().any(|c| c.key == name && !c.points.is_empty()) {
            continue;
        }
        let why = if let Some((_, msg)) = failures.iter().find(|f| f.0 == name) {
            format!("failed ({})", shorten(msg, 110))
        } else if zero(name) {
            "its error is exactly 0 (nothing to draw on a log scale)".to_string()
        } else {
            "not run".to_string()
        };
        notes.push(format!("{name} not shown: {why}."));
    }
    notes
}

/// Global error against the number of steps: T/h for a method that steps with h, the steps
/// it took for one that chooses its own (DOP853, labelled so), never against an h it did not
/// use.
fn error_panel(s: &ErrorStudy, title: String, names: &[&str]) -> Panel {
    let mut curves: Vec<Curve> = Vec::new();
    let mut zeros: Vec<String> = Vec::new();
    for run in &s.runs {
        let Some(y) = log10(run.error) else {
            zeros.push(format!("{} at h = {}", run.method, run.h));
            continue;
        };
        let x = (run.steps.max(1) as f64).log10();
        match curves.iter_mut().find(|c| c.key == run.method) {
            Some(c) => c.points.push((x, y)),
            None => {
                let label = if run.own_steps {
                    format!("{} (steps it chose)", run.method)
                } else {
                    run.method.clone()
                };
                curves.push(Curve::labelled(run.method.clone(), label, vec![(x, y)]));
            }
        }
    }
    let mut notes = omitted_notes(&curves, names, &s.failures, &|m| {
        s.runs.iter().any(|r| r.method == m)
    });
    if !zeros.is_empty() {
        notes.push(format!(
            "Error exactly 0 (not drawn): {}.",
            zeros.join(", ")
        ));
    }
    let floor = match s.reference {
        Reference::Ec { r, .. } => log10(s.reference_error).map(|y| Floor {
            y,
            label: format!("EC{r}P reference error (est.)"),
        }),
        Reference::Exact => None,
    };
    let mut panel = Panel::new(
        title,
        "log10(steps)  (T/h for a fixed step h)",
        "log10(global error)",
        curves,
        true,
    );
    panel.floor = floor;
    panel.notes = notes;
    panel.with_coincidence_notes()
}

/// The largest energy error so far, max over s ≤ t of |H(s) − H0|, against t: bounded or
/// growing at a glance. (The error within a window oscillates over decades on the NLS; drawn
/// window by window it hid the other curves.)
fn energy_panel(s: &EnergyStudy, title: String, names: &[&str]) -> Panel {
    let curves: Vec<Curve> = s
        .runs
        .iter()
        .map(|run| {
            let mut so_far = 0.0_f64;
            Curve::new(
                run.method.clone(),
                run.samples
                    .iter()
                    .filter_map(|&(t, e)| {
                        so_far = so_far.max(e);
                        log10(so_far).map(|y| (t, y))
                    })
                    .collect(),
            )
        })
        .collect();
    let notes = omitted_notes(&curves, names, &s.failures, &|m| {
        s.runs.iter().any(|r| r.method == m)
    });
    let mut panel = Panel::new(
        title,
        "t",
        "log10 max over [0, t] of |H - H0|",
        curves,
        false,
    );
    panel.notes = notes;
    panel.with_coincidence_notes()
}

/// H(t) of every method and of the 'exact' run, which comes last so that it is drawn on
/// top: a solid black line that the curves coinciding with it do not hide.
fn lyapunov_panel(s: &LyapunovStudy, title: String, names: &[&str]) -> Panel {
    let mut curves: Vec<Curve> = s
        .runs
        .iter()
        .map(|run| {
            Curve::labelled(
                run.method.clone(),
                format!("{} h = 1/{}", run.method, (1.0 / s.h).round()),
                run.samples.clone(),
            )
        })
        .collect();
    curves.push(Curve::labelled(
        REFERENCE_KEY,
        format!(
            "{} h = 1/{} ('exact')",
            s.reference.method,
            (1.0 / s.reference_h).round()
        ),
        s.reference.samples.clone(),
    ));
    let notes = omitted_notes(&curves, names, &s.failures, &|_| false);
    let mut panel = Panel::new(title, "t", "H", curves, false);
    panel.notes = notes;
    panel.with_coincidence_notes()
}

/// The paper's five figures; `names` are the registered methods (a panel without one of them
/// says why).
pub fn figures(r: &Results, names: &[&str]) -> Vec<Figure> {
    vec![
        Figure {
            id: "p1-1".to_string(),
            caption: format!(
                "Problem 1 (Duffing, k = 0.07): global error at T = {} against the number of steps",
                r.p1_errors[0].t_end
            ),
            panels: r
                .p1_errors
                .iter()
                .map(|s| error_panel(s, format!("({}) {}", &s.id[4..], s.label), names))
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
                .map(|s| energy_panel(s, format!("({}) {}", &s.id[4..], s.label), names))
                .collect(),
        },
        Figure {
            id: "p2-1".to_string(),
            caption: "Problem 2 (wind, θ = π/2, radius 20)".to_string(),
            panels: vec![
                error_panel(
                    &r.p2_errors,
                    format!("(a) global error at T = {}", r.p2_errors.t_end),
                    names,
                ),
                energy_panel(
                    &r.p2_energy,
                    format!("(b) energy error, h = 1/200, [0, {}]", r.p2_energy.t_end),
                    names,
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
                    names,
                ),
                lyapunov_panel(
                    &r.p2d_lyapunov,
                    "(b) Lyapunov function H(t)".to_string(),
                    names,
                ),
            ],
        },
        Figure {
            id: "p3".to_string(),
            caption: "Problem 3 (NLS, N = 128)".to_string(),
            panels: vec![
                error_panel(
                    &r.p3_errors,
                    format!("(a) global error at T = {}", r.p3_errors.t_end),
                    names,
                ),
                energy_panel(
                    &r.p3_energy,
                    format!("(b) energy error, h = 1/200, [0, {}]", r.p3_energy.t_end),
                    names,
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

/// A marker of `style` at `at`, `size` pixels across (about).
fn marker<'a, DB: DrawingBackend + 'a, C: Clone + 'a>(
    at: C,
    m: Marker,
    color: RGBColor,
) -> Option<DynElement<'a, DB, C>> {
    let e = EmptyElement::at(at);
    let open = color.stroke_width(2);
    Some(match m {
        Marker::Dot => (e + Circle::new((0, 0), 4, color.filled())).into_dyn(),
        Marker::Ring => (e + Circle::new((0, 0), 7, open)).into_dyn(),
        Marker::Triangle => (e + TriangleMarker::new((0, 0), 6, color.filled())).into_dyn(),
        Marker::OpenSquare => (e + Rectangle::new([(-6, -6), (6, 6)], open)).into_dyn(),
        Marker::Square => (e + Rectangle::new([(-4, -4), (4, 4)], color.filled())).into_dyn(),
        Marker::Diamond => {
            (e + Polygon::new(vec![(0, -6), (6, 0), (0, 6), (-6, 0)], color.filled())).into_dyn()
        }
        Marker::OpenDiamond => {
            (e + PathElement::new(vec![(0, -8), (8, 0), (0, 8), (-8, 0), (0, -8)], open)).into_dyn()
        }
        Marker::Cross => (e + Cross::new((0, 0), 6, open)).into_dyn(),
        Marker::None => return None,
    })
}

/// Legend rows and note lines below a panel: (legend entries per row, rows, note lines).
fn footer_layout(p: &Panel, width: u32) -> (usize, usize, Vec<String>) {
    let entries = p.curves.len() + usize::from(p.floor.is_some());
    let longest = p
        .curves
        .iter()
        .map(|c| c.label.chars().count())
        .chain(p.floor.as_ref().map(|f| f.label.chars().count()))
        .max()
        .unwrap_or(0);
    // Entry width: line sample (36 px) + text (≈ 7 px per character at size 13).
    let entry_w = 48 + 7 * longest as u32;
    let per_row = ((width - 20) / entry_w.max(1)).clamp(1, 3) as usize;
    let rows = entries.div_ceil(per_row);
    let chars = (NOTE_CHARS as u32 * width / PANEL_W) as usize;
    let lines = p.notes.iter().flat_map(|n| wrap(n, chars)).collect();
    (per_row, rows, lines)
}

fn footer_height(p: &Panel, width: u32) -> u32 {
    let (_, rows, lines) = footer_layout(p, width);
    8 + LEGEND_ROW_H * rows as u32 + NOTE_ROW_H * lines.len() as u32
}

/// Splits `text` into lines of at most `n` characters at spaces.
fn wrap(text: &str, n: usize) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    let mut line = String::new();
    for word in text.split(' ') {
        if !line.is_empty() && line.chars().count() + 1 + word.chars().count() > n {
            lines.push(std::mem::take(&mut line));
        }
        if !line.is_empty() {
            line.push(' ');
        }
        line.push_str(word);
    }
    if !line.is_empty() {
        lines.push(line);
    }
    lines
}

/// A line of `style` through `points`.
fn draw_line<DB, C, P>(
    area: &DrawingArea<DB, C>,
    points: Vec<P>,
    s: Style,
    width: u32,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>>
where
    DB: DrawingBackend,
    C: plotters::coord::CoordTranslate<From = P> + Clone + 'static,
    P: Clone + 'static,
{
    let st = s.color.stroke_width(width);
    if s.dashed {
        area.draw(&DashedPathElement::new(points, 7, 4, st))
    } else {
        area.draw(&PathElement::new(points, st))
    }
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    p: &Panel,
    footer_h: u32,
) -> Result<(), String> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| format!("{e:?}");
    let (w, h) = area.dim_in_pixel();
    let (plot, footer) = area.split_vertically(h.saturating_sub(footer_h));
    let xs = range(p.curves.iter().flat_map(|c| c.points.iter().map(|q| q.0)));
    let ys = p.y_range();
    let mut chart = ChartBuilder::on(&plot)
        .caption(&p.title, (FONT, 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(xs.clone(), ys)
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
    let pa = chart.plotting_area();
    if let Some(f) = &p.floor {
        let s = Style {
            color: FLOOR_COLOR,
            marker: Marker::None,
            dashed: true,
            phase: 0,
        };
        draw_line(pa, vec![(xs.start, f.y), (xs.end, f.y)], s, 1).map_err(e)?;
    }
    // Every line first, then every marker: a marker is never hidden under a later line.
    for c in &p.curves {
        // Width 1 for dense curves: plotters' thick polylines grow spikes at sharp turns.
        let width = if p.markers { 2 } else { 1 };
        draw_line(pa, c.points.clone(), style(&c.key), width).map_err(e)?;
    }
    for c in &p.curves {
        let s = style(&c.key);
        let n = c.points.len();
        let picked: Vec<(f64, f64)> = if p.markers {
            c.points.clone()
        } else {
            // Six markers along a dense curve, shifted by the style's phase.
            let stride = (n / 6).max(1);
            let start = (s.phase * stride / 8).min(n.saturating_sub(1));
            c.points
                .iter()
                .copied()
                .skip(start)
                .step_by(stride)
                .collect()
        };
        for q in picked {
            if let Some(m) = marker(q, s.marker, s.color) {
                pa.draw(&m).map_err(e)?;
            }
        }
    }
    // Legend and notes, below the plotting area.
    let (per_row, _, lines) = footer_layout(p, w);
    let col_w = (w as i32 - 20) / per_row as i32;
    let floor_entry = p.floor.as_ref().map(|f| {
        (
            f.label.as_str(),
            Style {
                color: FLOOR_COLOR,
                marker: Marker::None,
                dashed: true,
                phase: 0,
            },
        )
    });
    let entries = p
        .curves
        .iter()
        .map(|c| (c.label.as_str(), style(&c.key)))
        .chain(floor_entry);
    let text = (FONT, 13).into_font().color(&BLACK);
    for (i, (label, s)) in entries.enumerate() {
        let x = 60 + col_w * (i % per_row) as i32;
        let y = 4 + (LEGEND_ROW_H * (i / per_row) as u32) as i32 + LEGEND_ROW_H as i32 / 2;
        draw_line(&footer, vec![(x, y), (x + 30, y)], s, 2).map_err(e)?;
        if let Some(m) = marker((x + 15, y), s.marker, s.color) {
            footer.draw(&m).map_err(e)?;
        }
        footer
            .draw(&Text::new(label.to_string(), (x + 38, y - 7), text.clone()))
            .map_err(e)?;
    }
    let (_, rows, _) = footer_layout(p, w);
    let note = (FONT, 12).into_font().color(&RGBColor(60, 60, 60));
    for (j, line) in lines.iter().enumerate() {
        let y = 6 + (LEGEND_ROW_H * rows as u32 + NOTE_ROW_H * j as u32) as i32;
        footer
            .draw(&Text::new(line.clone(), (12, y), note.clone()))
            .map_err(e)?;
    }
    Ok(())
}

/// The footer height shared by a figure's panels.
fn figure_footer(fig: &Figure) -> u32 {
    fig.panels
        .iter()
        .map(|p| footer_height(p, PANEL_W))
        .max()
        .unwrap_or(0)
}

fn draw<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, fig: &Figure) -> Result<(), String> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| format!("{e:?}");
    root.fill(&WHITE).map_err(e)?;
    let body = root.titled(&fig.caption, (FONT, 22)).map_err(e)?;
    let n = fig.panels.len().max(1);
    let footer = figure_footer(fig);
    for (area, panel) in body.split_evenly((1, n)).iter().zip(&fig.panels) {
        draw_panel(area, panel, footer)?;
    }
    root.present().map_err(e)
}

fn size(fig: &Figure) -> (u32, u32) {
    (
        PANEL_W * fig.panels.len().max(1) as u32,
        PANEL_H + CAPTION_H + figure_footer(fig),
    )
}

/// The figure as a PNG file's bytes: drawn in memory, encoded as the bitmap backend's own
/// `save` encodes it (the `image` crate's PNG encoder with its defaults). The caller writes the
/// bytes, so that a failed write names the file and its cause.
pub fn png(fig: &Figure) -> Result<Vec<u8>, String> {
    use image::ImageEncoder;
    register_font()?;
    let (w, h) = size(fig);
    let mut rgb = vec![0u8; 3 * w as usize * h as usize];
    draw(
        BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area(),
        fig,
    )?;
    let mut bytes = Vec::new();
    image::codecs::png::PngEncoder::new(&mut bytes)
        .write_image(&rgb, w, h, image::ColorType::Rgb8)
        .map_err(|e| format!("cannot encode the PNG: {e}"))?;
    Ok(bytes)
}

/// The figure as an SVG file's text (drawn in memory; the caller writes it).
pub fn svg(fig: &Figure) -> Result<String, String> {
    register_font()?;
    let mut text = String::new();
    draw(
        SVGBackend::with_string(&mut text, size(fig)).into_drawing_area(),
        fig,
    )?;
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One style per name of `ecr reproduce`: no two methods share a colour or a marker, and
    /// the style depends on the name only (so it is the same in every panel and figure).
    #[test]
    fn style_map_is_one_to_one() {
        let mut names: Vec<&str> = super::super::methods::methods()
            .iter()
            .map(|m| m.name)
            .collect();
        names.push(REFERENCE_KEY);
        for (i, a) in names.iter().enumerate() {
            for b in &names[i + 1..] {
                let (sa, sb) = (style(a), style(b));
                assert_ne!(sa.color, sb.color, "{a} and {b} share a colour");
                assert_ne!(sa.marker, sb.marker, "{a} and {b} share a marker");
            }
            assert_eq!(style(a), style(a));
        }
        // Keys with a suffix keep their method's style; unknown names get a stable one.
        assert_eq!(style("EC2P, 1D NLS (FFT)"), style("EC2P"));
        assert_eq!(style("some new method"), style("some new method"));
    }

    /// Every bench name in the table has its own (colour, marker, pattern).
    #[test]
    fn table_styles_are_distinct() {
        for (i, a) in STYLES.iter().enumerate() {
            for b in &STYLES[i + 1..] {
                assert_ne!(a.0, b.0);
                assert!(
                    (a.1, a.2, a.3) != (b.1, b.2, b.3),
                    "{} and {} are drawn alike",
                    a.0,
                    b.0
                );
            }
        }
    }

    #[test]
    fn coinciding_curves_are_noted() {
        let a = vec![(0.0, -3.0), (1.0, -5.0), (2.0, -7.0)];
        let b: Vec<(f64, f64)> = a.iter().map(|&(x, y)| (x, y + 1e-4)).collect();
        let c: Vec<(f64, f64)> = a.iter().map(|&(x, y)| (x, y + 0.5)).collect();
        let p = Panel::new(
            "t".into(),
            "x",
            "y",
            vec![
                Curve::new("EC2P", a),
                Curve::new("EC2P-conv", b),
                Curve::new("DOP853", c),
            ],
            true,
        );
        let notes = p.coincidences();
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(notes[0].contains("EC2P and EC2P-conv"), "{notes:?}");
    }

    /// Curves linked by coincidences make one note, not one per pair (p2-2's Lyapunov panel
    /// had ten notes for five curves).
    #[test]
    fn coinciding_curves_make_one_note_per_group() {
        let a: Vec<(f64, f64)> = (0..50)
            .map(|i| (f64::from(i), 10.0 - 0.1 * f64::from(i)))
            .collect();
        let shifted = |d: f64| a.iter().map(|&(x, y)| (x, y + d)).collect::<Vec<_>>();
        let p = Panel::new(
            "t".into(),
            "x",
            "H",
            vec![
                Curve::new("EC2P", a.clone()),
                Curve::new("EC2P-conv", shifted(1e-3)),
                Curve::new("RKEPC2", shifted(3.0)),
                Curve::new("DOP853", shifted(2e-3)),
                Curve::new("reference", a.clone()),
            ],
            false,
        );
        let notes = p.coincidences();
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(
            notes[0].starts_with("EC2P, EC2P-conv, DOP853 and reference coincide"),
            "{notes:?}"
        );
        assert!(notes[0].contains("up to 2.0e-3 in H"), "{notes:?}");
    }

    #[test]
    fn wrap_keeps_words() {
        let lines = wrap("aa bb cc dd", 5);
        assert_eq!(lines, ["aa bb", "cc dd"]);
    }
}
