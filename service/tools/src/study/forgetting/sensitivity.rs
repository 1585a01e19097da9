//! The settings §5.3 leaves open or states ambiguously, and the chapter's claims under
//! each alternative ([`crate::study::reproduction::sensitivity`]).
//!
//! §5.3 prints the plant (5.8), `θ_0 = 0`, `P_0 = 100 I`, `τ_n = 10`, `τ_d = 80`, `η = 1`,
//! `α = 0.001`, the regressor and the inputs; what it leaves open:
//!
//! | setting | study | alternatives | claims | why open |
//! | --- | --- | --- | --- | --- |
//! | reading of "converge" (noiseless) | `‖θ_k − θ‖/‖θ‖` stays < 1 % | stays < 5 %, 10 %; first < 1 %, 10 %; every component within a line width; the figure's 5–95 % band | 5.1 | no rule is stated; Figure 5.2 is read by eye ([`super::readings`]) |
//! | `α`, `τ_n`/`τ_d` (noiseless) | 0.001, 10/80 | 0.01; 5/50 | 5.1 | printed; §5.3.2 suggests `α = 0.01` for speed (contrast, not a reading) |
//! | `v_k ~ N(0, 0.05)` | variance 0.05 (σ = 0.224) | σ = 0.05 | 5.3–5.9 | `N(μ, ·)` is written with the variance or with σ |
//! | prior error's convergence window | 10 steps | 5, 20 | 5.9 | "converge" of `e_k` is read off Figure 5.5 |
//! | prior error's convergence bound | 2× its late RMS | 1.5×, 3× | 5.9 | the same |
//!
//! Each alternative reruns the Monte Carlos it needs on the same inputs
//! ([`super::montecarlo::SeededRun::all`], common random numbers) and judges each
//! claim by its own criterion ([`super::claims::claims`]); the claims it does not bear on
//! keep the study's runs.

use crate::study::forgetting::claims;
use crate::study::forgetting::experiment::{
    Case, ERROR_BOUND, ERROR_WINDOW, Method, RunSummary, Variant,
};
use crate::study::forgetting::montecarlo::{SeededRun, Summary, summarize};
use crate::study::forgetting::readings::Reading as ConvergeReading;
use crate::study::reproduction::Claim;
use crate::study::reproduction::sensitivity::{Alternative, Reading};

/// The noise's standard deviation when `N(0, 0.05)` gives σ rather than the variance.
pub const NOISE_STD_ALTERNATIVE: f64 = 0.05;

/// The claims the noise bears on (the noisy and nonpersistent cases).
const NOISY_CLAIMS: [&str; 7] = ["5.3", "5.4", "5.5", "5.6", "5.7", "5.8", "5.9"];

/// One alternative of the Monte Carlo settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Change {
    /// The noise's σ.
    NoiseStd(f64),
    /// The prior error's convergence window, steps.
    ErrorWindow(usize),
    /// The prior error's convergence bound, times its late RMS.
    ErrorBound(f64),
}

impl Change {
    /// Every alternative the study runs.
    pub const ALL: [Change; 5] = [
        Change::NoiseStd(NOISE_STD_ALTERNATIVE),
        Change::ErrorWindow(5),
        Change::ErrorWindow(20),
        Change::ErrorBound(1.5),
        Change::ErrorBound(3.0),
    ];

    /// The variant of the runs.
    pub fn variant(self) -> Variant {
        let mut v = Variant::STUDY;
        match self {
            Change::NoiseStd(s) => v.noise_std = Some(s),
            Change::ErrorWindow(w) => v.error_window = w,
            Change::ErrorBound(b) => v.error_bound = b,
        }
        v
    }

