//! The run folder's writers on a real full filesystem: a 64 KiB tmpfs, mounted for the
//! test (as root), filled by the CSV writer and the histogram reporter.
//!
//! Asserted: `signals.csv` holds only whole rows (every line has the header's column
//! count), each interval log only whole lines, each `.hgrm` is complete or absent and no
//! temporary file is left; the failure is counted (rows lost to the disk, apart from
//! queue drops; the files in the telemetry summary) and reported on standard error once
//! per file; the writer threads end cleanly; after space is freed the CSV writer resumes. A
//! whole `service run` into a full run folder prints its report first and leaves only
//! whole files.
//!
//! Mounting needs root (CI runs as root). Where mounting is not permitted the tests fail
//! with a loud message, unless `OUTPUTS_ALLOW_NO_MOUNT=1` is set: then they say so and
//! pass without running.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::{Duration, Instant};

use rig_tests::full_disk::{mount_or_skip, whole_log, whole_rows};
use service::logging::{self, LogLayout, LogRecord, LogStats, PushOutcome};
use service::telemetry::{self, CycleTiming, TelemetrySummary};

/// The child test of [`writers_on_a_full_filesystem_keep_whole_records_and_report_once`]
/// reads its folder from this variable.
const CHILD_DIR_VAR: &str = "OUTPUTS_FULL_DISK_CHILD_DIR";

fn layout() -> LogLayout {
    LogLayout {
        n_y: 2,
        n_z: 1,
        n_u: 2,
        internal_names: vec!["theta_norm".into(), "lambda".into()],
        decimation: 1,
    }
}

fn record(seq: u64) -> LogRecord {
    let mut r = LogRecord::ZERO;
    r.seq = seq;
    r.t_sample_ns = 1_000_000_000 + seq * 125_000;
    r.y[0] = (seq as f64 * 0.01).sin();
    r.y[1] = 1.0 / (seq as f64 + 7.0);
    r.z[0] = (seq as f64 * 0.003).cos() * 1e-3;
    r.u[0] = seq as f64 * 0.125;
    r.u[1] = -(seq as f64).sqrt();
    r.internals[0] = 1.0 + seq as f64 * 1e-7;
    r.internals[1] = 0.999;
    r
}

fn timing(seq: u64) -> CycleTiming {
    CycleTiming {
        seq,
        wakeup_ns: 3_000 + seq % 2_000,
        compute_ns: 20_000 + (seq * 31) % 5_000,
        response_ns: 30_000 + (seq * 7_919) % 80_000,
        period_jitter_ns: Some((seq * 13) % 4_000),
    }
}

/// What the simulated run did.
struct Outcome {
    log: LogStats,
    latency: TelemetrySummary,
    cycles: u64,
}

/// A run against `dir`: a producer thread (the RT loop's side: push a log record and
/// record a cycle timing, never waiting) at about 20 kHz for `duration`, the CSV writer
/// thread and a reporter thread polling every 20 ms; `midway` runs on the test thread
/// half-way through.
fn run_writers(dir: &Path, duration: Duration, midway: impl FnOnce()) -> Outcome {
    let (mut tele_rt, mut reporter) = telemetry::channel(125_000, 500, 2, dir).unwrap();
    let (mut producer, writer) = logging::channel(1_024, layout());
    let log = writer.spawn(dir.join("signals.csv")).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let reporter_thread = {
        let stop = Arc::clone(&stop);
        thread::spawn(move || {
            while !stop.load(Ordering::Acquire) {
                reporter.poll().expect("poll never fails on a full disk");
                thread::sleep(Duration::from_millis(20));
            }
            reporter
        })
    };
    let producer_thread = thread::spawn(move || {
        let start = Instant::now();
        let mut seq = 0;
        while start.elapsed() < duration {
            let outcome = producer.push(&record(seq));
            assert_ne!(outcome, PushOutcome::Decimated);
            tele_rt.record(&timing(seq));
            seq += 1;
            thread::sleep(Duration::from_micros(50));
        }
        tele_rt.flush();
        (producer, tele_rt, seq)
    });
    thread::sleep(duration / 2);
    midway();
    let (producer, _tele_rt, cycles) = producer_thread.join().unwrap();
    stop.store(true, Ordering::Release);
    let reporter = reporter_thread.join().unwrap();
    let latency = reporter
        .finish()
        .expect("finish never fails on a full disk");
    let log = log.finish().expect("the writer thread ends cleanly");
    assert_eq!(log.pushed, producer.pushed());
    Outcome {
        log,
        latency,
        cycles,
    }
}

