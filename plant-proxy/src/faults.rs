//! Faults the plant injects on purpose (`[proxy.faults]`), by sample index.
//!
//! - **Measurement faults** (`nan-at`, `inf-at`, `neg-inf-at`, `out-of-range-at`): the first
//!   measurement channel of those samples is NaN, ±Inf or `out-of-range-value`, for testing
//!   the service's input validation.
//! - **Stalls** (`stalls = [{ at = 4000, periods = 4 }, …]`, lockstep only): the samples
//!   `at, at + 1, …, at + periods − 1` carry
//!   [`INJECTED_STALL`](ipc_types::measurement_flags::INJECTED_STALL). The service takes such
//!   a sample in without answering it and acknowledges it
//!   ([`STALL_ACK`](ipc_types::actuation_status::STALL_ACK)); the plant decides its input as
//!   at a deadline (the input sent ahead for it, else its late policy). A deterministic
//!   stand-in for a service that stalled for `periods` periods, repeatable bit for bit; in
//!   real time a stall is a real one (SIGSTOP, a CPU hog), so they are refused there.
//! - **Lost samples** (`lost = [{ at = 4000, periods = 8 }, …]`, lockstep only): the samples
//!   `at … at + periods − 1` are measured and the plant advances over them, but they are
//!   never published, as samples that overflowed the service's queue; the plant decides
//!   their inputs as at a deadline (the input sent ahead for the first, which the plant
//!   waits for when the service sends ahead, then its late policy: the plan). The service
//!   sees a gap in the sequence; a lockstep sample's stamp explains any burst up to the
//!   length of a fault list. A deterministic stand-in for a loop that lost samples,
//!   repeatable bit for bit, for testing the gap rules and the verdict.
//!
//! Every list holds at most [`MAX_FAULT_SAMPLES`] entries; stalls and losses are each sorted
//! by `at`, do not overlap and last at least one period.

use serde::{Deserialize, Serialize};

/// The most entries of one fault list (`nan-at`, …, `stalls`): each is checked per sample.
pub const MAX_FAULT_SAMPLES: usize = 65_536;

/// An injected stall of the service: samples `at .. at + periods` (lockstep only).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub struct Stall {
    /// The first stalled sample.
    pub at: u64,
    /// How many samples in a row are stalled (at least 1).
    pub periods: u64,
}

impl Stall {
    /// One past the last stalled sample; `None` when `at + periods` overflows.
    pub const fn end(&self) -> Option<u64> {
        self.at.checked_add(self.periods)
    }
}

/// The `[proxy.faults]` table.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub struct Faults {
    /// Samples whose first measurement channel is NaN.
    #[serde(default)]
    pub nan_at: Vec<u64>,
    /// Samples whose first measurement channel is +Inf.
    #[serde(default)]
    pub inf_at: Vec<u64>,
    /// Samples whose first measurement channel is -Inf.
    #[serde(default)]
    pub neg_inf_at: Vec<u64>,
    /// Samples whose first measurement channel is `out-of-range-value`.
    #[serde(default)]
    pub out_of_range_at: Vec<u64>,
    /// The value used for `out-of-range-at`.
    #[serde(default = "default_oor")]
    pub out_of_range_value: f64,
    /// Injected stalls of the service, sorted and not overlapping (lockstep only).
    #[serde(default)]
    pub stalls: Vec<Stall>,
    /// Samples never published, sorted and not overlapping (lockstep only; the same
    /// `{ at, periods }` spans as the stalls).
    #[serde(default)]
    pub lost: Vec<Stall>,
}

fn default_oor() -> f64 {
    1e6
}

/// A refused `[proxy.faults]` table: the field (a dotted path below `proxy.faults`) and
/// what is wrong.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FaultsError {
    /// The field, e.g. `proxy.faults.stalls[1].at`.
    pub field: String,
    /// What is wrong with it.
    pub problem: String,
}

impl Faults {
    /// Number of measurement faults configured (stalls not included).
    pub fn total(&self) -> usize {
        self.nan_at.len() + self.inf_at.len() + self.neg_inf_at.len() + self.out_of_range_at.len()
    }

    /// The injected measurement value at sample `k`, if any.
    pub fn at(&self, k: u64) -> Option<f64> {
        if self.nan_at.contains(&k) {
            Some(f64::NAN)
        } else if self.inf_at.contains(&k) {
            Some(f64::INFINITY)
        } else if self.neg_inf_at.contains(&k) {
            Some(f64::NEG_INFINITY)
        } else if self.out_of_range_at.contains(&k) {
            Some(self.out_of_range_value)
        } else {
            None
        }
    }

