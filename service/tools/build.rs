//! Records the commit the `study` binary is built from (`RIG_TOOLS_COMMIT`): a sharded
//! study's manifest carries it, and `study merge` refuses shards of different commits.

use std::path::Path;
use std::process::Command;

/// `git <args>` in this crate's folder, trimmed; `None` when git or the checkout is absent.
fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
        .filter(|s| !s.is_empty())
}

fn main() {
    let commit = git(&["rev-parse", "HEAD"]).unwrap_or_else(|| "unknown".to_string());
    println!("cargo:rustc-env=RIG_TOOLS_COMMIT={commit}");
    // Built again when HEAD moves: HEAD itself, the branch it names, the packed refs.
    let mut watched = Vec::new();
    if let Some(dir) = git(&["rev-parse", "--absolute-git-dir"]) {
        watched.push(Path::new(&dir).join("HEAD"));
    }
    if let Some(common) = git(&["rev-parse", "--git-common-dir"]) {
        let common = std::fs::canonicalize(&common).unwrap_or_else(|_| common.into());
        watched.push(common.join("packed-refs"));
        if let Some(branch) = git(&["symbolic-ref", "-q", "HEAD"]) {
            watched.push(common.join(branch));
        }
    }
    for p in watched.iter().filter(|p| p.exists()) {
        println!("cargo:rerun-if-changed={}", p.display());
    }
    println!("cargo:rerun-if-changed=build.rs");
}
