//! Tests of the record format: round trip through the RT recorder and the writer thread,
//! a truncated file, a gap, another version, not a record.

use super::*;
use ipc_types::{Actuation, ChannelCounts, Measurement};
use std::path::PathBuf;

fn counts() -> ChannelCounts {
    ChannelCounts {
        n_y: 2,
        n_z: 1,
        n_r: 1,
        n_u: 2,
    }
}

fn header() -> RecordHeader {
    RecordHeader {
        service_version: "test".into(),
        rig: "unit".into(),
        controller: "lti".into(),
        controller_fingerprint: "0".into(),
        config_fingerprint: "0".into(),
        n_y: 2,
        n_z: 1,
        n_r: 1,
        n_u: 2,
        plan_length: 3,
        timing: "send-ahead".into(),
        sample_period_ns: 125_000,
        config_origin: "unit.toml".into(),
        config_base_dir: "/".into(),
        config_text: "[rig]\nname = \"unit\"\n".into(),
        warm_start: None,
    }
}

fn temp(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("record-{name}-{}.bin", std::process::id()))
}

/// A measurement whose values have awkward bits (a subnormal, −0, a NaN payload).
fn measurement(seq: u64) -> Measurement {
    let mut m = Measurement::zeroed(counts());
    m.seq = seq;
    m.flags = 0x15;
    m.t_sample_ns = 1_000 + seq * 125_000;
    m.period_ns = 125_000;
    m.deadline_ns = 7;
    m.y[0] = 0.1 * seq as f64;
    m.y[1] = f64::from_bits(1);
    m.z[0] = -0.0;
    m.r[0] = f64::from_bits(0x7ff8_0000_0000_1234);
    m.u_applied[1] = 1e300;
    m
}

fn actuation(seq: u64) -> Actuation {
    let mut a = Actuation::zeroed(counts());
    a.seq = seq + 1;
    a.reply_to = seq;
    a.t_sample_ns = 99;
    a.status = 0x24;
    a.timing = 2;
    a.plan_len = 3;
    a.compute_ns = 1234;
    a.u[0] = std::f64::consts::PI;
    a.u[1] = -1.0 / 3.0;
    a.plan[2][1] = 2.5e-310;
    a
}

fn entries() -> Vec<Entry> {
    vec![
        Entry::Handle {
            m: measurement(0),
            t_recv_ns: 5_000,
        },
        Entry::Publish {
            act: actuation(0),
            ok: true,
            t_pub_ns: 6_000,
        },
        Entry::Observe { m: measurement(1) },
        Entry::NewPeer,
        Entry::WentSilent { now_ns: 77 },
        Entry::Publish {
            act: actuation(2),
            ok: false,
            t_pub_ns: 8_000,
        },
        Entry::Operator {
            request_id: 9,
            command: ipc_types::operator::command::SET_TUNABLE,
            index: 1,
            value: 0.25,
        },
    ]
}

/// Pushes `entries` through a recorder whose ring holds `samples` samples, then writes.
fn write(path: &std::path::Path, samples: usize, entries: &[Entry]) -> RecordStats {
    let (mut rec, writer) = channel(&header(), samples);
    for e in entries {
        match e {
            Entry::Handle { m, t_recv_ns } => rec.handle(m, *t_recv_ns),
            Entry::Observe { m } => rec.observe(m),
            Entry::NewPeer => rec.new_peer(),
            Entry::WentSilent { now_ns } => rec.went_silent(*now_ns),
            Entry::Publish { act, ok, t_pub_ns } => rec.publish(act, *ok, *t_pub_ns),
            Entry::Operator {
                request_id,
                command,
                index,
                value,
            } => rec.operator(&crate::runtime::operator::Queued {
                request_id: *request_id,
                command: crate::runtime::operator::Command::from_code(
                    *command,
                    *index as usize,
                    *value,
                )
                .unwrap(),
            }),
            Entry::End => {}
        }
    }
    writer.spawn(path).unwrap().finish().unwrap()
}

fn bytes(layout: &RecordLayout, index: u64, e: &Entry) -> Vec<u8> {
    let mut buf = vec![0u8; layout.max_entry_bytes()];
    let n = e.encode(layout, index, &mut buf);
    buf.truncate(n);
    buf
}

