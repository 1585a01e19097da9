//! `service replay`: a run folder's `record.bin` re-run offline through the same loop code
//! gives the logged actuations bit for bit, for a real-time run (whatever its timing did:
//! misses, late samples and safe states are inputs of the record) and for lockstep runs
//! with adaptive controllers; a changed controller is compared open loop; a damaged or
//! incomplete record is reported where it is damaged, never claimed equal.
//!
//! Every test starts real processes (`rig launch`, or `service run` with `plant-proxy`)
//! with its own rig name, then `target/<profile>/service replay`; no test asserts a timing.

use rig_tests::*;
use serde_json::Value;
use service::record::{Entry, RecordReader};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

/// An RCAC controller (RLS, `n_c = 4`) for the one-input plant of `rcac-tone.toml` at
/// 1 kHz, with an inline target model (the fixture `rcac-tone-1khz-controller.toml`);
/// `lambda` is its forgetting factor.
fn rcac_controller(lambda: f64) -> String {
    fixture("rcac-tone-1khz-controller.toml").replacen(
        "lambda = 0.999\n",
        &format!("lambda = {lambda:?}\n"),
        1,
    )
}

/// The tone plant of `rcac-tone.toml` at 1 kHz with the tests' service tables plus
/// `extra_service`, then `controller`.
fn tone_scenario(dir: &TestDir, test: &str, extra_service: &str, controller: &str) -> PathBuf {
    let plant = with_rig_name(&scenario_text("rcac-tone.toml"), &rig_name(test))
        .replace("sample-period = 0.01\n", "sample-period = 0.001\n");
    let text = plant + &test_service_tables(extra_service, controller);
    dir.write("scenario.toml", &text)
}

/// The first-order lockstep scenario with the static gain `u = −2 y`.
fn static_gain_scenario(dir: &TestDir, test: &str) -> PathBuf {
    let text = with_rig_name(&scenario_text("first-order-lockstep.toml"), &rig_name(test))
        + &test_service_tables("", &static_gain_controller());
    dir.write("scenario.toml", &text)
}

/// `service replay <folder> <extra…>`: its exit code and standard output (standard error
/// appended).
fn replay(folder: &Path, extra: &[&str]) -> (i32, String) {
    let out = Command::new(bin("service"))
        .arg("replay")
        .arg(folder)
        .args(extra)
        .output()
        .expect("service replay starts");
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    (out.status.code().unwrap_or(-1), text)
}

/// The value of `key=` on the summary's last line (`replay: VERDICT samples=N
/// actuations=M`), with the verdict.
fn summary(text: &str) -> (String, u64, u64) {
    let line = text
        .lines()
        .rev()
        .find(|l| l.starts_with("replay: "))
        .unwrap_or_else(|| panic!("no summary line in:\n{text}"));
    let words: Vec<&str> = line.split_whitespace().collect();
    let value = |key: &str| -> u64 {
        words
            .iter()
            .find_map(|w| w.strip_prefix(key))
            .unwrap_or_else(|| panic!("no {key} in {line}"))
            .parse()
            .unwrap()
    };
    (
        words[1].to_string(),
        value("samples="),
        value("actuations="),
    )
}

/// The samples the service received and the actuations it published (sent or not), from
/// its report.
fn reported_counts(folder: &Path) -> (u64, u64) {
    let report: Value = read_json(&folder.join("report.json"));
    let s = &report["stats"];
    let n = |k: &str| s[k].as_u64().unwrap_or_else(|| panic!("stats.{k}"));
    (
        n("received"),
        n("published") + n("published_extra") + n("publish_failures"),
    )
}

/// Asserts that the run's record is complete and replays equal bit for bit, covering every
/// sample and actuation of the report.
fn assert_replays_bit_for_bit(folder: &Path) {
    let report: Value = read_json(&folder.join("report.json"));
    assert_eq!(
        report["record"]["complete"],
        Value::Bool(true),
        "{}",
        report["record"]
    );
    let (code, text) = replay(folder, &[]);
    assert_eq!(code, 0, "{text}");
    let (verdict, samples, actuations) = summary(&text);
    assert_eq!(verdict, "EQUAL", "{text}");
    let (received, published) = reported_counts(folder);
    assert!(received > 0);
    assert_eq!(samples, received, "{text}");
    assert_eq!(actuations, published, "{text}");
}

#[test]
fn a_real_time_run_replays_bit_for_bit() {
    let dir = TestDir::new("replay-real-time");
    // RCAC answering ahead with plans, as the acoustic rig does, in real time.
    let scenario = tone_scenario(
        &dir,
        "replay-rt",
        "timing = \"send-ahead\"\nplan-length = 4\n",
        &rcac_controller(0.999),
    );
    let folder = dir.path.join("run");
    let mut launch = start_launch(&scenario, &folder, &["--duration", "2.0"]);
    // The run may miss deadlines on a loaded machine (then its verdict may fail): the record
    // holds what happened, and the replay must reproduce it whatever it was.
    launch.wait(Duration::from_secs(120));
    let launched = read_json(&folder.join("launch.json"));
    assert_eq!(launched["mode"], Value::String("real-time".into()));
    assert_eq!(
        launched["children"]["service"]["exit_code"]
            .as_i64()
            .map(|c| c <= 1),
        Some(true),
        "{launched}"
    );
    assert_replays_bit_for_bit(&folder);
    let report: Value = read_json(&folder.join("report.json"));
    assert_eq!(report["timing"], Value::String("send-ahead".into()));
    assert!(report["stats"]["controller_steps"].as_u64().unwrap() > 0);
}

