//! Shared by the plant-proxy integration tests: scenario texts with a `[proxy]` table.

#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// The path of a scenario in `scenarios/`.
pub fn scenario_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenarios")
        .join(name)
}

/// The first-order lockstep scenario (no `[proxy]` table of its own) with `proxy` (the
/// body of a `[proxy]` table and its sub-tables, starting with `[proxy]`) inserted before
/// `[plant]`, and the rig renamed to `rig`.
pub fn first_order_with(rig: &str, proxy: &str) -> String {
    let base = std::fs::read_to_string(scenario_path("first-order-lockstep.toml")).unwrap();
    assert!(
        !base.lines().any(|l| l.starts_with("[proxy")),
        "the fixture gained a [proxy] table"
    );
    let base = base.replacen(
        "name = \"first-order-lockstep\"",
        &format!("name = \"{rig}\""),
        1,
    );
    base.replacen("\n[plant]\n", &format!("\n{proxy}\n\n[plant]\n"), 1)
}
