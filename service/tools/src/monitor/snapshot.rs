//! The JSON views of the monitor's state: `/api/state` ([`StateView`]) and `/api/points`
//! ([`PointsView`]), documented field by field in docs/monitor.md.
//!
//! A number the service reports as NaN (‖θ‖ of a controller without parameters, a tone not
//! measured yet) is `null`. Times: `*_ns` fields are nanoseconds as the frame carries them
//! (monotonic unless named `unix`), `*_unix_ms` are Unix milliseconds (a float, as a
//! browser's `Date.now()`), `*_s` are seconds.

use super::counters;
use super::state::{
    Connection, Hub, RigState, RunSummary, ScopePoint, run_state_name, verdict_name,
};
use ipc_types::Timing;
use ipc_types::telemetry::{
    LATENCY_BUCKET_BOUNDS_NS, LatencySnapshot, TelemetryFrame, TelemetryInfo, fixed_text,
    latency_index, live_flags,
};
use serde::Serialize;
use std::collections::BTreeMap;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

/// `Some(x)` for a finite `x`, else `None` (JSON `null`).
pub fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

/// Now, Unix ms.
pub fn now_unix_ms() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs_f64() * 1e3)
        .unwrap_or(0.0)
}

/// The whole of `/api/state`.
#[derive(Debug, Serialize)]
pub struct StateView {
    /// The monitor itself.
    pub monitor: MonitorView,
    /// One entry per `--rig`, in the order given.
    pub rigs: Vec<RigView>,
}

/// How the monitor runs.
#[derive(Debug, Clone, Serialize)]
pub struct MonitorView {
    /// The `rig-tools` version.
    pub version: &'static str,
    /// Whether it forwards operator commands (`--allow-commands`).
    pub commands_allowed: bool,
    /// The Foxglove WebSocket address, when serving one.
    pub foxglove: Option<String>,
    /// The monitor's clock when the view was made, Unix ms.
    pub now_unix_ms: f64,
    /// A rig is stale after this long without a frame, s.
    pub stale_after_s: f64,
}

/// One rig.
#[derive(Debug, Serialize)]
pub struct RigView {
    /// Its name.
    pub rig: String,
    /// `"waiting"` (no frame yet), `"live"` or `"stale"` (no frame for more than
    /// `stale_after_s`).
    pub connection: &'static str,
    /// Age of the newest frame, s.
    pub last_frame_age_s: Option<f64>,
    /// Why the monitor cannot subscribe to the rig's telemetry, while it cannot.
    pub reader_error: Option<String>,
    /// Where the monitor keeps itself relative to the service's real-time cores.
    pub placement: Option<String>,
    /// Times the monitor subscribed (a stale rig is subscribed afresh now and then).
    pub reader_opens: u64,
    /// Frames received since the monitor started.
    pub frames_received: u64,
    /// Frames the monitor missed (it fell behind).
    pub frames_lost: u64,
    /// Runs seen since the monitor started.
    pub runs_seen: u64,
    /// The current (newest) run; `null` before the first frame.
    pub run: Option<RunView>,
    /// The run's info (configuration); `null` until the service published it.
    pub info: Option<InfoView>,
    /// Earlier runs seen by this monitor, oldest first.
    pub previous_runs: Vec<RunSummary>,
}

