//! # live: the telemetry thread, which publishes the live view of a run
//!
//! The RT loop hands every sample and its state to a wait-free ring
//! ([`crate::runtime::live_tap`]). The telemetry thread — the service's non-real-time
//! helper that also drains the latency histograms ([`crate::telemetry`]) — takes them out
//! every [`FRAME_PERIOD_MS`] and publishes a [`TelemetryFrame`] on
//! `adaptive-rig/<rig>/telemetry` (the contract is [`ipc_types::telemetry`]):
//!
//! - the decimated points (`z_k`, the input given for sample `k`, `‖θ_k‖`) since the
//!   last frame, in as many frames as they need;
//! - the counters and state bits of the newest state, and the verdict as it stands:
//!   [`verdict::judge`] on the counters so far, the live tone suppression and the safe
//!   state now — the rule of the final report, on what is known so far;
//! - the latency snapshots of the histogram totals ([`TelemetryReporter::snapshots`]);
//! - the live tone fit ([`tone_fit`]).
//!
//! The run's [`TelemetryInfo`] (configuration text, tunables) is published when the
//! thread starts; when the run ends, a last frame carries the final counters and verdict
//! with [`run_state::ENDED`]. The thread runs on the non-RT cores; a reader that is slow
//! or absent costs the loop nothing, and a publisher that cannot be created (another
//! process holds the rig's telemetry) is reported once and the run goes on without it.

pub mod tone_fit;

use crate::config::ServiceConfig;
use crate::runtime::live_tap::{LiveItem, LiveState};
use crate::runtime::{LoopStats, verdict};
use crate::telemetry::{TelemetryReporter, TelemetrySummary};
use ipc_types::clock::monotonic_ns;
use ipc_types::telemetry::ports::TelemetryPublisher;
use ipc_types::telemetry::{
    FRAME_PERIOD_MS, LatencySnapshot, MAX_POINTS, MAX_TUNABLES, TelemetryCounters, TelemetryFrame,
    TelemetryInfo, TelemetryPoint, TunableInfo, run_state, set_fixed_text, verdict_state,
};
use std::sync::mpsc;
use std::time::Duration;
use tone_fit::ToneFit;

/// The run's counters in the telemetry's terms.
pub fn counters(s: &LoopStats) -> TelemetryCounters {
    TelemetryCounters {
        received: s.received,
        published: s.published,
        controller_steps: s.controller_steps,
        lost: s.skipped,
        samples_past_startup: s.samples_past_startup,
        lost_past_startup: s.lost_past_startup,
        held_past_startup: s.held_past_startup,
        caught_up: s.caught_up,
        rejected: s.rejected_contract
            + s.rejected_non_finite
            + s.rejected_out_of_range
            + s.rejected_duplicate
            + s.rejected_backward
            + s.rejected_jump,
        deadline_misses: s.deadline_misses,
        plant_reported_misses: s.plant_reported_misses,
        plan_covered_misses: s.plan_covered_misses,
        max_consecutive_misses: s.max_consecutive_misses,
        safe_state_entries: s.safe_state_entries,
        safe_state_cycles: s.safe_state_cycles,
        plant_silent_events: s.plant_silent_events,
        new_sessions: s.new_sessions,
        saturated_cycles: s.saturated_cycles,
        controller_faults: s.controller_faults,
        fallback_cycles: s.fallback_cycles,
        publish_failures: s.publish_failures,
        foreign_samples: s.foreign_samples,
        commands_applied: s.commands_applied,
        commands_refused: s.commands_refused,
        telemetry_dropped: s.telemetry_dropped,
    }
}

/// What the run's end gives the last frame.
#[derive(Debug, Clone)]
pub struct FinalFigures {
    /// The final counters.
    pub stats: LoopStats,
    /// The final verdict.
    pub verdict: verdict::RunVerdict,
}

/// The live view's state on the telemetry thread.
pub struct LiveView {
    publisher: Option<TelemetryPublisher>,
    rx: rtrb::Consumer<LiveItem>,
    frame: Box<TelemetryFrame>,
    info: Box<TelemetryInfo>,
    points: Vec<TelemetryPoint>,
    tones: ToneFit,
    state: Option<LiveState>,
    limits: verdict::Limits,
    open_loop_cycles: u64,
    latency: [LatencySnapshot; 4],
    intervals_seen: u64,
    /// Frames that could not be published.
    pub publish_failures: u64,
}

impl std::fmt::Debug for LiveView {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LiveView")
            .field("frame_seq", &self.frame.frame_seq)
            .finish()
    }
}

