//! `ar_plant_config_t`: how a C plant connects and runs, and its translation into
//! plant-side's [`PlantPolicy`].

use crate::args;
use crate::guard;
use crate::status::{ArStatus, Failure};
use ipc_types::ChannelCounts;
use plant_side::{LatePolicy, Mode, PlanFallback, PlantPolicy};
use std::ffi::c_char;

/// `AR_MODE_REAL_TIME`: the plant keeps its own clock; inputs are decided at a deadline.
pub const AR_MODE_REAL_TIME: i32 = 0;
/// `AR_MODE_LOCKSTEP`: the plant waits for the service's answer to every sample.
pub const AR_MODE_LOCKSTEP: i32 = 1;
/// `AR_LATE_HOLD`: on a miss, hold the previous input.
pub const AR_LATE_HOLD: i32 = 0;
/// `AR_LATE_SAFE`: on a miss, apply the safe input.
pub const AR_LATE_SAFE: i32 = 1;
/// `AR_LATE_PLAN`: on a miss, apply the newest plan's entry, else `plan_fallback`.
pub const AR_LATE_PLAN: i32 = 2;

/// `ar_plant_config_t`: everything `ar_plant_open` needs. Fill it with
/// [`ar_plant_config_init`], then set `rig`, `counts`, `period_ns` and what differs.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct ArPlantConfig {
    /// Rig name (1 to 64 of ASCII letters, digits, `-`, `_`); NUL-terminated UTF-8.
    pub rig: *const c_char,
    /// The plant's channel counts; the service must state the same.
    pub counts: ChannelCounts,
    /// Sample period, ns; the service must state the same.
    pub period_ns: u64,
    /// `AR_MODE_REAL_TIME` or `AR_MODE_LOCKSTEP`.
    pub mode: i32,
    /// `AR_LATE_HOLD`, `AR_LATE_SAFE` or `AR_LATE_PLAN`.
    pub late_policy: i32,
    /// With `AR_LATE_PLAN`: `AR_LATE_HOLD` or `AR_LATE_SAFE` when no plan covers a miss.
    pub plan_fallback: i32,
    /// Non-zero: print connection progress and events to standard error.
    pub verbose: i32,
    /// Real time: the application instant `t_k + d·T` as the fraction `d` in [0, 1] (0:
    /// latched at the sample instant, which needs a service that sends ahead).
    pub deadline: f64,
    /// `counts.n_u` safe input values (the watchdog's output and the input before the first
    /// answer), or null for zeros. Copied by `ar_plant_open`.
    pub safe_input: *const f64,
    /// Consecutive misses that trip the watchdog into the safe output (at least 1).
    pub watchdog_periods: u64,
    /// Lockstep: how long to wait for each answer before counting a miss, s.
    pub lockstep_timeout_s: f64,
    /// How long to wait for the service at open, and in lockstep for an answer once the
    /// watchdog tripped before giving up, s.
    pub peer_timeout_s: f64,
    /// Prefix of the messages on standard error, or null for `"c-plant"`.
    pub label: *const c_char,
}

/// Fills `config` with the defaults of plant-proxy's `[proxy]` table: real time, deadline
/// 0.8, hold on a miss (plan fallback hold), safe input zeros, watchdog after 100 misses,
/// lockstep time-out 1 s, peer time-out 30 s, not verbose; `rig`, `label` null, counts and
/// period 0 (to be set).
///
/// # Safety
/// `config` is null or points to writable memory for one `ar_plant_config_t`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ar_plant_config_init(config: *mut ArPlantConfig) -> ArStatus {
    guard::call("ar_plant_config_init", || {
        // SAFETY: null or writable for one config, by this function's contract.
        let out = unsafe { args::write(config, "ar_plant_config_init", "config") }?;
        let d = PlantPolicy::new(0);
        *out = ArPlantConfig {
            rig: std::ptr::null(),
            counts: ChannelCounts::default(),
            period_ns: 0,
            mode: AR_MODE_REAL_TIME,
            late_policy: AR_LATE_HOLD,
            plan_fallback: AR_LATE_HOLD,
            verbose: 0,
            deadline: d.deadline,
            safe_input: std::ptr::null(),
            watchdog_periods: d.watchdog_periods,
            lockstep_timeout_s: d.lockstep_timeout.as_secs_f64(),
            peer_timeout_s: d.peer_timeout.as_secs_f64(),
            label: std::ptr::null(),
        };
        Ok(())
    })
}

