//! The committed robust gain `scenarios/arm/robust-gain.toml`, checked without the SDP
//! solver: its box is the chapter's (the decay rate at most the chapter's λ, see
//! docs/design-tools.md), and its `K` keeps the spectral radius of `A_d + B_d K` below
//! `e^{−λ T_s}` at the four vertices and over a 60×60 log grid of the box.

use control::arm::robust::RobustBox;
use rig_tools::design::robust_gain_file::RobustGainFile;
use std::path::PathBuf;

fn committed() -> RobustGainFile {
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenarios/arm/robust-gain.toml");
    RobustGainFile::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn the_committed_file_is_for_the_chapters_box() {
    let f = committed();
    let chapter = RobustBox::CHAPTER_7;
    assert_eq!(f.design.sample_period, chapter.sample_period);
    assert_eq!(f.design.stiffness, chapter.stiffness);
    assert_eq!(f.design.damping, chapter.damping);
    assert!(
        f.design.decay_rate > 0.0 && f.design.decay_rate <= chapter.decay_rate,
        "decay-rate {} outside (0, {}]",
        f.design.decay_rate,
        chapter.decay_rate
    );
    assert!(
        f.margin > 0.0,
        "margin {} is not a strict certificate",
        f.margin
    );
}

#[test]
fn the_committed_gain_decays_at_every_vertex_and_over_the_grid() {
    let f = committed();
    let check = f.design.check_gain(&f.gain, 60);
    for v in &check.vertices {
        assert!(
            v.radius < check.bound,
            "vertex ({}, {}): radius {} ≥ e^(−λT) = {}",
            v.stiffness,
            v.damping,
            v.radius,
            check.bound
        );
    }
    assert!(
        check.worst_grid.radius < check.bound,
        "grid: radius {} at ({}, {}) ≥ {}",
        check.worst_grid.radius,
        check.worst_grid.stiffness,
        check.worst_grid.damping,
        check.bound
    );
    assert!(check.passed());
}
