//! # telemetry: measure inside the loop, report outside it
//!
//! Every control cycle produces one [`CycleTiming`]: how late the RT thread woke up
//! relative to the sample timestamp, how long the controller step took, the total
//! response time from sample timestamp to publication of `u_k`, and the period jitter
//! `|(t_recv,k − t_recv,k−1) − T|` of the receipt times.
//!
//! ## Design
//!
//! ```text
//!  RT thread                                  reporter (non-RT) thread
//!  ┌───────────────────────────┐   full boxes    ┌──────────────────────────────────┐
//!  │ TelemetryRt               │ ──────────────► │ TelemetryReporter::poll           │
//!  │   current: Box<LoopHisto> │   (rtrb SPSC)   │   interval logs (*.hlog)          │
//!  │   record(): 4 × saturating│                 │   totals.add(box); box.reset()    │
//!  │   record, worst-K, budget │ ◄────────────── │                                   │
//!  └───────────────────────────┘   empty boxes   │ finish(): *.hgrm + summary        │
//!                                  (rtrb SPSC)   └──────────────────────────────────┘
//! ```
//!
//! - **Two phases.** [`channel`] allocates every histogram the run will ever use:
//!   `spare + 1` boxed [`LoopHistograms`] (one in the RT thread's hands, `spare` waiting
//!   in the return queue) plus the reporter's cumulative totals. Both queues are sized to
//!   hold every box, so a push between the two sides can never fail for lack of room.
//! - **Recording never allocates, locks, blocks or panics.** The histograms are created
//!   with a fixed range (1 ns … 10 s, 3 significant figures) and auto-resize off, and
//!   values are recorded with `saturating_record`, so an out-of-range value is clamped
//!   to the range instead of growing the counts array or failing. The worst-cycles
//!   tracker ([`WorstCycles`]) is a fixed array of `K =` [`WORST_K`] entries.
//! - **The swap.** Every `interval_cycles` cycles [`TelemetryRt::record`] hands the full
//!   box to the reporter and takes an empty one from the return queue (two wait-free
//!   queue operations and one `clock_gettime`). If the reporter has not returned a box
//!   yet, the swap is *missed*: the RT thread counts it and keeps recording into the
//!   current box, so the interval simply becomes longer. No sample is ever lost and no
//!   box is ever created after start-up.
//! - **Interval bounds travel with the box.** Each box carries the monotonic start and
//!   end of its interval (`ipc_types::clock::monotonic_ns`); the reporter turns them
//!   into interval-log timestamps relative to the instant [`channel`] was called.
//!   ([`channel_in_memory`] gives a reporter that writes no files.)
//! - **Reporting.** [`TelemetryReporter::poll`] (call it every few hundred ms from a
//!   non-RT thread) writes one tagged interval histogram per box into `wakeup.hlog`,
//!   `compute.hlog`, `response.hlog` and `jitter.hlog` (HdrHistogram interval-log
//!   format, V2 + deflate encoding, readable by `HistogramLogProcessor` and HdrHistogram
//!   plotters), adds the box into cumulative totals, resets it and returns it.
//!   [`TelemetryReporter::finish`] drains what is left and writes the classic
//!   percentile-distribution text files (`<name>.hgrm`, values in microseconds) and
//!   returns a [`TelemetrySummary`] (serde-serialisable for the run report, and
//!   printable as a cyclictest-style table with [`TelemetrySummary::render_table`]).
//! - **Full disk, I/O errors.** The interval logs are written in whole lines through a
//!   [`crate::logging::RecordFile`]: a failed write cuts the log back to its last whole
//!   line, is reported once on standard error, and the intervals that could not be
//!   written are counted; the totals (and so the summary and the `.hgrm` files) lose
//!   nothing. The `.hgrm` files are written atomically
//!   ([`ipc_types::files::write_atomic_with`]): complete or absent. Neither
//!   [`TelemetryReporter::poll`] nor [`TelemetryReporter::finish`] fails on a full disk;
//!   the files that failed are listed in [`TelemetrySummary::file_errors`].
//!
//! ## Example
//!
//! ```
//! use service::telemetry::{self, CycleTiming};
//!
//! // Set-up phase (allocates): 125 µs budget, swap every 8000 cycles, 2 spare boxes,
//! // interval logs and percentile files in `dir`.
//! let dir = std::env::temp_dir().join(format!("telemetry-doc-{}", std::process::id()));
//! let (mut rt, mut reporter) = telemetry::channel(125_000, 8_000, 2, &dir).unwrap();
//!
//! // RT thread, once per cycle (never allocates, locks, blocks or panics):
//! for k in 0..20_000u64 {
//!     rt.record(&CycleTiming {
//!         seq: k,
//!         wakeup_ns: 3_000,
//!         compute_ns: 20_000,
//!         response_ns: 30_000 + k,
//!         period_jitter_ns: Some(1_500),
//!     });
//!     if k % 8_000 == 0 {
//!         reporter.poll().unwrap(); // normally on its own non-RT thread
//!     }
//! }
//!
//! // End of run: the RT side hands over its last box, the reporter summarises.
//! rt.flush();
//! let summary = reporter.finish().unwrap();
//! assert_eq!(summary.response.count, 20_000);
//! assert_eq!(summary.response.over_budget, 0);
//! println!("{}", summary.render_table(125_000));
//! assert!(dir.join("response.hgrm").exists());
//! # std::fs::remove_dir_all(&dir).unwrap();
//! ```

mod histograms;
mod interval_logs;
mod report;
mod swap;

#[cfg(test)]
mod disk_failure_tests;
#[cfg(test)]
mod tests;

pub use histograms::{
    HIGHEST_TRACKABLE_NS, HistogramKind, LOWEST_DISCERNIBLE_NS, LoopHistograms,
    SIGNIFICANT_FIGURES, WORST_K, WorstCycles,
};
pub use report::{
    LatencySummary, TICKS_PER_HALF_DISTANCE, TelemetrySummary, latency_snapshot,
    write_percentile_distribution,
};
pub use swap::{TelemetryReporter, TelemetryRt, channel, channel_in_memory};

/// The timing of one control cycle, as measured by the RT thread.
///
/// All durations are in nanoseconds of `CLOCK_MONOTONIC` (the contract's time base, see
/// `ipc_types::clock`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CycleTiming {
    /// Sequence number `k` of the sample this cycle answered.
    pub seq: u64,
    /// Wake-up latency: sample timestamp → receipt of the sample by the RT thread.
    pub wakeup_ns: u64,
    /// Controller step duration.
    pub compute_ns: u64,
    /// Response time: sample timestamp → publication of `u_k`.
    pub response_ns: u64,
    /// Period jitter `|(t_recv,k − t_recv,k−1) − T|`; `None` on the first cycle or after a
    /// gap in the sequence numbers, when there is no previous receipt to compare with.
    pub period_jitter_ns: Option<u64>,
}

impl CycleTiming {
    /// The period jitter `|(t_recv − t_prev_recv) − period|` in nanoseconds.
    ///
    /// Wrapping arithmetic keeps it panic-free even if the clock readings are out of
    /// order (the result is then meaningless but finite).
    #[inline]
    pub fn period_jitter(t_recv_ns: u64, t_prev_recv_ns: u64, period_ns: u64) -> u64 {
        let actual = t_recv_ns.wrapping_sub(t_prev_recv_ns);
        actual.abs_diff(period_ns)
    }
}
