//! A white-noise excitation source for identification experiments.
//!
//! To measure a frequency response (section 3.2 of the dissertation: the data behind a
//! dereverberated target model) the loop is run open with independent, zero-mean white
//! Gaussian inputs
//!
//! ```text
//!   u_{j,k} = σ_j v_{j,k},   v_{j,k} ~ N(0, 1) i.i.d. over j and k,
//! ```
//!
//! saturated to the configured limits. Independent channels make the input spectral
//! matrix `S_uu` diagonal, which is what the multi-input H1 estimator
//! (`design::welch`) needs. The measurements are ignored; the signal log records `u` and
//! `y` for the design tools. The generator is ChaCha8 from a configured seed, so a run is
//! reproducible; [`Controller::reset`] re-seeds it.
//!
//! The step draws `n_u` normal numbers (ziggurat sampling of `rand_distr`): no allocation,
//! no lock, bounded work.

use crate::ParamError;
use crate::controller::{Controller, OutputLimits, StepInput};
use crate::controller::{Dimensions, status};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// Independent white Gaussian inputs of standard deviations `σ_j` (see the module docs).
#[derive(Debug, Clone)]
pub struct ExcitationSource {
    counts: Dimensions,
    std: Vec<f64>,
    seed: u64,
    rng: ChaCha8Rng,
    limits: Option<OutputLimits>,
}

/// The parameters of an [`ExcitationSource`].
#[derive(Debug, Clone, PartialEq)]
pub struct ExcitationParams {
    /// Standard deviation `σ_j` per input (finite, ≥ 0, not all zero).
    pub std: Vec<f64>,
    /// Generator seed.
    pub seed: u64,
    /// Output saturation.
    pub limits: Option<OutputLimits>,
}

impl ExcitationParams {
    /// The seed when a configuration gives none.
    pub const DEFAULT_SEED: u64 = 1;

    /// Checks the parameters against the rig's channels without building anything.
    ///
    /// # Errors
    ///
    /// `"std"`: not one value per input, or all zero (nothing to identify); `"std"` with
    /// the index of a value that is not a standard deviation; `"u-min"`: limits of the
    /// wrong length.
    pub fn validate(&self, counts: Dimensions) -> Result<(), ParamError> {
        let n_u = counts.n_u;
        let std = &self.std;
        if std.len() != n_u {
            return Err(ParamError::new(
                "std",
                format!(
                    "excitation std has {} values, expected one per control input ({n_u})",
                    std.len()
                ),
            ));
        }
        if let Some((j, s)) = std
            .iter()
            .enumerate()
            .find(|(_, s)| !(s.is_finite() && **s >= 0.0))
        {
            return Err(ParamError::at(
                "std",
                j,
                format!("excitation std[{j}] = {s} is not a standard deviation"),
            ));
        }
        if std.iter().all(|s| *s == 0.0) {
            return Err(ParamError::new(
                "std",
                "excitation std is zero on every input: nothing to identify",
            ));
        }
        if let Some(l) = &self.limits {
            l.validate(n_u)?;
        }
        Ok(())
    }
}

impl ExcitationSource {
    /// A source for `counts.n_u` inputs with standard deviations `std` (one per input,
    /// finite, ≥ 0) and generator seed `seed`.
    ///
    /// # Errors
    ///
    /// Those of [`ExcitationParams::validate`].
    pub fn new(
        counts: Dimensions,
        std: Vec<f64>,
        seed: u64,
        limits: Option<OutputLimits>,
    ) -> Result<Self, ParamError> {
        Self::from_params(&ExcitationParams { std, seed, limits }, counts)
    }

    /// A source for `counts.n_u` inputs, after [`ExcitationParams::validate`].
    ///
    /// # Errors
    ///
    /// Those of [`ExcitationParams::validate`].
    pub fn from_params(params: &ExcitationParams, counts: Dimensions) -> Result<Self, ParamError> {
        params.validate(counts)?;
        Ok(Self {
            counts,
            std: params.std.clone(),
            seed: params.seed,
            rng: ChaCha8Rng::seed_from_u64(params.seed),
            limits: params.limits.clone(),
        })
    }
}

