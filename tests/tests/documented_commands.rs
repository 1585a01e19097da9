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
    // The Python environment first (a fresh one installs iceoryx2 from PyPI, which can take
    // longer than a peer waits for the other side), then the loops as written.
    let _ = python();

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

/// The documents whose `sh` blocks are checked against the code.
fn documents() -> Vec<PathBuf> {
    let mut docs = vec![
        repo().join("README.md"),
        repo().join("ipc-types/python/README.md"),
        repo().join("ipc-types/c/README.md"),
    ];
    let mut pages: Vec<PathBuf> = std::fs::read_dir(repo().join("docs"))
        .expect("docs/")
        .map(|e| e.expect("a docs entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    pages.sort();
    docs.extend(pages);
    docs
}

/// The folder of a workspace package, for `cargo test -p P --test T`.
fn package_dir(package: &str) -> PathBuf {
    let dir = match package {
        "control" => "service/control",
        "rig-tools" => "service/tools",
        "rig-tests" => "tests",
        "plant-side" => "plant-proxy/plant-side",
        "rig-scenario" => "ipc-types/scenario",
        "adaptive-rig-c" => "ipc-types/c",
        other => other,
    };
    repo().join(dir)
}

/// `name` (a glob with `*` at most at its end) matches at least one `<dir>/<name>.rs`.
fn target_exists(dir: &Path, name: &str) -> bool {
    let name = name.trim_matches('\'');
    let Ok(entries) = std::fs::read_dir(dir) else {
        return false;
    };
    entries.filter_map(|e| e.ok()).any(|e| {
        let file = e.file_name().to_string_lossy().into_owned();
        let stem = file.strip_suffix(".rs").unwrap_or("");
        match name.strip_suffix('*') {
            Some(prefix) => stem.starts_with(prefix),
            None => stem == name,
        }
    })
}

/// The binary and its arguments of a documented line that runs one of the workspace's
/// programs (`target/release/B …` or `cargo run … [-p P] [--bin B] -- …`).
fn program_of(words: &[&str]) -> Option<(String, Vec<String>)> {
    let owned = |w: &[&str]| w.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    if let Some(b) = words.first()?.strip_prefix("target/release/") {
        return (!b.contains('.')).then(|| (b.to_string(), owned(&words[1..])));
    }
    if words.len() >= 2 && words[0] == "cargo" && words[1] == "run" {
        let flag = |f: &str| words.iter().position(|w| *w == f).map(|i| words[i + 1]);
        // An example is built next to the binaries, in `examples/`.
        let name = match flag("--example") {
            Some(e) => format!("examples/{e}"),
            None => flag("--bin").or(flag("-p"))?.to_string(),
        };
        let args = words
            .iter()
            .position(|w| *w == "--")
            .map_or(&[][..], |i| &words[i + 1..]);
        return Some((name, owned(args)));
    }
    None
}

/// Checks one documented line against the code; returns what is wrong with it.
fn line_problems(line: &str) -> Vec<String> {
    let mut problems = Vec::new();
    let line = line.split(" #").next().unwrap_or(line).trim();
    let line = line.trim_end_matches('&').trim();
    let words: Vec<&str> = line.split_whitespace().collect();
    // Every repository file the line reads exists (what it writes, after `>`, need not).
    for w in words.iter().take_while(|w| **w != ">") {
        let w = w.trim_matches(|c| matches!(c, '\'' | '"' | ',' | '[' | ']'));
        let named = ["scenarios/", "tests/fixtures/", "ipc-types/", "docs/"]
            .iter()
            .any(|p| w.starts_with(p));
        let placeholder = w.contains(['<', '$', '*', '{']);
        if named && !placeholder && !repo().join(w).exists() {
            problems.push(format!("no file {w}"));
        }
    }
    // A test or bench target exists in its package.
    if words.len() > 1 && words[0] == "cargo" && matches!(words[1], "test" | "bench") {
        let package = words.iter().position(|w| *w == "-p").map(|i| words[i + 1]);
        for (flag, folder) in [("--test", "tests"), ("--bench", "benches")] {
            for (i, _) in words.iter().enumerate().filter(|(_, w)| **w == flag) {
                let dir = package_dir(package.unwrap_or("rig-tests")).join(folder);
                if !target_exists(&dir, words[i + 1]) {
                    problems.push(format!("no {flag} {} in {}", words[i + 1], dir.display()));
                }
            }
        }
    }
    // A program's subcommand exists and takes every option the line gives (an example
    // reads plain arguments, which its own test runs).
    if let Some((program, args)) = program_of(&words).filter(|(p, _)| !p.starts_with("examples/")) {
        let sub = args
            .first()
            .filter(|a| !a.starts_with('-') && !a.contains(['/', '.', '<', '$']));
        let mut help = Command::new(bin(&program));
        help.args(sub).arg("--help");
        match help.output() {
            Ok(out) if out.status.success() => {
                let text = String::from_utf8_lossy(&out.stdout);
                for a in args.iter().filter(|a| a.starts_with("--") && a.len() > 2) {
                    let option = a.split('=').next().unwrap_or(a);
                    if !text.contains(option) {
                        problems.push(format!(
                            "{program} {} has no option {option}",
                            sub.map_or("", |s| s)
                        ));
                    }
                }
            }
            Ok(out) => problems.push(format!(
                "`{program} {} --help` failed: {}",
                sub.map_or("", |s| s),
                String::from_utf8_lossy(&out.stderr)
            )),
            Err(e) => problems.push(format!("{program} did not start: {e}")),
        }
    }
    problems
}

#[test]
fn every_documented_command_names_existing_files_targets_and_options() {
    let mut checked = 0;
    let mut problems = Vec::new();
    for doc in documents() {
        let text =
            std::fs::read_to_string(&doc).unwrap_or_else(|e| panic!("{}: {e}", doc.display()));
        for line in sh_blocks(&text).into_iter().flatten() {
            let p = line_problems(&line);
            checked += 1;
            problems.extend(
                p.into_iter()
                    .map(|p| format!("{}: `{line}`: {p}", doc.display())),
            );
        }
    }
    assert!(checked > 40, "only {checked} documented commands");
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn the_documented_checks_run_as_written() {
    for doc in documents() {
        let text = std::fs::read_to_string(&doc).expect("the document");
        for line in sh_blocks(&text).into_iter().flatten() {
            let line = line.split(" #").next().unwrap_or(&line).trim().to_string();
            let words: Vec<&str> = line.split_whitespace().collect();
            let runs_a_check = matches!(
                words.get(..2),
                Some(["target/release/service" | "target/release/rig", "check"])
                    | Some(["target/release/plant-proxy", "describe" | "check"])
            );
            if runs_a_check
                && words
                    .iter()
                    .all(|w| !w.contains(['<', '$']) && !w.starts_with("my-"))
            {
                let out = Command::new(bin(words[0].trim_start_matches("target/release/")))
                    .args(&words[1..])
                    .current_dir(repo())
                    .output()
                    .expect("the check starts");
                assert!(
                    out.status.success(),
                    "{}: `{line}`: {}",
                    doc.display(),
                    String::from_utf8_lossy(&out.stderr)
                );
            }
        }
    }
}
