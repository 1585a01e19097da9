//! The response-time phase: one controller runs with compute-first and with answer-first in
//! ABBA rounds of fresh service children of the built `latency-bench` binary; each round's
//! service says it ran the timing asked for and answered samples, the rows are the sum of
//! the rounds' own histograms, and the answer-first row carries its ratio to compute-first.
//! No timing is asserted.

mod common;
use common::test_dir;
use latency_bench::cli::{Cli, Settings};
use latency_bench::configs::timing_cases;
use latency_bench::timing_phase::{TIMINGS, case_rows, run_case};
use serde_json::Value;
use std::path::PathBuf;

const BENCH: &str = env!("CARGO_BIN_EXE_latency-bench");

#[test]
fn a_controller_runs_with_both_timings_and_each_service_reports_its_own() {
    let dir = test_dir("timing");
    let cli =
        <Cli as clap::Parser>::parse_from(["latency-bench", "--seconds", "0.4", "--rounds", "2"]);
    let mut s = Settings::from(&cli.opts);
    s.child_exe = Some(PathBuf::from(BENCH));
    let case = timing_cases()
        .into_iter()
        .find(|c| c.slug.starts_with("rcac-gradient"))
        .expect("the RCAC gradient case");
    let c = run_case(&s, &dir, &latency_bench::rig_base(), 0, &case);
    for (r, timing) in c.runs.iter().zip(TIMINGS) {
        assert_eq!(r.timing, timing);
        assert!(r.error.is_none(), "{}: {:?}", timing.name(), r.error);
        assert_eq!(r.rounds.len(), 2, "{}", timing.name());
        for (f, report) in r.rounds.iter().zip(&r.reports) {
            assert_eq!(report["timing"], timing.name(), "{report}");
            assert_eq!(report["stop_reason"], "plant-ended", "{report}");
            assert!(f.response.count > 0 && f.compute.count > 0, "{f:?}");
            assert!(f.samples > 0, "{f:?}");
            let steps = report
                .pointer("/stats/controller_steps")
                .and_then(Value::as_u64);
            assert!(steps > Some(0), "the controller never ran: {report}");
        }
        let counted: u64 = r.rounds.iter().map(|f| f.response.count).sum();
        assert_eq!(r.response.len(), counted, "{}", timing.name());
        // Each round has its own run folder, with the service's interval logs.
        for round in 0..2 {
            let folder = dir.join(timing.name()).join(format!("round-{round}"));
            assert!(folder.join("response.hlog").exists(), "{folder:?}");
        }
    }
    let (rows, details, block) = case_rows(&c, &dir);
    assert_eq!(rows.len(), 2);
    assert_eq!(
        rows[0].label,
        "response: rcac gradient exp nc 50 — compute-first"
    );
    assert_eq!(
        rows[1].label,
        "response: rcac gradient exp nc 50 — answer-first"
    );
    for m in &rows {
        assert!(m.error.is_none(), "{m:?}");
        assert!(m.count > Some(0), "{m:?}");
        assert!(m.note.contains("compute p50"), "{}", m.note);
    }
    assert!(
        rows[1].note.starts_with("÷ compute-first: p50 "),
        "{}",
        rows[1].note
    );
    assert!(block["answer_first_over_compute_first"]["p50"].is_number());
    assert_eq!(details.len(), 1);
    let _ = std::fs::remove_dir_all(&dir);
}
