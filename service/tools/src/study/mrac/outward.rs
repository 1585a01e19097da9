//! The outward reading of Figures 4.8a–4.10a: the pole grid of Example 2 (the NMP plant
//! (4.88), zero at 1.5) extended past the unit circle, plus a fine patch around the
//! plant's zero.
//!
//! The captions of Figures 4.8a–4.10a (APPC on (4.88)) say "Empty squares represent
//! regions where the system became unstable", and §4.6.1 that "the model-following
//! performance degrades as the plant poles move closer to the plant zero". On the grid
//! inside the unit circle ([`crate::study::mrac::grid`]) our APPC never diverges; the
//! zero of (4.88) is outside the circle, so the figures' grid may reach open-loop
//! unstable plants (`ρ ≥ 1`). This module runs that reading:
//!
//! - **outward grid** (`--outward-rho R`, `--outward-grid N`, default `R = 2`, `N = 40`):
//!   `ρ_i = i R / N` (`i = 1 … N`, so the last ring is at `R`), `ν_j = (j − 1/2) π / N`;
//! - **near-zero patch** (`N_z × N_z`, default 20): `ρ_i = c − w + (i − 1/2) 2w / N_z`,
//!   `ν_j = (j − 1/2) ν_z / N_z` with the zero `c` = 1.5, `w` = [`NEAR_ZERO_HALF_WIDTH`]
//!   and `ν_z` = [`NEAR_ZERO_NU_MAX`]: the poles `ρ e^{±jν}` nearest the zero;
//! - the plant at any `ρ > 0` is built here ([`plant`]): the scenario files (and
//!   plant-proxy's `MracExample::plant`) keep refusing `ρ ≥ 1`.
//!
//! Each point is one 200-step run of [`crate::study::mrac::closed_loop`] with the same
//! divergence rule (a non-finite or `|y| > 10⁶` output, or a controller fault), for APPC
//! and RC-MRAC with every command run. The outcome is written to `grid-outward.csv`
//! ([`write_csv`]) and drawn as `map-outward-ex2-{command}-{method}.png`; where APPC
//! diverges and RC-MRAC does not is counted by [`crate::study::mrac::empty_squares`].

use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::Path;

use plant_proxy::discrete::DiscreteTf;
use plant_proxy::mrac_examples::{MracExampleError, pole_polynomial};

use crate::file_error::{FileError, FileOp};
use rayon::prelude::*;

use crate::study::mrac::grid::{self, Grid, GridPoint, PlantRange, PointRun, Sweep, SweepPlan};
use crate::study::mrac::run_settings::RunSettings;
use crate::study::mrac::setup::{CommandKind, Example, Method};
use crate::study::mrac::{ArgError, MracError};

/// The default outermost pole radius `R`.
pub const DEFAULT_OUTWARD_RHO: f64 = 2.0;

/// The default `N` of the `N × N` outward grid.
pub const DEFAULT_OUTWARD_GRID: usize = 40;

/// The default `N_z` of the `N_z × N_z` patch around the zero.
pub const DEFAULT_NEAR_ZERO_GRID: usize = 20;

/// The patch's radii span the zero `± w`.
pub const NEAR_ZERO_HALF_WIDTH: f64 = 0.25;

/// The patch's angles span `(0, ν_z)`, rad.
pub const NEAR_ZERO_NU_MAX: f64 = 0.5;

/// The largest `R` accepted (beyond it every open-loop plant is far out of reach of 200
/// steps and `|y| ≤ 10⁶`).
pub const MAX_OUTWARD_RHO: f64 = 10.0;

/// The extent and resolution of the outward reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutwardOptions {
    /// `R`, the outermost pole radius, in `(1, 10]`.
    pub rho_max: f64,
    /// `N` of the `N × N` outward grid.
    pub grid: usize,
    /// `N_z` of the `N_z × N_z` patch around the zero.
    pub near_zero: usize,
}

impl Default for OutwardOptions {
    fn default() -> Self {
        Self {
            rho_max: DEFAULT_OUTWARD_RHO,
            grid: DEFAULT_OUTWARD_GRID,
            near_zero: DEFAULT_NEAR_ZERO_GRID,
        }
    }
}

impl OutwardOptions {
    /// `--outward-rho R --outward-grid N`, the patch at its default size (`N_z = N / 2`,
    /// at least 1). `R` must be finite, above 1 (outside the unit circle) and at most
    /// [`MAX_OUTWARD_RHO`]; `N` at least 1.
    pub fn new(rho_max: f64, grid: usize) -> Result<Self, ArgError> {
        if !(rho_max.is_finite() && rho_max > 1.0 && rho_max <= MAX_OUTWARD_RHO) {
            return Err(ArgError::OutwardRho(rho_max));
        }
        if grid == 0 {
            return Err(ArgError::NoOutwardGrid);
        }
        Ok(Self {
            rho_max,
            grid,
            near_zero: (grid / 2).max(1),
        })
    }

