//! The two examples of section 3.2 on the structure (3.41), for side-by-side printing.
//!
//! ```text
//! G(s) = (20π)² / (s² + 2π s + (20π)²)      ω_n = 20π rad/s, ζ = 0.05              (3.41)
//! ```
//!
//! discretized with a zero-order hold at `T_s = 0.01` s (here with
//! [`plant_proxy::lti::StateSpace::c2d_zoh`] and `channel_tf`, not typed in), which the
//! dissertation prints as
//!
//! ```text
//! G_d(z) = (0.1871 z + 0.1831) / (z² − 1.569 z + 0.9391)                                  (3.42)
//! ```
//!
//! - §3.2.1.1: windowed average with `Δ = 10π` rad/s `= 0.1π` rad/sample and a fit with
//!   `n̂ = 2` poles and one zero (the relative degree of `G_d`). Printed:
//!   `(0.1842 z + 0.181)/(z² − 1.333 z + 0.6814)` (3.43), poles of radius 0.8255 at
//!   ±0.631 rad/sample (≈ 20π rad/s), ζ ≈ 0.29.
//! - §3.2.2.1: optimization with `n̂_max = 1` and the relative degree of `G_d` (so no zero).
//!   Printed: `0.5126/(z − 0.5544)` (3.48).
//!
//! **What is reproduced.** (3.42) to all printed digits. (3.48) to about three digits with
//! the default grid `2·10⁻³π … π` ([`super::DEFAULT_THETA_LO`]): the result depends on the
//! lower end of the grid only (a lower end of `10⁻³π` gives pole 0.5525, gain 0.507; `10⁻²`
//! rad/sample gives 0.5565, 0.519), so the dissertation's grid most likely started near
//! 0.1 Hz.
//!
//! **What is not.** (3.43) is not reproduced by the fit implemented here (SK iterations to
//! convergence on a uniform grid with `dθ` weights), which gives poles of radius ≈ 0.74 at
//! the same angle and a zero outside the unit circle near −1.6; see [`Example341`] for the
//! numbers. Readings tried: linear or logarithmic grid, 100 to 2000 points, exact or on-grid
//! averaging (trapezoid or plain mean of the samples in the window), equation error (Levy,
//! one SK iteration), SK to convergence, true output error (Gauss–Newton) and a zero fixed
//! near −0.98. The closest is Levy's equation-error fit on a uniform grid
//! ([`Example341::levy`]): denominator `z² − 1.308 z + 0.659` (pole radius 0.812 vs 0.826,
//! angle 0.634 vs 0.631 rad/sample), numerator (re-solved for that denominator) `0.182 z + 0.200` (zero −1.10 vs −0.983).
//! The printed zero (−0.983) lies close to that of `G_d` (−0.979) and inside the unit circle,
//! which suggests that Algorithm 1 of \[65\] constrains or initializes the numerator
//! differently (for example minimum-phase zeros); without \[65\] this is not settled, so the
//! tests assert properties of the averaged DTF (stability, relative degree, fit error, the
//! phase trend, poles near the resonance frequency) rather than the printed coefficients.

use super::{
    Dtf, DtfError, ZeroCount, default_log_grid, fit, fit_iterations, linear_fit_error, log_cost,
    optimize_all, windowed_average_of,
};
use crate::design::C64;
use plant_proxy::lti::Tf;
use std::f64::consts::PI;

/// Points of the uniform grid `0 … π` on which the windowed average is fitted.
pub const EXAMPLE_LINEAR_POINTS: usize = 512;

/// Simpson sub-intervals per window for the windowed average of the model.
pub const EXAMPLE_WINDOW_INTERVALS: usize = 2000;

