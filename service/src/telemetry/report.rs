//! Summaries of the loop histograms: the serialisable [`TelemetrySummary`], its
//! cyclictest-style table, and the classic HdrHistogram percentile-distribution text
//! format (`.hgrm`).

use std::fmt::Write as _;
use std::io::{self, Write};

use hdrhistogram::Histogram;
use serde::Serialize;

use super::histograms::{HistogramKind, LoopHistograms};
use crate::logging::WriteHealth;

/// Percentile ticks per half distance to 100 % used in the `.hgrm` files (the value
/// HdrHistogram's own tools use).
pub const TICKS_PER_HALF_DISTANCE: u32 = 5;

/// Percentiles and counts of one latency distribution, in ns.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LatencySummary {
    /// Histogram name (`wakeup`, `compute`, `response`, `jitter`).
    pub name: String,
    /// Unit of every value below: always `"ns"`.
    pub unit: String,
    /// Number of values recorded.
    pub count: u64,
    /// Smallest value (0 when empty).
    pub min: u64,
    /// Median.
    pub p50: u64,
    /// 90th percentile.
    pub p90: u64,
    /// 99th percentile.
    pub p99: u64,
    /// 99.9th percentile.
    pub p99_9: u64,
    /// 99.99th percentile.
    pub p99_99: u64,
    /// Largest value (0 when empty); values above 10 s are reported as 10 s.
    pub max: u64,
    /// Mean value.
    pub mean: f64,
    /// Values over the response-time budget (response histogram only; 0 for the others).
    pub over_budget: u64,
    /// The largest response times as `(seq, ns)`, largest first (response histogram only;
    /// empty for the others).
    pub worst: Vec<(u64, u64)>,
}

impl LatencySummary {
    /// Summarises `h` under `name`, with no budget count and no worst cycles.
    pub fn from_histogram(name: &str, h: &Histogram<u64>) -> Self {
        let empty = h.is_empty();
        let q = |q: f64| if empty { 0 } else { h.value_at_quantile(q) };
        Self {
            name: name.to_owned(),
            unit: "ns".to_owned(),
            count: h.len(),
            min: if empty { 0 } else { h.min() },
            p50: q(0.5),
            p90: q(0.9),
            p99: q(0.99),
            p99_9: q(0.999),
            p99_99: q(0.9999),
            max: if empty { 0 } else { h.max() },
            mean: if empty { 0.0 } else { h.mean() },
            over_budget: 0,
            worst: Vec::new(),
        }
    }
}

/// The loop-latency part of the run report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TelemetrySummary {
    /// Sample timestamp → receipt by the RT thread.
    pub wakeup: LatencySummary,
    /// Controller step duration.
    pub compute: LatencySummary,
    /// Sample timestamp → publication of the actuation; carries the over-budget count and
    /// the worst cycles.
    pub response: LatencySummary,
    /// Period jitter of the receipt times.
    pub jitter: LatencySummary,
    /// Swaps the RT side missed because no empty box was available (the interval was
    /// extended; no sample was lost).
    pub missed_swaps: u64,
    /// Cycles the RT side could not record because it held no box.
    pub unrecorded_cycles: u64,
    /// Number of non-empty intervals the reporter received.
    pub intervals: u64,
    /// The output files (`.hlog`, `.hgrm`) whose writing failed, with the first error and
    /// what was lost (for an interval log, intervals; for a percentile file, 1: the file
    /// is absent). Empty on a healthy run and for a reporter without files.
    pub file_errors: Vec<WriteHealth>,
}

impl TelemetrySummary {
    /// Summarises cumulative totals.
    pub fn from_totals(
        totals: &LoopHistograms,
        missed_swaps: u64,
        unrecorded_cycles: u64,
        intervals: u64,
    ) -> Self {
        let s = |kind: HistogramKind| {
            LatencySummary::from_histogram(kind.name(), totals.histogram(kind))
        };
        let mut response = s(HistogramKind::Response);
        response.over_budget = totals.over_budget();
        let (worst, n) = totals.worst().sorted();
        response.worst = worst[..n].to_vec();
        Self {
            wakeup: s(HistogramKind::Wakeup),
            compute: s(HistogramKind::Compute),
            response,
            jitter: s(HistogramKind::Jitter),
            missed_swaps,
            unrecorded_cycles,
            intervals,
            file_errors: Vec::new(),
        }
    }

    /// The four summaries in report order.
    pub fn histograms(&self) -> [&LatencySummary; 4] {
        [&self.wakeup, &self.compute, &self.response, &self.jitter]
    }

