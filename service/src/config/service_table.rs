//! `[service]`: the real-time set-up, the deadline policy, the measurement limits and the
//! session of the service, and `[service.channels]`.
//!
//! ```toml
//! [service]
//! core = 1                        # pin the RT thread (omit: no pinning)
//! fifo-priority = 80              # SCHED_FIFO priority (0: stay SCHED_OTHER)
//! mlockall = true
//! cpu-latency = 0                 # µs: the CPUs' wake-up latency held while the service
//!                                 # runs (PM QoS, ipc_types::cpu_latency; 0: cores poll in
//!                                 # idle instead of halting); "off": leave it to the kernel
//! require-rt = false              # true: refuse to run when the OS refuses any of the above
//! wait = "sleep-poll"             # or "busy-poll", "block" (WaitMode; runtime::pacing)
//! poll-window = 40e-6             # s: sleep-poll polls from this long before the sample
//!                                 # is due (cover the timer's wake-up latency; ≤ T/3)
//! grace-periods = 100             # start-up cycles whose misses do not count toward the limit
//! max-consecutive-misses = 10     # then go to the safe state (≥ 1)
//! miss-source = "plant"           # misses the plant reports, or "response-time" (measured here)
//! recover-after = 0               # 0: the safe state is kept for the rest of the plant
//!                                 # session; N: leave it when the last N answers in it
//! recover-tolerance = 0           # held at most this many misses (0: N good in a row)
//! silent-periods = 400            # no sample for this many periods: the plant is silent (≥ 1)
//! reset-on-resume = false         # true: a new plant session (a restarted or replaced
//!                                 # plant process) resets the controller; false: it keeps
//!                                 # what it learned and only restarts its data history
//! checkpoint-every = 1.0          # s of samples between checkpoints of what the controller
//!                                 # learned (checkpoint.json; 0: only at the end of the run)
//! on-timing-fault = "keep-learned" # what leaving the safe state and a stalled plant that
//!                                 # resumes do to the controller: "keep-learned" (default:
//!                                 # a timing fault is not the controller's) or
//!                                 # "reset-controller" (back to its initial state)
//! max-safe-state-share = 0.1      # a run with more of its closed-loop cycles in the safe
//!                                 # state fails its verdict (exit status 1)
//! max-lost-share = 0.01           # ... more of its samples past start-up lost
//! max-held-share = 0.01           # ... more of its inputs past start-up held or safe-
//!                                 # outputted by the plant (a late answer no plan covered)
//! max-suspended-share = 0.5       # ... an adaptive controller's update suspended (a gap
//!                                 # in its data, a bad sample) on more of its steps
//! u-applied-tolerance = 1e-6      # |u_applied − u_sent| above this raises the foreign-
//!                                 # actuation alarm (a DAQ reading back quantized outputs
//!                                 # needs about one DAC step)
//! peer-timeout = 30.0             # s to wait for the plant at start
//! safe-input = [0.0, 0.0]         # scalar or one per input u (default 0)
//! y-min = -10.0                   # scalar or one per channel; measurements outside are rejected
//! y-max = 10.0                    # (default ±∞; also z-min, z-max)
//! histogram-interval = 1.0        # s between interval-log entries
//! run-dir = "runs"
//! rms-settle = 2.0                # s after which the "settled" RMS of z starts
//! open-loop = 1.0                 # s of each session run open loop (u = safe-input) before
//!                                 # the controller acts; it observes those samples
//! timing = "compute-first"        # when the service answers; see the answer_timing module
//! plan-length = 0                 # inputs ahead per answer; see the answer_timing module
//! [service.report]                # see the tone_report module
//! [service.channels]              # optional; default from [plant]
//! y = 1
//! z = 1
//! r = 0                           # default 0
//! u = 2                           # at least 1
//! ```
//!
//! Without `[service.channels]` the counts come from the plant proxy's `[plant]` table
//! (`outputs-y`, `outputs-z`, `commands` (default 0), `inputs`).

use super::bounds::{self, MAX_CORES, MAX_DURATION_S, MAX_WAIT_S};
use super::values::{ScalarOrVec, count, per_channel, seconds};
use super::{ConfigError, ErrFn};
use ipc_types::ChannelCounts;
use ipc_types::rt::RtRequest;
use rig_scenario::plant_outline::PlantOutline;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::time::Duration;

