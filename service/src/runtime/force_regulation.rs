//! The run report's force regulation (`service.report.force-regulation`): for each contact
//! phase, the stretch of samples during which the force set-point `F_d = r_k` is positive
//! (chapter 7: the guidance commands 25 N from contact onset for 2 s), what the measured
//! force `F_c = y_k` did:
//!
//! - the median of `F_c` over the phase (Figures 7.3 and 7.5 map this median);
//! - the settling time: from the phase's first sample to the first sample after which
//!   `|F_c − F_d| ≤ band · F_d` holds to the end of the phase (none when the last sample is
//!   outside the band);
//! - the peak of `F_c` and the share of the phase's samples inside the band.
//!
//! Recording is a store into a buffer sized before the loop starts ([`CAPACITY`] samples
//! over the run; later samples of a phase are counted but not stored, and the report says
//! so) and, at a phase's first sample, an entry in a fixed table of [`MAX_PHASES`]: no
//! allocation on the real-time thread. The median and settling time are computed when the
//! report is built, off the loop.

use crate::config::ForceRegulationConfig;
use serde::Serialize;

/// Force samples stored over a run (8 MiB): 4.4 min of contact at 2 kHz.
pub const CAPACITY: usize = 1 << 20;

/// Contact phases reported; later ones are counted only.
pub const MAX_PHASES: usize = 32;

#[derive(Debug, Clone, Copy, Default)]
struct Phase {
    first_seq: u64,
    last_seq: u64,
    set_point: f64,
    /// Offset of the phase's first stored sample in the buffer.
    start: usize,
    /// Samples stored.
    stored: usize,
    /// Samples seen (stored or not).
    seen: u64,
}

/// The accumulator held by the loop.
#[derive(Debug, Clone)]
pub struct ForceRegulation {
    cfg: Option<ForceRegulationConfig>,
    period_s: f64,
    samples: Vec<f64>,
    phases: [Phase; MAX_PHASES],
    n_phases: usize,
    phases_dropped: u64,
    in_phase: bool,
    /// The current phase is beyond the table: counted only.
    counting_only: bool,
}

/// One contact phase in the run report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PhaseReport {
    /// The phase's first sample (sequence number) and its time `seq · T` (s).
    pub first_seq: u64,
    /// `first_seq · T`, s.
    pub start_s: f64,
    /// From the first to the last sample of the phase, s.
    pub duration_s: f64,
    /// `F_d` at the phase's first sample.
    pub set_point: f64,
    /// The median of the measured force over the stored samples.
    pub median: f64,
    /// The largest measured force.
    pub peak: f64,
    /// From the phase's start to the sample after which the force stays in the band, s.
    pub settling_s: Option<f64>,
    /// The share of the stored samples inside the band.
    pub in_band: f64,
    /// Samples of the phase that were not stored (the buffer was full).
    pub not_stored: u64,
}

/// The force regulation of a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ForceRegulationReport {
    /// The settling band, a fraction of the set-point.
    pub band: f64,
    /// The contact phases, in order.
    pub phases: Vec<PhaseReport>,
    /// Phases beyond [`MAX_PHASES`], counted only.
    pub phases_not_reported: u64,
}

impl ForceRegulation {
    /// The accumulator for `cfg` (none: records nothing and allocates nothing) at sample
    /// period `period_s`.
    pub fn new(cfg: Option<ForceRegulationConfig>, period_s: f64) -> Self {
        Self {
            cfg,
            period_s,
            samples: if cfg.is_some() {
                vec![0.0; CAPACITY]
            } else {
                Vec::new()
            },
            phases: [Phase::default(); MAX_PHASES],
            n_phases: 0,
            phases_dropped: 0,
            in_phase: false,
            counting_only: false,
        }
    }

    /// Adds sample `seq` with its measurements `y` and commands `r`.
    #[inline]
    pub fn record(&mut self, seq: u64, y: &[f64], r: &[f64]) {
        let Some(cfg) = self.cfg else { return };
        let (Some(&f), Some(&fd)) = (y.get(cfg.measured), r.get(cfg.set_point)) else {
            return;
        };
        if !(fd > 0.0 && f.is_finite()) {
            self.in_phase = false;
            return;
        }
        if !self.in_phase {
            self.in_phase = true;
            self.counting_only = self.n_phases == MAX_PHASES;
            if self.counting_only {
                self.phases_dropped += 1;
            } else {
                let start = self.phases[..self.n_phases]
                    .last()
                    .map_or(0, |p| p.start + p.stored);
                self.phases[self.n_phases] = Phase {
                    first_seq: seq,
                    last_seq: seq,
                    set_point: fd,
                    start,
                    stored: 0,
                    seen: 0,
                };
                self.n_phases += 1;
            }
        }
        if self.counting_only {
            return;
        }
        let Some(phase) = self.phases[..self.n_phases].last_mut() else {
            return;
        };
        phase.last_seq = seq;
        phase.seen += 1;
        let at = phase.start + phase.stored;
        if let Some(slot) = self.samples.get_mut(at) {
            *slot = f;
            phase.stored += 1;
        }
    }

    /// The report, when configured and at least one phase was seen.
    pub fn report(&self) -> Option<ForceRegulationReport> {
        let cfg = self.cfg?;
        if self.n_phases == 0 {
            return None;
        }
        let phases = self.phases[..self.n_phases]
            .iter()
            .map(|p| self.phase_report(p, cfg.band))
            .collect();
        Some(ForceRegulationReport {
            band: cfg.band,
            phases,
            phases_not_reported: self.phases_dropped,
        })
    }

