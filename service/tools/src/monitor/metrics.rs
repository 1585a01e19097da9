//! `/metrics`: the rigs' state in the Prometheus text format (0.0.4), encoded by the
//! `prometheus-client` crate from a [`Collector`] that reads the [`Hub`] at each scrape.
//!
//! Nothing is recorded per sample: every value is taken from the newest frame as it
//! stands. The run report's counters are counters (`adaptive_rig_<name>_total`); the four
//! latency snapshots are histograms rebuilt from their cumulative buckets, sum and count
//! (seconds); their percentiles and the loop's state are gauges. Every series has a `rig`
//! label. A rig without a frame yet has only `adaptive_rig_up 0`. After a new run the
//! counters start again from zero, which Prometheus reads as a counter reset;
//! `adaptive_rig_run_start_timestamp_seconds` tells the runs apart. docs/monitor.md lists
//! every name.

use super::counters::{COUNTERS, MAXIMA};
use super::snapshot::{finite, suppression_db};
use super::state::{Connection, Hub};
use ipc_types::Timing;
use ipc_types::telemetry::{
    LATENCY_BUCKET_BOUNDS_NS, LatencySnapshot, MAX_TONES, TelemetryFrame, TelemetryInfo,
    fixed_text, live_flags, verdict_state,
};
use prometheus_client::collector::Collector;
use prometheus_client::encoding::{DescriptorEncoder, NoLabelSet};
use prometheus_client::metrics::MetricType;
use prometheus_client::registry::Registry;
use std::fmt;
use std::sync::Arc;
use std::time::Instant;

/// The `Content-Type` of `/metrics`.
pub const CONTENT_TYPE: &str = prometheus_client::encoding::prometheus_text::CONTENT_TYPE;

/// The histograms' metric names, in the order of
/// [`latency_index`](ipc_types::telemetry::latency_index), with their help.
pub const LATENCY_METRICS: [(&str, &str); 4] = [
    (
        "adaptive_rig_wakeup_latency_seconds",
        "Sample time to the real-time thread's wake-up.",
    ),
    (
        "adaptive_rig_compute_duration_seconds",
        "Duration of the controller's step.",
    ),
    (
        "adaptive_rig_response_latency_seconds",
        "Sample time to the publication of the answer.",
    ),
    (
        "adaptive_rig_period_jitter_seconds",
        "Period jitter of the receipt times.",
    ),
];

/// A field of a latency snapshot.
type SnapshotField = fn(&LatencySnapshot) -> u64;

/// The percentiles exported as gauges: label value and field.
const PERCENTILES: [(&str, SnapshotField); 4] = [
    ("50", |s| s.p50_ns),
    ("90", |s| s.p90_ns),
    ("99", |s| s.p99_ns),
    ("99.9", |s| s.p999_ns),
];

