//! The Python interface of the contract (`ipc-types/python`) against the Rust processes:
//! the payload layout, a Python plant against the real service and the Python controller
//! against the real plant-proxy (both in lockstep, compared sample by sample with the
//! all-Rust loop), and the refusals (wrong contract version, wrong channel count, a second
//! plant) with the same texts on both sides as with a Rust peer.
//!
//! The Python interpreter comes from `rig_tests::python` (`$RIG_PYTHON`, or a venv made
//! once under the target folder); without one these tests fail, saying why.

use rig_tests::python::{command, start_example};
use rig_tests::*;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Samples of every closed-loop run.
const STEPS: u64 = 2000;
/// The largest difference allowed between a Python loop and the all-Rust loop.
const TOL: f64 = 1e-12;

/// A CSV file read by `read_csv`: its header and rows.
type Csv = (Vec<String>, Vec<Vec<f64>>);

/// `scenarios/first-order-lockstep.toml` on rig `rig`, with the test service tables and the
/// static-gain controller u = −2 y, written into `dir` as `file`.
fn first_order_scenario(dir: &TestDir, rig: &str, file: &str) -> PathBuf {
    let text = with_rig_name(&scenario_text("first-order-lockstep.toml"), rig)
        + &test_service_tables("", &static_gain_controller());
    dir.write(file, &text)
}

/// The all-Rust loop: plant-proxy (lockstep, `--trace`) against the service; returns the
/// plant's trace and the service's signals.csv, as (header, rows) each.
fn all_rust_loop(dir: &TestDir, rig: &str) -> (Csv, Csv) {
    let sc = first_order_scenario(dir, rig, "rust-scenario.toml");
    let trace = dir.path.join("rust-trace.csv");
    let run = run_lockstep_pair_into(
        dir,
        "rust-run",
        &sc,
        STEPS,
        &["--trace", trace.to_str().unwrap()],
        &[],
    );
    let t = read_csv(&trace);
    assert_eq!(t.1.len() as u64, STEPS, "rows of {}", trace.display());
    (t, read_csv(&run.join("signals.csv")))
}

/// Compares column `name` of two CSV tables row by row to `TOL` (`exact`: bit for bit),
/// naming the files, the column and the first row that differs.
fn compare_column((what_a, a): (&str, &Csv), (what_b, b): (&str, &Csv), name: &str, exact: bool) {
    let (ca, cb) = (column(&a.0, name), column(&b.0, name));
    assert_eq!(a.1.len(), b.1.len(), "rows of {what_a} and {what_b}");
    for (i, (ra, rb)) in a.1.iter().zip(&b.1).enumerate() {
        let (x, y) = (ra[ca], rb[cb]);
        let ok = if exact { x == y } else { (x - y).abs() <= TOL };
        assert!(
            ok,
            "column {name}, row {i}: {what_a} has {x:e}, {what_b} has {y:e} (allowed: {})",
            if exact {
                "equal".to_string()
            } else {
                format!("{TOL:e}")
            }
        );
    }
}

/// Layout of one Rust struct: size, alignment and (field, offset) pairs.
macro_rules! rust_layout {
    ($t:ty, $($f:ident),+ $(,)?) => {
        (
            core::mem::size_of::<$t>(),
            core::mem::align_of::<$t>(),
            vec![$((stringify!($f), core::mem::offset_of!($t, $f))),+],
        )
    };
}

