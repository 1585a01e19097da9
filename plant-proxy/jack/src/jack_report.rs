//! What the JACK plant side reports besides the contract's counters: the server, the
//! latency the server states for each connected port, and how its process callbacks went
//! (xruns, budget, time). `plant-report.json` holds the plant side's report with this one
//! under `jack`.

use hdrhistogram::Histogram;
use plant_side::PlantReport;
use serde::Serialize;

/// One of the plant side's ports and what it is connected to.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct PortReport {
    /// The contract's channel, `y0`, `z0`, `u0`, ….
    pub channel: String,
    /// Our port, `client:y0`.
    pub port: String,
    /// The port it is connected to (`jack.y[i]`, …).
    pub peer: String,
    /// `capture` (a measurement) or `playback` (an input).
    pub direction: String,
    /// The server's latency range of the path through this port, frames: the capture
    /// latency of a measurement, the playback latency of an input
    /// (`jack_port_get_latency_range`).
    pub latency_frames: [u32; 2],
}

/// Percentiles of the process callback's duration, µs.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct CallbackTimes {
    /// Callbacks timed.
    pub callbacks: u64,
    /// Median, µs.
    pub p50_us: f64,
    /// 99th percentile, µs.
    pub p99_us: f64,
    /// Largest, µs.
    pub max_us: f64,
}

impl CallbackTimes {
    /// The percentiles of a histogram of durations in ns.
    pub fn of(h: &Histogram<u64>) -> Self {
        if h.is_empty() {
            return Self::default();
        }
        Self {
            callbacks: h.len(),
            p50_us: h.value_at_quantile(0.5) as f64 * 1e-3,
            p99_us: h.value_at_quantile(0.99) as f64 * 1e-3,
            max_us: h.max() as f64 * 1e-3,
        }
    }
}

/// The JACK side of a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JackReport {
    /// The server's name.
    pub server: String,
    /// The plant side's client name.
    pub client: String,
    /// The server's sample rate, Hz.
    pub sample_rate: u32,
    /// Frames per period at the end of the run.
    pub period_frames: u32,
    /// `jack.budget`: the share of a period the callback may wait for answers.
    pub budget: f64,
    /// The run was in lockstep: the server freewheeled.
    pub freewheel: bool,
    /// How the process thread was scheduled.
    pub thread: Option<String>,
    /// Process callbacks, from activation to the end (those before the first sample and
    /// after the last included).
    pub callbacks: u64,
    /// Xruns the server notified (a client, or the whole graph, missed its period).
    pub xruns: u64,
    /// Frames the server's clock advanced past the callbacks (cycles it skipped; real
    /// time only).
    pub frames_skipped: u64,
    /// Samples lost to skipped frames: decided as misses, never published (the service
    /// sees a gap); the contract's samples are the card's frames.
    pub samples_lost: u64,
    /// Callbacks that took longer than their period (real time only: a freewheeling
    /// server has no period).
    pub callbacks_over_period: u64,
    /// Callbacks whose budget ran out with a sample unanswered (the rest of the block
    /// were misses).
    pub callbacks_budget_exhausted: u64,
    /// Input samples beyond the DAC's full scale (written clipped to ±1).
    pub u_clipped: u64,
    /// The duration of the callbacks that decided samples.
    pub callback_time: CallbackTimes,
    /// The connected ports.
    pub ports: Vec<PortReport>,
    /// The delay the server adds to the loop, frames: the largest capture latency of a
    /// measured output plus the largest playback latency of an input (0 with nothing
    /// connected); the room or the card adds its own.
    pub added_delay_frames: u32,
}

impl JackReport {
    /// [`JackReport::added_delay_frames`] of `ports`.
    pub fn added_delay(ports: &[PortReport]) -> u32 {
        let most = |dir: &str| {
            ports
                .iter()
                .filter(|p| p.direction == dir && !p.channel.starts_with('z'))
                .map(|p| p.latency_frames[1])
                .max()
                .unwrap_or(0)
        };
        most("capture") + most("playback")
    }

    /// One line for the end of a run.
    pub fn summary_line(&self) -> String {
        format!(
            "JACK server '{}' at {} Hz, {} frames per period{}: {} callbacks ({} with samples: p50 {:.1} µs, p99 {:.1} µs, max {:.1} µs), {} xruns, {} frames skipped ({} samples lost), {} over their period, {} out of budget, {} input samples clipped, delay added by the server {} frames",
            self.server,
            self.sample_rate,
            self.period_frames,
            if self.freewheel {
                " (freewheeling)"
            } else {
                ""
            },
            self.callbacks,
            self.callback_time.callbacks,
            self.callback_time.p50_us,
            self.callback_time.p99_us,
            self.callback_time.max_us,
            self.xruns,
            self.frames_skipped,
            self.samples_lost,
            self.callbacks_over_period,
            self.callbacks_budget_exhausted,
            self.u_clipped,
            self.added_delay_frames
        )
    }
}

/// `plant-report.json` of a JACK run: the plant side's report, and the JACK part under
/// `jack`.
#[derive(Debug, Clone, Serialize)]
pub struct JackPlantReport<'a> {
    /// The contract's counters (the fields of plant-proxy's report).
    #[serde(flatten)]
    pub plant: &'a PlantReport,
    /// The JACK part.
    pub jack: &'a JackReport,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn port(port: &str, direction: &str, max: u32) -> PortReport {
        PortReport {
            channel: port.split(':').nth(1).unwrap().into(),
            port: port.into(),
            peer: "x:y".into(),
            direction: direction.into(),
            latency_frames: [max, max],
        }
    }

    #[test]
    fn the_added_delay_is_the_worst_measured_path_in_plus_the_worst_input_out() {
        let ports = [
            port("daq:y0", "capture", 32),
            port("daq:z0", "capture", 90),
            port("daq:u0", "playback", 64),
            port("daq:u1", "playback", 70),
        ];
        assert_eq!(JackReport::added_delay(&ports), 32 + 70);
        assert_eq!(JackReport::added_delay(&[]), 0);
    }

    #[test]
    fn callback_times_are_in_microseconds() {
        let mut h = Histogram::<u64>::new_with_bounds(1, 10_000_000_000, 3).unwrap();
        for v in [1_000, 2_000, 3_000] {
            h.record(v).unwrap();
        }
        let t = CallbackTimes::of(&h);
        assert_eq!(t.callbacks, 3);
        assert!(
            (t.p50_us - 2.0).abs() < 0.01 && (t.max_us - 3.0).abs() < 0.01,
            "{t:?}"
        );
        assert_eq!(
            CallbackTimes::of(&Histogram::new(3).unwrap()),
            CallbackTimes::default()
        );
    }
}
