//! What the RCAC studies' summary tables say of a group of sweep rows (one method and
//! update law, in `rcac-siso` also one case, or one phase-error bin): the median and the
//! worst suppression of each tone, how many points are poor or diverged, and the settling
//! times.

use crate::study::rcac::common::median;
use crate::study::rcac::driver::Row;

/// Suppression below this is counted as poor, dB.
pub const POOR_DB: f64 = 20.0;

/// The statistics of a group of rows.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepStats<const N: usize> {
    /// Number of rows.
    pub points: usize,
    /// Median suppression of each tone, dB.
    pub median: [f64; N],
    /// Smallest suppression of each tone, dB (+∞ for no rows).
    pub worst: [f64; N],
    /// Rows whose worst tone ([`Row::worst_suppression`]) is below [`POOR_DB`] (diverged
    /// rows included).
    pub poor: usize,
    /// Rows that diverged.
    pub diverged: usize,
    /// The settling times, increasing (+∞: never settled).
    pub settle: Vec<f64>,
}

impl<const N: usize> SweepStats<N> {
    /// The statistics of `rows`.
    pub fn of<At>(rows: &[&Row<At, N>]) -> Self {
        let sup = |j: usize| rows.iter().map(|r| r.suppression(j)).collect::<Vec<_>>();
        let mut settle: Vec<f64> = rows
            .iter()
            .map(|r| r.settle.unwrap_or(f64::INFINITY))
            .collect();
        settle.sort_by(f64::total_cmp);
        Self {
            points: rows.len(),
            median: std::array::from_fn(|j| median(&sup(j))),
            worst: std::array::from_fn(|j| sup(j).into_iter().fold(f64::INFINITY, f64::min)),
            poor: rows
                .iter()
                .filter(|r| r.worst_suppression() < POOR_DB)
                .count(),
            diverged: rows.iter().filter(|r| !r.finite).count(),
            settle,
        }
    }

    /// Median settling time, s.
    pub fn settle_median(&self) -> f64 {
        median(&self.settle)
    }

    /// 90th percentile of the settling times (the smallest time of at least 90 % of the
    /// rows), s; NaN for no rows.
    pub fn settle_p90(&self) -> f64 {
        let s = &self.settle;
        s.get((s.len() * 9).div_ceil(10).saturating_sub(1))
            .copied()
            .unwrap_or(f64::NAN)
    }
}

/// A time in s with one decimal, or "never" when it is not finite (+∞: never settled).
pub fn secs(t: f64) -> String {
    if t.is_finite() {
        format!("{t:.1}")
    } else {
        "never".into()
    }
}