/// The newest frame of the current run.
#[derive(Debug, Serialize)]
pub struct RunView {
    /// The run's identity (its start, Unix ns).
    pub run_id: u64,
    /// The service's process id.
    pub service_pid: u32,
    /// Frames the service published in this run before the newest.
    pub frame_seq: u64,
    /// `"waiting"`, `"running"` or `"ended"`.
    pub run_state: &'static str,
    /// The loop's state bits by name.
    pub flags: FlagsView,
    /// `"pending"`, `"ok"` or `"failed"`.
    pub verdict: &'static str,
    /// The verdict's failure lines.
    pub verdict_text: String,
    /// The newest sample's index.
    pub last_seq: u64,
    /// The newest point's sample time, Unix ms.
    pub last_sample_unix_ms: Option<f64>,
    /// The frame's publication time, Unix ms.
    pub publish_unix_ms: f64,
    /// Add to a monotonic time of the frame to get Unix time, ns.
    pub unix_minus_monotonic_ns: i64,
    /// ‖θ‖ of the newest point.
    pub theta_norm: Option<f64>,
    /// Channels of `z` in the points.
    pub n_z: u16,
    /// Channels of `u` in the points.
    pub n_u: u16,
    /// The counters by name (the run report's fields).
    pub counters: BTreeMap<&'static str, u64>,
    /// The latency histograms by name: `wakeup`, `compute`, `response`, `jitter`.
    pub latency: BTreeMap<&'static str, LatencyView>,
    /// Tone amplitudes.
    pub tones: TonesView,
    /// The declared tunables with their values now.
    pub tunables: Vec<TunableView>,
}

/// The loop's state bits.
#[derive(Debug, Serialize)]
pub struct FlagsView {
    /// The loop applies its safe input.
    pub safe_state: bool,
    /// The operator holds it there.
    pub operator_safe_state: bool,
    /// The operator froze the adaptation.
    pub adaptation_frozen: bool,
    /// The session's open-loop phase.
    pub open_loop: bool,
    /// The plant is silent.
    pub plant_silent: bool,
    /// The plant runs in lockstep.
    pub lockstep: bool,
    /// The service accepts operator commands.
    pub commands_enabled: bool,
}

impl FlagsView {
    /// The flags of [`live_flags`] bits.
    pub fn of(bits: u32) -> Self {
        let on = |b: u32| bits & b != 0;
        Self {
            safe_state: on(live_flags::SAFE_STATE),
            operator_safe_state: on(live_flags::OPERATOR_SAFE_STATE),
            adaptation_frozen: on(live_flags::ADAPTATION_FROZEN),
            open_loop: on(live_flags::OPEN_LOOP),
            plant_silent: on(live_flags::PLANT_SILENT),
            lockstep: on(live_flags::LOCKSTEP),
            commands_enabled: on(live_flags::COMMANDS_ENABLED),
        }
    }
}

/// One latency histogram.
#[derive(Debug, Serialize)]
pub struct LatencyView {
    /// Values recorded.
    pub count: u64,
    /// Their sum, ns.
    pub sum_ns: f64,
    /// Median, ns.
    pub p50_ns: u64,
    /// 90th percentile, ns.
    pub p90_ns: u64,
    /// 99th percentile, ns.
    pub p99_ns: u64,
    /// 99.9th percentile, ns.
    pub p999_ns: u64,
    /// Largest, ns.
    pub max_ns: u64,
    /// Values at or below each bound (cumulative), without the `+Inf` bucket (= `count`).
    pub buckets: Vec<BucketView>,
}

/// One cumulative bucket.
#[derive(Debug, Serialize)]
pub struct BucketView {
    /// Its upper bound, ns.
    pub le_ns: u64,
    /// Values at or below it.
    pub count: u64,
}

impl LatencyView {
    fn of(s: &LatencySnapshot) -> Self {
        Self {
            count: s.count,
            sum_ns: s.sum_ns,
            p50_ns: s.p50_ns,
            p90_ns: s.p90_ns,
            p99_ns: s.p99_ns,
            p999_ns: s.p999_ns,
            max_ns: s.max_ns,
            buckets: LATENCY_BUCKET_BOUNDS_NS
                .iter()
                .zip(s.buckets)
                .map(|(&le_ns, count)| BucketView { le_ns, count })
                .collect(),
        }
    }
}

/// The tones of the newest fit.
#[derive(Debug, Serialize)]
pub struct TonesView {
    /// Samples in the window of the newest fit (0: none yet).
    pub window_samples: u32,
    /// One entry per tone.
    pub tones: Vec<ToneView>,
}

