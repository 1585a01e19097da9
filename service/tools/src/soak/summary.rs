//! What the runs of a campaign add up to: per combination (controller, wait mode,
//! condition) how many runs met the acceptance criterion and what they lost, whether every
//! run that missed its criterion said so in its verdict, and, per controller and wait
//! mode, each load against idle in the same sitting.

use super::row::RunRow;

/// The median of `v` ([`crate::stats::median`]); `None` when no value is a number.
pub fn median(v: &[f64]) -> Option<f64> {
    Some(crate::stats::median(v)).filter(|m| !m.is_nan())
}

fn max(v: &[f64]) -> Option<f64> {
    v.iter().copied().reduce(f64::max)
}

fn min(v: &[f64]) -> Option<f64> {
    v.iter().copied().reduce(f64::min)
}

/// Whether every run below its criterion failed its verdict with the cause named.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CauseCheck {
    /// Every run below its criterion had a failed verdict with a failure line naming
    /// `SUPPRESSION`.
    Yes,
    /// At least one did not: its verdict was OK, or none of its failure lines named the
    /// suppression.
    No,
    /// No (readable) run was below its criterion.
    NoneBelow,
    /// The combination has no criterion.
    NoCriterion,
}

impl CauseCheck {
    /// `yes`, `no`, `none below`, `no criterion`.
    pub fn label(self) -> &'static str {
        match self {
            CauseCheck::Yes => "yes",
            CauseCheck::No => "no",
            CauseCheck::NoneBelow => "none below",
            CauseCheck::NoCriterion => "no criterion",
        }
    }
}

/// True when a run that missed its criterion failed its verdict and named the cause.
fn failed_naming_suppression(row: &RunRow) -> bool {
    match &row.outcome {
        Ok(f) => !f.verdict_ok && f.failures.iter().any(|l| l.contains("SUPPRESSION")),
        Err(_) => false,
    }
}

/// The check of [`CauseCheck`] over `rows`. Unreadable runs have no suppression to judge
/// and are left out (they are counted apart, [`CellSummary::unreadable`]).
pub fn cause_check(rows: &[&RunRow]) -> CauseCheck {
    let below: Vec<&&RunRow> = rows
        .iter()
        .filter(|r| r.outcome.is_ok() && r.met_criterion() == Some(false))
        .collect();
    if rows.iter().all(|r| r.criterion_db.is_none()) {
        CauseCheck::NoCriterion
    } else if below.is_empty() {
        CauseCheck::NoneBelow
    } else if below.iter().all(|r| failed_naming_suppression(r)) {
        CauseCheck::Yes
    } else {
        CauseCheck::No
    }
}

/// One combination (controller, wait mode, condition) over the campaign.
#[derive(Debug, Clone, PartialEq)]
pub struct CellSummary {
    /// The controller's label.
    pub controller: String,
    /// The wait mode.
    pub wait: String,
    /// The condition.
    pub condition: String,
    /// The acceptance criterion, dB.
    pub criterion_db: Option<f64>,
    /// Runs.
    pub runs: usize,
    /// Runs whose reports could not be read.
    pub unreadable: usize,
    /// Runs that met the criterion (`None` without one).
    pub met: Option<usize>,
    /// Median of the runs' smallest suppression, dB (runs with every tone measured).
    pub min_suppression_median_db: Option<f64>,
    /// The smallest of them, dB.
    pub min_suppression_min_db: Option<f64>,
    /// Runs with a tone not measured (or no tone at all).
    pub unmeasured: usize,
    /// Median lost share.
    pub lost_share_median: Option<f64>,
    /// Largest lost share.
    pub lost_share_max: Option<f64>,
    /// Largest held share.
    pub held_share_max: Option<f64>,
    /// Runs whose verdict was OK.
    pub verdicts_ok: usize,
    /// Whether every run below its criterion failed its verdict with the cause named.
    pub cause_named: CauseCheck,
}

