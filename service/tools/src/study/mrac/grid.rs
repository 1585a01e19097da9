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
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
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

/// How a sweep builds the plant at `(ρ, ν)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlantRange {
    /// The chapter's constructor, `0 < ρ < 1` ([`closed_loop::plant`]).
    Chapter,
    /// The study's own, any `ρ > 0` ([`crate::study::mrac::outward::plant`]).
    Outward,
}

impl PlantRange {
    /// `example`'s plant with poles at `ρ e^{±jν}`.
    pub fn plant(
        self,
        example: Example,
        rho: f64,
        nu: f64,
    ) -> Result<plant_proxy::discrete::DiscreteTf, MracError> {
        match self {
            PlantRange::Chapter => closed_loop::plant(example, rho, nu),
            PlantRange::Outward => crate::study::mrac::outward::plant(example, rho, nu),
        }
    }
}

/// A sweep to run: `method` on `example` with `command` at every point of `grid`, each
/// run under `settings` on the plant built by `plant`.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepPlan {
    /// The example.
    pub example: Example,
    /// The command.
    pub command: CommandKind,
    /// The method.
    pub method: Method,
    /// The poles.
    pub grid: Grid,
    /// The runs' settings.
    pub settings: RunSettings,
    /// How the plant is built.
    pub plant: PlantRange,
}

impl SweepPlan {
    /// The study's sweep of a case over `grid` (the chapter's plants, the study's
    /// settings).
    pub fn chapter(example: Example, command: CommandKind, method: Method, grid: &Grid) -> Self {
        Self {
            example,
            command,
            method,
            grid: grid.clone(),
            settings: RunSettings::STUDY,
            plant: PlantRange::Chapter,
        }
    }

    /// Its runs, in the order of [`Grid::points`].
    pub fn items(&self) -> Vec<PointRun> {
        self.grid
            .points()
            .into_iter()
            .map(|(rho, nu)| PointRun {
                example: self.example,
                command: self.command,
                method: self.method,
                rho,
                nu,
                settings: self.settings,
                plant: self.plant,
            })
            .collect()
    }

    /// Runs it here, in parallel.
    pub fn run(&self) -> Result<Sweep, MracError> {
        let points = self
            .items()
            .par_iter()
            .map(PointRun::run)
            .collect::<Result<Vec<_>, MracError>>()?;
        Ok(self.sweep(points))
    }

    /// The sweep of these `points`.
    fn sweep(&self, points: Vec<GridPoint>) -> Sweep {
        Sweep {
            example: self.example,
            command: self.command,
            method: self.method,
            points,
        }
    }
}

/// One run of a sweep (the item of the study's sharded stages: its `Debug` text names
/// everything the run depends on).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointRun {
    /// The example.
    pub example: Example,
    /// The command.
    pub command: CommandKind,
    /// The method.
    pub method: Method,
    /// Pole radius.
    pub rho: f64,
    /// Pole angle, rad.
    pub nu: f64,
    /// The run's settings.
    pub settings: RunSettings,
    /// How the plant is built.
    pub plant: PlantRange,
}

impl PointRun {
    /// Runs it.
    pub fn run(&self) -> Result<GridPoint, MracError> {
        let tf = self.plant.plant(self.example, self.rho, self.nu)?;
        closed_loop::run_on_with(
            tf,
            self.example,
            self.command,
            self.method,
            false,
            &self.settings,
        )
        .map(|o| GridPoint {
            rho: self.rho,
            nu: self.nu,
            e_norm: o.e_norm,
            diverged: o.diverged,
            peak_y: o.peak_y,
            theta_settle: o.theta_settle,
        })
    }

    /// Runs it, an error as its text (what a shard records; [`assemble`] gives it back as
    /// [`MracError::Recorded`], which prints the same).
    pub fn record(&self) -> Result<GridPoint, String> {
        self.run().map_err(|e| e.to_string())
    }
}

/// The runs of `plans`, one after the other.
pub fn items(plans: &[SweepPlan]) -> Vec<PointRun> {
    plans.iter().flat_map(SweepPlan::items).collect()
}

/// The sweeps of `plans` from their runs' `results` (in the order of [`items`]); the
/// first failed run's error.
pub fn assemble(
    plans: &[SweepPlan],
    results: Vec<Result<GridPoint, String>>,
) -> Result<Vec<Sweep>, MracError> {
    let mut results = results.into_iter();
    let mut out = Vec::with_capacity(plans.len());
    for plan in plans {
        let n = plan.grid.rho.len() * plan.grid.nu.len();
        let points = results
            .by_ref()
            .take(n)
            .collect::<Result<Vec<_>, String>>()
            .map_err(MracError::Recorded)?;
        if points.len() != n {
            return Err(MracError::Recorded(format!(
                "{} runs for {} sweeps: too few",
                points.len(),
                plans.len()
            )));
        }
        out.push(plan.sweep(points));
    }
    Ok(out)
}

/// Runs `plans` here (in parallel, every run at once) and assembles their sweeps.
pub fn run_plans(plans: &[SweepPlan]) -> Result<Vec<Sweep>, MracError> {
    let results = items(plans).par_iter().map(PointRun::record).collect();
    assemble(plans, results)
}

/// Runs `method` on `example` with `command` at every point of `grid`, in parallel (the
/// chapter's plants, `0 < ρ < 1`).
pub fn sweep(
    example: Example,
    command: CommandKind,
    method: Method,
    grid: &Grid,
) -> Result<Sweep, MracError> {
    SweepPlan::chapter(example, command, method, grid).run()
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

    #[test]
    fn a_sweep_assembled_from_its_recorded_runs_is_the_sweep_and_an_error_keeps_its_text() {
        let g = Grid::new(2).expect("valid");
        let plan = SweepPlan::chapter(Example::Two, CommandKind::Four, Method::Appc, &g);
        let direct = plan.run().expect("runs");
        let recorded: Vec<_> = plan.items().iter().map(PointRun::record).collect();
        // As a shard records them and a merge reads them back.
        let bytes = postcard::to_stdvec(&recorded).expect("encodes");
        let back: Vec<Result<GridPoint, String>> = postcard::from_bytes(&bytes).expect("decodes");
        let sweeps = assemble(std::slice::from_ref(&plan), back).expect("assembles");
        assert_eq!(sweeps[0].points, direct.points);
        assert_eq!(
            run_plans(std::slice::from_ref(&plan)).expect("runs")[0].points,
            direct.points
        );
        let bad = SweepPlan {
            grid: Grid {
                rho: vec![-1.0],
                nu: vec![0.5],
            },
            plant: PlantRange::Outward,
            ..plan
        };
        let text = bad.items()[0].run().unwrap_err().to_string();
        let err = assemble(std::slice::from_ref(&bad), vec![bad.items()[0].record()]).unwrap_err();
        assert_eq!(err.to_string(), text);
        assert!(text.contains("Example 2"), "{text}");
        assert!(assemble(std::slice::from_ref(&bad), Vec::new()).is_err());
    }
}
