//! The files of `study forgetting`: the CSV of one run and of the Monte Carlo bands, and
//! their PNG figures (plotters, bitmap backend, the embedded font of [`crate::plot`]).

use crate::file_error::{FileError, FileOp};
use std::fmt::Write as _;
use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::plot::{FONT, PlotError};
use crate::study::forgetting::ForgettingError;

use crate::study::forgetting::experiment::{N, Trace};
use crate::study::forgetting::montecarlo::{Band, Bands};

/// Writes a single-run trajectory as CSV: `k, theta1..5, true1..5, trP, lambda, e`.
pub fn write_trace_csv(path: &Path, t: &Trace) -> Result<(), ForgettingError> {
    let mut s = String::from(
        "k,theta1,theta2,theta3,theta4,theta5,true1,true2,true3,true4,true5,trP,lambda,e\n",
    );
    for i in 0..t.ks.len() {
        let _ = write!(s, "{}", t.ks[i]);
        for v in t.theta[i].iter().chain(&t.truth[i]) {
            let _ = write!(s, ",{v:.10e}");
        }
        let _ = writeln!(
            s,
            ",{:.10e},{:.10e},{:.10e}",
            t.trace_p[i], t.lambda[i], t.error[i]
        );
    }
    std::fs::write(path, s).map_err(|source| FileError::new(FileOp::Access, path, source).into())
}

/// Writes Monte Carlo bands as CSV: `k`, then `p05, p50, p95` of each `θ` component,
/// the true `θ`, and the bands of `tr(P)`, `λ`, `e`.
pub fn write_bands_csv(path: &Path, b: &Bands) -> Result<(), ForgettingError> {
    let mut s = String::from("k");
    for j in 1..=N {
        let _ = write!(s, ",theta{j}_p05,theta{j}_p50,theta{j}_p95");
    }
    for j in 1..=N {
        let _ = write!(s, ",true{j}");
    }
    s.push_str(",trP_p05,trP_p50,trP_p95,lambda_p05,lambda_p50,lambda_p95,e_p05,e_p50,e_p95\n");
    let band = |s: &mut String, b: &Band| {
        let _ = write!(s, ",{:.10e},{:.10e},{:.10e}", b.p05, b.p50, b.p95);
    };
    for i in 0..b.ks.len() {
        let _ = write!(s, "{}", b.ks[i]);
        for th in &b.theta[i] {
            band(&mut s, th);
        }
        for v in &b.truth[i] {
            let _ = write!(s, ",{v:.10e}");
        }
        band(&mut s, &b.trace_p[i]);
        band(&mut s, &b.lambda[i]);
        band(&mut s, &b.error[i]);
        s.push('\n');
    }
    std::fs::write(path, s).map_err(|source| FileError::new(FileOp::Access, path, source).into())
}

/// One line of a panel.
struct Line {
    points: Vec<(f64, f64)>,
    color: RGBColor,
    dashed: bool,
    width: u32,
}

/// Colors of the five `θ` components.
const THETA_COLORS: [RGBColor; N] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
];

/// Finite range of the lines' y values with a margin (log: positive values only).
fn y_range(lines: &[Line], log: bool) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for l in lines {
        for &(_, y) in &l.points {
            if y.is_finite() && (!log || y > 0.0) {
                lo = lo.min(y);
                hi = hi.max(y);
            }
        }
    }
    if !lo.is_finite() {
        return if log { (1e-3, 1.0) } else { (-1.0, 1.0) };
    }
    if log {
        (lo / 2.0, hi * 2.0)
    } else {
        let m = ((hi - lo) * 0.08).max(1e-3);
        (lo - m, hi + m)
    }
}

