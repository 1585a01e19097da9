//! `study mrac` on a small grid (3 × 3, Example 1, the step): the files it writes, the
//! summary's values, and its single runs against a loop written here directly on the
//! kernels of `control::mrac` (the loop of `service/control/tests/mrac.rs`).

use std::f64::consts::PI;
use std::path::PathBuf;

use control::mrac::{Appc, AppcParams, RcMrac, RcMracParams};
use control::{Controller, Dimensions, StepInput};
use rig_tools::study::mrac::setup::{CommandKind, Example, Method};
use rig_tools::study::mrac::summary::Verdict;
use rig_tools::study::mrac::{self, Options};
use rig_tools::study::shard::Runs;

/// ‖e‖ (4.85) of `c` on Example 1's plant at `ρ = 0.5`, `ν = π/4` with the unit step:
/// `y_{k+1} = u_k − 0.5 u_{k−1} + 2ρ cos ν y_k − ρ² y_{k−1}`, samples `k = 0 … 200`.
fn direct_e_norm(c: &mut dyn Controller) -> f64 {
    let (rho, nu) = (0.5_f64, PI / 4.0);
    let (a1, a2) = (-2.0 * rho * nu.cos(), rho * rho);
    let (mut y, mut y1, mut u1) = (0.0_f64, 0.0_f64, 0.0_f64);
    let mut sum = 0.0;
    let mut internals = [0.0; control::MAX_INTERNALS];
    let ie = c
        .internal_names()
        .iter()
        .position(|n| n.ends_with("_e"))
        .expect("e");
    for k in 0..=200u64 {
        let mut u = [0.0];
        // A step command, nothing lost, the input applied as computed (the defaults).
        let input = StepInput {
            seq: k,
            y: &[y],
            z: &[y],
            r: &[1.0],
            ..StepInput::default()
        };
        c.step(&input, &mut u);
        c.internals(&mut internals);
        if k >= 101 {
            sum += internals[ie] * internals[ie];
        }
        let next = u[0] - 0.5 * u1 - a1 * y - a2 * y1;
        (y1, y, u1) = (y, next, u[0]);
    }
    sum.sqrt()
}

