//! The color scale of the studies' heat maps (the pole plane of `study mrac`, the surface
//! grids of `study sampling-arm`): a viridis-like ramp and its color bar.

use plotters::prelude::*;

use crate::plot::{FONT, PlotError};

/// Anchor colors of the scale, low to high (a viridis-like ramp).
const RAMP: [(u8, u8, u8); 5] = [
    (68, 1, 84),
    (59, 82, 139),
    (33, 145, 140),
    (94, 201, 98),
    (253, 231, 37),
];

/// The color of `t ∈ [0, 1]` (clamped) on a viridis-like ramp from dark violet (0) to
/// yellow (1).
pub fn ramp(t: f64) -> RGBColor {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = t * (RAMP.len() - 1) as f64;
    let i = (x.floor() as usize).min(RAMP.len() - 2);
    let f = x - i as f64;
    let mix = |a: u8, b: u8| (a as f64 + f * (b as f64 - a as f64)).round() as u8;
    let (a, b) = (RAMP[i], RAMP[i + 1]);
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// The color bar of [`ramp`] over `[lo, hi]` in `area`, captioned `caption`, its labels
/// with `decimals` digits after the point (every heat map of the studies has one).
pub fn color_bar(
    area: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    (lo, hi): (f64, f64),
    caption: &str,
    decimals: usize,
) -> Result<(), PlotError> {
    let mut chart = ChartBuilder::on(area)
        .margin_top(20)
        .margin_bottom(46)
        .margin_right(10)
        .y_label_area_size(40)
        .caption(caption, (FONT, 13))
        .build_cartesian_2d(0.0..1.0, lo..hi.max(lo + 1e-9))
        .map_err(PlotError::backend)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .label_style((FONT, 12))
        .y_label_formatter(&|v| format!("{v:.decimals$}"))
        .draw()
        .map_err(PlotError::backend)?;
    const STEPS: usize = 100;
    let h = (hi - lo) / STEPS as f64;
    chart
        .draw_series((0..STEPS).map(|i| {
            let y = lo + i as f64 * h;
            Rectangle::new(
                [(0.0, y), (1.0, y + h)],
                ramp((i as f64 + 0.5) / STEPS as f64).filled(),
            )
        }))
        .map_err(PlotError::backend)?;
    Ok(())
}