/// The summary of `rows` (the runs of one combination).
pub fn summarize(controller: &str, wait: &str, condition: &str, rows: &[&RunRow]) -> CellSummary {
    let figures: Vec<_> = rows
        .iter()
        .filter_map(|r| r.outcome.as_ref().ok())
        .collect();
    let supp: Vec<f64> = figures
        .iter()
        .filter_map(|f| f.min_suppression_db)
        .collect();
    let lost: Vec<f64> = figures.iter().map(|f| f.lost_share).collect();
    let held: Vec<f64> = figures.iter().map(|f| f.held_share).collect();
    let criterion_db = rows.iter().find_map(|r| r.criterion_db);
    CellSummary {
        controller: controller.to_string(),
        wait: wait.to_string(),
        condition: condition.to_string(),
        criterion_db,
        runs: rows.len(),
        unreadable: rows.len() - figures.len(),
        met: criterion_db.map(|_| {
            rows.iter()
                .filter(|r| r.met_criterion() == Some(true))
                .count()
        }),
        min_suppression_median_db: median(&supp),
        min_suppression_min_db: min(&supp),
        unmeasured: figures.len() - supp.len(),
        lost_share_median: median(&lost),
        lost_share_max: max(&lost),
        held_share_max: max(&held),
        verdicts_ok: figures.iter().filter(|f| f.verdict_ok).count(),
        cause_named: cause_check(rows),
    }
}

/// Medians of one combination's runs, for [`LoadRatio`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Medians {
    /// Median response p99, ns.
    pub response_p99_ns: Option<f64>,
    /// Median wake-up p99, ns.
    pub wakeup_p99_ns: Option<f64>,
    /// Median lost share.
    pub lost_share: Option<f64>,
    /// Median run-queue wait of the RT thread, ns.
    pub run_queue_wait_ns: Option<f64>,
    /// Median of the smallest suppression, dB.
    pub min_suppression_db: Option<f64>,
}

/// The medians of `rows` (their readable runs).
pub fn medians(rows: &[&RunRow]) -> Medians {
    let figures: Vec<_> = rows
        .iter()
        .filter_map(|r| r.outcome.as_ref().ok())
        .collect();
    let of = |g: &dyn Fn(&super::row::RunFigures) -> Option<f64>| {
        median(&figures.iter().filter_map(|f| g(f)).collect::<Vec<_>>())
    };
    Medians {
        response_p99_ns: of(&|f| Some(f.response_p99_ns as f64)),
        wakeup_p99_ns: of(&|f| Some(f.wakeup_p99_ns as f64)),
        lost_share: of(&|f| Some(f.lost_share)),
        run_queue_wait_ns: of(&|f| f.run_queue_wait_ns.map(|n| n as f64)),
        min_suppression_db: of(&|f| f.min_suppression_db),
    }
}

/// One load against idle, for one controller and wait mode, in the same sitting.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadRatio {
    /// The controller's label.
    pub controller: String,
    /// The wait mode.
    pub wait: String,
    /// The loaded condition.
    pub condition: String,
    /// The idle runs' medians.
    pub idle: Medians,
    /// The loaded runs' medians.
    pub loaded: Medians,
}

/// `loaded / idle`; `None` when either is unknown or idle is 0.
pub fn ratio(loaded: Option<f64>, idle: Option<f64>) -> Option<f64> {
    match (loaded, idle) {
        (Some(l), Some(i)) if i > 0.0 => Some(l / i),
        _ => None,
    }
}

impl LoadRatio {
    /// Median response p99 loaded over idle.
    pub fn response_ratio(&self) -> Option<f64> {
        ratio(self.loaded.response_p99_ns, self.idle.response_p99_ns)
    }

    /// Median wake-up p99 loaded over idle.
    pub fn wakeup_ratio(&self) -> Option<f64> {
        ratio(self.loaded.wakeup_p99_ns, self.idle.wakeup_p99_ns)
    }
}

#[cfg(test)]
mod tests {
    use super::super::row::{RowError, RunRow, parse_reports, tests::report};
    use super::*;

    fn row(min_db: &str, ok: bool, failures: &[&str], criterion: Option<f64>) -> RunRow {
        RunRow {
            controller: "scenario".into(),
            wait: "sleep-poll".into(),
            condition: "hog-rt".into(),
            round: 1,
            seq: 1,
            folder: "scenario-sleep-poll-hog-rt-1".into(),
            criterion_db: criterion,
            outcome: parse_reports(&report(min_db, ok, failures), None),
            launch_error: None,
        }
    }