/// What a timing fault (deadline misses that led to the safe state, a stalled plant that
/// resumed) does to the controller's learned state; configuration value kebab-case
/// (`"keep-learned"`, `"reset-controller"`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TimingFaultReset {
    /// The controller keeps what it learned (the default): a timing fault is not its fault.
    #[default]
    KeepLearned,
    /// The controller returns to its initial state on leaving the safe state and after a
    /// stall.
    ResetController,
}

/// How the RT thread waits for the next measurement ([`crate::runtime::pacing`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WaitMode {
    /// Sleep until `service.poll-window` before the next sample is due, then poll a
    /// bounded window (the default: preempts other work on its core at `SCHED_FIFO`, never
    /// reaches RT throttling).
    SleepPoll,
    /// Spin on the subscriber (burns the pinned core; at `SCHED_FIFO` with RT throttling on
    /// the kernel stalls it every second, and `service check` refuses that).
    BusyPoll,
    /// Sleep on the plant's iceoryx2 event (spares the core; adds the event's wake-up).
    Block,
}

impl WaitMode {
    /// The name in the configuration (`sleep-poll`, `busy-poll`, `block`).
    pub fn name(self) -> &'static str {
        match self {
            WaitMode::SleepPoll => "sleep-poll",
            WaitMode::BusyPoll => "busy-poll",
            WaitMode::Block => "block",
        }
    }
}

/// Which misses count toward the safe-state limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MissSource {
    /// The plant's own verdict, carried in the next sample (`PREVIOUS_ACTUATION_MISSED`):
    /// the plant is the clock master and applies `u` at its deadline, so it decides.
    Plant,
    /// The service's measurement: publish time − sample time > the deadline. Stricter: it
    /// also counts the plant process's own lateness in waking up.
    ResponseTime,
}

/// The deadline and silence policy.
#[derive(Debug, Clone, PartialEq)]
pub struct DeadlinePolicy {
    /// Cycles after (re)connection whose misses do not count toward the limit.
    pub grace_cycles: u64,
    /// Consecutive misses that send the service to its safe state.
    pub max_consecutive_misses: u64,
    /// The recovery window: the safe state is left when the last `recover_after` answers
    /// in it held at most `recover_tolerance` misses; `None` keeps it for the session.
    pub recover_after: Option<u64>,
    /// Misses allowed in the recovery window (0: `recover_after` good answers in a row).
    pub recover_tolerance: u64,
    /// Periods without a sample after which the plant is declared silent.
    pub silent_periods: u64,
    /// Reset the controller when a new plant session starts; false (the default): it keeps
    /// what it learned and restarts its data history
    /// ([`control::Controller::restart_data`]).
    pub reset_on_resume: bool,
    /// What a timing fault (leaving the safe state, a stalled plant that resumes) does to
    /// the controller's learned state.
    pub on_timing_fault: TimingFaultReset,
    /// Which misses count toward `max_consecutive_misses`.
    pub miss_source: MissSource,
    /// Largest `|u_applied − u_sent|` the plant may report for an actuation it says it
    /// applied on time before the service raises the foreign-actuation alarm.
    pub u_applied_tolerance: f64,
    /// Largest share of the closed-loop cycles a run may spend in the safe state and still
    /// pass its verdict.
    pub max_safe_state_share: f64,
    /// Largest share of the samples past start-up a run may lose and still pass.
    pub max_lost_share: f64,
    /// Largest share of the inputs past start-up the plant may hold or replace by its safe
    /// output (late answers no plan covered) in a run that passes.
    pub max_held_share: f64,
    /// Largest share of an adaptive controller's closed-loop steps whose update may be
    /// suspended in a run that passes.
    pub max_suspended_share: f64,
}

