//! # replay: a recorded run re-run offline, compared bit for bit
//!
//! `service replay RUN_FOLDER` reads `record.bin` ([`crate::record`]), rebuilds the
//! configuration from the text the record keeps (relative file names resolved from the
//! recorded folder; the rebuilt configuration must have the recorded fingerprint), builds
//! the controller (from the warm-start checkpoint copied into the run folder, if the run
//! had one), and drives the same [`LoopCore`] as the real-time loop with the recorded
//! calls, in order: `handle(m, t_recv)`, `observe(m)`, `note_new_peer()`,
//! `on_idle(t)`. Its [`outbox::ReplayOutbox`] takes each actuation the loop publishes
//! against the next recorded one and hands back what the real publisher returned then
//! (sent or not, and its time), so that the deadline policy sees the same response
//! times. Every field of every actuation is compared bit for bit except the two clock
//! readings (`t_publish_ns`, `compute_ns`); the first difference, or an actuation only one
//! side has, stops the replay and is reported with the sample it answered. A gap or a
//! truncated end of the record stops it too: what came before is compared, and the summary
//! says where the record is incomplete.
//!
//! With `--controller FILE` (the scenario's `[controller]` replaced) or `--scenario FILE`
//! (another scenario), the replay is open loop: the new loop gets the logged inputs
//! (which the logged controller caused), and [`comparison::Comparison`] writes one row per
//! actuation with `u` logged, `u` replayed and their difference, and sums up the RMS and
//! largest difference and the first sample where they diverge.

pub mod comparison;
pub mod difference;
pub mod outbox;
pub mod summary;

use crate::config::{ConfigError, ServiceConfig};
use crate::record::{Entry, RecordError, RecordHeader, RecordReader, config_fingerprint};
use crate::runtime::operator::{Command, Queued};
use crate::runtime::{LoopCore, checkpoint};
use comparison::Comparison;
use outbox::{Compare, ReplayOutbox, Stop};
use std::fmt;
use std::path::{Path, PathBuf};
use summary::ReplaySummary;

/// What to replay and against what.
#[derive(Debug, Clone, Default)]
pub struct ReplayOptions {
    /// The run folder (its `record.bin`).
    pub run_folder: PathBuf,
    /// Replace the recorded `[controller]` (and `[log]`) table by this file's: open loop.
    pub controller: Option<PathBuf>,
    /// Rebuild from this scenario instead of the recorded text: open loop.
    pub scenario: Option<PathBuf>,
    /// The comparison CSV of an open-loop replay (default
    /// `<run folder>/replay-comparison.csv`).
    pub comparison: Option<PathBuf>,
}

/// Why a replay could not be done at all.
#[derive(Debug)]
pub enum ReplayError {
    /// The record cannot be opened or its header read.
    Record(RecordError),
    /// The configuration cannot be rebuilt.
    Config(ConfigError),
    /// The rebuilt configuration does not match the record (fingerprint, channels).
    Mismatch(String),
    /// The controller or its warm start cannot be built.
    Controller(String),
    /// The comparison CSV cannot be written.
    Output(String),
}

impl fmt::Display for ReplayError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReplayError::Record(e) => write!(f, "{e}"),
            ReplayError::Config(e) => write!(f, "configuration refused: {e}"),
            ReplayError::Mismatch(m) | ReplayError::Controller(m) | ReplayError::Output(m) => {
                write!(f, "{m}")
            }
        }
    }
}

impl std::error::Error for ReplayError {}

/// The configuration to replay with, and whether it is the recorded one.
fn rebuild(
    header: &RecordHeader,
    record: &Path,
    opts: &ReplayOptions,
) -> Result<(ServiceConfig, bool), ReplayError> {
    let recorded_origin = format!(
        "{} (recorded from {})",
        record.display(),
        header.config_origin
    );
    let cfg = match (&opts.scenario, &opts.controller) {
        (None, None) => ServiceConfig::parse_in(
            &header.config_text,
            &recorded_origin,
            Path::new(&header.config_base_dir),
        ),
        (None, Some(c)) => {
            ServiceConfig::parse_with_controller(&header.config_text, &recorded_origin, c)
        }
        (Some(s), c) => ServiceConfig::load_scenario(s, c.as_deref()),
    }
    .map_err(ReplayError::Config)?;
    let recorded = opts.scenario.is_none() && opts.controller.is_none();
    if recorded && config_fingerprint(&cfg) != header.config_fingerprint {
        return Err(ReplayError::Mismatch(format!(
            "{}: the recorded configuration rebuilds differently (fingerprint {}, recorded {}): \
             a file it names (in {}) has changed; give --scenario or --controller to compare \
             open loop",
            record.display(),
            config_fingerprint(&cfg),
            header.config_fingerprint,
            header.config_base_dir
        )));
    }
    let layout = header.layout();
    if cfg.counts != layout.counts {
        return Err(ReplayError::Mismatch(format!(
            "{}: channels {:?}, the record has {:?}",
            cfg.origin, cfg.counts, layout.counts
        )));
    }
    Ok((cfg, recorded))
}