impl LiveView {
    /// The live view of a run of `cfg` writing into `run_folder` with a controller of
    /// `kind` whose tunables have the values `tunable_values`, fed by `rx`; publishes the
    /// run's info. Returns a warning when the telemetry services cannot be opened (the
    /// view then publishes nothing).
    pub fn new(
        cfg: &ServiceConfig,
        run_folder: &std::path::Path,
        kind: &str,
        rx: rtrb::Consumer<LiveItem>,
    ) -> (Self, Option<String>) {
        let (publisher, warning) = match TelemetryPublisher::create(&cfg.rig) {
            Ok(p) => (Some(p), None),
            Err(e) => (None, Some(format!("telemetry not published: {e}"))),
        };
        let run_id = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos() as u64)
            .unwrap_or(0);
        let mut frame = Box::new(TelemetryFrame::empty());
        frame.run_id = run_id;
        frame.service_pid = std::process::id();
        frame.n_z = cfg.counts.n_z;
        frame.n_u = cfg.counts.n_u;
        frame.n_tunables = cfg.live.tunables.len().min(MAX_TUNABLES) as u32;
        let mut info = Box::new(TelemetryInfo::empty());
        info.service_pid = frame.service_pid;
        info.run_id = run_id;
        info.sample_period_ns = cfg.sample_period_ns;
        info.budget_ns = cfg.budget_ns;
        info.counts = cfg.counts;
        info.timing = cfg.answer.timing.wire();
        info.n_tunables = frame.n_tunables;
        for (slot, t) in info.tunables.iter_mut().zip(&cfg.live.tunables) {
            let mut name = [0u8; 32];
            set_fixed_text(&mut name, &t.name);
            *slot = TunableInfo {
                name,
                min: t.min,
                max: t.max,
                initial: t.initial,
            };
        }
        set_fixed_text(&mut info.rig, &cfg.rig);
        set_fixed_text(&mut info.controller, kind);
        set_fixed_text(&mut info.run_folder, &run_folder.display().to_string());
        set_fixed_text(&mut info.config_path, &cfg.origin);
        info.set_config_text(&cfg.source.text);
        let view = Self {
            publisher,
            rx,
            frame,
            info,
            points: Vec::with_capacity(4 * MAX_POINTS),
            tones: ToneFit::new(
                &cfg.tone_report.tones_hz,
                cfg.counts.n_z as usize,
                cfg.sample_period_ns as f64 * 1e-9,
                cfg.live.tone_window_cycles as usize,
            ),
            state: None,
            limits: verdict::Limits::of(cfg),
            open_loop_cycles: cfg.open_loop_cycles,
            latency: [LatencySnapshot::default(); 4],
            intervals_seen: u64::MAX,
            publish_failures: 0,
        };
        if let Some(p) = &view.publisher {
            p.publish_info(&view.info);
        }
        (view, warning)
    }

    /// Takes what the loop queued and publishes the frames it makes, with the latency
    /// snapshots of `reporter`'s totals.
    pub fn poll(&mut self, reporter: &TelemetryReporter) {
        if reporter.intervals() != self.intervals_seen {
            self.intervals_seen = reporter.intervals();
            self.latency = reporter.snapshots();
        }
        while let Ok(item) = self.rx.pop() {
            match item {
                LiveItem::Sample(s) => {
                    self.tones.push(s.seq, &s.z, s.status);
                    if s.point {
                        self.points.push(TelemetryPoint {
                            seq: s.seq,
                            t_sample_ns: s.t_sample_ns,
                            status: s.status,
                            flags: s.flags,
                            theta_norm: s.theta_norm,
                            z: s.z,
                            u: s.u,
                        });
                    }
                }
                LiveItem::State(st) => self.state = Some(st),
            }
        }
        let (state, flags) = match &self.state {
            Some(st) if st.stats.received > 0 => (run_state::RUNNING, st.flags),
            Some(st) => (run_state::WAITING, st.flags),
            None => (run_state::WAITING, 0),
        };
        let judged = self.state.as_ref().map(|st| {
            let v = verdict::judge(&verdict::VerdictInputs {
                stats: st.stats,
                safe_state_at_end: st.safe_state,
                limits: self.limits,
                open_loop_cycles: self.open_loop_cycles,
                log_dropped: 0,
                adaptation: None,
                suppression_db: self.tones.suppression_db(),
                throttled_busy_poll: None,
                rt_core_steal: None,
            });
            (st.stats, st.last_seq, st.tunables, v)
        });
        match judged {
            Some((stats, last_seq, tunables, v)) => {
                self.frame.counters = counters(&stats);
                self.frame.last_seq = last_seq;
                self.frame.tunable_values = tunables;
                let pending = stats.samples_past_startup == 0;
                self.set_verdict(&v, pending);
            }
            None => {
                let none = verdict::RunVerdict {
                    ok: true,
                    failures: Vec::new(),
                    warnings: Vec::new(),
                };
                self.set_verdict(&none, true);
            }
        }
        self.frame.state = state;
        self.frame.flags = flags;
        self.publish_points();
    }

    /// Publishes the last frame: the final counters and verdict, [`run_state::ENDED`].
    pub fn finish(&mut self, fin: &FinalFigures) {
        self.frame.counters = counters(&fin.stats);
        self.frame.state = run_state::ENDED;
        self.set_verdict(&fin.verdict, false);
        self.publish_points();
    }

    fn set_verdict(&mut self, v: &verdict::RunVerdict, pending: bool) {
        self.frame.verdict = if pending {
            verdict_state::PENDING
        } else if v.ok {
            verdict_state::OK
        } else {
            verdict_state::FAILED
        };
        set_fixed_text(&mut self.frame.verdict_text, &v.failures.join("\n"));
    }

    /// Publishes the points gathered, [`MAX_POINTS`] per frame (one frame without any).
    fn publish_points(&mut self) {
        let tones = *self.tones.snapshot();
        self.frame.tones = tones;
        self.frame.latency = self.latency;
        let now = monotonic_ns();
        let unix = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos() as i64)
            .unwrap_or(0);
        self.frame.unix_minus_monotonic_ns = unix - now as i64;
        let mut start = 0;
        loop {
            let end = (start + MAX_POINTS).min(self.points.len());
            let chunk = &self.points[start..end];
            self.frame.n_points = chunk.len() as u32;
            self.frame.points[..chunk.len()].copy_from_slice(chunk);
            self.frame.t_publish_ns = monotonic_ns();
            if let Some(p) = &self.publisher
                && !p.publish(&self.frame)
            {
                self.publish_failures += 1;
            }
            self.frame.frame_seq += 1;
            start = end;
            if start >= self.points.len() {
                break;
            }
        }
        self.points.clear();
    }
}

