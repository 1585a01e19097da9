//! The readings of §5.3.1's "all simulations converge to the true parameters in less than
//! 20 steps" (Figure 5.2) that the chapter leaves open, and the slowest run under each.
//!
//! §5.3 prints `θ_0 = 0`, `P_0 = 100 I`, `τ_n = 10`, `τ_d = 80`, `η = 1`, `α = 0.001`, the
//! input `u_k ~ N(0, 1)` and the change at `k = 100` (5.8); it leaves open what
//! "converge" means. The readings of the measurement (on the same 1000 runs,
//! [`super::slow_runs`]): the relative error stays below 1 %, 5 % or 10 %; it first falls
//! below 1 % or 10 %; every component stays within a line width ([`super::slow_runs::VISUAL`])
//! of its true value; and, since Figure 5.2 draws only the 5th–95th percentiles, the band of
//! every component lies within that width (a reading of the figure, not of "all
//! simulations"). For contrast, settings the chapter does not print for §5.3.1: `α = 0.01`
//! (which §5.3.2 suggests for faster convergence) and `τ_n = 5`, `τ_d = 50`.

use std::fmt::Write as _;

use control::forgetting::ForgettingRule;

use crate::study::forgetting::experiment::{
    Case, ETA, Method, TAU_D, TAU_N, Variant, run_seed, run_with,
};
use crate::study::forgetting::montecarlo::{Bands, percentile};
use crate::study::forgetting::plant::{CHANGE_STEP, Plant};
use crate::study::forgetting::slow_runs::{RunFeatures, STEPS, VISUAL};

/// A looser width for the band reading: a figure's `θ` axis spanning a few units shows
/// 0.05 as a few pixels (the figure's axis is not in the text).
pub const BAND_LOOSE: f64 = 0.05;

/// The settling of one reading over the Monte Carlo.
#[derive(Debug, Clone, PartialEq)]
pub struct Reading {
    /// What is read.
    pub name: String,
    /// Whether §5.3.1's text and printed settings support it as a reading of "all
    /// simulations converge" (false for the figure's band and for unprinted settings).
    pub supported: bool,
    /// Median settling over the runs (steps; `+∞`: never).
    pub median: f64,
    /// The slowest run's settling (steps; `+∞`: one never settles).
    pub slowest: f64,
    /// The slowest run's index (`None` for the band reading).
    pub slowest_run: Option<u64>,
}

impl Reading {
    /// Whether every run (or the band) settles in fewer than 20 steps, the claim's bound.
    pub fn within_20(&self) -> bool {
        self.slowest < 20.0
    }
}

/// A reading from one settling value per run.
fn of_runs(
    name: &str,
    supported: bool,
    runs: &[RunFeatures],
    f: impl Fn(&RunFeatures) -> Option<usize>,
) -> Reading {
    let mut v: Vec<f64> = runs
        .iter()
        .map(|r| f(r).map_or(f64::INFINITY, |s| s as f64))
        .collect();
    let slowest_run = runs
        .iter()
        .max_by(|a, b| {
            let (x, y) = (
                f(a).map_or(f64::INFINITY, |s| s as f64),
                f(b).map_or(f64::INFINITY, |s| s as f64),
            );
            x.total_cmp(&y).then(b.run.cmp(&a.run))
        })
        .map(|r| r.run);
    Reading {
        name: name.into(),
        supported,
        median: percentile(&mut v, 0.5),
        slowest: v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        slowest_run,
    }
}

/// Steps after the change until the 5th and 95th percentiles of every `θ` component stay
/// within `tol` of the true value to the end of the bands (`None`: not at the end).
pub fn band_settle(b: &Bands, tol: f64) -> Option<usize> {
    let bad = |i: usize| {
        (0..b.truth[i].len()).any(|j| {
            let t = b.truth[i][j];
            !((b.theta[i][j].p05 - t).abs() < tol && (b.theta[i][j].p95 - t).abs() < tol)
        })
    };
    let mut settle = Some(0);
    for i in 0..b.ks.len().min(b.theta.len()).min(b.truth.len()) {
        if b.ks[i] >= CHANGE_STEP && bad(i) {
            settle = if i + 1 == b.ks.len() {
                None
            } else {
                Some(b.ks[i] + 1 - CHANGE_STEP)
            };
        }
    }
    settle
}

