//! What the run figure reads of a run's `report.json`: the service's
//! `service::runtime::RunReport`, serialized, read back into the few fields the figure
//! needs.
//!
//! The service's report types only serialize; this module mirrors the parts the figure
//! uses with `Deserialize`, every field optional or defaulted, so that a report of an
//! older service (no verdict, no tones) still gives a figure, and unknown fields and
//! unknown event kinds are ignored. Anything else that does not parse is an error naming
//! the file.

use serde::Deserialize;

use super::run::RunFigureError;

/// The fields of `report.json` the figure uses.
#[derive(Debug, Clone, Default, Deserialize)]
pub struct ReportView {
    /// Rig name.
    #[serde(default)]
    pub rig: String,
    /// Controller kind.
    #[serde(default)]
    pub controller: String,
    /// Sample period `T`, s.
    #[serde(default)]
    pub sample_period_s: Option<f64>,
    /// Response-time budget (the sample period), ns: `T` when `sample_period_s` is absent.
    #[serde(default)]
    pub budget_ns: Option<f64>,
    /// Open-loop phase at the start of each session, s (`service.open-loop`).
    #[serde(default)]
    pub open_loop_s: Option<f64>,
    /// Whether the run did what it was started for; `None` in reports without one.
    #[serde(default)]
    pub verdict: Option<VerdictView>,
    /// The loop's events, in order.
    #[serde(default)]
    pub events: Vec<Event>,
    /// The tone table, when tones were known.
    #[serde(default)]
    pub tones: Option<TonesView>,
    /// Signal-log records dropped because the queue was full.
    #[serde(default)]
    pub log_dropped: u64,
}

/// The run's verdict (`service::runtime::verdict::RunVerdict`).
#[derive(Debug, Clone, Default, Deserialize)]
pub struct VerdictView {
    /// True when there is no failure.
    pub ok: bool,
    /// One line per failure.
    #[serde(default)]
    pub failures: Vec<String>,
    /// One line per warning.
    #[serde(default)]
    pub warnings: Vec<String>,
}

/// The tone table (`service::runtime::tones::ToneReport`).
#[derive(Debug, Clone, Default, Deserialize)]
pub struct TonesView {
    /// Window length of both tone fits, s.
    #[serde(default)]
    pub window_s: Option<f64>,
    /// Per tone and channel.
    #[serde(default)]
    pub tones: Vec<ToneView>,
    /// Why nothing could be measured, if so.
    #[serde(default)]
    pub error: Option<String>,
}

/// One line of the tone table.
#[derive(Debug, Clone, Default, Deserialize)]
pub struct ToneView {
    /// Tone frequency, Hz.
    #[serde(default)]
    pub hz: f64,
    /// Channel of `z`.
    #[serde(default)]
    pub channel: usize,
    /// Closed-loop amplitude over open-loop amplitude, dB (positive: suppressed).
    #[serde(default)]
    pub suppression_db: Option<f64>,
}

/// A loop event (`service::runtime::LoopEvent`), as serialized (`"event"` names the kind,
/// kebab-case); the kinds the figure does not use are [`Event::Other`].
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(tag = "event", rename_all = "kebab-case")]
pub enum Event {
    /// The first sample of a plant session arrived.
    FirstSample {
        /// Its sequence number.
        seq: u64,
    },
    /// No sample for the configured number of periods.
    PlantSilent {
        /// The last sequence number received.
        last_seq: u64,
    },
    /// Samples came back after silence.
    PlantResumed {
        /// The first sequence number received again.
        seq: u64,
    },
    /// A new plant session begins.
    NewPlantSession {
        /// The last sequence number of the previous session.
        from: u64,
        /// The first of the new one.
        to: u64,
        /// The safe state of the previous session was cleared.
        #[serde(default)]
        left_safe_state: bool,
    },
    /// Too many consecutive deadline misses: the safe input is applied.
    SafeStateEntered {
        /// Sequence number at which it happened.
        seq: u64,
    },
    /// The safe state was left after enough good answers.
    SafeStateLeft {
        /// Sequence number at which it happened.
        seq: u64,
    },
    /// The plant said this was its last sample.
    PlantEnded {
        /// Its sequence number.
        seq: u64,
    },
    /// Any other event (not drawn).
    #[serde(other)]
    Other,
}

impl ReportView {
    /// Parses the text of `report.json`; `origin` (the path) names the file in errors.
    pub fn parse(text: &str, origin: &str) -> Result<Self, RunFigureError> {
        serde_json::from_str(text).map_err(|source| RunFigureError::Report {
            origin: origin.into(),
            source,
        })
    }

    /// The sample period `T` in s (`sample_period_s`, else `budget_ns`), if positive.
    pub fn sample_period(&self) -> Option<f64> {
        self.sample_period_s
            .or_else(|| self.budget_ns.map(|b| b * 1e-9))
            .filter(|t| t.is_finite() && *t > 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_report_reads_back_with_unknown_fields_and_events_ignored() {
        let text = r#"{"rig":"r","controller":"rcac","sample_period_s":0.000125,
            "open_loop_s":1.0,"stats":{"skipped":3},
            "verdict":{"ok":false,"failures":["ENDED IN SAFE STATE since 6.49 s"],"warnings":[]},
            "events":[{"event":"first-sample","seq":0},
                      {"event":"dead-nodes-cleaned","count":2},
                      {"event":"safe-state-entered","seq":51920,"misses":8},
                      {"event":"new-plant-session","from":9,"to":0,"cause":"new-peer","left_safe_state":true}],
            "tones":{"source":"x","window_s":0.5,"samples":[4000,4000],
                     "tones":[{"hz":800.0,"channel":0,"open":0.5,"closed":0.5,"suppression_db":0.0}],
                     "error":null}}"#;
        let r = ReportView::parse(text, "report.json").unwrap();
        assert_eq!(r.sample_period(), Some(0.000125));
        assert_eq!(r.open_loop_s, Some(1.0));
        assert!(!r.verdict.as_ref().unwrap().ok);
        assert_eq!(
            r.events,
            vec![
                Event::FirstSample { seq: 0 },
                Event::Other,
                Event::SafeStateEntered { seq: 51920 },
                Event::NewPlantSession {
                    from: 9,
                    to: 0,
                    left_safe_state: true
                },
            ]
        );
        assert_eq!(r.tones.unwrap().window_s, Some(0.5));
        let old = ReportView::parse(r#"{"budget_ns":125000}"#, "report.json").unwrap();
        assert!((old.sample_period().unwrap() - 1.25e-4).abs() < 1e-15);
        assert!(old.verdict.is_none());
        let err = ReportView::parse(r#"{"events":[{"event":"plant-silent"}]}"#, "x/report.json")
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("x/report.json: "), "{err}");
    }
}
