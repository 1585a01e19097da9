//! What a replay found, printed by `service replay`, and its exit status.

use super::comparison::ComparisonStats;
use super::outbox::Stop;
use std::fmt::Write;

/// The result of a replay.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplaySummary {
    /// The record replayed.
    pub record: String,
    /// Rig, controller kind and timing of the record.
    pub recorded: String,
    /// The configuration the loop was rebuilt from (`recorded`, or the files given).
    pub configuration: String,
    /// Samples handed to the loop (`handle`).
    pub samples_handled: u64,
    /// Samples taken in too late (`observe`).
    pub samples_observed: u64,
    /// Publisher changes and silences replayed.
    pub sessions: (u64, u64),
    /// Operator commands replayed.
    pub commands: u64,
    /// Actuations compared equal (bit for bit) or paired (open loop).
    pub actuations: u64,
    /// Why the replay stopped early, if it did.
    pub stop: Option<Stop>,
    /// The last sample handled before the stop.
    pub last_seq: Option<u64>,
    /// The open-loop comparison, when another configuration was replayed.
    pub comparison: Option<ComparisonStats>,
    /// Wall time of the replay, s.
    pub elapsed_s: f64,
}

impl ReplaySummary {
    /// Samples replayed per second of wall time.
    pub fn samples_per_s(&self) -> f64 {
        let n = (self.samples_handled + self.samples_observed) as f64;
        if self.elapsed_s > 0.0 {
            n / self.elapsed_s
        } else {
            0.0
        }
    }

    /// True when the record is complete and (bit for bit) every output was equal.
    pub fn equal(&self) -> bool {
        self.stop.is_none() && self.comparison.is_none()
    }

    /// The exit status of `service replay`: 0 equal bit for bit (or an open-loop
    /// comparison of a complete record), 1 a difference, 3 an incomplete record.
    pub fn exit_code(&self) -> u8 {
        match &self.stop {
            None => 0,
            Some(Stop::Differ { .. }) => 1,
            Some(Stop::Record(_)) => 3,
        }
    }

    /// The printed summary; its last line is `replay: <VERDICT> samples=N actuations=M`.
    pub fn render(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(out, "replay of {}: {}", self.record, self.recorded);
        let _ = writeln!(out, "configuration: {}", self.configuration);
        let _ = writeln!(
            out,
            "inputs: {} samples handled, {} taken in late, {} publisher changes, {} silences, \
             {} operator commands; {:.3} s, {:.0} samples/s",
            self.samples_handled,
            self.samples_observed,
            self.sessions.0,
            self.sessions.1,
            self.commands,
            self.elapsed_s,
            self.samples_per_s()
        );
        let verdict = match (&self.stop, &self.comparison) {
            (
                Some(Stop::Differ {
                    index,
                    offset,
                    reply_to,
                    seq,
                    what,
                }),
                _,
            ) => {
                let _ = writeln!(
                    out,
                    "DIFFERENT at the answer to sample {reply_to} (actuation seq {seq}; record \
                     entry {index}, byte offset {offset}): {what}; {} actuations before it were \
                     equal",
                    self.actuations
                );
                "DIFFERENT"
            }
            (Some(Stop::Record(e)), _) => {
                let _ = writeln!(
                    out,
                    "INCOMPLETE record: {e}; {} actuations up to {} were {}, nothing after the \
                     gap is compared",
                    self.actuations,
                    self.last_seq
                        .map_or("the start".to_string(), |s| format!("sample {s}")),
                    if self.comparison.is_some() {
                        "compared"
                    } else {
                        "equal bit for bit"
                    }
                );
                "INCOMPLETE"
            }
            (None, Some(_)) => "OPEN-LOOP",
            (None, None) => {
                let _ = writeln!(
                    out,
                    "outputs: {} actuations equal bit for bit to the logged ones",
                    self.actuations
                );
                "EQUAL"
            }
        };
        if let Some(c) = &self.comparison {
            let _ = writeln!(
                out,
                "open-loop comparison with the logged run ({}): {} actuations paired, RMS of \
                 u replayed − u logged {:.6e}, largest |difference| {:.6e}, {}; status differs \
                 in {}; {} only replayed, {} only logged",
                c.path.display(),
                c.pairs,
                c.rms_difference,
                c.max_difference,
                match c.first_divergence {
                    Some((seq, reply_to)) => format!(
                        "first divergence at the answer to sample {reply_to} (actuation seq {seq})"
                    ),
                    None => "no divergence".to_string(),
                },
                c.status_differs,
                c.only_replayed,
                c.only_logged
            );
        }
        let _ = writeln!(
            out,
            "replay: {verdict} samples={} actuations={}",
            self.samples_handled + self.samples_observed,
            self.actuations
        );
        out
    }
}
