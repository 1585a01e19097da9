//! The `plant-proxy` command line: `describe` prints the exact discretization, and a bad
//! scenario is refused with the file and the field. (These tests also make `cargo test
//! --workspace` build the binary that the closed-loop tests in `tests/` start.)

use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_plant-proxy");

fn scenario(name: &str) -> String {
    format!("{}/../scenarios/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// `plant-proxy describe` of a scenario, which must succeed and print JSON.
fn describe(name: &str) -> serde_json::Value {
    let out = Command::new(BIN)
        .args(["describe", &scenario(name)])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON on stdout")
}

#[test]
fn describe_prints_the_exact_zoh_discretization_as_json() {
    let d = describe("first-order-lockstep.toml");
    // 1/(s + 5) at T = 1 ms: y_{k+1} = e^{-5T} y_k + (1 − e^{-5T})/5 u_k.
    let a = (-0.005_f64).exp();
    let ch = &d["channels"][0];
    assert_eq!(ch["output"], "y0");
    assert_eq!(ch["input"], "u0");
    assert_eq!(ch["delay-samples"], 0);
    let den: Vec<f64> = serde_json::from_value(ch["den"].clone()).unwrap();
    let num: Vec<f64> = serde_json::from_value(ch["num"].clone()).unwrap();
    assert!(
        (den[0] - 1.0).abs() < 1e-15 && (den[1] + a).abs() < 1e-15,
        "{den:?}"
    );
    assert!(
        num[0].abs() < 1e-15 && (num[1] - (1.0 - a) / 5.0).abs() < 1e-15,
        "{num:?}"
    );
    assert!((d["phi"][0][0].as_f64().unwrap() - a).abs() < 1e-15);
}

#[test]
fn describe_reports_the_acoustic_rigs_input_delays() {
    let d = describe("acoustic-rig.toml");
    let delays: Vec<u64> = d["channels"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["output"] == "y0")
        .map(|c| c["delay-samples"].as_u64().unwrap())
        .collect();
    assert_eq!(delays, vec![9, 16]);
}

#[test]
fn a_bad_scenario_is_refused_naming_the_file_and_the_field() {
    let dir = std::env::temp_dir().join(format!("pp-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string(scenario("first-order-lockstep.toml"))
        .unwrap()
        .replace("den = [1.0, 5.0]", "den = [0.0, 5.0]");
    let path = dir.join("bad.toml");
    std::fs::write(&path, text).unwrap();
    let out = Command::new(BIN)
        .args(["describe", path.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("bad.toml") && err.contains("plant.tf.yu[0][0]"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
