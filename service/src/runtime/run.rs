//! One run of the service: everything that allocates is built here (the controller, the
//! histogram boxes, the log and event queues), the helper threads are started off the RT
//! core, the RT thread is started and joined, and the run report is assembled.

use super::checkpoint::Checkpoint;
use super::checkpoint_slot::{CheckpointMark, CheckpointSlot};
use super::rt_thread::rt_thread_main;
use super::{AdaptationReport, CheckpointReport, LoopCore, LoopEvent, RunReport, ServiceError};
use super::{checkpoint, live_tap, operator, verdict};
use crate::config::{ServiceConfig, WaitMode};
use crate::live::{FinalFigures, LiveThread};
use crate::logging::{self, LogLayout};
use crate::operator::OperatorThread;
use crate::record::{self, RecordHeader};
use crate::telemetry;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

/// Options of one run that do not belong in the configuration file.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Overrides `service.run-dir`: the folder this run writes into (created).
    pub run_folder: Option<PathBuf>,
    /// Stop when the plant sends its last sample.
    pub exit_with_plant: bool,
    /// Stop after this many received samples.
    pub max_cycles: Option<u64>,
    /// Overrides `service.wait`.
    pub wait: Option<WaitMode>,
    /// Overrides `service.core`.
    pub core: Option<usize>,
    /// Start the controller from this checkpoint ([`checkpoint`]).
    pub warm_start: Option<PathBuf>,
}

