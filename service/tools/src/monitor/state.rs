//! What the monitor keeps of each rig, filled from the telemetry frames by the rig's
//! reader ([`super::reader`]) and read by the web page, `/api/*`, `/metrics` and the
//! Foxglove bridge.
//!
//! Per rig ([`RigState`]): the newest frame (counters, latencies, tones, verdict, flags,
//! tunable values), the newest [`TelemetryInfo`], a ring of recent points for the scope
//! ([`POINT_RING`]), the runs seen before the current one ([`RunSummary`]), and how the
//! reader fares. A frame of another `run_id` than the newest one starts a new run: the
//! old run's final figures go into [`RigState::previous_runs`] and the ring is emptied.
//! A rig is [`Connection::Live`] while frames arrive, [`Connection::Stale`] when none came
//! for more than [`STALE_AFTER`] (the service stopped, or stalls), and
//! [`Connection::Waiting`] until the first frame. [`Hub`] holds every rig's state behind
//! its own lock.

use ipc_types::telemetry::{TelemetryFrame, TelemetryInfo, TelemetryPoint};
use std::collections::VecDeque;
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// Points kept per rig for the scope: at the largest frame (128 points every 50 ms) a bit
/// more than 3 s.
pub const POINT_RING: usize = 8192;
/// Earlier runs kept per rig.
pub const RUNS_KEPT: usize = 16;
/// A rig whose newest frame is older than this is [`Connection::Stale`].
pub const STALE_AFTER: Duration = Duration::from_secs(1);

/// Whether frames arrive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Connection {
    /// No frame yet since the monitor started.
    Waiting,
    /// The newest frame is at most [`STALE_AFTER`] old.
    Live,
    /// The newest frame is older than [`STALE_AFTER`].
    Stale,
}

impl Connection {
    /// Its name in `/api/state` (`"waiting"`, `"live"`, `"stale"`).
    pub fn name(self) -> &'static str {
        match self {
            Connection::Waiting => "waiting",
            Connection::Live => "live",
            Connection::Stale => "stale",
        }
    }
}

/// One point of the scope: a decimated sample and the offset that turns its time into
/// Unix time.
#[derive(Debug, Clone, Copy)]
pub struct ScopePoint {
    /// The sample as the frame carried it.
    pub point: TelemetryPoint,
    /// The frame's `unix_minus_monotonic_ns`.
    pub unix_minus_monotonic_ns: i64,
}

impl ScopePoint {
    /// The sample's Unix time, ns.
    pub fn t_unix_ns(&self) -> i128 {
        i128::from(self.point.t_sample_ns) + i128::from(self.unix_minus_monotonic_ns)
    }
}

/// The final figures of a run the rig had before its current one.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RunSummary {
    /// The run's identity (its start, Unix ns).
    pub run_id: u64,
    /// The service's process id.
    pub service_pid: u32,
    /// Its state in its newest frame (`"ended"` when it ended cleanly).
    pub run_state: &'static str,
    /// Its verdict in its newest frame.
    pub verdict: &'static str,
    /// The verdict's failure lines.
    pub verdict_text: String,
    /// The newest sample's index.
    pub last_seq: u64,
    /// Deadline misses.
    pub deadline_misses: u64,
    /// Samples lost.
    pub lost: u64,
    /// Frames the monitor received of it.
    pub frames_received: u64,
}

/// The name of a [`ipc_types::telemetry::run_state`] code.
pub fn run_state_name(code: u32) -> &'static str {
    use ipc_types::telemetry::run_state::*;
    match code {
        WAITING => "waiting",
        RUNNING => "running",
        ENDED => "ended",
        _ => "unknown",
    }
}

/// The name of a [`ipc_types::telemetry::verdict_state`] code.
pub fn verdict_name(code: u32) -> &'static str {
    use ipc_types::telemetry::verdict_state::*;
    match code {
        PENDING => "pending",
        OK => "ok",
        FAILED => "failed",
        _ => "unknown",
    }
}