#[test]
fn the_python_payloads_have_the_layout_and_type_names_of_the_rust_structs() {
    use iceoryx2::prelude::ZeroCopySend;
    use ipc_types::{Actuation, ChannelCounts, Measurement};
    let out = command(&["-m", "adaptive_rig", "layout"])
        .output()
        .expect("running python -m adaptive_rig layout");
    assert!(
        out.status.success(),
        "python -m adaptive_rig layout: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let py: serde_json::Value =
        serde_json::from_slice(&out.stdout).expect("python -m adaptive_rig layout prints JSON");
    // SAFETY: type_name only returns the constant given in #[type_name].
    let names = unsafe {
        [
            Measurement::type_name(),
            Actuation::type_name(),
            ChannelCounts::type_name(),
        ]
    };
    let rust = [
        (
            "Measurement",
            rust_layout!(
                Measurement,
                contract_version,
                flags,
                seq,
                t_sample_ns,
                period_ns,
                deadline_ns,
                counts,
                y,
                z,
                r,
                u_applied
            ),
        ),
        (
            "Actuation",
            rust_layout!(
                Actuation,
                contract_version,
                status,
                seq,
                reply_to,
                t_sample_ns,
                t_publish_ns,
                compute_ns,
                counts,
                timing,
                plan_len,
                u,
                plan
            ),
        ),
        (
            "ChannelCounts",
            rust_layout!(ChannelCounts, n_y, n_z, n_r, n_u),
        ),
    ];
    for ((name, (size, align, fields)), type_name) in rust.iter().zip(names) {
        let p = &py[name];
        assert_eq!(
            p["type_name"], type_name,
            "adaptive_rig.contract.{name}.type_name()"
        );
        assert_eq!(p["size"], *size, "size of adaptive_rig.contract.{name}");
        assert_eq!(
            p["align"], *align,
            "alignment of adaptive_rig.contract.{name}"
        );
        let py_fields: Vec<(String, usize)> = serde_json::from_value(p["fields"].clone())
            .unwrap_or_else(|e| panic!("fields of {name} in the layout JSON: {e}"));
        let rust_fields: Vec<(String, usize)> =
            fields.iter().map(|(f, o)| (f.to_string(), *o)).collect();
        assert_eq!(
            py_fields, rust_fields,
            "the (field, offset) list of {name}, in order: Python (adaptive_rig/contract.py) vs Rust"
        );
    }
}

#[test]
fn the_python_unit_tests_pass() {
    // ipc-types/python/tests: the peer pin, the actuation book, counts and refusal texts.
    let dir = rig_tests::python::package_dir().join("tests");
    let out = command(&[
        "-m",
        "unittest",
        "discover",
        "-v",
        "-s",
        dir.to_str().unwrap(),
    ])
    .output()
    .expect("running python -m unittest");
    assert!(
        out.status.success(),
        "python -m unittest discover -s {}:\n{}",
        dir.display(),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The options that make a plant write its trace and its report to `trace` and `report`.
fn trace_and_report<'a>(trace: &'a Path, report: &'a Path) -> [&'a str; 4] {
    let path = |p: &'a Path| p.to_str().expect("a UTF-8 path");
    ["--trace", path(trace), "--report", path(report)]
}

#[test]
fn a_python_plant_against_the_service_matches_the_all_rust_loop() {
    let dir = TestDir::new("py-plant");
    let (rust_trace, rust_signals) = all_rust_loop(&dir, &rig_name("py-plant-rust"));

    let rig = rig_name("py-plant");
    let sc = first_order_scenario(&dir, &rig, "py-scenario.toml");
    let run = dir.path.join("py-run");
    let (trace, report) = (
        dir.path.join("py-trace.csv"),
        dir.path.join("py-report.json"),
    );
    let mut service = start_service_until_plant_ends(&sc, &run);
    let mut plant = start_example(
        "python plant",
        "first_order_plant.py",
        &[
            &["--rig", &rig, "--steps", &STEPS.to_string()][..],
            &trace_and_report(&trace, &report),
        ]
        .concat(),
    );
    plant.wait_success(Duration::from_secs(300));
    service.wait_success(Duration::from_secs(60));

    // The plant's view: y_k and the input applied for k, Python against plant-proxy.
    let py_trace = read_csv(&trace);
    let a = ("the Python plant's trace", &py_trace);
    let b = ("plant-proxy's trace", &rust_trace);
    compare_column(a, b, "k", true);
    compare_column(a, b, "y0", false);
    compare_column(a, b, "u0", false);
    // The service's view: the same flags (LOCKSTEP, U_APPLIED, LAST_SAMPLE), statuses,
    // measurements and inputs from either plant.
    let py_signals = read_csv(&run.join("signals.csv"));
    let a = ("signals.csv with the Python plant", &py_signals);
    let b = ("signals.csv with plant-proxy", &rust_signals);
    for (c, exact) in [
        ("seq", true),
        ("flags", true),
        ("status", true),
        ("y0", false),
        ("z0", false),
        ("u0", false),
    ] {
        compare_column(a, b, c, exact);
    }
    let r = read_json(&report);
    assert_eq!(r["samples"], STEPS, "{r}");
    assert_eq!(r["actuations_applied"], STEPS, "{r}");
    assert_eq!(r["misses"], 0, "{r}");
    assert_eq!(r["foreign_discarded"], 0, "{r}");
}

/// plant-proxy (lockstep, `STEPS` samples) against the real service and against the
/// Python controller (`static_gain_controller.py` with `py_args`) on the first-order
/// scenario with the test service tables, `extra_service` and `controller`: compares the two
/// traces sample by sample (k, t and flags exactly; y, z and the applied u to `TOL`) and
/// returns the trace with the Python controller and plant-proxy's report of that run.
fn plant_proxy_against_python_and_rust_controllers(
    test: &str,
    extra_service: &str,
    controller: &str,
    py_args: &[&str],
) -> (Csv, serde_json::Value) {
    let dir = TestDir::new(test);
    let scenario = |rig: &str, file: &str| {
        let text = with_rig_name(&scenario_text("first-order-lockstep.toml"), rig)
            + &test_service_tables(extra_service, controller);
        dir.write(file, &text)
    };
    let rust_trace = dir.path.join("rust-trace.csv");
    run_lockstep_pair_into(
        &dir,
        "rust-run",
        &scenario(&rig_name(&format!("{test}-rust")), "rust-scenario.toml"),
        STEPS,
        &["--trace", rust_trace.to_str().unwrap()],
        &[],
    );

    let rig = rig_name(test);
    let sc = scenario(&rig, "py-scenario.toml");
    let (trace, report) = (dir.path.join("trace.csv"), dir.path.join("report.json"));
    let mut args = vec!["--rig", rig.as_str()];
    args.extend_from_slice(py_args);
    let mut controller = start_example("python controller", "static_gain_controller.py", &args);
    let mut plant = start_lockstep_plant("plant", &sc, STEPS, &trace_and_report(&trace, &report));
    plant.wait_success(Duration::from_secs(300));
    controller.wait_success(Duration::from_secs(60));

    // plant-proxy's trace with either controller: the same samples, times, y, z, applied
    // inputs and flags. The status differs by design: the service flags its grace periods
    // STARTING, the Python controller answers OK throughout.
    let py = read_csv(&trace);
    let rust = read_csv(&rust_trace);
    let a = ("plant-proxy's trace with the Python controller", &py);
    let b = ("plant-proxy's trace with the service", &rust);
    for (c, exact) in [
        ("k", true),
        ("t", true),
        ("flags", true),
        ("y0", false),
        ("z0", false),
        ("u0", false),
    ] {
        compare_column(a, b, c, exact);
    }
    let status = column(&py.0, "actuation_status");
    assert!(
        py.1.iter().all(|r| r[status] == 0.0),
        "the Python controller answers OK"
    );
    let r = read_json(&report);
    assert_eq!(r["actuations_applied"], STEPS, "{r}");
    assert_eq!(r["misses"], 0, "{r}");
    assert_eq!(r["foreign_discarded"], 0, "{r}");
    (py, r)
}

#[test]
fn plant_proxy_against_the_python_controller_matches_the_all_rust_loop() {
    let (_, report) = plant_proxy_against_python_and_rust_controllers(
        "py-controller",
        "",
        &static_gain_controller(),
        &[],
    );
    assert_eq!(report["timing"], "compute-first", "{report}");
}

#[test]
fn plant_proxy_against_a_send_ahead_python_controller_matches_the_send_ahead_service() {
    // The delayed gain u_{k+1} = −2 y_k, sent ahead: by the service (an LTI controller with
    // D = 0, service.timing = "send-ahead") and by the Python controller (--send-ahead).
    let (py, report) = plant_proxy_against_python_and_rust_controllers(
        "py-send-ahead",
        "timing = \"send-ahead\"\n",
        &fixture("delayed-gain-controller.toml"),
        &["--send-ahead"],
    );
    assert_eq!(report["timing"], "send-ahead", "{report}");
    // The loop really ran ahead: u_k = −2 y_{k−1} was applied at every sample but the first
    // (answered with the initial input 0, as the service answers it from x_0 = 0).
    let (iy, iu) = (column(&py.0, "y0"), column(&py.0, "u0"));
    assert_eq!(py.1[0][iu], 0.0);
    for k in 1..py.1.len() {
        assert!(
            (py.1[k][iu] + 2.0 * py.1[k - 1][iy]).abs() <= TOL,
            "u at k = {k} is not −2 y_(k−1)"
        );
    }
}

/// The message after `prefix` in `output` with its "  - " lines, the rig name replaced by
/// `<rig>`; panics naming `who` when there is none.
fn message(who: &str, output: &str, prefix: &str, rig: &str) -> String {
    let mut lines = output.lines().skip_while(|l| !l.contains(prefix));
    let first = lines
        .next()
        .unwrap_or_else(|| panic!("{who} printed no '{prefix}…':\n{output}"));
    let mut text = first[first.find(prefix).unwrap() + prefix.len()..].to_string();
    for l in lines.take_while(|l| l.starts_with("  - ")) {
        text += "\n";
        text += l;
    }
    text.replace(rig, "<rig>")
}

/// Starts the service on `service_scenario` (its rig `rig`), waits until it waits for the
/// plant, runs `plant`, and returns the refusals both print (after `plant_prefix` and
/// `service: `); both must fail.
fn refused_by_the_service(
    dir: &TestDir,
    rig: &str,
    service_scenario: &Path,
    plant: impl FnOnce() -> Proc,
    plant_prefix: &str,
) -> (String, String) {
    let run = dir.path.join(format!("run-{rig}"));
    let mut service = start_service("service", service_scenario, &run);
    service.wait_for_line("waiting for the plant", Duration::from_secs(30));
    let mut p = plant();
    let plant_out = p.wait_failure(Duration::from_secs(60));
    let service_out = service.wait_failure(Duration::from_secs(60));
    (
        message("the plant", &plant_out, plant_prefix, rig),
        message("the service", &service_out, "service: ", rig),
    )
}

/// [`refused_by_the_service`] for the Python example plant started with `args` after
/// `--rig rig`, against the first-order service of rig `rig`.
fn python_plant_refused(dir: &TestDir, rig: &str, args: &[&str]) -> (String, String) {
    let mut all = vec!["--rig", rig];
    all.extend_from_slice(args);
    refused_by_the_service(
        dir,
        rig,
        &first_order_scenario(dir, rig, "py.toml"),
        || start_example("python plant", "first_order_plant.py", &all),
        "python plant: ",
    )
}

/// The Python plant's refusal is `plant_text`, and both refusals (the plant's and the
/// service's) are the same for the Python and the Rust plant.
fn assert_same_refusals(py: (&str, &str), rust: (&str, &str), plant_text: &str) {
    assert_eq!(py.0, plant_text);
    assert_eq!(py.0, rust.0, "the plant's refusal, Python vs Rust");
    assert_eq!(
        py.1, rust.1,
        "the service's refusal of a Python vs a Rust plant"
    );
}

#[test]
fn a_plant_of_another_contract_version_is_refused_with_the_texts_of_a_rust_plant() {
    let dir = TestDir::new("py-version");
    let (py_rig, rust_rig) = (rig_name("py-version"), rig_name("rust-version"));
    let (py_plant, py_service) = python_plant_refused(&dir, &py_rig, &["--contract-version", "2"]);
    let (rust_plant, rust_service) = refused_by_the_service(
        &dir,
        &rust_rig,
        &first_order_scenario(&dir, &rust_rig, "rust.toml"),
        || {
            Proc::start(
                "rust plant",
                &bin("contract_plant"),
                &[&rust_rig, "--contract-version", "2"],
            )
        },
        "contract_plant: ",
    );
    assert_same_refusals(
        (&py_plant, &py_service),
        (&rust_plant, &rust_service),
        "contract mismatch on 'adaptive-rig/<rig>/actuation' (defined by the service), \
         refusing to connect:\n  - contract version: service has 3, plant has 2",
    );
    assert_eq!(
        py_service,
        "contract mismatch on 'adaptive-rig/<rig>/measurement' (defined by the plant), \
         refusing to connect:\n  - contract version: plant has 2, service has 3"
    );
}

#[test]
fn a_plant_with_another_measurement_count_is_refused_with_the_texts_of_plant_proxy() {
    let dir = TestDir::new("py-counts");
    let (py_rig, rust_rig) = (rig_name("py-counts"), rig_name("rust-counts"));
    // plant-proxy's plant: the first-order plant measured twice (n_y = 2).
    let two_y = |rig: &str| {
        let text = with_rig_name(&scenario_text("first-order-lockstep.toml"), rig);
        let tf = "{ num = [1.0], den = [1.0, 5.0] }";
        let text = text.replace("outputs-y = 1", "outputs-y = 2").replace(
            &format!("yu = [[ {tf} ]]"),
            &format!("yu = [[ {tf} ], [ {tf} ]]"),
        );
        assert!(
            text.contains("outputs-y = 2") && text.contains("], ["),
            "{text}"
        );
        dir.write("rust-plant.toml", &text)
    };
    let (py_plant, py_service) = python_plant_refused(&dir, &py_rig, &["--n-y", "2"]);
    let plant_scenario = two_y(&rust_rig);
    let (rust_plant, rust_service) = refused_by_the_service(
        &dir,
        &rust_rig,
        &first_order_scenario(&dir, &rust_rig, "rust.toml"),
        || start_lockstep_plant("plant-proxy", &plant_scenario, 100, &[]),
        "plant-proxy: ",
    );
    assert_same_refusals(
        (&py_plant, &py_service),
        (&rust_plant, &rust_service),
        "contract mismatch on 'adaptive-rig/<rig>/actuation' (defined by the service), \
         refusing to connect:\n  - measurement channels (y): service uses 1, plant uses 2",
    );
    assert_eq!(
        py_service,
        "contract mismatch on 'adaptive-rig/<rig>/measurement' (defined by the plant), \
         refusing to connect:\n  - measurement channels (y): plant uses 2, service uses 1"
    );
}

#[test]
fn a_plant_differing_in_every_respect_is_refused_with_every_difference_as_a_rust_plant() {
    let dir = TestDir::new("py-every");
    let (py_rig, rust_rig) = (rig_name("py-every"), rig_name("rust-every"));
    // Version 2, two measurement channels, a 2 ms period, inputs applied at the sample
    // instant (real time, deadline 0) against a compute-first service of 1 ms.
    let (py_plant, py_service) = python_plant_refused(
        &dir,
        &py_rig,
        &[
            "--contract-version",
            "2",
            "--n-y",
            "2",
            "--period",
            "0.002",
            "--mode",
            "real-time",
            "--deadline",
            "0",
        ],
    );
    let (rust_plant, rust_service) = refused_by_the_service(
        &dir,
        &rust_rig,
        &first_order_scenario(&dir, &rust_rig, "rust.toml"),
        || {
            Proc::start(
                "rust plant",
                &bin("contract_plant"),
                &[
                    &rust_rig,
                    "--contract-version",
                    "2",
                    "--n-y",
                    "2",
                    "--period-ns",
                    "2000000",
                    "--at-sample",
                ],
            )
        },
        "contract_plant: ",
    );
    assert_same_refusals(
        (&py_plant, &py_service),
        (&rust_plant, &rust_service),
        "contract mismatch on 'adaptive-rig/<rig>/actuation' (defined by the service), \
         refusing to connect:\n  - contract version: service has 3, plant has 2\n  - \
         measurement channels (y): service uses 1, plant uses 2\n  - sample period: service \
         runs at 1000000 ns (1000.000 Hz), plant at 2000000 ns (500.000 Hz)\n  - timing: the \
         plant applies each input at its sample instant (its deadline is 0), which only a \
         service that sends ahead can meet; the service answers compute-first (set \
         service.timing = \"send-ahead\", or give the plant a deadline inside the period)",
    );
    assert_eq!(py_service.lines().count(), 5, "{py_service}");
}

/// `text` with the number of seconds after "within " replaced by `<s>`.
fn without_seconds(text: &str) -> String {
    match (text.find("within "), text.find(" s (")) {
        (Some(a), Some(b)) if a < b => format!("{}<s>{}", &text[..a + 7], &text[b..]),
        _ => text.to_string(),
    }
}

#[test]
fn a_plant_without_a_service_times_out_with_the_text_of_a_rust_plant() {
    let (py_rig, rust_rig) = (rig_name("py-alone"), rig_name("rust-alone"));
    let py = start_example(
        "python plant",
        "first_order_plant.py",
        &["--rig", &py_rig, "--peer-timeout", "0.3"],
    )
    .wait_failure(Duration::from_secs(60));
    let rust = Proc::start(
        "rust plant",
        &bin("contract_plant"),
        &[&rust_rig, "--peer-timeout", "0.3"],
    )
    .wait_failure(Duration::from_secs(60));
    let py = without_seconds(&message("the Python plant", &py, "python plant: ", &py_rig));
    let rust = without_seconds(&message(
        "the Rust plant",
        &rust,
        "contract_plant: ",
        &rust_rig,
    ));
    assert_eq!(
        py,
        "no peer: 'adaptive-rig/<rig>/actuation' did not appear within <s> s (is the other \
         process running with the same rig name?)"
    );
    assert_eq!(py, rust, "the timeout, Python vs Rust");
}

#[test]
fn a_second_plant_is_refused_naming_the_first_in_python_as_in_rust() {
    let dir = TestDir::new("py-second");
    let rig = rig_name("py-second");
    let sc = first_order_scenario(&dir, &rig, "scenario.toml");
    let first = start_lockstep_plant("first plant", &sc, 100, &[]);
    first.wait_for_line("waiting for the service", Duration::from_secs(30));
    let py = start_example("python plant", "first_order_plant.py", &["--rig", &rig])
        .wait_failure(Duration::from_secs(60));
    let rust =
        start_lockstep_plant("second plant", &sc, 100, &[]).wait_failure(Duration::from_secs(60));
    let py = message("the Python plant", &py, "python plant: ", &rig);
    let rust = message("the second plant-proxy", &rust, "plant-proxy: ", &rig);
    assert_eq!(
        py,
        format!(
            "rig '<rig>' already has a plant: pid {} (node 'adaptive-rig-plant'), which holds \
             the one publisher of 'adaptive-rig/<rig>/measurement'; refusing to start a second \
             plant",
            first.child.id()
        )
    );
    assert_eq!(
        py, rust,
        "the refusal of a second plant, Python vs plant-proxy"
    );
}
