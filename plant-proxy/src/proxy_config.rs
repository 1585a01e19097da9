//! The `[proxy]` table of a scenario: how plant-proxy runs the plant.
//!
//! ```toml
//! [proxy]
//! mode = "real-time"           # or "lockstep" (plant-proxy --mode overrides)
//! deadline = 0.5               # the input for sample k is applied at t_k + dT, d in [0, 1]
//! late-policy = "hold"         # on a miss: "hold", "safe" or "plan"
//! plan-fallback = "hold"       # with late-policy = "plan", a miss no plan covers: "hold" or "safe"
//! intersample = "ideal"        # or "at-deadline"
//! overrun = "slip"             # the plant itself woke a period late: "slip" or "catch-up"
//! safe-input = [0.0]           # one per control input
//! watchdog-periods = 100
//! lockstep-timeout = 1.0       # s
//! peer-timeout = 30.0          # s
//! core = 0                     # real-time set-up of the plant thread
//! fifo-priority = 70
//! mlockall = true
//!
//! [proxy.faults]               # crate::faults
//! nan-at = [10]
//! stalls = [{ at = 4000, periods = 4 }]   # lockstep only
//! lost = [{ at = 6000, periods = 3 }]      # lockstep only: samples never published
//! ```
//!
//! Every refusal names the file and the field ([`ProxyConfigError`]). The checks that
//! depend on the mode (`proxy.faults.stalls` and `lost` only in lockstep) are made for the mode the
//! plant will run in: [`ProxyConfig::parse_with_mode`] takes the command line's `--mode`.

use crate::faults::Faults;
use ipc_types::ports::Applies;
use ipc_types::rt::RtRequest;
pub use plant_side::policy::Mode;
use plant_side::{LatePolicy, Overrun, PlanFallback, PlantPolicy, late_policy::MissPolicy};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::time::Duration;

/// When a new input takes effect inside the period.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Intersample {
    /// `u_k` over `[kT, (k+1)T)`: the dissertation's sampled-data assumption.
    Ideal,
    /// `u_{k-1}` until `kT + dT`, then `u_k`: what the real hold does with a deadline offset.
    AtDeadline,
}

#[derive(Debug, Clone, Default, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawProxy {
    mode: Option<Mode>,
    deadline: Option<f64>,
    late_policy: Option<LatePolicy>,
    plan_fallback: Option<PlanFallback>,
    intersample: Option<Intersample>,
    overrun: Option<Overrun>,
    safe_input: Option<Vec<f64>>,
    watchdog_periods: Option<u64>,
    lockstep_timeout: Option<f64>,
    peer_timeout: Option<f64>,
    core: Option<usize>,
    fifo_priority: Option<i32>,
    mlockall: Option<bool>,
    faults: Option<Faults>,
}

/// The `[proxy]` table of a scenario: how plant-proxy runs the plant. Everything but the
/// simulation's own fields is the plant side's policy.
#[derive(Debug, Clone, PartialEq)]
pub struct ProxyConfig {
    /// The plant side's policy: pacing, deadline, late policy, overrun, safe input,
    /// watchdog, time-outs, real-time set-up.
    pub plant: PlantPolicy,
    /// When a new input takes effect in the simulation.
    pub intersample: Intersample,
    /// Faults to inject.
    pub faults: Faults,
}

/// A refused `[proxy]` table: `"<file>: field 'proxy.<field>': <what>"` (or
/// `"<file>: <what>"` for a file that is not TOML).
#[derive(Debug, Clone, PartialEq)]
pub struct ProxyConfigError(pub String);

impl fmt::Display for ProxyConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ProxyConfigError {}

impl ProxyConfig {
    /// Reads the `[proxy]` table from the scenario text (defaults when absent).
    pub fn parse(text: &str, origin: &str, n_u: usize) -> Result<Self, ProxyConfigError> {
        Self::parse_with_mode(text, origin, n_u, None)
    }