/// One tone, per channel of `z`.
#[derive(Debug, Serialize)]
pub struct ToneView {
    /// Its frequency, Hz.
    pub hz: f64,
    /// Its amplitude in each channel of `z` now.
    pub amplitude: Vec<Option<f64>>,
    /// The same in the open-loop phase.
    pub open_loop: Vec<Option<f64>>,
    /// `20·log10(open_loop / amplitude)` per channel, dB: how much the loop suppresses it.
    pub suppression_db: Vec<Option<f64>>,
}

/// Suppression in dB of a tone at `now` against its open-loop level `open`.
pub fn suppression_db(open: f64, now: f64) -> Option<f64> {
    if open.is_finite() && now.is_finite() && open > 0.0 && now > 0.0 {
        Some(20.0 * (open / now).log10())
    } else {
        None
    }
}

/// One declared tunable.
#[derive(Debug, Serialize)]
pub struct TunableView {
    /// Its name.
    pub name: String,
    /// Smallest value allowed.
    pub min: f64,
    /// Largest value allowed.
    pub max: f64,
    /// Its value at the start of the run.
    pub initial: f64,
    /// Its value now.
    pub value: Option<f64>,
}

/// The run's info.
#[derive(Debug, Serialize)]
pub struct InfoView {
    /// The run it describes.
    pub run_id: u64,
    /// Whether that is the current run (false until the new run's info arrives).
    pub current: bool,
    /// The service's process id.
    pub service_pid: u32,
    /// The rig's name as the service has it.
    pub rig: String,
    /// The controller's kind.
    pub controller: String,
    /// Sample period, ns.
    pub sample_period_ns: u64,
    /// Response-time budget, ns.
    pub budget_ns: u64,
    /// Channel counts `{n_y, n_z, n_r, n_u}`.
    pub counts: BTreeMap<&'static str, u16>,
    /// The loop's timing (`"send-ahead"`, …).
    pub timing: String,
    /// The run folder.
    pub run_folder: String,
    /// The configuration file.
    pub config_path: String,
    /// The configuration text.
    pub config_text: String,
    /// The text was cut to the contract's capacity.
    pub config_cut: bool,
}

impl InfoView {
    fn of(info: &TelemetryInfo, current: bool) -> Self {
        let c = info.counts;
        Self {
            run_id: info.run_id,
            current,
            service_pid: info.service_pid,
            rig: fixed_text(&info.rig).to_string(),
            controller: fixed_text(&info.controller).to_string(),
            sample_period_ns: info.sample_period_ns,
            budget_ns: info.budget_ns,
            counts: BTreeMap::from([
                ("n_y", c.n_y),
                ("n_z", c.n_z),
                ("n_r", c.n_r),
                ("n_u", c.n_u),
            ]),
            timing: Timing::from_wire(info.timing)
                .map(|t| t.name().to_string())
                .unwrap_or_else(|| format!("unknown ({})", info.timing)),
            run_folder: fixed_text(&info.run_folder).to_string(),
            config_path: fixed_text(&info.config_path).to_string(),
            config_text: info.config_text().to_string(),
            config_cut: info.config_cut != 0,
        }
    }
}

/// The tunables of the current run: names and bounds from `info`, values from `frame`.
pub fn tunables(frame: &TelemetryFrame, info: Option<&TelemetryInfo>) -> Vec<TunableView> {
    let Some(info) = info else {
        return Vec::new();
    };
    info.tunables()
        .iter()
        .enumerate()
        .map(|(i, t)| TunableView {
            name: t.name().to_string(),
            min: t.min,
            max: t.max,
            initial: t.initial,
            value: frame.tunable_values.get(i).copied().and_then(finite),
        })
        .collect()
}

