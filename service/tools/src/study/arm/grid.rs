//! The surface grids of `study sampling-arm` (Figures 7.3 and 7.5): their runs ([`jobs`],
//! [`run_point`], a sharded stage of the study), and their CSV.
//!
//! An `N × N` grid, log-spaced in both parameters (both ends included):
//!
//! ```text
//! k_s,i = k_lo (k_hi / k_lo)^((i − 1)/(N − 1)),   i = 1 … N,   k_s ∈ [300, 2.7·10⁵]
//! c_j   = c_lo (c_hi / c_lo)^((j − 1)/(N − 1)),   j = 1 … N,
//! ```
//!
//! with `c = c_s ∈ [0.35, 10³]` N s/m for the linear model (7.27) (§7.3.1) and
//! `c = c_r ∈ [0.1, 1]` for Hunt–Crossley (7.28) (§7.3.2). Each point is the single
//! maneuver of `scenarios/arm/linear.toml` on that surface, run to the end of its contact
//! phase ([`Record::FirstContact`]); a point whose run fails is kept, flagged.

use crate::file_error::{FileError, FileOp};
use std::fmt::Write as _;
use std::path::Path;

use crate::study::arm::ArmError;
use crate::study::arm::closed_loop::{self, Law, Model, Record, Setup};

/// The stiffness range of both grids, N/m (N/m^{3/2} for Hunt–Crossley).
pub const STIFFNESS: (f64, f64) = (300.0, 2.7e5);

/// The damping range of the linear grid, N s/m.
pub const DAMPING: (f64, f64) = (0.35, 1.0e3);

/// The restitution range of the Hunt–Crossley grid.
pub const RESTITUTION: (f64, f64) = (0.1, 1.0);

/// `n` log-spaced values from `lo` to `hi` (`lo` alone for `n = 1`).
pub fn log_space(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    if n == 1 {
        return vec![lo];
    }
    (0..n)
        .map(|i| {
            if i + 1 == n {
                hi
            } else {
                lo * (hi / lo).powf(i as f64 / (n - 1) as f64)
            }
        })
        .collect()
}

/// The grid of one contact model.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    /// The contact model.
    pub model: Model,
    /// `k_s`, ascending.
    pub k_s: Vec<f64>,
    /// `c_s` or `c_r`, ascending.
    pub c: Vec<f64>,
}

impl Grid {
    /// The `n × n` grid of `model` (module documentation); `n` at least 2.
    pub fn new(model: Model, n: usize) -> Result<Self, ArmError> {
        if n < 2 {
            return Err(ArmError::Grid(n));
        }
        let (lo, hi) = match model {
            Model::Linear => DAMPING,
            Model::HuntCrossley => RESTITUTION,
        };
        Ok(Self {
            model,
            k_s: log_space(STIFFNESS.0, STIFFNESS.1, n),
            c: log_space(lo, hi, n),
        })
    }

    /// Every `(k_s, c)`, `k_s` outer.
    pub fn points(&self) -> Vec<(f64, f64)> {
        self.k_s
            .iter()
            .flat_map(|&k| self.c.iter().map(move |&c| (k, c)))
            .collect()
    }
}

/// One grid point's result.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GridPoint {
    /// The contact model.
    pub model: Model,
    /// The controller.
    pub law: Law,
    /// `k_s`.
    pub k_s: f64,
    /// `c_s` or `c_r`.
    pub c: f64,
    /// The median contact force over the contact phase, N (NaN when it failed before).
    pub median: f64,
    /// The settling time into `±5 %` of 25 N, s.
    pub settling: f64,
    /// Why the run failed, if it did.
    pub failure: Option<String>,
}

impl GridPoint {
    /// True when the run failed.
    pub fn failed(&self) -> bool {
        self.failure.is_some()
    }
}

/// One run of a grid: both controllers at every point of every grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Job {
    /// The contact model.
    pub model: Model,
    /// The controller.
    pub law: Law,
    /// `k_s`.
    pub k_s: f64,
    /// `c_s` or `c_r`.
    pub c: f64,
}

/// Every run of every grid, in the order grid, law, point (the order of the points
/// [`run_point`] gives, and of `grid.csv`).
pub fn jobs(grids: &[Grid]) -> Vec<Job> {
    grids
        .iter()
        .flat_map(|g| {
            Law::ALL.into_iter().flat_map(move |law| {
                g.points().into_iter().map(move |(k_s, c)| Job {
                    model: g.model,
                    law,
                    k_s,
                    c,
                })
            })
        })
        .collect()
}

/// Runs one grid point (a sharded stage of the study: the study runs every [`jobs`]'s
/// point in parallel).
pub fn run_point(setup: &Setup, job: &Job) -> GridPoint {
    let &Job { model, law, k_s, c } = job;
    let out = setup
        .single_on(model, k_s, c)
        .and_then(|sc| closed_loop::run(setup, &sc, law, Record::FirstContact));
    let (median, settling, failure) = match out {
        Ok(o) => (o.median(), o.settling(), o.failure),
        Err(e) => (f64::NAN, f64::NAN, Some(e.to_string())),
    };
    GridPoint {
        model,
        law,
        k_s,
        c,
        median,
        settling,
        failure,
    }
}

/// Writes the points as CSV: `model, controller, k_s, c_s_or_c_r, median_force,
/// settling_s, failed, failure` (`settling_s` is `inf` when never settled).
pub fn write_csv(path: &Path, points: &[GridPoint]) -> Result<(), ArmError> {
    let mut s =
        String::from("model,controller,k_s,c_s_or_c_r,median_force,settling_s,failed,failure\n");
    for p in points {
        let _ = writeln!(
            s,
            "{},{},{:.6e},{:.6e},{:.6},{:.6},{},\"{}\"",
            p.model.name(),
            p.law.name(),
            p.k_s,
            p.c,
            p.median,
            p.settling,
            u8::from(p.failed()),
            p.failure.as_deref().unwrap_or("").replace('"', "'")
        );
    }
    std::fs::write(path, s).map_err(|source| FileError::new(FileOp::Access, path, source).into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_is_log_spaced_between_the_chapters_ends() {
        let g = Grid::new(Model::Linear, 3).unwrap();
        assert_eq!(g.k_s[0], 300.0);
        assert_eq!(g.k_s[2], 2.7e5);
        assert!((g.k_s[1] - (300.0_f64 * 2.7e5).sqrt()).abs() < 1e-6);
        assert_eq!((g.c[0], g.c[2]), DAMPING);
        let h = Grid::new(Model::HuntCrossley, 2).unwrap();
        assert_eq!(h.c, vec![0.1, 1.0]);
        assert_eq!(h.points().len(), 4);
        assert!(
            Grid::new(Model::Linear, 1)
                .unwrap_err()
                .to_string()
                .contains("--grid")
        );
    }
}
