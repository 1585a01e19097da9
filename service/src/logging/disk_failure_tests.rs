//! Tests of the signal log on a failing disk: whole records only, failures counted and
//! kept apart from queue drops, the queue drained throughout, writing resumed when space
//! frees up.

use std::path::PathBuf;
use std::thread;
use std::time::{Duration, Instant};

use super::full_disk::FullDisk;
use super::*;

/// Never retry within a test.
const NO_RETRY: Duration = Duration::from_secs(3_600);

/// A record of `n` bytes (including the line end), different for each `seq`.
fn record_bytes(seq: u64, n: usize) -> Vec<u8> {
    let mut r = format!("{seq}:").into_bytes();
    while r.len() + 1 < n {
        r.push(b'a' + (seq % 26) as u8);
    }
    r.push(b'\n');
    r
}

/// Checks that `text` is a preamble followed by whole records of the form
/// `<seq>:<letters>\n`; returns their sequence numbers.
fn whole_records(text: &str, preamble: &str) -> Vec<u64> {
    let body = text.strip_prefix(preamble).expect("the preamble is intact");
    assert!(
        body.is_empty() || body.ends_with('\n'),
        "torn last record: {:?}",
        &body[body.len().saturating_sub(40)..]
    );
    body.lines()
        .map(|l| {
            let (seq, fill) = l.split_once(':').expect("a whole record");
            let seq: u64 = seq.parse().unwrap();
            let letter = (b'a' + (seq % 26) as u8) as char;
            assert!(fill.chars().all(|c| c == letter), "torn record {l:?}");
            seq
        })
        .collect()
}

#[test]
fn a_full_disk_leaves_only_whole_records_and_counts_the_rest() {
    let disk = FullDisk::with_capacity(1_000);
    let mut file = RecordFile::new(disk.clone(), "sim/signals.csv".into(), 64, NO_RETRY);
    file.write_preamble(b"header\n").unwrap();
    // Records of 7 … 29 bytes: the capacity falls inside a record.
    for seq in 0..200u64 {
        file.push(&record_bytes(seq, 7 + (seq as usize * 7) % 23));
    }
    let health = file.finish();

    let seqs = whole_records(&disk.text(), "header\n");
    assert!(!seqs.is_empty());
    assert_eq!(seqs, (0..seqs.len() as u64).collect::<Vec<_>>());
    assert_eq!(health.records_written, seqs.len() as u64);
    assert_eq!(health.records_written + health.records_lost, 200);
    assert!(health.records_lost > 0);
    assert_eq!(health.failures, 1, "no retry: one failure");
    assert!(health.intact);
    let error = health.first_error.unwrap();
    assert!(
        error.starts_with("writing sim/signals.csv: No space left on device"),
        "{error}"
    );
    // The disk took as much as whole records allow: the next record would not fit.
    let len = disk.content().len();
    let next = record_bytes(seqs.len() as u64, 7 + (seqs.len() * 7) % 23).len();
    assert!(len + next > 1_000, "{len} + {next}");
}

#[test]
fn a_write_failing_inside_the_buffer_keeps_the_records_before_the_failure() {
    // One big flush: 10 records of 10 bytes, room for 45 bytes: 4 whole records stay.
    let disk = FullDisk::with_capacity(45);
    let mut file = RecordFile::new(disk.clone(), "x.csv".into(), 1 << 20, NO_RETRY);
    for seq in 0..10 {
        file.push(&record_bytes(seq, 10));
    }
    file.flush();
    assert_eq!(disk.content().len(), 40);
    assert_eq!(whole_records(&disk.text(), ""), [0, 1, 2, 3]);
    assert_eq!(file.health().records_written, 4);
    assert_eq!(file.health().records_lost, 6);
    // While failing (no retry due), records are not even buffered.
    file.push(&record_bytes(10, 10));
    assert_eq!(file.health().records_lost, 7);
    assert!(!file.accepting());
}