/// Labels of one series.
type Labels = Vec<(&'static str, String)>;

/// What a scrape reads of one rig, copied out under its lock.
struct RigScrape {
    rig: String,
    up: bool,
    age_s: Option<f64>,
    frames_received: u64,
    frames_lost: u64,
    frame: Option<Box<TelemetryFrame>>,
    info: Option<Box<TelemetryInfo>>,
}

impl RigScrape {
    fn labels(&self) -> Labels {
        vec![("rig", self.rig.clone())]
    }
}

/// The collector of every rig's metrics.
#[derive(Debug)]
pub struct RigCollector {
    hub: Arc<Hub>,
}

impl RigCollector {
    /// A collector of `hub`'s rigs.
    pub fn new(hub: Arc<Hub>) -> Self {
        Self { hub }
    }

    fn scrape(&self) -> Vec<RigScrape> {
        let now = Instant::now();
        (0..self.hub.names().len())
            .map(|i| {
                let s = self.hub.lock(i);
                RigScrape {
                    rig: s.rig.clone(),
                    up: s.connection(now) == Connection::Live,
                    age_s: s
                        .latest_at
                        .map(|t| now.saturating_duration_since(t).as_secs_f64()),
                    frames_received: s.frames_received,
                    frames_lost: s.frames_lost,
                    frame: s.latest.clone(),
                    info: s.current_info().map(|i| Box::new(*i)),
                }
            })
            .collect()
    }
}

/// Writes one gauge family (help and type even when it has no series).
fn gauges(
    enc: &mut DescriptorEncoder,
    name: &str,
    help: &str,
    series: impl IntoIterator<Item = (Labels, f64)>,
) -> fmt::Result {
    let mut m = enc.encode_descriptor(name, help, None, MetricType::Gauge)?;
    for (labels, v) in series {
        m.encode_family(&labels)?.encode_gauge(&v)?;
    }
    Ok(())
}

/// Writes one counter family; `name` is without `_total`, which the encoder appends.
fn counters(
    enc: &mut DescriptorEncoder,
    name: &str,
    help: &str,
    series: impl IntoIterator<Item = (Labels, u64)>,
) -> fmt::Result {
    let mut m = enc.encode_descriptor(name, help, None, MetricType::Counter)?;
    for (labels, v) in series {
        m.encode_family(&labels)?
            .encode_counter::<NoLabelSet, u64, u64>(&v, None)?;
    }
    Ok(())
}

/// The buckets of a snapshot as the encoder takes them: `(upper bound in s, count in that
/// bucket alone)`; the cumulative counts of the snapshot are taken apart again. A
/// snapshot whose counts fall from one bucket to the next (never expected) is read as if
/// they stayed level, so that the histogram stays well-formed.
pub fn histogram_buckets(s: &LatencySnapshot) -> Vec<(f64, u64)> {
    let mut below = 0u64;
    LATENCY_BUCKET_BOUNDS_NS
        .iter()
        .zip(s.buckets)
        .map(|(&le, cum)| {
            let n = cum.saturating_sub(below);
            below = below.max(cum);
            (le as f64 / 1e9, n)
        })
        .collect()
}

/// The count of the `+Inf` bucket: the snapshot's count, never below its last bucket.
pub fn histogram_count(s: &LatencySnapshot) -> u64 {
    s.buckets.iter().copied().max().unwrap_or(0).max(s.count)
}

fn flag_gauge(
    enc: &mut DescriptorEncoder,
    rigs: &[RigScrape],
    name: &str,
    help: &str,
    bit: u32,
) -> fmt::Result {
    gauges(
        enc,
        name,
        help,
        rigs.iter().filter_map(|r| {
            let f = r.frame.as_deref()?;
            Some((r.labels(), if f.flags & bit != 0 { 1.0 } else { 0.0 }))
        }),
    )
}

impl Collector for RigCollector {
    fn encode(&self, mut enc: DescriptorEncoder) -> fmt::Result {
        let rigs = self.scrape();
        let e = &mut enc;
        let with_frame = || {
            rigs.iter()
                .filter_map(|r| r.frame.as_deref().map(|f| (r, f)))
        };

        gauges(
            e,
            "adaptive_rig_up",
            "1 while the rig's service publishes telemetry (a frame within the last second), else 0.",
            rigs.iter()
                .map(|r| (r.labels(), if r.up { 1.0 } else { 0.0 })),
        )?;
        gauges(
            e,
            "adaptive_rig_last_frame_age_seconds",
            "Age of the newest telemetry frame the monitor received.",
            rigs.iter().filter_map(|r| Some((r.labels(), r.age_s?))),
        )?;
        counters(
            e,
            "adaptive_rig_monitor_frames_received",
            "Telemetry frames the monitor received.",
            rigs.iter().map(|r| (r.labels(), r.frames_received)),
        )?;
        counters(
            e,
            "adaptive_rig_monitor_frames_lost",
            "Telemetry frames the monitor missed (it fell behind).",
            rigs.iter().map(|r| (r.labels(), r.frames_lost)),
        )?;

        // The run.
        gauges(
            e,
            "adaptive_rig_run_start_timestamp_seconds",
            "Start of the current run (its run_id), Unix time.",
            with_frame().map(|(r, f)| (r.labels(), f.run_id as f64 / 1e9)),
        )?;
        gauges(
            e,
            "adaptive_rig_run_state",
            "The run's state: 0 waiting for the plant, 1 running, 2 ended.",
            with_frame().map(|(r, f)| (r.labels(), f64::from(f.state))),
        )?;
        {
            let mut m = e.encode_descriptor(
                "adaptive_rig_run",
                "The current run's controller and timing (value 1).",
                None,
                MetricType::Info,
            )?;
            for r in &rigs {
                let Some(info) = r.info.as_deref() else {
                    continue;
                };
                let timing = Timing::from_wire(info.timing)
                    .map(|t| t.name().to_string())
                    .unwrap_or_else(|| info.timing.to_string());
                let labels = r.labels();
                m.encode_family(&labels)?.encode_info(&vec![
                    ("controller", fixed_text(&info.controller).to_string()),
                    ("timing", timing),
                ])?;
            }
        }
        gauges(
            e,
            "adaptive_rig_sample_period_seconds",
            "The loop's sample period.",
            rigs.iter().filter_map(|r| {
                Some((r.labels(), r.info.as_deref()?.sample_period_ns as f64 / 1e9))
            }),
        )?;
        gauges(
            e,
            "adaptive_rig_response_budget_seconds",
            "The response-time budget of the latency figures.",
            rigs.iter()
                .filter_map(|r| Some((r.labels(), r.info.as_deref()?.budget_ns as f64 / 1e9))),
        )?;
        gauges(
            e,
            "adaptive_rig_verdict_ok",
            "The verdict as it stands: 1 no failure so far, 0 at least one (absent while pending).",
            with_frame().filter_map(|(r, f)| match f.verdict {
                verdict_state::OK => Some((r.labels(), 1.0)),
                verdict_state::FAILED => Some((r.labels(), 0.0)),
                _ => None,
            }),
        )?;
        gauges(
            e,
            "adaptive_rig_verdict_state",
            "The verdict's state: 0 pending, 1 ok, 2 failed.",
            with_frame().map(|(r, f)| (r.labels(), f64::from(f.verdict))),
        )?;
        for (name, help, bit) in [
            (
                "adaptive_rig_safe_state",
                "1 while the loop applies its safe input.",
                live_flags::SAFE_STATE,
            ),
            (
                "adaptive_rig_operator_safe_state",
                "1 while the operator holds the loop in its safe state.",
                live_flags::OPERATOR_SAFE_STATE,
            ),
            (
                "adaptive_rig_adaptation_frozen",
                "1 while the operator holds the controller's adaptation frozen.",
                live_flags::ADAPTATION_FROZEN,
            ),
            (
                "adaptive_rig_open_loop",
                "1 during the session's open-loop phase.",
                live_flags::OPEN_LOOP,
            ),
            (
                "adaptive_rig_plant_silent",
                "1 while the plant is silent.",
                live_flags::PLANT_SILENT,
            ),
            (
                "adaptive_rig_commands_enabled",
                "1 when the service accepts operator commands.",
                live_flags::COMMANDS_ENABLED,
            ),
        ] {
            flag_gauge(e, &rigs, name, help, bit)?;
        }
        gauges(
            e,
            "adaptive_rig_last_sample_seq",
            "Index of the newest sample.",
            with_frame().map(|(r, f)| (r.labels(), f.last_seq as f64)),
        )?;
        gauges(
            e,
            "adaptive_rig_last_sample_timestamp_seconds",
            "Sample time of the newest decimated point, Unix time.",
            with_frame().filter_map(|(r, f)| {
                let p = f.points().last()?;
                let t = i128::from(p.t_sample_ns) + i128::from(f.unix_minus_monotonic_ns);
                Some((r.labels(), t as f64 / 1e9))
            }),
        )?;
        gauges(
            e,
            "adaptive_rig_theta_norm",
            "2-norm of the controller's parameter estimate at the newest point (absent for a controller without one).",
            with_frame()
                .filter_map(|(r, f)| Some((r.labels(), finite(f.points().last()?.theta_norm)?))),
        )?;
        gauges(
            e,
            "adaptive_rig_tunable_value",
            "Value of each declared tunable now.",
            rigs.iter().flat_map(|r| {
                let mut out = Vec::new();
                if let (Some(f), Some(info)) = (r.frame.as_deref(), r.info.as_deref()) {
                    for (i, t) in info.tunables().iter().enumerate() {
                        if let Some(v) = f.tunable_values.get(i).copied().and_then(finite) {
                            let mut l = r.labels();
                            l.push(("tunable", t.name().to_string()));
                            out.push((l, v));
                        }
                    }
                }
                out
            }),
        )?;

        // Tones: per tone (`hz`) and channel of z.
        let tone_series = |value: fn(f64, f64) -> Option<f64>| {
            let mut out = Vec::new();
            for (r, f) in with_frame() {
                let n_z = usize::from(f.n_z).min(ipc_types::MAX_Z);
                for i in 0..(f.tones.n_tones as usize).min(MAX_TONES) {
                    for j in 0..n_z {
                        let (now, open) = (f.tones.amplitude[i][j], f.tones.open_loop[i][j]);
                        if let Some(v) = value(now, open) {
                            let mut l = r.labels();
                            l.push(("hz", format!("{}", f.tones.hz[i])));
                            l.push(("channel", j.to_string()));
                            out.push((l, v));
                        }
                    }
                }
            }
            out
        };
        gauges(
            e,
            "adaptive_rig_tone_amplitude",
            "Amplitude of each tone in each channel of z over the newest window.",
            tone_series(|now, _| finite(now)),
        )?;
        gauges(
            e,
            "adaptive_rig_tone_open_loop_amplitude",
            "Amplitude of each tone in each channel of z in the open-loop phase.",
            tone_series(|_, open| finite(open)),
        )?;
        gauges(
            e,
            "adaptive_rig_tone_suppression_db",
            "Suppression of each tone in each channel of z: 20 log10(open-loop amplitude / amplitude now), dB.",
            tone_series(|now, open| suppression_db(open, now)),
        )?;

        // The run report's counters.
        for c in COUNTERS {
            let name = format!("adaptive_rig_{}", c.name);
            let series = with_frame().map(|(r, f)| (r.labels(), (c.get)(&f.counters)));
            if MAXIMA.contains(&c.name) {
                gauges(e, &name, c.help, series.map(|(l, v)| (l, v as f64)))?;
            } else {
                counters(e, &name, c.help, series)?;
            }
        }

        // Latencies: histograms, then percentile and maximum gauges.
        for (k, (name, help)) in LATENCY_METRICS.iter().enumerate() {
            let mut m = e.encode_descriptor(name, help, None, MetricType::Histogram)?;
            for (r, f) in with_frame() {
                let s = &f.latency[k];
                let labels = r.labels();
                m.encode_family(&labels)?.encode_histogram::<NoLabelSet>(
                    s.sum_ns / 1e9,
                    histogram_count(s),
                    &histogram_buckets(s),
                    None,
                )?;
            }
        }
        let per_histogram = |value: &dyn Fn(&LatencySnapshot) -> Vec<(&'static str, u64)>| {
            let mut out = Vec::new();
            for (r, f) in with_frame() {
                for (k, hist) in ipc_types::telemetry::latency_index::NAMES
                    .iter()
                    .enumerate()
                {
                    for (p, ns) in value(&f.latency[k]) {
                        let mut l = r.labels();
                        l.push(("histogram", (*hist).to_string()));
                        if !p.is_empty() {
                            l.push(("percentile", p.to_string()));
                        }
                        out.push((l, ns as f64 / 1e9));
                    }
                }
            }
            out
        };
        gauges(
            e,
            "adaptive_rig_latency_percentile_seconds",
            "Percentiles of the latency histograms (histogram: wakeup, compute, response, jitter).",
            per_histogram(&|s| PERCENTILES.iter().map(|(p, get)| (*p, get(s))).collect()),
        )?;
        gauges(
            e,
            "adaptive_rig_latency_max_seconds",
            "Largest value of each latency histogram.",
            per_histogram(&|s| vec![("", s.max_ns)]),
        )?;
        Ok(())
    }
}

/// A registry holding the collector of `hub`'s rigs.
pub fn registry(hub: Arc<Hub>) -> Registry {
    let mut r = Registry::default();
    r.register_collector(Box::new(RigCollector::new(hub)));
    r
}

/// The text of `/metrics`.
///
/// # Errors
///
/// Formatting failed (never expected when writing into a string).
pub fn render(registry: &Registry) -> Result<String, fmt::Error> {
    let mut out = String::new();
    prometheus_client::encoding::prometheus_text::encode(&mut out, registry)?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cumulative_buckets_are_taken_apart_and_kept_well_formed() {
        let mut s = LatencySnapshot {
            count: 10,
            ..Default::default()
        };
        s.buckets = [0, 1, 3, 3, 2, 5, 9, 9, 9, 9, 9, 9, 9, 9];
        let b = histogram_buckets(&s);
        let per: Vec<u64> = b.iter().map(|(_, n)| *n).collect();
        assert_eq!(per, [0, 1, 2, 0, 0, 2, 4, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(b[7].0, 125e-6);
        assert_eq!(histogram_count(&s), 10);
        s.count = 4;
        assert_eq!(histogram_count(&s), 9);
    }
}
