//! The verdict of a run: whether it did what it was started for, and what a reader of its
//! report must be warned about.
//!
//! A run **failed** when any of these holds (each gives one line of
//! [`RunVerdict::failures`]):
//!
//! 1. it ended in the safe state: the last window of the run is open loop, and the line
//!    says since when, what recovery needs and the longest clean stretch seen since;
//! 2. the share of closed-loop cycles spent in the safe state,
//!    `s = n_safe / (n_steps + n_safe)`, exceeds `service.max-safe-state-share`;
//! 3. samples past the open-loop phase were answered but the controller never ran;
//! 4. the plant reported applying inputs the service did not send (a foreign actuation);
//! 5. the share of the samples past start-up (the grace period and the open-loop phase)
//!    that never reached the service, `lost / (received + lost)` over those samples,
//!    exceeds `service.max-lost-share`;
//! 6. the share of the inputs past start-up that the plant held or replaced by its safe
//!    output (a late answer that no plan entry covered) exceeds `service.max-held-share`;
//! 7. the controller ran, but none of its inputs left the safe input (`service.safe-input`):
//!    it controlled nothing;
//! 8. an adaptive controller's update was suspended (a gap in its data, a bad sample) on
//!    more than `service.max-suspended-share` of its closed-loop steps;
//! 9. a tone of the report was suppressed by less than `service.report.min-suppression-db`
//!    (the scenario's acceptance criterion), or could not be measured;
//! 10. the service busy-polled at `SCHED_FIFO` while the kernel's RT throttling was on: the
//!     kernel stalled it every second, so its figures are not those of a real-time loop.
//!
//! Everything else that makes the figures less than they look — lost, refused or rejected
//! samples, new plant sessions, impossible sample times, misses during start-up, dropped
//! log records, controller faults and fallbacks, and steal time on the RT core of at least
//! [`STEAL_WARNING_SHARE`] of the loop (the hypervisor did not run the RT thread's CPU,
//! which no priority on the box prevents) — is a [`RunVerdict::warnings`] line. The
//! verdict is a pure function of the counters; the service's exit status follows
//! [`RunVerdict::ok`].

use super::LoopStats;
use serde::Serialize;

/// Steal time on the RT core, as a share of the loop, from which the verdict warns.
pub const STEAL_WARNING_SHARE: f64 = 0.01;

/// Where the safe state stood when the run ended, if it was in it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SafeStateAtEnd {
    /// Plant time of the last entry, s (its sequence number times the period).
    pub since_s: f64,
    /// Answers of the recovery window (`service.recover-after`); `None`: kept for the
    /// session.
    pub recover_after: Option<u64>,
    /// Misses the window may hold (`service.recover-tolerance`).
    pub tolerance: u64,
    /// The longest run of on-time answers since the last entry.
    pub longest_clean_run: u64,
}

/// The acceptance limits of a run (`[service]` and `[service.report]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// `service.max-safe-state-share`.
    pub max_safe_state_share: f64,
    /// `service.max-lost-share`.
    pub max_lost_share: f64,
    /// `service.max-held-share`.
    pub max_held_share: f64,
    /// `service.max-suspended-share`.
    pub max_suspended_share: f64,
    /// `service.report.min-suppression-db`, when the scenario states one.
    pub min_suppression_db: Option<f64>,
}

impl Limits {
    /// The limits `cfg` sets.
    pub fn of(cfg: &crate::config::ServiceConfig) -> Self {
        Self {
            max_safe_state_share: cfg.policy.max_safe_state_share,
            max_lost_share: cfg.policy.max_lost_share,
            max_held_share: cfg.policy.max_held_share,
            max_suspended_share: cfg.policy.max_suspended_share,
            min_suppression_db: cfg.tone_report.min_suppression_db,
        }
    }
}

impl Default for Limits {
    /// The configuration's defaults.
    fn default() -> Self {
        Self {
            max_safe_state_share: 0.1,
            max_lost_share: 0.01,
            max_held_share: 0.01,
            max_suspended_share: 0.5,
            min_suppression_db: None,
        }
    }
}

/// How often an adaptive controller's update ran in closed loop and why it did not
/// ([`control::Controller::adaptation`]).
pub use control::controller::Adaptation;

