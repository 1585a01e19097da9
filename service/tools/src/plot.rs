//! PNG figures for the offline tools: panels of line series (linear or logarithmic axes)
//! and pole–zero maps, drawn with plotters' bitmap backend and the DejaVu Sans font
//! embedded from the `dejavu` crate, so no system font is needed.
//!
//! A figure is a grid of [`Panel`]s ([`figure`]), or columns of stacked panels under a
//! title and lines of text ([`column_figure`]); each panel holds [`Series`] (lines, or
//! markers for a pole–zero map), optionally shaded x intervals ([`Band`]), vertical
//! markers ([`VLine`]) and the unit circle. Non-finite points are skipped, and values are
//! clipped to the panel's range so a stray spike does not flatten the rest.

use plotters::coord::Shift;
use plotters::prelude::*;
use std::fmt::Display;
use std::path::{Path, PathBuf};
use std::sync::Once;

/// A figure that cannot be drawn.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The embedded font cannot be registered.
    #[error("cannot load the embedded DejaVu Sans font")]
    Font,
    /// Drawing into the PNG failed: the file and plotters' message (or that of the step
    /// that failed, [`PlotError::Backend`]).
    #[error("drawing {}: {message}", path.display())]
    Draw {
        /// The PNG file.
        path: PathBuf,
        /// What failed.
        message: String,
    },
    /// Writing the PNG file failed (plotters' message).
    #[error("{}: {message}", path.display())]
    File {
        /// The PNG file.
        path: PathBuf,
        /// What failed.
        message: String,
    },
    /// A step of plotters failed (within a panel, before the file is known).
    #[error("{0}")]
    Backend(String),
}

impl PlotError {
    /// Drawing into `path` failed with `e`.
    pub fn drawing(path: &Path, e: &dyn Display) -> Self {
        PlotError::Draw {
            path: path.to_path_buf(),
            message: e.to_string(),
        }
    }

    /// A step of plotters failed with `e`.
    pub fn backend(e: impl Display) -> Self {
        PlotError::Backend(e.to_string())
    }
}

message_from!(PlotError);

/// Font family under which the embedded font is registered ([`register_font`]).
pub const FONT: &str = "sans-serif";

/// A palette of distinguishable colors, in the order series usually take them.
pub const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(0, 0, 0),
];

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mark {
    /// A solid line.
    Line,
    /// A dashed line.
    Dashed,
    /// A cross at each point (poles).
    Cross,
    /// A circle at each point (zeros).
    Circle,
}

/// One labelled series of `(x, y)` points.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// The points.
    pub points: Vec<(f64, f64)>,
    /// Color.
    pub color: RGBColor,
    /// How it is drawn.
    pub mark: Mark,
}

impl Series {
    /// A solid line of color `color` from `x` and `y`.
    pub fn line(label: &str, x: &[f64], y: &[f64], color: RGBColor) -> Self {
        Self {
            label: label.into(),
            points: x.iter().copied().zip(y.iter().copied()).collect(),
            color,
            mark: Mark::Line,
        }
    }

    /// The same series drawn with `mark`.
    pub fn with(mut self, mark: Mark) -> Self {
        self.mark = mark;
        self
    }
}

/// A shaded interval `[from, to]` of the x axis spanning the panel's height (a state of the
/// run such as the safe state), drawn under the series.
#[derive(Debug, Clone)]
pub struct Band {
    /// Legend text (empty: no legend entry, e.g. for the second interval of a kind).
    pub label: String,
    /// Start, in x units.
    pub from: f64,
    /// End, in x units (an interval narrower than 1/400 of the axis is drawn that wide,
    /// darker).
    pub to: f64,
    /// Color (drawn translucent).
    pub color: RGBColor,
}

/// A dashed vertical line at `x` spanning the panel's height (an event such as the
/// controller start).
#[derive(Debug, Clone)]
pub struct VLine {
    /// Legend text (empty: no legend entry).
    pub label: String,
    /// Position, in x units.
    pub x: f64,
    /// Color.
    pub color: RGBColor,
}

