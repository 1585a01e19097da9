//! Lockstep runs with injected losses are repeatable bit for bit under send-ahead timing.
//!
//! The main job's scenario (send-ahead with plans of 64) in lockstep for 1.5 s, with every
//! other sample of the closed loop lost (`[proxy.faults] lost`, from 1 s on). Each sample
//! after a loss had nothing sent ahead for it, so the service answers it twice: its own
//! input, then the input for the next sample, which is lost. The plant must decide that
//! lost sample's input from the second answer every time (`Wait::LockstepAhead`), not from
//! whichever had arrived: two runs must then log the same signals (every column but the
//! wall-clock sample time). Before, three such runs of 10 s gave three different logs.

use rig_tests::*;
use std::time::Duration;

/// First and last (exclusive) sample of the lossy stretch: every other sample is lost.
const LOSSY: (u64, u64) = (8_000, 12_000);

/// Runs the lossy scenario once; returns the signal log's header and rows.
fn run(test: &str) -> (Vec<String>, Vec<Vec<f64>>) {
    let dir = TestDir::new(test);
    let text = acoustic_rig_scenario(test);
    let losses: String = (LOSSY.0..LOSSY.1)
        .step_by(2)
        .map(|k| format!("[[proxy.faults.lost]]\nat = {k}\nperiods = 1\n\n"))
        .collect();
    let scenario = dir.write("acoustic-rig.toml", &format!("{text}\n{losses}"));
    let folder = dir.path.join("run");
    let mut launch = start_launch(
        &scenario,
        &folder,
        &["--mode", "lockstep", "--duration", "1.5"],
    );
    launch.wait(Duration::from_secs(120));
    let report = read_json(&folder.join("report.json"));
    let lost = report["stats"]["lost_past_startup"].as_u64().unwrap_or(0);
    assert_eq!(
        lost,
        (LOSSY.1 - LOSSY.0) / 2,
        "{test}: every injected loss counted, no other: {}",
        launch.output()
    );
    read_csv(&folder.join("signals.csv"))
}

#[test]
fn a_lockstep_run_with_injected_losses_repeats_bit_for_bit_under_send_ahead() {
    let (header, a) = run("loss-repeat-a");
    let (_, b) = run("loss-repeat-b");
    let t = column(&header, "t_sample_ns");
    assert_eq!(a.len(), b.len());
    for (ra, rb) in a.iter().zip(&b) {
        for (i, (x, y)) in ra.iter().zip(rb).enumerate() {
            if i != t {
                assert_eq!(
                    x.to_bits(),
                    y.to_bits(),
                    "seq {}: {} differs ({x} against {y})",
                    ra[0],
                    header[i]
                );
            }
        }
    }
}