/// The two DTF examples of section 3.2 and the dissertation's printed results.
#[derive(Debug, Clone)]
pub struct Example341 {
    /// Sample period, s (0.01).
    pub ts: f64,
    /// (3.41) discretized here: `G_d(z)`.
    pub gd: Dtf,
    /// The printed (3.42).
    pub printed_3_42: Dtf,
    /// Window half-width `Δ`, rad/sample (`10π` rad/s · `T_s`).
    pub delta: f64,
    /// The uniform grid of the windowed average, rad/sample.
    pub linear_grid: Vec<f64>,
    /// `Ḡ_d(e^{jθ})` (3.40) on `linear_grid`.
    pub averaged_response: Vec<C64>,
    /// The windowed-average DTF, `n̂ = 2`, one zero ([`fit`]).
    pub averaged: Dtf,
    /// The same fit with a single SK iteration (Levy's equation error), the closest reading
    /// of (3.43) found.
    pub levy: Dtf,
    /// The printed (3.43).
    pub printed_3_43: Dtf,
    /// Relative RMS error of `averaged` to `Ḡ_d` ([`linear_fit_error`]).
    pub averaged_fit_error: f64,
    /// The same measure for `levy`.
    pub levy_fit_error: f64,
    /// The same measure for the printed (3.43).
    pub printed_3_43_fit_error: f64,
    /// The logarithmic grid of the optimization, rad/sample ([`default_log_grid`]).
    pub log_grid: Vec<f64>,
    /// The optimization DTF, `n̂_max = 1`, relative degree of `G_d` ([`super::optimize`]).
    pub optimized: Dtf,
    /// Its relative cost (3.44) ([`log_cost`]).
    pub optimized_cost: f64,
    /// The printed (3.48).
    pub printed_3_48: Dtf,
    /// The relative cost (3.44) of the printed (3.48) on the same grid.
    pub printed_3_48_cost: f64,
}

/// Runs both examples (see the module docs).
pub fn example_3_41() -> Result<Example341, DtfError> {
    let ts = 0.01;
    let wn = 20.0 * PI;
    let g = Tf::new(vec![wn * wn], vec![1.0, 2.0 * PI, wn * wn])?;
    let ss = g.realize().c2d_zoh(ts)?;
    let gd = Dtf::from_state_space(&ss, 0, 0)?;
    let printed_3_42 = Dtf::new(vec![0.1871, 0.1831], vec![1.0, -1.569, 0.9391])?;
    let printed_3_43 = Dtf::new(vec![0.1842, 0.181], vec![1.0, -1.333, 0.6814])?;
    let printed_3_48 = Dtf::new(vec![0.5126], vec![1.0, -0.5544])?;

    let delta = 10.0 * PI * ts;
    let linear_grid = crate::design::grid(0.0, PI, EXAMPLE_LINEAR_POINTS, false)?;
    let averaged_response = windowed_average_of(
        |nu| gd.eval(nu),
        &linear_grid,
        delta,
        EXAMPLE_WINDOW_INTERVALS,
    )?;
    let m = gd.order() - gd.relative_degree();
    let averaged = fit(&linear_grid, &averaged_response, None, 2, m)?;
    let levy = fit_iterations(&linear_grid, &averaged_response, None, 2, m, 1)?;
    let averaged_fit_error = linear_fit_error(&linear_grid, &averaged_response, &averaged)?;
    let levy_fit_error = linear_fit_error(&linear_grid, &averaged_response, &levy)?;
    let printed_3_43_fit_error = linear_fit_error(&linear_grid, &averaged_response, &printed_3_43)?;

    let log_grid = default_log_grid();
    let response = gd.response(&log_grid);
    let opt = optimize_all(
        &log_grid,
        &response,
        1,
        ZeroCount::RelativeDegree(gd.relative_degree()),
    )?;
    let printed_3_48_cost = log_cost(&log_grid, &response, &printed_3_48)?;
    Ok(Example341 {
        ts,
        gd,
        printed_3_42,
        delta,
        linear_grid,
        averaged_response,
        averaged,
        levy,
        printed_3_43,
        averaged_fit_error,
        levy_fit_error,
        printed_3_43_fit_error,
        log_grid,
        optimized: opt.best,
        optimized_cost: opt.relative_cost,
        printed_3_48,
        printed_3_48_cost,
    })
}

