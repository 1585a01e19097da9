//! Tests of the telemetry module as a whole (the box-accounting tests live next to the
//! swap code in `swap.rs`).

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::Duration;

use hdrhistogram::Histogram;
use hdrhistogram::serialization::Deserializer;
use hdrhistogram::serialization::interval_log::{IntervalLogIterator, LogEntry};

use super::*;

/// A fresh, empty scratch folder for one test.
fn scratch_dir(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("service-telemetry-{}-{}", name, std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn timing(seq: u64, response_ns: u64) -> CycleTiming {
    CycleTiming {
        seq,
        wakeup_ns: 2_000,
        compute_ns: 15_000,
        response_ns,
        period_jitter_ns: if seq == 0 { None } else { Some(500) },
    }
}

/// Within the histogram's 3-significant-figure resolution.
fn close(actual: u64, expected: u64) -> bool {
    actual.abs_diff(expected) as f64 <= expected as f64 * 1e-3 + 1.0
}

#[test]
fn known_values_give_the_expected_percentiles_and_counts() {
    let mut h = LoopHistograms::new(900_000);
    // Response times 1 µs, 2 µs, …, 1000 µs.
    for i in 1..=1_000u64 {
        h.record(&timing(i, i * 1_000));
    }
    assert_eq!(h.cycles(), 1_000);
    assert_eq!(h.response().len(), 1_000);
    assert_eq!(h.wakeup().len(), 1_000);
    assert_eq!(h.compute().len(), 1_000);
    assert_eq!(h.jitter().len(), 1_000);
    assert!(close(h.response().value_at_quantile(0.5), 500_000));
    assert!(close(h.response().value_at_quantile(0.99), 990_000));
    assert!(close(h.response().max(), 1_000_000));
    assert!(close(h.response().min(), 1_000));
    assert_eq!(h.over_budget(), 100);

    let s = TelemetrySummary::from_totals(&h, 0, 0, 1);
    assert_eq!(s.response.count, 1_000);
    assert!(close(s.response.p50, 500_000));
    assert!(close(s.response.p90, 900_000));
    assert!(close(s.response.p99_9, 999_000));
    assert!(close(s.response.p99_99, 1_000_000));
    assert!((s.response.mean - 500_500.0).abs() < 500.0);
    assert_eq!(s.response.over_budget, 100);
    assert_eq!(s.wakeup.over_budget, 0);
    assert!(s.wakeup.worst.is_empty());
    let seqs: Vec<u64> = s.response.worst.iter().map(|&(seq, _)| seq).collect();
    assert_eq!(seqs, (991..=1_000).rev().collect::<Vec<_>>());
    assert_eq!(s.response.worst[0].1, 1_000_000);
    assert!(close(s.wakeup.p99_99, 2_000));
    assert_eq!(s.response.unit, "ns");
}

#[test]
fn the_first_cycle_without_a_period_jitter_is_not_recorded_in_the_jitter_histogram() {
    let mut h = LoopHistograms::new(u64::MAX);
    h.record(&timing(0, 10));
    h.record(&timing(1, 10));
    assert_eq!(h.jitter().len(), 1);
    assert_eq!(h.response().len(), 2);
    assert_eq!(h.over_budget(), 0);
}

#[test]
fn out_of_range_values_saturate_instead_of_failing() {
    let mut h = LoopHistograms::new(1_000);
    h.record(&CycleTiming {
        seq: 7,
        wakeup_ns: 0,
        compute_ns: u64::MAX,
        response_ns: 50 * HIGHEST_TRACKABLE_NS,
        period_jitter_ns: Some(u64::MAX),
    });
    assert_eq!(h.compute().len(), 1);
    assert!(close(h.compute().max(), HIGHEST_TRACKABLE_NS));
    assert!(close(h.response().max(), HIGHEST_TRACKABLE_NS));
    assert_eq!(h.wakeup().min(), 0);
    assert_eq!(h.over_budget(), 1);
    // The worst-cycle tracker keeps the true value.
    assert_eq!(h.worst().entries(), &[(7, 50 * HIGHEST_TRACKABLE_NS)]);
}

#[test]
fn the_worst_cycles_tracker_keeps_the_k_largest_and_the_earliest_on_ties() {
    let mut w = WorstCycles::new();
    let values = [5u64, 90, 3, 70, 70, 8, 100, 1, 60, 2, 99, 70, 4, 80, 0];
    for (seq, &v) in values.iter().enumerate() {
        w.offer(seq as u64, v);
    }
    assert_eq!(w.len(), WORST_K);
    let (sorted, n) = w.sorted();
    let got: Vec<(u64, u64)> = sorted[..n].to_vec();
    assert_eq!(
        got,
        vec![
            (6, 100),
            (10, 99),
            (1, 90),
            (13, 80),
            (3, 70),
            (4, 70),
            (11, 70),
            (8, 60),
            (5, 8),
            (0, 5)
        ]
    );
    w.clear();
    assert!(w.is_empty());
}

#[test]
fn adding_sets_merges_counts_worst_cycles_and_intervals() {
    let mut a = LoopHistograms::new(5_000);
    let mut b = LoopHistograms::new(5_000);
    a.begin_interval(100);
    a.end_interval(200);
    b.begin_interval(200);
    b.end_interval(300);
    for i in 0..100 {
        a.record(&timing(i, 1_000 + i));
        b.record(&timing(100 + i, 10_000 + i));
    }
    a.add(&b);
    assert_eq!(a.cycles(), 200);
    assert_eq!(a.response().len(), 200);
    assert_eq!(a.over_budget(), 100);
    assert_eq!(a.interval_start_ns(), 100);
    assert_eq!(a.interval_end_ns(), 300);
    assert_eq!(a.worst().sorted().0[0], (199, 10_099));
    a.reset();
    assert_eq!(a.cycles(), 0);
    assert!(a.response().is_empty());
    assert!(a.worst().is_empty());
    assert_eq!(a.budget_ns(), 5_000);
}

#[test]
fn the_swap_between_two_threads_loses_no_sample() {
    const CYCLES: u64 = 200_000;
    let (mut rt, mut reporter) = channel_in_memory(25_000, 997, 2);
    let done = Arc::new(AtomicBool::new(false));

    let rt_done = Arc::clone(&done);
    let producer = thread::spawn(move || {
        for seq in 0..CYCLES {
            rt.record(&timing(seq, 10_000 + seq % 20_000));
            if seq % 10_000 == 0 {
                // Give the reporter a chance to lag behind now and then.
                thread::yield_now();
            }
        }
        rt.flush();
        rt_done.store(true, Ordering::Release);
        (rt.missed_swaps(), rt.unrecorded_cycles())
    });

    let mut drained = 0;
    while !done.load(Ordering::Acquire) {
        drained += reporter.poll().unwrap();
        thread::sleep(Duration::from_micros(200));
    }
    let (missed, unrecorded) = producer.join().unwrap();
    drained += reporter.poll().unwrap();
    assert!(drained >= 1);
    let summary = reporter.finish().unwrap();
    assert_eq!(unrecorded, 0);
    assert_eq!(summary.missed_swaps, missed);
    assert_eq!(summary.response.count, CYCLES);
    assert_eq!(summary.wakeup.count, CYCLES);
    assert_eq!(summary.compute.count, CYCLES);
    assert_eq!(summary.jitter.count, CYCLES - 1);
    assert_eq!(
        summary.response.over_budget,
        (CYCLES / 20_000) * (20_000 - 15_001)
    );
}

/// Minimal standard-alphabet base64 decoder for reading interval logs back.
fn base64_decode(s: &str) -> Vec<u8> {
    fn sextet(c: u8) -> u32 {
        match c {
            b'A'..=b'Z' => u32::from(c - b'A'),
            b'a'..=b'z' => u32::from(c - b'a') + 26,
            b'0'..=b'9' => u32::from(c - b'0') + 52,
            b'+' => 62,
            b'/' => 63,
            _ => panic!("not base64: {c}"),
        }
    }
    let bytes: Vec<u8> = s.bytes().filter(|&c| c != b'=').collect();
    let mut out = Vec::with_capacity(bytes.len() * 3 / 4);
    for chunk in bytes.chunks(4) {
        let mut acc = 0u32;
        for (i, &c) in chunk.iter().enumerate() {
            acc |= sextet(c) << (18 - 6 * i as u32);
        }
        let n = chunk.len() - 1;
        for i in 0..n {
            out.push((acc >> (16 - 8 * i as u32)) as u8);
        }
    }
    out
}

#[test]
fn the_output_files_parse_back() {
    let dir = scratch_dir("files");
    let (mut rt, mut reporter) = channel(40_000, 1_000, 1, &dir).unwrap();
    assert_eq!(reporter.output_dir(), Some(dir.as_path()));
    for seq in 0..5_000u64 {
        rt.record(&timing(seq, 20_000 + 10 * (seq % 3_000)));
        if seq % 1_000 == 999 {
            assert_eq!(reporter.poll().unwrap(), 1);
        }
    }
    rt.record(&timing(5_000, 20_000));
    assert!(rt.flush());
    let summary = reporter.finish().unwrap();
    assert_eq!(summary.intervals, 6);
    assert_eq!(summary.response.count, 5_001);

    // Interval logs: non-empty, parseable, tagged, and the intervals add up.
    for kind in HistogramKind::ALL {
        let bytes = std::fs::read(dir.join(format!("{}.hlog", kind.name()))).unwrap();
        assert!(!bytes.is_empty());
        let mut intervals = 0;
        let mut total = 0;
        let mut saw_start_time = false;
        let mut last_start = Duration::ZERO;
        for entry in IntervalLogIterator::new(&bytes) {
            match entry.unwrap() {
                LogEntry::StartTime(_) => saw_start_time = true,
                LogEntry::BaseTime(_) => {}
                LogEntry::Interval(ilh) => {
                    assert_eq!(ilh.tag().map(|t| t.as_str()), Some(kind.name()));
                    assert!(ilh.start_timestamp() >= last_start);
                    last_start = ilh.start_timestamp();
                    let raw = base64_decode(ilh.encoded_histogram());
                    let h: Histogram<u64> = Deserializer::new()
                        .deserialize(&mut raw.as_slice())
                        .unwrap();
                    total += h.len();
                    intervals += 1;
                }
            }
        }
        assert!(saw_start_time);
        assert_eq!(intervals, 6, "{}", kind.name());
        let expected = if kind == HistogramKind::Jitter {
            5_000
        } else {
            5_001
        };
        assert_eq!(total, expected, "{}", kind.name());
    }

    // Percentile distribution: header, first rows, last row and footer.
    let text = std::fs::read_to_string(dir.join("response.hgrm")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let header: Vec<&str> = lines[0].split_whitespace().collect();
    assert_eq!(
        header,
        ["Value", "Percentile", "TotalCount", "1/(1-Percentile)"]
    );
    assert!(lines[1].is_empty());
    let rows: Vec<Vec<&str>> = lines[2..]
        .iter()
        .take_while(|l| !l.starts_with('#'))
        .map(|l| l.split_whitespace().collect())
        .collect();
    assert!(rows.len() > 20);
    let first = &rows[0];
    assert_eq!(first.len(), 4);
    let v0: f64 = first[0].parse().unwrap();
    assert!((v0 - 20.0).abs() < 0.05, "first value {v0} µs");
    assert_eq!(first[1].parse::<f64>().unwrap(), 0.0);
    assert!(first[2].parse::<u64>().unwrap() >= 1);
    assert_eq!(first[3].parse::<f64>().unwrap(), 1.0);
    let p50_row = rows
        .iter()
        .find(|r| r[1].parse::<f64>().unwrap() >= 0.5)
        .unwrap();
    let p50: f64 = p50_row[0].parse().unwrap();
    assert!((p50 * 1_000.0 - summary.response.p50 as f64).abs() < 1.0);
    let last = rows.last().unwrap();
    assert_eq!(last.len(), 3);
    assert_eq!(last[1].parse::<f64>().unwrap(), 1.0);
    assert_eq!(last[2].parse::<u64>().unwrap(), 5_001);
    let mut counts: Vec<u64> = rows.iter().map(|r| r[2].parse().unwrap()).collect();
    let unsorted = counts.clone();
    counts.sort_unstable();
    assert_eq!(counts, unsorted, "TotalCount is cumulative");

    let footer: Vec<&str> = lines
        .iter()
        .copied()
        .filter(|l| l.starts_with("#["))
        .collect();
    assert_eq!(footer.len(), 3);
    assert!(footer[0].starts_with("#[Mean    = "));
    assert!(footer[0].contains("StdDeviation   = "));
    let max_field = footer[1]
        .trim_start_matches("#[Max     = ")
        .split(',')
        .next()
        .unwrap()
        .trim();
    let max_us: f64 = max_field.parse().unwrap();
    assert!((max_us * 1_000.0 - summary.response.max as f64).abs() < 1.0);
    assert!(footer[1].trim_end_matches(']').ends_with("5001"));
    assert!(footer[2].starts_with("#[Buckets = "));
    assert!(footer[2].contains("SubBuckets     =         2048]"));

    for kind in HistogramKind::ALL {
        assert!(dir.join(format!("{}.hgrm", kind.name())).exists());
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn an_empty_run_writes_header_and_footer_only() {
    let dir = scratch_dir("empty");
    let (mut rt, reporter) = channel(40_000, 1_000, 1, &dir).unwrap();
    assert!(!rt.flush());
    let summary = reporter.finish().unwrap();
    assert_eq!(summary.response.count, 0);
    assert_eq!(summary.response.max, 0);
    let text = std::fs::read_to_string(dir.join("compute.hgrm")).unwrap();
    assert_eq!(text.lines().count(), 5);
    assert!(text.contains("Total count    =            0]"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_table_lists_every_histogram_and_the_worst_cycles() {
    let (mut rt, reporter) = channel_in_memory(100_000, 0, 1);
    for seq in 0..1_000 {
        rt.record(&timing(seq, if seq == 123 { 250_000 } else { 30_000 }));
    }
    rt.flush();
    let summary = reporter.finish().unwrap();
    let table = summary.render_table(100_000);
    println!("{table}");
    let lines: Vec<&str> = table.lines().collect();
    assert!(lines[0].contains("budget 100.000 us"));
    assert!(lines[1].starts_with("histogram"));
    for (line, name) in lines[2..6]
        .iter()
        .zip(["wakeup", "compute", "response", "jitter"])
    {
        assert!(line.starts_with(name), "{line}");
    }
    let response: Vec<&str> = lines[4].split_whitespace().collect();
    assert_eq!(response[1], "1000");
    assert_eq!(response[7], "1");
    assert!(lines[6].starts_with("worst response cycles: seq 123 (250."));
    assert!(
        lines[6].contains("seq 0 (30."),
        "earliest kept on ties: {}",
        lines[6]
    );
    assert!(lines[7].starts_with("missed swaps: 0"));

    let json = serde_json::to_value(&summary).unwrap();
    assert_eq!(json["response"]["over_budget"], 1);
    assert_eq!(json["response"]["worst"][0][0], 123);
    assert_eq!(json["compute"]["unit"], "ns");
    assert_eq!(json["missed_swaps"], 0);
}

#[test]
fn period_jitter_is_the_absolute_deviation_from_the_period() {
    assert_eq!(
        CycleTiming::period_jitter(1_125_300, 1_000_000, 125_000),
        300
    );
    assert_eq!(
        CycleTiming::period_jitter(1_124_000, 1_000_000, 125_000),
        1_000
    );
}
