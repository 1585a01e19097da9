//! The stall study (`rig stalls`, `rig_tools::stalls`) on the main job's scenario, as a
//! test: stalls of the service of 1, 2, 4 and 16 periods injected in lockstep, under
//! compute-first and send-ahead, with the plant holding, applying the safe input, or
//! applying the service's plan. Lockstep is deterministic, so each case is compared with
//! its own run without stalls; the study's cost is the energy of the change a stall made
//! to `z` over 0.25 s, against the residual `z` of the same window (dB).

use rig_tests::{TestDir, bin};
use serde_json::Value;
use std::process::Command;

#[test]
fn a_stall_costs_the_acoustic_rig_an_error_pulse_unless_the_service_sends_ahead_with_plans() {
    let dir = TestDir::new("stall-policies");
    let json = dir.path.join("stalls.json");
    let scenario =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/acoustic-rig.toml");
    let out = Command::new(bin("rig"))
        .arg("stalls")
        .arg(&scenario)
        .args(["--plan-length", "32", "--runs"])
        .arg(dir.path.join("runs"))
        .arg("--json")
        .arg(&json)
        .output()
        .expect("rig stalls runs");
    let table = String::from_utf8_lossy(&out.stdout);
    eprintln!("{table}");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let study: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();

    // The ahead form regulates as compute-first does: the residuals agree within 1 dB.
    let rms: Vec<f64> = study["baseline_rms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r[1].as_f64().unwrap())
        .collect();
    assert!((20.0 * (rms[0] / rms[1]).log10()).abs() < 1.0, "{rms:?}");

    let costs = study["costs"].as_array().unwrap();
    assert_eq!(costs.len(), 5 * 4);
    let row = |timing: &str, policy: &str, periods: u64| -> (u64, u64, f64) {
        let c = costs
            .iter()
            .find(|c| {
                c["case"]["timing"] == timing
                    && c["case"]["late_policy"] == policy
                    && c["periods"] == periods
            })
            .unwrap_or_else(|| panic!("{timing} {policy} {periods}"));
        (
            c["held_or_safe"].as_u64().unwrap(),
            c["plan_entries"].as_u64().unwrap(),
            c["cost_db"].as_f64().unwrap_or(f64::NEG_INFINITY),
        )
    };
    for n in [1, 2, 4, 16] {
        // Compute-first: every stalled sample's input is missing, and each stall is a
        // pulse larger than the whole residual, whatever the plant does.
        for policy in ["hold", "safe"] {
            let (held, planned, db) = row("compute-first", policy, n);
            assert_eq!((held, planned), (n, 0), "compute-first {policy} {n}");
            assert!(db > 0.0, "compute-first {policy} {n}: {db} dB");
        }
        // Send-ahead: the input for the first stalled sample was already at the plant.
        let missing = n - 1;
        for policy in ["hold", "safe"] {
            let (held, planned, db) = row("send-ahead", policy, n);
            assert_eq!((held, planned), (missing, 0), "send-ahead {policy} {n}");
            if n == 1 {
                assert!(db < -40.0, "a one-period stall costs nothing: {db} dB");
            } else {
                assert!(db > 0.0, "send-ahead {policy} {n}: {db} dB");
            }
        }
        // With plans, no held or safe input reaches the plant, and a stall stays far below
        // the residual: at least 30 dB better than holding or the safe input.
        let (held, planned, db) = row("send-ahead", "plan", n);
        assert_eq!((held, planned), (0, missing), "send-ahead plan {n}");
        assert!(db < -20.0, "send-ahead plan {n}: {db} dB");
        if n > 1 {
            for policy in ["hold", "safe"] {
                let other = row("send-ahead", policy, n).2;
                assert!(
                    db < other - 30.0,
                    "plan {db} dB against {policy} {other} dB ({n})"
                );
            }
        }
    }
}