/// What the monitor keeps of one rig.
#[derive(Debug)]
pub struct RigState {
    /// The rig's name.
    pub rig: String,
    /// The newest frame (boxed: it is about 30 KiB).
    pub latest: Option<Box<TelemetryFrame>>,
    /// When it arrived.
    pub latest_at: Option<Instant>,
    /// The newest info received (it may be of an earlier run than the newest frame until
    /// the service publishes the new run's).
    pub info: Option<Box<TelemetryInfo>>,
    /// Recent points, oldest first, of the current run.
    pub points: VecDeque<ScopePoint>,
    /// Earlier runs, oldest first (at most [`RUNS_KEPT`]).
    pub previous_runs: VecDeque<RunSummary>,
    /// Frames received since the monitor started.
    pub frames_received: u64,
    /// Frames of the current run received.
    pub run_frames_received: u64,
    /// Frames the monitor never saw (gaps in `frame_seq` within a run: the reader fell
    /// behind and its queue dropped the oldest).
    pub frames_lost: u64,
    /// Runs seen since the monitor started (a new `run_id`).
    pub runs_seen: u64,
    /// Times the reader subscribed to the rig's telemetry.
    pub reader_opens: u64,
    /// Why the reader could not subscribe, while it cannot.
    pub reader_error: Option<String>,
    /// Where the monitor keeps itself relative to this rig's service's real-time cores
    /// ([`super::placement`]), once it looked.
    pub placement: Option<String>,
}

impl RigState {
    /// The state of rig `rig` before any frame.
    pub fn new(rig: &str) -> Self {
        Self {
            rig: rig.to_string(),
            latest: None,
            latest_at: None,
            info: None,
            points: VecDeque::with_capacity(POINT_RING),
            previous_runs: VecDeque::new(),
            frames_received: 0,
            run_frames_received: 0,
            frames_lost: 0,
            runs_seen: 0,
            reader_opens: 0,
            reader_error: None,
            placement: None,
        }
    }

    /// Takes in `frame`, received at `now`; returns true when it started a new run.
    pub fn on_frame(&mut self, frame: &TelemetryFrame, now: Instant) -> bool {
        let mut new_run = false;
        match self.latest.as_deref() {
            Some(prev) if prev.run_id == frame.run_id => {
                if frame.frame_seq > prev.frame_seq + 1 {
                    self.frames_lost += frame.frame_seq - prev.frame_seq - 1;
                }
            }
            Some(prev) => {
                self.previous_runs.push_back(RunSummary {
                    run_id: prev.run_id,
                    service_pid: prev.service_pid,
                    run_state: run_state_name(prev.state),
                    verdict: verdict_name(prev.verdict),
                    verdict_text: prev.verdict_text().to_string(),
                    last_seq: prev.last_seq,
                    deadline_misses: prev.counters.deadline_misses,
                    lost: prev.counters.lost,
                    frames_received: self.run_frames_received,
                });
                while self.previous_runs.len() > RUNS_KEPT {
                    self.previous_runs.pop_front();
                }
                self.points.clear();
                self.run_frames_received = 0;
                self.runs_seen += 1;
                new_run = true;
            }
            None => {
                self.runs_seen += 1;
                new_run = true;
            }
        }
        for p in frame.points() {
            // Points arrive in order; a repeated or older one (never expected) is left out so
            // that `since` queries stay monotonic.
            if self.points.back().is_some_and(|b| b.point.seq >= p.seq) {
                continue;
            }
            if self.points.len() == POINT_RING {
                self.points.pop_front();
            }
            self.points.push_back(ScopePoint {
                point: *p,
                unix_minus_monotonic_ns: frame.unix_minus_monotonic_ns,
            });
        }
        match self.latest.as_deref_mut() {
            Some(l) => *l = *frame,
            None => self.latest = Some(Box::new(*frame)),
        }
        self.latest_at = Some(now);
        self.frames_received += 1;
        self.run_frames_received += 1;
        new_run
    }

    /// Takes in the run's info.
    pub fn on_info(&mut self, info: Box<TelemetryInfo>) {
        self.info = Some(info);
    }

    /// Whether frames arrive, as of `now`.
    pub fn connection(&self, now: Instant) -> Connection {
        match self.latest_at {
            None => Connection::Waiting,
            Some(t) if now.saturating_duration_since(t) > STALE_AFTER => Connection::Stale,
            Some(_) => Connection::Live,
        }
    }

    /// The info, when it is the current run's (or no frame came yet).
    pub fn current_info(&self) -> Option<&TelemetryInfo> {
        let info = self.info.as_deref()?;
        match self.latest.as_deref() {
            Some(f) if f.run_id != info.run_id => None,
            _ => Some(info),
        }
    }

    /// The points of the current run after sample `since`, oldest first, at most `max`
    /// (the newest ones when there are more).
    pub fn points_since(&self, since: Option<u64>, max: usize) -> Vec<ScopePoint> {
        let start = match since {
            Some(s) => self.points.partition_point(|p| p.point.seq <= s),
            None => 0,
        };
        let n = self.points.len() - start;
        let skip = start + n.saturating_sub(max);
        self.points.iter().skip(skip).copied().collect()
    }
}