impl Controller for ExcitationSource {
    fn kind(&self) -> &'static str {
        "excitation"
    }

    fn counts(&self) -> Dimensions {
        self.counts
    }

    fn step(&mut self, _input: &StepInput<'_>, u: &mut [f64]) -> u32 {
        for (v, s) in u.iter_mut().zip(&self.std) {
            let n: f64 = StandardNormal.sample(&mut self.rng);
            *v = s * n;
        }
        match &self.limits {
            Some(l) if l.apply(u) => status::SATURATED,
            _ => status::OK,
        }
    }

    fn reset(&mut self) {
        self.rng = ChaCha8Rng::seed_from_u64(self.seed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn counts() -> Dimensions {
        Dimensions::new(1, 1, 0, 2)
    }

    fn source(
        std: Vec<f64>,
        seed: u64,
        limits: Option<OutputLimits>,
    ) -> Result<ExcitationSource, ParamError> {
        ExcitationSource::new(counts(), std, seed, limits)
    }

    /// A measurement of zeros (the source does not read it).
    fn zero_input() -> StepInput<'static> {
        StepInput {
            seq: 0,
            y: &[0.0],
            z: &[0.0],
            r: &[],
            ..Default::default()
        }
    }

    #[test]
    fn inputs_have_the_configured_spread_and_are_uncorrelated() {
        let mut src = source(vec![2.0, 0.5], 7, None).unwrap();
        let input = zero_input();
        let n = 200_000;
        let (mut s0, mut s1, mut s01, mut lag) = (0.0, 0.0, 0.0, 0.0);
        let mut prev = 0.0;
        let mut u = [0.0; 2];
        for _ in 0..n {
            assert_eq!(src.step(&input, &mut u), status::OK);
            s0 += u[0] * u[0];
            s1 += u[1] * u[1];
            s01 += u[0] * u[1];
            lag += u[0] * prev;
            prev = u[0];
        }
        let n = n as f64;
        let (sd0, sd1) = ((s0 / n).sqrt(), (s1 / n).sqrt());
        assert!((sd0 / 2.0 - 1.0).abs() < 0.01, "σ0 = {sd0}");
        assert!((sd1 / 0.5 - 1.0).abs() < 0.01, "σ1 = {sd1}");
        // Correlation across channels and across one lag: |ρ| < 4/√n ≈ 0.009.
        assert!((s01 / n / (sd0 * sd1)).abs() < 0.009);
        assert!((lag / n / (sd0 * sd0)).abs() < 0.009);
    }

    #[test]
    fn reset_repeats_the_sequence_and_limits_clip() {
        let l = OutputLimits {
            min: vec![-1.0; 2],
            max: vec![1.0; 2],
        };
        let mut src = source(vec![3.0, 3.0], 1, Some(l)).unwrap();
        let input = zero_input();
        let mut first = Vec::new();
        let mut saturated = 0;
        let mut u = [0.0; 2];
        for _ in 0..100 {
            saturated += (src.step(&input, &mut u) == status::SATURATED) as u32;
            assert!(u.iter().all(|v| v.abs() <= 1.0));
            first.push(u);
        }
        assert!(saturated > 50, "σ = 3 against ±1 limits clips most samples");
        src.reset();
        for f in &first {
            src.step(&input, &mut u);
            assert_eq!(&u, f);
        }
    }

    #[test]
    fn bad_parameters_are_refused() {
        let e = source(vec![1.0], 0, None).unwrap_err();
        assert!(
            e.message.contains("expected one per control input (2)"),
            "{e}"
        );
        let e = source(vec![1.0, f64::NAN], 0, None).unwrap_err();
        assert_eq!(e.path(), "std[1]");
        let e = source(vec![0.0, 0.0], 0, None).unwrap_err();
        assert!(e.message.contains("nothing to identify"), "{e}");
    }
}