/// Replays the record of `opts.run_folder` (module docs).
///
/// # Errors
///
/// A record that cannot be opened, a configuration that cannot be rebuilt or does not
/// match it, a controller or warm start that cannot be built, a comparison file that
/// cannot be written. A difference or an incomplete record is not an error: the summary
/// says so ([`ReplaySummary::exit_code`]).
pub fn replay(opts: &ReplayOptions) -> Result<ReplaySummary, ReplayError> {
    let path = opts.run_folder.join(crate::record::FILE_NAME);
    let mut reader = RecordReader::open(&path).map_err(ReplayError::Record)?;
    let header = reader.header().clone();
    let (cfg, recorded) = rebuild(&header, &path, opts)?;
    let mut controller = cfg
        .controller
        .build(cfg.counts)
        .map_err(|e| ReplayError::Controller(format!("{}: controller: {e}", cfg.origin)))?;
    if let Some(name) = &header.warm_start {
        let warm = opts.run_folder.join(name);
        match checkpoint::warm_start(&warm, &cfg, &mut *controller) {
            Ok(_) => {}
            Err(e) if recorded => return Err(ReplayError::Controller(e)),
            Err(e) => {
                eprintln!(
                    "[replay] the run's warm start does not fit this controller ({e}); it starts fresh"
                );
                controller = cfg
                    .controller
                    .build(cfg.counts)
                    .map_err(ReplayError::Controller)?;
            }
        }
    }
    let (tele, _reporter) =
        crate::telemetry::channel_in_memory(cfg.budget_ns, cfg.histogram_interval_cycles, 1);
    let (events_tx, mut events_rx) = rtrb::RingBuffer::new(4096);
    let mut core = LoopCore::new(&cfg, controller, tele, None, events_tx);
    core.prepare_controller_thread();
    if recorded && core.timing().name() != header.timing {
        return Err(ReplayError::Mismatch(format!(
            "{}: the rebuilt loop runs {}, the record {}",
            path.display(),
            core.timing().name(),
            header.timing
        )));
    }
    let mut comparison = if recorded {
        None
    } else {
        let out = opts
            .comparison
            .clone()
            .unwrap_or_else(|| opts.run_folder.join("replay-comparison.csv"));
        Some(Comparison::create(&out, cfg.counts.n_u as usize).map_err(ReplayError::Output)?)
    };
    let start = std::time::Instant::now();
    let mut summary = ReplaySummary {
        record: path.display().to_string(),
        recorded: format!(
            "rig '{}', controller {} ({}, plans of {}), sample period {} ns",
            header.rig,
            header.controller,
            header.timing,
            header.plan_length,
            header.sample_period_ns
        ),
        configuration: if recorded {
            "as recorded".to_string()
        } else {
            cfg.origin.clone()
        },
        samples_handled: 0,
        samples_observed: 0,
        sessions: (0, 0),
        commands: 0,
        actuations: 0,
        stop: None,
        last_seq: None,
        comparison: None,
        elapsed_s: 0.0,
    };
    let n_u = cfg.counts.n_u as usize;
    let mut out = ReplayOutbox {
        reader: &mut reader,
        compare: match comparison.as_mut() {
            Some(c) => Compare::OpenLoop(c),
            None => Compare::BitForBit,
        },
        n_u,
        t_recv_ns: 0,
        compared: 0,
        stop: None,
    };
    loop {
        let next = match out.reader.next_entry() {
            Ok(Some(l)) => l,
            Ok(None) => break,
            Err(e) => {
                out.stop = Some(Stop::Record(e));
                break;
            }
        };
        match next.entry {
            Entry::Handle { m, t_recv_ns } => {
                out.t_recv_ns = t_recv_ns;
                core.handle(&m, t_recv_ns, &mut out);
                summary.samples_handled += 1;
                summary.last_seq = Some(m.seq);
            }
            Entry::Observe { m } => {
                core.observe(&m, &mut out);
                summary.samples_observed += 1;
                summary.last_seq = Some(m.seq);
            }
            Entry::NewPeer => {
                core.note_new_peer();
                summary.sessions.0 += 1;
            }
            Entry::WentSilent { now_ns } => {
                core.on_idle(now_ns);
                summary.sessions.1 += 1;
            }
            Entry::Operator {
                request_id,
                command,
                index,
                value,
            } => match Command::from_code(command, index as usize, value) {
                Some(command) => {
                    core.apply_command(Queued {
                        request_id,
                        command,
                    });
                    summary.commands += 1;
                }
                None => {
                    out.stop = Some(Stop::Record(crate::record::RecordError::NotARecord {
                        path: path.display().to_string(),
                        why: format!(
                            "entry {} is an operator command of unknown code {command}",
                            next.index
                        ),
                    }));
                }
            },
            Entry::End => break,
            Entry::Publish { act, .. } => {
                // Not taken by the loop's publications of the previous input.
                if out.stop.is_none() {
                    match &mut out.compare {
                        Compare::BitForBit => {
                            out.stop = Some(Stop::Differ {
                                index: next.index,
                                offset: next.offset,
                                reply_to: act.reply_to,
                                seq: act.seq,
                                what: difference::Difference {
                                    field: "actuation".into(),
                                    logged: format!(
                                        "one for sample {} (status {})",
                                        act.seq, act.status
                                    ),
                                    replayed: "none published here".into(),
                                },
                            });
                        }
                        Compare::OpenLoop(c) => c.only_logged(),
                    }
                }
            }
        }
        while events_rx.pop().is_ok() {}
        if out.stop.is_some() {
            break;
        }
    }
    summary.actuations = out.compared;
    summary.stop = out.stop.take();
    summary.elapsed_s = start.elapsed().as_secs_f64();
    if let Some(c) = comparison {
        summary.comparison = Some(c.finish().map_err(ReplayError::Output)?);
    }
    Ok(summary)
}
