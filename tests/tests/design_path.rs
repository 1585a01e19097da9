//! The identification path of issue 4 end to end, on data logged by the real processes:
//! an excitation run of the acoustic rig (service + plant-proxy over iceoryx2, lockstep)
//! → `rig-design identify` (H1 frequency response, coherence, pure delays, dereverberated
//! transfer function per channel) → a target-model file that RCAC's configuration reads.

use control::target::{TargetForm, TargetModel};
use rig_tests::*;
use service::config::TargetModelFile;
use std::path::{Path, PathBuf};

/// The `[rig]` and `[plant…]` tables of a scenario text (its service, controller, log and
/// proxy tables are dropped so a test can give its own).
fn rig_and_plant(text: &str) -> String {
    let mut out = String::new();
    let mut keep = true;
    for line in text.lines() {
        let t = line.trim();
        if t.starts_with('[') {
            let name = t.trim_start_matches('[').trim_end_matches(']');
            keep = name == "rig" || name == "plant" || name.starts_with("plant.");
        }
        if keep {
            out += line;
            out.push('\n');
        }
    }
    out
}

/// Runs the acoustic rig for `steps` samples in lockstep with the excitation source of
/// `scenarios/identify/excitation.toml`; returns the folder and the log path.
fn excitation_run(test: &str, steps: u64) -> (TestDir, PathBuf, PathBuf) {
    let dir = TestDir::new(test);
    let rig = rig_name(test);
    let excitation = scenario_text("identify/excitation.toml");
    let controller = excitation
        .split("[log]")
        .next()
        .expect("excitation file has a [controller] table");
    let text = with_rig_name(&rig_and_plant(&scenario_text("acoustic-rig.toml")), &rig)
        + &test_service_tables("", controller);
    let scenario = dir.write("scenario.toml", &text);
    let run_folder = run_lockstep_pair(&dir, &scenario, steps, &[]);
    (dir, scenario, run_folder.join("signals.csv"))
}

/// Runs `rig-design <args…> --out <out>`, asserts that it succeeded, and reads back the
/// target model it wrote there; returns that and what it printed.
fn rig_design_target(args: &[&str], out: &Path) -> (TargetModel, String) {
    let (ok, text) = rig_design(&[args, &["--out", out.to_str().unwrap()]].concat());
    assert!(ok, "rig-design {} failed:\n{text}", args[0]);
    let tm = TargetModel::load(&out.join("target-model.toml"))
        .unwrap_or_else(|e| panic!("the target model of rig-design {} reads back: {e}", args[0]));
    (tm, text)
}

