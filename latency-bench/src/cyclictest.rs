//! The machine's own wake-up floor: cyclictest (Debian package `rt-tests`) on the RT core
//! at the loop's interval, when it is installed.
//!
//! cyclictest sleeps on absolute `CLOCK_MONOTONIC` deadlines (`clock_nanosleep`,
//! `TIMER_ABSTIME`) every interval and records how late each wake-up was. It is run as
//!
//! ```text
//! cyclictest -m -q -p 80 -a <core> -t 1 -i 125 -D <seconds>s -h 1000
//! ```
//!
//! `-h 1000` makes it print, at exit, a histogram with one line per whole microsecond
//! (`000017 004162`: 4162 wake-ups between 17 µs and 18 µs late; cyclictest truncates
//! its latency to whole µs) up to 999 µs, then a footer:
//!
//! ```text
//! # Total: 000015995           ← wake-ups inside the histogram (overflows excluded)
//! # Min Latencies: 00010
//! # Avg Latencies: 00017
//! # Max Latencies: 00185       ← exact maximum, µs
//! # Histogram Overflows: 00000 ← wake-ups ≥ 1000 µs late
//! # Histogram Overflow at cycle number:
//! # Thread 0: ...
//! ```
//!
//! [`CyclictestHistogram::percentile_us`] computes a percentile from those lines: the
//! first bucket whose cumulative count reaches `q` of all wake-ups (overflows included),
//! reported at the middle of the bucket (`i + 0.5` µs) because bucket `i` holds latencies
//! in `[i, i + 1)` µs; a percentile that falls among the overflows is reported as the
//! maximum. `-N` (nanoseconds) is not used: it changes the histogram's bucket unit to ns.

use std::path::PathBuf;
use std::process::Command;

/// cyclictest's histogram of one thread.
#[derive(Debug, Clone, PartialEq)]
pub struct CyclictestHistogram {
    /// `buckets[i]`: wake-ups between `i` and `i + 1` µs late.
    pub buckets: Vec<u64>,
    /// Wake-ups beyond the histogram's range.
    pub overflows: u64,
    /// `# Min Latencies`, µs.
    pub min_us: Option<u64>,
    /// `# Avg Latencies`, µs.
    pub avg_us: Option<u64>,
    /// `# Max Latencies`, µs.
    pub max_us: Option<u64>,
}

impl CyclictestHistogram {
    /// Parses cyclictest's `-h` output (the first thread's column). Lines that are neither
    /// histogram rows nor known footer lines are ignored.
    pub fn parse(text: &str) -> Result<Self, String> {
        let mut buckets: Vec<u64> = Vec::new();
        let mut overflows = 0;
        let (mut min_us, mut avg_us, mut max_us) = (None, None, None);
        let footer = |line: &str, key: &str| -> Option<u64> {
            let rest = line.strip_prefix(key)?;
            rest.split_whitespace().next()?.parse().ok()
        };
        for line in text.lines() {
            let line = line.trim();
            if let Some(comment) = line.strip_prefix('#') {
                let c = comment.trim();
                if let Some(v) = footer(c, "Min Latencies:") {
                    min_us = Some(v);
                } else if let Some(v) = footer(c, "Avg Latencies:") {
                    avg_us = Some(v);
                } else if let Some(v) = footer(c, "Max Latencies:") {
                    max_us = Some(v);
                } else if let Some(v) = footer(c, "Histogram Overflows:") {
                    overflows = v;
                }
                continue;
            }
            let mut cols = line.split_whitespace();
            let (Some(a), Some(b)) = (cols.next(), cols.next()) else {
                continue;
            };
            let (Ok(i), Ok(n)) = (a.parse::<usize>(), b.parse::<u64>()) else {
                continue;
            };
            if i > 10_000_000 {
                return Err(format!("histogram row '{line}' has an implausible bucket"));
            }
            if buckets.len() <= i {
                buckets.resize(i + 1, 0);
            }
            buckets[i] += n;
        }
        if buckets.is_empty() && overflows == 0 {
            return Err("no histogram in cyclictest's output (was -h given?)".into());
        }
        Ok(Self {
            buckets,
            overflows,
            min_us,
            avg_us,
            max_us,
        })
    }

    /// All wake-ups counted: histogram rows plus overflows.
    pub fn total(&self) -> u64 {
        self.buckets.iter().sum::<u64>() + self.overflows
    }

    /// The `q`-quantile (`0 < q ≤ 1`) in µs, at the middle of its 1 µs bucket; the maximum
    /// when it falls among the overflows; `None` when nothing was counted.
    pub fn percentile_us(&self, q: f64) -> Option<f64> {
        let total = self.total();
        if total == 0 {
            return None;
        }
        let target = ((q.clamp(0.0, 1.0) * total as f64).ceil() as u64).max(1);
        let mut cum = 0;
        for (i, n) in self.buckets.iter().enumerate() {
            cum += n;
            if cum >= target {
                return Some(i as f64 + 0.5);
            }
        }
        Some(
            self.max_us
                .map(|m| m as f64)
                .unwrap_or(self.buckets.len() as f64),
        )
    }

