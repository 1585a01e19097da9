//! Tests of the reporter's files on a failing disk: interval logs keep whole lines and
//! count the intervals they lost, percentile files are complete or absent, the summary
//! carries the failures and the totals lose nothing.

use std::path::PathBuf;
use std::time::Duration;

use hdrhistogram::serialization::interval_log::{IntervalLogIterator, LogEntry};

use super::interval_logs::LogTarget;
use super::*;
use crate::logging::full_disk::FullDisk;

/// A fresh, empty scratch folder for one test.
fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "service-telemetry-disk-{}-{}",
        name,
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn timing(seq: u64) -> CycleTiming {
    CycleTiming {
        seq,
        wakeup_ns: 2_000 + seq % 1_000,
        compute_ns: 15_000 + seq % 3_000,
        response_ns: 30_000 + (seq * 7_919) % 90_000,
        period_jitter_ns: Some(seq % 5_000),
    }
}

/// Parses an interval log completely (header, then whole lines); returns the number of
/// intervals in it.
fn parse_whole_log(bytes: &[u8]) -> usize {
    assert!(bytes.ends_with(b"\n"), "torn last line");
    let mut intervals = 0;
    for entry in IntervalLogIterator::new(bytes) {
        if let LogEntry::Interval(_) = entry.expect("every line parses") {
            intervals += 1;
        }
    }
    intervals
}

#[test]
fn interval_logs_on_a_full_disk_keep_whole_lines_and_the_summary_reports_the_loss() {
    let dir = scratch_dir("hlog");
    let (mut rt, mut reporter) = channel_in_memory(100_000, 500, 2);
    // Each disk holds the header and a few intervals (a line is a few hundred bytes).
    let disks: Vec<FullDisk> = (0..4).map(|_| FullDisk::with_capacity(2_500)).collect();
    let targets: [LogTarget; 4] = std::array::from_fn(|i| Box::new(disks[i].clone()) as LogTarget);
    reporter
        .open_logs_into(&dir, targets, Duration::from_secs(3_600))
        .unwrap();
    for seq in 0..20_000 {
        rt.record(&timing(seq));
        if seq % 500 == 499 {
            reporter.poll().unwrap();
        }
    }
    rt.flush();
    let summary = reporter.finish().unwrap();

    // The totals lose nothing to the disk.
    assert_eq!(summary.response.count, 20_000);
    assert_eq!(summary.intervals, 40);
    // Each log: whole lines, the intervals written + lost = all of them.
    assert_eq!(summary.file_errors.len(), 4, "{:?}", summary.file_errors);
    for (kind, disk) in HistogramKind::ALL.iter().zip(&disks) {
        let written = parse_whole_log(&disk.content());
        assert!(written > 0 && written < 40, "{}: {written}", kind.name());
        let health = summary
            .file_errors
            .iter()
            .find(|h| h.path.ends_with(&format!("{}.hlog", kind.name())))
            .unwrap();
        assert_eq!(health.records_written, written as u64);
        assert_eq!(health.records_written + health.records_lost, 40);
        assert_eq!(health.failures, 1);
        assert!(health.intact);
        assert!(
            health
                .first_error
                .as_deref()
                .unwrap()
                .contains("No space left on device")
        );
    }
    // The percentile files went to a healthy folder: complete.
    for kind in HistogramKind::ALL {
        let text = std::fs::read_to_string(dir.join(format!("{}.hgrm", kind.name()))).unwrap();
        assert!(text.contains("#[Buckets"), "{}", kind.name());
    }
    let table = summary.render_table(100_000);
    assert_eq!(table.matches("FILE WRITE FAILED").count(), 4, "{table}");
    let json = serde_json::to_value(&summary).unwrap();
    assert_eq!(json["file_errors"].as_array().unwrap().len(), 4);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_percentile_file_that_cannot_be_written_is_absent_listed_and_the_others_are_written() {
    let dir = scratch_dir("hgrm");
    let (mut rt, reporter) = channel(100_000, 0, 1, &dir).unwrap();
    // A non-empty folder in the way of response.hgrm: the rename fails.
    std::fs::create_dir_all(dir.join("response.hgrm").join("blocker")).unwrap();
    for seq in 0..1_000 {
        rt.record(&timing(seq));
    }
    rt.flush();
    let summary = reporter.finish().unwrap();
    assert_eq!(summary.response.count, 1_000);
    assert_eq!(summary.file_errors.len(), 1, "{:?}", summary.file_errors);
    let failed = &summary.file_errors[0];
    assert!(failed.path.ends_with("response.hgrm"));
    assert_eq!((failed.records_lost, failed.failures), (1, 1));
    assert!(
        failed
            .first_error
            .as_deref()
            .unwrap()
            .contains("response.hgrm")
    );
    assert!(dir.join("response.hgrm").join("blocker").is_dir());
    for kind in [
        HistogramKind::Wakeup,
        HistogramKind::Compute,
        HistogramKind::Jitter,
    ] {
        assert!(dir.join(format!("{}.hgrm", kind.name())).is_file());
    }
    // No temporary file is left behind.
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
    let _ = std::fs::remove_dir_all(&dir);
}
