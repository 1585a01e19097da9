//! PCAC as the augmentation of a fixed output feedback: the identification of the open
//! loop and the prediction of the closed loop, dissertation (7.42)–(7.57).
//!
//! # The loop
//!
//! A fixed gain `K̄ ∈ ℝ^{m×p}` already closes the loop around the plant, and PCAC adds
//! `u_aug` to it (chapter 7: `K̄ = [0_{2×2} K]` is the robust state feedback `τ_f = K χ` on
//! the outputs `y = ζ`):
//!
//! ```text
//! τ_{f,k} = K̄ y_k + u_aug,k                                                     (Alg. 3)
//! ```
//!
//! `u_aug,k` is PCAC's output (its decision variable, within `u-min`/`u-max` and the move
//! bounds (7.61)); `τ_{f,k}` is what the plant receives.
//!
//! # Identification regresses on the plant's input (7.42)–(7.52)
//!
//! The model identified is the plant's, without the feedback,
//!
//! ```text
//! ŷ_k = − Σ_{i=1}^{n̂} F̂_i y_{k−i} + Σ_{i=1}^{n̂} Ĝ_i τ_{f,k−i}                    (7.42)
//! ```
//!
//! so the regressor (7.46) holds `τ_{f,k−i} = u_aug,k−i + K̄ y_{k−i}`: at step `k` the
//! input stored with `y_k` is `τ_{f,k−1} = u_aug,k−1 + K̄ y_{k−1}`, from the output stored
//! one step earlier. (Regressing on `u_aug` instead would identify the closed loop, whose
//! coefficients change with `K̄`; this way a `K̄` changed between runs leaves the learned
//! `θ` valid.)
//!
//! # Prediction with the closed loop (7.53)–(7.57)
//!
//! Substituting `τ_{f,k−i} = K̄ y_{k−i} + u_aug,k−i` into (7.42) gives the same outputs as
//! the input–output model of the closed loop with input `u_aug`:
//!
//! ```text
//! ŷ_k = − Σ_{i=1}^{n̂} (F̂_i − Ĝ_i K̄) y_{k−i} + Σ_{i=1}^{n̂} Ĝ_i u_aug,k−i
//!     = − Σ_{i=1}^{n̂} F̂'_i y_{k−i} + Σ_{i=1}^{n̂} Ĝ_i u_aug,k−i,     F̂'_i ≜ F̂_i − Ĝ_i K̄
//! ```
//!
//! Its block observable canonical realization ([`crate::bocf`], (2.36)–(2.42)) has
//! `−F̂'_i = −F̂_i + Ĝ_i K̄` in block `(i, 1)` of `Â`: since `Ĉ = [I_p 0 … 0]`, adding
//! `Ĝ_i K̄` to block `(i, 1)` is adding `B̂ K̄ Ĉ`, so
//!
//! ```text
//! Â'_k = Â_k + B̂_k K̄ Ĉ,   B̂'_k = B̂_k,   Ĉ' = Ĉ                               (7.56)–(7.57)
//! ```
//!
//! which is (7.56) (`Â_k` plus `[Ĝ_1; …; Ĝ_n̂] K`). The state estimate (7.55) of the
//! closed-loop model from its own data `y`, `u_aug`,
//!
//! ```text
//! x̂'_{i,k} = Σ_{j=1}^{n̂−i+1} (−F̂'_{i+j−1} y_{k−j} + Ĝ_{i+j−1} u_aug,k−j)
//!          = Σ_{j=1}^{n̂−i+1} (−F̂_{i+j−1} y_{k−j} + Ĝ_{i+j−1} (u_aug,k−j + K̄ y_{k−j}))
//!          = x̂_{i,k}                                                             (7.55)
//! ```
//!
//! equals the one of the identified model from `y`, `τ_f`, as (7.55) writes it. So the
//! predictor of (7.58)–(7.61) is exactly [`crate::bocf`]'s for the coefficients
//! `Θ̃' = [F̂'_1 … F̂'_n̂ Ĝ_1 … Ĝ_n̂]` and the data `y`, `u_aug`: the controller keeps
//! `Θ̃'` (refreshed from `Θ̃` before each prediction, `n̂ p² m` multiply–adds) and the
//! `u_aug` history in preallocated buffers, and [`AugmentedModel`] presents them as an
//! [`IdentifiedModel`], so that the Markov parameters `Ĥ'_i = Ĉ Â'^{i−1} B̂` of
//! `T̂_{k,ℓ}` and the free response `Γ̂'_{k,ℓ} x̂_k` come from the companion structure
//! without a dense `Â'`. The MPC problem is unchanged: its decision variable is `u_aug`.

#![allow(clippy::needless_range_loop)] // index-heavy block algebra

use super::model::{IoModel, Ring};
use crate::bocf::{DataWindow, IdentifiedModel, Realization};

/// A fixed output feedback `K̄ ∈ ℝ^{m×p}` that PCAC augments (module docs): the plant's
/// input is `K̄ y_k + u_k`, `u_k` being PCAC's output.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputFeedback {
    /// `K̄`, `m × p` row-major (`m` inputs, `p` outputs of the identified model).
    pub gain: Vec<f64>,
}

impl OutputFeedback {
    /// `K̄ = [0_{m×(p−c)} K]`: a gain `K` (`m × c`, row-major) on the last `c` of the `p`
    /// outputs, as chapter 7's `[0_2 K]` on `ζ = [θ̇_1 θ̇_2 ẋ ẏ e]`.
    ///
    /// # Errors
    ///
    /// When `k` does not have `m c` entries or `c > p`.
    pub fn on_last_outputs(m: usize, p: usize, c: usize, k: &[f64]) -> Result<Self, String> {
        if c > p || k.len() != m * c {
            return Err(format!(
                "the gain on the last {c} of {p} outputs has {} entries, expected {m}×{c}",
                k.len()
            ));
        }
        let mut gain = vec![0.0; m * p];
        for i in 0..m {
            gain[i * p + (p - c)..(i + 1) * p].copy_from_slice(&k[i * c..(i + 1) * c]);
        }
        Ok(Self { gain })
    }