/// Runs in a child process (see the parent test below), so that the parent can read
/// what was reported on standard error. Does nothing unless the child variable is set.
#[test]
fn child_fills_the_filesystem() {
    let Some(dir) = std::env::var_os(CHILD_DIR_VAR) else {
        return;
    };
    let dir = PathBuf::from(dir);
    let out = run_writers(&dir, Duration::from_millis(1_500), || {});

    // signals.csv: only whole rows, the loss counted apart from queue drops.
    let csv = dir.join("signals.csv");
    let rows = whole_rows(&csv);
    let log = &out.log;
    assert!(!rows.is_empty());
    assert_eq!(rows, (0..rows.len() as u64).collect::<Vec<_>>());
    assert_eq!(log.written, rows.len() as u64);
    assert_eq!(log.pushed + log.dropped, out.cycles);
    assert_eq!(log.written + log.lost_to_disk, log.pushed);
    assert!(log.lost_to_disk > 0, "the filesystem never filled");
    assert!(log.write_failures >= 1);
    assert!(log.intact);
    let error = log.first_error.as_deref().unwrap();
    assert_eq!(
        error,
        format!(
            "writing {}: No space left on device (os error 28)",
            csv.display()
        )
    );

    // The histograms: totals complete, every failing file listed, files whole.
    assert_eq!(out.latency.response.count, out.cycles);
    assert!(
        !out.latency.file_errors.is_empty(),
        "no telemetry file failed on a full filesystem"
    );
    for f in &out.latency.file_errors {
        assert!(f.first_error.as_deref().unwrap().contains(&f.path), "{f:?}");
        assert!(f.intact, "{f:?}");
    }
    for kind in telemetry::HistogramKind::ALL {
        let hlog = dir.join(format!("{}.hlog", kind.name()));
        let intervals = whole_log(&hlog) as u64;
        let failed = out
            .latency
            .file_errors
            .iter()
            .find(|f| Path::new(&f.path) == hlog);
        match failed {
            Some(f) => assert_eq!(f.records_written, intervals),
            None => assert_eq!(intervals, out.latency.intervals),
        }
        let hgrm = dir.join(format!("{}.hgrm", kind.name()));
        let listed = out
            .latency
            .file_errors
            .iter()
            .any(|f| Path::new(&f.path) == hgrm);
        match std::fs::read_to_string(&hgrm) {
            Ok(text) => {
                assert!(
                    text.contains("#[Buckets"),
                    "{} is incomplete",
                    hgrm.display()
                );
                assert!(!listed);
            }
            Err(_) => assert!(listed, "{} absent but not listed", hgrm.display()),
        }
    }
    let leftovers: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
    println!(
        "child: {} cycles, {} rows written, {} lost to the disk, {} dropped (queue), \
         {} telemetry files failed",
        out.cycles,
        log.written,
        log.lost_to_disk,
        log.dropped,
        out.latency.file_errors.len()
    );
}

#[test]
fn writers_on_a_full_filesystem_keep_whole_records_and_report_once() {
    let Some(fs) = mount_or_skip("fill", "64k") else {
        return;
    };
    let child = Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "child_fills_the_filesystem",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(CHILD_DIR_VAR, &fs.dir)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&child.stdout);
    let stderr = String::from_utf8_lossy(&child.stderr);
    assert!(
        child.status.success(),
        "the child failed ({}):\n--- stdout\n{stdout}\n--- stderr\n{stderr}",
        child.status
    );
    assert!(
        stdout.contains("child: "),
        "the child did not run:\n{stdout}"
    );
    // Reported when it happened, once per file, naming the file and the OS error.
    let csv_line = format!(
        "[service] writing {}: No space left on device (os error 28)",
        fs.dir.join("signals.csv").display()
    );
    let reported = stderr.lines().filter(|l| l.starts_with(&csv_line)).count();
    assert_eq!(reported, 1, "the CSV failure reported once:\n{stderr}");
    for kind in telemetry::HistogramKind::ALL {
        let name = fs.dir.join(format!("{}.hlog", kind.name()));
        let line = format!("[service] writing {}:", name.display());
        let n = stderr.lines().filter(|l| l.starts_with(&line)).count();
        assert!(n <= 1, "{} reported {n} times:\n{stderr}", name.display());
    }
    drop(fs);
}

#[test]
fn the_csv_writer_resumes_when_space_is_freed() {
    let Some(fs) = mount_or_skip("resume", "64k") else {
        return;
    };
    // Take most of the space, so that the writers fill the rest quickly.
    let filler = fs.dir.join("filler");
    std::fs::write(&filler, vec![0u8; 40 * 1024]).unwrap();
    let freed = AtomicBool::new(false);
    let out = run_writers(&fs.dir, Duration::from_millis(2_800), || {
        // Half-way: the disk has been full for about a second; free the space. The
        // writers retry every second.
        std::fs::remove_file(&filler).unwrap();
        freed.store(true, Ordering::Relaxed);
    });
    assert!(freed.load(Ordering::Relaxed));
    let rows = whole_rows(&fs.dir.join("signals.csv"));
    let log = &out.log;
    assert!(log.lost_to_disk > 0, "the filesystem never filled");
    assert_eq!(log.written, rows.len() as u64);
    assert_eq!(log.written + log.lost_to_disk, log.pushed);
    let gap = rows.windows(2).position(|w| w[1] != w[0] + 1);
    assert!(gap.is_some(), "no gap: writing never failed");
    let after_gap = rows.len() - gap.unwrap() - 1;
    assert!(
        after_gap > 100,
        "writing did not resume: {after_gap} rows after the gap"
    );
    assert!(
        log.first_error
            .as_deref()
            .unwrap()
            .contains("No space left")
    );
    drop(fs);
}

