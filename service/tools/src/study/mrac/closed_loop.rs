//! One closed-loop run of chapter 4 (§4.5): a controller of [`setup`] on
//! plant-proxy's difference equation of the example's plant at `(ρ, ν)`, 200 steps, and
//! the metric (4.85).
//!
//! # The loop
//!
//! Samples `k = 0, 1, …, 200` ([`STEPS`]` + 1` of them; the plant starts at rest,
//! `y_0 = 0`): the plant's `y_k`, the command's `r_k`, the controller's `u_k` (it steps
//! compute-first, [`control::mrac`]), then the plant applies `u_k + d_k` (`d_k` the input
//! disturbance of Example 3, 0 otherwise) and moves to `k + 1`. This is the loop of
//! `service/control/tests/mrac.rs`, so the study's single runs repeat the kernel tests'
//! values.
//!
//! # The metric and divergence
//!
//! `‖e‖ = sqrt(Σ_{i=101}^{200} e_i²)` (4.85), `e_k = y_k − y_{m,k}` from the controller.
//! A run is **unstable** when it diverges: a non-finite `y_k` or `u_k`, `|y_k|` above
//! [`DIVERGENCE_LIMIT`], or a controller fault ([`control::status::CONTROLLER_FAULT`]:
//! a non-finite regression or input). The run stops at the first such sample and its
//! `‖e‖` is `+∞`.
//!
//! # The estimate's settling
//!
//! Every run keeps `θ̂_0 … θ̂_200` and reports when it settles
//! ([`crate::study::mrac::theta_settling`]); a diverged run has none.
//!
//! # Other settings
//!
//! [`run_on_with`] runs under any [`RunSettings`] (another run length, metric window,
//! divergence limit, settling rule, `R_θ` or Example 3 disturbance: the sensitivity table,
//! [`crate::study::mrac::sensitivity`]); [`run`] and [`run_on`] are the study's
//! ([`RunSettings::STUDY`]).
//!
//! [`setup`]: crate::study::mrac::setup

use crate::study::mrac::MracError;
use crate::study::mrac::run_settings::{RunSettings, Signal};
use crate::study::mrac::setup::{CommandKind, Example, Kernel, Method};
use crate::study::mrac::theta_settling::settling_step_in;
use control::status;

/// The chapter's run length: 200 steps after `k = 0`.
pub const STEPS: usize = 200;

/// The first sample of (4.85).
pub const METRIC_FROM: usize = 101;

/// `|y_k|` above this marks a run as diverged (the reference output is of order 1: the
/// commands are at most 4 in magnitude and the reference model's gain is below 3).
pub const DIVERGENCE_LIMIT: f64 = 1e6;

/// Why a run was stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Divergence {
    /// `y_k` or `u_k` not finite.
    NonFinite,
    /// `|y_k|` above [`DIVERGENCE_LIMIT`] (or the run's [`RunSettings::divergence_limit`]).
    Large,
    /// The controller reported [`status::CONTROLLER_FAULT`].
    Fault,
}

/// The signals of one run, sample by sample (up to the divergence, if any).
#[derive(Debug, Clone, Default)]
pub struct RunTrace {
    /// The command `r_k`.
    pub r: Vec<f64>,
    /// The plant output `y_k`.
    pub y: Vec<f64>,
    /// The reference output `y_{m,k}`.
    pub y_m: Vec<f64>,
    /// The model-following error `e_k`.
    pub e: Vec<f64>,
    /// The input `u_k`.
    pub u: Vec<f64>,
    /// `θ̂_k`.
    pub theta: Vec<Vec<f64>>,
}

/// The outcome of one run.
#[derive(Debug, Clone)]
pub struct RunOutcome {
    /// ‖e‖ (4.85); `+∞` when the run diverged.
    pub e_norm: f64,
    /// Why the run diverged, if it did, and at which sample.
    pub diverged: Option<(Divergence, usize)>,
    /// The largest `|y_k|` of the run (up to the divergence).
    pub peak_y: f64,
    /// The step after which `θ̂_k` stays within 10 % of its largest excursion from
    /// `θ̂_200` ([`crate::study::mrac::theta_settling`]; under other [`RunSettings`], the
    /// settling step of their signal and band); `None` when the run diverged.
    pub theta_settle: Option<usize>,
    /// The signals, when asked for.
    pub trace: Option<RunTrace>,
}

