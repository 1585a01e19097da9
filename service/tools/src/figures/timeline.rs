//! The plant time of a run's logged samples and events, and the intervals of its states.
//!
//! Time is plant time: sample `seq` of a plant session is at
//!
//! ```text
//!   t(seq) = t₀ + (seq − seq₀) T
//! ```
//!
//! where `seq₀` is the session's first logged sample and `t₀` its time; the first logged
//! sample of the run is at `t = 0`. Lost samples (gaps in `seq`) and a decimated log
//! therefore keep every sample at its own time: positions come from `seq`, never from the
//! row index. A plant session that restarts its numbering (a sequence number that does
//! not increase, or the `to` of a `new-plant-session` event) starts a new session after
//! the previous one: `t₀` is the previous session's last time plus the silence between
//! them measured on the plant clock (`t_sample_ns`), when the clock tells it, else one
//! period.
//!
//! [`Timeline::intervals`] gives the intervals to shade, merged per [`IntervalKind`]: the
//! safe state (from the `safe-state-entered` / `safe-state-left` events and from the
//! `SAFE_STATE` status bit of the rows, whichever says more; a safe state never left lasts
//! to the end of the run), the plant's silence (`plant-silent` to `plant-resumed` or to the
//! next session) and the plant's watchdog (rows whose measurement flags carry
//! `PLANT_SAFE_OUTPUT`), and where samples were lost: the steps of `seq` inside a session
//! longer than the log's stride (from the last logged sample before the gap to the first
//! after it: samples the service never answered, or rows the logger dropped) and the
//! samples whose answer missed the plant's deadline (a row with the measurement flag
//! `PREVIOUS_ACTUATION_MISSED` marks the period before it). [`Timeline::markers`] gives
//! the starts of new plant sessions.

use std::ops::Range;

use ipc_types::{actuation_status, measurement_flags};

use super::report::Event;
use super::run::RunFigureError;

/// Largest silence between two sessions drawn at its clock length, in multiples of the
/// number of logged rows (a broken clock must not squash the figure).
const MAX_GAP_ROWS: f64 = 10.0;

/// One plant session of the log.
#[derive(Debug, Clone, PartialEq)]
pub struct Session {
    /// Its rows in the log.
    pub rows: Range<usize>,
    /// Sequence number of its first logged row.
    pub seq0: u64,
    /// Plant time of its first logged row, s.
    pub t0: f64,
    /// The index in the report's events of the `new-plant-session` event that began it,
    /// if one was matched.
    pub opened_by: Option<usize>,
}

impl Session {
    /// Plant time of sample `seq` of this session, s.
    pub fn time_of(&self, seq: u64, sample_period: f64) -> f64 {
        self.t0 + (seq as f64 - self.seq0 as f64) * sample_period
    }
}

/// What a shaded interval shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum IntervalKind {
    /// The service was in its safe state (it applied the safe input).
    SafeState,
    /// The plant sent no sample (the service declared it silent).
    PlantSilent,
    /// The plant's watchdog had tripped: it applied its safe output.
    PlantWatchdog,
    /// The answer to the sample missed the plant's deadline (`PREVIOUS_ACTUATION_MISSED`
    /// on the next row).
    AnswerMissed,
    /// Samples missing from the log: a gap in `seq` (never answered, or dropped by the
    /// logger); drawn over the missed answers.
    SamplesLost,
}

impl IntervalKind {
    /// Legend text.
    pub fn label(self) -> &'static str {
        match self {
            IntervalKind::SafeState => "safe state (service)",
            IntervalKind::PlantSilent => "plant silent",
            IntervalKind::PlantWatchdog => "plant watchdog (safe output)",
            IntervalKind::SamplesLost => "samples lost (gap in seq)",
            IntervalKind::AnswerMissed => "answer missed (plant's flag)",
        }
    }
}

/// A time interval `[from_s, to_s]` in plant time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Interval {
    /// What it shows.
    pub kind: IntervalKind,
    /// Start, s.
    pub from_s: f64,
    /// End, s.
    pub to_s: f64,
}