#[test]
fn writing_resumes_after_space_is_freed_and_the_gap_is_counted() {
    let disk = FullDisk::with_capacity(100);
    let mut file = RecordFile::new(disk.clone(), "r.csv".into(), 1, Duration::ZERO);
    for seq in 0..30 {
        file.push(&record_bytes(seq, 10));
    }
    assert_eq!(file.health().records_written, 10);
    assert_eq!(file.health().records_lost, 20);
    // Every retry failed again: counted, not reported again.
    assert_eq!(file.health().failures, 20);
    disk.set_capacity(1_000);
    for seq in 30..40 {
        file.push(&record_bytes(seq, 10));
    }
    let health = file.finish();
    let seqs = whole_records(&disk.text(), "");
    let expected: Vec<u64> = (0..10).chain(30..40).collect();
    assert_eq!(seqs, expected);
    assert_eq!(health.records_written, 20);
    assert_eq!(health.records_lost, 20);
    assert!(
        health
            .first_error
            .unwrap()
            .contains("No space left on device")
    );
}

#[test]
fn an_io_error_writes_nothing_and_is_reported_with_its_os_error() {
    let disk = FullDisk::with_capacity(1 << 20);
    let mut file = RecordFile::new(disk.clone(), "eio.csv".into(), 32, NO_RETRY);
    file.write_preamble(b"h\n").unwrap();
    file.push(&record_bytes(0, 40));
    disk.set_io_error(true);
    for seq in 1..10 {
        file.push(&record_bytes(seq, 40));
    }
    let health = file.finish();
    assert_eq!(whole_records(&disk.text(), "h\n"), [0]);
    assert_eq!((health.records_written, health.records_lost), (1, 9));
    assert_eq!(health.failures, 1);
    assert!(
        health
            .first_error
            .unwrap()
            .starts_with("writing eio.csv: Input/output error"),
    );
}

#[test]
fn a_failed_cut_back_marks_the_file_as_not_intact_and_stops_writing_it() {
    let disk = FullDisk::with_capacity(25);
    disk.set_truncate_fails(true);
    let mut file = RecordFile::new(disk.clone(), "t.csv".into(), 1 << 20, Duration::ZERO);
    for seq in 0..5 {
        file.push(&record_bytes(seq, 10));
    }
    file.flush();
    assert!(!file.health().intact);
    disk.set_capacity(1_000);
    disk.set_truncate_fails(false);
    file.push(&record_bytes(5, 10));
    let health = file.finish();
    assert!(!health.intact);
    assert_eq!(health.records_written, 2);
    assert_eq!(health.records_lost, 4);
    assert_eq!(
        disk.content().len(),
        25,
        "nothing written after the failure"
    );
}

#[test]
fn a_preamble_that_does_not_fit_is_an_error_naming_the_file() {
    let disk = FullDisk::with_capacity(3);
    let mut file = RecordFile::new(disk.clone(), "run/signals.csv".into(), 64, NO_RETRY);
    let err = file.write_preamble(b"seq,t_sample_ns\n").unwrap_err();
    assert_eq!(err.kind(), std::io::ErrorKind::StorageFull);
    assert!(
        err.to_string().starts_with("writing run/signals.csv: "),
        "{err}"
    );
    assert!(disk.content().is_empty(), "cut back");
}

fn layout() -> LogLayout {
    LogLayout {
        n_y: 2,
        n_z: 1,
        n_u: 1,
        internal_names: vec!["theta_norm".into()],
        decimation: 1,
    }
}

fn record(seq: u64) -> LogRecord {
    let mut r = LogRecord::ZERO;
    r.seq = seq;
    r.t_sample_ns = 1_000_000_000 + seq * 125_000;
    r.y[0] = 1.0 / (seq as f64 + 3.0);
    r.y[1] = -(seq as f64) * 1e-9;
    r.z[0] = (seq as f64).sqrt();
    r.u[0] = std::f64::consts::PI * seq as f64;
    r.internals[0] = 1e300 / (seq as f64 + 1.0);
    r
}