/// Accepted range of each measurement channel.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasurementLimits {
    /// Lower bounds of `y`.
    pub y_min: Vec<f64>,
    /// Upper bounds of `y`.
    pub y_max: Vec<f64>,
    /// Lower bounds of `z`.
    pub z_min: Vec<f64>,
    /// Upper bounds of `z`.
    pub z_max: Vec<f64>,
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawChannels {
    y: usize,
    z: usize,
    #[serde(default)]
    r: usize,
    u: usize,
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawService {
    core: Option<usize>,
    fifo_priority: Option<i32>,
    mlockall: Option<bool>,
    cpu_latency: Option<toml::Value>,
    require_rt: Option<bool>,
    wait: Option<WaitMode>,
    grace_periods: Option<u64>,
    max_consecutive_misses: Option<u64>,
    recover_after: Option<u64>,
    recover_tolerance: Option<u64>,
    silent_periods: Option<u64>,
    reset_on_resume: Option<bool>,
    checkpoint_every: Option<f64>,
    on_timing_fault: Option<TimingFaultReset>,
    miss_source: Option<MissSource>,
    u_applied_tolerance: Option<f64>,
    max_safe_state_share: Option<f64>,
    max_lost_share: Option<f64>,
    max_held_share: Option<f64>,
    max_suspended_share: Option<f64>,
    poll_window: Option<f64>,
    peer_timeout: Option<f64>,
    safe_input: Option<ScalarOrVec>,
    y_min: Option<ScalarOrVec>,
    y_max: Option<ScalarOrVec>,
    z_min: Option<ScalarOrVec>,
    z_max: Option<ScalarOrVec>,
    histogram_interval: Option<f64>,
    run_dir: Option<PathBuf>,
    rms_settle: Option<f64>,
    open_loop: Option<f64>,
    /// `service.timing`, read by the answer_timing module (it needs the controller).
    pub timing: Option<String>,
    /// `service.plan-length`, read by the answer_timing module.
    pub plan_length: Option<u64>,
    /// `[service.report]`, read by the tone_report module.
    pub report: Option<super::tone_report::RawReport>,
    /// `[service.telemetry]`, read by the live module.
    pub telemetry: Option<super::live::RawTelemetry>,
    /// `[service.operator]`, read by the live module.
    pub operator: Option<super::live::RawOperator>,
    channels: Option<RawChannels>,
}

/// The `[service]` table, validated, its durations converted to cycles.
pub(super) struct ServiceTable {
    pub counts: ChannelCounts,
    pub rt: RtRequest,
    pub require_rt: bool,
    pub wait: WaitMode,
    pub poll_window_ns: u64,
    pub policy: DeadlinePolicy,
    pub limits: MeasurementLimits,
    pub safe_input: Vec<f64>,
    pub peer_timeout: Duration,
    pub histogram_interval_cycles: u64,
    pub run_dir: PathBuf,
    pub rms_settle_cycles: u64,
    pub open_loop_cycles: u64,
    pub checkpoint_every_cycles: u64,
}

/// `service.cpu-latency`: absent → 0 µs, an integer of µs (0 … 2^31 − 1), or `"off"`
/// (`None`: no request).
fn cpu_latency(v: Option<&toml::Value>) -> Result<Option<u32>, String> {
    match v {
        None => Ok(Some(0)),
        Some(toml::Value::Integer(us)) => match i32::try_from(*us) {
            Ok(us) if us >= 0 => Ok(Some(us as u32)),
            _ => Err(format!("{us} µs: must lie in 0 … {}", i32::MAX)),
        },
        Some(toml::Value::String(s)) if s == "off" => Ok(None),
        Some(other) => Err(format!(
            "{other}: an integer of µs (0: the cores never halt in idle) or \"off\""
        )),
    }
}

/// Validates the table; `plant` gives the channel counts when `[service.channels]` is
/// absent, `period` (s) converts the durations to cycles.
pub(super) fn parse(
    s: &RawService,
    plant: Option<&toml::Value>,
    period: f64,
    err: &ErrFn<'_>,
) -> Result<ServiceTable, ConfigError> {
    let counts = match &s.channels {
        Some(c) => {
            ChannelCounts::new(c.y, c.z, c.r, c.u).map_err(|m| err("service.channels", m))?
        }
        None => channels_from_plant(plant).map_err(|m| err("service.channels", m))?,
    };
    let n_y = counts.n_y as usize;
    let n_z = counts.n_z as usize;
    let n_u = counts.n_u as usize;
    if n_u == 0 {
        return Err(err(
            "service.channels.u",
            "the service needs at least one input u".into(),
        ));
    }

    let fifo_priority = ipc_types::rt::fifo_priority_from_config(s.fifo_priority, 80)
        .map_err(|m| err("service.fifo-priority", m))?;
    let rt = RtRequest {
        core: check_core(s.core, "service.core", "", err)?,
        fifo_priority,
        mlockall: s.mlockall.unwrap_or(true),
        prefault_stack_bytes: 256 * 1024,
        cpu_latency_us: cpu_latency(s.cpu_latency.as_ref())
            .map_err(|m| err("service.cpu-latency", m))?,
    };
    let max_cycles = bounds::max_cycles(period);
    let cycles = |v: Option<u64>, default: u64, min: u64, field: &str| {
        count(v.unwrap_or(default), min, max_cycles, field, err)
    };
    let share = |v: Option<f64>, default: f64, field: &str| match v.unwrap_or(default) {
        x if (0.0..=1.0).contains(&x) => Ok(x),
        _ => Err(err(field, "must lie in [0, 1]".into())),
    };
    let policy = DeadlinePolicy {
        grace_cycles: cycles(s.grace_periods, 100, 0, "service.grace-periods")?,
        max_consecutive_misses: cycles(
            s.max_consecutive_misses,
            10,
            1,
            "service.max-consecutive-misses",
        )?,
        recover_after: Some(cycles(s.recover_after, 0, 0, "service.recover-after")?)
            .filter(|n| *n > 0),
        recover_tolerance: cycles(s.recover_tolerance, 0, 0, "service.recover-tolerance")?,
        silent_periods: cycles(s.silent_periods, 400, 1, "service.silent-periods")?,
        reset_on_resume: s.reset_on_resume.unwrap_or(false),
        on_timing_fault: s.on_timing_fault.unwrap_or_default(),
        miss_source: s.miss_source.unwrap_or(MissSource::Plant),
        max_safe_state_share: share(s.max_safe_state_share, 0.1, "service.max-safe-state-share")?,
        max_lost_share: share(s.max_lost_share, 0.01, "service.max-lost-share")?,
        max_held_share: share(s.max_held_share, 0.01, "service.max-held-share")?,
        max_suspended_share: share(s.max_suspended_share, 0.5, "service.max-suspended-share")?,
        u_applied_tolerance: match s.u_applied_tolerance.unwrap_or(1e-6) {
            t if t >= 0.0 && t.is_finite() => t,
            _ => {
                return Err(err(
                    "service.u-applied-tolerance",
                    "must be finite and ≥ 0".into(),
                ));
            }
        },
    };
    match policy.recover_after {
        Some(m) if policy.recover_tolerance >= m => {
            return Err(err(
                "service.recover-tolerance",
                format!(
                    "{} misses allowed in a recovery window of {m} answers would leave the \
                     safe state whatever happens; it must be less than service.recover-after",
                    policy.recover_tolerance
                ),
            ));
        }
        None if policy.recover_tolerance > 0 => {
            return Err(err(
                "service.recover-tolerance",
                "has no effect without service.recover-after (the safe state is kept for \
                 the session)"
                    .into(),
            ));
        }
        _ => {}
    }
    let limits = MeasurementLimits {
        y_min: per_channel(&s.y_min, n_y, f64::NEG_INFINITY, "service.y-min", err)?,
        y_max: per_channel(&s.y_max, n_y, f64::INFINITY, "service.y-max", err)?,
        z_min: per_channel(&s.z_min, n_z, f64::NEG_INFINITY, "service.z-min", err)?,
        z_max: per_channel(&s.z_max, n_z, f64::INFINITY, "service.z-max", err)?,
    };
    check_range(&limits.y_min, &limits.y_max, "y", "service.y-min", err)?;
    check_range(&limits.z_min, &limits.z_max, "z", "service.z-min", err)?;
    check_noise(plant, &limits, err)?;
    let safe_input = per_channel(&s.safe_input, n_u, 0.0, "service.safe-input", err)?;
    if safe_input.iter().any(|v| !v.is_finite()) {
        return Err(err("service.safe-input", "must be finite".into()));
    }
    let wait_s = |v: Option<f64>, default: f64, field: &str| {
        seconds(v.unwrap_or(default), false, MAX_WAIT_S, field, err)
    };
    let peer_timeout = wait_s(s.peer_timeout, 30.0, "service.peer-timeout")?;
    let peer_timeout = Duration::try_from_secs_f64(peer_timeout)
        .map_err(|e| err("service.peer-timeout", e.to_string()))?;
    let interval = wait_s(s.histogram_interval, 1.0, "service.histogram-interval")?;
    let run_s = |v: Option<f64>, field: &str| -> Result<u64, ConfigError> {
        let v = seconds(v.unwrap_or(0.0), true, MAX_DURATION_S, field, err)?;
        Ok(bounds::cycles(v, period))
    };
    Ok(ServiceTable {
        counts,
        rt,
        require_rt: s.require_rt.unwrap_or(false),
        wait: s.wait.unwrap_or(WaitMode::SleepPoll),
        poll_window_ns: {
            let w = seconds(
                s.poll_window.unwrap_or(40e-6),
                true,
                MAX_WAIT_S,
                "service.poll-window",
                err,
            )?;
            if w > period / 3.0 {
                return Err(err(
                    "service.poll-window",
                    format!(
                        "{w} s is more than a third of the sample period {period} s: the \
                         thread would poll most of each period"
                    ),
                ));
            }
            (w * 1e9).round() as u64
        },
        policy,
        limits,
        safe_input,
        peer_timeout,
        histogram_interval_cycles: bounds::cycles(interval, period).max(1),
        run_dir: s.run_dir.clone().unwrap_or_else(|| PathBuf::from("runs")),
        rms_settle_cycles: run_s(s.rms_settle, "service.rms-settle")?,
        open_loop_cycles: run_s(s.open_loop, "service.open-loop")?,
        checkpoint_every_cycles: {
            let every = seconds(
                s.checkpoint_every.unwrap_or(1.0),
                true,
                MAX_DURATION_S,
                "service.checkpoint-every",
                err,
            )?;
            if every > 0.0 && every < 0.1 {
                return Err(err(
                    "service.checkpoint-every",
                    format!("{every} s is below 0.1 s (0 writes a checkpoint only at the end)"),
                ));
            }
            bounds::cycles(every, period)
        },
    })
}

/// A core to pin the RT thread to (`service.core`, or the `--core` option: `how` says
/// which), below [`MAX_CORES`].
pub(super) fn check_core(
    core: Option<usize>,
    field: &str,
    how: &str,
    err: &ErrFn<'_>,
) -> Result<Option<usize>, ConfigError> {
    match core {
        Some(c) if c >= MAX_CORES => Err(err(
            field,
            format!("core {c}{how} is not below {MAX_CORES} (CPU_SETSIZE)"),
        )),
        c => Ok(c),
    }
}

/// Every channel's `min < max` (`signal` is `y` or `z`; `field` names the lower bound).
fn check_range(
    min: &[f64],
    max: &[f64],
    signal: &str,
    field: &str,
    err: &ErrFn<'_>,
) -> Result<(), ConfigError> {
    for (i, (lo, hi)) in min.iter().zip(max).enumerate() {
        if lo.is_nan() || hi.is_nan() || lo >= hi {
            return Err(err(
                field,
                format!("channel {i}: {signal}-min {lo} must be below {signal}-max {hi}"),
            ));
        }
    }
    Ok(())
}

/// The measurement noise of the plant proxy's `[plant.noise]` table (when it gives it as
/// numbers) against the accepted ranges: a standard deviation wider than a channel's
/// range would have most samples rejected, and is refused naming the noise.
fn check_noise(
    plant: Option<&toml::Value>,
    limits: &MeasurementLimits,
    err: &ErrFn<'_>,
) -> Result<(), ConfigError> {
    let Some(plant) = plant.map(PlantOutline::new) else {
        return Ok(());
    };
    let ranges = [
        ("y", &limits.y_min, &limits.y_max),
        ("z", &limits.z_min, &limits.z_max),
    ];
    for (signal, min, max) in ranges {
        for (i, (lo, hi)) in min.iter().zip(max.iter()).enumerate() {
            if let Some(sigma) = plant.noise_std(signal, i)
                && sigma > hi - lo
            {
                return Err(err(
                    &format!("plant.noise.{signal}-std"),
                    format!(
                        "channel {i}: a noise of standard deviation {sigma} is wider than the \
                         accepted range [{lo}, {hi}] (service.{signal}-min, \
                         service.{signal}-max): most samples would be rejected"
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// The channel counts from the plant proxy's `[plant]` table ([`PlantOutline`]).
fn channels_from_plant(plant: Option<&toml::Value>) -> Result<ChannelCounts, String> {
    let plant = plant.ok_or(
        "neither [service.channels] nor a [plant] table says how many channels the rig has",
    )?;
    PlantOutline::new(plant).channel_counts()
}

#[cfg(test)]
mod tests {
    use super::super::ServiceConfig;
    use super::super::refusal_cases::assert_refused_naming_fields;

    /// A static gain `u = −2y`, with a `[service]` table.
    const BASE: &str = include_str!("../../../tests/fixtures/config/lti-static-gain.toml");

    fn latency(lines: &str) -> Option<u32> {
        let text = BASE.replacen("[service]", &format!("[service]\n{lines}"), 1);
        ServiceConfig::parse(&text, "t.toml")
            .expect("valid")
            .rt
            .cpu_latency_us
    }

    #[test]
    fn the_cpu_wake_up_latency_is_held_at_0_unless_configured() {
        assert_eq!(latency(""), Some(0));
        assert_eq!(latency("cpu-latency = 20"), Some(20));
        assert_eq!(latency("cpu-latency = \"off\""), None);
        let cases = include_str!("../../../tests/fixtures/refusals/service-cpu-latency.toml");
        assert_refused_naming_fields(BASE, "t.toml", cases);
    }
}
