//! The box swap between the RT thread ([`TelemetryRt`]) and the reporter
//! ([`TelemetryReporter`]), and the reporter's interval-log output.
//!
//! Box accounting: [`channel`] creates `spare + 1` boxes. At any time each box is in
//! exactly one place: in the RT thread's hands, in the full queue, in the reporter's
//! hands during [`TelemetryReporter::poll`], or in the return queue. Both queues have
//! room for all of them, so neither side ever fails a push for lack of room.

use std::io;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, SystemTime};

use ipc_types::clock::monotonic_ns;
use rtrb::{Consumer, Producer, RingBuffer};

use super::CycleTiming;
use super::histograms::{HistogramKind, LoopHistograms};
use super::interval_logs::IntervalLogs;
#[cfg(test)]
use super::interval_logs::LogTarget;
use super::report::TelemetrySummary;
use crate::logging::WriteHealth;

/// Counters the RT side publishes for the reporter (single writer, relaxed stores).
#[derive(Debug, Default)]
struct Shared {
    missed_swaps: AtomicU64,
    unrecorded_cycles: AtomicU64,
}

/// Creates the RT recording side and the reporting side of the loop telemetry, with the
/// reporter writing its files into `out_dir` (created if missing).
///
/// - `budget_ns`: response-time budget; cycles whose response time exceeds it are
///   counted as over budget.
/// - `interval_cycles`: the RT side hands its histograms to the reporter every
///   `interval_cycles` cycles (e.g. the number of cycles in one second). `0` means
///   never: only [`TelemetryRt::flush`] hands them over.
/// - `spare`: number of empty boxes waiting in the return queue. With `spare ≥ 1` and a
///   reporter that polls at least once per interval no swap is ever missed.
/// - `out_dir`: the interval logs `wakeup.hlog`, `compute.hlog`, `response.hlog`,
///   `jitter.hlog` are created there now (with their headers); the percentile
///   distributions `<name>.hgrm` are written by [`TelemetryReporter::finish`].
///   Interval-log timestamps are seconds since this call, which is also the logs'
///   `StartTime` and `BaseTime`; interval maxima are in ns.
///
/// Allocates `spare + 2` [`LoopHistograms`] (about 800 KiB each): `spare + 1` boxes
/// shared by the two sides, and the reporter's totals. Call it before the RT thread
/// starts. Fails only if the folder or the interval logs cannot be created.
pub fn channel(
    budget_ns: u64,
    interval_cycles: u64,
    spare: usize,
    out_dir: impl AsRef<Path>,
) -> io::Result<(TelemetryRt, TelemetryReporter)> {
    let (rt, mut reporter) = channel_in_memory(budget_ns, interval_cycles, spare);
    reporter.open_logs(out_dir.as_ref())?;
    Ok((rt, reporter))
}

/// Like [`channel`], but the reporter writes no files: it only keeps the totals and
/// returns the summary (for benchmarks and tests).
pub fn channel_in_memory(
    budget_ns: u64,
    interval_cycles: u64,
    spare: usize,
) -> (TelemetryRt, TelemetryReporter) {
    let boxes = spare.saturating_add(1);
    let (full_tx, full_rx) = RingBuffer::<Box<LoopHistograms>>::new(boxes);
    let (mut empty_tx, empty_rx) = RingBuffer::<Box<LoopHistograms>>::new(boxes);
    for _ in 0..spare {
        // The return queue has room for `spare + 1` boxes, so this push succeeds.
        let _ = empty_tx.push(Box::new(LoopHistograms::new(budget_ns)));
    }
    let shared = Arc::new(Shared::default());
    let rt = TelemetryRt {
        current: Some(Box::new(LoopHistograms::new(budget_ns))),
        full_tx,
        empty_rx,
        interval_cycles,
        since_swap: 0,
        missed_swaps: 0,
        unrecorded_cycles: 0,
        shared: Arc::clone(&shared),
    };
    let reporter = TelemetryReporter {
        full_rx,
        empty_tx,
        totals: LoopHistograms::new(budget_ns),
        shared,
        budget_ns,
        boxes,
        intervals: 0,
        anchor_mono_ns: monotonic_ns(),
        anchor_wall: SystemTime::now(),
        logs: None,
        closed_failures: Vec::new(),
    };
    (rt, reporter)
}

