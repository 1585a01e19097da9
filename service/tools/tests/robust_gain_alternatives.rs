//! The alternative robust gains `scenarios/arm/robust-gain-{min-gain,lqr}.toml` (written by
//! `rig-design robust-gain --objective …`), checked without the SDP solver as the committed
//! one is: the committed file's box and decay rate, a strict recorded margin, and `K`
//! keeping the spectral radius of `A_d + B_d K` below `e^{−λ T_s}` at the vertices and over
//! a 60×60 log grid. The minimum-gain design's `K` is smaller than the committed one's.

use rig_tools::design::robust_gain_file::RobustGainFile;
use std::path::PathBuf;

fn load(name: &str) -> RobustGainFile {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenarios/arm")
        .join(name);
    RobustGainFile::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn each_alternative_is_certified_for_the_committed_box_and_passes_the_radius_check() {
    let committed = load("robust-gain.toml");
    for name in ["robust-gain-min-gain.toml", "robust-gain-lqr.toml"] {
        let f = load(name);
        assert_eq!(f.design, committed.design, "{name}: another box");
        assert!(f.margin > 1e-7, "{name}: margin {} not strict", f.margin);
        let check = f.design.check_gain(&f.gain, 60);
        assert!(check.passed(), "{name}: {check:?}");
    }
}

#[test]
fn the_minimum_gain_is_smaller_than_the_committed_gain() {
    let small = load("robust-gain-min-gain.toml").gain;
    let margin = load("robust-gain.toml").gain;
    // Entry by entry on χ = [ẋ, ẏ, e] (the units differ between columns, not designs).
    for j in 0..3 {
        let col = |k: &nalgebra::Matrix2x3<f64>| k.column(j).norm();
        assert!(
            col(&small) < col(&margin),
            "column {j}: {small} vs {margin}"
        );
    }
}