    /// The Monte Carlos it reruns, and the claims it bears on.
    fn runs(self) -> (&'static [(Case, Method)], &'static [&'static str]) {
        match self {
            Change::NoiseStd(_) => (
                &[
                    (Case::Noisy, Method::Ftvrf),
                    (Case::Noisy, Method::Crf),
                    (Case::Noisy, Method::Rmsvrf),
                    (Case::Nonpersistent, Method::Ftvrf),
                    (Case::Nonpersistent, Method::Crf),
                ],
                &NOISY_CLAIMS,
            ),
            Change::ErrorWindow(_) | Change::ErrorBound(_) => (
                &[(Case::Noisy, Method::Ftvrf), (Case::Noisy, Method::Rmsvrf)],
                &["5.9"],
            ),
        }
    }

    /// The row's setting, why it is open, the study's value and the alternative.
    fn labels(self) -> (&'static str, &'static str, String, String) {
        match self {
            Change::NoiseStd(s) => (
                "v_k ~ N(0, 0.05)",
                "N(μ, ·) is written with the variance or with σ",
                format!("variance 0.05 (σ {:.3})", Case::Noisy.noise_std()),
                format!("σ {s}"),
            ),
            Change::ErrorWindow(w) => (
                "prior error's convergence window",
                "\"converge\" of e_k is read off Figure 5.5",
                format!("{ERROR_WINDOW} steps"),
                format!("{w} steps"),
            ),
            Change::ErrorBound(b) => (
                "prior error's convergence bound",
                "\"converge\" of e_k is read off Figure 5.5",
                format!("{ERROR_BOUND}× late RMS"),
                format!("{b}× late RMS"),
            ),
        }
    }
}

/// The number behind claim `id` in `results` (empty when its runs are missing).
fn measured(id: &str, results: &[(Case, Method, Summary)]) -> String {
    let get = |case, method| {
        results
            .iter()
            .find(|(c, m, _)| *c == case && *m == method)
            .map(|r| r.2)
    };
    let steps = |v: f64| {
        if v.is_finite() {
            format!("{v:.0} steps")
        } else {
            "never".into()
        }
    };
    let pct = |f: f64| format!("{:.1} %", 100.0 * f);
    let text = match id {
        "5.3" => get(Case::Noisy, Method::Ftvrf)
            .map(|s| format!("median (10 %) {}", steps(s.settle_loose_median))),
        "5.4" => get(Case::Noisy, Method::Crf)
            .map(|s| format!("median (10 %) {}", steps(s.settle_loose_median))),
        "5.5" => get(Case::Noisy, Method::Rmsvrf)
            .map(|s| format!("{} forget early", pct(s.early_forget_fraction))),
        "5.6" => get(Case::Noisy, Method::Ftvrf)
            .map(|s| format!("{} forget early", pct(s.early_forget_fraction))),
        "5.7" => get(Case::Nonpersistent, Method::Ftvrf)
            .map(|s| format!("largest tr P {:.3e}", s.max_trace_max)),
        "5.8" => get(Case::Nonpersistent, Method::Crf)
            .map(|s| format!("median final tr P {:.3e}", s.final_trace_median)),
        "5.9" => match (
            get(Case::Noisy, Method::Ftvrf),
            get(Case::Noisy, Method::Rmsvrf),
        ) {
            (Some(f), Some(r)) => Some(format!(
                "{} vs {} ({:+} steps)",
                steps(f.error_settle_median),
                steps(r.error_settle_median),
                f.error_settle_median - r.error_settle_median
            )),
            _ => None,
        },
        _ => None,
    };
    text.unwrap_or_default()
}

/// The readings of `ids` in `claims`, with their numbers from `results`.
fn readings_of(
    ids: &[&str],
    claims: &[Claim],
    results: &[(Case, Method, Summary)],
) -> Vec<Reading> {
    ids.iter()
        .filter_map(|id| claims.iter().find(|c| c.id == *id))
        .map(|c| Reading {
            claim: c.id.clone(),
            verdict: c.verdict,
            measured: measured(&c.id, results),
        })
        .collect()
}

/// Claim 5.1's row under one reading of "converge" or of the settings.
fn converge_row(r: &ConvergeReading) -> Alternative {
    let (setting, why, ours) = if r.name.contains("not printed") {
        (
            "α, τ_n/τ_d (noiseless)",
            "printed; §5.3.2 suggests α = 0.01 for speed (contrast, not a reading)",
            "α 0.001, τ_n/τ_d 10/80",
        )
    } else if r.supported {
        (
            "reading of \"converge\" (noiseless)",
            "no rule is stated; Figure 5.2 is read by eye",
            "stays < 1 % (the study's)",
        )
    } else {
        (
            "reading of \"converge\" (noiseless)",
            "the figure draws the 5–95 % band, not all simulations",
            "stays < 1 % (the study's)",
        )
    };
    let slowest = if r.slowest.is_finite() {
        format!("{:.0} steps", r.slowest)
    } else {
        "never".into()
    };
    let run = r
        .slowest_run
        .map_or(String::new(), |i| format!(" (run {i})"));
    Alternative::new(
        setting,
        why,
        ours,
        r.name.clone(),
        vec![Reading::of(
            "5.1",
            r.within_20(),
            format!("slowest {slowest}{run}"),
        )],
    )
}

/// The seeded runs of the Monte Carlo alternatives ([`Change::ALL`], each the Monte Carlos
/// it reruns, in order), `runs` runs each from the master seed `seed`: the items of the
/// sensitivity's stage. Each reruns the study's inputs ([`SeededRun::all`], common random
/// numbers).
pub fn items(runs: usize, seed: u64) -> Vec<SeededRun> {
    let mut items = Vec::new();
    for change in Change::ALL {
        for &(case, method) in change.runs().0 {
            items.extend(SeededRun::all(
                case,
                method,
                change.variant(),
                case.steps(),
                runs,
                seed,
                false,
            ));
        }
    }
    items
}

/// The study's sensitivity rows: its own run (`results`, `study_claims`), claim 5.1 under
/// the `converge` readings, and the Monte Carlo alternatives ([`Change::ALL`]) from the
/// summaries `summaries` of [`items`]`(runs, …)` in its order.
pub fn record(
    runs: usize,
    summaries: &[RunSummary],
    results: &[(Case, Method, Summary)],
    study_claims: &[Claim],
    converge: &[ConvergeReading],
) -> Vec<Alternative> {
    // The study's own run: claim 5.1's is the study's reading of "converge" below.
    let mut rows = vec![Alternative::new(
        "the study's choices",
        "",
        "–",
        "–",
        readings_of(&NOISY_CLAIMS, study_claims, results),
    )];
    rows.extend(converge.iter().map(converge_row));
    let mut at = 0;
    for change in Change::ALL {
        let (which, ids) = change.runs();
        let mut alt: Vec<(Case, Method, Summary)> = Vec::new();
        for &(case, method) in which {
            let s = summarize(&summaries[at..at + runs]);
            at += runs;
            alt.push((case, method, s));
        }
        let verdicts = claims::claims(&alt, &[], "");
        let (setting, why, ours, value) = change.labels();
        rows.push(Alternative::new(
            setting,
            why,
            ours,
            value,
            readings_of(ids, &verdicts, &alt),
        ));
    }
    rows
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::forgetting::montecarlo::monte_carlo_variant;
    use crate::study::forgetting::plant::Plant;

    #[test]
    fn each_change_moves_only_its_setting() {
        assert_eq!(
            Change::NoiseStd(0.05).variant(),
            Variant {
                noise_std: Some(0.05),
                ..Variant::STUDY
            }
        );
        assert_eq!(Change::ErrorWindow(5).variant().error_window, 5);
        assert_eq!(Change::ErrorWindow(5).variant().noise_std, None);
        assert_eq!(Change::ErrorBound(3.0).variant().error_bound, 3.0);
        // The error rule bears only on claim 5.9; the noise on the noisy cases' claims.
        assert_eq!(Change::ErrorBound(3.0).runs().1, ["5.9"]);
        assert!(Change::NoiseStd(0.05).runs().1.contains(&"5.5"));
    }

    #[test]
    fn the_noise_alternative_reaches_the_runs_and_the_error_rule_the_prior_error() {
        let plant = Plant::chapter().unwrap();
        let study =
            monte_carlo_variant(&plant, Case::Noisy, Method::Ftvrf, Variant::STUDY, 40, 3).unwrap();
        let quiet = monte_carlo_variant(
            &plant,
            Case::Noisy,
            Method::Ftvrf,
            Change::NoiseStd(0.05).variant(),
            40,
            3,
        )
        .unwrap();
        // Less noise: the estimate settles (10 %) no later in the median.
        assert!(
            quiet.settle_loose_median <= study.settle_loose_median,
            "{} vs {}",
            quiet.settle_loose_median,
            study.settle_loose_median
        );
        let loose = monte_carlo_variant(
            &plant,
            Case::Noisy,
            Method::Ftvrf,
            Change::ErrorBound(3.0).variant(),
            40,
            3,
        )
        .unwrap();
        // A looser bound is met no later.
        assert!(loose.error_settle_median <= study.error_settle_median);
        // The parameter error does not depend on the error rule.
        assert_eq!(loose.settle_loose_median, study.settle_loose_median);
    }

    /// The stage's items are every alternative's Monte Carlos, in the order `record` reads
    /// them, on the study's inputs.
    #[test]
    fn the_items_are_each_alternative_s_runs_in_order() {
        let items = items(4, 9);
        let expected: usize = Change::ALL.iter().map(|c| c.runs().0.len() * 4).sum();
        assert_eq!(items.len(), expected);
        let first = &items[..4];
        assert!(first.iter().all(|r| r.variant == Change::ALL[0].variant()));
        assert_eq!(
            first.iter().map(|r| r.seed).collect::<Vec<_>>(),
            SeededRun::all(Case::Noisy, Method::Ftvrf, Variant::STUDY, 300, 4, 9, false)
                .iter()
                .map(|r| r.seed)
                .collect::<Vec<_>>()
        );
        let summaries = vec![
            RunSummary {
                settle: Some(3),
                settle_loose: Some(2),
                early_forget: false,
                max_trace: 1.0,
                final_trace: 1.0,
                resets: 0,
                error_settle: Some(4),
            };
            items.len()
        ];
        let rows = record(4, &summaries, &[], &[], &[]);
        assert_eq!(rows.len(), 1 + Change::ALL.len());
    }

    #[test]
    fn claim_5_1_rows_name_the_slowest_run_and_judge_it_against_20_steps() {
        let r = ConvergeReading {
            name: "stays < 5 %".into(),
            supported: true,
            median: 12.0,
            slowest: 25.0,
            slowest_run: Some(7),
        };
        let row = converge_row(&r);
        assert_eq!(row.value, "stays < 5 %");
        assert_eq!(
            row.readings[0].verdict,
            crate::study::reproduction::Verdict::Fail
        );
        assert_eq!(row.readings[0].measured, "slowest 25 steps (run 7)");
    }
}
