//! The figures of `study sampling-arm`, in the manner of Figures 7.3–7.8.
//!
//! - [`heat_map`] (Figures 7.3 and 7.5): the median contact force over the contact phase
//!   on the `k_s × c` grid, log axes; each point fills the cell between the geometric
//!   midpoints to its neighbours with the color of its median on the fixed scale
//!   `[0, 30]` N (the color bar; the same in every map, so that the maps compare), and
//!   prints the value; a failed run is a black cross.
//! - [`run_figure`] (Figures 7.4 and 7.6): contact force with `F_d`, sampler velocity
//!   `ẋ`, `ẏ`, torques `τ1`, `τ2`, for both controllers, and the augmented controller's
//!   PCAC coefficients (the 35 entries of `Θ̃_k`); for the double maneuver (Figures 7.7
//!   and 7.8) the same over both contacts with `λ_k` and `tr P_k` of the identification.

use std::path::Path;

use plotters::prelude::*;

use crate::plot::{self, FONT, Mark, PALETTE, Panel, PlotError, Series, register_font};
use crate::study::arm::closed_loop::{F_D, Law, Trace};
use crate::study::arm::grid::{Grid, GridPoint};
use crate::study::common::color_scale::{color_bar, ramp};

/// The color scale of the heat maps, N.
pub const SCALE: (f64, f64) = (0.0, 30.0);

/// The cell edges around log-spaced `v`: geometric midpoints, the ends extended by the
/// same ratio.
fn edges(v: &[f64]) -> Vec<f64> {
    let n = v.len();
    let mut e = Vec::with_capacity(n + 1);
    let r = if n > 1 { (v[1] / v[0]).sqrt() } else { 2.0 };
    e.push(v[0] / r);
    for i in 1..n {
        e.push((v[i - 1] * v[i]).sqrt());
    }
    let r = if n > 1 {
        (v[n - 1] / v[n - 2]).sqrt()
    } else {
        2.0
    };
    e.push(v[n - 1] * r);
    e
}

