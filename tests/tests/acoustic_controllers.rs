//! The acoustic rig's shipped adaptive controllers, each in lockstep (deterministic) on the
//! main job's scenario `scenarios/acoustic-rig.toml`, the real processes over shared
//! memory: the scenario's gradient RCAC, full-RLS RCAC (`scenarios/rcac/acoustic-rls.toml`)
//! and PCAC (`scenarios/pcac/acoustic.toml`, checked against its own bars: see
//! [`PCAC_MEDIAN_DB`] and [`PCAC_FLOOR_DB`]), and PCAC with the internal model of the known tones
//! (`scenarios/pcac/acoustic-internal-model.toml`, 40 dB). Each RCAC must meet its own acceptance criterion
//! (`service.report.min-suppression-db`: 60 dB and 40 dB for every one of the seven tones
//! at the end of the 10 s run), pass its verdict, and show no burst once adapted: a burst
//! is the adapted loop leaving its stability margin for a moment, `z` ringing up several
//! times its residual and the inputs climbing from about 11 V towards their ±40 V limits
//! (docs/rcac.md, "Variants on the same rig"). From 2 s on (the open loop and the first
//! closed-loop second excluded) the RMS of `z` over windows of 0.25 s must stay within
//! [`Z_RING_MAX`] times its median over those windows, and |u| within [`U_ADAPTED_MAX`].
//!
//! Measured (lockstep, deterministic): the largest window over the median is 1.34 for the
//! gradient update and 1.12 for full RLS at `p0 = 0.15`; at `p0 = 0.1` and 0.12 a burst
//! near 5 s gives 5.5 and 5.8.

use rig_tests::*;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The largest |u| allowed after the first two seconds (the open loop and the first
/// closed-loop second): the adapted inputs stay near 11 V, a burst reaches the 40 V limit.
const U_ADAPTED_MAX: f64 = 20.0;
/// The sample from which [`U_ADAPTED_MAX`] and [`Z_RING_MAX`] apply: 2 s at 8 kHz.
const ADAPTED_FROM: f64 = 16_000.0;
/// The largest RMS of `z` over a window of [`WINDOW`] samples, over the median of those
/// windows, that is not a burst.
const Z_RING_MAX: f64 = 2.0;
/// Samples per window of the burst check: 0.25 s at 8 kHz.
const WINDOW: usize = 2000;

/// The first bar of the PCAC run: the median of the seven tones' suppressions at the end
/// of the 10 s run. The file keeps the 40 dB as its acceptance criterion, which it
/// does not meet (docs/pcac.md, "PCAC on the acoustic rig"). Measured in lockstep, the
/// seven tones (0.8 … 3 kHz) gave 13.4 10.5 13.2 20.7 38.2 22.8 18.8 dB when the file was
/// tuned, 15.8 9.6 9.5 20.4 31.3 22.7 19.0 at f9def90 and 12.6 6.9 11.5 18.6 32.2 22.5
/// 18.8 after the QP's start-point change (79e5fe3), whose solutions agree with the
/// previous ones to round-off: the loop, adapting while 2 % of its cycles saturate, carries
/// a round-off difference into the weaker tones by up to 3.6 dB, and the median (18.6 to
/// 19.0 dB) by 0.4 dB. So the median carries the bar, 3.6 dB under the lowest measured.
const PCAC_MEDIAN_DB: f64 = 15.0;
/// The second bar of the PCAC run: every tone suppressed by at least this much (a tone
/// left alone or amplified is a broken loop). The configurations of the search whose loop
/// went unstable or identified a wrong model in the start-up transient were recorded by
/// their worst tone only, −0.7 to 6 dB: this bar catches the worse of them, and a loop
/// that suppresses most tones poorly fails [`PCAC_MEDIAN_DB`]; a failure confined to one
/// or two tones between 5 and 15 dB passes both.
const PCAC_FLOOR_DB: f64 = 5.0;
/// The input bound of `scenarios/pcac/acoustic.toml`, V.
const PCAC_U_MAX: f64 = 20.0;
/// The largest mean of either input over the last second of the PCAC run, V: the move
/// penalty leaves the mean free, and with ±40 V bounds it wandered to ±25 V; with the
/// file's ±20 V it stays within about 0.6 V.
const PCAC_U_MEAN_MAX: f64 = 3.0;

/// The repository's `scenarios/` folder.
fn scenarios() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios")
}

/// `text` with its relative target-model file name made absolute (the copies are written
/// into a test folder, away from the target model).
fn absolute_target(text: &str, relative: &str) -> String {
    text.replace(
        &format!("target-model-file = \"{relative}\""),
        &format!(
            "target-model-file = \"{}\"",
            scenarios().join("rcac/acoustic-target.toml").display()
        ),
    )
}