/// Every rig's state, each behind its own lock.
#[derive(Debug)]
pub struct Hub {
    rigs: Vec<Mutex<RigState>>,
    names: Vec<String>,
}

impl Hub {
    /// A hub for `rigs` (names already checked), in that order.
    pub fn new(rigs: &[String]) -> Self {
        Self {
            rigs: rigs.iter().map(|r| Mutex::new(RigState::new(r))).collect(),
            names: rigs.to_vec(),
        }
    }

    /// The rigs' names, in order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// The index of rig `rig`.
    pub fn index(&self, rig: &str) -> Option<usize> {
        self.names.iter().position(|n| n == rig)
    }

    /// Locks rig `i`'s state (a reader that panicked leaves it usable).
    pub fn lock(&self, i: usize) -> MutexGuard<'_, RigState> {
        self.rigs[i]
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ipc_types::telemetry::run_state;

    fn frame(run_id: u64, frame_seq: u64, first_seq: u64, n: u32) -> TelemetryFrame {
        let mut f = TelemetryFrame::empty();
        f.run_id = run_id;
        f.frame_seq = frame_seq;
        f.state = run_state::RUNNING;
        f.n_points = n;
        for i in 0..n as usize {
            f.points[i].seq = first_seq + i as u64;
            f.points[i].t_sample_ns = (first_seq + i as u64) * 1_000_000;
        }
        f.last_seq = first_seq + u64::from(n).saturating_sub(1);
        f
    }

    #[test]
    fn a_new_run_id_keeps_the_old_run_and_empties_the_scope() {
        let mut s = RigState::new("a");
        let t = Instant::now();
        assert!(s.on_frame(&frame(1, 0, 0, 10), t));
        assert!(!s.on_frame(&frame(1, 1, 10, 10), t));
        assert_eq!(s.points.len(), 20);
        let mut last = frame(1, 2, 20, 0);
        last.state = run_state::ENDED;
        last.counters.deadline_misses = 4;
        assert!(!s.on_frame(&last, t));
        assert!(s.on_frame(&frame(2, 0, 0, 5), t));
        assert_eq!(s.points.len(), 5);
        assert_eq!(s.previous_runs.len(), 1);
        let r = &s.previous_runs[0];
        assert_eq!((r.run_id, r.run_state, r.deadline_misses), (1, "ended", 4));
        assert_eq!(r.frames_received, 3);
        assert_eq!(s.runs_seen, 2);
    }

    #[test]
    fn gaps_in_frame_seq_are_counted_as_lost_frames() {
        let mut s = RigState::new("a");
        let t = Instant::now();
        s.on_frame(&frame(1, 0, 0, 1), t);
        s.on_frame(&frame(1, 4, 1, 1), t);
        assert_eq!(s.frames_lost, 3);
    }

    #[test]
    fn points_since_returns_the_newer_points_capped_to_the_newest() {
        let mut s = RigState::new("a");
        s.on_frame(&frame(1, 0, 100, 50), Instant::now());
        let p = s.points_since(Some(139), 100);
        assert_eq!(p.len(), 10);
        assert_eq!(p[0].point.seq, 140);
        let p = s.points_since(None, 5);
        assert_eq!(
            p.iter().map(|p| p.point.seq).collect::<Vec<_>>(),
            [145, 146, 147, 148, 149]
        );
        assert!(s.points_since(Some(149), 10).is_empty());
    }

    #[test]
    fn the_ring_keeps_the_newest_points() {
        let mut s = RigState::new("a");
        let t = Instant::now();
        for k in 0..100u64 {
            s.on_frame(&frame(1, k, k * 128, 128), t);
        }
        assert_eq!(s.points.len(), POINT_RING);
        assert_eq!(s.points.back().map(|p| p.point.seq), Some(100 * 128 - 1));
    }

    #[test]
    fn a_rig_is_stale_a_second_after_its_newest_frame() {
        let mut s = RigState::new("a");
        let t = Instant::now();
        assert_eq!(s.connection(t), Connection::Waiting);
        s.on_frame(&frame(1, 0, 0, 1), t);
        assert_eq!(
            s.connection(t + Duration::from_millis(500)),
            Connection::Live
        );
        assert_eq!(
            s.connection(t + Duration::from_millis(1500)),
            Connection::Stale
        );
    }
}
