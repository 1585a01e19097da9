//! What a plant run did: its counters, written as `plant-report.json` and summarized in the
//! `done:` line.
//!
//! The misses add up: `misses = plan_entries_applied + misses_held_or_safe` (every miss
//! reached the plant either as a plan entry or as a held or safe output).

use serde::Serialize;

/// Counters and results of a plant run.
#[derive(Debug, Clone, Default, Serialize)]
pub struct PlantReport {
    /// Rig name.
    pub rig: String,
    /// Mode used (`RealTime` or `Lockstep`).
    pub mode: String,
    /// When the plant applied each input, as stated at connect: `"at-sample"` (real time,
    /// deadline 0), `"at-deadline"` (real time, deadline > 0) or `"lockstep"`.
    pub applies: String,
    /// The service's timing (`"compute-first"`, `"answer-first"`, `"send-ahead"`, or
    /// `"unknown (n)"` for a wire value this build does not know) stated by the last
    /// actuation the plant applied; `None` when it applied none.
    pub timing: Option<String>,
    /// Samples published.
    pub samples: u64,
    /// Valid actuations applied (each the answer for its own sample, received by its
    /// application instant).
    pub actuations_applied: u64,
    /// Samples without a valid actuation for them by their application instant (the
    /// deadline in real time; the service's answer, or `proxy.lockstep-timeout`, in lockstep).
    pub misses: u64,
    /// Misses covered by a plan (`proxy.late-policy = "plan"`): the plant applied the entry
    /// of the newest plan for the sample and flagged `PLAN_APPLIED` in the next sample.
    pub plan_entries_applied: u64,
    /// Misses that reached the plant as a held or a safe output (the late policy, the plan's
    /// fallback, or the watchdog's safe output): the misses no plan covered.
    pub misses_held_or_safe: u64,
    /// Of those, the ones before the first valid actuation of the run: the service had not
    /// answered yet, so there was nothing to hold but the initial (safe) input and no plan.
    pub misses_before_first_answer: u64,
    /// Actuations that arrived after their sample's input was decided (an answer to an older
    /// sample).
    pub late_discarded: u64,
    /// Actuations refused (other contract, counts, `plan_len` past the capacity, or a
    /// non-finite `u` or plan entry).
    pub invalid_discarded: u64,
    /// Actuations received ahead that the plant dropped because it already held the most it
    /// keeps for later samples (the earliest received are dropped).
    pub ahead_dropped: u64,
    /// Actuations refused because they did not come from the pinned service (a foreign
    /// publisher, or a replaced service's leftovers).
    pub foreign_discarded: u64,
    /// Times a new service replaced the one the plant was connected to.
    pub new_services: u64,
    /// The pid of the service the plant is pinned to at the end of the run, when known.
    pub service_pid: Option<u32>,
    /// Watchdog trips.
    pub watchdog_trips: u64,
    /// Recoveries from the safe output.
    pub watchdog_recoveries: u64,
    /// Samples spent in the safe output.
    pub safe_output_samples: u64,
    /// Measurement faults configured (`nan-at`, `inf-at`, `neg-inf-at`, `out-of-range-at`).
    pub faults_injected: u64,
    /// Samples published with `INJECTED_STALL` (`proxy.faults.stalls`, lockstep; a stall of
    /// `periods` samples counts `periods`).
    pub stalls_injected: u64,
    /// Stall acknowledgements (`STALL_ACK`) received from the service.
    pub stall_acks: u64,
    /// Times the real-time plant woke more than a period late and re-based its clock
    /// (`proxy.overrun = "slip"`).
    pub clock_slips: u64,
    /// The total time the clock was re-based by, s.
    pub slipped_s: f64,
    /// Real-time set-up outcome.
    pub rt_setup: String,
    /// RMS of each performance channel (noise included).
    pub z_rms: Vec<f64>,
    /// Wall time of the run, s.
    pub wall_time_s: f64,
    /// The round trip of the samples whose answer the plant waited for (lockstep, or
    /// [`Wait::Until`](crate::Wait::Until), [`Wait::Spin`](crate::Wait::Spin)): from publishing
    /// `M_k` to holding the service's answer to it; `None` when no sample was timed.
    pub round_trip: Option<RoundTrip>,
    /// Allocations on the thread of [`run`](crate::run)'s loop
    /// ([`ipc_types::rt_alloc`]): none from the system allocator, and one pool block per
    /// published sample (iceoryx2's loan state) when the process installs
    /// `RtAwareAllocator`; zeros and `installed = false` otherwise.
    pub rt_allocations: ipc_types::rt_alloc::RtAllocStats,
    /// Set when the lockstep plant gave up
    /// ([`PlantError::GaveUp`](crate::PlantError::GaveUp)): why. `None` for a run
    /// that ended at its last sample or on a signal.
    pub gave_up: Option<String>,
}

/// Percentiles of the round trip from a measurement to the service's answer, µs.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct RoundTrip {
    /// Samples timed.
    pub samples: u64,
    /// Median, µs.
    pub p50_us: f64,
    /// 99th percentile, µs.
    pub p99_us: f64,
    /// Largest, µs.
    pub max_us: f64,
}

impl PlantReport {
    /// The counters of a run, one line (printed after `done: ` or `gave up: `).
    pub fn summary_line(&self) -> String {
        format!(
            "{} samples, {} actuations applied, {} misses ({} late, {} invalid; {} plan entries applied, {} held or safe, {} of them before the first answer), watchdog trips {}, recoveries {}, timing {}, applies {}, stalls injected {}, clock slips {} ({:.6} s), z RMS {:?}",
            self.samples,
            self.actuations_applied,
            self.misses,
            self.late_discarded,
            self.invalid_discarded,
            self.plan_entries_applied,
            self.misses_held_or_safe,
            self.misses_before_first_answer,
            self.watchdog_trips,
            self.watchdog_recoveries,
            self.timing.as_deref().unwrap_or("none"),
            self.applies,
            self.stalls_injected,
            self.clock_slips,
            self.slipped_s,
            self.z_rms
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_done_line_names_every_new_counter() {
        let r = PlantReport {
            samples: 10,
            actuations_applied: 7,
            misses: 3,
            plan_entries_applied: 2,
            misses_held_or_safe: 1,
            misses_before_first_answer: 1,
            timing: Some("send-ahead".into()),
            applies: "lockstep".into(),
            stalls_injected: 4,
            clock_slips: 1,
            slipped_s: 0.25,
            ..PlantReport::default()
        };
        let line = r.summary_line();
        for part in [
            "10 samples, 7 actuations applied, 3 misses",
            "2 plan entries applied, 1 held or safe, 1 of them before the first answer",
            "timing send-ahead",
            "applies lockstep",
            "stalls injected 4",
            "clock slips 1 (0.250000 s)",
        ] {
            assert!(line.contains(part), "{part}: {line}");
        }
        let json = serde_json::to_value(&r).unwrap();
        for key in [
            "timing",
            "plan_entries_applied",
            "misses_held_or_safe",
            "misses_before_first_answer",
            "clock_slips",
            "slipped_s",
            "stalls_injected",
        ] {
            assert!(json.get(key).is_some(), "{key}");
        }
        assert_eq!(
            serde_json::to_value(PlantReport::default()).unwrap()["timing"],
            serde_json::Value::Null
        );
    }
}