#[test]
fn every_entry_reads_back_bit_for_bit_through_the_recorder_and_the_writer() {
    let path = temp("round-trip");
    let stats = write(&path, 16, &entries());
    assert!(stats.complete, "{stats:?}");
    assert_eq!((stats.entries, stats.written), (7, 7));
    let mut r = RecordReader::open(&path).unwrap();
    assert_eq!(r.header(), &header());
    let layout = *r.layout();
    for (i, e) in entries().iter().enumerate() {
        let got = r.next_entry().unwrap().expect("an entry");
        assert_eq!(got.index, i as u64);
        assert_eq!(got.entry.kind(), e.kind());
        assert_eq!(
            bytes(&layout, i as u64, &got.entry),
            bytes(&layout, i as u64, e)
        );
        assert_eq!(bytes(&layout, 0, e).len(), layout.entry_bytes(e.kind()));
    }
    assert!(r.next_entry().unwrap().is_none());
    let len = std::fs::metadata(&path).unwrap().len() as usize;
    let body: usize = entries().iter().map(|e| layout.entry_bytes(e.kind())).sum();
    // And the end mark.
    assert_eq!(len, header().encode().len() + body + ENTRY_HEAD_BYTES);
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn a_truncated_file_is_refused_naming_the_file_and_the_offset_of_the_torn_entry_or_its_end() {
    let path = temp("truncated");
    write(&path, 16, &entries());
    let layout = header().layout();
    let head = header().encode().len() as u64;
    let torn_at = head + layout.measurement_bytes() as u64;
    // Cut inside the second entry (the first Publish).
    let f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    f.set_len(torn_at + 10).unwrap();
    let mut r = RecordReader::open(&path).unwrap();
    assert!(r.next_entry().unwrap().is_some());
    let e = r.next_entry().unwrap_err();
    assert!(e.is_incomplete());
    assert_eq!(
        e,
        RecordError::Truncated {
            path: path.display().to_string(),
            offset: torn_at,
            index: 1,
            needed: layout.publish_bytes(),
            found: 10,
        }
    );
    let text = e.to_string();
    assert!(text.contains(&path.display().to_string()), "{text}");
    assert!(text.contains(&format!("byte offset {torn_at}")), "{text}");
    // The error stays.
    assert_eq!(r.next_entry().unwrap_err(), e);
    // Cut on an entry boundary: whole entries, but no end mark.
    f.set_len(torn_at).unwrap();
    let mut r = RecordReader::open(&path).unwrap();
    assert!(r.next_entry().unwrap().is_some());
    let e = r.next_entry().unwrap_err();
    assert!(e.is_incomplete());
    assert_eq!(
        e,
        RecordError::Unfinished {
            path: path.display().to_string(),
            offset: torn_at,
            entries: 1,
        }
    );
    assert!(e.to_string().contains("without its end mark"), "{e}");
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn entries_dropped_by_a_full_queue_show_as_a_gap_at_their_place() {
    let path = temp("gap");
    // A ring of one sample (one measurement and one publish entry): the third entry finds
    // it full, and so do the later ones until the writer drains it.
    let stats = write(&path, 1, &entries());
    assert!(!stats.complete);
    assert!(stats.dropped > 0);
    assert_eq!(stats.written + stats.dropped, 7);
    let mut r = RecordReader::open(&path).unwrap();
    let first = r.next_entry().unwrap().unwrap();
    assert_eq!(first.index, 0);
    let mut seen = 1;
    let err = loop {
        match r.next_entry() {
            Ok(Some(_)) => seen += 1,
            Ok(None) => panic!("no gap found"),
            Err(e) => break e,
        }
    };
    match &err {
        RecordError::Gap {
            expected, found, ..
        } => {
            assert_eq!(*expected, seen);
            assert!(*found > seen);
        }
        other => panic!("{other:?}"),
    }
    assert!(err.is_incomplete());
    assert!(err.to_string().contains("gap at byte offset"), "{err}");
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn another_format_version_is_refused_with_both_versions() {
    let path = temp("version");
    write(&path, 16, &entries());
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[8..12].copy_from_slice(&(FORMAT_VERSION + 1).to_le_bytes());
    std::fs::write(&path, &bytes).unwrap();
    let e = RecordReader::open(&path).err().expect("refused");
    assert_eq!(
        e,
        RecordError::Version {
            path: path.display().to_string(),
            found: FORMAT_VERSION + 1
        }
    );
    assert!(
        e.to_string()
            .contains(&format!("versions 1 to {FORMAT_VERSION}"))
    );
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn a_version_1_record_without_operator_entries_is_still_read() {
    let path = temp("version-1");
    let old: Vec<Entry> = entries()
        .into_iter()
        .filter(|e| !matches!(e, Entry::Operator { .. }))
        .collect();
    write(&path, 16, &old);
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[8..12].copy_from_slice(&1u32.to_le_bytes());
    std::fs::write(&path, &bytes).unwrap();
    let mut r = RecordReader::open(&path).unwrap();
    let mut n = 0;
    while r.next_entry().unwrap().is_some() {
        n += 1;
    }
    assert_eq!(n, old.len());
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn a_file_that_is_not_a_record_is_refused_naming_it() {
    let path = temp("not-a-record");
    std::fs::write(&path, "seq,t_sample_ns\n1,2\n").unwrap();
    let e = RecordReader::open(&path).err().expect("refused");
    assert!(matches!(e, RecordError::NotARecord { .. }), "{e:?}");
    assert!(e.to_string().starts_with(&path.display().to_string()));
    let missing = temp("missing");
    let e = RecordReader::open(&missing).err().expect("refused");
    assert!(matches!(e, RecordError::Io { .. }), "{e:?}");
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn the_entry_sizes_follow_the_channels_and_the_plan_length() {
    let l = header().layout();
    // 2 y, 1 z, 1 r, 2 u; plans of 3.
    assert_eq!(l.measurement_bytes(), ENTRY_HEAD_BYTES + 56 + 8 * 6);
    assert_eq!(l.publish_bytes(), ENTRY_HEAD_BYTES + 65 + 8 * 2 * 4);
    assert_eq!(l.entry_bytes(EntryKind::NewPeer), ENTRY_HEAD_BYTES);
    assert_eq!(l.entry_bytes(EntryKind::WentSilent), ENTRY_HEAD_BYTES + 8);
}