impl RunOutcome {
    /// True when the run diverged.
    pub fn unstable(&self) -> bool {
        self.diverged.is_some()
    }
}

/// ‖e‖ of (4.85) over `e_101 … e_200` (`e` has at least 201 samples).
pub fn e_norm(e: &[f64]) -> f64 {
    e_norm_over(e, METRIC_FROM, STEPS)
}

/// ‖e‖ over `e_from … e_to` (`e` has at least `to + 1` samples).
pub fn e_norm_over(e: &[f64], from: usize, to: usize) -> f64 {
    e[from..=to].iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// Runs `method` on `example` with `command` at the plant poles `ρ e^{±jν}` (the
/// chapter's range, `0 < ρ < 1`, as the scenario files); records the signals when
/// `record`.
pub fn run(
    example: Example,
    command: CommandKind,
    method: Method,
    (rho, nu): (f64, f64),
    record: bool,
) -> Result<RunOutcome, MracError> {
    run_on(plant(example, rho, nu)?, example, command, method, record)
}

/// The plant of `example` with poles `ρ e^{±jν}` in the chapter's range (`0 < ρ < 1`, as
/// the scenario files), the error naming the example and the point.
pub fn plant(
    example: Example,
    rho: f64,
    nu: f64,
) -> Result<plant_proxy::discrete::DiscreteTf, MracError> {
    example
        .plant()
        .plant(rho, nu)
        .map_err(|source| MracError::Plant {
            example,
            rho,
            nu,
            source,
        })
}

/// Runs `method` on the plant `tf` with `example`'s disturbance and `command`; records
/// the signals when `record`. `tf` may be any plant of the example's numerator, e.g. one
/// with poles outside the unit circle ([`crate::study::mrac::outward::plant`]).
pub fn run_on(
    tf: plant_proxy::discrete::DiscreteTf,
    example: Example,
    command: CommandKind,
    method: Method,
    record: bool,
) -> Result<RunOutcome, MracError> {
    run_on_with(tf, example, command, method, record, &RunSettings::STUDY)
}

/// As [`run_on`], under `settings`: `settings.steps` steps, (4.85) over its window, its
/// divergence limit, `R_θ` and Example 3 disturbance, and the settling step of its signal
/// and band.
pub fn run_on_with(
    tf: plant_proxy::discrete::DiscreteTf,
    example: Example,
    command: CommandKind,
    method: Method,
    record: bool,
    settings: &RunSettings,
) -> Result<RunOutcome, MracError> {
    let steps = settings.steps;
    let mut plant = plant_proxy::discrete::DifferenceEquation::new(tf);
    let mut kernel = Kernel::with_r_theta(example, method, settings.r_theta)?;
    let cmd = command.command();
    let disturbance = example.disturbance().map(|h| settings.disturbance_of(h));
    let mut trace = RunTrace::default();
    let mut e = Vec::with_capacity(steps + 1);
    let mut diverged = None;
    let mut peak_y = 0.0_f64;
    let dim = kernel.theta().len();
    let mut history = Vec::with_capacity((steps + 1) * dim);
    for k in 0..=steps {
        let y = plant.output();
        peak_y = peak_y.max(y.abs());
        let r = cmd.value(k as u64);
        let mut u = 0.0;
        let st = kernel.step(k as u64, y, r, &mut u);
        if record {
            trace.r.push(r);
            trace.y.push(y);
            trace.y_m.push(kernel.y_m());
            trace.e.push(kernel.e());
            trace.u.push(u);
            trace.theta.push(kernel.theta().to_vec());
        }
        let why = if !(y.is_finite() && u.is_finite()) {
            Some(Divergence::NonFinite)
        } else if y.abs() > settings.divergence_limit {
            Some(Divergence::Large)
        } else if st & status::CONTROLLER_FAULT != 0 {
            Some(Divergence::Fault)
        } else {
            None
        };
        if let Some(why) = why {
            diverged = Some((why, k));
            break;
        }
        e.push(kernel.e());
        history.extend_from_slice(kernel.theta());
        let d = disturbance.map_or(0.0, |h| h.at(k as u64));
        plant.step(u + d);
    }
    let e_norm = if diverged.is_some() {
        f64::INFINITY
    } else {
        e_norm_over(&e, settings.metric_from, settings.metric_to.min(steps))
    };
    // A finite run whose θ̂ is not finite has no settling step either.
    let theta_settle = if diverged.is_some() {
        None
    } else {
        match settings.settle_signal {
            Signal::Theta => settling_step_in(&history, dim, settings.settle_band),
            Signal::Error => settling_step_in(&e, 1, settings.settle_band),
        }
        .ok()
    };
    Ok(RunOutcome {
        e_norm,
        diverged,
        peak_y,
        theta_settle,
        trace: record.then_some(trace),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn a_recorded_run_has_every_sample_and_its_metric_is_4_85_of_its_error() {
        let out = run(
            Example::One,
            CommandKind::Four,
            Method::Appc,
            (0.5, PI / 4.0),
            true,
        )
        .expect("runs");
        let t = out.trace.as_ref().expect("recorded");
        assert!(!out.unstable());
        assert_eq!(t.e.len(), STEPS + 1);
        assert_eq!(t.theta[0].len(), 8);
        assert_eq!(out.e_norm, e_norm(&t.e));
        for k in 0..=STEPS {
            assert_eq!(t.e[k], t.y[k] - t.y_m[k], "e_{k}");
        }
        // The unrecorded run gives the same value.
        let again = run(
            Example::One,
            CommandKind::Four,
            Method::Appc,
            (0.5, PI / 4.0),
            false,
        )
        .expect("runs");
        assert_eq!(again.e_norm, out.e_norm);
        assert!(again.trace.is_none());
        // The settling step is the recorded θ̂'s.
        let flat: Vec<f64> = t.theta.iter().flatten().copied().collect();
        assert_eq!(
            out.theta_settle,
            crate::study::mrac::theta_settling::settling_step(&flat, 8).ok()
        );
        assert_eq!(again.theta_settle, out.theta_settle);
        assert!(out.theta_settle.is_some_and(|k| k > 0 && k <= STEPS));
    }

    #[test]
    fn the_settings_reach_the_run() {
        let at = |s: &RunSettings| {
            run_on_with(
                plant(Example::One, 0.5, PI / 4.0).expect("plant"),
                Example::One,
                CommandKind::Step,
                Method::RcMrac,
                true,
                s,
            )
            .expect("runs")
        };
        let study = at(&RunSettings::STUDY);
        assert_eq!(
            study.e_norm,
            run(
                Example::One,
                CommandKind::Step,
                Method::RcMrac,
                (0.5, PI / 4.0),
                false
            )
            .expect("runs")
            .e_norm
        );
        // A longer run, another window.
        let long = at(&RunSettings {
            steps: 400,
            ..RunSettings::STUDY
        });
        assert_eq!(long.trace.as_ref().map(|t| t.e.len()), Some(401));
        assert_eq!(long.e_norm, study.e_norm);
        let whole = at(&RunSettings {
            metric_from: 0,
            ..RunSettings::STUDY
        });
        let t = study.trace.as_ref().expect("recorded");
        assert_eq!(whole.e_norm, e_norm_over(&t.e, 0, STEPS));
        assert!(whole.e_norm > study.e_norm);
        // A divergence limit below the response's peak stops the run.
        let low = at(&RunSettings {
            divergence_limit: 0.1,
            ..RunSettings::STUDY
        });
        assert!(matches!(low.diverged, Some((Divergence::Large, _))));
        assert!(low.theta_settle.is_none());
        // The settling of e_k under a fixed band.
        let e = at(&RunSettings {
            settle_signal: Signal::Error,
            settle_band: crate::study::mrac::theta_settling::Band::Absolute(1e-3),
            ..RunSettings::STUDY
        });
        assert_eq!(
            e.theta_settle,
            settling_step_in(
                &t.e,
                1,
                crate::study::mrac::theta_settling::Band::Absolute(1e-3)
            )
            .ok()
        );
        assert_ne!(e.theta_settle, study.theta_settle);
        // Another R_θ moves θ̂.
        let slow = at(&RunSettings {
            r_theta: 1e2,
            ..RunSettings::STUDY
        });
        let ts = slow.trace.as_ref().expect("recorded");
        assert_ne!(ts.theta[10], t.theta[10]);
    }

    #[test]
    fn a_bad_pole_radius_is_refused_naming_the_example_and_the_point() {
        let err = run(
            Example::Two,
            CommandKind::Step,
            Method::RcMrac,
            (1.5, 0.3),
            false,
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("Example 2") && err.contains("rho = 1.5"),
            "{err}"
        );
    }
}
