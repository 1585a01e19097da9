//! The examples' commands run as the documentation writes them: each `sh` block of
//! `ipc-types/python/README.md` and `ipc-types/c/README.md` that closes a loop on the
//! first-order plant is read from the file and run word for word, from a folder laid out as
//! the repository (`scenarios/`, `ipc-types/`, `target/release/` with the binaries and the
//! static library), with `python` the tests' interpreter. A line ending in `&` starts a
//! process in the background, the others run to completion in order; every process must
//! exit with 0, and the loop must have run every sample. The blocks share the rig name of
//! the documentation, so they run one after the other in one test.

use rig_tests::python::python;
use rig_tests::{Proc, TestDir, bin, column, read_csv};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

/// The repository's root.
fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The fenced `sh` blocks of `text`, each a list of commands (a trailing `\` joins a line
/// with the next).
fn sh_blocks(text: &str) -> Vec<Vec<String>> {
    let mut blocks = Vec::new();
    let mut current: Option<Vec<String>> = None;
    let mut pending = String::new();
    for line in text.lines() {
        match (&mut current, line.trim_end()) {
            (None, "```sh") => current = Some(Vec::new()),
            (Some(_), "```") => blocks.push(current.take().expect("open block")),
            (Some(cmds), l) => {
                pending.push_str(l.trim_end_matches('\\').trim());
                pending.push(' ');
                if !l.ends_with('\\') {
                    cmds.push(pending.trim().to_string());
                    pending.clear();
                }
            }
            (None, _) => {}
        }
    }
    blocks
}

/// The blocks of the file `doc` (relative to the repository) that name the first-order
/// scenario.
fn loops_of(doc: &str) -> Vec<Vec<String>> {
    let text = std::fs::read_to_string(repo().join(doc)).unwrap_or_else(|e| panic!("{doc}: {e}"));
    sh_blocks(&text)
        .into_iter()
        .filter(|b| b.iter().any(|l| l.contains("first-order-lockstep")))
        .collect()
}

/// The static library cargo built for this test run (`deps/` holds this profile's build;
/// the copy next to the binaries is only refreshed by `cargo build`).
fn static_lib() -> PathBuf {
    let dir = bin("service").parent().expect("bin folder").to_path_buf();
    [
        dir.join("deps/libadaptive_rig.a"),
        dir.join("libadaptive_rig.a"),
    ]
    .into_iter()
    .find(|p| p.exists())
    .unwrap_or_else(|| panic!("no libadaptive_rig.a under {}", dir.display()))
}

/// A folder laid out as the repository, for commands written relative to its root.
fn workdir(name: &str) -> TestDir {
    let dir = TestDir::new(name);
    let link = |from: PathBuf, to: &str| {
        std::os::unix::fs::symlink(&from, dir.path.join(to))
            .unwrap_or_else(|e| panic!("symlink {} -> {}: {e}", to, from.display()))
    };
    link(repo().join("scenarios"), "scenarios");
    link(repo().join("ipc-types"), "ipc-types");
    std::fs::create_dir_all(dir.path.join("target/release")).expect("target folder");
    for b in ["service", "plant-proxy"] {
        link(bin(b), &format!("target/release/{b}"));
    }
    link(static_lib(), "target/release/libadaptive_rig.a");
    dir
}

/// The command of one documented line, run in `dir`.
fn command(line: &str, dir: &Path) -> Command {
    let mut words = line.split_whitespace();
    let program = words.next().expect("a command");
    let mut c = match program {
        "python" => Command::new(python()),
        p if p.contains('/') => Command::new(dir.join(p)),
        p => Command::new(p),
    };
    c.args(words)
        .current_dir(dir)
        .env("PYTHONPATH", repo().join("ipc-types/python"))
        .env("PYTHONUNBUFFERED", "1");
    c
}

/// Runs one block in `dir`, line by line; all its processes must succeed.
fn run_block(block: &[String], dir: &Path) {
    assert!(
        block.last().is_some_and(|l| !l.ends_with('&')),
        "the last command of {block:?} runs in the foreground"
    );
    let mut started: Vec<Proc> = Vec::new();
    for line in block {
        if let Some(line) = line.strip_suffix('&') {
            let line = line.trim();
            started.push(Proc::spawn(line, command(line, dir)));
            std::thread::sleep(Duration::from_millis(500));
            continue;
        }
        let out = command(line, dir)
            .output()
            .unwrap_or_else(|e| panic!("`{line}` did not start: {e}"));
        assert!(
            out.status.success(),
            "`{line}` failed: {}\n{}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
    }
    for p in &mut started {
        p.wait_success(Duration::from_secs(60));
    }
}

/// The one run folder the service left in `dir/runs`: 2000 samples answered with u = −2 y.
fn assert_static_gain_run(dir: &Path) {
    let runs: Vec<PathBuf> = std::fs::read_dir(dir.join("runs"))
        .expect("the service's run folder")
        .map(|e| e.expect("a run folder").path())
        .collect();
    assert_eq!(runs.len(), 1, "{runs:?}");
    let (header, rows) = read_csv(&runs[0].join("signals.csv"));
    assert_eq!(rows.len(), 2000);
    let (y, u) = (column(&header, "y0"), column(&header, "u0"));
    for r in &rows {
        assert_eq!(r[u], -2.0 * r[y], "u = −2 y");
    }
}

#[test]
fn the_examples_close_their_loops_as_the_readmes_write_them() {
    let python_loops = loops_of("ipc-types/python/README.md");
    assert_eq!(
        python_loops.len(),
        2,
        "the service loop and the plant-proxy loop: {python_loops:?}"
    );
    let c_loops = loops_of("ipc-types/c/README.md");
    assert_eq!(
        c_loops.len(),
        1,
        "the C plant against the service: {c_loops:?}"
    );

    // The service as the controller of the Python plant.
    let dir = workdir("documented-python-service");
    run_block(&python_loops[0], &dir.path);
    assert_static_gain_run(&dir.path);

    // The Python controller of plant-proxy's simulated plant.
    let dir = workdir("documented-python-proxy");
    run_block(&python_loops[1], &dir.path);

    // The C plant, compiled as written, against the service.
    let dir = workdir("documented-c-service");
    run_block(&c_loops[0], &dir.path);
    assert_static_gain_run(&dir.path);
    let (_, trace) = read_csv(&dir.path.join("trace.csv"));
    assert_eq!(trace.len(), 2000, "the C plant's trace");
}