    /// A cyclictest-style table in microseconds: one row per histogram (count, p50,
    /// p99, p99.9, p99.99, max, over budget), then the sequence numbers of the worst
    /// cycles, the missed swaps, and one `FILE WRITE FAILED` line per output file whose
    /// writing failed.
    ///
    /// ```text
    /// loop latency (us), response budget 125.000 us
    /// histogram       count        p50        p99      p99.9     p99.99        max  over budget
    /// wakeup          20000      3.001      3.001      3.001      3.001      3.001            -
    /// ...
    /// worst response cycles: seq 19999 (50.015 us), seq 19998 (50.015 us), ...
    /// missed swaps: 0
    /// ```
    pub fn render_table(&self, budget_ns: u64) -> String {
        let us = |ns: u64| ns as f64 / 1_000.0;
        let mut out = String::new();
        // Writing into a String cannot fail.
        let _ = writeln!(
            out,
            "loop latency (us), response budget {:.3} us",
            us(budget_ns)
        );
        let _ = writeln!(
            out,
            "{:<10} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10} {:>12}",
            "histogram", "count", "p50", "p99", "p99.9", "p99.99", "max", "over budget"
        );
        for s in self.histograms() {
            let over = if s.name == HistogramKind::Response.name() {
                s.over_budget.to_string()
            } else {
                "-".to_owned()
            };
            let _ = writeln!(
                out,
                "{:<10} {:>10} {:>10.3} {:>10.3} {:>10.3} {:>10.3} {:>10.3} {:>12}",
                s.name,
                s.count,
                us(s.p50),
                us(s.p99),
                us(s.p99_9),
                us(s.p99_99),
                us(s.max),
                over
            );
        }
        out.push_str("worst response cycles:");
        if self.response.worst.is_empty() {
            out.push_str(" none");
        }
        for (i, &(seq, ns)) in self.response.worst.iter().enumerate() {
            let sep = if i == 0 { " " } else { ", " };
            let _ = write!(out, "{sep}seq {seq} ({:.3} us)", us(ns));
        }
        out.push('\n');
        let _ = writeln!(out, "missed swaps: {}", self.missed_swaps);
        if self.unrecorded_cycles != 0 {
            let _ = writeln!(out, "unrecorded cycles: {}", self.unrecorded_cycles);
        }
        for f in &self.file_errors {
            let _ = writeln!(
                out,
                "FILE WRITE FAILED: {} ({} written, {} lost{}): {}",
                f.path,
                f.records_written,
                f.records_lost,
                if f.intact {
                    ""
                } else {
                    ", may end in a torn record"
                },
                f.first_error.as_deref().unwrap_or("unknown error")
            );
        }
        out
    }
}

/// Writes `h` in the classic HdrHistogram percentile-distribution text format (the
/// `.hgrm` files that HdrHistogram's plotters read): a header line
/// `Value Percentile TotalCount 1/(1-Percentile)`, one row per percentile tick
/// (`ticks_per_half_distance` ticks per half distance to 100 %), values divided by
/// `value_scale` (1000 turns ns into µs) with as many decimals as the histogram has
/// significant figures, then the `#[Mean …]`, `#[Max …]` and `#[Buckets …]` footer
/// lines. An empty histogram gives the header and the footer only.
pub fn write_percentile_distribution<W: Write>(
    h: &Histogram<u64>,
    w: &mut W,
    ticks_per_half_distance: u32,
    value_scale: f64,
) -> io::Result<()> {
    let digits = usize::from(h.sigfig());
    writeln!(
        w,
        "{:>12} {:>14} {:>10} {:>14}\n",
        "Value", "Percentile", "TotalCount", "1/(1-Percentile)"
    )?;
    if !h.is_empty() {
        let mut total: u64 = 0;
        for v in h.iter_quantiles(ticks_per_half_distance.max(1)) {
            total += v.count_since_last_iteration();
            let value = v.value_iterated_to() as f64 / value_scale;
            let q = v.quantile_iterated_to();
            if q < 1.0 {
                writeln!(
                    w,
                    "{value:12.digits$} {q:2.12} {total:10} {:14.2}",
                    1.0 / (1.0 - q)
                )?;
            } else {
                writeln!(w, "{value:12.digits$} {q:2.12} {total:10}")?;
            }
        }
    }
    let (mean, stdev, max) = if h.is_empty() {
        (0.0, 0.0, 0.0)
    } else {
        (
            h.mean() / value_scale,
            h.stdev() / value_scale,
            h.max() as f64 / value_scale,
        )
    };
    let buckets = u64::from(h.buckets());
    // The counts array holds (buckets + 1) half sub-bucket ranges.
    let sub_buckets = 2 * h.distinct_values() as u64 / (buckets + 1);
    writeln!(
        w,
        "#[Mean    = {mean:12.digits$}, StdDeviation   = {stdev:12.digits$}]"
    )?;
    writeln!(
        w,
        "#[Max     = {max:12.digits$}, Total count    = {:12}]",
        h.len()
    )?;
    writeln!(
        w,
        "#[Buckets = {buckets:12}, SubBuckets     = {sub_buckets:12}]"
    )?;
    Ok(())
}

/// The live view's snapshot of `h` ([`ipc_types::telemetry::LatencySnapshot`]): the
/// percentiles of [`LatencySummary::from_histogram`], the sum from the mean, and the
/// cumulative counts at [`ipc_types::telemetry::LATENCY_BUCKET_BOUNDS_NS`].
pub fn latency_snapshot(h: &Histogram<u64>) -> ipc_types::telemetry::LatencySnapshot {
    let s = LatencySummary::from_histogram("", h);
    let mut buckets = [0u64; ipc_types::telemetry::LATENCY_BUCKETS];
    if !h.is_empty() {
        for (b, bound) in buckets
            .iter_mut()
            .zip(ipc_types::telemetry::LATENCY_BUCKET_BOUNDS_NS)
        {
            *b = h.count_between(0, bound);
        }
    }
    ipc_types::telemetry::LatencySnapshot {
        count: s.count,
        sum_ns: s.mean * s.count as f64,
        p50_ns: s.p50,
        p90_ns: s.p90,
        p99_ns: s.p99,
        p999_ns: s.p99_9,
        max_ns: s.max,
        buckets,
    }
}