#[test]
fn a_lockstep_pcac_run_replays_bit_for_bit() {
    let dir = TestDir::new("replay-pcac");
    let rig = rig_name("replay-pcac");
    let plant = with_rig_name(&scenario_text("rcac-tone.toml"), &rig).replace(
        "outputs-z = 1\n",
        "outputs-z = 1\ncommands = 1\ncommand = [0.5]\n",
    );
    let text = plant + &test_service_tables("", &fixture("pcac-controller.toml"));
    let scenario = dir.write("scenario.toml", &text);
    let folder = run_lockstep_pair(&dir, &scenario, 400, &[]);
    assert_replays_bit_for_bit(&folder);
}

#[test]
fn a_lockstep_rcac_run_replays_bit_for_bit_and_a_changed_forgetting_factor_replays_open_loop() {
    let dir = TestDir::new("replay-rcac");
    let scenario = tone_scenario(&dir, "replay-rcac", "", &rcac_controller(0.999));
    let folder = run_lockstep_pair(&dir, &scenario, 1500, &[]);
    assert_replays_bit_for_bit(&folder);

    let other = dir.write("other.toml", &rcac_controller(0.99));
    let csv = dir.path.join("comparison.csv");
    let (code, text) = replay(
        &folder,
        &[
            "--controller",
            other.to_str().unwrap(),
            "--comparison",
            csv.to_str().unwrap(),
        ],
    );
    assert_eq!(code, 0, "{text}");
    let (verdict, _, actuations) = summary(&text);
    assert_eq!(verdict, "OPEN-LOOP", "{text}");
    assert!(
        text.contains("first divergence at the answer to sample"),
        "{text}"
    );
    let (header, rows) = read_csv(&csv);
    assert_eq!(rows.len() as u64, actuations);
    let (logged, replayed, diff) = (
        column(&header, "u0_logged"),
        column(&header, "u0_replayed"),
        column(&header, "u0_difference"),
    );
    assert!(rows.iter().any(|r| r[diff] != 0.0), "the decisions differ");
    for r in &rows {
        assert_eq!(r[diff], r[replayed] - r[logged]);
    }
}

#[test]
fn another_static_gain_replayed_open_loop_differs_by_exactly_its_change() {
    let dir = TestDir::new("replay-gain");
    let scenario = static_gain_scenario(&dir, "replay-gain");
    let folder = run_lockstep_pair(&dir, &scenario, 200, &[]);
    assert_replays_bit_for_bit(&folder);
    // u = −3 y instead of u = −2 y.
    let gain = static_gain_controller();
    assert!(gain.contains("-2.0"), "{gain}");
    let other = dir.write("gain-3.toml", &gain.replace("-2.0", "-3.0"));
    let (code, text) = replay(&folder, &["--controller", other.to_str().unwrap()]);
    assert_eq!(code, 0, "{text}");
    assert_eq!(summary(&text).0, "OPEN-LOOP", "{text}");
    let (header, rows) = read_csv(&folder.join("replay-comparison.csv"));
    let (logged, replayed) = (column(&header, "u0_logged"), column(&header, "u0_replayed"));
    let (_, signals) = read_csv(&folder.join("signals.csv"));
    assert_eq!(rows.len(), signals.len());
    // Where the controller acts, −3 y = 1.5 · (−2 y).
    let acting: Vec<&Vec<f64>> = rows.iter().filter(|r| r[logged] != 0.0).collect();
    assert!(acting.len() > 100, "{}", acting.len());
    for r in acting {
        assert_eq!(r[replayed], 1.5 * r[logged], "{r:?}");
    }
}

/// The byte offset of the `n`-th `Publish` entry of a record, and the sample it answers.
fn publish_entry(record: &Path, n: usize) -> (u64, u64) {
    let mut r = RecordReader::open(record).unwrap();
    let mut seen = 0;
    while let Some(l) = r.next_entry().unwrap() {
        if let Entry::Publish { act, .. } = l.entry {
            if seen == n {
                return (l.offset, act.reply_to);
            }
            seen += 1;
        }
    }
    panic!("fewer than {n} publish entries");
}