#[test]
fn an_excitation_log_of_the_acoustic_rig_gives_a_target_model_with_its_delays() {
    let (dir, scenario, log) = excitation_run("design-path", 40_000);
    let out = dir.path.join("design");
    let (tm, text) = rig_design_target(
        &[
            "identify",
            log.to_str().unwrap(),
            "--inputs",
            "u0,u1",
            "--outputs",
            "y0",
            "--scenario",
            scenario.to_str().unwrap(),
            "--compare",
            "--method",
            "average",
            "--delta-hz",
            "500",
            "--order",
            "6",
            "--beta",
            "0.8",
        ],
        &out,
    );
    // The delays of the rig (9 and 16 samples, §3.5) are found from the data.
    assert!(text.contains("delays found [9, 16]"), "{text}");
    // The H1 estimate agrees with the model: median relative error on coherent bins < 3 %.
    let medians: Vec<f64> = text
        .lines()
        .filter_map(|l| l.split("median ").nth(1))
        .filter_map(|r| r.split(" %").next()?.parse().ok())
        .collect();
    assert_eq!(medians.len(), 2, "{text}");
    assert!(medians.iter().all(|m| *m < 3.0), "{medians:?}\n{text}");
    // The target model is a file RCAC's configuration reads: two channels with the delays
    // added back, β as asked, stable denominators, the response finite.
    assert_eq!((tm.outputs, tm.inputs, tm.beta), (1, 2, 0.8));
    assert_eq!(tm.sample_period, 1.25e-4);
    let TargetForm::TransferFunction(ch) = &tm.form else {
        panic!("a transfer-function target model")
    };
    let delays: Vec<usize> = ch.iter().map(|c| c.delay).collect();
    assert_eq!(delays, vec![9, 16]);
    for c in ch {
        assert_eq!(c.den.len(), 7, "order 6");
        let roots = plant_proxy::lti::eigenvalues(&companion(&c.den)).unwrap();
        assert!(roots.iter().all(|r| r.norm() < 1.0), "stable: {roots:?}");
    }
    let h = tm.markov(40);
    for (j, d) in [(0, 9), (1, 16)] {
        for (k, hk) in h.iter().enumerate().take(d + 1) {
            assert_eq!(
                hk[(0, j)],
                0.0,
                "no response before the delay, input {j}, k = {k}"
            );
        }
    }
    for name in [
        "frf.csv",
        "coherence.png",
        "frf-0.png",
        "dtf-0.png",
        "dtf-1.png",
    ] {
        assert!(out.join(name).exists(), "{name} written");
    }

    // The target model against the plant at the rig's seven tones: one row per tone and
    // channel, finite errors.
    let tones = "800,900,1060,1300,1600,2200,3000";
    let tm_path = out.join("target-model.toml");
    let (ok, text) = rig_design(&[
        "compare",
        tm_path.to_str().unwrap(),
        scenario.to_str().unwrap(),
        "--hz",
        tones,
    ]);
    assert!(ok, "{text}");
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| {
            l.split_whitespace()
                .filter_map(|v| v.parse().ok())
                .collect()
        })
        .collect();
    assert_eq!(rows.len(), 14, "{text}");
    assert!(
        rows.iter()
            .all(|r| r.len() == 4 && r.iter().all(|v| v.is_finite())),
        "{text}"
    );

    // The FIR target (3.39) from the measured impulse response: zeros up to the delays,
    // then the model's Markov parameters to within 5 % (relative 2-norm over 200).
    let fir_out = dir.path.join("fir");
    let frf_csv = out.join("frf.csv");
    let (fir, _) = rig_design_target(
        &[
            "dtf",
            frf_csv.to_str().unwrap(),
            "--method",
            "fir",
            "--count",
            "200",
        ],
        &fir_out,
    );
    let TargetForm::Markov(h_est) = &fir.form else {
        panic!("a Markov target model")
    };
    let sc = plant_proxy::scenario::load(&scenario).unwrap();
    let model = rig_tools::design::model::DiscreteModel::from_scenario(
        &sc,
        rig_tools::design::model::OutputSet::Y,
    )
    .unwrap();
    let h_true = model.markov(200);
    // The committed target model of the main job, made by the same path from a longer run
    // (scenarios/rcac/acoustic-target.toml): this shorter run must agree with it as well.
    let committed = TargetModel::parse(
        &scenario_text("rcac/acoustic-target.toml"),
        "acoustic-target.toml",
    )
    .expect("the committed acoustic target model reads");
    let h_committed = committed.markov(200);
    for (what, h_ref) in [("model", &h_true), ("committed target", &h_committed)] {
        for j in 0..2 {
            let (mut err, mut norm) = (0.0, 0.0);
            for (e, t) in h_est.iter().zip(h_ref) {
                err += (e[(0, j)] - t[(0, j)]).powi(2);
                norm += t[(0, j)].powi(2);
            }
            let rel = (err / norm).sqrt();
            eprintln!("input {j}: Markov parameters within {rel:.4} of the {what}");
            assert!(
                rel < 0.05,
                "input {j}: relative error of the Markov parameters against the {what}: {rel}"
            );
        }
    }
    for j in 0..2 {
        let d = [9, 16][j];
        assert!(h_est[..=d].iter().all(|h| h[(0, j)] == 0.0));
        assert!(h_committed[..=d].iter().all(|h| h[(0, j)] == 0.0));
    }

    // Bad input: a log cut to fewer samples than one segment, and a missing channel.
    let short = dir.write(
        "short.csv",
        &std::fs::read_to_string(&log)
            .unwrap()
            .lines()
            .take(500)
            .collect::<Vec<_>>()
            .join("\n"),
    );
    let frf = |log: &Path, inputs: &str| {
        let args = [
            "frf",
            log.to_str().unwrap(),
            "--inputs",
            inputs,
            "--outputs",
            "y0",
        ];
        let more = ["--sample-period", "1.25e-4", "--out", out.to_str().unwrap()];
        rig_design(&[&args[..], &more[..]].concat())
    };
    let (ok, text) = frf(&short, "u0,u1");
    assert!(
        !ok && text.contains("short.csv") && text.contains("samples"),
        "{text}"
    );
    let (ok, text) = frf(&log, "u0,u2");
    assert!(!ok && text.contains("u2"), "{text}");
}

/// The companion matrix of a monic polynomial (descending powers): its eigenvalues are the
/// roots.
fn companion(den: &[f64]) -> nalgebra::DMatrix<f64> {
    let n = den.len() - 1;
    nalgebra::DMatrix::from_fn(n, n, |i, j| {
        if i == 0 {
            -den[j + 1]
        } else if i == j + 1 {
            1.0
        } else {
            0.0
        }
    })
}
