//! When the controller's parameter estimate `θ̂_k` settles, as a reader reads it off the
//! `θ̂` panels of the b figures (Figures 4.5b–4.7b against 4.11b–4.13b): the claim of
//! §4.6.2 that on the NMP plant (4.88) "the convergence is much slower than in the
//! minimum-phase case" is about those curves, not about the error (4.85).
//!
//! # The measurement
//!
//! Over a run's samples `k = 0 … K` with the last estimate `θ̂_K`:
//!
//! ```text
//! d_k = ‖θ̂_k − θ̂_K‖₂,    D = max_k d_k   (the largest excursion from the final value)
//! settling step = the smallest k with d_j ≤ 0.1 D for every j ≥ k   (0 when D = 0)
//! ```
//!
//! i.e. the step after which every coefficient curve stays, as a whole, within 10 %
//! ([`SETTLE_FRACTION`]) of its largest distance from where it ends. A run that ends
//! still moving settles late (its last steps are close to `θ̂_K` only because `θ̂_K` is
//! where it stopped); the 200 steps of the chapter bound the measure.
//!
//! # Other readings
//!
//! The chapter states no rule, so the band is one of several ([`Band`]): the study's
//! `0.1 D` ([`Band::OfExcursion`]), a fraction of the final value's size `‖θ̂_K‖`
//! ([`Band::OfFinal`]), or a fixed distance ([`Band::Absolute`]); the same measure applies
//! to any signal sampled with the run, e.g. the model-following error `e_k` (`dim = 1`).
//! [`settling_step_in`] measures under any of them; [`settling_step`] is the study's.

/// The band around `θ̂_K`, as a fraction of the largest excursion `D`.
pub const SETTLE_FRACTION: f64 = 0.1;

/// Why a `θ̂` history cannot be measured.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SettlingError {
    /// No sample, or `θ̂` with no entry.
    #[error("θ̂ history: no samples or no coefficients")]
    Empty,
    /// The flat history is not a whole number of samples.
    #[error("θ̂ history: {len} values are not a multiple of {dim} coefficients")]
    Ragged {
        /// Values given.
        len: usize,
        /// Coefficients per sample.
        dim: usize,
    },
    /// A coefficient is NaN or infinite.
    #[error("θ̂ history: a non-finite coefficient at sample {0}")]
    NonFinite(usize),
}

/// The band around the final value `x_K` within which a history counts as settled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Band {
    /// `d_k ≤ f · D`, `D` the largest distance from `x_K` (the study's, `f` =
    /// [`SETTLE_FRACTION`]).
    OfExcursion(f64),
    /// `d_k ≤ f · ‖x_K‖`.
    OfFinal(f64),
    /// `d_k ≤ a`.
    Absolute(f64),
}

impl Band {
    /// The study's band: [`SETTLE_FRACTION`] of the largest excursion.
    pub const STUDY: Band = Band::OfExcursion(SETTLE_FRACTION);

    /// The band as text, e.g. `10 % of the largest excursion`.
    pub fn text(self) -> String {
        match self {
            Band::OfExcursion(f) => format!("{} % of the largest excursion", f * 100.0),
            Band::OfFinal(f) => format!("{} % of the final value's norm", f * 100.0),
            Band::Absolute(a) => format!("{a:e} absolute"),
        }
    }
}

/// The settling step of the module documentation for `history`, the samples
/// `θ̂_0, θ̂_1, …` laid end to end, `dim` coefficients each.
pub fn settling_step(history: &[f64], dim: usize) -> Result<usize, SettlingError> {
    settling_step_in(history, dim, Band::STUDY)
}