/// What the verdict is computed from.
#[derive(Debug, Clone)]
pub struct VerdictInputs {
    /// The loop's counters.
    pub stats: LoopStats,
    /// `Some` when the run ended in the safe state.
    pub safe_state_at_end: Option<SafeStateAtEnd>,
    /// The acceptance limits.
    pub limits: Limits,
    /// Cycles of the open-loop phase of a session.
    pub open_loop_cycles: u64,
    /// Signal-log records dropped.
    pub log_dropped: u64,
    /// The controller's adaptation counts, for an adaptive controller.
    pub adaptation: Option<Adaptation>,
    /// Per tone of the report: its frequency (Hz) and suppression (dB; `None`: not
    /// measured).
    pub suppression_db: Vec<(f64, Option<f64>)>,
    /// The throttling warning, when the loop busy-polled at `SCHED_FIFO` with throttling
    /// on.
    pub throttled_busy_poll: Option<String>,
    /// Steal time on the RT core over the loop and the loop's length, s, when both are
    /// known.
    pub rt_core_steal: Option<(f64, f64)>,
}

/// The verdict: failures make the run failed; warnings qualify its figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunVerdict {
    /// True when there is no failure.
    pub ok: bool,
    /// One line per failure, as listed in the module docs.
    pub failures: Vec<String>,
    /// One line per warning.
    pub warnings: Vec<String>,
}

impl RunVerdict {
    /// The first line of the report's verdict: `OK`, or `FAILED: ` and the failures.
    pub fn headline(&self) -> String {
        if self.ok {
            "verdict: OK".into()
        } else {
            format!("verdict: FAILED: {}", self.failures.join("; "))
        }
    }
}

/// The share of closed-loop cycles spent in the safe state (0 without any).
pub fn safe_state_share(stats: &LoopStats) -> f64 {
    let closed = stats.controller_steps + stats.safe_state_cycles;
    if closed == 0 {
        0.0
    } else {
        stats.safe_state_cycles as f64 / closed as f64
    }
}

/// The share of the samples past start-up that were lost (0 without any).
pub fn lost_share(stats: &LoopStats) -> f64 {
    ratio(stats.lost_past_startup, stats.samples_past_startup)
}

/// The share of the inputs past start-up that the plant held or replaced by its safe
/// output (0 without any).
pub fn held_share(stats: &LoopStats) -> f64 {
    ratio(stats.held_past_startup, stats.samples_past_startup)
}

fn ratio(n: u64, d: u64) -> f64 {
    if d == 0 { 0.0 } else { n as f64 / d as f64 }
}