/// What a run left: its verdict, `report.json`, and `signals.csv` (header, rows).
struct Run {
    ok: bool,
    report: Value,
    header: Vec<String>,
    rows: Vec<Vec<f64>>,
}

/// Runs the main job's scenario in lockstep, with `controller` (a file of `scenarios/`)
/// in place of the scenario's own when given.
fn run(test: &str, controller: Option<&str>) -> Run {
    let dir = TestDir::new(test);
    let scenario = dir.write("acoustic-rig.toml", &acoustic_rig_scenario(test));
    let folder = dir.path.join("run");
    let mut extra = vec!["--mode".to_string(), "lockstep".to_string()];
    if let Some(file) = controller {
        let text = std::fs::read_to_string(scenarios().join(file)).expect(file);
        let copy = dir.write(
            "controller.toml",
            &absolute_target(&text, "acoustic-target.toml"),
        );
        extra.push("--controller".to_string());
        extra.push(copy.display().to_string());
    }
    let args: Vec<&str> = extra.iter().map(String::as_str).collect();
    let mut launch = start_launch(&scenario, &folder, &args);
    let ok = launch.wait(Duration::from_secs(300)).success();
    let report = read_json(&folder.join("report.json"));
    assert_eq!(
        ok,
        report["verdict"]["ok"].as_bool().unwrap(),
        "{}",
        launch.output()
    );
    let (header, rows) = read_csv(&folder.join("signals.csv"));
    Run {
        ok,
        report,
        header,
        rows,
    }
}

/// Checks a run against its criterion: verdict OK, every tone suppressed by at least
/// `criterion_db`, and |u| ≤ [`U_ADAPTED_MAX`] from [`ADAPTED_FROM`] on.
fn check(name: &str, run: Run, criterion_db: f64) {
    let Run {
        ok,
        report,
        header,
        rows,
    } = run;
    let tones = report["tones"]["tones"].as_array().expect("tones");
    assert_eq!(tones.len(), 7, "{name}: seven tones");
    for t in tones {
        let db = t["suppression_db"].as_f64().unwrap_or(f64::NAN);
        assert!(
            db >= criterion_db,
            "{name}: tone {t} suppressed by {db} dB < {criterion_db}"
        );
    }
    assert!(ok, "{name}: verdict {}", report["verdict"]);
    let (seq, z0, u0, u1) = (
        column(&header, "seq"),
        column(&header, "z0"),
        column(&header, "u0"),
        column(&header, "u1"),
    );
    let adapted: Vec<&Vec<f64>> = rows.iter().filter(|r| r[seq] >= ADAPTED_FROM).collect();
    assert!(
        adapted.len() > 60_000,
        "{name}: {} adapted rows",
        adapted.len()
    );
    let u_max = adapted
        .iter()
        .map(|r| r[u0].abs().max(r[u1].abs()))
        .fold(0.0, f64::max);
    assert!(
        u_max <= U_ADAPTED_MAX,
        "{name}: |u| reached {u_max} V after 2 s (a burst)"
    );
    let mut rms: Vec<f64> = adapted
        .chunks_exact(WINDOW)
        .map(|w| (w.iter().map(|r| r[z0] * r[z0]).sum::<f64>() / WINDOW as f64).sqrt())
        .collect();
    let largest = rms.iter().copied().fold(0.0, f64::max);
    rms.sort_by(f64::total_cmp);
    let median = rms[rms.len() / 2];
    assert!(
        largest <= Z_RING_MAX * median,
        "{name}: z rang up to {largest:.3e} RMS over {WINDOW} samples, {:.2} times its median \
         {median:.3e} (a burst)",
        largest / median
    );
}

#[test]
fn the_main_jobs_gradient_rcac_meets_its_60_db_without_a_burst() {
    check("gradient", run("acoustic-gradient", None), 60.0);
}

#[test]
fn full_rls_rcac_meets_its_40_db_without_a_burst() {
    check(
        "full RLS",
        run("acoustic-rls", Some("rcac/acoustic-rls.toml")),
        40.0,
    );
}