impl RunView {
    fn of(f: &TelemetryFrame, info: Option<&TelemetryInfo>) -> Self {
        let unix_ms =
            |t_ns: u64| (i128::from(t_ns) + i128::from(f.unix_minus_monotonic_ns)) as f64 / 1e6;
        let n_z = usize::from(f.n_z).min(ipc_types::MAX_Z);
        let n_tones = (f.tones.n_tones as usize).min(ipc_types::telemetry::MAX_TONES);
        let newest = f.points().last();
        Self {
            run_id: f.run_id,
            service_pid: f.service_pid,
            frame_seq: f.frame_seq,
            run_state: run_state_name(f.state),
            flags: FlagsView::of(f.flags),
            verdict: verdict_name(f.verdict),
            verdict_text: f.verdict_text().to_string(),
            last_seq: f.last_seq,
            last_sample_unix_ms: newest.map(|p| unix_ms(p.t_sample_ns)),
            publish_unix_ms: unix_ms(f.t_publish_ns),
            unix_minus_monotonic_ns: f.unix_minus_monotonic_ns,
            theta_norm: newest.and_then(|p| finite(p.theta_norm)),
            n_z: f.n_z,
            n_u: f.n_u,
            counters: counters::pairs(&f.counters).collect(),
            latency: latency_index::NAMES
                .iter()
                .zip(&f.latency)
                .map(|(&n, s)| (n, LatencyView::of(s)))
                .collect(),
            tones: TonesView {
                window_samples: f.tones.window_samples,
                tones: (0..n_tones)
                    .map(|i| ToneView {
                        hz: f.tones.hz[i],
                        amplitude: f.tones.amplitude[i][..n_z]
                            .iter()
                            .map(|&a| finite(a))
                            .collect(),
                        open_loop: f.tones.open_loop[i][..n_z]
                            .iter()
                            .map(|&a| finite(a))
                            .collect(),
                        suppression_db: (0..n_z)
                            .map(|j| {
                                suppression_db(f.tones.open_loop[i][j], f.tones.amplitude[i][j])
                            })
                            .collect(),
                    })
                    .collect(),
            },
            tunables: tunables(f, info),
        }
    }
}

impl RigView {
    /// The view of one rig's state as of `now`.
    pub fn of(s: &RigState, now: Instant) -> Self {
        let connection = s.connection(now);
        Self {
            rig: s.rig.clone(),
            connection: connection.name(),
            last_frame_age_s: s
                .latest_at
                .map(|t| now.saturating_duration_since(t).as_secs_f64()),
            reader_error: s.reader_error.clone(),
            placement: s.placement.clone(),
            reader_opens: s.reader_opens,
            frames_received: s.frames_received,
            frames_lost: s.frames_lost,
            runs_seen: s.runs_seen,
            run: s
                .latest
                .as_deref()
                .map(|f| RunView::of(f, s.current_info())),
            info: s.info.as_deref().map(|i| {
                let current = s.latest.as_deref().is_none_or(|f| f.run_id == i.run_id);
                InfoView::of(i, current)
            }),
            previous_runs: s.previous_runs.iter().cloned().collect(),
        }
    }
}

impl StateView {
    /// The view of every rig.
    pub fn of(hub: &Hub, monitor: MonitorView) -> Self {
        let now = Instant::now();
        Self {
            monitor,
            rigs: (0..hub.names().len())
                .map(|i| RigView::of(&hub.lock(i), now))
                .collect(),
        }
    }
}

/// `/api/points`: the points of one rig after a sample.
#[derive(Debug, Serialize)]
pub struct PointsView {
    /// The rig.
    pub rig: String,
    /// The current run (`null` before the first frame). A client that asked with a `since`
    /// of another run starts over.
    pub run_id: Option<u64>,
    /// `"waiting"`, `"live"` or `"stale"`.
    pub connection: &'static str,
    /// Channels of `z`.
    pub n_z: u16,
    /// Channels of `u`.
    pub n_u: u16,
    /// The newest sample's index.
    pub last_seq: u64,
    /// The monitor's clock, Unix ms.
    pub now_unix_ms: f64,
    /// The points, oldest first.
    pub points: Vec<PointView>,
}

