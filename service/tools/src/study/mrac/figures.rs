//! The figures of `study mrac`, in the manner of Figures 4.2–4.14.
//!
//! - [`heat_map`] (the a panels): `log₁₀‖e‖` over the upper half of the pole plane. Each
//!   grid point `(ρ_i, ν_j)` fills its cell `[ρ_i ± Δρ/2] × [ν_j ± Δν/2]` (an annular
//!   sector around the pole `ρ_i e^{jν_j}`) with the color of its `log₁₀‖e‖` on a scale
//!   common to every map of the run (the color bar at the right); an unstable point is
//!   an empty square at the pole, as in the chapter. The unit circle, the plant's zero
//!   (when inside the frame) and the reference model's pole `0.5 e^{jπ/2}` are drawn. The
//!   frame is the unit half-disc, or the grid's half-disc when it reaches past the unit
//!   circle (the outward reading, [`crate::study::mrac::outward`]).
//! - [`single_run`] (the b panels): `e_k`, `u_k` and the two groups of `θ̂_k`, clockwise
//!   from the top left as the chapter: `e`, `u`, then `θ̂_2` (Bezout) and `θ̂_1`
//!   (controller) for APPC, `θ̂` of `r` and `θ̂` of `y`, `u` for RC-MRAC.

use std::f64::consts::PI;
use std::path::Path;

use plotters::prelude::*;

use crate::plot::{self, FONT, Mark, PALETTE, Panel, PlotError, Series, register_font};
use crate::study::common::color_scale::{color_bar, ramp};
use crate::study::mrac::closed_loop::RunTrace;
use crate::study::mrac::grid::{Grid, Sweep};
use crate::study::mrac::setup::{Example, Method, theta_names};

/// The heat map of `sweep` on `grid` into `path`, colors scaled on `[lo, hi]`
/// (`log₁₀‖e‖`).
pub fn heat_map(
    path: &Path,
    title: &str,
    sweep: &Sweep,
    grid: &Grid,
    (lo, hi): (f64, f64),
) -> Result<(), PlotError> {
    register_font()?;
    let fail = |e: &dyn std::fmt::Display| PlotError::drawing(path, e);
    let root = BitMapBackend::new(path, (900, 450)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let root = root.titled(title, (FONT, 18)).map_err(|e| fail(&e))?;
    let (left, right) = root.split_horizontally(780);
    // The unit disc's upper half, or the grid's when it reaches past the unit circle.
    let reach = grid.rho.iter().copied().fold(1.0, f64::max) * 1.05;
    let mut chart = ChartBuilder::on(&left)
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(48)
        .build_cartesian_2d(-reach..reach, 0.0..reach)
        .map_err(|e| fail(&e))?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("Re of the pole ρe^(jν)")
        .y_desc("Im of the pole")
        .label_style((FONT, 12))
        .draw()
        .map_err(|e| fail(&e))?;
    let d_rho = step_of(&grid.rho, 1.0);
    let d_nu = step_of(&grid.nu, PI);
    let span = (hi - lo).max(1e-12);
    for p in &sweep.points {
        if p.unstable() {
            continue;
        }
        let color = ramp((p.e_norm.log10() - lo) / span);
        let cell = sector(p.rho, p.nu, d_rho, d_nu);
        chart
            .draw_series(std::iter::once(Polygon::new(cell, color.filled())))
            .map_err(|e| fail(&e))?;
    }
    let half = 0.3 * d_rho;
    let empty: Vec<_> = sweep
        .points
        .iter()
        .filter(|p| p.unstable())
        .map(|p| {
            let (x, y) = (p.rho * p.nu.cos(), p.rho * p.nu.sin());
            Rectangle::new(
                [(x - half, y - half), (x + half, y + half)],
                BLACK.stroke_width(2),
            )
        })
        .collect();
    chart.draw_series(empty).map_err(|e| fail(&e))?;
    let circle: Vec<(f64, f64)> = (0..=180)
        .map(|i| {
            let a = PI * i as f64 / 180.0;
            (a.cos(), a.sin())
        })
        .collect();
    chart
        .draw_series(LineSeries::new(circle, BLACK.stroke_width(1)))
        .map_err(|e| fail(&e))?;
    let zero = sweep.example.plant().zero();
    if zero <= reach {
        chart
            .draw_series(std::iter::once(Circle::new(
                (zero, 0.0),
                6,
                RED.stroke_width(2),
            )))
            .map_err(|e| fail(&e))?
            .label(format!("plant zero {zero}"))
            .legend(|(x, y)| Circle::new((x, y), 5, RED.stroke_width(2)));
    }
    chart
        .draw_series(std::iter::once(Cross::new(
            (0.0, 0.5),
            6,
            RED.stroke_width(2),
        )))
        .map_err(|e| fail(&e))?
        .label("reference pole 0.5j")
        .legend(|(x, y)| Cross::new((x, y), 5, RED.stroke_width(2)));
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [(4.0 * reach, 4.0 * reach), (4.0 * reach, 4.0 * reach)],
            BLACK.stroke_width(2),
        )))
        .map_err(|e| fail(&e))?
        .label(format!("unstable ({})", sweep.unstable()))
        .legend(|(x, y)| Rectangle::new([(x - 5, y - 5), (x + 5, y + 5)], BLACK.stroke_width(2)));
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font((FONT, 12))
        .draw()
        .map_err(|e| fail(&e))?;
    color_bar(&right, (lo, hi), "log10 ‖e‖", 1).map_err(|e| fail(&e))?;
    root.present().map_err(|e| fail(&e))
}

