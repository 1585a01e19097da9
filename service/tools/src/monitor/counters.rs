//! The run report's counters by name: one table that `/api/state`, `/metrics` and the
//! Foxglove `counters` channel all read, so that the three say the same thing.
//!
//! The names are those of the fields of [`TelemetryCounters`] (and of the run report); a
//! metric is `adaptive_rig_<name>_total`, except the one maximum among them
//! ([`MAXIMA`]), a gauge `adaptive_rig_<name>`.

use ipc_types::telemetry::TelemetryCounters;

/// One counter: its name, what it counts, and how to read it from the counters.
#[derive(Clone, Copy)]
pub struct CounterField {
    /// The field's name (`"deadline_misses"`).
    pub name: &'static str,
    /// What it counts, for a metric's help text.
    pub help: &'static str,
    /// Its value in a set of counters.
    pub get: fn(&TelemetryCounters) -> u64,
}

impl core::fmt::Debug for CounterField {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name)
    }
}

macro_rules! fields {
    ($($name:ident: $help:literal),+ $(,)?) => {
        /// Every counter of [`TelemetryCounters`], in the order of its fields.
        pub const COUNTERS: &[CounterField] = &[
            $(CounterField {
                name: stringify!($name),
                help: $help,
                get: |c: &TelemetryCounters| c.$name,
            }),+
        ];
    };
}

fields! {
    received: "Measurements received.",
    published: "Answers published.",
    controller_steps: "Controller steps run.",
    lost: "Samples never seen (gaps in the sequence).",
    samples_past_startup: "Samples past start-up.",
    lost_past_startup: "Samples past start-up that were lost.",
    held_past_startup: "Samples past start-up whose input the plant held although the service had sent one.",
    caught_up: "Samples received too late to answer.",
    rejected: "Samples refused by the gate or the sequence checks.",
    deadline_misses: "Answers after the plant's deadline.",
    plant_reported_misses: "Misses the plant reported.",
    plan_covered_misses: "Plant-reported misses covered by a plan entry.",
    max_consecutive_misses: "Longest run of consecutive misses so far.",
    safe_state_entries: "Entries into the safe state.",
    safe_state_cycles: "Cycles in the safe state.",
    plant_silent_events: "Times the plant went silent.",
    new_sessions: "New plant sessions after the first.",
    saturated_cycles: "Cycles the controller reported saturation.",
    controller_faults: "Cycles the controller reported a fault.",
    fallback_cycles: "Cycles the controller applied its fallback input.",
    publish_failures: "Actuations that could not be published.",
    foreign_samples: "Samples refused because another publisher than the pinned plant sent them.",
    commands_applied: "Operator commands applied.",
    commands_refused: "Operator commands refused.",
    telemetry_dropped: "Samples the service's telemetry thread did not get (its queue was full).",
}

/// The fields that are maxima, not counts (exported as gauges).
pub const MAXIMA: &[&str] = &["max_consecutive_misses"];

/// The counters as `(name, value)` pairs, in the order of [`COUNTERS`].
pub fn pairs(c: &TelemetryCounters) -> impl Iterator<Item = (&'static str, u64)> + '_ {
    COUNTERS.iter().map(move |f| (f.name, (f.get)(c)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_field_is_listed_once_and_read_from_its_own_field() {
        // 25 u64 fields: the table must cover the whole struct.
        assert_eq!(
            COUNTERS.len() * 8,
            core::mem::size_of::<TelemetryCounters>()
        );
        let mut names: Vec<_> = COUNTERS.iter().map(|f| f.name).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), COUNTERS.len());
        let c = TelemetryCounters {
            deadline_misses: 7,
            telemetry_dropped: 3,
            ..Default::default()
        };
        let m: std::collections::HashMap<_, _> = pairs(&c).collect();
        assert_eq!(m["deadline_misses"], 7);
        assert_eq!(m["telemetry_dropped"], 3);
        assert_eq!(m["received"], 0);
    }
}