/// `c_0 z^n + … + c_n` as text, six decimals, `z^k` powers (coefficients in descending
/// powers, as [`Dtf`] holds them).
pub fn format_poly(c: &[f64]) -> String {
    let n = c.len() - 1;
    let mut s = String::new();
    for (i, &v) in c.iter().enumerate() {
        let p = n - i;
        let mag = v.abs();
        let sign = if v < 0.0 { "−" } else { "+" };
        if i == 0 {
            if v < 0.0 {
                s.push('−');
            }
        } else {
            s.push_str(&format!(" {sign} "));
        }
        let coef = if mag == 1.0 && p > 0 {
            String::new()
        } else {
            format!("{mag:.6}")
        };
        let sep = if coef.is_empty() || p == 0 { "" } else { " " };
        match p {
            0 => s.push_str(&coef),
            1 => s.push_str(&format!("{coef}{sep}z")),
            _ => s.push_str(&format!("{coef}{sep}z^{p}")),
        }
    }
    s
}

/// Roots as text, `re±imj`, four decimals, comma separated.
pub fn format_roots(r: &[C64]) -> String {
    r.iter()
        .map(|v| format!("{:.4}{:+.4}j", v.re, v.im))
        .collect::<Vec<_>>()
        .join(", ")
}

fn line(name: &str, d: &Dtf) -> String {
    let poles = d
        .poles()
        .map(|r| format_roots(&r))
        .unwrap_or_else(|e| e.to_string());
    let zeros = d
        .zeros()
        .map(|r| format_roots(&r))
        .unwrap_or_else(|e| e.to_string());
    format!(
        "  {name:<22} ({}) / ({})\n  {:<22} poles [{poles}], zeros [{zeros}], DC gain {:.4}\n",
        format_poly(&d.num),
        format_poly(&d.den),
        "",
        d.dc_gain()
    )
}

/// [`line`] and a measure of the fit under it: `what` and `value`, already formatted.
fn line_with(name: &str, d: &Dtf, what: &str, value: String) -> String {
    format!("{}  {:<22} {what} {value}\n", line(name, d), "")
}

impl Example341 {
    /// A plain-text side-by-side report of both examples.
    pub fn report(&self) -> String {
        let mut s = String::new();
        s.push_str(&format!(
            "(3.41) G(s) = (20π)²/(s² + 2π s + (20π)²) discretized with a ZOH at T_s = {} s\n",
            self.ts
        ));
        s.push_str(&line("computed G_d", &self.gd));
        s.push_str(&line("printed (3.42)", &self.printed_3_42));
        s.push_str(&format!(
            "\n§3.2.1.1 windowed average, Δ = {:.4} rad/sample, n̂ = 2, {} zero(s), {} grid points 0…π\n",
            self.delta,
            self.averaged.num.len() - 1,
            self.linear_grid.len()
        ));
        s.push_str(&line_with(
            "SK fit (this code)",
            &self.averaged,
            "relative RMS error to Ḡ_d",
            format!("{:.4}", self.averaged_fit_error),
        ));
        s.push_str(&line_with(
            "Levy (1 SK iteration)",
            &self.levy,
            "relative RMS error to Ḡ_d",
            format!("{:.4}", self.levy_fit_error),
        ));
        s.push_str(&line_with(
            "printed (3.43)",
            &self.printed_3_43,
            "relative RMS error to Ḡ_d",
            format!("{:.4}", self.printed_3_43_fit_error),
        ));
        s.push_str(&format!(
            "\n§3.2.2.1 optimization, n̂_max = 1, {} log-spaced points {:.5}…π rad/sample\n",
            self.log_grid.len(),
            self.log_grid[0]
        ));
        s.push_str(&line_with(
            "optimized (this code)",
            &self.optimized,
            "relative cost (3.44)",
            format!("{:.6}", self.optimized_cost),
        ));
        s.push_str(&line_with(
            "printed (3.48)",
            &self.printed_3_48,
            "relative cost (3.44)",
            format!("{:.6}", self.printed_3_48_cost),
        ));
        s
    }
}