/// The RT thread's side: records every cycle and periodically hands its histograms to the
/// reporter. Owned by the RT thread; `Send` so it can be moved there after set-up.
///
/// [`record`](Self::record) never allocates, locks, blocks, does I/O or panics. Dropping
/// it frees its box: do that outside the RT loop.
pub struct TelemetryRt {
    /// The box being recorded into. `None` only in the (theoretically unreachable) case
    /// that a swap could push but not pop, or after a [`flush`](Self::flush) found no
    /// empty box; recording then resumes as soon as an empty box is available.
    current: Option<Box<LoopHistograms>>,
    full_tx: Producer<Box<LoopHistograms>>,
    empty_rx: Consumer<Box<LoopHistograms>>,
    interval_cycles: u64,
    since_swap: u64,
    missed_swaps: u64,
    unrecorded_cycles: u64,
    shared: Arc<Shared>,
}

impl TelemetryRt {
    /// Records one cycle; every `interval_cycles` cycles, tries to swap boxes with the
    /// reporter (see the [module documentation](super)). Never allocates, locks,
    /// blocks or panics.
    #[inline]
    pub fn record(&mut self, t: &CycleTiming) {
        if self.current.is_none() {
            match self.empty_rx.pop() {
                Ok(mut b) => {
                    b.begin_interval(monotonic_ns());
                    self.current = Some(b);
                }
                Err(_) => {
                    self.unrecorded_cycles = self.unrecorded_cycles.wrapping_add(1);
                    self.shared
                        .unrecorded_cycles
                        .store(self.unrecorded_cycles, Ordering::Relaxed);
                    return;
                }
            }
        }
        if let Some(h) = self.current.as_deref_mut() {
            if h.interval_start_ns() == 0 {
                h.begin_interval(monotonic_ns());
            }
            h.record(t);
        }
        self.since_swap += 1;
        if self.interval_cycles != 0 && self.since_swap >= self.interval_cycles {
            self.since_swap = 0;
            if !self.try_swap() {
                self.missed_swaps = self.missed_swaps.wrapping_add(1);
                self.shared
                    .missed_swaps
                    .store(self.missed_swaps, Ordering::Relaxed);
            }
        }
    }

    /// Hands the current box to the reporter and takes an empty one. Returns `false`
    /// (and changes nothing) when no empty box is available.
    fn try_swap(&mut self) -> bool {
        // We are the only consumer of the return queue: if a box is there now, the pop
        // below succeeds.
        if self.empty_rx.is_empty() {
            return false;
        }
        let Some(mut full) = self.current.take() else {
            return false;
        };
        let now = monotonic_ns();
        full.end_interval(now);
        if let Err(rtrb::PushError::Full(mut back)) = self.full_tx.push(full) {
            // Cannot happen (the full queue holds every box); keep recording into it.
            back.end_interval(0);
            self.current = Some(back);
            return false;
        }
        self.current = match self.empty_rx.pop() {
            Ok(mut b) => {
                b.begin_interval(now);
                Some(b)
            }
            Err(_) => None,
        };
        true
    }

    /// Hands the current box to the reporter at the end of a run (or whenever the caller
    /// wants the reporter to see everything recorded so far), then takes an empty box if
    /// one is available so recording can continue. Returns whether a box was handed
    /// over (`false` if nothing was recorded since the last hand-over).
    ///
    /// Does not allocate or block; meant for the end of the run, but RT-safe.
    pub fn flush(&mut self) -> bool {
        let Some(current) = self.current.as_deref() else {
            return false;
        };
        if current.cycles() == 0 {
            return false;
        }
        let Some(mut full) = self.current.take() else {
            return false;
        };
        full.end_interval(monotonic_ns());
        if let Err(rtrb::PushError::Full(mut back)) = self.full_tx.push(full) {
            back.end_interval(0);
            self.current = Some(back);
            return false;
        }
        self.since_swap = 0;
        // The next interval starts at the next recorded cycle.
        self.current = self.empty_rx.pop().ok();
        true
    }

    /// Number of swaps that found no empty box (the interval was extended instead).
    pub fn missed_swaps(&self) -> u64 {
        self.missed_swaps
    }

    /// Number of cycles that could not be recorded because the RT side held no box
    /// (only possible after a [`flush`](Self::flush) with no empty box available).
    pub fn unrecorded_cycles(&self) -> u64 {
        self.unrecorded_cycles
    }
}

/// The non-RT side: drains the boxes the RT thread hands over, writes interval logs,
/// keeps cumulative totals and returns the boxes.
pub struct TelemetryReporter {
    full_rx: Consumer<Box<LoopHistograms>>,
    empty_tx: Producer<Box<LoopHistograms>>,
    totals: LoopHistograms,
    shared: Arc<Shared>,
    budget_ns: u64,
    boxes: usize,
    intervals: u64,
    anchor_mono_ns: u64,
    anchor_wall: SystemTime,
    logs: Option<IntervalLogs>,
    /// Files that failed, once [`finish`](TelemetryReporter::finish) closed them.
    closed_failures: Vec<WriteHealth>,
}

