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

use crate::cli::Settings;
use crate::hist;
use crate::report::{Collected, Measured};
use crate::table::fmt_ratio;
use crate::{PERIOD_NS, progress};
use serde_json::{Map, Value, json};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Instant, SystemTime};

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
    ///
    /// The rank is found by the bench's one quantile helper, [`hist::quantile`], on
    /// [`Self::to_hdr`] (which records bucket `i` at its middle `i + 0.5` µs): the median
    /// equivalent of the value found is less than half a µs from that middle, so it names
    /// the bucket exactly.
    pub fn percentile_us(&self, q: f64) -> Option<f64> {
        if self.total() == 0 {
            return None;
        }
        let h = self.to_hdr();
        let bucket = (h.median_equivalent(hist::quantile(&h, q.clamp(0.0, 1.0))) / 1_000) as usize;
        Some(if bucket < self.buckets.len() {
            bucket as f64 + 0.5
        } else {
            self.max_us
                .map(|m| m as f64)
                .unwrap_or(self.buckets.len() as f64)
        })
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
        let mut h = hist::new_histogram();
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

/// The cyclictest phase of the full run: cyclictest on the RT core for `s.seconds`
/// (rounded up) into `dir`, unless it is skipped or not installed. Adds its block to
/// `col.extra` and, to each service wake-up row already in `col.measured`, its ratios to
/// cyclictest at p50, p99 and max. Returns the cyclictest row and those ratios (the
/// `wakeup_over_cyclictest` block of `summary.json`).
pub fn cyclictest_phase(
    s: &Settings,
    dir: &Path,
    col: &mut Collected,
) -> (Measured, Map<String, Value>) {
    progress("5/6 cyclictest");
    let ct_label = format!("cyclictest (core {}, {} µs)", s.rt_core, PERIOD_NS / 1_000);
    let ct = run_into(s, dir);
    let ct_measured = match &ct {
        Ok(Some((run, files))) => {
            let h = &run.histogram;
            let us = [
                h.percentile_us(0.5),
                h.percentile_us(0.99),
                h.percentile_us(0.999),
                h.max(),
            ];
            col.extra.insert(
                "cyclictest".into(),
                json!({
                    "command": run.command, "total": h.total(), "overflows": h.overflows,
                    "min_us": h.min_us, "avg_us": h.avg_us, "max_us": h.max_us,
                    "p50_us": us[0], "p99_us": us[1], "p99_9_us": us[2],
                    "percentiles": "from its 1 µs histogram, at bucket middles",
                }),
            );
            Measured {
                id: "cyclictest".into(),
                label: ct_label,
                count: Some(h.total()),
                us,
                summary: None,
                note: "machine floor; percentiles ±0.5 µs (1 µs buckets)".into(),
                files: files.clone(),
                error: None,
            }
        }
        Ok(None) => {
            let why = if s.cyclictest {
                "cyclictest not installed"
            } else {
                "skipped (--skip-cyclictest)"
            };
            col.extra.insert("cyclictest".into(), json!(why));
            Measured::empty("cyclictest", &ct_label, why)
        }
        Err(e) => Measured::failed("cyclictest", &ct_label, e.clone()),
    };
    // Ratios of the service wake-up to the machine floor.
    let mut wake_ratios = serde_json::Map::new();
    if ct_measured.error.is_none() && ct_measured.count.is_some() {
        for m in col
            .measured
            .iter_mut()
            .filter(|m| m.id.starts_with("wakeup-"))
        {
            if let Some(sum) = m.summary {
                let r = |v: u64, c: Option<f64>| c.filter(|c| *c > 0.0).map(|c| v as f64 / 1e3 / c);
                let (p50, p99, max) = (
                    r(sum.p50_ns, ct_measured.us[0]),
                    r(sum.p99_ns, ct_measured.us[1]),
                    r(sum.max_ns, ct_measured.us[3]),
                );
                let skipped = std::mem::take(&mut m.note);
                m.note = format!(
                    "÷ cyclictest: p50 {}, p99 {}, max {}",
                    fmt_ratio(p50),
                    fmt_ratio(p99),
                    fmt_ratio(max)
                );
                if !skipped.is_empty() {
                    m.note = format!("{}; {skipped}", m.note);
                }
                wake_ratios.insert(
                    m.id.trim_start_matches("wakeup-").to_string(),
                    json!({ "p50": p50, "p99": p99, "max": max }),
                );
            }
        }
    }
    (ct_measured, wake_ratios)
}

/// Runs cyclictest into `dir` (its output as `cyclictest.txt`, its histogram as
/// `.hgrm`/`.hlog`); `None` when it is skipped or not installed.
fn run_into(s: &Settings, dir: &Path) -> Result<Option<(CyclictestRun, Vec<PathBuf>)>, String> {
    if !s.cyclictest {
        return Ok(None);
    }
    let Some(exe) = find() else {
        return Ok(None);
    };
    std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    let seconds = s.seconds.ceil().max(1.0) as u64;
    let start = SystemTime::now();
    let t = Instant::now();
    let run = run(&exe, s.rt_core, PERIOD_NS / 1_000, seconds)?;
    let elapsed = t.elapsed();
    let _ = std::fs::write(
        dir.join("cyclictest.txt"),
        format!("$ {}\n{}", run.command, run.output),
    );
    let mut files = vec![dir.join("cyclictest.txt")];
    if let Ok(f) = hist::write_files(dir, "cyclictest", &run.histogram.to_hdr(), start, elapsed) {
        files.extend(f);
    }
    Ok(Some((run, files)))
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
    fn every_bucket_up_to_the_last_is_found_at_its_middle() {
        let mut text = String::new();
        for i in 0..1000 {
            text.push_str(&format!("{i:06} 000001\n"));
        }
        text.push_str("# Max Latencies: 00999\n");
        let h = CyclictestHistogram::parse(&text).unwrap();
        for i in 0..1000u64 {
            let q = (i + 1) as f64 / 1000.0;
            assert_eq!(h.percentile_us(q), Some(i as f64 + 0.5), "bucket {i}");
        }
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