/// What `ar_plant_open` makes of a config.
#[derive(Debug, Clone)]
pub struct PlantSetup {
    /// The rig name.
    pub rig: String,
    /// The channel counts.
    pub counts: ChannelCounts,
    /// The sample period, ns.
    pub period_ns: u64,
    /// The policy.
    pub policy: PlantPolicy,
    /// The label.
    pub label: String,
    /// Verbose.
    pub verbose: bool,
}

impl ArPlantConfig {
    /// Reads and checks the config, naming the field that is wrong
    /// (`ar_plant_open: config->counts: ...`).
    ///
    /// # Safety
    /// `rig` and `label` are null or NUL-terminated strings; `safe_input` is null or points
    /// to `counts.n_u` values.
    pub unsafe fn setup(&self) -> Result<PlantSetup, Failure> {
        const F: &str = "ar_plant_open";
        // SAFETY: NUL-terminated or null by this function's contract.
        let rig = unsafe { args::text(self.rig, F, "config->rig") }?.to_string();
        let counts = args::counts(self.counts, F, "config->counts")?;
        let n_u = counts.n_u as usize;
        if self.period_ns == 0 {
            return Err(Failure::invalid(format!(
                "{F}: config->period_ns: the sample period must be positive"
            )));
        }
        let mut policy = PlantPolicy::new(n_u);
        policy.mode = match self.mode {
            AR_MODE_REAL_TIME => Mode::RealTime,
            AR_MODE_LOCKSTEP => Mode::Lockstep,
            m => {
                return Err(Failure::invalid(format!(
                    "{F}: config->mode: {m} is neither AR_MODE_REAL_TIME ({AR_MODE_REAL_TIME}) nor AR_MODE_LOCKSTEP ({AR_MODE_LOCKSTEP})"
                )));
            }
        };
        policy.late_policy = match self.late_policy {
            AR_LATE_HOLD => LatePolicy::Hold,
            AR_LATE_SAFE => LatePolicy::Safe,
            AR_LATE_PLAN => LatePolicy::Plan,
            p => {
                return Err(Failure::invalid(format!(
                    "{F}: config->late_policy: {p} is none of AR_LATE_HOLD, AR_LATE_SAFE, AR_LATE_PLAN"
                )));
            }
        };
        policy.plan_fallback = match self.plan_fallback {
            AR_LATE_HOLD => PlanFallback::Hold,
            AR_LATE_SAFE => PlanFallback::Safe,
            p => {
                return Err(Failure::invalid(format!(
                    "{F}: config->plan_fallback: {p} is neither AR_LATE_HOLD nor AR_LATE_SAFE"
                )));
            }
        };
        policy.deadline = self.deadline;
        if !self.safe_input.is_null() {
            // SAFETY: not null, n_u values by this function's contract.
            let v = unsafe { args::values(self.safe_input, n_u, F, "config->safe_input") }?;
            policy.safe_input = v.to_vec();
        }
        policy.watchdog_periods = self.watchdog_periods;
        policy.lockstep_timeout =
            args::seconds(self.lockstep_timeout_s, F, "config->lockstep_timeout_s")?;
        policy.peer_timeout = args::seconds(self.peer_timeout_s, F, "config->peer_timeout_s")?;
        policy.validate(n_u).map_err(|m| {
            // plant-side names the fields as in a scenario file; C knows them as fields.
            let m = m.replacen("safe-input", "safe_input", 1).replacen(
                "watchdog-periods",
                "watchdog_periods",
                1,
            );
            Failure::invalid(format!("{F}: config->{m}"))
        })?;
        let label = if self.label.is_null() {
            "c-plant".to_string()
        } else {
            // SAFETY: not null, NUL-terminated by this function's contract.
            unsafe { args::text(self.label, F, "config->label") }?.to_string()
        };
        Ok(PlantSetup {
            rig,
            counts,
            period_ns: self.period_ns,
            policy,
            label,
            verbose: self.verbose != 0,
        })
    }
}