/// The heat map of `points` (one law on `grid`, in the order of [`Grid::points`]) into
/// `path`.
pub fn heat_map(
    path: &Path,
    title: &str,
    grid: &Grid,
    points: &[&GridPoint],
) -> Result<(), PlotError> {
    register_font()?;
    let fail = |e: &dyn std::fmt::Display| PlotError::drawing(path, e);
    let root = BitMapBackend::new(path, (900, 650)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let root = root.titled(title, (FONT, 18)).map_err(|e| fail(&e))?;
    let (left, right) = root.split_horizontally(800);
    let (kx, cy) = (edges(&grid.k_s), edges(&grid.c));
    let mut chart = ChartBuilder::on(&left)
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(
            (kx[0]..kx[kx.len() - 1]).log_scale(),
            (cy[0]..cy[cy.len() - 1]).log_scale(),
        )
        .map_err(|e| fail(&e))?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("k_s")
        .y_desc(grid.model.second())
        .label_style((FONT, 12))
        .draw()
        .map_err(|e| fail(&e))?;
    let n = grid.c.len();
    for (idx, p) in points.iter().enumerate() {
        let (i, j) = (idx / n, idx % n);
        let cell = [(kx[i], cy[j]), (kx[i + 1], cy[j + 1])];
        if p.failed() || !p.median.is_finite() {
            chart
                .draw_series(std::iter::once(Cross::new(
                    (grid.k_s[i], grid.c[j]),
                    8,
                    BLACK.stroke_width(2),
                )))
                .map_err(|e| fail(&e))?;
            continue;
        }
        let color = ramp((p.median - SCALE.0) / (SCALE.1 - SCALE.0));
        chart
            .draw_series(std::iter::once(Rectangle::new(cell, color.filled())))
            .map_err(|e| fail(&e))?;
        let text_color = if p.median > 18.0 { BLACK } else { WHITE };
        chart
            .draw_series(std::iter::once(Text::new(
                format!("{:.1}", p.median),
                (grid.k_s[i], grid.c[j]),
                (FONT, 11).into_font().color(&text_color).pos(
                    plotters::style::text_anchor::Pos::new(
                        plotters::style::text_anchor::HPos::Center,
                        plotters::style::text_anchor::VPos::Center,
                    ),
                ),
            )))
            .map_err(|e| fail(&e))?;
    }
    color_bar(&right, SCALE, "F_c (N)", 0).map_err(|e| fail(&e))?;
    root.present().map_err(|e| fail(&e))
}

/// A time-series panel.
fn panel(title: &str, y_label: &str, series: Vec<Series>) -> Panel {
    Panel {
        title: title.into(),
        x_label: "t (s)".into(),
        y_label: y_label.into(),
        series,
        ..Panel::default()
    }
}

/// The panels of one controller's run: force, velocity, torques.
fn law_panels(law: Law, t: &Trace) -> Vec<Panel> {
    // One panel of `what` (in `unit`) with two signals, each `(name, values, color)`.
    let two = |what: &str, unit: &str, a: (&str, &[f64], usize), b: (&str, &[f64], usize)| {
        panel(
            &format!("{}: {what}", law.label()),
            unit,
            vec![
                Series::line(a.0, &t.t, a.1, PALETTE[a.2]),
                Series::line(b.0, &t.t, b.1, PALETTE[b.2]),
            ],
        )
    };
    let mut force = two("contact force", "N", ("F_c", &t.force, 0), ("F_d", &t.r, 1));
    force.series[1].mark = Mark::Dashed;
    vec![
        force,
        two("sampler velocity", "m/s", ("ẋ", &t.xd, 0), ("ẏ", &t.yd, 2)),
        two(
            "joint torques",
            "N m",
            ("τ1", &t.tau1, 0),
            ("τ2", &t.tau2, 3),
        ),
    ]
}

/// The 35 coefficients of `Θ̃_k` over time (every entry one line).
fn theta_panel(t: &Trace) -> Panel {
    let n = t.theta.first().map_or(0, Vec::len);
    let series = (0..n)
        .map(|i| {
            let y: Vec<f64> = t.theta.iter().map(|th| th[i]).collect();
            Series::line(
                if i == 0 { "entries of Θ̃" } else { "" },
                &t.t,
                &y,
                PALETTE[i % PALETTE.len()],
            )
        })
        .collect();
    panel(
        "PCAC augmented controller: model coefficients Θ̃_k (35)",
        "",
        series,
    )
}

/// The panels of [`law_panels`] of both controllers side by side, row by row (robust left).
fn both_laws(robust: &Trace, augmented: &Trace) -> Vec<Panel> {
    law_panels(Law::Robust, robust)
        .into_iter()
        .zip(law_panels(Law::Augmented, augmented))
        .flat_map(|(r, a)| [r, a])
        .collect()
}

/// The contact force of both controllers, as two series.
fn forces(robust: &Trace, augmented: &Trace) -> Vec<Series> {
    vec![
        Series::line("robust", &robust.t, &robust.force, PALETTE[1]),
        Series::line("augmented", &augmented.t, &augmented.force, PALETTE[0]),
    ]
}

/// Figure 7.4 / 7.6 (`double` false: both controllers' runs on one surface) or 7.7 / 7.8
/// (`double`: the double maneuver, with `λ_k` and `tr P_k`) into `path`.
pub fn run_figure(
    path: &Path,
    title: &str,
    (robust, augmented): (&Trace, &Trace),
    double: bool,
) -> Result<(), PlotError> {
    let mut panels = both_laws(robust, augmented);
    let identification = |title: &str, y_label: &str, name: &str, v: &[f64], color: usize| {
        panel(
            title,
            y_label,
            vec![Series::line(name, &augmented.t, v, PALETTE[color])],
        )
    };
    if double {
        panels.push(identification(
            "PCAC augmented controller: forgetting factor λ_k",
            "λ",
            "λ_k",
            &augmented.lambda,
            0,
        ));
        panels.push(identification(
            "PCAC augmented controller: tr P_k",
            "tr P",
            "tr P_k",
            &augmented.trace_p,
            3,
        ));
    }
    panels.push(theta_panel(augmented));
    let mut force = forces(robust, augmented);
    if !double {
        let fd = vec![F_D; augmented.t.len()];
        force.push(Series::line("F_d = 25 N", &augmented.t, &fd, BLACK).with(Mark::Dashed));
    }
    panels.push(panel("contact force, both controllers", "N", force));
    let (layout, size) = if double {
        ((5, 2), (1400, 1800))
    } else {
        ((4, 2), (1400, 1500))
    };
    plot::figure(path, title, layout, size, &panels)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_edges_are_geometric_midpoints() {
        let e = edges(&[1.0, 100.0, 10_000.0]);
        assert_eq!(e.len(), 4);
        for (a, b) in e.iter().zip([0.1, 10.0, 1000.0, 100_000.0]) {
            assert!((a / b - 1.0).abs() < 1e-12, "{a} {b}");
        }
    }
}