impl TelemetryReporter {
    /// Creates `dir` and the four interval logs with their headers.
    fn open_logs(&mut self, dir: &Path) -> io::Result<()> {
        self.logs = Some(IntervalLogs::open(dir, self.anchor_wall)?);
        Ok(())
    }

    /// Like [`open_logs`](Self::open_logs), with the interval logs written into the
    /// given targets (tests inject failing ones); `dir` receives the `.hgrm` files.
    #[cfg(test)]
    pub(crate) fn open_logs_into(
        &mut self,
        dir: &Path,
        targets: [LogTarget; 4],
        retry_every: Duration,
    ) -> io::Result<()> {
        self.logs = Some(IntervalLogs::with_targets(
            dir,
            self.anchor_wall,
            targets,
            retry_every,
        )?);
        Ok(())
    }

    /// The output folder, if one was given.
    pub fn output_dir(&self) -> Option<&Path> {
        self.logs.as_ref().map(IntervalLogs::dir)
    }

    /// Drains every box the RT side has handed over: writes each non-empty interval into
    /// the interval logs (if there is an output folder), adds it into the totals, resets
    /// the box and returns it to the RT side. Returns the number of boxes drained.
    ///
    /// Call it periodically (at least once per interval to avoid missed swaps) from a
    /// non-RT thread. A failing disk is not an error: the logs keep whole lines, report
    /// the failure once on standard error and count the intervals they could not write
    /// (see [`file_failures`](Self::file_failures)); every box is still added to the
    /// totals and returned. The only error is an interval that could not be serialized.
    pub fn poll(&mut self) -> io::Result<usize> {
        let mut drained = 0;
        let mut result = Ok(());
        while let Ok(mut b) = self.full_rx.pop() {
            drained += 1;
            if b.cycles() > 0 {
                let written = self.write_interval(&b);
                if result.is_ok() {
                    result = written;
                }
                self.totals.add(&b);
                self.intervals += 1;
            }
            b.reset();
            // The return queue holds every box, so this cannot fail; if it did, the box
            // would simply be freed here, outside the RT thread.
            let _ = self.empty_tx.push(b);
        }
        if drained > 0
            && let Some(logs) = self.logs.as_mut()
        {
            logs.flush();
        }
        result.map(|()| drained)
    }

    fn write_interval(&mut self, b: &LoopHistograms) -> io::Result<()> {
        let Some(logs) = self.logs.as_mut() else {
            return Ok(());
        };
        let start_ns = b.interval_start_ns();
        let end_ns = if b.interval_end_ns() != 0 {
            b.interval_end_ns()
        } else {
            monotonic_ns()
        };
        let start = Duration::from_nanos(start_ns.saturating_sub(self.anchor_mono_ns));
        let length = Duration::from_nanos(end_ns.saturating_sub(start_ns));
        logs.write_interval(b, start, length)
    }

    /// The output files that failed so far (interval logs; after
    /// [`finish`](Self::finish) also the percentile files), with what was lost and the
    /// first error. Empty on a healthy run.
    pub fn file_failures(&self) -> Vec<WriteHealth> {
        let mut failed = self.closed_failures.clone();
        if let Some(logs) = self.logs.as_ref() {
            failed.extend(logs.failures());
        }
        failed
    }

    /// Cumulative totals of everything drained so far.
    pub fn totals(&self) -> &LoopHistograms {
        &self.totals
    }

    /// The live view's snapshots of the totals drained so far, in
    /// [`ipc_types::telemetry::latency_index`] order.
    pub fn snapshots(&self) -> [ipc_types::telemetry::LatencySnapshot; 4] {
        HistogramKind::ALL.map(|k| super::report::latency_snapshot(self.totals.histogram(k)))
    }

    /// Number of non-empty intervals drained so far.
    pub fn intervals(&self) -> u64 {
        self.intervals
    }

    /// Number of boxes shared by the two sides (`spare + 1`); constant for the run.
    pub fn boxes(&self) -> usize {
        self.boxes
    }

    /// The response-time budget given to [`channel`].
    pub fn budget_ns(&self) -> u64 {
        self.budget_ns
    }

    /// Missed swaps reported by the RT side so far.
    pub fn missed_swaps(&self) -> u64 {
        self.shared.missed_swaps.load(Ordering::Relaxed)
    }

    /// Summary of the totals drained so far (does not poll), with the
    /// [`file_failures`](Self::file_failures) so far.
    pub fn summary(&self) -> TelemetrySummary {
        let mut summary = TelemetrySummary::from_totals(
            &self.totals,
            self.missed_swaps(),
            self.shared.unrecorded_cycles.load(Ordering::Relaxed),
            self.intervals,
        );
        summary.file_errors = self.file_failures();
        summary
    }