    /// The maximum in µs: cyclictest's exact `Max Latencies`, else the last non-empty
    /// bucket's upper edge.
    pub fn max(&self) -> Option<f64> {
        self.max_us.map(|m| m as f64).or_else(|| {
            self.buckets
                .iter()
                .rposition(|n| *n > 0)
                .map(|i| i as f64 + 1.0)
        })
    }

    /// The histogram as an HdrHistogram in ns (each bucket at its middle, overflows at the
    /// maximum), for the `.hgrm`/`.hlog` files.
    pub fn to_hdr(&self) -> hdrhistogram::Histogram<u64> {
        let mut h = crate::hist::new_histogram();
        for (i, n) in self.buckets.iter().enumerate() {
            if *n > 0 {
                h.saturating_record_n(i as u64 * 1_000 + 500, *n);
            }
        }
        if self.overflows > 0 {
            let max = self.max_us.unwrap_or(self.buckets.len() as u64);
            h.saturating_record_n(max * 1_000, self.overflows);
        }
        h
    }
}

/// Where cyclictest is on `PATH`, if it is.
pub fn find() -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join("cyclictest"))
        .find(|p| p.is_file())
}

/// What one cyclictest run gave.
#[derive(Debug, Clone)]
pub struct CyclictestRun {
    /// The command line run.
    pub command: String,
    /// Its whole standard output and error.
    pub output: String,
    /// The parsed histogram.
    pub histogram: CyclictestHistogram,
}

/// Runs cyclictest on `core` every `interval_us` for `seconds` at [`crate::RT_PRIORITY`],
/// histogram up to 1000 µs.
pub fn run(
    exe: &std::path::Path,
    core: usize,
    interval_us: u64,
    seconds: u64,
) -> Result<CyclictestRun, String> {
    let args: Vec<String> = [
        "-m".to_string(),
        "-q".into(),
        "-p".into(),
        crate::RT_PRIORITY.to_string(),
        "-a".into(),
        core.to_string(),
        "-t".into(),
        "1".into(),
        "-i".into(),
        interval_us.to_string(),
        "-D".into(),
        format!("{seconds}s"),
        "-h".into(),
        "1000".into(),
    ]
    .into();
    let command = format!("{} {}", exe.display(), args.join(" "));
    let out = Command::new(exe)
        .args(&args)
        .output()
        .map_err(|e| format!("{command}: {e}"))?;
    let mut output = String::from_utf8_lossy(&out.stdout).into_owned();
    output.push_str(&String::from_utf8_lossy(&out.stderr));
    if !out.status.success() {
        return Err(format!(
            "{command} failed ({}): {}",
            out.status,
            tail(&output, 600)
        ));
    }
    let histogram = CyclictestHistogram::parse(&output).map_err(|e| format!("{command}: {e}"))?;
    Ok(CyclictestRun {
        command,
        output,
        histogram,
    })
}

fn tail(s: &str, n: usize) -> &str {
    let start = s.len().saturating_sub(n);
    let mut i = start;
    while !s.is_char_boundary(i) {
        i += 1;
    }
    &s[i..]
}

#[cfg(test)]
mod tests {
    use super::*;

    const SAMPLE: &str = "# /dev/cpu_dma_latency set to 0us
# Histogram
000000 000000
000001 000000
000002 000050
000003 000040
000004 000009
000005 000000
000006 000001
# Total: 000000100
# Min Latencies: 00002
# Avg Latencies: 00002
# Max Latencies: 01234
# Histogram Overflows: 00000
# Histogram Overflow at cycle number:
# Thread 0:
";

    #[test]
    fn percentiles_come_from_the_cumulative_histogram_at_bucket_middles() {
        let h = CyclictestHistogram::parse(SAMPLE).unwrap();
        assert_eq!(h.total(), 100);
        assert_eq!(h.max_us, Some(1234));
        assert_eq!(h.min_us, Some(2));
        assert_eq!(h.percentile_us(0.5), Some(2.5));
        assert_eq!(h.percentile_us(0.51), Some(3.5));
        assert_eq!(h.percentile_us(0.90), Some(3.5));
        assert_eq!(h.percentile_us(0.99), Some(4.5));
        assert_eq!(h.percentile_us(1.0), Some(6.5));
        assert_eq!(h.max(), Some(1234.0));
    }

    #[test]
    fn a_percentile_among_the_overflows_is_the_maximum() {
        let text = SAMPLE.replace(
            "# Histogram Overflows: 00000",
            "# Histogram Overflows: 00010",
        ) + "# Thread 0: 00012 00013 00014\n";
        let h = CyclictestHistogram::parse(&text).unwrap();
        assert_eq!(h.total(), 110);
        assert_eq!(h.percentile_us(0.5), Some(3.5));
        assert_eq!(h.percentile_us(0.95), Some(1234.0));
    }

    #[test]
    fn output_without_a_histogram_is_refused() {
        assert!(
            CyclictestHistogram::parse("T: 0 ( 1) P:80 I:125 C: 100 Min: 2 Act: 3 Avg: 3 Max: 9")
                .is_err()
        );
    }

    #[test]
    fn the_hdr_copy_keeps_counts_and_medians() {
        let h = CyclictestHistogram::parse(SAMPLE).unwrap().to_hdr();
        assert_eq!(h.len(), 100);
        let p50 = h.value_at_quantile(0.5);
        assert!((2_490..=2_510).contains(&p50), "{p50}");
    }
}