    /// The outward grid of the module documentation.
    pub fn outward_grid(&self) -> Grid {
        let n = self.grid;
        Grid {
            rho: (1..=n)
                .map(|i| i as f64 * self.rho_max / n as f64)
                .collect(),
            nu: (1..=n).map(|j| (j as f64 - 0.5) * PI / n as f64).collect(),
        }
    }

    /// The patch around the zero `zero` of the module documentation.
    pub fn near_zero_grid(&self, zero: f64) -> Grid {
        let n = self.near_zero;
        let w = NEAR_ZERO_HALF_WIDTH;
        Grid {
            rho: (1..=n)
                .map(|i| zero - w + (i as f64 - 0.5) * 2.0 * w / n as f64)
                .collect(),
            nu: (1..=n)
                .map(|j| (j as f64 - 0.5) * NEAR_ZERO_NU_MAX / n as f64)
                .collect(),
        }
    }
}

/// Which part of the outward reading a sweep covers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Region {
    /// The `N × N` grid up to `R`.
    Outward,
    /// The patch around the zero.
    NearZero,
}

impl Region {
    /// The name in `grid-outward.csv`: `outward` or `near-zero`.
    pub fn name(self) -> &'static str {
        match self {
            Region::Outward => "outward",
            Region::NearZero => "near-zero",
        }
    }
}

/// One sweep of the outward reading.
#[derive(Debug, Clone)]
pub struct OutwardSweep {
    /// The part of the plane.
    pub region: Region,
    /// Its grid.
    pub grid: Grid,
    /// The runs, in the order of [`Grid::points`].
    pub sweep: Sweep,
}

/// `example`'s plant with poles at `ρ e^{±jν}` for any finite `ρ > 0` (open-loop unstable
/// for `ρ ≥ 1`) and `ν` in `[0, π]`; the study's own constructor, the scenario files keep
/// the chapter's `0 < ρ < 1`.
pub fn plant(example: Example, rho: f64, nu: f64) -> Result<DiscreteTf, MracError> {
    if !(rho.is_finite() && rho > 0.0 && nu.is_finite() && (0.0..=PI).contains(&nu)) {
        return Err(MracError::OutwardPole { example, rho, nu });
    }
    DiscreteTf::new(example.numerator(), pole_polynomial(rho, nu).to_vec()).map_err(|e| {
        MracError::Plant {
            example,
            rho,
            nu,
            source: MracExampleError::Tf(e),
        }
    })
}

/// One sweep of the outward reading, to run.
#[derive(Debug, Clone, PartialEq)]
pub struct OutwardPlan {
    /// The part of the plane.
    pub region: Region,
    /// The sweep (its grid the region's).
    pub plan: SweepPlan,
}

/// The sweeps of the outward reading: APPC and RC-MRAC on Example 2 with each of
/// `commands` over the outward grid and the patch around the zero, each run under
/// `settings` (e.g. another divergence limit or run length).
pub fn plans(
    options: &OutwardOptions,
    commands: &[CommandKind],
    settings: &RunSettings,
) -> Vec<OutwardPlan> {
    let example = Example::Two;
    let regions = [
        (Region::Outward, options.outward_grid()),
        (
            Region::NearZero,
            options.near_zero_grid(example.plant().zero()),
        ),
    ];
    let mut out = Vec::new();
    for (region, g) in &regions {
        for &c in commands {
            for m in [Method::Appc, Method::RcMrac] {
                out.push(OutwardPlan {
                    region: *region,
                    plan: SweepPlan {
                        example,
                        command: c,
                        method: m,
                        grid: g.clone(),
                        settings: *settings,
                        plant: PlantRange::Outward,
                    },
                });
            }
        }
    }
    out
}

/// The sweep plans of `plans`, in order (their runs are [`grid::items`] of these).
pub fn sweep_plans(plans: &[OutwardPlan]) -> Vec<SweepPlan> {
    plans.iter().map(|p| p.plan.clone()).collect()
}

/// The outward sweeps of `plans` from their runs' `results` (in the order of
/// [`grid::items`] of [`sweep_plans`]).
pub fn assemble(
    plans: &[OutwardPlan],
    results: Vec<Result<GridPoint, String>>,
) -> Result<Vec<OutwardSweep>, MracError> {
    let sweeps = grid::assemble(&sweep_plans(plans), results)?;
    Ok(plans
        .iter()
        .zip(sweeps)
        .map(|(p, sweep)| OutwardSweep {
            region: p.region,
            grid: p.plan.grid.clone(),
            sweep,
        })
        .collect())
}

