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
//!
//! The inputs do not depend on the measurements, so the source answers ahead
//! ([`crate::ahead`]): its ready input is the next draw of the stream, prepared when the
//! previous one was given, and its plan the draws that follow (from a copy of the
//! generator), exactly what it will give. The ahead cycle gives the inputs of `step`, in
//! the same order.

use crate::ParamError;
use crate::controller::{Controller, OutputLimits, StepInput};
use crate::controller::{Dimensions, status};
use crate::output_limits::limit_output;
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
    /// The ahead form's ready input (the next draw) and its status.
    ready: Vec<f64>,
    ready_status: u32,
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

    /// The parameters for the standard deviations `std` (one per input), with the seed
    /// [`Self::DEFAULT_SEED`] and no saturation, the defaults of the service's
    /// `[controller]` table for `kind = "excitation"` (the source checks them,
    /// [`ExcitationParams::validate`]).
    pub fn new(std: Vec<f64>) -> Self {
        Self {
            std,
            seed: Self::DEFAULT_SEED,
            limits: None,
        }
    }

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
        let params = ExcitationParams {
            seed,
            limits,
            ..ExcitationParams::new(std)
        };
        Self::from_params(&params, counts)
    }

    /// A source for `counts.n_u` inputs, after [`ExcitationParams::validate`].
    ///
    /// # Errors
    ///
    /// Those of [`ExcitationParams::validate`].
    pub fn from_params(params: &ExcitationParams, counts: Dimensions) -> Result<Self, ParamError> {
        params.validate(counts)?;
        let mut s = Self {
            counts,
            std: params.std.clone(),
            seed: params.seed,
            rng: ChaCha8Rng::seed_from_u64(params.seed),
            limits: params.limits.clone(),
            ready: vec![0.0; params.std.len()],
            ready_status: status::OK,
        };
        s.prepare_ready();
        Ok(s)
    }

    /// The next `u.len()` inputs of the stream `rng` (standard deviations `std`, clipped to
    /// `limits`) into `u`; the status bits.
    fn draw(
        std: &[f64],
        limits: &Option<OutputLimits>,
        rng: &mut ChaCha8Rng,
        u: &mut [f64],
    ) -> u32 {
        for (v, s) in u.iter_mut().zip(std) {
            let n: f64 = StandardNormal.sample(rng);
            *v = s * n;
        }
        limit_output(limits.as_ref(), u)
    }

    /// The ready input: the next draw, read from a copy of the generator.
    fn prepare_ready(&mut self) {
        let mut rng = self.rng.clone();
        self.ready_status = Self::draw(&self.std, &self.limits, &mut rng, &mut self.ready);
    }
}

impl ExcitationParams {
    /// True: the inputs do not depend on the measurements (module docs).
    pub fn answers_ahead(&self) -> bool {
        true
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
        Self::draw(&self.std, &self.limits, &mut self.rng, u)
    }

    fn reset(&mut self) {
        self.rng = ChaCha8Rng::seed_from_u64(self.seed);
        self.prepare_ready();
    }

    fn ahead(&mut self) -> Option<&mut dyn crate::ahead::Ahead> {
        Some(self)
    }
}

impl crate::ahead::Ahead for ExcitationSource {
    fn ready(&self, u: &mut [f64]) -> u32 {
        for (d, s) in u.iter_mut().zip(&self.ready) {
            *d = *s;
        }
        self.ready_status
    }

    fn advance(&mut self, _input: &StepInput<'_>, _applied: &[f64], _adapt: bool) -> u32 {
        // The ready input was given: the stream moves past it, and the next is prepared.
        for _ in 0..self.std.len() {
            let _: f64 = StandardNormal.sample(&mut self.rng);
        }
        self.prepare_ready();
        self.ready_status
    }

    fn plan(&mut self, out: &mut [f64]) -> usize {
        let n_u = self.std.len().max(1);
        let mut rng = self.rng.clone();
        for _ in 0..self.std.len() {
            let _: f64 = StandardNormal.sample(&mut rng);
        }
        let mut rows = 0;
        for row in out.chunks_exact_mut(n_u) {
            let _ = Self::draw(&self.std, &self.limits, &mut rng, row);
            rows += 1;
        }
        rows
    }

    fn plan_source(&self) -> &'static str {
        "the next draws of the generator: exact"
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
    fn the_ahead_form_gives_the_inputs_of_step_and_its_plan_is_exact() {
        let lim = OutputLimits::symmetric(1.0, 2);
        let mut a = source(vec![2.0, 0.5], 3, Some(lim.clone())).unwrap();
        let mut b = source(vec![2.0, 0.5], 3, Some(lim)).unwrap();
        let input = zero_input();
        let mut plan = [0.0; 2 * 5];
        let mut planned: Vec<f64> = Vec::new();
        for k in 0..200 {
            let (mut ua, mut ub) = ([0.0; 2], [0.0; 2]);
            let sb = b.step(&input, &mut ub);
            let ahead = a.ahead().unwrap();
            let sa = ahead.ready(&mut ua);
            assert_eq!(
                (ua.map(f64::to_bits), sa),
                (ub.map(f64::to_bits), sb),
                "k = {k}"
            );
            if k % 50 == 10 {
                planned = ua.to_vec();
                ahead.advance(&input, &ua, true);
                assert_eq!(ahead.plan(&mut plan), 5);
                planned.extend_from_slice(&plan);
            } else {
                ahead.advance(&input, &ua, true);
            }
            // The plan made at k = 10 (inputs for 11 … 15) comes true.
            if (11..=15).contains(&(k % 50)) && k >= 11 {
                let j = (k % 50 - 10) as usize;
                let mut next = [0.0; 2];
                let _ = b.clone().step(&input, &mut next);
                assert_eq!(next.to_vec(), planned[2 * j..2 * j + 2].to_vec(), "k = {k}");
            }
        }
        a.reset();
        let (mut ua, mut fresh) = ([0.0; 2], [0.0; 2]);
        a.ahead().unwrap().ready(&mut ua);
        source(vec![2.0, 0.5], 3, None)
            .unwrap()
            .step(&input, &mut fresh);
        assert_eq!(ua[1], fresh[1], "after a reset the stream starts again");
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
        let l = OutputLimits::symmetric(1.0, 2);
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
