//! The settings of one closed-loop run of `study mrac` that are the study's to set: the
//! chapter's printed values and the choices it leaves open, gathered so that the
//! sensitivity table ([`crate::study::mrac::sensitivity`]) can move one at a time.
//!
//! | setting | the study's value ([`RunSettings::STUDY`]) | in the chapter |
//! | --- | --- | --- |
//! | run length | 200 steps | printed, §4.5 ("Each simulation is run for 200 steps") |
//! | metric window | steps 101–200 | printed, (4.85) |
//! | divergence | `\|y\| > 10⁶` (or not finite, or a fault) | not given: the captions of Figures 4.8a–4.10a say only "became unstable" |
//! | settling rule | `θ̂_k` within 10 % of its largest excursion from its final value | not given: "convergence" (§4.6.2) is read off the θ̂ panels |
//! | `R_θ` | `10⁻⁵ I` | printed, §4.5.1, §4.5.2, §4.6, §4.7 (`P_0 = R_θ⁻¹`, §2) |
//! | Example 3's disturbance | `cos(0.35 k)`: amplitude 1, phase 0 | the frequency only, §4.7 |

use plant_proxy::harmonic::Harmonic;

use crate::study::mrac::closed_loop::{DIVERGENCE_LIMIT, METRIC_FROM, STEPS};
use crate::study::mrac::theta_settling::Band;

/// The signal whose settling step a run reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Signal {
    /// The estimate `θ̂_k` (the study's: what the θ̂ panels show).
    Theta,
    /// The model-following error `e_k`.
    Error,
}

impl Signal {
    /// `θ̂_k` or `e_k`.
    pub fn name(self) -> &'static str {
        match self {
            Signal::Theta => "θ̂_k",
            Signal::Error => "e_k",
        }
    }
}

/// The settings of a run (module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunSettings {
    /// The last sample `K` (the run has samples `0 … K`).
    pub steps: usize,
    /// The first sample of the metric (4.85) `‖e‖ = sqrt(Σ e_i²)`, `i = metric_from … metric_to`.
    pub metric_from: usize,
    /// The last sample of the metric (at most [`Self::steps`]).
    pub metric_to: usize,
    /// `|y_k|` above this marks the run as diverged.
    pub divergence_limit: f64,
    /// The signal whose settling is reported.
    pub settle_signal: Signal,
    /// Its band ([`crate::study::mrac::theta_settling`]).
    pub settle_band: Band,
    /// `R_θ = r_theta · I` of every controller.
    pub r_theta: f64,
    /// Example 3's input disturbance `a cos(0.35 k + φ)`: `(a, φ)`, φ in rad.
    pub disturbance: (f64, f64),
}

impl RunSettings {
    /// The study's settings (module documentation).
    pub const STUDY: RunSettings = RunSettings {
        steps: STEPS,
        metric_from: METRIC_FROM,
        metric_to: STEPS,
        divergence_limit: DIVERGENCE_LIMIT,
        settle_signal: Signal::Theta,
        settle_band: Band::STUDY,
        r_theta: control::mrac::RcMracParams::DEFAULT_R_THETA,
        disturbance: (1.0, 0.0),
    };

    /// Example 3's disturbance at this amplitude and phase, from the example's harmonic
    /// `h` (its frequency kept).
    pub fn disturbance_of(&self, h: Harmonic) -> Harmonic {
        Harmonic {
            amplitude: self.disturbance.0,
            phase: self.disturbance.1,
            ..h
        }
    }
}

impl Default for RunSettings {
    fn default() -> Self {
        Self::STUDY
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::mrac::setup::Example;

    #[test]
    fn the_studys_settings_are_the_chapters_printed_values_and_its_own_choices() {
        let s = RunSettings::STUDY;
        assert_eq!((s.steps, s.metric_from, s.metric_to), (200, 101, 200));
        assert_eq!(s.divergence_limit, 1e6);
        assert_eq!(s.r_theta, 1e-5);
        assert_eq!(control::mrac::AppcParams::DEFAULT_R_THETA, s.r_theta);
        assert_eq!(s.settle_band, Band::OfExcursion(0.1));
        let h = Example::Three.disturbance().expect("Example 3 has one");
        assert_eq!(s.disturbance_of(h), h);
        let moved = RunSettings {
            disturbance: (2.0, 0.5),
            ..s
        }
        .disturbance_of(h);
        assert_eq!(
            (moved.amplitude, moved.phase, moved.omega),
            (2.0, 0.5, h.omega)
        );
    }
}