/// Runs APPC and RC-MRAC on Example 2 with each of `commands` over the outward grid and
/// the patch around the zero, here.
pub fn sweep(
    options: &OutwardOptions,
    commands: &[CommandKind],
) -> Result<Vec<OutwardSweep>, MracError> {
    sweep_with(options, commands, &RunSettings::STUDY)
}

/// As [`sweep`], each run under `settings` (e.g. another divergence limit or run length).
pub fn sweep_with(
    options: &OutwardOptions,
    commands: &[CommandKind],
    settings: &RunSettings,
) -> Result<Vec<OutwardSweep>, MracError> {
    let p = plans(options, commands, settings);
    let results = grid::items(&sweep_plans(&p))
        .par_iter()
        .map(PointRun::record)
        .collect();
    assemble(&p, results)
}

/// Writes `grid-outward.csv`: `region, command, method, rho, nu, open_loop_unstable,
/// e_norm, unstable, diverged_at, peak_y, theta_settle` (`open_loop_unstable` is 1 for
/// `ρ ≥ 1`; the other columns as `grid.csv`).
pub fn write_csv(path: &Path, sweeps: &[OutwardSweep]) -> Result<(), MracError> {
    let mut s = String::from(
        "region,command,method,rho,nu,open_loop_unstable,e_norm,unstable,diverged_at,peak_y,theta_settle\n",
    );
    for o in sweeps {
        for p in &o.sweep.points {
            let _ = writeln!(
                s,
                "{},{},{},{:.6},{:.6},{},{}",
                o.region.name(),
                o.sweep.command.name(),
                o.sweep.method.name(),
                p.rho,
                p.nu,
                u8::from(p.rho >= 1.0),
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
    fn the_outward_grid_reaches_r_and_the_patch_surrounds_the_zero() {
        let o = OutwardOptions::new(2.0, 4).expect("valid");
        let g = o.outward_grid();
        assert_eq!(g.rho, [0.5, 1.0, 1.5, 2.0]);
        assert!((g.nu[0] - PI / 8.0).abs() < 1e-15);
        assert_eq!(o.near_zero, 2);
        let z = o.near_zero_grid(1.5);
        assert_eq!(z.rho, [1.375, 1.625]);
        assert_eq!(z.nu, [0.125, 0.375]);
    }

    #[test]
    fn bad_outward_options_are_refused_naming_the_option() {
        for r in [1.0, 0.5, f64::NAN, f64::INFINITY, 11.0] {
            let e = OutwardOptions::new(r, 10).unwrap_err().to_string();
            assert!(e.contains("--outward-rho"), "{r}: {e}");
        }
        let e = OutwardOptions::new(2.0, 0).unwrap_err().to_string();
        assert!(e.contains("--outward-grid"), "{e}");
    }

    #[test]
    fn the_plant_is_built_outside_the_unit_circle_with_the_examples_zero() {
        let g = plant(Example::Two, 1.5, 0.2).expect("built");
        assert_eq!(g.num(), &[0.0, 1.0, -1.5]);
        assert_eq!(g.den()[2], 2.25);
        assert!((g.den()[1] + 3.0 * 0.2_f64.cos()).abs() < 1e-15);
        for (rho, nu) in [(0.0, 0.2), (-1.0, 0.2), (f64::NAN, 0.2), (1.5, 4.0)] {
            let e = plant(Example::Two, rho, nu).unwrap_err().to_string();
            assert!(e.contains("Example 2"), "{e}");
        }
        // The chapter's constructor keeps refusing it.
        assert!(Example::Two.plant().plant(1.5, 0.2).is_err());
    }

    #[test]
    fn the_plant_outside_the_circle_is_open_loop_unstable_and_inside_it_is_not() {
        // The impulse response grows like ρ^k for ρ = 1.9 and decays for ρ = 0.9.
        let impulse_peak = |rho: f64| {
            let mut p = plant_proxy::discrete::DifferenceEquation::new(
                plant(Example::Two, rho, 0.1).expect("built"),
            );
            let mut peak = 0.0_f64;
            for k in 0..60 {
                p.step(if k == 0 { 1.0 } else { 0.0 });
                peak = peak.max(p.output().abs());
            }
            (peak, p.output().abs())
        };
        let (peak, last) = impulse_peak(1.9);
        assert!(peak > 1e12 && last > 1e12, "{peak} {last}");
        let (_, last) = impulse_peak(0.9);
        assert!(last < 0.1, "{last}");
    }
}