/// What the run's thread asks of the telemetry thread.
enum Request {
    /// Drain the histograms and give back their summary and the thread's CPU time so far.
    Finish(mpsc::Sender<(std::io::Result<TelemetrySummary>, f64)>),
    /// Publish the last frame and end.
    Final(Box<FinalFigures>),
}

/// The run's handle on the telemetry thread.
#[derive(Debug)]
pub struct LiveThread {
    requests: mpsc::Sender<Request>,
    handle: std::thread::JoinHandle<()>,
}

impl LiveThread {
    /// Starts the telemetry thread: it drains `reporter` and, when `live` is given (the
    /// ring's consumer; `service.telemetry.enabled`), publishes the live view of the run
    /// of `cfg` in `run_folder` with a controller of `kind`. A warning (the telemetry
    /// services could not be opened) is printed by the thread.
    pub fn spawn(
        cfg: &ServiceConfig,
        run_folder: &std::path::Path,
        kind: &str,
        reporter: TelemetryReporter,
        live: Option<rtrb::Consumer<LiveItem>>,
    ) -> std::io::Result<Self> {
        let (tx, rx) = mpsc::channel();
        let cfg = cfg.clone();
        let folder = run_folder.to_path_buf();
        let kind = kind.to_string();
        let handle = std::thread::Builder::new()
            .name("telemetry".into())
            .spawn(move || {
                let mut view = live.map(|rx| {
                    let (view, warning) = LiveView::new(&cfg, &folder, &kind, rx);
                    if let Some(w) = warning {
                        eprintln!("[service] WARNING: {w}");
                    }
                    view
                });
                let period = Duration::from_millis(FRAME_PERIOD_MS);
                let mut reporter = Some(reporter);
                let poll = |reporter: &mut TelemetryReporter, view: &mut Option<LiveView>| {
                    if let Err(e) = reporter.poll() {
                        eprintln!("[service] histogram log write failed: {e}");
                    }
                    if let Some(v) = view.as_mut() {
                        v.poll(reporter);
                    }
                };
                loop {
                    match rx.recv_timeout(period) {
                        Ok(Request::Finish(back)) => {
                            if let Some(mut r) = reporter.take() {
                                poll(&mut r, &mut view);
                                let summary = r.finish();
                                let cpu_s = crate::scheduling::watch::thread_cpu_ns() as f64 * 1e-9;
                                let _ = back.send((summary, cpu_s));
                            }
                        }
                        Ok(Request::Final(fin)) => {
                            if let Some(v) = view.as_mut() {
                                v.finish(&fin);
                            }
                            return;
                        }
                        Err(mpsc::RecvTimeoutError::Disconnected) => return,
                        Err(mpsc::RecvTimeoutError::Timeout) => {
                            if let Some(r) = reporter.as_mut() {
                                poll(r, &mut view);
                            }
                        }
                    }
                }
            })?;
        Ok(Self {
            requests: tx,
            handle,
        })
    }

    /// Drains the histograms (after the RT thread handed its last box back) and returns
    /// their summary, and the CPU time the telemetry thread used so far, s.
    pub fn finish_histograms(&self) -> (std::io::Result<TelemetrySummary>, f64) {
        let (tx, rx) = mpsc::channel();
        let gone = || std::io::Error::other("the telemetry thread ended early");
        if self.requests.send(Request::Finish(tx)).is_err() {
            return (Err(gone()), f64::NAN);
        }
        rx.recv().unwrap_or_else(|_| (Err(gone()), f64::NAN))
    }

    /// Publishes the last frame and joins the thread.
    pub fn end(self, fin: FinalFigures) {
        let _ = self.requests.send(Request::Final(Box::new(fin)));
        let _ = self.handle.join();
    }
}
