//! # The telemetry contract: a live view of a run, for readers that are never peers
//!
//! The control services of a rig admit exactly one plant and one service ([`crate::ports`]).
//! A live view must not change that, so the service publishes what a watcher needs on
//! services of its own, from a non-real-time thread:
//!
//! | service (rig `N`)                 | pattern           | payload            | history |
//! |-----------------------------------|-------------------|--------------------|---------|
//! | `adaptive-rig/N/telemetry`        | publish-subscribe | [`TelemetryFrame`] | none    |
//! | `adaptive-rig/N/telemetry-info`   | publish-subscribe | [`TelemetryInfo`]  | 1       |
//!
//! Each admits one publisher (the service) and up to [`MAX_READERS`] subscribers
//! (`rig monitor`, a script); a reader that falls behind loses its oldest frames, never
//! the service's time. [`TelemetryInfo`] is published once per run and kept as history, so
//! a reader that connects later still gets the configuration in use; frames follow at about
//! [`FRAME_PERIOD_MS`].
//!
//! ## What a frame holds
//!
//! - the run's state ([`run_state`]), the loop's state bits ([`live_flags`]) and the
//!   verdict as it stands ([`verdict_state`], with its failure lines as text): the service
//!   judges the counters so far with the same rule as its final report;
//! - [`TelemetryCounters`]: the run report's counters so far;
//! - four [`LatencySnapshot`]s (wake-up, compute, response, period jitter): percentiles and
//!   cumulative bucket counts of the HdrHistograms the loop keeps, as of the latest
//!   histogram interval;
//! - a [`ToneSnapshot`]: the amplitude of each tone of the report in `z`, fitted by least
//!   squares over the last window of samples, beside its open-loop level (the last window
//!   of the session's open-loop phase);
//! - up to [`MAX_POINTS`] decimated [`TelemetryPoint`]s: `z_k`, `u_k` and `‖θ_k‖` (the
//!   2-norm of the controller's parameter estimate, e.g. RCAC's θ of (2.22)).
//!
//! Times are `CLOCK_MONOTONIC` nanoseconds ([`crate::clock::monotonic_ns`]);
//! [`TelemetryFrame::unix_minus_monotonic_ns`] turns them into Unix time for a display.
//! Every payload is `#[repr(C)]`, `Copy` and [`ZeroCopySend`] with a versioned type name;
//! [`TELEMETRY_VERSION`] changes with any change of layout or meaning.

pub mod ports;

use crate::{ChannelCounts, MAX_U, MAX_Z};
use iceoryx2::prelude::ZeroCopySend;

/// Version of the telemetry contract, carried in every frame and info.
pub const TELEMETRY_VERSION: u32 = 1;
/// Decimated points a frame carries at most.
pub const MAX_POINTS: usize = 128;
/// Tones a frame reports at most.
pub const MAX_TONES: usize = 16;
/// Tunables a controller declares to the operator at most.
pub const MAX_TUNABLES: usize = 8;
/// Subscribers a telemetry service admits.
pub const MAX_READERS: usize = 8;
/// About how often the service publishes a frame, ms.
pub const FRAME_PERIOD_MS: u64 = 50;
/// Bytes of configuration text an info carries (a longer text is cut and flagged).
pub const CONFIG_TEXT_CAPACITY: usize = 65_536;
/// Bytes of the verdict's failure lines a frame carries.
pub const VERDICT_TEXT_CAPACITY: usize = 1_024;
/// Upper bounds of the latency buckets, ns: 1 µs to 10 ms in a 1-2-5 series, with the
/// 8 kHz period (125 µs) among them. A [`LatencySnapshot`] counts the values at or below
/// each.
pub const LATENCY_BUCKET_BOUNDS_NS: [u64; LATENCY_BUCKETS] = [
    1_000, 2_000, 5_000, 10_000, 20_000, 50_000, 100_000, 125_000, 200_000, 500_000, 1_000_000,
    2_000_000, 5_000_000, 10_000_000,
];
/// Number of latency buckets.
pub const LATENCY_BUCKETS: usize = 14;

