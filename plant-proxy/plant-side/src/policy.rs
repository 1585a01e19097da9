//! How a plant side runs: pacing, the application instant, the late policy, the watchdog
//! and the safe output, the time-outs. Typed and validated by the caller (plant-proxy reads
//! it from a scenario's `[proxy]` table; a DAQ process builds it in code).

use crate::late_policy::{LatePolicy, MissPolicy, PlanFallback};
use crate::sample_clock::Overrun;
use ipc_types::ports::Applies;
use ipc_types::rt::RtRequest;
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// How the plant paces itself.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Mode {
    /// Paced on `CLOCK_MONOTONIC` at the sample period (or by the DAQ's own clock).
    RealTime,
    /// Advance when the service has answered each measurement.
    Lockstep,
}

impl Mode {
    /// The name used in the configuration (`"real-time"`, `"lockstep"`).
    pub const fn name(self) -> &'static str {
        match self {
            Mode::RealTime => "real-time",
            Mode::Lockstep => "lockstep",
        }
    }
}

/// The policies of one plant side. [`PlantPolicy::new`] gives the defaults of plant-proxy's
/// `[proxy]` table for a plant with `n_u` inputs.
#[derive(Debug, Clone, PartialEq)]
pub struct PlantPolicy {
    /// Pacing.
    pub mode: Mode,
    /// The application instant of the input for sample `k`, `t_k + dT`, as the fraction `d`
    /// of the period, in [0, 1]; 0 latches the input at the sample instant (only a service
    /// that sends ahead meets it). Not used in lockstep.
    pub deadline: f64,
    /// Input on a miss.
    pub late_policy: LatePolicy,
    /// Input on a miss no plan covers, with [`LatePolicy::Plan`].
    pub plan_fallback: PlanFallback,
    /// What the real-time loop of [`crate::plant_loop::run`] does when it wakes more than a
    /// period late.
    pub overrun: Overrun,
    /// The safe input, one value per control input; also the input before the first answer.
    pub safe_input: Vec<f64>,
    /// Consecutive misses that trip the watchdog into the safe output.
    pub watchdog_periods: u64,
    /// Lockstep: how long to wait for the service's answer before counting a miss.
    pub lockstep_timeout: Duration,
    /// How long to wait for the service at start, and, in lockstep, for an answer once the
    /// watchdog tripped before giving up.
    pub peer_timeout: Duration,
    /// Real-time set-up of the loop thread ([`crate::plant_loop::run`], real-time mode).
    pub rt: RtRequest,
}

impl PlantPolicy {
    /// Real time, deadline 0.8 of the period, hold on a miss, slip on an overrun, safe input
    /// 0, watchdog after 100 misses, lockstep time-out 1 s, peer time-out 30 s, no real-time
    /// set-up (the defaults of plant-proxy's `[proxy]` table but for the set-up).
    pub fn new(n_u: usize) -> Self {
        Self {
            mode: Mode::RealTime,
            deadline: 0.8,
            late_policy: LatePolicy::Hold,
            plan_fallback: PlanFallback::Hold,
            overrun: Overrun::Slip,
            safe_input: vec![0.0; n_u],
            watchdog_periods: 100,
            lockstep_timeout: Duration::from_secs(1),
            peer_timeout: Duration::from_secs(30),
            rt: RtRequest {
                core: None,
                fifo_priority: None,
                mlockall: false,
                prefault_stack_bytes: 0,
                cpu_latency_us: None,
            },
        }
    }

    /// The policy of a miss.
    pub const fn miss_policy(&self) -> MissPolicy {
        self.late_policy.with_fallback(self.plan_fallback)
    }

    /// When the plant applies an input, as it states at connect: at the sample instant (real
    /// time, deadline 0), at a deadline inside the period (real time, deadline > 0), or in
    /// lockstep.
    pub fn applies(&self) -> Applies {
        ipc_types::timing_rules::applies(self.mode == Mode::Lockstep, self.deadline)
    }

    /// The late policy in words: `"hold"`, `"safe"`, or `"plan (else hold)"`.
    pub fn describe_late_policy(&self) -> String {
        match self.late_policy {
            LatePolicy::Plan => format!("plan (else {})", self.plan_fallback.name()),
            p => p.name().to_string(),
        }
    }

    /// Refuses what cannot run: a deadline outside [0, 1] or not finite, a safe input of
    /// another length than `n_u` or not finite, a watchdog of 0 periods. The message names
    /// the field.
    pub fn validate(&self, n_u: usize) -> Result<(), String> {
        if !(0.0..=1.0).contains(&self.deadline) {
            return Err(format!(
                "deadline: {} is not a fraction of the period in [0, 1]",
                self.deadline
            ));
        }
        if self.safe_input.len() != n_u {
            return Err(format!(
                "safe-input: {} value(s) for {n_u} input(s)",
                self.safe_input.len()
            ));
        }
        if self.safe_input.iter().any(|v| !v.is_finite()) {
            return Err("safe-input: every value must be finite".into());
        }
        if self.watchdog_periods == 0 {
            return Err("watchdog-periods: must be at least 1".into());
        }
        Ok(())
    }
}
