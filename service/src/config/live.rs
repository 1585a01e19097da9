//! `[service.telemetry]` and `[service.operator]`: the live view and the operator's
//! commands (docs/monitor.md).
//!
//! ```toml
//! [service.telemetry]
//! enabled = true                  # default true: publish adaptive-rig/<rig>/telemetry
//! points-per-second = 1000        # scope points per second of plant time (1 to the
//!                                 # sample rate; default min(1000, sample rate))
//! tone-window = 0.25              # s: the window of the live tone fit (default 0.25,
//!                                 # at most service.report.window's bound)
//!
//! [service.operator]
//! commands = true                 # default true: accept operator commands
//!                                 # (adaptive-rig/<rig>/operator)
//! tunables = { alpha = [0.05, 1.0] }
//!                                 # the controller's parameters an operator may set, each
//!                                 # with the bounds [min, max] the operator must stay in;
//!                                 # default none. Each must be a tunable of the configured
//!                                 # controller (RCAC with the gradient update: alpha) and
//!                                 # its bounds within what the law admits ((0, 1] for alpha)
//! ```

use super::bounds::{self, MAX_REPORT_WINDOW_CYCLES};
use super::values::{count, seconds};
use super::{ConfigError, ControllerConfig, ErrFn};
use ipc_types::ChannelCounts;
use ipc_types::telemetry::MAX_TUNABLES;
use serde::Deserialize;
use std::collections::BTreeMap;

/// A tunable the configuration offers to the operator.
#[derive(Debug, Clone, PartialEq)]
pub struct DeclaredTunable {
    /// Its name.
    pub name: String,
    /// Its index in the controller's [`control::Controller::tunables`].
    pub index: usize,
    /// Smallest value the operator may set.
    pub min: f64,
    /// Largest value the operator may set.
    pub max: f64,
    /// Its value at the start of a run.
    pub initial: f64,
}

/// The live view and the operator's commands.
#[derive(Debug, Clone, PartialEq)]
pub struct LiveConfig {
    /// Publish the telemetry services.
    pub telemetry: bool,
    /// A scope point every this many samples.
    pub point_every: u64,
    /// Samples in the window of the live tone fit.
    pub tone_window_cycles: u64,
    /// Accept operator commands.
    pub commands: bool,
    /// The tunables offered to the operator.
    pub tunables: Vec<DeclaredTunable>,
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawTelemetry {
    enabled: Option<bool>,
    points_per_second: Option<f64>,
    tone_window: Option<f64>,
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawOperator {
    commands: Option<bool>,
    tunables: Option<BTreeMap<String, [f64; 2]>>,
}

/// The two tables, checked; the tunables against `controller` (built once when any is
/// declared, to ask it).
pub(super) fn parse(
    telemetry: RawTelemetry,
    operator: RawOperator,
    period: f64,
    controller: &ControllerConfig,
    counts: ChannelCounts,
    err: &ErrFn<'_>,
) -> Result<LiveConfig, ConfigError> {
    let rate = 1.0 / period;
    let field = "service.telemetry.points-per-second";
    let pps = telemetry.points_per_second.unwrap_or(rate.min(1000.0));
    if !(pps.is_finite() && pps >= 1.0 && pps <= rate * (1.0 + 1e-9)) {
        return Err(err(
            field,
            format!("{pps} is not between 1 and the sample rate {rate} per second"),
        ));
    }
    let point_every = ((rate / pps).round() as u64).max(1);
    let field = "service.telemetry.tone-window";
    let window = seconds(
        telemetry.tone_window.unwrap_or(0.25),
        false,
        bounds::MAX_DURATION_S,
        field,
        err,
    )?;
    let tone_window_cycles = count(
        bounds::cycles(window, period).max(1),
        1,
        MAX_REPORT_WINDOW_CYCLES,
        field,
        err,
    )?;
    let tunables = match operator.tunables {
        Some(t) if !t.is_empty() => declared(&t, controller, counts, err)?,
        _ => Vec::new(),
    };
    Ok(LiveConfig {
        telemetry: telemetry.enabled.unwrap_or(true),
        point_every,
        tone_window_cycles,
        commands: operator.commands.unwrap_or(true),
        tunables,
    })
}

fn declared(
    given: &BTreeMap<String, [f64; 2]>,
    controller: &ControllerConfig,
    counts: ChannelCounts,
    err: &ErrFn<'_>,
) -> Result<Vec<DeclaredTunable>, ConfigError> {
    let field = "service.operator.tunables";
    if given.len() > MAX_TUNABLES {
        return Err(err(
            field,
            format!("{} tunables, at most {MAX_TUNABLES}", given.len()),
        ));
    }
    let built = controller.build(counts).map_err(|e| err("controller", e))?;
    let offered = built.tunables();
    let mut out = Vec::new();
    for (name, [min, max]) in given {
        let at = format!("{field}.{name}");
        let Some(index) = offered.iter().position(|t| t.name == name) else {
            let names: Vec<&str> = offered.iter().map(|t| t.name).collect();
            return Err(err(
                &at,
                format!(
                    "the {} controller has no tunable '{name}' (it has: {})",
                    built.kind(),
                    if names.is_empty() {
                        "none".to_string()
                    } else {
                        names.join(", ")
                    }
                ),
            ));
        };
        let Some(initial) = built.tunable(index) else {
            return Err(err(
                &at,
                format!("this {} configuration does not use '{name}'", built.kind()),
            ));
        };
        let t = offered[index];
        if !(min <= max && (t.admits)(*min) && (t.admits)(*max)) {
            return Err(err(
                &at,
                format!(
                    "[{min}, {max}] must be an interval within {} (what the law admits)",
                    t.range
                ),
            ));
        }
        out.push(DeclaredTunable {
            name: name.clone(),
            index,
            min: *min,
            max: *max,
            initial,
        });
    }
    Ok(out)
}