/// One point.
#[derive(Debug, Serialize)]
pub struct PointView {
    /// Sample index.
    pub seq: u64,
    /// Sample time, monotonic ns.
    pub t_sample_ns: u64,
    /// Sample time, Unix ms.
    pub t_unix_ms: f64,
    /// ‖θ‖.
    pub theta_norm: Option<f64>,
    /// `z` (n_z values).
    pub z: Vec<f64>,
    /// `u` (n_u values).
    pub u: Vec<f64>,
    /// The actuation status of the input.
    pub status: u32,
    /// The measurement's flags.
    pub flags: u32,
}

impl PointView {
    /// The view of a point with `n_z` and `n_u` channels.
    pub fn of(p: &ScopePoint, n_z: usize, n_u: usize) -> Self {
        Self {
            seq: p.point.seq,
            t_sample_ns: p.point.t_sample_ns,
            t_unix_ms: p.t_unix_ns() as f64 / 1e6,
            theta_norm: finite(p.point.theta_norm),
            z: p.point.z[..n_z.min(ipc_types::MAX_Z)].to_vec(),
            u: p.point.u[..n_u.min(ipc_types::MAX_U)].to_vec(),
            status: p.point.status,
            flags: p.point.flags,
        }
    }
}

impl PointsView {
    /// The points of `s` after `since`, at most `max`.
    pub fn of(s: &RigState, since: Option<u64>, max: usize) -> Self {
        let (n_z, n_u, last_seq, run_id) = match s.latest.as_deref() {
            Some(f) => (f.n_z, f.n_u, f.last_seq, Some(f.run_id)),
            None => (0, 0, 0, None),
        };
        Self {
            rig: s.rig.clone(),
            run_id,
            connection: s.connection(Instant::now()).name(),
            n_z,
            n_u,
            last_seq,
            now_unix_ms: now_unix_ms(),
            points: s
                .points_since(since, max)
                .iter()
                .map(|p| PointView::of(p, usize::from(n_z), usize::from(n_u)))
                .collect(),
        }
    }
}

/// Whether a connection counts as up for `/metrics`.
pub fn is_up(c: Connection) -> bool {
    c == Connection::Live
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suppression_is_positive_when_the_tone_is_below_its_open_loop_level() {
        let s = suppression_db(1.0, 0.1).unwrap();
        assert!((s - 20.0).abs() < 1e-9);
        assert_eq!(suppression_db(f64::NAN, 0.1), None);
        assert_eq!(suppression_db(1.0, 0.0), None);
    }

    #[test]
    fn a_rig_view_serializes_nan_as_null_and_names_the_states() {
        let mut s = RigState::new("r");
        let mut f = TelemetryFrame::empty();
        f.run_id = 5;
        f.n_z = 1;
        f.n_points = 1;
        f.points[0].theta_norm = f64::NAN;
        f.tones.n_tones = 1;
        f.tones.hz[0] = 100.0;
        f.tones.amplitude[0][0] = 0.5;
        s.on_frame(&f, Instant::now());
        let v = serde_json::to_value(RigView::of(&s, Instant::now())).unwrap();
        assert_eq!(v["connection"], "live");
        assert_eq!(v["run"]["run_state"], "waiting");
        assert_eq!(v["run"]["theta_norm"], serde_json::Value::Null);
        assert_eq!(
            v["run"]["tones"]["tones"][0]["open_loop"][0],
            serde_json::Value::Null
        );
        assert_eq!(v["run"]["tones"]["tones"][0]["amplitude"][0], 0.5);
        assert_eq!(
            v["run"]["latency"]["response"]["buckets"]
                .as_array()
                .unwrap()
                .len(),
            14
        );
    }
}