/// The time axis of a run's log.
#[derive(Debug, Clone, PartialEq)]
pub struct Timeline {
    /// Sample period `T`, s.
    pub sample_period: f64,
    /// Sequence number of each row.
    pub seq: Vec<u64>,
    /// Plant time of each row, s.
    pub t: Vec<f64>,
    /// The plant sessions, in order; their rows cover the log.
    pub sessions: Vec<Session>,
    /// The step of `seq` between most consecutive rows (1, or the log's decimation).
    pub stride: u64,
    /// Rows missing from the log inside sessions: steps of `seq` longer than the stride,
    /// counted in strides (samples lost, or records dropped by the logger).
    pub missing: u64,
}

impl Timeline {
    /// The time axis of the rows with sequence numbers `seq` and sample times `t_ns`
    /// (ns, 0 when unknown), sample period `sample_period` (s), the report's `events`
    /// used to find where sessions begin. `origin` names the log in errors: a sequence
    /// number that is not a non-negative integer, or no rows.
    pub fn new(
        seq: &[f64],
        t_ns: Option<&[f64]>,
        events: &[Event],
        sample_period: f64,
        origin: &str,
    ) -> Result<Self, RunFigureError> {
        if seq.is_empty() {
            return Err(RunFigureError::NoRows {
                origin: origin.into(),
            });
        }
        if !(sample_period.is_finite() && sample_period > 0.0) {
            return Err(RunFigureError::SamplePeriod {
                origin: origin.into(),
                period: sample_period,
            });
        }
        let mut s = Vec::with_capacity(seq.len());
        for (r, v) in seq.iter().enumerate() {
            if !(v.is_finite() && *v >= 0.0 && v.fract() == 0.0 && *v < 9.0e15) {
                return Err(RunFigureError::Sequence {
                    origin: origin.into(),
                    row: r + 1,
                    value: *v,
                });
            }
            s.push(*v as u64);
        }
        let clock = |r: usize| -> Option<f64> {
            t_ns.and_then(|c| c.get(r))
                .copied()
                .filter(|v| v.is_finite() && *v > 0.0)
        };
        let new_sessions: Vec<(usize, u64, u64)> = events
            .iter()
            .enumerate()
            .filter_map(|(i, e)| match e {
                Event::NewPlantSession { from, to, .. } => Some((i, *from, *to)),
                _ => None,
            })
            .collect();
        let mut pending = new_sessions.iter().peekable();
        let max_gap = MAX_GAP_ROWS * seq.len() as f64;
        let mut t = Vec::with_capacity(s.len());
        let mut sessions = vec![Session {
            rows: 0..0,
            seq0: s[0],
            t0: 0.0,
            opened_by: None,
        }];
        t.push(0.0);
        for r in 1..s.len() {
            let (prev, now) = (s[r - 1], s[r]);
            // Does the next new-session event begin here?
            let by_event = pending.peek().is_some_and(|&&(_, from, to)| {
                if to <= from {
                    now <= prev
                } else {
                    prev < to && now >= to
                }
            });
            let opened_by = if by_event {
                pending.next().map(|&(i, _, _)| i)
            } else {
                None
            };
            if by_event || now <= prev {
                let last = *t.last().unwrap_or(&0.0);
                let forward = (now > prev).then(|| (now - prev) as f64);
                let steps = match forward {
                    Some(d) if d <= max_gap => d,
                    _ => match (clock(r - 1), clock(r)) {
                        (Some(a), Some(b)) if b > a => {
                            ((b - a) * 1e-9 / sample_period).round().clamp(1.0, max_gap)
                        }
                        _ => 1.0,
                    },
                };
                if let Some(cur) = sessions.last_mut() {
                    cur.rows.end = r;
                }
                sessions.push(Session {
                    rows: r..r,
                    seq0: now,
                    t0: last + steps * sample_period,
                    opened_by,
                });
            }
            let cur = sessions
                .last()
                .map_or(0.0, |c| c.time_of(now, sample_period));
            t.push(cur);
        }
        if let Some(cur) = sessions.last_mut() {
            cur.rows.end = s.len();
        }
        let mut steps: Vec<u64> = Vec::with_capacity(s.len());
        for ss in &sessions {
            for r in ss.rows.start + 1..ss.rows.end {
                steps.push(s[r] - s[r - 1]);
            }
        }
        steps.sort_unstable();
        let stride = steps.get(steps.len() / 2).copied().unwrap_or(1).max(1);
        let missing = steps
            .iter()
            .map(|d| d.div_ceil(stride).saturating_sub(1))
            .sum();
        Ok(Self {
            sample_period,
            seq: s,
            t,
            sessions,
            stride,
            missing,
        })
    }