#[test]
fn pcac_suppresses_every_tone_to_its_bar_with_every_qp_solved() {
    let text = std::fs::read_to_string(scenarios().join("pcac/acoustic.toml")).expect("file");
    for line in [
        "u-min = [-20.0, -20.0]\n",
        "u-max = [20.0, 20.0]\n",
        "min-suppression-db = 40.0\n",
    ] {
        assert!(
            text.contains(line),
            "pcac/acoustic.toml does not say {line:?}"
        );
    }
    let Run {
        ok,
        report,
        header,
        rows,
    } = run("acoustic-pcac", Some("pcac/acoustic.toml"));
    let tones = report["tones"]["tones"].as_array().expect("tones");
    assert_eq!(tones.len(), 7, "seven tones");
    let dbs: Vec<f64> = tones
        .iter()
        .map(|t| t["suppression_db"].as_f64().unwrap_or(f64::NAN))
        .collect();
    for (t, db) in tones.iter().zip(&dbs) {
        assert!(
            *db >= PCAC_FLOOR_DB,
            "tone {t} suppressed by {db} dB < {PCAC_FLOOR_DB}"
        );
    }
    let mut sorted = dbs.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    assert!(
        median >= PCAC_MEDIAN_DB,
        "median suppression {median} dB < {PCAC_MEDIAN_DB} (tones {dbs:?})"
    );
    // The verdict fails on the 40 dB criterion alone while a tone is below it: no miss, no
    // loss, no held input, no suspended update.
    let failures = report["verdict"]["failures"].as_array().expect("failures");
    let below_40 = dbs.iter().any(|db| *db < 40.0);
    assert_eq!(ok, !below_40, "verdict {}", report["verdict"]);
    for f in failures {
        let f = f.as_str().unwrap_or_default();
        assert!(
            f.starts_with("SUPPRESSION BELOW 40 dB"),
            "verdict failure {f}"
        );
    }
    every_qp_solved(&report);
    let (seq, u0, u1) = (
        column(&header, "seq"),
        column(&header, "u0"),
        column(&header, "u1"),
    );
    let last = rows.last().expect("rows")[seq];
    let mut sums = [0.0; 2];
    let mut count = 0.0;
    for r in &rows {
        for (i, c) in [u0, u1].into_iter().enumerate() {
            assert!(
                r[c].abs() <= PCAC_U_MAX,
                "u{i} = {} at seq {} beyond ±{PCAC_U_MAX} V",
                r[c],
                r[seq]
            );
            if r[seq] > last - 8000.0 {
                sums[i] += r[c];
            }
        }
        if r[seq] > last - 8000.0 {
            count += 1.0;
        }
    }
    for (i, sum) in sums.iter().enumerate() {
        let mean = sum / count;
        assert!(
            mean.abs() <= PCAC_U_MEAN_MAX,
            "u{i}'s mean over the last second is {mean} V (wandered)"
        );
    }
}

/// PCAC with the internal model of the seven tones (docs/pcac.md, "The internal model of
/// known tones") meets the issue's 40 dB on every tone without a burst, every QP solved,
/// re-planning every 4 samples with the Hessian kept between builds (one cycle in 32, 8
/// samples long) and the QP spread over the periods. Measured (lockstep): 44.1 to
/// 69.2 dB.
#[test]
fn pcac_with_the_internal_model_meets_its_40_db_with_every_qp_solved() {
    let r = run(
        "acoustic-pcac-im",
        Some("pcac/acoustic-internal-model.toml"),
    );
    every_qp_solved(&r.report);
    check("pcac internal model", r, 40.0);
}

/// A PCAC run's report shows no fallback and a solved QP at every one of its MPC steps
/// (but the last when it re-plans: that cycle may end with the run): at least one per `N`
/// samples of the 9 s of closed loop at 8 kHz (72 000 samples) when it re-plans every `N`
/// (`samples per solve`), `M` per `(M − 1) N + N_H` samples when one cycle in `M` builds
/// the Hessian in `N_H` samples.
fn every_qp_solved(report: &Value) {
    let counters: Vec<(String, u64)> =
        serde_json::from_value(report["controller_counters"].clone()).expect("counters");
    let counter = |name: &str| {
        counters
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| *v)
            .unwrap_or_else(|| panic!("no counter {name:?} in {counters:?}"))
    };
    assert_eq!(counter("fallbacks"), 0, "{counters:?}");
    let every = counter("samples per solve (replan-every)").max(1);
    // One cycle in `M` builds the Hessian in `N_H` samples, the others take `N`.
    let m_every = counter("solves per hessian (hessian-every)").max(1);
    let build_cycle = counter("samples per hessian cycle (hessian-cycle)").max(every);
    let samples_per_m = (m_every - 1) * every + build_cycle;
    assert!(
        counter("mpc steps") >= 72_000 * m_every / samples_per_m,
        "{counters:?}"
    );
    // A cycle begun in the run's last `N` samples ends with the run, unsolved.
    let (solved, steps) = (counter("qp solved"), counter("mpc steps"));
    assert!(
        solved <= steps && solved + u64::from(every > 1) >= steps,
        "{counters:?}"
    );
}