/// One line of text under a figure's title.
#[derive(Debug, Clone)]
pub struct Note {
    /// The text.
    pub text: String,
    /// Its color.
    pub color: RGBColor,
}

/// One panel of a figure.
#[derive(Debug, Clone, Default)]
pub struct Panel {
    /// Caption.
    pub title: String,
    /// Label of the x axis.
    pub x_label: String,
    /// Label of the y axis.
    pub y_label: String,
    /// Logarithmic x axis (positive x only).
    pub x_log: bool,
    /// Logarithmic y axis (positive y only).
    pub y_log: bool,
    /// Fixed x range (default: the data's).
    pub x_range: Option<(f64, f64)>,
    /// Fixed y range (default: the data's, with a margin).
    pub y_range: Option<(f64, f64)>,
    /// Draw the unit circle and use equal axes (pole–zero maps).
    pub unit_circle: bool,
    /// The series.
    pub series: Vec<Series>,
    /// Shaded x intervals, drawn first.
    pub bands: Vec<Band>,
    /// Vertical markers, drawn over the series.
    pub vlines: Vec<VLine>,
}

/// Registers the embedded DejaVu Sans (the `dejavu` crate) as [`FONT`], once per process,
/// so that no system font is needed.
pub fn register_font() -> Result<(), PlotError> {
    static ONCE: Once = Once::new();
    let mut result = Ok(());
    ONCE.call_once(|| {
        result = plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular())
            .map_err(|_| PlotError::Font);
    });
    result
}

/// Range of the finite values of `v` (positive only when `log`), with a margin.
fn data_range(v: impl Iterator<Item = f64>, log: bool, margin: bool) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for x in v.filter(|x| x.is_finite() && (!log || *x > 0.0)) {
        lo = lo.min(x);
        hi = hi.max(x);
    }
    if !lo.is_finite() {
        return if log { (1e-3, 1.0) } else { (-1.0, 1.0) };
    }
    if log {
        if hi <= lo {
            return (lo / 2.0, lo * 2.0);
        }
        return if margin {
            (lo / 1.5, hi * 1.5)
        } else {
            (lo, hi)
        };
    }
    let m = if margin {
        ((hi - lo) * 0.06).max(1e-12)
    } else {
        0.0
    };
    if hi - lo < 1e-12 {
        return (lo - 1.0, hi + 1.0);
    }
    (lo - m, hi + m)
}