/// Draws one panel of lines into `area`.
fn panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    title: &str,
    x_max: f64,
    lines: &[Line],
    log: bool,
) -> Result<(), PlotError> {
    let (lo, hi) = y_range(lines, log);
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(title, (FONT, 16))
        .margin(6)
        .x_label_area_size(24)
        .y_label_area_size(64);
    let style = |l: &Line| ShapeStyle::from(&l.color).stroke_width(l.width);
    let clip = |p: &Vec<(f64, f64)>, lo: f64, hi: f64| -> Vec<(f64, f64)> {
        p.iter()
            .filter(|(_, y)| y.is_finite())
            .map(|&(x, y)| (x, y.clamp(lo, hi)))
            .collect()
    };
    if log {
        let mut chart = builder
            .build_cartesian_2d(0.0..x_max, (lo..hi).log_scale())
            .map_err(PlotError::backend)?;
        chart
            .configure_mesh()
            .label_style((FONT, 12))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .draw()
            .map_err(PlotError::backend)?;
        for l in lines {
            let pts = clip(&l.points, lo, hi);
            chart
                .draw_series(LineSeries::new(pts, style(l)))
                .map_err(PlotError::backend)?;
        }
    } else {
        let mut chart = builder
            .build_cartesian_2d(0.0..x_max, lo..hi)
            .map_err(PlotError::backend)?;
        chart
            .configure_mesh()
            .label_style((FONT, 12))
            .draw()
            .map_err(PlotError::backend)?;
        for l in lines {
            let pts = clip(&l.points, lo, hi);
            if l.dashed {
                chart
                    .draw_series(DashedLineSeries::new(pts, 6, 4, style(l)))
                    .map_err(PlotError::backend)?;
            } else {
                chart
                    .draw_series(LineSeries::new(pts, style(l)))
                    .map_err(PlotError::backend)?;
            }
        }
    }
    Ok(())
}

/// The four panels (θ, tr(P), λ, e) of a figure in the manner of Figures 5.1–5.8.
struct Figure {
    theta: Vec<Line>,
    trace_p: Vec<Line>,
    lambda: Vec<Line>,
    error: Vec<Line>,
}