/// Runs the service with `cfg` until a signal sets `shutdown`, the plant ends (with
/// `exit_with_plant`), or `max_cycles` samples have been received. Prints events as they
/// happen; returns the report, which the caller prints and then writes
/// ([`RunReport::write_json`]).
pub fn run(
    cfg: &ServiceConfig,
    opts: &RunOptions,
    shutdown: Arc<AtomicBool>,
) -> Result<RunReport, ServiceError> {
    let mut cfg = cfg.clone();
    if let Some(w) = opts.wait {
        cfg.wait = w;
    }
    if let Some(c) = opts.core {
        cfg.rt.core = Some(c);
    }
    let folder = match &opts.run_folder {
        Some(f) => f.clone(),
        None => cfg.run_dir.join(format!("{}-{}", cfg.rig, timestamp())),
    };
    std::fs::create_dir_all(&folder).map_err(|error| ServiceError::Io {
        what: format!("creating run folder {}", folder.display()),
        error,
    })?;
    let mut controller = cfg
        .controller
        .build(cfg.counts)
        .map_err(ServiceError::Controller)?;
    let warm_start = match &opts.warm_start {
        Some(path) => Some(
            checkpoint::warm_start(path, &cfg, &mut *controller)
                .map_err(ServiceError::Checkpoint)?,
        ),
        None => None,
    };
    let checkpoint_slot = Arc::new(CheckpointSlot::new(&*controller));
    let mut checkpoints = CheckpointWriter::new(folder.join("checkpoint.json"));
    let controller_kind = controller.kind();
    let internal_names = controller.internal_names();

    let (tele_rt, tele_reporter) =
        telemetry::channel(cfg.budget_ns, cfg.histogram_interval_cycles, 4, &folder).map_err(
            |error| ServiceError::Io {
                what: "creating histogram logs".into(),
                error,
            },
        )?;
    let (log_producer, log_writer) = if cfg.log.enabled {
        let layout = LogLayout {
            n_y: cfg.counts.n_y as usize,
            n_z: cfg.counts.n_z as usize,
            n_u: cfg.counts.n_u as usize,
            internal_names,
            decimation: cfg.log.decimation,
        };
        let (p, w) = logging::channel(cfg.log.queue_capacity, layout);
        (Some(p), Some(w))
    } else {
        (None, None)
    };
    let (event_tx, mut event_rx) = rtrb::RingBuffer::<LoopEvent>::new(1024);
    let rt_core = cfg.rt.core;

    // Helper threads inherit this thread's affinity and policy: off the RT core, normal
    // priority. The RT thread pins itself afterwards.
    ipc_types::rt::keep_off_core(rt_core);
    let sched_watch = crate::scheduling::RunWatch::start(rt_core);
    let rt_probe = sched_watch.probe();
    let log_handle = match log_writer {
        Some(w) => Some(
            w.spawn(folder.join("signals.csv"))
                .map_err(|error| ServiceError::Io {
                    what: "starting the CSV writer".into(),
                    error,
                })?,
        ),
        None => None,
    };
    // The live view's ring: half a second of samples, at least 8192 (a lockstep plant
    // runs faster than real time); the state every 10 ms of plant time.
    let rate = 1e9 / cfg.sample_period_ns as f64;
    let (live_tap, live_rx) = if cfg.live.telemetry {
        let (tap, rx) = live_tap::channel(
            ((rate * 0.5) as usize).clamp(8192, 1 << 15),
            cfg.live.point_every,
            (rate / 100.0).round().max(1.0) as u64,
        );
        (Some(tap), Some(rx))
    } else {
        (None, None)
    };
    let live = LiveThread::spawn(&cfg, &folder, controller_kind, tele_reporter, live_rx).map_err(
        |error| ServiceError::Io {
            what: "starting the telemetry thread".into(),
            error,
        },
    )?;
    let (operator_outbox, operator_inbox) = operator::channel();
    let operator_thread =
        OperatorThread::spawn(&cfg, operator_outbox).map_err(|error| ServiceError::Io {
            what: "starting the operator thread".into(),
            error,
        })?;

    let mut core = LoopCore::new(&cfg, controller, tele_rt, log_producer, event_tx)
        .with_checkpoints(checkpoint_slot.clone());
    if let Some(tap) = live_tap {
        core = core.with_live(tap);
    }
    if cfg.live.commands {
        core = core.with_operator(operator_inbox);
    }
    let record_handle = if cfg.log.record {
        // The warm start's checkpoint goes with the record: checkpoint.json is overwritten
        // by this run.
        let warm_copy = match &opts.warm_start {
            Some(path) => {
                let name = "warm-start.json";
                std::fs::copy(path, folder.join(name)).map_err(|error| ServiceError::Io {
                    what: format!(
                        "copying the warm-start checkpoint {} into the run folder",
                        path.display()
                    ),
                    error,
                })?;
                Some(name.to_string())
            }
            None => None,
        };
        let header = RecordHeader::for_run(
            &cfg,
            controller_kind,
            core.timing(),
            core.plan_length(),
            warm_copy,
        );
        let (recorder, writer) = record::channel(&header, cfg.log.queue_capacity);
        let handle = writer
            .spawn(&folder.join(record::FILE_NAME))
            .map_err(|error| ServiceError::Io {
                what: "starting the record writer".into(),
                error,
            })?;
        core = core.with_recorder(recorder);
        Some(handle)
    } else {
        None
    };
    let rt_cfg = cfg.clone();
    let rt_shutdown = shutdown.clone();
    let max_cycles = opts.max_cycles;
    let exit_with_plant = opts.exit_with_plant;
    let rt_thread = std::thread::Builder::new()
        .name("rt-loop".into())
        .spawn(move || {
            rt_probe.register();
            rt_thread_main(
                rt_cfg,
                core,
                rt_shutdown,
                max_cycles,
                exit_with_plant,
                &rt_probe,
            )
        })
        .map_err(|error| ServiceError::Io {
            what: "starting the RT thread".into(),
            error,
        })?;

    // Supervise: print events while the RT thread runs.
    let mut events = Vec::new();
    let mut drain = |events: &mut Vec<LoopEvent>| {
        while let Ok(e) = event_rx.pop() {
            eprintln!("[service] {e}");
            events.push(e);
        }
    };
    while !rt_thread.is_finished() {
        drain(&mut events);
        if let Some((mark, blocks)) = checkpoint_slot.take() {
            checkpoints.write(&Checkpoint::new(&cfg, controller_kind, mark, blocks));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let rt_result = rt_thread
        .join()
        .map_err(|_| ServiceError::RtThread("panicked".into()))?;
    drain(&mut events);
    let scheduling = sched_watch.finish();
    let operator_commands = operator_thread.finish();
    let (mut core, setup, stop_reason) = match rt_result {
        Ok(r) => r,
        Err(e) => {
            let _ = live.finish_histograms();
            return Err(e);
        }
    };
    core.flush_telemetry();
    if !checkpoint_slot.is_empty() {
        // The final state, whatever the periodic ones were.
        let mark = CheckpointMark {
            seq: core.last_seq().unwrap_or(0),
            plant_session: core.stats.new_sessions + 1,
        };
        let blocks = checkpoint_slot.snapshot(core.controller());
        if blocks.iter().all(|(_, v)| v.iter().all(|x| x.is_finite())) {
            checkpoints.write(&Checkpoint::new(&cfg, controller_kind, mark, blocks));
        } else {
            checkpoints.note_failure("the final learned state is not finite; not written".into());
        }
    }
    let (latency, telemetry_cpu_s) = live.finish_histograms();
    let latency = latency.map_err(|error| ServiceError::Io {
        what: "writing histogram files".into(),
        error,
    })?;
    let mut warnings = Vec::new();
    let log = match log_handle.map(|h| h.finish()) {
        Some(Ok(st)) => LogOutcome {
            written: st.written,
            dropped: st.dropped,
            lost_to_disk: st.lost_to_disk,
            first_error: st.first_error,
            intact: st.intact,
        },
        Some(Err(e)) => {
            warnings.push(format!("the signal log writer failed: {e}"));
            LogOutcome {
                intact: false,
                first_error: Some(e.to_string()),
                ..LogOutcome::default()
            }
        }
        None => LogOutcome::default(),
    };
    let record = match record_handle.map(|h| h.finish()) {
        Some(Ok(st)) => Some(st),
        Some(Err(e)) => {
            warnings.push(format!("the record writer failed: {e}"));
            None
        }
        None => None,
    };
    if let Some(r) = record.as_ref().filter(|r| !r.complete) {
        warnings.push(format!(
            "{}: incomplete ({} of {} entries written, {} dropped (queue full), {} lost to \
             the disk{}); a replay stops at the first gap",
            r.path,
            r.written,
            r.entries,
            r.dropped,
            r.lost_to_disk,
            r.first_error
                .as_deref()
                .map(|e| format!(": {e}"))
                .unwrap_or_default()
        ));
    }
    if let Some(e) = &log.first_error {
        warnings.push(format!(
            "signals.csv: {} records lost to the disk{}: {e}",
            log.lost_to_disk,
            if log.intact {
                ""
            } else {
                " and the file may end in a torn row"
            }
        ));
    }
    for f in &latency.file_errors {
        warnings.push(format!(
            "{}: {} records lost{}",
            f.path,
            f.records_lost,
            f.first_error
                .as_deref()
                .map(|e| format!(": {e}"))
                .unwrap_or_default()
        ));
    }
    let (z_rms, z_rms_settled) = core.z_rms();
    if setup.any_refused() {
        warnings.push(format!("real-time set-up incomplete: {}", setup.describe()));
    }
    let throttled_busy_poll = cfg
        .throttled_busy_poll()
        .filter(|_| setup.fifo == ipc_types::rt::StepOutcome::Done);
    let tones = core.tones.report();
    let adaptation = core.controller().adaptation();
    let verdict = verdict::judge(&verdict::VerdictInputs {
        stats: core.stats,
        safe_state_at_end: core.safe_state_at_end(),
        limits: verdict::Limits::of(&cfg),
        open_loop_cycles: cfg.open_loop_cycles,
        log_dropped: log.dropped + log.lost_to_disk,
        adaptation: adaptation.clone(),
        suppression_db: tones
            .as_ref()
            .map(|t| t.tones.iter().map(|l| (l.hz, l.suppression_db)).collect())
            .unwrap_or_default(),
        throttled_busy_poll,
        rt_core_steal: scheduling.steal.rt_core_s.zip(scheduling.loop_s),
    });
    warnings.extend(verdict.warnings.iter().cloned());
    if let Some(w) = core.pacing.throttling_risk() {
        warnings.push(w);
    }
    if let Some(e) = &checkpoints.first_error {
        warnings.push(format!(
            "checkpoint: {} of {} writes failed: {e}",
            checkpoints.failures,
            checkpoints.failures + checkpoints.written
        ));
    }
    if let Some(w) = warm_start.as_ref().filter(|w| !w.same_controller_table) {
        warnings.push(format!(
            "warm start from {}: its [controller] table differs from this run's (the shapes \
             match, a value changed)",
            w.path
        ));
    }
    let report = RunReport {
        rig: cfg.rig.clone(),
        config: cfg.origin.clone(),
        run_folder: folder.display().to_string(),
        controller: controller_kind.to_string(),
        wait: format!("{:?}", cfg.wait),
        timing: core.timing().name().to_string(),
        plan_length: core.plan_length(),
        plan_source: core.plan_source().map(str::to_string),
        rt_setup: setup.describe(),
        rt_degraded: setup.any_refused(),
        warnings,
        verdict,
        stop_reason,
        stats: core.stats,
        events,
        z_rms,
        z_rms_settled,
        latency,
        log_written: log.written,
        log_dropped: log.dropped,
        log_lost_to_disk: log.lost_to_disk,
        log_first_error: log.first_error,
        record,
        budget_ns: cfg.budget_ns,
        sample_period_s: cfg.sample_period_ns as f64 * 1e-9,
        open_loop_s: cfg.open_loop_cycles as f64 * cfg.sample_period_ns as f64 * 1e-9,
        rt_allocations: core.rt_allocations,
        pacing: core.pacing,
        tones,
        adaptation: adaptation.map(AdaptationReport::from),
        model_following: core.following.report(),
        force_regulation: core.force.report(),
        system: crate::system_check::check_system(
            &crate::system_check::SystemRoot::live(),
            cfg.rt.core,
        ),
        checkpoint: (!checkpoint_slot.is_empty()).then(|| CheckpointReport {
            path: checkpoints.path.display().to_string(),
            written: checkpoints.written,
            failures: checkpoints.failures,
            first_error: checkpoints.first_error.clone(),
            last_seq: checkpoints.last_seq,
            warm_start: warm_start.clone(),
        }),
        scheduling,
        controller_counters: core
            .controller()
            .counters()
            .into_iter()
            .map(|(k, v)| (k.to_string(), v))
            .collect(),
        operator_commands,
        telemetry_cpu_s,
    };
    live.end(FinalFigures {
        stats: report.stats,
        verdict: report.verdict.clone(),
    });
    Ok(report)
}

/// Writes the checkpoints the loop hands over and counts what happened.
struct CheckpointWriter {
    path: PathBuf,
    written: u64,
    failures: u64,
    first_error: Option<String>,
    last_seq: Option<u64>,
}

impl CheckpointWriter {
    fn new(path: PathBuf) -> Self {
        Self {
            path,
            written: 0,
            failures: 0,
            first_error: None,
            last_seq: None,
        }
    }

    fn write(&mut self, c: &Checkpoint) {
        match c.write(&self.path) {
            Ok(()) => {
                self.written += 1;
                self.last_seq = Some(c.seq);
            }
            Err(e) => {
                if self.first_error.is_none() {
                    eprintln!("[service] checkpoint: {e}");
                }
                self.note_failure(e);
            }
        }
    }

    fn note_failure(&mut self, e: String) {
        self.failures += 1;
        self.first_error.get_or_insert(e);
    }
}

/// What the signal-log writer reported at the end.
#[derive(Debug, Default)]
struct LogOutcome {
    written: u64,
    dropped: u64,
    lost_to_disk: u64,
    first_error: Option<String>,
    intact: bool,
}

fn timestamp() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    format!("{secs}-{}", std::process::id())
}