    /// `τ = u + K̄ y` into `tau` (lengths `m`, `p`, `m`; `K̄` has `m p` entries).
    pub fn plant_input(&self, y: &[f64], u: &[f64], tau: &mut [f64]) {
        let p = y.len();
        for (i, (t, ui)) in tau.iter_mut().zip(u).enumerate() {
            let row = &self.gain[i * p..(i + 1) * p];
            *t = ui + row.iter().zip(y).map(|(k, v)| k * v).sum::<f64>();
        }
    }
}

/// The closed-loop coefficients `Θ̃'` and the `u_aug` history of an augmented PCAC
/// (module docs), sized once.
#[derive(Debug, Clone)]
pub(super) struct Augmentation {
    feedback: OutputFeedback,
    n_hat: usize,
    p: usize,
    m: usize,
    /// `Θ̃' = [F̂'_1 … F̂'_n̂ Ĝ_1 … Ĝ_n̂]`, `p × n̂(p+m)` row-major.
    coef: Vec<f64>,
    /// `u_aug,k−1, u_aug,k−2, …` (capacity `n̂`), pushed with the model's `τ_f` history.
    inputs: Ring,
    /// Scratch: the plant input `τ_{f,k−1}` handed to the identification.
    tau: Vec<f64>,
}

impl Augmentation {
    /// The buffers for `model`'s dimensions; `feedback` has `m p` entries (checked by
    /// [`super::PcacParams::validate`]).
    pub(super) fn new(model: &IoModel, feedback: &OutputFeedback) -> Self {
        let (n_hat, p, m) = (model.n_hat(), model.p(), model.m());
        let mut a = Self {
            feedback: feedback.clone(),
            n_hat,
            p,
            m,
            coef: vec![0.0; p * n_hat * (p + m)],
            inputs: Ring::new(m, n_hat),
            tau: vec![0.0; m],
        };
        a.refresh(model);
        a
    }

    /// The gain `K̄`.
    pub(super) fn feedback(&self) -> &OutputFeedback {
        &self.feedback
    }

    /// Stores `u_aug,k−1` and returns the plant input `τ_{f,k−1} = u_aug,k−1 + K̄ y_{k−1}`
    /// for the identification, `y_{k−1}` being the model's newest stored output.
    pub(super) fn take_input(&mut self, y_prev: &[f64], u_aug: &[f64]) -> &[f64] {
        self.inputs.push(u_aug);
        self.feedback.plant_input(y_prev, u_aug, &mut self.tau);
        &self.tau
    }

    /// `Θ̃'` from the model's current `Θ̃`: `F̂'_i = F̂_i − Ĝ_i K̄`, `Ĝ_i` copied.
    pub(super) fn refresh(&mut self, model: &IoModel) {
        let (n_hat, p, m) = (self.n_hat, self.p, self.m);
        let nr = n_hat * (p + m);
        let src = model.coefficients();
        self.coef.copy_from_slice(src);
        let k = &self.feedback.gain;
        for r in 0..p {
            let row = &src[r * nr..(r + 1) * nr];
            for i in 0..n_hat {
                let g = &row[n_hat * p + i * m..n_hat * p + (i + 1) * m];
                for s in 0..p {
                    let mut gk = 0.0;
                    for j in 0..m {
                        gk += g[j] * k[j * p + s];
                    }
                    self.coef[r * nr + i * p + s] -= gk;
                }
            }
        }
    }

    /// The `u_aug` history back to zeros (a reset or a restart of the histories).
    pub(super) fn clear(&mut self) {
        self.inputs.clear();
    }

    /// The closed-loop model for the realization at the current step.
    pub(super) fn view<'a>(&'a self, model: &'a IoModel) -> AugmentedModel<'a> {
        AugmentedModel { model, aug: self }
    }

    /// `Θ̃'` (`p × n̂(p+m)`, row-major).
    pub(super) fn coefficients(&self) -> &[f64] {
        &self.coef
    }
}

/// The closed-loop model of an augmented PCAC at its current step (module docs): the
/// coefficients `Θ̃'` with the data `y` (the identified model's) and `u_aug`, an
/// [`IdentifiedModel`] for [`crate::bocf::HorizonPrediction`].
#[derive(Debug, Clone, Copy)]
pub struct AugmentedModel<'a> {
    model: &'a IoModel,
    aug: &'a Augmentation,
}

impl AugmentedModel<'_> {
    /// `Θ̃' = [F̂'_1 … F̂'_n̂ Ĝ_1 … Ĝ_n̂]`, `F̂'_i = F̂_i − Ĝ_i K̄` (`p × n̂(p+m)`, row-major).
    pub fn coefficients(&self) -> &[f64] {
        self.aug.coefficients()
    }
}

impl DataWindow for AugmentedModel<'_> {
    #[inline]
    fn past_output(&self, j: usize) -> &[f64] {
        self.model.past_output(j)
    }

    #[inline]
    fn past_input(&self, j: usize) -> &[f64] {
        self.aug.inputs.back(j.saturating_sub(1))
    }
}

impl IdentifiedModel for AugmentedModel<'_> {
    #[inline]
    fn realization(&self) -> Realization<'_> {
        Realization::new_unchecked(self.aug.n_hat, self.aug.p, self.aug.m, &self.aug.coef)
    }
}

#[cfg(test)]
mod tests;