    fn phase_report(&self, p: &Phase, band: f64) -> PhaseReport {
        let f = &self.samples[p.start..p.start + p.stored];
        let tol = band * p.set_point;
        let inside = |v: &f64| (v - p.set_point).abs() <= tol;
        let mut sorted = f.to_vec();
        sorted.sort_by(f64::total_cmp);
        let n = sorted.len();
        let median = match n {
            0 => f64::NAN,
            _ if n % 2 == 1 => sorted[n / 2],
            _ => 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]),
        };
        let settled_from = match f.iter().rposition(|v| !inside(v)) {
            None => Some(0),
            Some(i) if i + 1 < n => Some(i + 1),
            Some(_) => None,
        };
        PhaseReport {
            first_seq: p.first_seq,
            start_s: p.first_seq as f64 * self.period_s,
            duration_s: (p.last_seq - p.first_seq) as f64 * self.period_s,
            set_point: p.set_point,
            median,
            peak: f.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            settling_s: settled_from.map(|i| i as f64 * self.period_s),
            in_band: if n == 0 {
                0.0
            } else {
                f.iter().filter(|v| inside(v)).count() as f64 / n as f64
            },
            not_stored: p.seen - p.stored as u64,
        }
    }
}

impl ForceRegulationReport {
    /// The report's lines, one per phase.
    pub fn lines(&self) -> String {
        let mut out = String::new();
        for (i, p) in self.phases.iter().enumerate() {
            let settled = match p.settling_s {
                Some(s) => format!("settled within ±{:.0} % after {s:.3} s", self.band * 100.0),
                None => format!("not settled within ±{:.0} %", self.band * 100.0),
            };
            out += &format!(
                "force regulation, contact {}: from {:.3} s for {:.3} s, set-point {} N: median {:.3} N, \
                 peak {:.3} N, {settled}, {:.1} % of samples in the band{}\n",
                i + 1,
                p.start_s,
                p.duration_s,
                p.set_point,
                p.median,
                p.peak,
                p.in_band * 100.0,
                if p.not_stored > 0 {
                    format!(" ({} samples beyond the buffer not counted)", p.not_stored)
                } else {
                    String::new()
                }
            );
        }
        if self.phases_not_reported > 0 {
            out += &format!(
                "force regulation: {} later contact phases not reported\n",
                self.phases_not_reported
            );
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> Option<ForceRegulationConfig> {
        Some(ForceRegulationConfig {
            measured: 1,
            set_point: 0,
            band: 0.05,
        })
    }

    #[test]
    fn a_phase_reports_its_median_peak_and_settling_time() {
        let mut fr = ForceRegulation::new(cfg(), 0.5e-3);
        // Out of contact, then 10 samples at 25 N preceded by a ramp, then out again.
        fr.record(0, &[0.0, 0.0], &[0.0]);
        let forces = [5.0, 15.0, 30.0, 26.0, 24.5, 25.0, 25.2, 24.9, 25.1, 25.0];
        for (i, f) in forces.iter().enumerate() {
            fr.record(1 + i as u64, &[0.0, *f], &[25.0]);
        }
        fr.record(11, &[0.0, 0.0], &[0.0]);
        let rep = fr.report().expect("one phase");
        assert_eq!(rep.phases.len(), 1);
        let p = &rep.phases[0];
        assert_eq!(p.first_seq, 1);
        assert_eq!(p.set_point, 25.0);
        assert_eq!(p.peak, 30.0);
        // Sorted: 5, 15, 24.5, 24.9, 25, 25, 25.1, 25.2, 26, 30 → (25 + 25)/2.
        assert_eq!(p.median, 25.0);
        // Outside ±1.25 N: 5, 15, 30 (index 2); 26 is inside; settled from index 3.
        assert!((p.settling_s.unwrap() - 3.0 * 0.5e-3).abs() < 1e-15);
        assert!((p.in_band - 0.7).abs() < 1e-12);
        assert!((p.duration_s - 9.0 * 0.5e-3).abs() < 1e-15);
    }

    #[test]
    fn two_phases_are_reported_apart_and_an_unsettled_end_says_so() {
        let mut fr = ForceRegulation::new(cfg(), 1e-3);
        for k in 0..5 {
            fr.record(k, &[0.0, 25.0], &[25.0]);
        }
        fr.record(5, &[0.0, 0.0], &[0.0]);
        for k in 6..9 {
            fr.record(k, &[0.0, 10.0], &[25.0]);
        }
        let rep = fr.report().unwrap();
        assert_eq!(rep.phases.len(), 2);
        assert_eq!(rep.phases[0].settling_s, Some(0.0));
        assert_eq!(rep.phases[1].first_seq, 6);
        assert_eq!(rep.phases[1].median, 10.0);
        assert_eq!(rep.phases[1].settling_s, None);
        assert!(rep.lines().contains("not settled"));
    }

    #[test]
    fn without_configuration_or_contact_there_is_no_report() {
        let mut off = ForceRegulation::new(None, 1e-3);
        off.record(0, &[0.0, 25.0], &[25.0]);
        assert!(off.report().is_none());
        let mut idle = ForceRegulation::new(cfg(), 1e-3);
        idle.record(0, &[0.0, 3.0], &[0.0]);
        assert!(idle.report().is_none());
    }
}
