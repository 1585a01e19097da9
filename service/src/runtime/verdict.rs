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
//! 4. the plant reported applying inputs the service did not send (a foreign actuation).
//!
//! Everything else that makes the figures less than they look — lost, refused or rejected
//! samples, new plant sessions, impossible sample times, misses during start-up, dropped
//! log records, controller faults and fallbacks — is a [`RunVerdict::warnings`] line. The
//! verdict is a pure function of the counters; the service's exit status follows
//! [`RunVerdict::ok`].

use super::LoopStats;
use serde::Serialize;

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

/// What the verdict is computed from.
#[derive(Debug, Clone, Copy)]
pub struct VerdictInputs {
    /// The loop's counters.
    pub stats: LoopStats,
    /// `Some` when the run ended in the safe state.
    pub safe_state_at_end: Option<SafeStateAtEnd>,
    /// `service.max-safe-state-share`.
    pub max_safe_state_share: f64,
    /// Cycles of the open-loop phase of a session.
    pub open_loop_cycles: u64,
    /// Signal-log records dropped.
    pub log_dropped: u64,
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
    if share > v.max_safe_state_share {
        failures.push(format!(
            "{:.1} % of the closed-loop cycles in the safe state ({} of {}), more than \
             service.max-safe-state-share = {:.1} %",
            100.0 * share,
            s.safe_state_cycles,
            s.controller_steps + s.safe_state_cycles,
            100.0 * v.max_safe_state_share
        ));
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
            max_safe_state_share: 0.1,
            open_loop_cycles: 10,
            log_dropped: 0,
        }
    }

    fn clean() -> LoopStats {
        LoopStats {
            received: 1000,
            published: 1000,
            controller_steps: 990,
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
            max_safe_state_share: 0.25,
            ..inputs(stats)
        });
        assert!(v.ok, "{v:?}");
    }

    #[test]
    fn a_controller_that_never_ran_and_foreign_actuations_fail_the_run() {
        let v = judge(&inputs(LoopStats {
            controller_steps: 0,
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
}