fn draw_figure(path: &Path, title: &str, x_max: f64, fig: &Figure) -> Result<(), PlotError> {
    let root = BitMapBackend::new(path, (1000, 1100)).into_drawing_area();
    root.fill(&WHITE).map_err(PlotError::backend)?;
    let root = root.titled(title, (FONT, 20)).map_err(PlotError::backend)?;
    let areas = root.split_evenly((4, 1));
    panel(&areas[0], "θ_k (true dashed)", x_max, &fig.theta, false)?;
    panel(&areas[1], "tr(P_k)", x_max, &fig.trace_p, true)?;
    panel(&areas[2], "λ_k", x_max, &fig.lambda, false)?;
    panel(&areas[3], "e_k", x_max, &fig.error, false)?;
    root.present().map_err(|e| PlotError::File {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

fn xy(ks: &[usize], v: impl Iterator<Item = f64>) -> Vec<(f64, f64)> {
    ks.iter().map(|&k| k as f64).zip(v).collect()
}

/// Plots single runs of several methods (one color and line width per method), the true
/// `θ` dashed in black.
pub fn plot_runs(path: &Path, title: &str, runs: &[(&str, &Trace)]) -> Result<(), PlotError> {
    const METHOD_COLORS: [RGBColor; 3] = [
        RGBColor(200, 0, 0),
        RGBColor(0, 70, 200),
        RGBColor(0, 150, 0),
    ];
    let Some((_, first)) = runs.first() else {
        return Ok(());
    };
    let x_max = *first.ks.last().unwrap_or(&1) as f64;
    let mut fig = Figure {
        theta: Vec::new(),
        trace_p: Vec::new(),
        lambda: Vec::new(),
        error: Vec::new(),
    };
    for (m, (_, t)) in runs.iter().enumerate() {
        let color = METHOD_COLORS[m % METHOD_COLORS.len()];
        for j in 0..N {
            fig.theta.push(Line {
                points: xy(&t.ks, t.theta.iter().map(|th| th[j])),
                color,
                dashed: false,
                width: 1,
            });
        }
        let line = |v: &[f64]| Line {
            points: xy(&t.ks, v.iter().copied()),
            color,
            dashed: false,
            width: 1,
        };
        fig.trace_p.push(line(&t.trace_p));
        fig.lambda.push(line(&t.lambda));
        fig.error.push(line(&t.error));
    }
    for j in 0..N {
        fig.theta.push(Line {
            points: xy(&first.ks, first.truth.iter().map(|th| th[j])),
            color: BLACK,
            dashed: true,
            width: 1,
        });
    }
    let legend: Vec<String> = runs
        .iter()
        .enumerate()
        .map(|(m, (name, _))| format!("{name}: {}", ["red", "blue", "green"][m % 3]))
        .collect();
    draw_figure(
        path,
        &format!("{title} — {}", legend.join(", ")),
        x_max,
        &fig,
    )
}

/// Plots Monte Carlo bands: median in `color`, 5th/95th percentiles thin and light, the
/// true `θ` dashed in black.
pub fn plot_bands(path: &Path, title: &str, b: &Bands, color: RGBColor) -> Result<(), PlotError> {
    let x_max = *b.ks.last().unwrap_or(&1) as f64;
    let light = RGBColor(
        ((color.0 as u16 + 2 * 255) / 3) as u8,
        ((color.1 as u16 + 2 * 255) / 3) as u8,
        ((color.2 as u16 + 2 * 255) / 3) as u8,
    );
    let band_lines = |get: &dyn Fn(usize) -> Band, c: RGBColor, cl: RGBColor| {
        vec![
            Line {
                points: xy(&b.ks, (0..b.ks.len()).map(|i| get(i).p05)),
                color: cl,
                dashed: false,
                width: 1,
            },
            Line {
                points: xy(&b.ks, (0..b.ks.len()).map(|i| get(i).p95)),
                color: cl,
                dashed: false,
                width: 1,
            },
            Line {
                points: xy(&b.ks, (0..b.ks.len()).map(|i| get(i).p50)),
                color: c,
                dashed: false,
                width: 2,
            },
        ]
    };
    let mut theta = Vec::new();
    for (j, &c) in THETA_COLORS.iter().enumerate() {
        let cl = RGBColor(
            ((c.0 as u16 + 2 * 255) / 3) as u8,
            ((c.1 as u16 + 2 * 255) / 3) as u8,
            ((c.2 as u16 + 2 * 255) / 3) as u8,
        );
        theta.extend(band_lines(&|i| b.theta[i][j], c, cl));
        theta.push(Line {
            points: xy(&b.ks, b.truth.iter().map(|th| th[j])),
            color: BLACK,
            dashed: true,
            width: 1,
        });
    }
    let fig = Figure {
        theta,
        trace_p: band_lines(&|i| b.trace_p[i], color, light),
        lambda: band_lines(&|i| b.lambda[i], color, light),
        error: band_lines(&|i| b.error[i], color, light),
    };
    draw_figure(path, title, x_max, &fig)
}

/// Plots each noiseless RLS/FTVRF run's settling (1 %, steps after the change) against the
/// smallest singular value of its regressor matrix over the 20 steps after the change
/// ([`crate::study::forgetting::slow_runs`]); the claim's 20 steps dashed. Runs that never
/// settle are drawn at the top edge.
pub fn plot_settle_vs_excitation(
    path: &Path,
    runs: &[crate::study::forgetting::slow_runs::RunFeatures],
) -> Result<(), PlotError> {
    let pts: Vec<(f64, f64)> = runs
        .iter()
        .map(|r| {
            (
                r.excitation.sigma_min,
                r.settle.map_or(f64::INFINITY, |s| s as f64),
            )
        })
        .collect();
    let x_max = pts.iter().map(|p| p.0).fold(0.0, f64::max).max(1e-3) * 1.05;
    let finite_max = pts
        .iter()
        .map(|p| p.1)
        .filter(|v| v.is_finite())
        .fold(20.0, f64::max);
    let y_max = finite_max * 1.1 + 1.0;
    let root = BitMapBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(PlotError::backend)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Case 1 (noiseless), RLS/FTVRF: settling (1 %) vs σ_min of the regressor matrix, k = 100..119",
            (FONT, 18),
        )
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..x_max, 0.0..y_max)
        .map_err(PlotError::backend)?;
    chart
        .configure_mesh()
        .x_desc("σ_min(Φ) over the 20 steps after the change")
        .y_desc("steps to settle (1 %)")
        .label_style((FONT, 13))
        .draw()
        .map_err(PlotError::backend)?;
    chart
        .draw_series(
            pts.iter()
                .map(|&(x, y)| Circle::new((x, y.min(y_max)), 3, RGBColor(200, 0, 0).filled())),
        )
        .map_err(PlotError::backend)?;
    chart
        .draw_series(DashedLineSeries::new(
            vec![(0.0, 20.0), (x_max, 20.0)],
            6,
            4,
            ShapeStyle::from(&BLACK).stroke_width(1),
        ))
        .map_err(PlotError::backend)?;
    root.present().map_err(|e| PlotError::File {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}