    /// Plant time of the last logged row, s.
    pub fn end(&self) -> f64 {
        self.t.last().copied().unwrap_or(0.0)
    }

    /// The index of the session of row `r`.
    pub fn session_of_row(&self, r: usize) -> usize {
        self.sessions
            .iter()
            .position(|s| s.rows.contains(&r))
            .unwrap_or(self.sessions.len().saturating_sub(1))
    }

    /// The row of sample `seq` in session `session`, or the last row before it (`None`
    /// when `seq` precedes the session's first row).
    pub fn row_at_or_before(&self, session: usize, seq: u64) -> Option<usize> {
        let ss = self.sessions.get(session)?;
        let rows = &self.seq[ss.rows.clone()];
        let n = rows.partition_point(|v| *v <= seq);
        (n > 0).then(|| ss.rows.start + n - 1)
    }

    /// The intervals to shade (see the module docs), merged per kind, within
    /// `[0, end]`, sorted by kind and start. `status` and `flags` are the rows' actuation
    /// status and measurement flags (either may be absent).
    pub fn intervals(
        &self,
        events: &[Event],
        status: Option<&[f64]>,
        flags: Option<&[f64]>,
    ) -> Vec<Interval> {
        let ts = self.sample_period;
        let end = self.end();
        let mut out = Vec::new();
        // From the events.
        let mut cursor = 0usize;
        let mut beyond_log = false;
        let mut safe_from: Option<f64> = None;
        let mut silent_from: Option<f64> = None;
        let at = |cursor: usize, seq: u64, beyond: bool| -> f64 {
            if beyond {
                end
            } else {
                self.sessions[cursor].time_of(seq, ts)
            }
        };
        for (i, e) in events.iter().enumerate() {
            match *e {
                Event::NewPlantSession { from, .. } => {
                    let before = at(cursor, from, beyond_log);
                    match self.sessions.iter().position(|s| s.opened_by == Some(i)) {
                        Some(s) => cursor = s,
                        None => beyond_log = true,
                    }
                    let start = if beyond_log {
                        end
                    } else {
                        self.sessions[cursor].t0
                    };
                    if let Some(f) = silent_from.take() {
                        out.push((IntervalKind::PlantSilent, f, start));
                    }
                    // A new session always begins out of the safe state.
                    if let Some(f) = safe_from.take() {
                        out.push((IntervalKind::SafeState, f, before));
                    }
                }
                Event::PlantSilent { last_seq } => {
                    silent_from.get_or_insert(at(cursor, last_seq, beyond_log));
                }
                Event::PlantResumed { seq } => {
                    // A resume that begins a new session is closed by that event.
                    let new_session = matches!(
                        events.get(i + 1),
                        Some(Event::NewPlantSession { to, .. }) if *to == seq
                    );
                    if !new_session && let Some(f) = silent_from.take() {
                        out.push((IntervalKind::PlantSilent, f, at(cursor, seq, beyond_log)));
                    }
                }
                Event::SafeStateEntered { seq } => {
                    safe_from.get_or_insert(at(cursor, seq, beyond_log));
                }
                Event::SafeStateLeft { seq } => {
                    if let Some(f) = safe_from.take() {
                        out.push((IntervalKind::SafeState, f, at(cursor, seq, beyond_log)));
                    }
                }
                Event::FirstSample { .. } | Event::PlantEnded { .. } | Event::Other => {}
            }
        }
        if let Some(f) = safe_from {
            out.push((IntervalKind::SafeState, f, end));
        }
        if let Some(f) = silent_from {
            out.push((IntervalKind::PlantSilent, f, end));
        }
        // From the rows.
        let bit = |col: Option<&[f64]>, mask: u32| -> Vec<bool> {
            match col {
                Some(c) => c.iter().map(|v| (*v as u32) & mask != 0).collect(),
                None => Vec::new(),
            }
        };
        for (kind, rows) in [
            (
                IntervalKind::SafeState,
                bit(status, actuation_status::SAFE_STATE),
            ),
            (
                IntervalKind::PlantWatchdog,
                bit(flags, measurement_flags::PLANT_SAFE_OUTPUT),
            ),
        ] {
            for ss in &self.sessions {
                let mut run: Option<usize> = None;
                for r in ss.rows.clone() {
                    let on = rows.get(r).copied().unwrap_or(false);
                    match (on, run) {
                        (true, None) => run = Some(r),
                        (false, Some(a)) => {
                            out.push((kind, self.t[a], self.t[r - 1]));
                            run = None;
                        }
                        _ => {}
                    }
                }
                if let Some(a) = run {
                    out.push((kind, self.t[a], self.t[ss.rows.end - 1]));
                }
            }
        }
        out.extend(self.loss_intervals(flags));
        merge(out, 1.5 * ts * self.stride as f64, end)
    }