fn out_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("mrac-study-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn a_small_study_writes_its_files_and_repeats_the_kernel_tests_single_runs() {
    let out = out_dir("small");
    let options = Options::parse("1", "step", 3).expect("valid");
    let report = mrac::run(
        &Runs::whole(),
        &options,
        &out,
        "study mrac --example 1 --command step --grid 3",
    )
    .expect("runs");

    for f in [
        "grid.csv",
        "summary.md",
        "map-ex1-step-appc.png",
        "map-ex1-step-rc-mrac.png",
        "single-ex1-step-appc.png",
        "single-ex1-step-rc-mrac.png",
        "single-ex1-step-appc.csv",
        "single-ex1-step-rc-mrac.csv",
    ] {
        let meta = std::fs::metadata(out.join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
        assert!(meta.len() > 100, "{f} is nearly empty");
    }
    let grid = std::fs::read_to_string(out.join("grid.csv")).expect("grid.csv");
    assert_eq!(
        grid.lines().count(),
        1 + 2 * 9,
        "header and 9 points per method"
    );
    assert!(grid.starts_with("example,command,method,rho,nu,e_norm,unstable"));
    assert!(grid.contains("\n1,step,rc-mrac,0.500000,1.570796,"));

    // The summary: two methods, finite statistics, RC-MRAC ahead, nothing unstable.
    assert_eq!(report.stats.len(), 2);
    for s in &report.stats {
        assert!(s.median.is_finite() && s.worst.is_finite(), "{s:?}");
        assert_eq!((s.unstable, s.points), (0, 9));
    }
    let median = |m| {
        report
            .stats
            .iter()
            .find(|s| s.method == m)
            .expect("method")
            .median
    };
    assert!(median(Method::RcMrac) < median(Method::Appc) - 2.0);
    // Only the claims whose runs were all made are checked: RC-MRAC's stability (5).
    for c in &report.claims {
        let want = if c.number == 5 {
            Verdict::Pass
        } else {
            Verdict::NotChecked
        };
        assert_eq!(c.verdict, want, "claim {}", c.number);
    }
    let summary = std::fs::read_to_string(out.join("summary.md")).expect("summary.md");
    assert_eq!(summary, report.markdown);
    // The sensitivity table: only claim 5 is read (the others' runs were not made), under
    // every alternative that bears on it, the study's own row first; the alternatives
    // bearing on other claims only have no reading.
    let sens = std::fs::read_to_string(out.join("sensitivity.csv")).expect("sensitivity.csv");
    let lines: Vec<&str> = sens.lines().collect();
    assert_eq!(lines[0], "setting,ours,value,claim,verdict,measured");
    assert!(
        lines[1].starts_with("\"the study's choices\",\"–\",\"–\",\"4.5\",PASS,"),
        "{}",
        lines[1]
    );
    assert!(
        lines
            .iter()
            .skip(1)
            .all(|l| l.contains(",\"4.5\",") || l.ends_with(",,,")),
        "{sens}"
    );
    assert!(
        lines.iter().filter(|l| l.contains(",\"4.5\",")).count() > 5,
        "{sens}"
    );
    let claims = rig_tools::study::reproduction::read(&out).expect("claims.json");
    assert_eq!(
        claims.sensitivity.len(),
        mrac::sensitivity::alternatives(3).len()
    );
    assert!(summary.contains("Sensitivity (`sensitivity.csv`)"));

    // The single runs equal the loop written here on the kernels (same arithmetic), and
    // RC-MRAC's is the value the kernel test measures (1.2·10⁻⁶).
    let single = |m| {
        report
            .singles
            .iter()
            .find(|s| s.example == Example::One && s.command == CommandKind::Step && s.method == m)
            .expect("single run")
            .e_norm
    };
    let siso = Dimensions::new(1, 1, 1, 1);
    let num = vec![0.0, 1.0, -0.5];
    let d_m = vec![1.0, 0.0, 0.25];
    let mut rc = RcMrac::new(
        &RcMracParams::new(
            2,
            1,
            1.0,
            vec![1.0],
            1,
            vec![1.0, 0.5],
            d_m.clone(),
            num.clone(),
        ),
        siso,
    )
    .expect("valid");
    let mut appc =
        Appc::new(&AppcParams::new(2, d_m, num, vec![1.0, 0.0, -0.25]), siso).expect("valid");
    let rc_direct = direct_e_norm(&mut rc);
    let appc_direct = direct_e_norm(&mut appc);
    let rel = |a: f64, b: f64| (a - b).abs() / b.abs();
    assert!(
        rel(single(Method::RcMrac), rc_direct) < 1e-9,
        "{} vs {rc_direct}",
        single(Method::RcMrac)
    );
    assert!(
        rel(single(Method::Appc), appc_direct) < 1e-9,
        "{} vs {appc_direct}",
        single(Method::Appc)
    );
    assert_eq!(format!("{:.1e}", single(Method::RcMrac)), "1.2e-6");

    // The single run's CSV carries the error whose (4.85) is the reported value.
    let csv = std::fs::read_to_string(out.join("single-ex1-step-rc-mrac.csv")).expect("csv");
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("k,r,y,y_m,e,u,nc1,nc2,dc1,dc2,rc0,rc1"));
    let e: Vec<f64> = lines
        .map(|l| l.split(',').nth(4).expect("e").parse().expect("number"))
        .collect();
    assert_eq!(e.len(), 201);
    let from_csv = e[101..].iter().map(|v| v * v).sum::<f64>().sqrt();
    assert!(rel(from_csv, single(Method::RcMrac)) < 1e-8);

    // The results file.
    let results = out.join("results.md");
    mrac::write_results(&results, &report).expect("written");
    let text = std::fs::read_to_string(&results).expect("results");
    assert!(text.starts_with("# Chapter 4 study"));
    assert!(text.contains("Written by `study mrac`"));
    assert!(text.ends_with(&report.markdown));
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn the_outward_reading_of_example_two_writes_its_grid_and_maps_and_can_be_turned_off() {
    let out = out_dir("outward");
    // A 4 × 4 outward grid to ρ = 2 and the 2 × 2 patch around the zero 1.5.
    let options = Options::parse("2", "step", 2)
        .and_then(|o| o.with_outward(2.0, 4))
        .expect("valid");
    let report = mrac::run(&Runs::whole(), &options, &out, "outward").expect("runs");
    let csv = std::fs::read_to_string(out.join("grid-outward.csv")).expect("grid-outward.csv");
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some(
            "region,command,method,rho,nu,open_loop_unstable,e_norm,unstable,diverged_at,peak_y,theta_settle"
        )
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    // Two methods on 16 outward points and 4 patch points.
    assert_eq!(rows.len(), 2 * (16 + 4));
    assert_eq!(rows.iter().filter(|r| r[0] == "outward").count(), 32);
    // The outermost ring is at ρ = 2 and open-loop unstable; the patch surrounds 1.5.
    assert!(rows.iter().any(|r| r[3] == "2.000000" && r[5] == "1"));
    assert!(
        rows.iter()
            .filter(|r| r[0] == "near-zero")
            .all(|r| r[3] == "1.375000" || r[3] == "1.625000")
    );
    for f in [
        "map-outward-ex2-step-appc.png",
        "map-outward-ex2-step-rc-mrac.png",
    ] {
        let meta = std::fs::metadata(out.join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
        assert!(meta.len() > 100, "{f} is nearly empty");
    }
    assert!(
        report
            .markdown
            .contains("Outward reading of Figures 4.8a–4.10a")
    );
    // Claim 4 needs every command: not checked on the step alone.
    let c4 = report
        .claims
        .iter()
        .find(|c| c.number == 4)
        .expect("claim 4");
    assert_eq!(c4.verdict, Verdict::NotChecked);
    let _ = std::fs::remove_dir_all(&out);

    // Turned off, no outward file is written.
    let off = out_dir("outward-off");
    let options = Options::parse("2", "step", 2)
        .and_then(|o| o.with_outward(2.0, 0))
        .expect("valid");
    mrac::run(&Runs::whole(), &options, &off, "off").expect("runs");
    assert!(!off.join("grid-outward.csv").exists());
    let _ = std::fs::remove_dir_all(&off);
    assert!(
        Options::parse("2", "step", 2)
            .and_then(|o| o.with_outward(0.9, 4))
            .unwrap_err()
            .to_string()
            .contains("--outward-rho")
    );
}

#[test]
fn example_three_without_the_step_is_refused_naming_the_arguments() {
    let options = Options::parse("3", "two,four", 3).expect("parses");
    let err = mrac::run(&Runs::whole(), &options, &out_dir("empty"), "")
        .unwrap_err()
        .to_string();
    assert!(err.contains("--example/--command"), "{err}");
    assert!(
        Options::parse("1", "step", 0)
            .unwrap_err()
            .to_string()
            .contains("--grid")
    );
    assert!(
        Options::parse("1,5", "all", 3)
            .unwrap_err()
            .to_string()
            .contains("--example")
    );
}
