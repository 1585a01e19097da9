//! `run.png` of a service run: the data preparation (`rig_tools::figures::run::prepare`,
//! read from a run folder) on synthetic `report.json` + `signals.csv`, and one drawing.

use std::fmt::Write as _;
use std::path::PathBuf;

use rig_tools::figures::run::{self, Outcome, RunFigure};
use rig_tools::figures::timeline::IntervalKind;
use serde_json::json;

/// 8 kHz.
const T: f64 = 1.0 / 8000.0;

const OPEN_LOOP: u32 = 1 << 5;
const STARTING: u32 = 1 << 3;
const SAFE_STATE: u32 = 1 << 0;
const REJECTED: u32 = 1 << 1;

/// One logged row.
struct Row {
    seq: u64,
    status: u32,
    flags: u32,
}

/// A fresh run folder `name` with `report` and a `signals.csv` of `rows` (z0 a tone
/// of 800 Hz, 0.5 in open loop and 0.01 after, u0 and u1 distinct).
fn folder(name: &str, report: serde_json::Value, rows: &[Row]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("run-figure-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("report.json"), report.to_string()).unwrap();
    let mut csv = String::from("seq,t_sample_ns,status,flags,y0,z0,u0,u1,theta_norm\n");
    for r in rows {
        let t = r.seq as f64 * T;
        let open = r.status & (OPEN_LOOP | SAFE_STATE) != 0;
        let a = if open { 0.5 } else { 0.01 };
        let z = a * (2.0 * std::f64::consts::PI * 800.0 * t).sin();
        let (u0, u1) = if open {
            (0.0, 0.0)
        } else {
            (0.3 * z, -2.0 * z)
        };
        writeln!(
            csv,
            "{},{},{},{},{z},{z},{u0},{u1},{}",
            r.seq,
            1_000_000_000 + r.seq * 125_000,
            r.status,
            r.flags,
            if open { 0.0 } else { 1.0 }
        )
        .unwrap();
    }
    std::fs::write(dir.join("signals.csv"), csv).unwrap();
    dir
}

/// The report of a run: `open_loop_s`, tone window 0.5 s, `verdict`, `events`.
fn report(
    open_loop_s: f64,
    verdict: serde_json::Value,
    events: serde_json::Value,
) -> serde_json::Value {
    json!({
        "rig": "test-rig",
        "controller": "rcac",
        "sample_period_s": T,
        "budget_ns": 125000,
        "open_loop_s": open_loop_s,
        "verdict": verdict,
        "events": events,
        "log_dropped": 0,
        "stats": { "skipped": 0 },
        "tones": {
            "source": "plant.disturbance",
            "window_s": 0.5,
            "samples": [4000, 4000],
            "tones": [{ "hz": 800.0, "channel": 0, "open": 0.5, "closed": 0.5, "suppression_db": 0.0 }],
            "error": null
        }
    })
}

fn ok() -> serde_json::Value {
    json!({ "ok": true, "failures": [], "warnings": [] })
}

/// The status of sample `k` of a run with `open` open-loop samples (the first 800 in
/// the start-up grace).
fn status(k: u64, open: u64) -> u32 {
    match k {
        k if k < 800 => OPEN_LOOP | STARTING,
        k if k < open => OPEN_LOOP,
        _ => 0,
    }
}

fn rows(seqs: impl Iterator<Item = u64>, status: impl Fn(u64) -> u32) -> Vec<Row> {
    seqs.map(|seq| Row {
        seq,
        status: status(seq),
        flags: 17,
    })
    .collect()
}

fn prepared(name: &str, report: serde_json::Value, rows: &[Row]) -> (RunFigure, PathBuf) {
    let dir = folder(name, report, rows);
    (run::read(&dir).unwrap(), dir)
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-9
}

#[test]
fn a_one_second_open_loop_at_8_khz_starts_the_controller_at_1_000_s() {
    // A rejected measurement at 0.05 s has no OPEN_LOOP bit: it must not end the phase.
    let rows = rows(
        0..24_000,
        |k| {
            if k == 400 { REJECTED } else { status(k, 8000) }
        },
    );
    let (fig, dir) = prepared("start", report(1.0, ok(), json!([])), &rows);
    let start = fig.controller_start_s.unwrap();
    assert!(close(start, 1.0), "controller start {start}");
    assert_eq!(fig.phases.len(), 1);
    assert_eq!(fig.phases[0].open_rows, 0..8000);
    assert_eq!(fig.phases[0].closed_rows, 8000..24_000);
    assert!(fig.phases[0].from_status);
    assert_eq!(fig.outcome, Outcome::Ok);
    assert!(fig.title.ends_with("run OK"), "{}", fig.title);
    // Both windows: the last 0.5 s of the open loop and of the run, 4000 samples each.
    let (o, c) = (
        fig.psd.open.as_ref().unwrap(),
        fig.psd.closed.as_ref().unwrap(),
    );
    assert!(
        close(o.from_s, 0.5) && close(o.to_s, 1.0),
        "{} {}",
        o.from_s,
        o.to_s
    );
    assert!(
        close(c.from_s, 2.5) && close(c.to_s, 3.0),
        "{} {}",
        c.from_s,
        c.to_s
    );
    assert_eq!((o.samples, c.samples, fig.psd.samples), (4000, 4000, 4000));
    assert_eq!(o.z[0].len(), c.z[0].len());
    assert_eq!(fig.psd.segment, 1000);
    assert!(fig.intervals.is_empty());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn lost_samples_place_the_start_the_windows_and_the_intervals_by_sequence_number() {
    // The log starts at seq 100; 200 samples of the open loop and 1000 of the closed loop
    // are lost. Row indices and sequence numbers disagree by up to 1200.
    let lost = |k: u64| (300..500).contains(&k) || (12_000..13_000).contains(&k);
    let rows = rows((100..24_100).filter(|k| !lost(*k)), |k| {
        if (20_100..=22_099).contains(&k) {
            SAFE_STATE
        } else {
            status(k - 100, 8000)
        }
    });
    let events = json!([
        { "event": "first-sample", "seq": 100 },
        { "event": "safe-state-entered", "seq": 20_099, "misses": 8 },
        { "event": "safe-state-left", "seq": 22_099 },
    ]);
    let (fig, dir) = prepared("gaps", report(1.0, ok(), events), &rows);
    assert!(close(fig.controller_start_s.unwrap(), 1.0));
    assert_eq!(
        fig.phases[0].open_rows.end,
        8000 - 200,
        "row index of the start"
    );
    assert_eq!(fig.timeline.missing, 1200);
    let safe: Vec<_> = fig
        .intervals
        .iter()
        .filter(|i| i.kind == IntervalKind::SafeState)
        .collect();
    assert_eq!(safe.len(), 1, "{:?}", fig.intervals);
    // Entered at seq 20 099, left at seq 22 099: (seq − 100) T.
    assert!(close(safe[0].from_s, 19_999.0 * T), "{}", safe[0].from_s);
    assert!(close(safe[0].to_s, 21_999.0 * T), "{}", safe[0].to_s);
    assert_eq!(fig.outcome, Outcome::Ok);
    let (o, c) = (
        fig.psd.open.as_ref().unwrap(),
        fig.psd.closed.as_ref().unwrap(),
    );
    assert_eq!(o.samples, c.samples);
    assert_eq!(o.logged, 4000, "the open window (0.5–1 s) lost nothing");
    assert!(close(c.to_s, 24_000.0 * T), "{}", c.to_s);
    assert!(fig.notes.iter().any(|n| n.contains("1200 samples missing")));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_run_that_enters_the_safe_state_at_6_49_s_and_never_leaves_is_shaded_to_the_end_and_failed() {
    let entered = (6.49 / T).round() as u64;
    let n = 64_000;
    let rows = rows(0..n, |k| {
        if k > entered {
            SAFE_STATE
        } else {
            status(k, 8000)
        }
    });
    let verdict = json!({
        "ok": false,
        "failures": ["ENDED IN SAFE STATE since 6.49 s: the last window is open loop; recovery needs 800 clean cycles in a row, the longest run of clean cycles since the entry was 3"],
        "warnings": []
    });
    let events = json!([
        { "event": "first-sample", "seq": 0 },
        { "event": "safe-state-entered", "seq": entered, "misses": 8 },
    ]);
    let (fig, dir) = prepared("safe", report(1.0, verdict, events.clone()), &rows);
    assert_eq!(fig.intervals.len(), 1, "{:?}", fig.intervals);
    let i = fig.intervals[0];
    assert_eq!(i.kind, IntervalKind::SafeState);
    assert!(close(i.from_s, 6.49), "{}", i.from_s);
    assert!(close(i.to_s, fig.end_s) && close(fig.end_s, (n - 1) as f64 * T));
    assert_eq!(fig.outcome, Outcome::Failed);
    assert!(fig.title.contains("FAILED"), "{}", fig.title);
    assert!(
        fig.verdict_line
            .starts_with("verdict: FAILED: ENDED IN SAFE STATE since 6.49 s"),
        "{}",
        fig.verdict_line
    );
    assert!(
        fig.notes
            .iter()
            .any(|l| l.contains("0.0 to 0.0 dB") && l.contains("FAILED")),
        "the 0 dB tones say the run failed: {:?}",
        fig.notes
    );
    // A report without a verdict: the log alone says it failed.
    let mut old = report(1.0, json!(null), events);
    old.as_object_mut().unwrap().remove("verdict");
    let (fig, dir2) = prepared("safe-old", old, &rows);
    assert_eq!(fig.outcome, Outcome::Failed);
    assert!(
        fig.verdict_line
            .contains("ends in the safe state (since 6.49 s)"),
        "{}",
        fig.verdict_line
    );
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&dir2);
}

#[test]
fn both_psd_windows_have_the_same_number_of_samples_when_the_open_loop_is_shorter() {
    // 0.3 s of open loop against a 0.5 s tone window: both windows shrink to 2400
    // samples; samples lost in the closed window are held, not dropped.
    let rows = rows((0..16_000).filter(|k| !(15_000..15_100).contains(k)), |k| {
        status(k, 2400)
    });
    let (fig, dir) = prepared("short", report(0.3, ok(), json!([])), &rows);
    let (o, c) = (
        fig.psd.open.as_ref().unwrap(),
        fig.psd.closed.as_ref().unwrap(),
    );
    assert_eq!(o.samples, 2400);
    assert_eq!(c.samples, o.samples);
    assert_eq!(c.z[0].len(), o.z[0].len());
    assert_eq!(c.logged, 2400 - 100);
    assert!(close(o.from_s, 0.0) && close(o.to_s, 0.3));
    assert!(close(c.to_s - c.from_s, o.to_s - o.from_s));
    assert!(
        fig.notes.iter().any(|n| n.contains("shortened")),
        "{:?}",
        fig.notes
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn every_channel_is_listed_in_channel_order() {
    let dir = std::env::temp_dir().join(format!("run-figure-channels-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("report.json"),
        report(0.0, ok(), json!([])).to_string(),
    )
    .unwrap();
    let mut csv = String::from("seq,t_sample_ns,status,flags,z1,z0,u10,u2,uu,theta_norm\n");
    for k in 0..100 {
        writeln!(csv, "{k},0,0,17,{},{},{},{},0,0", k, -k, 2 * k, 3 * k).unwrap();
    }
    std::fs::write(dir.join("signals.csv"), csv).unwrap();
    let fig = run::read(&dir).unwrap();
    let names = |c: &[run::Channel]| c.iter().map(|c| c.name.clone()).collect::<Vec<_>>();
    assert_eq!(names(&fig.z), ["z0", "z1"]);
    assert_eq!(names(&fig.u), ["u2", "u10"]);
    assert_eq!(fig.u[1].values[7], 14.0);
    // No open loop: the controller acts from the first sample.
    assert!(fig.phases[0].open_rows.is_empty());
    assert_eq!(fig.controller_start_s, Some(0.0));
    assert!(fig.psd.open.is_none() && fig.psd.closed.is_some());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_run_folders_are_errors_naming_the_file() {
    let dir = std::env::temp_dir().join(format!("run-figure-bad-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let e = run::read(&dir).unwrap_err().to_string();
    assert!(e.contains("report.json"), "{e}");
    std::fs::write(dir.join("report.json"), "{ not json").unwrap();
    assert!(
        run::read(&dir)
            .unwrap_err()
            .to_string()
            .contains("report.json")
    );
    std::fs::write(dir.join("report.json"), json!({"rig": "r"}).to_string()).unwrap();
    std::fs::write(dir.join("signals.csv"), "seq,z0\n0,1\n").unwrap();
    let e = run::read(&dir).unwrap_err().to_string();
    assert!(
        e.contains("report.json") && e.contains("sample period"),
        "{e}"
    );
    std::fs::write(
        dir.join("report.json"),
        report(1.0, ok(), json!([])).to_string(),
    )
    .unwrap();
    std::fs::write(dir.join("signals.csv"), "seq,z0\n0,1\nx,2\n").unwrap();
    assert!(
        run::read(&dir)
            .unwrap_err()
            .to_string()
            .contains("signals.csv")
    );
    std::fs::write(dir.join("signals.csv"), "seq,z0\n0,1\n1e300,2\n").unwrap();
    assert!(
        run::read(&dir)
            .unwrap_err()
            .to_string()
            .contains("signals.csv")
    );
    std::fs::write(dir.join("signals.csv"), "seq,y0\n0,1\n1,2\n").unwrap();
    let e = run::read(&dir).unwrap_err().to_string();
    assert!(e.contains("signals.csv") && e.contains("z0"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn run_png_is_drawn_into_the_run_folder() {
    let entered = 14_000;
    let rows = rows(0..20_000, |k| {
        if k > entered {
            SAFE_STATE
        } else {
            status(k, 8000)
        }
    });
    let events = json!([{ "event": "safe-state-entered", "seq": entered, "misses": 8 }]);
    let verdict =
        json!({ "ok": false, "failures": ["ENDED IN SAFE STATE since 1.75 s"], "warnings": [] });
    let dir = folder("draw", report(1.0, verdict, events), &rows);
    let path = rig_tools::figures::run_folder_figure(&dir).unwrap();
    assert_eq!(path, dir.join("run.png"));
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    assert!(
        bytes.len() > 50_000,
        "a non-trivial image: {} bytes",
        bytes.len()
    );
    let _ = std::fs::remove_dir_all(&dir);
}