/// What the run is doing ([`TelemetryFrame::state`]).
pub mod run_state {
    /// Waiting for the plant to connect.
    pub const WAITING: u32 = 0;
    /// The loop runs.
    pub const RUNNING: u32 = 1;
    /// The run ended; the frame holds its final figures.
    pub const ENDED: u32 = 2;
}

/// The loop's state as of the newest sample ([`TelemetryFrame::flags`]).
pub mod live_flags {
    /// The loop applies its safe input (after deadline misses, or on the operator's
    /// command).
    pub const SAFE_STATE: u32 = 1 << 0;
    /// The operator holds the loop in its safe state.
    pub const OPERATOR_SAFE_STATE: u32 = 1 << 1;
    /// The operator froze the controller's adaptation.
    pub const ADAPTATION_FROZEN: u32 = 1 << 2;
    /// The session's open-loop phase (`service.open-loop`).
    pub const OPEN_LOOP: u32 = 1 << 3;
    /// The plant is silent.
    pub const PLANT_SILENT: u32 = 1 << 4;
    /// The plant runs in lockstep.
    pub const LOCKSTEP: u32 = 1 << 5;
    /// The service accepts operator commands ([`crate::operator`]).
    pub const COMMANDS_ENABLED: u32 = 1 << 6;
}

/// The verdict as it stands ([`TelemetryFrame::verdict`]).
pub mod verdict_state {
    /// Nothing judged yet (no sample past start-up).
    pub const PENDING: u32 = 0;
    /// No failure so far (final when the run ended).
    pub const OK: u32 = 1;
    /// At least one failure so far (final when the run ended);
    /// [`TelemetryFrame::verdict_text`](super::TelemetryFrame::verdict_text) lists them.
    pub const FAILED: u32 = 2;
}

/// Text in a fixed byte array: UTF-8, up to the first NUL.
pub fn fixed_text(bytes: &[u8]) -> &str {
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    match core::str::from_utf8(&bytes[..end]) {
        Ok(s) => s,
        // Cut inside a character: keep the valid prefix.
        Err(e) => core::str::from_utf8(&bytes[..e.valid_up_to()]).unwrap_or(""),
    }
}

/// Copies `text` into `out`, cut at a character boundary so that it fits with a NUL after
/// it; returns false when it was cut.
pub fn set_fixed_text(out: &mut [u8], text: &str) -> bool {
    out.fill(0);
    let room = out.len().saturating_sub(1);
    let mut end = text.len().min(room);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    out[..end].copy_from_slice(&text.as_bytes()[..end]);
    end == text.len()
}

/// One decimated sample of the loop.
#[repr(C)]
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[type_name("adaptive_rig::TelemetryPoint.v1")]
pub struct TelemetryPoint {
    /// Sample index `k`.
    pub seq: u64,
    /// Sample time, `CLOCK_MONOTONIC` ns.
    pub t_sample_ns: u64,
    /// The actuation status of the input given for sample `k` (`actuation_status`).
    pub status: u32,
    /// The measurement's flags (`measurement_flags`).
    pub flags: u32,
    /// `‖θ_k‖`, the 2-norm of the controller's parameter estimate; NaN for a controller
    /// without one.
    pub theta_norm: f64,
    /// `z_k` (the frame's `n_z` entries are used).
    pub z: [f64; MAX_Z],
    /// The input given for sample `k` (the frame's `n_u` entries are used).
    pub u: [f64; MAX_U],
}

impl TelemetryPoint {
    /// A point of sample 0 with every value zero and `‖θ‖` NaN.
    pub const fn zeroed() -> Self {
        Self {
            seq: 0,
            t_sample_ns: 0,
            status: 0,
            flags: 0,
            theta_norm: f64::NAN,
            z: [0.0; MAX_Z],
            u: [0.0; MAX_U],
        }
    }
}