#[test]
fn a_changed_logged_output_and_a_cut_record_are_reported_where_they_are() {
    let dir = TestDir::new("replay-damaged");
    let scenario = static_gain_scenario(&dir, "replay-damaged");
    let folder = run_lockstep_pair(&dir, &scenario, 200, &[]);
    let record = folder.join("record.bin");
    let original = std::fs::read(&record).unwrap();

    // One bit of u[0] of the 150th actuation: kind, index, ok, t_pub, contract, status,
    // seq, reply_to, t_sample, compute, counts, timing, plan_len come first.
    let (offset, reply_to) = publish_entry(&record, 150);
    let mut bytes = original.clone();
    bytes[offset as usize + 74] ^= 1;
    std::fs::write(&record, &bytes).unwrap();
    let (code, text) = replay(&folder, &[]);
    assert_eq!(code, 1, "{text}");
    assert_eq!(summary(&text).0, "DIFFERENT", "{text}");
    assert!(
        text.contains(&format!("DIFFERENT at the answer to sample {reply_to} ")),
        "{text}"
    );
    assert!(text.contains("field u[0]"), "{text}");
    assert!(
        text.contains("150 actuations before it were equal"),
        "{text}"
    );

    // Cut inside that entry: equal up to it, then incomplete, naming the offset.
    std::fs::write(&record, &original[..offset as usize + 20]).unwrap();
    let (code, text) = replay(&folder, &[]);
    assert_eq!(code, 3, "{text}");
    assert_eq!(summary(&text).0, "INCOMPLETE", "{text}");
    assert!(
        text.contains(&format!("truncated at byte offset {offset}")),
        "{text}"
    );
    assert!(text.contains("150 actuations up to sample"), "{text}");

    // Not a record at all.
    std::fs::write(&record, b"seq,t_sample_ns\n").unwrap();
    let (code, text) = replay(&folder, &[]);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("not a record file"), "{text}");
}

#[test]
fn a_run_with_a_silent_and_restarted_plant_replays_bit_for_bit() {
    let dir = TestDir::new("replay-sessions");
    let scenario = tone_scenario(&dir, "replay-sessions", "", &rcac_controller(0.999));
    let folder = dir.path.join("service-run");
    let mut service = start_service("service", &scenario, &folder);
    let mut plant = start_lockstep_plant("plant-1", &scenario, 300, &[]);
    plant.wait_success(Duration::from_secs(60));
    service.wait_for_line("PLANT SILENT", Duration::from_secs(30));
    let mut plant = start_lockstep_plant("plant-2", &scenario, 300, &[]);
    plant.wait_success(Duration::from_secs(60));
    service.signal(libc::SIGTERM);
    service.wait(Duration::from_secs(30));
    let report: Value = read_json(&folder.join("report.json"));
    assert_eq!(report["stats"]["new_sessions"], Value::from(1), "{report}");
    assert_replays_bit_for_bit(&folder);
    // The silence and the new publisher were replayed as inputs.
    let (_, text) = replay(&folder, &[]);
    let inputs = text
        .lines()
        .find(|l| l.starts_with("inputs:"))
        .unwrap_or_else(|| panic!("{text}"));
    assert!(inputs.contains("600 samples handled"), "{inputs}");
    assert!(!inputs.contains(" 0 silences"), "{inputs}");
}

#[test]
fn a_warm_started_run_replays_bit_for_bit_from_the_checkpoint_copied_into_its_folder() {
    let dir = TestDir::new("replay-warm");
    let scenario = tone_scenario(&dir, "replay-warm", "", &rcac_controller(0.999));
    let first = run_lockstep_pair_into(&dir, "first", &scenario, 500, &[], &[]);
    // The second run starts from what the first learned, from a file removed after the
    // run: the replay must find the checkpoint in the second run's folder.
    let checkpoint = dir.path.join("learned.json");
    std::fs::copy(first.join("checkpoint.json"), &checkpoint).unwrap();
    let second = run_lockstep_pair_into(
        &dir,
        "second",
        &scenario,
        500,
        &[],
        &["--warm-start", checkpoint.to_str().unwrap()],
    );
    std::fs::remove_file(&checkpoint).unwrap();
    assert_eq!(
        std::fs::read(second.join("warm-start.json")).unwrap(),
        std::fs::read(first.join("checkpoint.json")).unwrap()
    );
    assert_replays_bit_for_bit(&second);
    // Without that copy the replay refuses, naming it, rather than start from nothing.
    std::fs::remove_file(second.join("warm-start.json")).unwrap();
    let (code, text) = replay(&second, &[]);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("warm-start.json"), "{text}");
}

#[test]
fn with_record_off_there_is_no_record_and_replay_says_which_file_it_lacks() {
    let dir = TestDir::new("replay-off");
    let text = with_rig_name(
        &scenario_text("first-order-lockstep.toml"),
        &rig_name("replay-off"),
    ) + &test_service_tables("", &static_gain_controller()).replace(
        "[log]\ndecimation = 1\n",
        "[log]\ndecimation = 1\nrecord = false\n",
    );
    assert!(text.contains("record = false"));
    let scenario = dir.write("scenario.toml", &text);
    let folder = run_lockstep_pair(&dir, &scenario, 100, &[]);
    assert!(folder.join("signals.csv").exists());
    assert!(!folder.join("record.bin").exists());
    assert_eq!(
        read_json(&folder.join("report.json"))["record"],
        Value::Null
    );
    let (code, text) = replay(&folder, &[]);
    assert_eq!(code, 2, "{text}");
    assert!(
        text.contains(&folder.join("record.bin").display().to_string()),
        "{text}"
    );
}
