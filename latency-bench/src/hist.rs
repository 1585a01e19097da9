//! HdrHistogram helpers: one histogram shape for every distribution of the bench, its
//! percentile summary, and the two files written per distribution.
//!
//! Values are recorded in nanoseconds into histograms of range 1 ns … 60 s with three
//! significant figures (relative error ≤ 0.1 %), recorded with saturation so that an
//! absurd value is clamped instead of lost. Every percentile of the bench is [`quantile`]:
//! HdrHistogram's `value_at_quantile`, i.e. the highest value equivalent to the bucket that
//! holds the sample of rank `⌈q·n⌉` (at least 1).
//!
//! Files, for a distribution named `name`:
//! - `name.hgrm`: the classic percentile distribution text, values in µs, written with the
//!   service's own writer (`service::telemetry::write_percentile_distribution`) so that the
//!   bench and the service produce files of the same format;
//! - `name.hlog`: an HdrHistogram interval log (V2 + deflate, values in ns) holding the
//!   whole measurement as one interval, readable by `HistogramLogProcessor` and the
//!   HdrHistogram plotters. [`read_interval_log`] reads such a log back, summing its
//!   intervals (the service's own logs among them).

use hdrhistogram::Histogram;
use hdrhistogram::serialization::V2DeflateSerializer;
use hdrhistogram::serialization::interval_log::{IntervalLogWriterBuilder, Tag};
use serde::Serialize;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

/// Highest value the bench's histograms track, in ns (60 s).
pub const HIGHEST_NS: u64 = 60_000_000_000;
/// Significant figures of the bench's histograms.
pub const SIGFIG: u8 = 3;

/// A new, empty histogram of the bench's shape (1 ns … [`HIGHEST_NS`], [`SIGFIG`] figures).
pub fn new_histogram() -> Histogram<u64> {
    // The constant bounds satisfy every precondition of new_with_bounds.
    Histogram::new_with_bounds(1, HIGHEST_NS, SIGFIG).expect("constant bounds are valid")
}

/// The `q`-quantile of `h` (see the module docs); 0 when `h` is empty.
pub fn quantile(h: &Histogram<u64>, q: f64) -> u64 {
    if h.is_empty() {
        0
    } else {
        h.value_at_quantile(q)
    }
}

/// Percentiles of one distribution, in nanoseconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Summary {
    /// Number of values.
    pub count: u64,
    /// Smallest value.
    pub min_ns: u64,
    /// Median.
    pub p50_ns: u64,
    /// 99th percentile.
    pub p99_ns: u64,
    /// 99.9th percentile.
    pub p99_9_ns: u64,
    /// Largest value.
    pub max_ns: u64,
    /// Mean.
    pub mean_ns: f64,
}

impl Summary {
    /// Summarises `h`; all zero when it is empty.
    pub fn of(h: &Histogram<u64>) -> Self {
        if h.is_empty() {
            return Self {
                count: 0,
                min_ns: 0,
                p50_ns: 0,
                p99_ns: 0,
                p99_9_ns: 0,
                max_ns: 0,
                mean_ns: 0.0,
            };
        }
        Self {
            count: h.len(),
            min_ns: h.min(),
            p50_ns: quantile(h, 0.5),
            p99_ns: quantile(h, 0.99),
            p99_9_ns: quantile(h, 0.999),
            max_ns: h.max(),
            mean_ns: h.mean(),
        }
    }

    /// Reads a summary from one `LatencySummary` object of the service's run report
    /// (`report.json` → `latency.<name>`), whose values are in ns.
    pub fn from_service_json(v: &serde_json::Value) -> Result<Self, String> {
        let num = |k: &str| -> Result<u64, String> {
            v.get(k)
                .and_then(|x| x.as_u64())
                .ok_or_else(|| format!("the latency summary has no integer field '{k}'"))
        };
        Ok(Self {
            count: num("count")?,
            min_ns: num("min")?,
            p50_ns: num("p50")?,
            p99_ns: num("p99")?,
            p99_9_ns: num("p99_9")?,
            max_ns: num("max")?,
            mean_ns: v.get("mean").and_then(|x| x.as_f64()).unwrap_or(f64::NAN),
        })
    }

    /// The four table columns (p50, p99, p99.9, max) in µs.
    pub fn columns_us(&self) -> [Option<f64>; 4] {
        let us = |ns: u64| Some(ns as f64 / 1_000.0);
        [
            us(self.p50_ns),
            us(self.p99_ns),
            us(self.p99_9_ns),
            us(self.max_ns),
        ]
    }
}

/// `a / b` of two nanosecond values, `None` when `b` is zero.
pub fn ratio(a: u64, b: u64) -> Option<f64> {
    if b == 0 {
        None
    } else {
        Some(a as f64 / b as f64)
    }
}

/// Writes `dir/name.hgrm` (µs) and `dir/name.hlog` (ns, one interval starting at `start`
/// and lasting `duration`), and returns their paths.
pub fn write_files(
    dir: &Path,
    name: &str,
    h: &Histogram<u64>,
    start: SystemTime,
    duration: Duration,
) -> io::Result<Vec<PathBuf>> {
    let hgrm = dir.join(format!("{name}.hgrm"));
    let mut w = BufWriter::new(File::create(&hgrm)?);
    service::telemetry::write_percentile_distribution(
        h,
        &mut w,
        service::telemetry::TICKS_PER_HALF_DISTANCE,
        1_000.0,
    )?;
    w.flush()?;

    let hlog = dir.join(format!("{name}.hlog"));
    let mut w = BufWriter::new(File::create(&hlog)?);
    let mut serializer = V2DeflateSerializer::new();
    let mut log = IntervalLogWriterBuilder::new()
        .add_comment(&format!("latency-bench: {name}, values in ns"))
        .with_start_time(start)
        .with_base_time(start)
        .with_max_value_divisor(1_000.0)
        .begin_log_with(&mut w, &mut serializer)?;
    // Tags may not contain spaces, commas or newlines; distribution names never do.
    let tag = Tag::new(name);
    log.write_histogram(h, Duration::ZERO, duration, tag)
        .map_err(|e| io::Error::other(format!("writing {}: {e:?}", hlog.display())))?;
    drop(log);
    w.flush()?;
    Ok(vec![hgrm, hlog])
}