    /// [`ProxyConfig::parse`] for a plant that runs in `mode` when given (the command line's
    /// `--mode`), else in the table's `mode`; the mode-dependent checks are made for it.
    pub fn parse_with_mode(
        text: &str,
        origin: &str,
        n_u: usize,
        mode: Option<Mode>,
    ) -> Result<Self, ProxyConfigError> {
        let err = |field: &str, m: String| field_error(origin, field, m);
        let table: toml::Table = toml::from_str(text)
            .map_err(|e| ProxyConfigError(format!("{origin}: not valid TOML: {e}")))?;
        let raw: RawProxy = match table.get("proxy") {
            None => RawProxy::default(),
            Some(v) => v.clone().try_into().map_err(|e: toml::de::Error| {
                ProxyConfigError(format!("{origin}: table 'proxy': {e}"))
            })?,
        };
        let deadline = raw.deadline.unwrap_or(0.5);
        if !(0.0..=1.0).contains(&deadline) {
            return Err(err(
                "deadline",
                format!("{deadline} is not a fraction of the period in [0, 1]"),
            ));
        }
        let late_policy = raw.late_policy.unwrap_or(LatePolicy::Hold);
        if let Some(f) = raw.plan_fallback
            && late_policy != LatePolicy::Plan
        {
            return Err(err(
                "plan-fallback",
                format!(
                    "\"{}\" is read only with late-policy = \"plan\", and late-policy is \"{}\"",
                    f.name(),
                    late_policy.name()
                ),
            ));
        }
        let safe_input = raw.safe_input.unwrap_or_else(|| vec![0.0; n_u]);
        if safe_input.len() != n_u || safe_input.iter().any(|v| !v.is_finite()) {
            return Err(err(
                "safe-input",
                format!("needs {n_u} finite values (one per control input)"),
            ));
        }
        let watchdog_periods = raw.watchdog_periods.unwrap_or(100);
        if watchdog_periods == 0 {
            return Err(err("watchdog-periods", "must be at least 1".into()));
        }
        const MAX_WAIT_S: f64 = 86_400.0;
        let secs = |v: Option<f64>, d: f64, f: &str| {
            let v = v.unwrap_or(d);
            // A day at most: longer waits are a typo, and the conversion stays exact.
            if v.is_finite() && v > 0.0 && v <= MAX_WAIT_S {
                Ok(Duration::from_secs_f64(v))
            } else {
                Err(err(f, format!("{v} s is not in (0, {MAX_WAIT_S}] s")))
            }
        };
        let fifo_priority = ipc_types::rt::fifo_priority_from_config(raw.fifo_priority, 70)
            .map_err(|m| err("fifo-priority", m))?;
        let faults = raw.faults.unwrap_or_default();
        faults.validate().map_err(|e| {
            let field = e.field.strip_prefix("proxy.").unwrap_or(&e.field);
            err(field, e.problem)
        })?;
        let config = Self {
            plant: PlantPolicy {
                mode: mode.or(raw.mode).unwrap_or(Mode::RealTime),
                deadline,
                late_policy,
                plan_fallback: raw.plan_fallback.unwrap_or_default(),
                overrun: raw.overrun.unwrap_or_default(),
                safe_input,
                watchdog_periods,
                lockstep_timeout: secs(raw.lockstep_timeout, 1.0, "lockstep-timeout")?,
                peer_timeout: secs(raw.peer_timeout, 30.0, "peer-timeout")?,
                rt: RtRequest {
                    core: raw.core,
                    fifo_priority,
                    mlockall: raw.mlockall.unwrap_or(true),
                    prefault_stack_bytes: 256 * 1024,
                    // The service holds the (global) request for both sides.
                    cpu_latency_us: None,
                },
            },
            intersample: raw.intersample.unwrap_or(Intersample::Ideal),
            faults,
        };
        config.check_mode(origin)?;
        Ok(config)
    }

    /// The checks that depend on the mode ([`PlantPolicy::mode`]): injected stalls only in
    /// lockstep.
    /// `origin` names the file in the message.
    pub fn check_mode(&self, origin: &str) -> Result<(), ProxyConfigError> {
        if self.plant.mode == Mode::RealTime && !self.faults.stalls.is_empty() {
            return Err(field_error(
                origin,
                "faults.stalls",
                "injected stalls need lockstep mode (mode = \"lockstep\" or --mode lockstep); \
                 the plant runs in real time, where a stall of the service is a real one \
                 (SIGSTOP, a CPU hog)"
                    .into(),
            ));
        }
        if self.plant.mode == Mode::RealTime && !self.faults.lost.is_empty() {
            return Err(field_error(
                origin,
                "faults.lost",
                "injected lost samples need lockstep mode (mode = \"lockstep\" or --mode \
                 lockstep); in real time samples are lost for real (a service kept off its core)"
                    .into(),
            ));
        }
        Ok(())
    }

    /// The policy of a miss.
    pub const fn miss_policy(&self) -> MissPolicy {
        self.plant.miss_policy()
    }

    /// When the plant applies an input, as it states at connect ([`PlantPolicy::applies`]).
    pub fn applies(&self) -> Applies {
        self.plant.applies()
    }

    /// The late policy in words ([`PlantPolicy::describe_late_policy`]).
    pub fn describe_late_policy(&self) -> String {
        self.plant.describe_late_policy()
    }
}

fn field_error(origin: &str, field: &str, m: String) -> ProxyConfigError {
    ProxyConfigError(format!("{origin}: field 'proxy.{field}': {m}"))
}