/// The first step after which `history` (samples `x_0, x_1, …` laid end to end, `dim`
/// entries each) stays within `band` of its last sample `x_K`; 0 when it never leaves it.
pub fn settling_step_in(history: &[f64], dim: usize, band: Band) -> Result<usize, SettlingError> {
    if dim == 0 || history.is_empty() {
        return Err(SettlingError::Empty);
    }
    if !history.len().is_multiple_of(dim) {
        return Err(SettlingError::Ragged {
            len: history.len(),
            dim,
        });
    }
    if let Some(i) = history.iter().position(|v| !v.is_finite()) {
        return Err(SettlingError::NonFinite(i / dim));
    }
    let samples: Vec<&[f64]> = history.chunks_exact(dim).collect();
    let last = samples[samples.len() - 1];
    let distance: Vec<f64> = samples
        .iter()
        .map(|s| {
            s.iter()
                .zip(last)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt()
        })
        .collect();
    let largest = distance.iter().copied().fold(0.0, f64::max);
    if largest == 0.0 {
        return Ok(0);
    }
    let band = match band {
        Band::OfExcursion(f) => f * largest,
        Band::OfFinal(f) => f * last.iter().map(|v| v * v).sum::<f64>().sqrt(),
        Band::Absolute(a) => a,
    };
    // The last sample outside the band; the run settles on the next one.
    Ok(distance
        .iter()
        .rposition(|&d| d > band)
        .map_or(0, |k| k + 1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_geometric_decay_settles_when_it_falls_under_a_tenth_of_its_start() {
        // θ̂_k = 0.9^k on two coefficients, ending near 0: d_k ≈ √2 (0.9^k − 0.9^200),
        // D = d_0; within 10 % from the first k with 0.9^k − 0.9^200 ≤ 0.1 (1 − 0.9^200),
        // k = 22 (0.9^21 = 0.109, 0.9^22 = 0.098).
        let h: Vec<f64> = (0..=200)
            .flat_map(|k| {
                let v = 0.9_f64.powi(k);
                [v, -v]
            })
            .collect();
        assert_eq!(settling_step(&h, 2), Ok(22));
    }

    #[test]
    fn a_jump_settles_on_its_step_and_a_late_excursion_moves_the_settling_past_it() {
        // 0 until k = 49, then 1 to the end: settled from k = 50.
        let mut h: Vec<f64> = (0..=200).map(|k| f64::from(u8::from(k >= 50))).collect();
        assert_eq!(settling_step(&h, 1), Ok(50));
        // A bump to half the excursion at k = 150 (outside the 10 % band): settled from 151.
        h[150] = 0.5;
        assert_eq!(settling_step(&h, 1), Ok(151));
        // A bump inside the band (0.95, 5 % of the excursion away) changes nothing.
        h[150] = 0.95;
        assert_eq!(settling_step(&h, 1), Ok(50));
    }

    #[test]
    fn the_other_bands_measure_against_the_final_value_or_a_fixed_distance() {
        // 2, then 1.5 from k = 10, then 1.05 from k = 20, then 1 from k = 30 to the end:
        // distances 1, 0.5, 0.05, 0; the largest excursion is 1 and the final value 1.
        let h: Vec<f64> = (0..=100)
            .map(|k| match k {
                0..10 => 2.0,
                10..20 => 1.5,
                20..30 => 1.05,
                _ => 1.0,
            })
            .collect();
        assert_eq!(settling_step_in(&h, 1, Band::OfExcursion(0.6)), Ok(10));
        assert_eq!(settling_step_in(&h, 1, Band::OfExcursion(0.1)), Ok(20));
        assert_eq!(settling_step_in(&h, 1, Band::OfFinal(0.1)), Ok(20));
        assert_eq!(settling_step_in(&h, 1, Band::OfFinal(0.01)), Ok(30));
        assert_eq!(settling_step_in(&h, 1, Band::Absolute(0.7)), Ok(10));
        assert_eq!(settling_step_in(&h, 1, Band::Absolute(1e-3)), Ok(30));
        // Scaled by 10: the relative bands do not move, the absolute one does.
        let h10: Vec<f64> = h.iter().map(|v| 10.0 * v).collect();
        assert_eq!(settling_step_in(&h10, 1, Band::OfFinal(0.1)), Ok(20));
        assert_eq!(settling_step_in(&h10, 1, Band::Absolute(0.7)), Ok(20));
        assert_eq!(settling_step(&h, 1), settling_step_in(&h, 1, Band::STUDY));
    }

    #[test]
    fn a_constant_history_is_settled_from_the_start() {
        assert_eq!(settling_step(&[0.3, 0.3, 0.3, 0.3], 2), Ok(0));
        assert_eq!(settling_step(&[7.0], 1), Ok(0));
    }

    #[test]
    fn bad_histories_are_refused_naming_the_fault() {
        assert_eq!(settling_step(&[], 2), Err(SettlingError::Empty));
        assert_eq!(settling_step(&[1.0], 0), Err(SettlingError::Empty));
        assert_eq!(
            settling_step(&[1.0, 2.0, 3.0], 2),
            Err(SettlingError::Ragged { len: 3, dim: 2 })
        );
        let e = settling_step(&[1.0, 2.0, f64::NAN, 0.0], 2).unwrap_err();
        assert_eq!(e, SettlingError::NonFinite(1));
        assert!(e.to_string().contains("sample 1"));
    }
}
