//! What the plant applies when the input for a sample is missing at its deadline.
//!
//! The input for sample `k` is the service's actuation with sequence number `k`
//! ([`ipc_types::Actuation::seq`]). When it has not arrived by the application instant (the
//! deadline `t_k + dT` in real time; the service's answer to `M_k` in lockstep) the sample is a
//! **miss**, and the plant applies instead
//!
//! - `"hold"` ([`LatePolicy::Hold`]): the input it applied for sample `k − 1`;
//! - `"safe"` ([`LatePolicy::Safe`]): `proxy.safe-input`;
//! - `"plan"` ([`LatePolicy::Plan`]): the entry for sample `k` of the newest valid actuation
//!   received so far (the one with the largest `seq`, `seq < k`), when its plan covers `k`
//!   ([`ipc_types::Actuation::input_for`]); otherwise `proxy.plan-fallback`
//!   ([`PlanFallback`]: hold or safe). The next measurement then carries
//!   [`PLAN_APPLIED`](ipc_types::measurement_flags::PLAN_APPLIED) beside
//!   [`PREVIOUS_ACTUATION_MISSED`](ipc_types::measurement_flags::PREVIOUS_ACTUATION_MISSED).
//!
//! The rule itself is [`ipc_types::timing_rules::on_miss`] (with [`MissPolicy`] and
//! [`PlanFallback`], defined beside it in the contract); this module reads the
//! configuration into them.
//!
//! A plan entry is still a miss: the watchdog counts it as one, and its safe output, once
//! tripped, overrides the plan as it overrides every other input.

use serde::{Deserialize, Serialize};

/// What the plant applies on a miss (`proxy.late-policy`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum LatePolicy {
    /// Keep the last applied input.
    Hold,
    /// Apply the safe input.
    Safe,
    /// Apply the newest plan's entry for the sample, else [`PlanFallback`].
    Plan,
}

impl LatePolicy {
    /// The name used in the configuration (`"hold"`, `"safe"`, `"plan"`).
    pub const fn name(self) -> &'static str {
        match self {
            LatePolicy::Hold => "hold",
            LatePolicy::Safe => "safe",
            LatePolicy::Plan => "plan",
        }
    }

    /// The resolved policy of a miss (with `fallback` read only for [`LatePolicy::Plan`]).
    pub const fn with_fallback(self, fallback: PlanFallback) -> MissPolicy {
        match self {
            LatePolicy::Hold => MissPolicy::Hold,
            LatePolicy::Safe => MissPolicy::Safe,
            LatePolicy::Plan => MissPolicy::Plan(fallback),
        }
    }
}

pub use ipc_types::timing_rules::{MissPolicy, PlanFallback};