/// A short tick label: up to 4 significant digits, exponent notation (`1e-7`, `2.5e4`)
/// outside `[10⁻³, 10⁴)`, no float noise such as `0.09999999999999999`.
fn tick_label(v: &f64) -> String {
    let v = *v;
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if !(1e-3..1e4).contains(&a) {
        let s = format!("{v:.3e}");
        let (mant, exp) = s.split_once('e').unwrap_or((&s, "0"));
        let mant = mant.trim_end_matches('0').trim_end_matches('.');
        return format!("{mant}e{exp}");
    }
    let decimals = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// `v`, or 0 when it is float noise around 0 on the linear axis `[lo, hi]` (a tick such
/// as `1.11e-16` on an axis from −0.5 to 0.5); ticks of a logarithmic axis are kept.
fn snap(v: f64, lo: f64, hi: f64, log: bool) -> f64 {
    if !log && v.abs() < 1e-9 * (hi - lo).abs() {
        0.0
    } else {
        v
    }
}

fn draw_panel(area: &DrawingArea<BitMapBackend<'_>, Shift>, p: &Panel) -> Result<(), PlotError> {
    let pts = || p.series.iter().flat_map(|s| s.points.iter());
    let (mut x0, mut x1) = p
        .x_range
        .unwrap_or_else(|| data_range(pts().map(|q| q.0), p.x_log, false));
    let (mut y0, mut y1) = p
        .y_range
        .unwrap_or_else(|| data_range(pts().map(|q| q.1), p.y_log, true));
    if p.unit_circle {
        let r = [x0.abs(), x1.abs(), y0.abs(), y1.abs(), 1.05]
            .into_iter()
            .fold(0.0, f64::max)
            * 1.05;
        (x0, x1, y0, y1) = (-r, r, -r, r);
    }
    let mut b = ChartBuilder::on(area);
    b.caption(&p.title, (FONT, 16))
        .margin(8)
        .x_label_area_size(36)
        .y_label_area_size(64);
    // The four axis kinds give four chart types; one macro body serves them.
    macro_rules! body {
        ($chart:expr) => {{
            let mut chart = $chart.map_err(PlotError::backend)?;
            chart
                .configure_mesh()
                .x_desc(p.x_label.as_str())
                .y_desc(p.y_label.as_str())
                .label_style((FONT, 12))
                .x_label_formatter(&|v: &f64| tick_label(&snap(*v, x0, x1, p.x_log)))
                .y_label_formatter(&|v: &f64| tick_label(&snap(*v, y0, y1, p.y_log)))
                .draw()
                .map_err(PlotError::backend)?;
            if p.unit_circle {
                let circle: Vec<(f64, f64)> = (0..=200)
                    .map(|i| {
                        let a = i as f64 * std::f64::consts::TAU / 200.0;
                        (a.cos(), a.sin())
                    })
                    .collect();
                chart
                    .draw_series(DashedLineSeries::new(
                        circle,
                        4,
                        4,
                        ShapeStyle::from(&BLACK.mix(0.5)),
                    ))
                    .map_err(PlotError::backend)?;
            }
            for band in &p.bands {
                let (lo, hi) = (band.from.min(band.to), band.from.max(band.to));
                if !(lo.is_finite() && hi.is_finite()) || hi < x0 || lo > x1 {
                    continue;
                }
                // At least a few pixels wide, inside the panel; a narrow one darker so that
                // a short event stays visible.
                let min_width = (x1 - x0) / 400.0;
                let alpha = if hi - lo < min_width { 0.6 } else { 0.22 };
                let (lo, hi) = (lo.max(x0), hi.max(lo + min_width).min(x1));
                let fill = band.color.mix(alpha).filled();
                let anno = chart
                    .draw_series(std::iter::once(Rectangle::new([(lo, y0), (hi, y1)], fill)))
                    .map_err(PlotError::backend)?;
                if !band.label.is_empty() {
                    anno.label(band.label.as_str())
                        .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 16, y + 5)], fill));
                }
            }
            for s in &p.series {
                let ok = |&&(x, y): &&(f64, f64)| {
                    x.is_finite() && y.is_finite() && (!p.x_log || x > 0.0) && (!p.y_log || y > 0.0)
                };
                let mut clipped: Vec<(f64, f64)> = s
                    .points
                    .iter()
                    .filter(ok)
                    .map(|&(x, y)| (x, y.clamp(y0, y1)))
                    .collect();
                clipped.dedup();
                // plotters joins wide polyline segments with mitres, which become long
                // stray spikes at the sharp turns of a dense zig-zag (an 8 kHz signal
                // over seconds): draw dense lines one pixel wide.
                let width = if s.mark == Mark::Line && clipped.len() > 1500 {
                    1
                } else {
                    2
                };
                let style = ShapeStyle::from(&s.color).stroke_width(width);
                let color = s.color;
                let anno = match s.mark {
                    Mark::Line => chart.draw_series(LineSeries::new(clipped, style)),
                    Mark::Dashed => chart.draw_series(DashedLineSeries::new(clipped, 6, 4, style)),
                    Mark::Cross => {
                        chart.draw_series(clipped.into_iter().map(|q| Cross::new(q, 5, style)))
                    }
                    Mark::Circle => {
                        chart.draw_series(clipped.into_iter().map(|q| Circle::new(q, 5, style)))
                    }
                }
                .map_err(PlotError::backend)?;
                if !s.label.is_empty() {
                    anno.label(s.label.as_str()).legend(move |(x, y)| {
                        PathElement::new(
                            vec![(x, y), (x + 16, y)],
                            ShapeStyle::from(&color).stroke_width(2),
                        )
                    });
                }
            }
            for v in &p.vlines {
                if !v.x.is_finite() || v.x < x0 || v.x > x1 {
                    continue;
                }
                let style = ShapeStyle::from(&v.color).stroke_width(2);
                let anno = chart
                    .draw_series(DashedLineSeries::new(
                        vec![(v.x, y0), (v.x, y1)],
                        6,
                        4,
                        style,
                    ))
                    .map_err(PlotError::backend)?;
                if !v.label.is_empty() {
                    anno.label(v.label.as_str())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], style));
                }
            }
            let labelled = p.series.iter().any(|s| !s.label.is_empty())
                || p.bands.iter().any(|b| !b.label.is_empty())
                || p.vlines.iter().any(|v| !v.label.is_empty());
            if labelled {
                chart
                    .configure_series_labels()
                    .background_style(WHITE.mix(0.85))
                    .border_style(BLACK)
                    .label_font((FONT, 12))
                    .position(SeriesLabelPosition::UpperRight)
                    .draw()
                    .map_err(PlotError::backend)?;
            }
        }};
    }
    match (p.x_log, p.y_log) {
        (false, false) => body!(b.build_cartesian_2d(x0..x1, y0..y1)),
        (true, false) => body!(b.build_cartesian_2d((x0..x1).log_scale(), y0..y1)),
        (false, true) => body!(b.build_cartesian_2d(x0..x1, (y0..y1).log_scale())),
        (true, true) => body!(b.build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())),
    }
    Ok(())
}

