//! Helpers shared by the bench's integration tests.

use std::path::PathBuf;

/// A fresh folder for one test under the target directory.
pub fn test_dir(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("test executable");
    let target = exe
        .ancestors()
        .nth(3)
        .expect("target/<profile>/deps/<test>")
        .to_path_buf();
    let dir = target
        .join("test-runs")
        .join(format!("bench-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("creating the test folder");
    dir
}
