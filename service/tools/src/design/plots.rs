//! The design tools' figures: Bode plots of responses side by side with a pole–zero map,
//! in the manner of Figures 3.3, 3.4, 3.6 and 3.9 of the dissertation, and coherence.
//!
//! Magnitudes are in dB (`20 log10 |G(e^{jθ})|`), phases in degrees, unwrapped along the
//! grid, frequencies in Hz on a logarithmic axis (the bin at θ = 0 is left out).

use super::C64;
use crate::plot::{Mark, PALETTE, Panel, PlotError, Series, figure};
use std::path::Path;

/// A named response on the figure's grid.
pub struct Curve<'a> {
    /// Legend text.
    pub label: &'a str,
    /// `G(e^{jθ_k})` on the grid.
    pub response: &'a [C64],
    /// Draw dashed.
    pub dashed: bool,
    /// Also draw its phase (false for an error curve, whose phase means nothing).
    pub phase: bool,
}

/// A named set of poles and zeros.
pub struct PoleZero<'a> {
    /// Legend text (", poles"/", zeros" appended).
    pub label: &'a str,
    /// Poles.
    pub poles: &'a [C64],
    /// Zeros.
    pub zeros: &'a [C64],
}

impl<'a> Curve<'a> {
    /// A solid curve with magnitude and phase.
    pub fn new(label: &'a str, response: &'a [C64]) -> Self {
        Self {
            label,
            response,
            dashed: false,
            phase: true,
        }
    }

    /// The same curve dashed.
    pub fn dashed(mut self) -> Self {
        self.dashed = true;
        self
    }

    /// The same curve without its phase.
    pub fn magnitude_only(mut self) -> Self {
        self.phase = false;
        self
    }
}

/// Phase in degrees, unwrapped along the grid, starting in `(−270°, 90°]` (so that curves
/// with a negative low-frequency gain all start near −180°, not some at +180°).
pub fn unwrapped_phase_deg(g: &[C64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(g.len());
    let mut offset = 0.0;
    let mut prev: Option<f64> = None;
    for v in g {
        let a = v.arg().to_degrees();
        if let Some(p) = prev {
            let mut d = a + offset - p;
            while d > 180.0 {
                offset -= 360.0;
                d -= 360.0;
            }
            while d < -180.0 {
                offset += 360.0;
                d += 360.0;
            }
        }
        let u = a + offset;
        out.push(u);
        prev = Some(u);
    }
    if out.first().is_some_and(|p| *p > 90.0) {
        out.iter_mut().for_each(|p| *p -= 360.0);
    }
    out
}

/// An empty panel over a logarithmic axis in Hz.
fn hz_panel(title: &str, y_label: &str) -> Panel {
    Panel {
        title: title.into(),
        x_label: "Hz".into(),
        y_label: y_label.into(),
        x_log: true,
        ..Default::default()
    }
}

/// The roots `z` in the complex plane, each drawn as `mark`.
fn roots(label: &str, z: &[C64], color: plotters::style::RGBColor, mark: Mark) -> Series {
    let re: Vec<f64> = z.iter().map(|c| c.re).collect();
    let im: Vec<f64> = z.iter().map(|c| c.im).collect();
    Series::line(label, &re, &im, color).with(mark)
}

/// Writes a figure with magnitude and phase of `curves` over `hz` and, when `pz` is not
/// empty, a pole–zero map.
pub fn bode_figure(
    path: &Path,
    title: &str,
    hz: &[f64],
    curves: &[Curve<'_>],
    pz: &[PoleZero<'_>],
) -> Result<(), PlotError> {
    let keep: Vec<usize> = (0..hz.len()).filter(|&k| hz[k] > 0.0).collect();
    let x: Vec<f64> = keep.iter().map(|&k| hz[k]).collect();
    let mut mag = hz_panel("magnitude", "dB");
    let mut phase = hz_panel("phase", "degrees");
    for (i, c) in curves.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        let mark = if c.dashed { Mark::Dashed } else { Mark::Line };
        let g: Vec<C64> = keep.iter().map(|&k| c.response[k]).collect();
        let db: Vec<f64> = g.iter().map(|v| 20.0 * v.norm().log10()).collect();
        mag.series
            .push(Series::line(c.label, &x, &db, color).with(mark));
        if c.phase {
            phase
                .series
                .push(Series::line(c.label, &x, &unwrapped_phase_deg(&g), color).with(mark));
        }
    }
    let mut panels = vec![mag, phase];
    if !pz.is_empty() {
        let mut map = Panel {
            title: "poles (×) and zeros (o)".into(),
            x_label: "Re z".into(),
            y_label: "Im z".into(),
            unit_circle: true,
            ..Default::default()
        };
        for (i, s) in pz.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            map.series.push(roots(
                &format!("{}, poles", s.label),
                s.poles,
                color,
                Mark::Cross,
            ));
            map.series.push(roots(
                &format!("{}, zeros", s.label),
                s.zeros,
                color,
                Mark::Circle,
            ));
        }
        panels.push(map);
        figure(path, title, (1, 3), (1800, 600), &panels)
    } else {
        figure(path, title, (2, 1), (1000, 900), &panels)
    }
}

/// Writes the multiple coherence of each output over `hz`.
pub fn coherence_figure(
    path: &Path,
    title: &str,
    hz: &[f64],
    coherence: &[Vec<f64>],
) -> Result<(), PlotError> {
    let keep: Vec<usize> = (0..hz.len()).filter(|&k| hz[k] > 0.0).collect();
    let x: Vec<f64> = keep.iter().map(|&k| hz[k]).collect();
    let series = coherence
        .iter()
        .enumerate()
        .map(|(o, c)| {
            let y: Vec<f64> = keep.iter().map(|&k| c[k]).collect();
            Series::line(&format!("output {o}"), &x, &y, PALETTE[o % PALETTE.len()])
        })
        .collect();
    let panel = Panel {
        y_range: Some((0.0, 1.05)),
        series,
        ..hz_panel("multiple coherence", "γ²")
    };
    figure(path, title, (1, 1), (1000, 450), &[panel])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phase_is_unwrapped_across_the_branch_cut() {
        // A pure delay of 3 samples: phase −3θ, crossing −180° twice on [0, π].
        let th: Vec<f64> = (0..100)
            .map(|k| k as f64 * std::f64::consts::PI / 99.0)
            .collect();
        let g: Vec<C64> = th.iter().map(|t| C64::from_polar(1.0, -3.0 * t)).collect();
        let ph = unwrapped_phase_deg(&g);
        for (p, t) in ph.iter().zip(&th) {
            assert!((p + 3.0 * t.to_degrees()).abs() < 1e-9, "{p} at {t}");
        }
    }
}