/// The run report's counters so far; the meaning of each is that of the report's field
/// of the same name (docs/report.md).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, ZeroCopySend)]
#[type_name("adaptive_rig::TelemetryCounters.v1")]
pub struct TelemetryCounters {
    /// Measurements received.
    pub received: u64,
    /// Answers published.
    pub published: u64,
    /// Controller steps run.
    pub controller_steps: u64,
    /// Samples never seen (gaps in the sequence).
    pub lost: u64,
    /// Samples past start-up.
    pub samples_past_startup: u64,
    /// Of those, the lost ones.
    pub lost_past_startup: u64,
    /// Of those, the ones whose input the plant held although the service had sent one.
    pub held_past_startup: u64,
    /// Samples received too late to answer (observed).
    pub caught_up: u64,
    /// Samples refused by the gate or the sequence checks.
    pub rejected: u64,
    /// Answers after the plant's deadline.
    pub deadline_misses: u64,
    /// Misses the plant reported.
    pub plant_reported_misses: u64,
    /// Of those, the ones covered by a plan entry.
    pub plan_covered_misses: u64,
    /// Longest run of consecutive misses.
    pub max_consecutive_misses: u64,
    /// Entries into the safe state.
    pub safe_state_entries: u64,
    /// Cycles in the safe state.
    pub safe_state_cycles: u64,
    /// Times the plant went silent.
    pub plant_silent_events: u64,
    /// New plant sessions after the first.
    pub new_sessions: u64,
    /// Cycles the controller reported saturation.
    pub saturated_cycles: u64,
    /// Cycles the controller reported a fault.
    pub controller_faults: u64,
    /// Cycles the controller applied its fallback input.
    pub fallback_cycles: u64,
    /// Actuations that could not be published.
    pub publish_failures: u64,
    /// Samples refused because another publisher than the pinned plant sent them.
    pub foreign_samples: u64,
    /// Operator commands applied.
    pub commands_applied: u64,
    /// Operator commands refused.
    pub commands_refused: u64,
    /// Samples the telemetry thread did not get (its queue was full); the loop never
    /// waits for it.
    pub telemetry_dropped: u64,
}

/// Percentiles and bucket counts of one of the loop's latency histograms.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("adaptive_rig::LatencySnapshot.v1")]
pub struct LatencySnapshot {
    /// Values recorded.
    pub count: u64,
    /// Their sum, ns (from the histogram's mean; within its 3 significant figures).
    pub sum_ns: f64,
    /// Median, ns.
    pub p50_ns: u64,
    /// 90th percentile, ns.
    pub p90_ns: u64,
    /// 99th percentile, ns.
    pub p99_ns: u64,
    /// 99.9th percentile, ns.
    pub p999_ns: u64,
    /// Largest value, ns.
    pub max_ns: u64,
    /// Values at or below each of [`LATENCY_BUCKET_BOUNDS_NS`] (cumulative).
    pub buckets: [u64; LATENCY_BUCKETS],
}

/// Which histogram a [`TelemetryFrame::latency`] entry is.
pub mod latency_index {
    /// Sample time to the RT thread's wake-up.
    pub const WAKEUP: usize = 0;
    /// The controller's step.
    pub const COMPUTE: usize = 1;
    /// Sample time to the publication of the answer.
    pub const RESPONSE: usize = 2;
    /// Period jitter of the receipt times.
    pub const JITTER: usize = 3;
    /// The names used in reports and metrics, by index.
    pub const NAMES: [&str; 4] = ["wakeup", "compute", "response", "jitter"];
}

/// Tone amplitudes in `z`, now and in the open-loop phase.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("adaptive_rig::ToneSnapshot.v1")]
pub struct ToneSnapshot {
    /// Tones used.
    pub n_tones: u32,
    /// Samples in the window of the newest fit (0: none yet).
    pub window_samples: u32,
    /// Frequency of each tone, Hz.
    pub hz: [f64; MAX_TONES],
    /// Amplitude of tone `i` in channel `j` of `z` over the newest window: `amplitude[i][j]`;
    /// NaN when not measured yet.
    pub amplitude: [[f64; MAX_Z]; MAX_TONES],
    /// The same over the last window of the session's open-loop phase; NaN when the
    /// session has none or it is not over yet.
    pub open_loop: [[f64; MAX_Z]; MAX_TONES],
}

impl Default for ToneSnapshot {
    fn default() -> Self {
        Self {
            n_tones: 0,
            window_samples: 0,
            hz: [0.0; MAX_TONES],
            amplitude: [[f64::NAN; MAX_Z]; MAX_TONES],
            open_loop: [[f64::NAN; MAX_Z]; MAX_TONES],
        }
    }
}

