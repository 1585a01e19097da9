//! The stall study (`rig stalls`, `rig_tools::stalls`) on the main job's scenario, as a
//! test: stalls of the service of 1, 2, 4, 16, 48 and 80 periods injected in lockstep,
//! under compute-first and send-ahead, with the plant holding, applying the safe input, or
//! applying the service's plan of 32 or of 64 entries. Lockstep is deterministic, so each
//! case is compared with its own run without stalls; the study's cost is the energy of the
//! change a stall made to `z` over 0.25 s, against the residual `z` of the same window
//! (dB).

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
        .args(["--plan-length", "32", "--plan-length", "64", "--runs"])
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
    const STALLS: [u64; 6] = [1, 2, 4, 16, 48, 80];
    const PLANS: [u64; 2] = [32, 64];
    assert_eq!(costs.len(), (4 + PLANS.len()) * STALLS.len());
    // (held or safe inputs, plan entries, cost dB) of a case (`plan`: its plan length, 0
    // for the cases without plans) and a stall.
    let row = |timing: &str, policy: &str, plan: u64, periods: u64| -> (u64, u64, f64) {
        let c = costs
            .iter()
            .find(|c| {
                c["case"]["timing"] == timing
                    && c["case"]["late_policy"] == policy
                    && c["case"]["plan_length"] == plan
                    && c["periods"] == periods
            })
            .unwrap_or_else(|| panic!("{timing} {policy} {plan} {periods}"));
        (
            c["held_or_safe"].as_u64().unwrap(),
            c["plan_entries"].as_u64().unwrap(),
            c["cost_db"].as_f64().unwrap_or(f64::NEG_INFINITY),
        )
    };
    for n in STALLS {
        // Compute-first: every stalled sample's input is missing, and each stall is a
        // pulse larger than the whole residual, whatever the plant does.
        for policy in ["hold", "safe"] {
            let (held, planned, db) = row("compute-first", policy, 0, n);
            assert_eq!((held, planned), (n, 0), "compute-first {policy} {n}");
            assert!(db > 0.0, "compute-first {policy} {n}: {db} dB");
        }
        // Send-ahead: the input for the first stalled sample was already at the plant.
        let missing = n - 1;
        for policy in ["hold", "safe"] {
            let (held, planned, db) = row("send-ahead", policy, 0, n);
            assert_eq!((held, planned), (missing, 0), "send-ahead {policy} {n}");
            if n == 1 {
                assert!(db < -40.0, "a one-period stall costs nothing: {db} dB");
            } else {
                assert!(db > 0.0, "send-ahead {policy} {n}: {db} dB");
            }
        }
        for plan in PLANS {
            let (held, planned, db) = row("send-ahead", "plan", plan, n);
            let covered = missing.min(plan);
            assert_eq!(
                (held, planned),
                (missing - covered, covered),
                "send-ahead plan {plan}, stall {n}"
            );
            if missing <= plan {
                // A stall the plan covers: no held or safe input reaches the plant, and
                // the stall stays far below the residual, at least 30 dB better than
                // holding or the safe input.
                assert!(db < -15.0, "plan {plan}, stall {n}: {db} dB");
                if n > 1 {
                    for policy in ["hold", "safe"] {
                        let other = row("send-ahead", policy, 0, n).2;
                        assert!(
                            db < other - 30.0,
                            "plan {plan}: {db} dB against {policy} {other} dB (stall {n})"
                        );
                    }
                }
            } else {
                // Past the plan's end the plant holds: a pulse again.
                assert!(db > 0.0, "plan {plan}, stall {n} past its end: {db} dB");
            }
        }
    }
    // A 6 ms stall (48 periods), which a shared VM inflicts: the plan of 64 covers it and
    // the plan of 32 does not.
    let (short, long) = (
        row("send-ahead", "plan", 32, 48).2,
        row("send-ahead", "plan", 64, 48).2,
    );
    assert!(long < short - 20.0, "plan 64 {long} dB, plan 32 {short} dB");
}