/// Every file of `dir` that must be complete or absent (`report.json`,
/// `plant-report.json`, the `.hgrm` files) is complete when present; returns the names of
/// those present.
fn complete_or_absent(dir: &Path) -> Vec<String> {
    let mut present = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        let path = dir.join(&name);
        assert!(!name.ends_with(".tmp"), "temporary file left: {name}");
        if name.ends_with(".json") {
            let text = std::fs::read_to_string(&path).unwrap();
            serde_json::from_str::<serde_json::Value>(&text)
                .unwrap_or_else(|e| panic!("{name} is not whole JSON: {e}"));
        } else if name.ends_with(".hgrm") {
            let text = std::fs::read_to_string(&path).unwrap();
            assert!(text.contains("#[Buckets"), "{name} is incomplete");
        } else if name.ends_with(".hlog") {
            whole_log(&path);
        } else {
            continue;
        }
        present.push(name);
    }
    present
}

/// A whole `service run` against plant-proxy (lockstep, 20 000 samples of the first-order
/// scenario with the signal log on) into a run folder on a full filesystem (a 96 KiB
/// tmpfs; the log needs about 20 times that). Required: the loop serves every sample (the
/// plant ends); the run report reaches standard output (its signal-log line counts rows
/// lost to the disk, and the verdict line is there) whatever the disk does; `signals.csv`
/// holds only whole rows, numbered from 0 without a gap up to where the disk filled; every
/// interval log only whole lines; `report.json`, `plant-report.json` and the `.hgrm` files
/// are complete or absent, and no temporary file is left; a `report.json` that could not
/// be written is named on standard error and fails the service's exit status.
#[test]
fn a_whole_service_run_into_a_full_run_folder_prints_its_report_and_leaves_whole_files() {
    let Some(fs) = mount_or_skip("whole-run", "96k") else {
        return;
    };
    let dir = rig_tests::TestDir::new("full-disk-run");
    let rig = rig_tests::rig_name("full-disk-run");
    let text =
        rig_tests::with_rig_name(&rig_tests::scenario_text("first-order-lockstep.toml"), &rig)
            + &rig_tests::test_service_tables("", &rig_tests::static_gain_controller());
    let scenario = dir.write("scenario.toml", &text);
    let run_folder = fs.dir.join("run");
    let plant_report = run_folder.join("plant-report.json");
    let mut service = rig_tests::start_service("service", &scenario, &run_folder);
    // start_service does not pass --exit-with-plant: the service is stopped below.
    let mut plant = rig_tests::start_lockstep_plant(
        "plant",
        &scenario,
        20_000,
        &["--report", plant_report.to_str().unwrap()],
    );
    let plant_status = plant.wait(Duration::from_secs(300));
    service.wait_for_line("plant ended", Duration::from_secs(30));
    service.signal(libc::SIGTERM);
    let service_status = service.wait(Duration::from_secs(60));
    let said = service.output();

    assert!(said.contains("verdict:"), "no report printed:\n{said}");
    let log_line = said
        .lines()
        .find(|l| l.starts_with("signal log:"))
        .unwrap_or_else(|| panic!("no signal-log line:\n{said}"));
    let lost: u64 = log_line
        .split(", ")
        .find_map(|part| part.strip_suffix(" lost to the disk"))
        .or_else(|| {
            log_line.split(", ").find_map(|p| {
                p.split(" lost to the disk")
                    .next()
                    .filter(|_| p.contains("lost"))
            })
        })
        .and_then(|n| n.trim().parse().ok())
        .unwrap_or_else(|| panic!("no count of rows lost to the disk: {log_line}"));
    assert!(lost > 0, "{log_line}");
    let rows = whole_rows(&run_folder.join("signals.csv"));
    assert!(
        !rows.is_empty() && rows.len() < 20_000,
        "{} rows",
        rows.len()
    );
    assert_eq!(rows, (0..rows.len() as u64).collect::<Vec<_>>());
    let present = complete_or_absent(&run_folder);
    eprintln!(
        "present: {present:?}; service {service_status}, plant {plant_status}; {} rows",
        rows.len()
    );
    if present.iter().any(|n| n == "report.json") {
        let report = rig_tests::read_json(&run_folder.join("report.json"));
        assert!(report["log_lost_to_disk"].as_u64().unwrap() > 0, "{report}");
    } else {
        assert!(!service_status.success(), "report.json lost, exit status 0");
        assert!(
            said.contains("report.json"),
            "report.json not named:\n{said}"
        );
    }
}
