//! `study sampling-arm --quick` (a 2 × 2 grid per contact model, the single runs and the
//! double maneuvers): the files it writes, its claims with verdicts, and the augmented
//! controller's force on the Figure 7.4 surface read back from its CSV.

use std::path::PathBuf;

use rig_tools::study::arm::closed_loop;
use rig_tools::study::reproduction::{self, Verdict};

fn out_dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("sampling-arm-study-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// The median `F_c` over the samples with `r > 0` of a trace CSV.
fn contact_median(csv: &str) -> f64 {
    let forces: Vec<f64> = csv
        .lines()
        .skip(1)
        .filter_map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let r: f64 = f[1].parse().ok()?;
            (r > 0.0).then(|| f[2].parse().unwrap())
        })
        .collect();
    assert!(
        forces.len() > 3000,
        "a 2 s contact phase at 2 kHz: {}",
        forces.len()
    );
    closed_loop::median(&forces)
}

#[test]
fn the_quick_study_writes_its_files_and_claims_and_the_augmented_arm_holds_25_n() {
    let out = out_dir();
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_study"))
        .args(["sampling-arm", "--quick", "--out"])
        .arg(&out)
        .status()
        .expect("runs");
    assert!(status.success());
    for f in [
        "grid.csv",
        "summary.md",
        "claims.json",
        "fig7_3_robust.png",
        "fig7_3_augmented.png",
        "fig7_5_robust.png",
        "fig7_5_augmented.png",
        "fig7_4.png",
        "fig7_6.png",
        "fig7_7.png",
        "fig7_8.png",
        "fig7_4_augmented.csv",
        "fig7_7_augmented.csv",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    // 2 models × 2 controllers × 2 × 2 points, plus the header.
    let grid = std::fs::read_to_string(out.join("grid.csv")).unwrap();
    assert_eq!(grid.lines().count(), 1 + 16);
    let claims = reproduction::read(&out).expect("claims.json");
    assert_eq!((claims.study.as_str(), claims.chapter), ("sampling-arm", 7));
    assert_eq!(claims.claims.len(), 8);
    assert!(
        claims
            .claims
            .iter()
            .all(|c| c.verdict != Verdict::NotChecked && !c.ours.is_empty())
    );
    // Behaviour: on Figure 7.4's surface the augmented controller holds 25 N ± 5 %.
    let csv = std::fs::read_to_string(out.join("fig7_4_augmented.csv")).unwrap();
    let m = contact_median(&csv);
    assert!(
        (m - 25.0).abs() <= 0.05 * 25.0,
        "median contact force {m} N"
    );
    let _ = std::fs::remove_dir_all(&out);
}
