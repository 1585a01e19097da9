//! A plant written in C, through the C interface (`ipc-types/include/adaptive_rig.h`,
//! `libadaptive_rig.a`), against the real service: the C example
//! `ipc-types/c/examples/first_order_plant.c` is compiled with the machine's C compiler and
//! linked against the workspace's static library, then closes the loop in lockstep.
//!
//! The library is built before these tests by cargo itself: `adaptive-rig-c` is a
//! dependency of this crate, so `cargo test --workspace` compiles its lib target, with every
//! crate type (`rlib`, `staticlib`, `cdylib`), into `target/<profile>/deps` first.

use rig_tests::*;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;
use std::time::Duration;

/// `target/<profile>`, the folder of the workspace binaries.
fn profile_dir() -> PathBuf {
    bin("service").parent().unwrap().to_path_buf()
}

/// The static library cargo built for this test run (`deps/` holds the build of this
/// profile; the copy in `target/<profile>` is only refreshed by `cargo build`).
fn static_lib() -> PathBuf {
    let dir = profile_dir();
    [
        dir.join("deps/libadaptive_rig.a"),
        dir.join("libadaptive_rig.a"),
    ]
    .into_iter()
    .find(|p| p.exists())
    .unwrap_or_else(|| panic!("no libadaptive_rig.a under {}", dir.display()))
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Compiles `source` (C or C++ by `compiler`) against the header and the static library
/// into `out`; panics with the compiler's output when it fails.
fn build(compiler: &str, flags: &[&str], source: &Path, out: &Path) {
    let include = repo().join("ipc-types/include");
    let result = Command::new(compiler)
        .args(flags)
        .arg("-I")
        .arg(&include)
        .arg(source)
        .arg(static_lib())
        .args([
            "-lgcc_s",
            "-lutil",
            "-lrt",
            "-lpthread",
            "-lm",
            "-ldl",
            "-lc",
            "-o",
        ])
        .arg(out)
        .output()
        .unwrap_or_else(|e| panic!("running {compiler} (a C compiler is required): {e}"));
    assert!(
        result.status.success(),
        "{compiler} {} failed:\n{}",
        source.display(),
        String::from_utf8_lossy(&result.stderr)
    );
}

/// The C example, compiled once per test process.
fn c_plant() -> &'static Path {
    static EXE: OnceLock<PathBuf> = OnceLock::new();
    EXE.get_or_init(|| {
        let dir = profile_dir()
            .join("..")
            .join("test-runs")
            .join(format!("c-build-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let exe = dir.join("first_order_plant");
        build(
            "cc",
            &["-std=c11", "-Wall", "-Wextra", "-Werror", "-O2"],
            &repo().join("ipc-types/c/examples/first_order_plant.c"),
            &exe,
        );
        exe
    })
}

/// The scenario first-order-lockstep on rig `rig` with the test service tables and
/// `controller`.
fn scenario(dir: &TestDir, file: &str, rig: &str, controller: &str) -> PathBuf {
    let text = with_rig_name(&scenario_text("first-order-lockstep.toml"), rig)
        + &test_service_tables("", controller);
    dir.write(file, &text)
}

/// Runs the service against the C plant in lockstep for `steps` samples; returns the C
/// plant's trace rows (`k,y,u`) and the service's report.
fn run_c_pair(
    dir: &TestDir,
    rig: &str,
    controller: &str,
    steps: u64,
) -> (Vec<Vec<f64>>, serde_json::Value) {
    let scenario = scenario(dir, "c-scenario.toml", rig, controller);
    let run_folder = dir.path.join("c-service-run");
    let trace = dir.path.join("c-trace.csv");
    let mut service = start_service_until_plant_ends(&scenario, &run_folder);
    let steps_arg = steps.to_string();
    let mut plant = Proc::start(
        "c-plant",
        c_plant(),
        &[rig, &steps_arg, "lockstep", trace.to_str().unwrap()],
    );
    plant.wait_success(Duration::from_secs(300));
    service.wait_success(Duration::from_secs(60));
    let done = plant.wait_for_line("done:", Duration::from_secs(1));
    assert!(
        done.contains(&format!(
            "done: {steps} samples, {steps} actuations applied, 0 misses"
        )),
        "{done}"
    );
    let (header, rows) = read_csv(&trace);
    assert_eq!(header, ["k", "y", "u"]);
    (rows, read_json(&run_folder.join("report.json")))
}

#[test]
fn a_c_plant_closes_the_loop_with_the_service_exactly_as_plant_proxy_does() {
    let steps = 3000;
    let dir = TestDir::new("c-vs-proxy");
    let controller = fixture("dynamic-controller.toml");

    // The same loop with plant-proxy, the reference.
    let proxy_rig = rig_name("c-ref");
    let proxy_scenario = scenario(&dir, "proxy-scenario.toml", &proxy_rig, &controller);
    let proxy_trace = dir.path.join("proxy-trace.csv");
    let proxy_run = run_lockstep_pair(
        &dir,
        &proxy_scenario,
        steps,
        &["--trace", proxy_trace.to_str().unwrap()],
    );
    let (header, proxy_rows) = read_csv(&proxy_trace);
    let (y_col, u_col) = (column(&header, "y0"), column(&header, "u0"));

    let (c_rows, c_report) = run_c_pair(&dir, &rig_name("c-plant"), &controller, steps);
    assert_eq!(c_rows.len() as u64, steps);
    assert_eq!(proxy_rows.len(), c_rows.len());
    let (mut worst_y, mut worst_u) = (0.0_f64, 0.0_f64);
    for (p, c) in proxy_rows.iter().zip(&c_rows) {
        assert_eq!(p[0], c[0], "sample numbers");
        worst_y = worst_y.max((p[y_col] - c[1]).abs());
        worst_u = worst_u.max((p[u_col] - c[2]).abs());
    }
    eprintln!("C plant vs plant-proxy, largest deviations: y {worst_y:e}, u {worst_u:e}");
    assert!(worst_y <= 1e-12, "largest deviation of y: {worst_y:e}");
    assert!(worst_u <= 1e-12, "largest deviation of u: {worst_u:e}");
    // The loop is not trivial: the controller moved the plant.
    assert!(c_rows.iter().any(|r| r[2].abs() > 0.1));

    let proxy_report = read_json(&proxy_run.join("report.json"));
    for report in [&proxy_report, &c_report] {
        assert_eq!(report["stats"]["controller_steps"], steps, "{report}");
        assert_eq!(report["stats"]["deadline_misses"], 0, "{report}");
    }
}

#[test]
fn a_c_plant_with_another_channel_count_is_refused_naming_the_difference() {
    let dir = TestDir::new("c-mismatch");
    let rig = rig_name("c-mismatch");
    let scenario = scenario(&dir, "scenario.toml", &rig, &static_gain_controller());
    let service = start_service("service", &scenario, &dir.path.join("service-run"));
    service.wait_for_line("waiting for the plant", Duration::from_secs(60));
    let mut plant = Proc::start(
        "c-plant",
        c_plant(),
        &[&rig, "100", "lockstep", "--n-y", "2"],
    );
    let out = plant.wait_failure(Duration::from_secs(60));
    assert!(
        out.contains(&format!(
            "first_order_plant: ar_plant_open: AR_ERR_MISMATCH: contract mismatch on 'adaptive-rig/{rig}/actuation' (defined by the service), refusing to connect:"
        )),
        "{out}"
    );
    assert!(
        out.contains("- measurement channels (y): service uses 1, plant uses 2"),
        "{out}"
    );
    assert!(
        !out.contains("performance channels"),
        "only the difference: {out}"
    );
}

#[test]
fn a_cxx_program_links_against_the_library_and_calls_it() {
    let dir = TestDir::new("c-cxx");
    let source = dir.write(
        "use.cpp",
        r#"#include "adaptive_rig.h"
#include <cstdio>
int main() {
    ar_plant_t* plant = nullptr;
    ar_status_t rc = ar_plant_open(nullptr, &plant);
    std::printf("%s|%s|%d\n", ar_status_name(rc), ar_last_error(), ar_monotonic_ns() > 0 ? 1 : 0);
    return rc == AR_ERR_INVALID_ARGUMENT ? 0 : 1;
}
"#,
    );
    let exe = dir.path.join("use");
    build("c++", &["-std=c++11", "-Wall", "-Werror"], &source, &exe);
    let out = Command::new(&exe).output().unwrap();
    assert!(out.status.success());
    assert_eq!(
        String::from_utf8_lossy(&out.stdout),
        "AR_ERR_INVALID_ARGUMENT|ar_plant_open: config: null pointer|1\n"
    );
}