/// One telemetry frame (see the module docs).
#[repr(C)]
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[type_name("adaptive_rig::TelemetryFrame.v1")]
pub struct TelemetryFrame {
    /// [`TELEMETRY_VERSION`].
    pub version: u32,
    /// [`run_state`].
    pub state: u32,
    /// [`live_flags`].
    pub flags: u32,
    /// [`verdict_state`].
    pub verdict: u32,
    /// Performance channels used in the points.
    pub n_z: u16,
    /// Actuation channels used in the points.
    pub n_u: u16,
    /// Points used.
    pub n_points: u32,
    /// The service's process id.
    pub service_pid: u32,
    /// Tunables used in [`TelemetryFrame::tunable_values`].
    pub n_tunables: u32,
    /// The run's identity: its start, Unix ns (a restarted service starts a new run).
    pub run_id: u64,
    /// Frames published in this run before this one.
    pub frame_seq: u64,
    /// Publication time, `CLOCK_MONOTONIC` ns.
    pub t_publish_ns: u64,
    /// Add to a `CLOCK_MONOTONIC` time of this machine to get Unix time, ns.
    pub unix_minus_monotonic_ns: i64,
    /// The newest sample's index (0 before any).
    pub last_seq: u64,
    /// The counters so far.
    pub counters: TelemetryCounters,
    /// Wake-up, compute, response and jitter histograms ([`latency_index`]).
    pub latency: [LatencySnapshot; 4],
    /// Tone amplitudes.
    pub tones: ToneSnapshot,
    /// The current value of each declared tunable, in the order of
    /// [`TelemetryInfo::tunables`].
    pub tunable_values: [f64; MAX_TUNABLES],
    /// The verdict's failure lines so far, one per line (UTF-8, NUL-terminated).
    pub verdict_text: [u8; VERDICT_TEXT_CAPACITY],
    /// The decimated samples since the previous frame, oldest first.
    pub points: [TelemetryPoint; MAX_POINTS],
}

impl TelemetryFrame {
    /// An empty frame of this version: no points, no tones, every counter zero.
    pub fn empty() -> Self {
        Self {
            version: TELEMETRY_VERSION,
            state: run_state::WAITING,
            flags: 0,
            verdict: verdict_state::PENDING,
            n_z: 0,
            n_u: 0,
            n_points: 0,
            service_pid: 0,
            n_tunables: 0,
            run_id: 0,
            frame_seq: 0,
            t_publish_ns: 0,
            unix_minus_monotonic_ns: 0,
            last_seq: 0,
            counters: TelemetryCounters::default(),
            latency: [LatencySnapshot::default(); 4],
            tones: ToneSnapshot::default(),
            tunable_values: [f64::NAN; MAX_TUNABLES],
            verdict_text: [0; VERDICT_TEXT_CAPACITY],
            points: [TelemetryPoint::zeroed(); MAX_POINTS],
        }
    }

    /// The points used, oldest first.
    pub fn points(&self) -> &[TelemetryPoint] {
        &self.points[..(self.n_points as usize).min(MAX_POINTS)]
    }

    /// The verdict's failure lines.
    pub fn verdict_text(&self) -> &str {
        fixed_text(&self.verdict_text)
    }
}

/// A parameter of the controller that the operator may change while it runs, within the
/// bounds the configuration declares ([`crate::operator`]).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("adaptive_rig::TunableInfo.v1")]
pub struct TunableInfo {
    /// Its name in the configuration (`"alpha"`), NUL-terminated.
    pub name: [u8; 32],
    /// Smallest value the operator may set.
    pub min: f64,
    /// Largest value the operator may set.
    pub max: f64,
    /// Its value at the start of the run.
    pub initial: f64,
}

impl TunableInfo {
    /// Its name.
    pub fn name(&self) -> &str {
        fixed_text(&self.name)
    }
}