/// Draws `panels` on a grid of `rows × cols` into the PNG `path` (`width × height`
/// pixels) under `title`.
pub fn figure(
    path: &Path,
    title: &str,
    (rows, cols): (usize, usize),
    (width, height): (u32, u32),
    panels: &[Panel],
) -> Result<(), PlotError> {
    register_font()?;
    let fail = |e: &dyn Display| PlotError::drawing(path, e);
    let root = BitMapBackend::new(path, (width, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let root = root.titled(title, (FONT, 20)).map_err(|e| fail(&e))?;
    for (area, p) in root.split_evenly((rows, cols)).iter().zip(panels) {
        draw_panel(area, p).map_err(|e| fail(&e))?;
    }
    root.present().map_err(|e| fail(&e))
}

/// Height in pixels of one line of [`Note`] text.
const NOTE_HEIGHT: u32 = 22;

/// Draws `columns` of panels side by side (each column's panels stacked, of equal
/// height) into the PNG `path` (`width × height` pixels) under `title`, with `notes`, one
/// line each, between the title and the panels.
pub fn column_figure(
    path: &Path,
    title: &str,
    notes: &[Note],
    columns: &[Vec<Panel>],
    (width, height): (u32, u32),
) -> Result<(), PlotError> {
    register_font()?;
    let fail = |e: &dyn Display| PlotError::drawing(path, e);
    let root = BitMapBackend::new(path, (width, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let root = root.titled(title, (FONT, 22)).map_err(|e| fail(&e))?;
    let notes_height = (NOTE_HEIGHT * notes.len() as u32 + 6).min(height / 3);
    let (top, body) = root.split_vertically(notes_height);
    for (i, n) in notes.iter().enumerate() {
        let style = TextStyle::from((FONT, 15).into_font()).color(&n.color);
        top.draw_text(&n.text, &style, (12, 2 + NOTE_HEIGHT as i32 * i as i32))
            .map_err(|e| fail(&e))?;
    }
    if columns.is_empty() {
        return root.present().map_err(|e| fail(&e));
    }
    for (area, column) in body.split_evenly((1, columns.len())).iter().zip(columns) {
        if column.is_empty() {
            continue;
        }
        for (cell, p) in area.split_evenly((column.len(), 1)).iter().zip(column) {
            draw_panel(cell, p).map_err(|e| fail(&e))?;
        }
    }
    root.present().map_err(|e| fail(&e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(tick_label(&0.09999999999999999), "0.1");
        assert_eq!(tick_label(&9.999999999999999e-5), "1e-4");
        assert_eq!(tick_label(&1e-7), "1e-7");
        assert_eq!(tick_label(&25000.0), "2.5e4");
        assert_eq!(tick_label(&-0.25), "-0.25");
        assert_eq!(tick_label(&120.0), "120");
        assert_eq!(tick_label(&0.0), "0");
    }

    #[test]
    fn ticks_of_float_noise_around_zero_read_zero() {
        assert_eq!(tick_label(&snap(1.11e-16, -0.5, 0.5, false)), "0");
        assert_eq!(tick_label(&snap(1e-16, -1e-15, 1e-15, false)), "1e-16");
        assert_eq!(snap(0.25, -0.5, 0.5, false), 0.25);
        assert_eq!(tick_label(&snap(1e-10, 1e-12, 0.1, true)), "1e-10");
    }

    #[test]
    fn a_figure_of_every_axis_kind_is_written() {
        let dir = std::env::temp_dir().join(format!("plot-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let x: Vec<f64> = (1..200).map(|i| i as f64 * 0.01).collect();
        let y: Vec<f64> = x.iter().map(|v| v.powi(2)).collect();
        let mut panels = Vec::new();
        for (x_log, y_log) in [(false, false), (true, false), (false, true), (true, true)] {
            panels.push(Panel {
                title: format!("log x {x_log}, log y {y_log}"),
                x_log,
                y_log,
                series: vec![
                    Series::line("x²", &x, &y, PALETTE[0]),
                    Series::line("dashed", &x, &x, PALETTE[1]).with(Mark::Dashed),
                ],
                ..Default::default()
            });
        }
        panels.push(Panel {
            title: "pole-zero".into(),
            unit_circle: true,
            series: vec![
                Series::line("poles", &[0.5, 0.5], &[0.3, -0.3], PALETTE[0]).with(Mark::Cross),
                Series::line("zeros", &[-0.9], &[0.0], PALETTE[1]).with(Mark::Circle),
            ],
            ..Default::default()
        });
        let path = dir.join("f.png");
        figure(&path, "test", (3, 2), (900, 900), &panels).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        assert!(bytes.len() > 10_000, "a non-trivial image");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_column_figure_with_bands_markers_and_notes_is_written() {
        let dir = std::env::temp_dir().join(format!("plot-columns-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let x: Vec<f64> = (0..500).map(|i| i as f64 * 0.01).collect();
        let y: Vec<f64> = x.iter().map(|v| v.sin()).collect();
        let panel = |title: &str| Panel {
            title: title.into(),
            x_label: "time (s)".into(),
            y_label: "y (plant units)".into(),
            series: vec![Series::line("y", &x, &y, PALETTE[0])],
            bands: vec![
                Band {
                    label: "safe state".into(),
                    from: 1.0,
                    to: 2.0,
                    color: PALETTE[1],
                },
                Band {
                    label: String::new(),
                    from: 4.0,
                    to: 4.0,
                    color: PALETTE[1],
                },
            ],
            vlines: vec![VLine {
                label: "start".into(),
                x: 0.5,
                color: BLACK,
            }],
            ..Default::default()
        };
        let path = dir.join("c.png");
        column_figure(
            &path,
            "columns",
            &[Note {
                text: "verdict: FAILED".into(),
                color: PALETTE[1],
            }],
            &[vec![panel("a"), panel("b")], vec![panel("c")]],
            (900, 700),
        )
        .unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        assert!(bytes.len() > 10_000, "a non-trivial image");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