/// The verdict of the module docs.
pub fn judge(v: &VerdictInputs) -> RunVerdict {
    let s = &v.stats;
    let mut failures = Vec::new();
    let mut warnings = Vec::new();
    if let Some(end) = v.safe_state_at_end {
        let recovery = match end.recover_after {
            Some(m) if end.tolerance == 0 => format!("recovery needs {m} clean cycles in a row"),
            Some(m) => format!(
                "recovery needs at most {} misses in {m} cycles",
                end.tolerance
            ),
            None => "the safe state is kept for the session (no service.recover-after)".into(),
        };
        failures.push(format!(
            "ENDED IN SAFE STATE since {:.2} s: the last window is open loop; {recovery}, the \
             longest run of clean cycles since the entry was {}",
            end.since_s, end.longest_clean_run
        ));
    }
    let share = safe_state_share(s);
    let limits = &v.limits;
    if share > limits.max_safe_state_share {
        failures.push(format!(
            "{:.1} % of the closed-loop cycles in the safe state ({} of {}), more than \
             service.max-safe-state-share = {:.1} %",
            100.0 * share,
            s.safe_state_cycles,
            s.controller_steps + s.safe_state_cycles,
            100.0 * limits.max_safe_state_share
        ));
    }
    let lost = lost_share(s);
    if lost > limits.max_lost_share {
        failures.push(format!(
            "SAMPLES LOST: {:.2} % of the samples past start-up never reached the service ({} \
             of {}), more than service.max-lost-share = {:.2} %",
            100.0 * lost,
            s.lost_past_startup,
            s.samples_past_startup,
            100.0 * limits.max_lost_share
        ));
    }
    let held = held_share(s);
    if held > limits.max_held_share {
        failures.push(format!(
            "INPUTS HELD: the plant held or safe-outputted {:.2} % of the inputs past start-up \
             ({} of {}; late answers no plan covered), more than service.max-held-share = \
             {:.2} %",
            100.0 * held,
            s.held_past_startup,
            s.samples_past_startup,
            100.0 * limits.max_held_share
        ));
    }
    if s.controller_steps > 0 && s.inputs_off_safe == 0 {
        failures.push(format!(
            "NO CONTROL: the controller ran {} steps but its input never left the safe input",
            s.controller_steps
        ));
    }
    if let Some(a) = &v.adaptation {
        let closed = a.updated + a.suspended();
        let suspended = ratio(a.suspended(), closed);
        if closed > 0 && suspended > limits.max_suspended_share {
            let causes: Vec<String> = a
                .suspended
                .iter()
                .filter(|(_, n)| *n > 0)
                .map(|(cause, n)| format!("{n} for {cause}"))
                .collect();
            failures.push(format!(
                "ADAPTATION SUSPENDED on {:.1} % of the closed-loop steps ({} of {}: {}), more \
                 than service.max-suspended-share = {:.1} %",
                100.0 * suspended,
                a.suspended(),
                closed,
                causes.join(", "),
                100.0 * limits.max_suspended_share
            ));
        }
    }
    if let Some(min) = limits.min_suppression_db {
        let short: Vec<String> = v
            .suppression_db
            .iter()
            .filter(|(_, db)| db.is_none_or(|d| d.is_nan() || d < min))
            .map(|(hz, db)| match db {
                Some(d) => format!("{hz} Hz {d:.1} dB"),
                None => format!("{hz} Hz not measured"),
            })
            .collect();
        if v.suppression_db.is_empty() {
            failures.push(format!(
                "SUPPRESSION NOT MEASURED: service.report.min-suppression-db = {min} dB, but the \
                 run measured no tone"
            ));
        } else if !short.is_empty() {
            failures.push(format!(
                "SUPPRESSION BELOW {min} dB (service.report.min-suppression-db): {}",
                short.join(", ")
            ));
        }
    }
    if let Some(w) = &v.throttled_busy_poll {
        failures.push(format!("THROTTLED BUSY-POLL: {w}"));
    }
    if s.controller_steps == 0 && s.published > v.open_loop_cycles && s.safe_state_cycles == 0 {
        failures.push(format!(
            "the controller never ran although {} samples were answered",
            s.published
        ));
    }
    if s.foreign_actuations > 0 {
        failures.push(format!(
            "FOREIGN ACTUATION: on {} samples the plant applied inputs the service did not send",
            s.foreign_actuations
        ));
    }
    let mut warn = |n: u64, what: &str| {
        if n > 0 {
            warnings.push(format!("{n} {what}"));
        }
    };
    warn(s.skipped, "samples lost (gaps in the sequence)");
    warn(
        s.rejected_duplicate + s.rejected_backward + s.rejected_jump,
        "samples refused for their sequence number (duplicate, backward or unexplained jump)",
    );
    warn(
        s.rejected_contract + s.rejected_non_finite + s.rejected_out_of_range,
        "measurements rejected (contract, non-finite or out of range)",
    );
    warn(s.new_sessions, "new plant sessions after the first");
    warn(
        s.foreign_samples,
        "samples refused because another publisher than the pinned plant sent them",
    );
    warn(
        s.plant_silent_events,
        "times the plant went silent (no sample for service.silent-periods)",
    );
    warn(
        s.impossible_timestamps,
        "samples with an impossible sample time (left out of the latency figures)",
    );
    warn(
        s.protected_misses,
        "misses during start-up (grace period or open-loop phase; not acted on)",
    );
    warn(s.controller_faults, "cycles with a controller fault");
    warn(
        s.fallback_cycles,
        "cycles on the controller's fallback input",
    );
    warn(s.publish_failures, "actuations that could not be published");
    warn(v.log_dropped, "signal-log records dropped");
    if let Some((steal, loop_s)) = v.rt_core_steal
        && loop_s > 0.0
        && steal >= STEAL_WARNING_SHARE * loop_s
    {
        warnings.push(format!(
            "HYPERVISOR STEAL: the host did not run the RT core for {steal:.2} s of the \
             {loop_s:.2} s loop ({:.1} %); no priority on this box prevents the misses and \
             losses that causes",
            100.0 * steal / loop_s
        ));
    }
    RunVerdict {
        ok: failures.is_empty(),
        failures,
        warnings,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn inputs(stats: LoopStats) -> VerdictInputs {
        VerdictInputs {
            stats,
            safe_state_at_end: None,
            limits: Limits::default(),
            open_loop_cycles: 10,
            log_dropped: 0,
            adaptation: None,
            suppression_db: vec![],
            throttled_busy_poll: None,
            rt_core_steal: None,
        }
    }

    fn clean() -> LoopStats {
        LoopStats {
            received: 1000,
            published: 1000,
            controller_steps: 990,
            inputs_off_safe: 990,
            samples_past_startup: 900,
            ..LoopStats::default()
        }
    }

    #[test]
    fn a_clean_run_is_ok_without_warnings() {
        let v = judge(&inputs(clean()));
        assert_eq!(
            v,
            RunVerdict {
                ok: true,
                failures: vec![],
                warnings: vec![]
            }
        );
        assert_eq!(v.headline(), "verdict: OK");
    }

    #[test]
    fn a_run_that_ends_in_the_safe_state_fails_and_says_what_recovery_needed() {
        let mut i = inputs(LoopStats {
            safe_state_cycles: 10,
            ..clean()
        });
        i.safe_state_at_end = Some(SafeStateAtEnd {
            since_s: 6.49,
            recover_after: Some(800),
            tolerance: 0,
            longest_clean_run: 159,
        });
        let v = judge(&i);
        assert!(!v.ok);
        assert_eq!(
            v.failures,
            [
                "ENDED IN SAFE STATE since 6.49 s: the last window is open loop; recovery needs 800 \
              clean cycles in a row, the longest run of clean cycles since the entry was 159"
            ]
        );
        assert!(
            v.headline()
                .starts_with("verdict: FAILED: ENDED IN SAFE STATE")
        );
    }

    #[test]
    fn too_large_a_safe_state_share_fails_the_run() {
        let stats = LoopStats {
            controller_steps: 800,
            safe_state_cycles: 200,
            ..clean()
        };
        assert!((safe_state_share(&stats) - 0.2).abs() < 1e-12);
        let v = judge(&inputs(stats));
        assert!(!v.ok);
        assert!(
            v.failures[0].starts_with("20.0 % of the closed-loop cycles"),
            "{v:?}"
        );
        let v = judge(&VerdictInputs {
            limits: Limits {
                max_safe_state_share: 0.25,
                ..Limits::default()
            },
            ..inputs(stats)
        });
        assert!(v.ok, "{v:?}");
    }

    #[test]
    fn a_controller_that_never_ran_and_foreign_actuations_fail_the_run() {
        let v = judge(&inputs(LoopStats {
            controller_steps: 0,
            inputs_off_safe: 0,
            foreign_actuations: 3,
            ..clean()
        }));
        assert_eq!(v.failures.len(), 2, "{v:?}");
        assert!(v.failures[0].contains("controller never ran"));
        assert!(v.failures[1].starts_with("FOREIGN ACTUATION: on 3 samples"));
    }

    #[test]
    fn every_counted_anomaly_is_a_warning() {
        let stats = LoopStats {
            skipped: 1,
            rejected_duplicate: 1,
            rejected_backward: 1,
            rejected_jump: 1,
            rejected_non_finite: 1,
            new_sessions: 1,
            plant_silent_events: 1,
            impossible_timestamps: 1,
            protected_misses: 1,
            controller_faults: 1,
            fallback_cycles: 1,
            publish_failures: 1,
            foreign_samples: 1,
            ..clean()
        };
        let v = judge(&VerdictInputs {
            log_dropped: 1,
            ..inputs(stats)
        });
        assert!(v.ok);
        assert_eq!(v.warnings.len(), 12, "{:#?}", v.warnings);
        assert!(v.warnings[1].starts_with("3 samples refused"));
    }

    #[test]
    fn lost_samples_past_start_up_above_the_limit_fail_the_run_naming_the_share() {
        let at = |lost| LoopStats {
            lost_past_startup: lost,
            skipped: lost,
            ..clean()
        };
        assert!(judge(&inputs(at(9))).ok, "1 % of 900 is the limit itself");
        let v = judge(&inputs(at(10)));
        assert!(!v.ok);
        assert_eq!(
            v.failures,
            [
                "SAMPLES LOST: 1.11 % of the samples past start-up never reached the service (10 \
              of 900), more than service.max-lost-share = 1.00 %"
            ]
        );
        assert!(v.warnings[0].starts_with("10 samples lost"), "{v:?}");
    }

    #[test]
    fn inputs_the_plant_held_above_the_limit_fail_the_run() {
        let v = judge(&inputs(LoopStats {
            held_past_startup: 20,
            ..clean()
        }));
        assert!(!v.ok);
        assert!(v.failures[0].starts_with("INPUTS HELD: the plant held or safe-outputted 2.22 %"));
    }

    #[test]
    fn a_controller_whose_input_never_left_the_safe_input_fails_the_run() {
        let v = judge(&inputs(LoopStats {
            inputs_off_safe: 0,
            ..clean()
        }));
        assert_eq!(
            v.failures,
            ["NO CONTROL: the controller ran 990 steps but its input never left the safe input"]
        );
    }

    #[test]
    fn adaptation_suspended_on_most_steps_fails_the_run_naming_the_causes() {
        let adaptation = |updated, gap| Adaptation {
            updated,
            suspended: vec![("a gap in its data", gap), ("a bad sample", 0)],
            frozen: 0,
        };
        let mut i = inputs(clean());
        i.adaptation = Some(adaptation(500, 500));
        assert!(judge(&i).ok, "half is the limit itself");
        i.adaptation = Some(adaptation(100, 890));
        let v = judge(&i);
        assert_eq!(
            v.failures,
            [
                "ADAPTATION SUSPENDED on 89.9 % of the closed-loop steps (890 of 990: 890 for a gap \
              in its data), more than service.max-suspended-share = 50.0 %"
            ]
        );
    }

    #[test]
    fn a_tone_below_the_acceptance_criterion_fails_the_run_and_an_unmeasured_one_too() {
        let mut i = inputs(clean());
        i.limits.min_suppression_db = Some(60.0);
        i.suppression_db = vec![(800.0, Some(66.0)), (900.0, Some(61.0))];
        assert!(judge(&i).ok);
        i.suppression_db = vec![(800.0, Some(66.0)), (900.0, Some(12.2)), (1060.0, None)];
        let v = judge(&i);
        assert_eq!(
            v.failures,
            [
                "SUPPRESSION BELOW 60 dB (service.report.min-suppression-db): 900 Hz 12.2 dB, 1060 \
              Hz not measured"
            ]
        );
        i.suppression_db.clear();
        assert!(judge(&i).failures[0].starts_with("SUPPRESSION NOT MEASURED"));
        i.limits.min_suppression_db = None;
        assert!(judge(&i).ok, "no criterion, no failure");
    }

    #[test]
    fn a_throttled_fifo_busy_poll_fails_the_run() {
        let mut i = inputs(clean());
        i.throttled_busy_poll = Some("RT throttling is on".into());
        assert_eq!(
            judge(&i).failures,
            ["THROTTLED BUSY-POLL: RT throttling is on"]
        );
    }

    #[test]
    fn steal_on_the_rt_core_from_one_percent_of_the_loop_is_a_warning_not_a_failure() {
        let judge_with = |steal: Option<(f64, f64)>| {
            judge(&VerdictInputs {
                rt_core_steal: steal,
                ..inputs(clean())
            })
        };
        let stolen = judge_with(Some((2.9, 10.0)));
        assert!(stolen.ok, "{stolen:?}");
        assert_eq!(stolen.warnings.len(), 1, "{stolen:?}");
        assert!(
            stolen.warnings[0].starts_with("HYPERVISOR STEAL")
                && stolen.warnings[0].contains("2.90 s of the 10.00 s loop (29.0 %)"),
            "{}",
            stolen.warnings[0]
        );
        assert!(judge_with(Some((0.11, 10.0))).warnings[0].contains("(1.1 %)"));
        assert!(judge_with(Some((0.09, 10.0))).warnings.is_empty());
        assert!(judge_with(None).warnings.is_empty());
        assert!(judge_with(Some((1.0, 0.0))).warnings.is_empty());
    }
}