/// What a run is: published once per run on `adaptive-rig/N/telemetry-info` and kept as
/// the service's history, so a reader that connects later gets it too.
#[repr(C)]
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[type_name("adaptive_rig::TelemetryInfo.v1")]
pub struct TelemetryInfo {
    /// [`TELEMETRY_VERSION`].
    pub version: u32,
    /// The service's process id.
    pub service_pid: u32,
    /// The run's identity ([`TelemetryFrame::run_id`]).
    pub run_id: u64,
    /// Sample period, ns.
    pub sample_period_ns: u64,
    /// The response-time budget of the latency figures, ns.
    pub budget_ns: u64,
    /// The configured channel counts.
    pub counts: ChannelCounts,
    /// The loop's timing (`Timing::wire`).
    pub timing: u32,
    /// Tunables used in [`TelemetryInfo::tunables`].
    pub n_tunables: u32,
    /// The declared tunables.
    pub tunables: [TunableInfo; MAX_TUNABLES],
    /// The rig's name.
    pub rig: [u8; 72],
    /// The controller's kind (`"rcac"`, …).
    pub controller: [u8; 32],
    /// The run folder.
    pub run_folder: [u8; 512],
    /// The configuration file.
    pub config_path: [u8; 512],
    /// The configuration text was longer than [`CONFIG_TEXT_CAPACITY`] and is cut.
    pub config_cut: u32,
    /// Bytes used in [`TelemetryInfo::config_text`].
    pub config_len: u32,
    /// The configuration file's text as the service read it.
    pub config_text: [u8; CONFIG_TEXT_CAPACITY],
}

impl TelemetryInfo {
    /// An info of this version with every field empty.
    pub fn empty() -> Self {
        Self {
            version: TELEMETRY_VERSION,
            service_pid: 0,
            run_id: 0,
            sample_period_ns: 0,
            budget_ns: 0,
            counts: ChannelCounts::default(),
            timing: 0,
            n_tunables: 0,
            tunables: [TunableInfo {
                name: [0; 32],
                min: 0.0,
                max: 0.0,
                initial: 0.0,
            }; MAX_TUNABLES],
            rig: [0; 72],
            controller: [0; 32],
            run_folder: [0; 512],
            config_path: [0; 512],
            config_cut: 0,
            config_len: 0,
            config_text: [0; CONFIG_TEXT_CAPACITY],
        }
    }

    /// The declared tunables.
    pub fn tunables(&self) -> &[TunableInfo] {
        &self.tunables[..(self.n_tunables as usize).min(MAX_TUNABLES)]
    }

    /// The configuration text (cut at a character boundary when it did not fit).
    pub fn config_text(&self) -> &str {
        let n = (self.config_len as usize).min(CONFIG_TEXT_CAPACITY);
        fixed_text(&self.config_text[..n])
    }

    /// Sets the configuration text, cut to [`CONFIG_TEXT_CAPACITY`] − 1 bytes.
    pub fn set_config_text(&mut self, text: &str) {
        let whole = set_fixed_text(&mut self.config_text, text);
        self.config_cut = u32::from(!whole);
        self.config_len = fixed_text(&self.config_text).len() as u32;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bucket_bounds_rise_and_hold_the_8_khz_period() {
        assert!(LATENCY_BUCKET_BOUNDS_NS.windows(2).all(|w| w[0] < w[1]));
        assert!(LATENCY_BUCKET_BOUNDS_NS.contains(&125_000));
    }

    #[test]
    fn fixed_text_is_cut_at_a_character_boundary_and_read_back() {
        let mut buf = [0u8; 6];
        // "ααα" is 6 bytes; only two characters fit before the NUL.
        assert!(!set_fixed_text(&mut buf, "ααα"));
        assert_eq!(fixed_text(&buf), "αα");
        assert!(set_fixed_text(&mut buf, "ab"));
        assert_eq!(fixed_text(&buf), "ab");
    }

    #[test]
    fn an_info_keeps_its_configuration_text_and_says_when_it_was_cut() {
        let mut info = TelemetryInfo::empty();
        info.set_config_text("[service]\nrig = \"a\"\n");
        assert_eq!(info.config_text(), "[service]\nrig = \"a\"\n");
        assert_eq!(info.config_cut, 0);
        let long = "x".repeat(CONFIG_TEXT_CAPACITY + 10);
        info.set_config_text(&long);
        assert_eq!(info.config_cut, 1);
        assert_eq!(info.config_text().len(), CONFIG_TEXT_CAPACITY - 1);
    }
}