    /// True when sample `k` is inside an injected stall (a binary search of the validated,
    /// sorted list; no allocation).
    pub fn stalled(&self, k: u64) -> bool {
        covers(&self.stalls, k)
    }

    /// True when sample `k` is one of the injected lost samples (a binary search, no
    /// allocation).
    pub fn lost(&self, k: u64) -> bool {
        covers(&self.lost, k)
    }

    /// Checks the bounds: at most [`MAX_FAULT_SAMPLES`] entries per list; stalls of at least
    /// one period, sorted by `at`, not overlapping, with `at + periods` representable.
    pub fn validate(&self) -> Result<(), FaultsError> {
        let err = |field: String, problem: String| Err(FaultsError { field, problem });
        let lists = [
            ("nan-at", self.nan_at.len()),
            ("inf-at", self.inf_at.len()),
            ("neg-inf-at", self.neg_inf_at.len()),
            ("out-of-range-at", self.out_of_range_at.len()),
            ("stalls", self.stalls.len()),
            ("lost", self.lost.len()),
        ];
        for (name, n) in lists {
            if n > MAX_FAULT_SAMPLES {
                return err(
                    format!("proxy.faults.{name}"),
                    format!("{n} entries, at most {MAX_FAULT_SAMPLES}"),
                );
            }
        }
        validate_spans(&self.stalls, "stalls")?;
        validate_spans(&self.lost, "lost")
    }
}

/// True when one of the sorted, validated `spans` covers sample `k`.
fn covers(spans: &[Stall], k: u64) -> bool {
    let i = spans.partition_point(|s| s.at <= k);
    i > 0 && spans[i - 1].end().is_none_or(|end| k < end)
}

/// Spans of at least one period, sorted by `at`, not overlapping, with `at + periods`
/// representable; `name` is the list's key below `proxy.faults`.
fn validate_spans(spans: &[Stall], name: &str) -> Result<(), FaultsError> {
    let err = |field: String, problem: String| Err(FaultsError { field, problem });
    let mut previous: Option<(usize, Stall, u64)> = None;
    for (i, s) in spans.iter().enumerate() {
        if s.periods == 0 {
            return err(
                format!("proxy.faults.{name}[{i}].periods"),
                "must be at least 1".into(),
            );
        }
        let Some(end) = s.end() else {
            return err(
                format!("proxy.faults.{name}[{i}]"),
                format!(
                    "at + periods = {} + {} is past the last sample number",
                    s.at, s.periods
                ),
            );
        };
        if let Some((j, p, p_end)) = previous
            && s.at < p_end
        {
            return err(
                format!("proxy.faults.{name}[{i}].at"),
                format!(
                    "{} is inside or before {name}[{j}] (samples {} to {}): the spans must be \
                         sorted by 'at' and must not overlap",
                    s.at,
                    p.at,
                    p_end - 1
                ),
            );
        }
        previous = Some((i, *s, end));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stalls(list: &[(u64, u64)]) -> Faults {
        Faults {
            stalls: list
                .iter()
                .map(|&(at, periods)| Stall { at, periods })
                .collect(),
            ..Faults::default()
        }
    }

    #[test]
    fn a_stall_covers_its_periods_and_nothing_else() {
        let f = stalls(&[(4, 2), (6, 1), (10, 3)]);
        assert!(f.validate().is_ok());
        let stalled: Vec<u64> = (0..20).filter(|&k| f.stalled(k)).collect();
        assert_eq!(stalled, [4, 5, 6, 10, 11, 12]);
        assert!(!Faults::default().stalled(0));
    }

    #[test]
    fn overlapping_unsorted_empty_and_overflowing_stalls_are_refused_naming_the_entry() {
        for (list, field, words) in [
            (
                &[(4, 0)][..],
                "proxy.faults.stalls[0].periods",
                "at least 1",
            ),
            (&[(4, 3), (6, 1)], "proxy.faults.stalls[1].at", "overlap"),
            (&[(10, 1), (4, 1)], "proxy.faults.stalls[1].at", "sorted"),
            (&[(u64::MAX, 2)], "proxy.faults.stalls[0]", "past the last"),
        ] {
            let e = stalls(list).validate().unwrap_err();
            assert_eq!(e.field, field, "{list:?}: {e:?}");
            assert!(e.problem.contains(words), "{list:?}: {e:?}");
        }
    }

    #[test]
    fn a_fault_list_is_bounded() {
        let f = Faults {
            nan_at: vec![1; MAX_FAULT_SAMPLES + 1],
            ..Faults::default()
        };
        assert_eq!(f.validate().unwrap_err().field, "proxy.faults.nan-at");
        let f = Faults {
            nan_at: vec![1; MAX_FAULT_SAMPLES],
            ..Faults::default()
        };
        assert!(f.validate().is_ok());
    }
}