    fn unreadable() -> RunRow {
        RunRow {
            outcome: Err(RowError::Unreadable {
                path: "report.json".into(),
                message: String::new(),
            }),
            ..row("0", false, &[], Some(60.0))
        }
    }

    const BELOW: &str =
        "SUPPRESSION BELOW 60 dB (service.report.min-suppression-db): 900 Hz 41.0 dB";

    #[test]
    fn medians_of_odd_even_and_empty_lists() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), Some(2.5));
        assert_eq!(median(&[]), None);
    }

    #[test]
    fn the_criterion_counts_runs_at_or_above_it() {
        let rows = [
            row("60.0", true, &[], Some(60.0)),
            row("72.5", true, &[], Some(60.0)),
            row("41.0", false, &[BELOW], Some(60.0)),
            row(
                "null",
                false,
                &["SUPPRESSION BELOW 60 dB …: 900 Hz not measured"],
                Some(60.0),
            ),
            unreadable(),
        ];
        let refs: Vec<&RunRow> = rows.iter().collect();
        let s = summarize("scenario", "sleep-poll", "hog-rt", &refs);
        assert_eq!(s.runs, 5);
        assert_eq!(s.unreadable, 1);
        assert_eq!(s.met, Some(2));
        assert_eq!(s.unmeasured, 1);
        assert_eq!(s.min_suppression_median_db, Some(60.0));
        assert_eq!(s.min_suppression_min_db, Some(41.0));
        assert_eq!(s.verdicts_ok, 2);
        assert_eq!(s.lost_share_median, Some(36.0 / 72000.0));
        assert_eq!(s.held_share_max, Some(18.0 / 72000.0));
        assert_eq!(s.criterion_db, Some(60.0));
        assert_eq!(s.cause_named, CauseCheck::Yes);
    }

    #[test]
    fn a_run_below_its_criterion_that_passed_or_named_another_cause_fails_the_check() {
        let passed = [row("59.9", true, &[], Some(60.0))];
        let refs: Vec<&RunRow> = passed.iter().collect();
        assert_eq!(cause_check(&refs), CauseCheck::No);

        let other = [
            row("41.0", false, &[BELOW], Some(60.0)),
            row("30.0", false, &["SAMPLES LOST: 2.00 % …"], Some(60.0)),
        ];
        let refs: Vec<&RunRow> = other.iter().collect();
        assert_eq!(cause_check(&refs), CauseCheck::No);

        // The cause may be any failure line, not only the first.
        let second = [row(
            "41.0",
            false,
            &["SAMPLES LOST: 2.00 % …", BELOW],
            Some(60.0),
        )];
        let refs: Vec<&RunRow> = second.iter().collect();
        assert_eq!(cause_check(&refs), CauseCheck::Yes);
    }

    #[test]
    fn the_check_without_runs_below_or_without_a_criterion() {
        let fine = [row("65.0", true, &[], Some(60.0)), unreadable()];
        let refs: Vec<&RunRow> = fine.iter().collect();
        assert_eq!(cause_check(&refs), CauseCheck::NoneBelow);

        let none = [row("10.0", true, &[], None)];
        let refs: Vec<&RunRow> = none.iter().collect();
        assert_eq!(cause_check(&refs), CauseCheck::NoCriterion);
        let s = summarize("scenario", "sleep-poll", "idle", &refs);
        assert_eq!(s.met, None);
    }

    #[test]
    fn loaded_over_idle() {
        let idle = [row("65.0", true, &[], Some(60.0))];
        let loaded = [
            row("65.0", true, &[], Some(60.0)),
            row("65.0", true, &[], Some(60.0)),
        ];
        let r = LoadRatio {
            controller: "scenario".into(),
            wait: "sleep-poll".into(),
            condition: "hog-rt".into(),
            idle: medians(&idle.iter().collect::<Vec<_>>()),
            loaded: Medians {
                response_p99_ns: Some(84000.0),
                ..medians(&loaded.iter().collect::<Vec<_>>())
            },
        };
        assert_eq!(r.response_ratio(), Some(2.0));
        assert_eq!(r.wakeup_ratio(), Some(1.0));
        assert_eq!(ratio(Some(1.0), Some(0.0)), None);
        assert_eq!(ratio(None, Some(1.0)), None);
    }
}