    /// The unmerged intervals of lost samples (gaps in `seq` inside a session) and missed
    /// answers (rows whose `flags` carry `PREVIOUS_ACTUATION_MISSED`: the period before
    /// the row), see the module docs.
    pub fn loss_intervals(&self, flags: Option<&[f64]>) -> Vec<(IntervalKind, f64, f64)> {
        let ts = self.sample_period;
        let mut out = Vec::new();
        for ss in &self.sessions {
            for r in ss.rows.start + 1..ss.rows.end {
                if self.seq[r] - self.seq[r - 1] > self.stride {
                    out.push((IntervalKind::SamplesLost, self.t[r - 1], self.t[r]));
                }
            }
        }
        if let Some(f) = flags {
            for (r, v) in f.iter().enumerate().take(self.t.len()) {
                if (*v as u32) & measurement_flags::PREVIOUS_ACTUATION_MISSED != 0 {
                    out.push((IntervalKind::AnswerMissed, self.t[r] - ts, self.t[r]));
                }
            }
        }
        out
    }

    /// Plant times of the starts of the sessions after the first (new plant sessions).
    pub fn markers(&self) -> Vec<f64> {
        self.sessions.iter().skip(1).map(|s| s.t0).collect()
    }
}

/// Sorts `raw` intervals by kind and start, clips them to `[0, end]` and merges those of
/// a kind that overlap or are less than `tolerance` apart.
fn merge(raw: Vec<(IntervalKind, f64, f64)>, tolerance: f64, end: f64) -> Vec<Interval> {
    let mut v: Vec<Interval> = raw
        .into_iter()
        .filter(|(_, a, b)| a.is_finite() && b.is_finite())
        .map(|(kind, a, b)| Interval {
            kind,
            from_s: a.min(b).clamp(0.0, end),
            to_s: a.max(b).clamp(0.0, end),
        })
        .collect();
    v.sort_by(|a, b| a.kind.cmp(&b.kind).then(a.from_s.total_cmp(&b.from_s)));
    let mut out: Vec<Interval> = Vec::with_capacity(v.len());
    for i in v {
        match out.last_mut() {
            Some(last) if last.kind == i.kind && i.from_s <= last.to_s + tolerance => {
                last.to_s = last.to_s.max(i.to_s);
            }
            _ => out.push(i),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: f64 = 0.5;

    #[test]
    fn rows_are_placed_by_sequence_number_not_by_row() {
        let tl = Timeline::new(&[10.0, 11.0, 14.0, 15.0], None, &[], T, "s.csv").unwrap();
        assert_eq!(tl.t, vec![0.0, 0.5, 2.0, 2.5]);
        assert_eq!(tl.sessions.len(), 1);
        assert_eq!(tl.missing, 2);
        assert_eq!(tl.stride, 1);
        assert_eq!(tl.row_at_or_before(0, 13), Some(1));
        assert_eq!(tl.row_at_or_before(0, 9), None);
    }

    #[test]
    fn a_restarted_sequence_begins_a_new_session_after_the_silence_on_the_clock() {
        let events = [
            Event::FirstSample { seq: 5 },
            Event::PlantSilent { last_seq: 7 },
            Event::PlantResumed { seq: 0 },
            Event::NewPlantSession {
                from: 7,
                to: 0,
                left_safe_state: false,
            },
        ];
        let t_ns = [1e9, 1.5e9, 2e9, 5e9, 5.5e9];
        let tl = Timeline::new(&[5.0, 6.0, 7.0, 0.0, 1.0], Some(&t_ns), &events, T, "s").unwrap();
        assert_eq!(tl.sessions.len(), 2);
        assert_eq!(tl.sessions[1].opened_by, Some(3));
        // 3 s of silence on the plant clock = 6 periods after the last sample at 1 s.
        assert_eq!(tl.t, vec![0.0, 0.5, 1.0, 4.0, 4.5]);
        let iv = tl.intervals(&events, None, None);
        assert_eq!(
            iv,
            vec![Interval {
                kind: IntervalKind::PlantSilent,
                from_s: 1.0,
                to_s: 4.0
            }]
        );
        assert_eq!(tl.markers(), vec![4.0]);
    }

    #[test]
    fn safe_state_from_events_and_status_bits_is_merged_and_lasts_to_the_end() {
        let seq: Vec<f64> = (0..20).map(f64::from).collect();
        let status: Vec<f64> = (0..20)
            .map(|k| if (13..).contains(&k) { 1.0 } else { 0.0 })
            .collect();
        let flags: Vec<f64> = (0..20)
            .map(|k| if (3..5).contains(&k) { 2.0 } else { 17.0 })
            .collect();
        let events = [Event::SafeStateEntered { seq: 12 }];
        let tl = Timeline::new(&seq, None, &events, T, "s").unwrap();
        let iv = tl.intervals(&events, Some(&status), Some(&flags));
        assert_eq!(iv.len(), 2);
        assert_eq!(iv[0].kind, IntervalKind::SafeState);
        assert_eq!((iv[0].from_s, iv[0].to_s), (6.0, 9.5));
        assert_eq!(iv[1].kind, IntervalKind::PlantWatchdog);
        assert_eq!((iv[1].from_s, iv[1].to_s), (1.5, 2.0));
    }

    #[test]
    fn gaps_in_seq_and_missed_answers_are_shaded_and_merged_when_close() {
        // Samples 3–4 and 9 are lost; the answers to 12 and 13 missed (flags of 13 and 14).
        let seq: Vec<f64> = (0..20u32)
            .filter(|k| !(3..5).contains(k) && *k != 9)
            .map(f64::from)
            .collect();
        let flags: Vec<f64> = seq
            .iter()
            .map(|k| {
                if (13.0..15.0).contains(k) {
                    4.0 + 16.0
                } else {
                    16.0
                }
            })
            .collect();
        let tl = Timeline::new(&seq, None, &[], T, "s").unwrap();
        assert_eq!(tl.missing, 3);
        let raw = tl.loss_intervals(Some(&flags));
        assert_eq!(
            raw,
            vec![
                (IntervalKind::SamplesLost, 1.0, 2.5),
                (IntervalKind::SamplesLost, 4.0, 5.0),
                (IntervalKind::AnswerMissed, 6.0, 6.5),
                (IntervalKind::AnswerMissed, 6.5, 7.0),
            ]
        );
        let iv = tl.intervals(&[], None, Some(&flags));
        let kinds: Vec<(IntervalKind, f64, f64)> =
            iv.iter().map(|i| (i.kind, i.from_s, i.to_s)).collect();
        assert_eq!(
            kinds,
            vec![
                (IntervalKind::AnswerMissed, 6.0, 7.0),
                (IntervalKind::SamplesLost, 1.0, 2.5),
                (IntervalKind::SamplesLost, 4.0, 5.0),
            ]
        );
        // A decimated log (stride 2) with nothing lost shades nothing; a new session is
        // not a gap.
        let tl = Timeline::new(&[0.0, 2.0, 4.0, 6.0, 0.0, 2.0], None, &[], T, "s").unwrap();
        assert!(tl.loss_intervals(None).is_empty());
    }

    #[test]
    fn bad_sequence_numbers_are_errors_naming_the_file() {
        for bad in [f64::NAN, -1.0, 2.5] {
            let e = Timeline::new(&[0.0, bad], None, &[], T, "x/signals.csv")
                .unwrap_err()
                .to_string();
            assert!(e.starts_with("x/signals.csv: data row 2"), "{e}");
        }
        assert!(Timeline::new(&[], None, &[], T, "x").is_err());
    }
}
