//! Tests of the signal log: CSV round trip, drop counting, decimation, concurrent use.

use std::path::PathBuf;
use std::thread;

use super::*;

fn scratch_file(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!(
        "service-logging-{}-{}.csv",
        name,
        std::process::id()
    ))
}

fn layout(n_y: usize, n_z: usize, n_u: usize, internals: &[&str], decimation: u32) -> LogLayout {
    LogLayout {
        n_y,
        n_z,
        n_u,
        internal_names: internals.iter().map(|s| (*s).to_owned()).collect(),
        decimation,
    }
}

fn record(seq: u64) -> LogRecord {
    let mut r = LogRecord::ZERO;
    r.seq = seq;
    r.t_sample_ns = 1_000_000_000 + seq * 125_000;
    r
}

/// Splits the file into the header fields and the rows' fields.
fn read_csv(path: &PathBuf) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_owned)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(str::to_owned).collect())
        .collect();
    (header, rows)
}

#[test]
fn values_survive_the_csv_round_trip_bit_for_bit() {
    let path = scratch_file("roundtrip");
    let (mut producer, writer) =
        channel(1_024, layout(3, 2, 2, &["theta0", "trace P", "lambda"], 1));
    let handle = writer.spawn(path.clone()).unwrap();

    let tricky = [
        0.1,
        1.0 / 3.0,
        -0.0,
        1e-300,
        f64::MAX,
        f64::MIN_POSITIVE,
        5e-324,
        std::f64::consts::PI * 1e20,
        -123_456.789_012_345_67,
        9_007_199_254_740_993.0,
        1e-5,
        0.999_999_999_999_999_9,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    let mut sent = Vec::new();
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    for seq in 0..500u64 {
        let mut r = record(seq);
        r.status = (seq % 3) as u32;
        r.flags = u32::MAX - seq as u32;
        let mut vals = [0.0f64; 10];
        for (i, v) in vals.iter_mut().enumerate() {
            // xorshift bits → arbitrary finite doubles of every magnitude, plus the tricky ones.
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let random = f64::from_bits(x);
            *v = match (seq as usize + i) % 5 {
                0 => tricky[(seq as usize + i) % tricky.len()],
                _ if random.is_finite() => random,
                _ => seq as f64 * 0.1,
            };
        }
        r.y[..3].copy_from_slice(&vals[0..3]);
        r.z[..2].copy_from_slice(&vals[3..5]);
        r.u[..2].copy_from_slice(&vals[5..7]);
        r.internals[..3].copy_from_slice(&vals[7..10]);
        // Unlogged channels must not appear.
        r.y[3] = 42.0;
        r.internals[3] = 42.0;
        assert_eq!(producer.push(&r), PushOutcome::Pushed);
        sent.push(r);
    }
    let stats = handle.finish().unwrap();
    assert_eq!(stats.written, 500);
    assert_eq!(stats.pushed, 500);
    assert_eq!(stats.dropped, 0);
    assert_eq!(stats.path, path);

    let (header, rows) = read_csv(&path);
    assert_eq!(
        header,
        [
            "seq",
            "t_sample_ns",
            "status",
            "flags",
            "y0",
            "y1",
            "y2",
            "z0",
            "z1",
            "u0",
            "u1",
            "theta0",
            "trace P",
            "lambda"
        ]
    );
    assert_eq!(rows.len(), sent.len());
    for (row, r) in rows.iter().zip(&sent) {
        assert_eq!(row.len(), header.len());
        assert_eq!(row[0].parse::<u64>().unwrap(), r.seq);
        assert_eq!(row[1].parse::<u64>().unwrap(), r.t_sample_ns);
        assert_eq!(row[2].parse::<u32>().unwrap(), r.status);
        assert_eq!(row[3].parse::<u32>().unwrap(), r.flags);
        let expected = r.y[..3]
            .iter()
            .chain(&r.z[..2])
            .chain(&r.u[..2])
            .chain(&r.internals[..3]);
        for (field, v) in row[4..].iter().zip(expected) {
            let back: f64 = field.parse().unwrap();
            assert_eq!(back.to_bits(), v.to_bits(), "{field} vs {v:e}");
        }
    }
    let _ = std::fs::remove_file(&path);
}

#[test]
fn a_full_queue_drops_and_counts_while_the_writer_is_stalled() {
    let path = scratch_file("drops");
    let (mut producer, writer) = channel(8, layout(1, 0, 0, &[], 1));
    let counters = writer.counters();
    // Writer not spawned yet: nobody drains.
    let outcomes: Vec<PushOutcome> = (0..20).map(|k| producer.push(&record(k))).collect();
    assert!(outcomes[..8].iter().all(|&o| o == PushOutcome::Pushed));
    assert!(outcomes[8..].iter().all(|&o| o == PushOutcome::Dropped));
    assert_eq!(producer.pushed(), 8);
    assert_eq!(producer.dropped(), 12);
    assert_eq!(counters.pushed(), 8);
    assert_eq!(counters.dropped(), 12);

    let handle = writer.spawn(path.clone()).unwrap();
    let stats = handle.finish().unwrap();
    assert_eq!(stats.written, 8);
    assert_eq!(stats.dropped, 12);
    let (_, rows) = read_csv(&path);
    let seqs: Vec<u64> = rows.iter().map(|r| r[0].parse().unwrap()).collect();
    assert_eq!(
        seqs,
        (0..8).collect::<Vec<_>>(),
        "the oldest records are kept"
    );
    let _ = std::fs::remove_file(&path);
}

#[test]
fn decimation_keeps_every_nth_record_starting_with_the_first() {
    let path = scratch_file("decimation");
    let (mut producer, writer) = channel(1_000, layout(0, 0, 1, &[], 4));
    let handle = writer.spawn(path.clone()).unwrap();
    for k in 0..10 {
        let expected = if k % 4 == 0 {
            PushOutcome::Pushed
        } else {
            PushOutcome::Decimated
        };
        assert_eq!(producer.push(&record(k)), expected);
    }
    assert_eq!(producer.decimated(), 7);
    let stats = handle.finish().unwrap();
    assert_eq!(stats.written, 3);
    assert_eq!(stats.decimated, 7);
    assert_eq!(stats.dropped, 0);
    let (header, rows) = read_csv(&path);
    assert_eq!(header, ["seq", "t_sample_ns", "status", "flags", "u0"]);
    let seqs: Vec<u64> = rows.iter().map(|r| r[0].parse().unwrap()).collect();
    assert_eq!(seqs, [0, 4, 8]);
    let _ = std::fs::remove_file(&path);
}

#[test]
fn a_decimation_of_zero_keeps_everything() {
    let (mut producer, _writer) = channel(16, layout(0, 0, 0, &[], 0));
    for k in 0..5 {
        assert_eq!(producer.push(&record(k)), PushOutcome::Pushed);
    }
}

#[test]
fn finish_writes_everything_pushed_by_a_concurrent_producer() {
    let path = scratch_file("concurrent");
    let (mut producer, writer) = channel(256, layout(2, 1, 1, &["a"], 1));
    let handle = writer.spawn(path.clone()).unwrap();
    let rt = thread::spawn(move || {
        for k in 0..50_000u64 {
            let mut r = record(k);
            r.y[0] = k as f64 * 0.5;
            producer.push(&r);
            if k % 64 == 0 {
                thread::yield_now();
            }
        }
        producer
    });
    let producer = rt.join().unwrap();
    let stats = handle.finish().unwrap();
    assert_eq!(stats.pushed + stats.dropped, 50_000);
    assert_eq!(stats.written, stats.pushed);
    assert_eq!(producer.pushed(), stats.pushed);
    let (_, rows) = read_csv(&path);
    assert_eq!(rows.len() as u64, stats.written);
    let seqs: Vec<u64> = rows.iter().map(|r| r[0].parse().unwrap()).collect();
    assert!(seqs.windows(2).all(|w| w[0] < w[1]), "rows in push order");
    let _ = std::fs::remove_file(&path);
}

#[test]
fn dropping_the_handle_still_flushes_the_file() {
    let path = scratch_file("drop");
    let (mut producer, writer) = channel(64, layout(1, 0, 0, &[], 1));
    let handle = writer.spawn(path.clone()).unwrap();
    for k in 0..10 {
        producer.push(&record(k));
    }
    drop(handle);
    let (_, rows) = read_csv(&path);
    assert_eq!(rows.len(), 10);
    let _ = std::fs::remove_file(&path);
}

#[test]
fn layouts_beyond_the_record_capacities_or_with_bad_names_are_rejected() {
    assert!(layout(16, 16, 8, &["a", "b"], 1).validate().is_ok());
    assert_eq!(
        layout(17, 0, 0, &[], 1).validate(),
        Err(LogLayoutError::TooManyChannels {
            kind: "y",
            requested: 17,
            capacity: ipc_types::MAX_Y
        })
    );
    let many: Vec<String> = (0..=MAX_INTERNALS).map(|i| format!("p{i}")).collect();
    let names: Vec<&str> = many.iter().map(String::as_str).collect();
    assert!(matches!(
        layout(0, 0, 0, &names, 1).validate(),
        Err(LogLayoutError::TooManyChannels {
            kind: "internals",
            ..
        })
    ));
    assert!(matches!(
        layout(2, 0, 0, &["y1"], 1).validate(),
        Err(LogLayoutError::BadInternalName { index: 0, .. })
    ));
    assert!(matches!(
        layout(0, 0, 0, &["a", "a"], 1).validate(),
        Err(LogLayoutError::BadInternalName { index: 1, .. })
    ));
    assert!(matches!(
        layout(0, 0, 0, &[""], 1).validate(),
        Err(LogLayoutError::BadInternalName { index: 0, .. })
    ));
}

#[test]
fn an_oversized_layout_is_clamped_by_channel_and_names_with_commas_are_quoted() {
    let path = scratch_file("clamp");
    let (mut producer, writer) = channel(4, layout(99, 0, 0, &["gain, k"], 1));
    assert_eq!(writer.layout().n_y, ipc_types::MAX_Y);
    let handle = writer.spawn(path.clone()).unwrap();
    producer.push(&record(0));
    handle.finish().unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let header = text.lines().next().unwrap();
    assert!(header.ends_with(",y15,\"gain, k\""), "{header}");
    let _ = std::fs::remove_file(&path);
}

#[test]
fn f64_formatting_is_short_and_exact() {
    let fmt = |v: f64| {
        let mut buf = Vec::new();
        writer::write_f64(&mut buf, v).unwrap();
        String::from_utf8(buf).unwrap()
    };
    assert_eq!(fmt(0.1), "0.1");
    assert_eq!(fmt(1.0), "1");
    assert_eq!(fmt(-0.0), "-0");
    assert_eq!(fmt(1e-7), "1e-7");
    assert_eq!(fmt(2e300), "2e300");
    assert_eq!(fmt(f64::NAN), "NaN");
    assert_eq!(fmt(f64::NEG_INFINITY), "-inf");
    assert!(fmt(f64::NAN).parse::<f64>().unwrap().is_nan());
}