/// The sum of every interval of the HdrHistogram interval log `path` (V2 or V2 +
/// deflate, values in ns): the service's `<name>.hlog` files hold one interval per
/// `service.histogram-interval`, whose sum is the distribution its run report
/// summarises. Values are added into a histogram of the bench's shape
/// ([`new_histogram`]).
pub fn read_interval_log(path: &Path) -> Result<Histogram<u64>, String> {
    use hdrhistogram::serialization::Deserializer;
    use hdrhistogram::serialization::interval_log::{IntervalLogIterator, LogEntry};
    let what = || path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| format!("reading {}: {e}", what()))?;
    let mut sum = new_histogram();
    let mut deserializer = Deserializer::new();
    for entry in IntervalLogIterator::new(&bytes) {
        let entry = entry.map_err(|e| format!("parsing {}: {e:?}", what()))?;
        if let LogEntry::Interval(ilh) = entry {
            let raw = base64_decode(ilh.encoded_histogram())
                .ok_or_else(|| format!("{}: an interval is not base64", what()))?;
            let h: Histogram<u64> = deserializer
                .deserialize(&mut raw.as_slice())
                .map_err(|e| format!("decoding an interval of {}: {e:?}", what()))?;
            sum.add(&h)
                .map_err(|e| format!("adding an interval of {}: {e:?}", what()))?;
        }
    }
    Ok(sum)
}

/// Standard base64 (with or without `=` padding) to bytes; `None` for any other
/// character.
fn base64_decode(s: &str) -> Option<Vec<u8>> {
    fn sextet(c: u8) -> Option<u32> {
        Some(match c {
            b'A'..=b'Z' => u32::from(c - b'A'),
            b'a'..=b'z' => u32::from(c - b'a') + 26,
            b'0'..=b'9' => u32::from(c - b'0') + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return None,
        })
    }
    let bytes: Vec<u8> = s.trim().bytes().filter(|&c| c != b'=').collect();
    let mut out = Vec::with_capacity(bytes.len() * 3 / 4);
    for chunk in bytes.chunks(4) {
        let mut acc = 0u32;
        for (i, &c) in chunk.iter().enumerate() {
            acc |= sextet(c)? << (18 - 6 * i as u32);
        }
        for i in 0..chunk.len().saturating_sub(1) {
            out.push((acc >> (16 - 8 * i as u32)) as u8);
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_summary_reports_the_quantiles_of_the_histogram() {
        let mut h = new_histogram();
        for v in 1..=1000u64 {
            h.saturating_record(v * 1_000);
        }
        let s = Summary::of(&h);
        assert_eq!(s.count, 1000);
        assert!((s.p50_ns as f64 - 500_000.0).abs() < 1_000.0, "{s:?}");
        assert!((s.p99_ns as f64 - 990_000.0).abs() < 1_000.0, "{s:?}");
        assert!((s.max_ns as f64 - 1_000_000.0).abs() < 1_000.0, "{s:?}");
        assert_eq!(Summary::of(&new_histogram()).count, 0);
        assert_eq!(quantile(&new_histogram(), 0.5), 0);
        assert_eq!(quantile(&h, 0.5), s.p50_ns);
    }

    #[test]
    fn a_service_latency_summary_is_read_from_its_json() {
        let v = serde_json::json!({
            "name": "wakeup", "unit": "ns", "count": 10, "min": 1, "p50": 2, "p90": 3,
            "p99": 4, "p99_9": 5, "p99_99": 6, "max": 7, "mean": 2.5, "over_budget": 0, "worst": []
        });
        let s = Summary::from_service_json(&v).unwrap();
        assert_eq!(
            (s.count, s.p50_ns, s.p99_ns, s.p99_9_ns, s.max_ns),
            (10, 2, 4, 5, 7)
        );
        assert!(Summary::from_service_json(&serde_json::json!({"p50": 1})).is_err());
    }

    #[test]
    fn base64_decodes_with_and_without_padding() {
        assert_eq!(base64_decode("TWFu").unwrap(), b"Man");
        assert_eq!(base64_decode("TWE=").unwrap(), b"Ma");
        assert_eq!(base64_decode("TQ").unwrap(), b"M");
        assert!(base64_decode("T*").is_none());
    }

    #[test]
    fn the_files_are_written_and_the_log_reads_back() {
        let dir = std::env::temp_dir().join(format!("lb-hist-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut h = new_histogram();
        h.saturating_record_n(12_345, 10);
        let files =
            write_files(&dir, "unit", &h, SystemTime::now(), Duration::from_secs(1)).unwrap();
        let hgrm = std::fs::read_to_string(&files[0]).unwrap();
        assert!(
            hgrm.contains("Percentile") && hgrm.contains("#[Max"),
            "{hgrm}"
        );
        let hlog = std::fs::read(&files[1]).unwrap();
        let n = hdrhistogram::serialization::interval_log::IntervalLogIterator::new(&hlog)
            .filter(|e| {
                matches!(
                    e,
                    Ok(hdrhistogram::serialization::interval_log::LogEntry::Interval(_))
                )
            })
            .count();
        assert_eq!(n, 1);
        let back = read_interval_log(&files[1]).unwrap();
        assert_eq!((back.len(), back.max()), (h.len(), h.max()));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