/// The spacing of evenly spaced values (`whole` for a single value, its cell the whole
/// range).
fn step_of(v: &[f64], whole: f64) -> f64 {
    match v {
        [a, b, ..] => b - a,
        _ => whole,
    }
}

/// The corners of the annular sector around `ρ e^{jν}`, sampled along the arcs.
fn sector(rho: f64, nu: f64, d_rho: f64, d_nu: f64) -> Vec<(f64, f64)> {
    let (r0, r1) = ((rho - d_rho / 2.0).max(0.0), rho + d_rho / 2.0);
    let (a0, a1) = (nu - d_nu / 2.0, nu + d_nu / 2.0);
    const ARC: usize = 8;
    let arc = |r: f64, rev: bool| {
        (0..=ARC).map(move |i| {
            let i = if rev { ARC - i } else { i };
            let a = a0 + (a1 - a0) * i as f64 / ARC as f64;
            (r * a.cos(), r * a.sin())
        })
    };
    arc(r1, false).chain(arc(r0, true)).collect()
}

/// The four panels of a single run into `path` (see the module documentation).
pub fn single_run(
    path: &Path,
    title: &str,
    example: Example,
    method: Method,
    trace: &RunTrace,
) -> Result<(), PlotError> {
    let k: Vec<f64> = (0..trace.e.len()).map(|k| k as f64).collect();
    let names = theta_names(example, method);
    // Controller (or y/u) coefficients first: the 2n entries of N_c and D_c.
    let split = names
        .iter()
        .take_while(|n| n.starts_with("nc") || n.starts_with("dc"))
        .count();
    let group = |range: std::ops::Range<usize>| -> Vec<Series> {
        range
            .enumerate()
            .map(|(c, i)| {
                let y: Vec<f64> = trace.theta.iter().map(|t| t[i]).collect();
                let s = Series::line(&names[i], &k, &y, PALETTE[c % PALETTE.len()]);
                if c >= PALETTE.len() {
                    s.with(Mark::Dashed)
                } else {
                    s
                }
            })
            .collect()
    };
    let panel = |title: &str, y_label: &str, series: Vec<Series>| Panel {
        title: title.into(),
        x_label: "step k".into(),
        y_label: y_label.into(),
        series,
        ..Panel::default()
    };
    let (first, second) = match method {
        Method::Appc => (
            "controller coefficients θ̂_1 (N_c, D_c)",
            "Bezout coefficients θ̂_2 (B, C)",
        ),
        _ => ("θ̂ of y and u (N_c, D_c)", "θ̂ of r (R_c)"),
    };
    let panels = [
        panel(
            "model-following error e_k",
            "e",
            vec![Series::line("e", &k, &trace.e, PALETTE[1])],
        ),
        panel(
            "control input u_k",
            "u",
            vec![Series::line("u", &k, &trace.u, PALETTE[0])],
        ),
        panel(first, "θ̂", group(0..split)),
        panel(second, "θ̂", group(split..names.len())),
    ];
    plot::figure(path, title, (2, 2), (1200, 800), &panels)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ramp_runs_from_its_first_to_its_last_anchor_and_clamps() {
        assert_eq!(ramp(0.0), RGBColor(68, 1, 84));
        assert_eq!(ramp(1.0), RGBColor(253, 231, 37));
        assert_eq!(ramp(-3.0), ramp(0.0));
        assert_eq!(ramp(7.0), ramp(1.0));
        assert_eq!(ramp(0.25), RGBColor(59, 82, 139));
    }

    #[test]
    fn a_sector_surrounds_its_pole() {
        let s = sector(0.5, PI / 4.0, 0.1, 0.2);
        assert_eq!(s.len(), 18);
        let r: Vec<f64> = s.iter().map(|(x, y)| x.hypot(*y)).collect();
        assert!(r.iter().all(|r| (0.45 - 1e-12..=0.55 + 1e-12).contains(r)));
    }
}