/// The `seq` column of `text`, whose rows must all be whole ([`super::whole_rows`]).
fn assert_whole_rows(text: &str) -> Vec<u64> {
    super::whole_rows(text).unwrap_or_else(|e| panic!("signals.csv {e}"))
}

#[test]
fn the_csv_writer_on_a_full_disk_keeps_whole_rows_keeps_draining_and_reports_the_failure() {
    let disk = FullDisk::with_capacity(8 * 1024);
    let (mut producer, writer) = channel(32, layout());
    let counters = writer.counters();
    let path = PathBuf::from("/sim/run/signals.csv");
    let handle = writer
        .spawn_into(disk.clone(), path.clone(), NO_RETRY)
        .unwrap();

    // The "RT thread": push until the disk has failed (the writer counts losses).
    let mut seq = 0;
    let deadline = Instant::now() + Duration::from_secs(20);
    while counters.lost_to_disk() == 0 {
        assert!(Instant::now() < deadline, "the disk never filled");
        producer.push(&record(seq));
        seq += 1;
        if seq % 16 == 0 {
            thread::sleep(Duration::from_millis(1));
        }
    }
    // The writer still drains the queue: a full queue's worth, a pause, another one.
    for _ in 0..5 {
        for _ in 0..32 {
            assert_eq!(producer.push(&record(seq)), PushOutcome::Pushed);
            seq += 1;
        }
        let drained = Instant::now() + Duration::from_secs(5);
        while producer.tx.slots() < 32 && Instant::now() < drained {
            thread::sleep(Duration::from_millis(1));
        }
        assert!(Instant::now() < drained, "the writer stopped draining");
    }
    let stats = handle.finish().unwrap();

    let rows = assert_whole_rows(&disk.text());
    assert_eq!(stats.written, rows.len() as u64);
    assert!(rows.windows(2).all(|w| w[0] < w[1]), "rows in push order");
    assert_eq!(stats.pushed + stats.dropped, seq);
    assert_eq!(stats.written + stats.lost_to_disk, stats.pushed);
    assert!(stats.lost_to_disk >= 5 * 32);
    assert_eq!(stats.write_failures, 1);
    assert!(stats.intact);
    assert_eq!(stats.path, path);
    let error = stats.first_error.unwrap();
    assert!(
        error.starts_with("writing /sim/run/signals.csv: No space left on device"),
        "{error}"
    );
    assert_eq!(counters.lost_to_disk(), stats.lost_to_disk);
}

#[test]
fn the_csv_writer_resumes_after_space_is_freed() {
    let disk = FullDisk::with_capacity(4 * 1024);
    let (mut producer, writer) = channel(1_024, layout());
    let counters = writer.counters();
    let handle = writer
        .spawn_into(disk.clone(), "resume.csv".into(), Duration::from_millis(20))
        .unwrap();
    let mut seq = 0;
    while counters.lost_to_disk() == 0 {
        producer.push(&record(seq));
        seq += 1;
        thread::sleep(Duration::from_micros(50));
    }
    disk.set_capacity(1 << 20);
    thread::sleep(Duration::from_millis(50));
    let resumed_from = seq;
    for _ in 0..200 {
        producer.push(&record(seq));
        seq += 1;
    }
    let stats = handle.finish().unwrap();
    let rows = assert_whole_rows(&disk.text());
    assert_eq!(stats.written, rows.len() as u64);
    assert!(
        rows.contains(&(seq - 1)) && rows.iter().any(|&s| s >= resumed_from),
        "writing resumed"
    );
    assert!(
        rows.windows(2).any(|w| w[1] > w[0] + 1),
        "a gap of lost rows"
    );
    assert_eq!(stats.written + stats.lost_to_disk + stats.dropped, seq);
    assert!(stats.lost_to_disk > 0);
    assert!(stats.write_failures >= 1);
}