/// The readings of the measurement on the runs `runs` and the Monte Carlo bands `bands`.
pub fn measurement_readings(runs: &[RunFeatures], bands: &Bands) -> Vec<Reading> {
    let mut out = vec![
        of_runs("stays < 1 % (the study's)", true, runs, |r| r.settle),
        of_runs("stays < 5 %", true, runs, |r| r.settle_5),
        of_runs("stays < 10 %", true, runs, |r| r.settle_10),
        of_runs("first < 1 %", true, runs, |r| r.first_1),
        of_runs("first < 10 %", true, runs, |r| r.first_10),
        of_runs(
            &format!("every |error| stays < {VISUAL}"),
            true,
            runs,
            |r| r.settle_visual,
        ),
    ];
    for tol in [VISUAL, BAND_LOOSE] {
        let band = band_settle(bands, tol).map_or(f64::INFINITY, |s| s as f64);
        out.push(Reading {
            name: format!("5-95 % band within {tol} (figure only)"),
            supported: false,
            median: band,
            slowest: band,
            slowest_run: None,
        });
    }
    out
}

/// A forgetting setting of RLS/FTVRF that the chapter does not print for §5.3.1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Setting {
    /// The reading's name.
    pub name: &'static str,
    /// Short window `τ_n`.
    pub tau_n: usize,
    /// Long window `τ_d`.
    pub tau_d: usize,
    /// Significance level `α`.
    pub alpha: f64,
}

/// The settings read for contrast: `α = 0.01`, and `τ_n = 5`, `τ_d = 50`.
pub const SETTINGS: [Setting; 2] = [
    Setting {
        name: "alpha = 0.01 (not printed)",
        tau_n: TAU_N,
        tau_d: TAU_D,
        alpha: 0.01,
    },
    Setting {
        name: "tau_n = 5, tau_d = 50 (not printed)",
        tau_n: 5,
        tau_d: 50,
        alpha: crate::study::forgetting::experiment::ALPHA,
    },
];

/// One noiseless RLS/FTVRF run under a [`Setting`], an item of the settings' stage: run
/// `run` of the Monte Carlo, seeded `seed` ([`run_seed`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SettingRun {
    /// The setting.
    pub setting: Setting,
    /// The run's index in the Monte Carlo.
    pub run: u64,
    /// Its seed.
    pub seed: u64,
}

/// The `runs` runs of master seed `seed` under each of [`SETTINGS`], setting by setting.
pub fn setting_items(runs: usize, seed: u64) -> Vec<SettingRun> {
    SETTINGS
        .iter()
        .flat_map(|&setting| {
            (0..runs as u64).map(move |run| SettingRun {
                setting,
                run,
                seed: run_seed(seed, Case::Noiseless, run),
            })
        })
        .collect()
}

/// The 1 % settling of the run `item` on `plant` (an error as its message).
pub fn settle_under(plant: &Plant, item: &SettingRun) -> Result<Option<usize>, String> {
    let mut config = Method::Ftvrf.config();
    config.rule = ForgettingRule::FTest {
        tau_n: item.setting.tau_n,
        tau_d: item.setting.tau_d,
        eta: ETA,
        alpha: item.setting.alpha,
    };
    run_with(
        plant,
        Case::Noiseless,
        &config,
        Variant::STUDY,
        STEPS,
        item.seed,
        false,
    )
    .map(|(r, _)| r.settle)
    .map_err(|e| e.to_string())
}

