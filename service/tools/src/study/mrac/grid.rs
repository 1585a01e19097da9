//! The sweep of `study mrac` over the plant's pole location `ρ e^{±jν}` (Figures
//! 4.2a–4.14a), in parallel with rayon, and its CSV.
//!
//! An `N × N` grid inside the upper half of the unit disc:
//!
//! ```text
//! ρ_i = i / (N + 1),          i = 1 … N   (evenly in (0, 1), both ends excluded)
//! ν_j = (j − 1/2) π / N,      j = 1 … N   (cell midpoints of (0, π))
//! ```
//!
//! so every plant is asymptotically stable and has complex poles; the default `N = 15`
//! is 225 plants per example, command and method.

use crate::file_error::{FileError, FileOp};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::Path;

use crate::study::mrac::closed_loop::{self, Divergence};
use crate::study::mrac::run_settings::RunSettings;
use crate::study::mrac::setup::{CommandKind, Example, Method};
use crate::study::mrac::{ArgError, MracError};

/// The `(ρ, ν)` grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    /// `ρ_1 < … < ρ_N`.
    pub rho: Vec<f64>,
    /// `ν_1 < … < ν_N`, rad.
    pub nu: Vec<f64>,
}

impl Grid {
    /// The `n × n` grid of the module documentation; `n` at least 1.
    pub fn new(n: usize) -> Result<Self, ArgError> {
        if n == 0 {
            return Err(ArgError::NoGrid);
        }
        let rho = (1..=n).map(|i| i as f64 / (n + 1) as f64).collect();
        let nu = (1..=n)
            .map(|j| (j as f64 - 0.5) * std::f64::consts::PI / n as f64)
            .collect();
        Ok(Self { rho, nu })
    }

    /// Every `(ρ, ν)`, `ρ` outer.
    pub fn points(&self) -> Vec<(f64, f64)> {
        self.rho
            .iter()
            .flat_map(|&r| self.nu.iter().map(move |&v| (r, v)))
            .collect()
    }
}

/// One grid point's result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridPoint {
    /// Pole radius.
    pub rho: f64,
    /// Pole angle, rad.
    pub nu: f64,
    /// ‖e‖ (4.85); `+∞` when unstable.
    pub e_norm: f64,
    /// Why and where the run diverged, if it did.
    pub diverged: Option<(Divergence, usize)>,
    /// The largest `|y_k|` of the run.
    pub peak_y: f64,
    /// When `θ̂_k` settles ([`crate::study::mrac::theta_settling`]); `None` when unstable.
    pub theta_settle: Option<usize>,
}

impl GridPoint {
    /// True when the run diverged.
    pub fn unstable(&self) -> bool {
        self.diverged.is_some()
    }

    /// The run's outcome as the CSV columns `e_norm, unstable, diverged_at, peak_y,
    /// theta_settle` (shared by `grid.csv` and `grid-outward.csv`).
    pub fn csv_outcome(&self) -> String {
        format!(
            "{:.6e},{},{},{:.6e},{}",
            self.e_norm,
            u8::from(self.unstable()),
            self.diverged
                .map(|(_, k)| k.to_string())
                .unwrap_or_default(),
            self.peak_y,
            self.theta_settle.map(|k| k.to_string()).unwrap_or_default()
        )
    }
}

/// The grid of one example, command and method.
#[derive(Debug, Clone)]
pub struct Sweep {
    /// The example.
    pub example: Example,
    /// The command.
    pub command: CommandKind,
    /// The method.
    pub method: Method,
    /// One entry per grid point, in the order of [`Grid::points`].
    pub points: Vec<GridPoint>,
}

impl Sweep {
    /// The number of unstable points.
    pub fn unstable(&self) -> usize {
        self.points.iter().filter(|p| p.unstable()).count()
    }
}

/// Runs `method` on `example` with `command` at every point of `grid`, in parallel (the
/// chapter's plants, `0 < ρ < 1`).
pub fn sweep(
    example: Example,
    command: CommandKind,
    method: Method,
    grid: &Grid,
) -> Result<Sweep, MracError> {
    sweep_with(
        example,
        command,
        method,
        grid,
        &RunSettings::STUDY,
        |rho, nu| closed_loop::plant(example, rho, nu),
    )
}

/// As [`sweep`], each run under `settings`, with the plant at `(ρ, ν)` built by `plant`
/// (e.g. [`crate::study::mrac::outward::plant`], which also builds open-loop unstable
/// plants).
pub fn sweep_with<P>(
    example: Example,
    command: CommandKind,
    method: Method,
    grid: &Grid,
    settings: &RunSettings,
    plant: P,
) -> Result<Sweep, MracError>
where
    P: Fn(f64, f64) -> Result<plant_proxy::discrete::DiscreteTf, MracError> + Sync,
{
    let points = grid
        .points()
        .into_par_iter()
        .map(|(rho, nu)| {
            let tf = plant(rho, nu)?;
            closed_loop::run_on_with(tf, example, command, method, false, settings).map(|o| {
                GridPoint {
                    rho,
                    nu,
                    e_norm: o.e_norm,
                    diverged: o.diverged,
                    peak_y: o.peak_y,
                    theta_settle: o.theta_settle,
                }
            })
        })
        .collect::<Result<Vec<_>, MracError>>()?;
    Ok(Sweep {
        example,
        command,
        method,
        points,
    })
}

/// Writes every sweep as CSV: `example, command, method, rho, nu, e_norm, unstable,
/// diverged_at, peak_y, theta_settle` (`e_norm` is `inf` and `diverged_at` the sample for
/// an unstable point; `peak_y` the largest `|y_k|`; `theta_settle` the step `θ̂` settles,
/// empty for an unstable point).
pub fn write_csv(path: &Path, sweeps: &[Sweep]) -> Result<(), MracError> {
    let mut s = String::from(
        "example,command,method,rho,nu,e_norm,unstable,diverged_at,peak_y,theta_settle\n",
    );
    for sw in sweeps {
        for p in &sw.points {
            let _ = writeln!(
                s,
                "{},{},{},{:.6},{:.6},{}",
                sw.example.number(),
                sw.command.name(),
                sw.method.name(),
                p.rho,
                p.nu,
                p.csv_outcome()
            );
        }
    }
    std::fs::write(path, s).map_err(|source| FileError::new(FileOp::Access, path, source).into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_is_inside_the_upper_half_disc_and_evenly_spaced() {
        let g = Grid::new(3).expect("valid");
        assert_eq!(g.rho, [0.25, 0.5, 0.75]);
        let pi = std::f64::consts::PI;
        for (a, b) in g.nu.iter().zip([pi / 6.0, pi / 2.0, 5.0 * pi / 6.0]) {
            assert!((a - b).abs() < 1e-15);
        }
        assert_eq!(g.points().len(), 9);
        assert_eq!(g.points()[1], (0.25, pi / 2.0));
        assert!(Grid::new(0).unwrap_err().to_string().contains("--grid"));
    }
}