    /// Ends the report: drains the remaining boxes (call [`TelemetryRt::flush`] first so
    /// the RT side's last interval is included), writes and syncs the interval logs,
    /// writes the percentile distribution files `<name>.hgrm` (values in µs, each
    /// atomically: complete or absent) if there is an output folder, and returns the
    /// summary.
    ///
    /// Never fails: a failing disk is reported on standard error and the files that
    /// failed are listed in [`TelemetrySummary::file_errors`]; an interval that could not
    /// be serialized (not seen in practice) is reported on standard error and missing
    /// from its log. The `io::Result` is kept for compatibility.
    pub fn finish(mut self) -> io::Result<TelemetrySummary> {
        if let Err(e) = self.poll() {
            eprintln!("[service] {e}");
        }
        if let Some(logs) = self.logs.take() {
            let failed = logs.finish(&self.totals);
            self.closed_failures.extend(failed);
        }
        Ok(self.summary())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    fn timing(seq: u64) -> CycleTiming {
        CycleTiming {
            seq,
            wakeup_ns: 1_000 + seq % 7,
            compute_ns: 10_000,
            response_ns: 20_000 + seq % 1_000,
            period_jitter_ns: Some(seq % 50),
        }
    }

    /// Where every box is: (held by RT, queued full, queued empty).
    fn box_census(rt: &TelemetryRt) -> (usize, usize, usize) {
        let full = rt.full_tx.buffer().capacity() - rt.full_tx.slots();
        (usize::from(rt.current.is_some()), full, rt.empty_rx.slots())
    }

    fn box_address(b: &LoopHistograms) -> usize {
        b as *const LoopHistograms as usize
    }

    #[test]
    fn recording_over_many_intervals_reuses_the_boxes_created_at_start_up() {
        let spare = 1;
        let interval = 100;
        let (mut rt, mut reporter) = channel_in_memory(50_000, interval, spare);

        let mut initial = HashSet::new();
        initial.insert(box_address(rt.current.as_deref().unwrap()));
        // Peek the spare box's address without taking it out.
        initial.insert(box_address(rt.empty_rx.peek().unwrap()));
        assert_eq!(initial.len(), spare + 1);
        assert_eq!(reporter.boxes(), spare + 1);

        let mut seq = 0;
        for _ in 0..200 {
            for _ in 0..interval {
                rt.record(&timing(seq));
                seq += 1;
            }
            let (held, full, empty) = box_census(&rt);
            assert_eq!(held + full + empty, spare + 1, "no box created or lost");
            assert!(initial.contains(&box_address(rt.current.as_deref().unwrap())));
            assert_eq!(reporter.poll().unwrap(), 1);
            let (held, full, empty) = box_census(&rt);
            assert_eq!((held, full, empty), (1, 0, spare));
        }
        assert_eq!(rt.missed_swaps(), 0);
        assert_eq!(rt.unrecorded_cycles(), 0);
        rt.flush();
        let summary = reporter.finish().unwrap();
        assert_eq!(summary.response.count, seq);
        assert_eq!(summary.intervals, 200);
    }

    #[test]
    fn a_missed_swap_extends_the_interval_and_loses_nothing() {
        // No spare box: every swap is missed, everything stays in the one box.
        let (mut rt, mut reporter) = channel_in_memory(50_000, 10, 0);
        for seq in 0..1_000 {
            rt.record(&timing(seq));
        }
        assert_eq!(rt.missed_swaps(), 100);
        assert_eq!(reporter.poll().unwrap(), 0);
        assert!(rt.flush());
        assert_eq!(reporter.missed_swaps(), 100);
        let summary = reporter.finish().unwrap();
        assert_eq!(summary.missed_swaps, 100);
        assert_eq!(summary.wakeup.count, 1_000);
        assert_eq!(summary.intervals, 1);
    }

    #[test]
    fn after_a_flush_without_a_spare_box_cycles_are_counted_as_unrecorded_until_one_returns() {
        let (mut rt, mut reporter) = channel_in_memory(50_000, 0, 0);
        for seq in 0..5 {
            rt.record(&timing(seq));
        }
        assert!(rt.flush());
        assert!(rt.current.is_none());
        rt.record(&timing(5));
        assert_eq!(rt.unrecorded_cycles(), 1);
        assert_eq!(reporter.poll().unwrap(), 1);
        rt.record(&timing(6));
        assert!(rt.current.is_some());
        assert!(rt.flush());
        let summary = reporter.finish().unwrap();
        assert_eq!(summary.response.count, 6);
        assert_eq!(summary.unrecorded_cycles, 1);
    }
}