/// The noiseless RLS/FTVRF Monte Carlo under forgetting settings the chapter does not print
/// for §5.3.1 (1 % settling, as the study's), from the settling of each of
/// [`setting_items`]`(runs, …)` in its order.
pub fn setting_readings(runs: usize, settles: &[Option<usize>]) -> Vec<Reading> {
    SETTINGS
        .iter()
        .enumerate()
        .map(|(n, setting)| {
            let settle: Vec<(u64, Option<usize>)> = settles[n * runs..(n + 1) * runs]
                .iter()
                .enumerate()
                .map(|(i, &s)| (i as u64, s))
                .collect();
            let mut v: Vec<f64> = settle
                .iter()
                .map(|(_, s)| s.map_or(f64::INFINITY, |s| s as f64))
                .collect();
            let slowest_run = settle
                .iter()
                .max_by(|a, b| {
                    let x = a.1.map_or(f64::INFINITY, |s| s as f64);
                    let y = b.1.map_or(f64::INFINITY, |s| s as f64);
                    x.total_cmp(&y).then(b.0.cmp(&a.0))
                })
                .map(|r| r.0);
            Reading {
                name: setting.name.into(),
                supported: false,
                median: percentile(&mut v, 0.5),
                slowest: v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                slowest_run,
            }
        })
        .collect()
}

/// The readings as a table for the summary.
pub fn table(readings: &[Reading]) -> String {
    let steps = |v: f64| {
        if v.is_finite() {
            format!("{v:.0}")
        } else {
            "never".into()
        }
    };
    let mut s = String::from(
        "\nReadings of \"all simulations converge in less than 20 steps\" (case 1, RLS/FTVRF):\n",
    );
    let _ = writeln!(
        s,
        "{:<42} {:>9} {:>7} {:>8} {:>12} {:>7}",
        "reading", "supported", "median", "slowest", "slowest run", "< 20"
    );
    for r in readings {
        let _ = writeln!(
            s,
            "{:<42} {:>9} {:>7} {:>8} {:>12} {:>7}",
            r.name,
            if r.supported { "yes" } else { "no" },
            steps(r.median),
            steps(r.slowest),
            r.slowest_run.map_or_else(|| "-".into(), |i| i.to_string()),
            if r.within_20() { "yes" } else { "no" }
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::forgetting::excitation::Excitation;
    use crate::study::forgetting::montecarlo::Band;

    fn run(i: u64, settle: Option<usize>, first: Option<usize>) -> RunFeatures {
        RunFeatures {
            run: i,
            seed: i,
            settle,
            settle_5: settle,
            settle_10: first,
            first_1: first,
            first_10: first,
            settle_visual: settle,
            excitation: Excitation {
                sigma_min: 1.0,
                sigma_max: 1.0,
                input_rms: 1.0,
            },
            forget_start: Some(1),
            forget_steps: 3,
            lambda_min: 0.5,
            forget_end: Some(4),
            error_at_forget_end: 0.1,
            trace_at_forget_end: 1.0,
            sigma_min_forgetting: 1.0,
        }
    }

    fn bands(enter: usize) -> Bands {
        let mut b = Bands::default();
        for k in 0..150 {
            b.ks.push(k);
            b.truth.push([1.0; 5]);
            let off = if k >= CHANGE_STEP + enter { 0.001 } else { 0.5 };
            let band = Band {
                p05: 1.0 - off,
                p50: 1.0,
                p95: 1.0 + off,
            };
            b.theta.push([band; 5]);
        }
        b
    }

    #[test]
    fn the_slowest_run_decides_each_reading() {
        let runs = [
            run(0, Some(10), Some(5)),
            run(1, Some(30), Some(12)),
            run(2, None, Some(19)),
        ];
        let r = measurement_readings(&runs, &bands(7));
        assert_eq!(r[0].slowest, f64::INFINITY);
        assert_eq!(r[0].slowest_run, Some(2));
        assert_eq!(r[0].median, 30.0);
        assert!(!r[0].within_20());
        // First entry: 19 < 20.
        assert_eq!(r[3].slowest, 19.0);
        assert_eq!(r[3].slowest_run, Some(2));
        assert!(r[3].within_20());
        // The band enters at 7 steps and is marked as a reading of the figure only.
        let band = r.last().unwrap();
        assert_eq!((band.slowest, band.supported), (7.0, false));
        assert!(table(&r).contains("never"));
    }

    #[test]
    fn band_settling_of_hand_made_bands() {
        assert_eq!(band_settle(&bands(0), 0.02), Some(0));
        assert_eq!(band_settle(&bands(23), 0.02), Some(23));
        assert_eq!(band_settle(&bands(200), 0.02), None);
        assert_eq!(band_settle(&bands(23), 1.0), Some(0));
    }
}
