//! PCAC with the internal model of known tones (an extension beyond the dissertation;
//! the mathematics is in [`crate::internal_model`]): the tone-free identification data,
//! the product model the prediction uses, and the notch filter's free response of the
//! input cost (2.47').
//!
//! # Per sample `k` (the call order of [`super::model::IoModel`])
//!
//! 1. `u_{k−1}` and `y_k` are stored unfiltered (histories of `n̂ + 2n_t` samples), and
//!    `v_{k−1} = W(q) u_{k−1}` is computed from the stored `u`, `v` (`W = D(q)/D(ρq)`).
//! 2. The identification gets `y_{f,k} = Σ_j δ_j y_{k−j}` and
//!    `u_{f,k−1} = Σ_j δ_j u_{k−1−j}`: RLS (2.30)–(2.32) on the regressor (2.28) of the
//!    filtered data estimates the plant part `F̂_i`, `Ĝ_i`, `i = 1 … n̂`.
//! 3. At each prediction the product coefficients (order `n̄ = n̂ + 2n_t`) are refreshed
//!    from `Θ̃`:
//!
//!    ```text
//!    F̄_i = δ_i I_p + Σ_{j=0}^{2n_t} δ_j F̂_{i−j},   Ḡ_i = Σ_{j=0}^{2n_t} δ_j Ĝ_{i−j},   i = 1 … n̄
//!    ```
//!
//!    (`F̂_0 = I`, `Ĝ_0 = 0`, `F̂_i = Ĝ_i = 0` beyond `n̂`), `O(2n_t n̂ p (p+m))`. Their
//!    block observable canonical realization (2.36)–(2.42) ([`crate::bocf`]) with the
//!    state (2.38)–(2.39) from the unfiltered `y`, `u` is [`ToneProductModel`]. Since `D`
//!    cancels, its Markov parameters (2.46) are the plant part's; its free response (2.45)
//!    continues the tones.
//! 4. `v_free` of (2.47'): `W`'s state after the inputs up to `u_{k−1}`, driven by the
//!    committed inputs (`u_k` in next-step timing, `u_k … u_{k+N−1}` when re-planning every
//!    `N`) and then by zeros for the `ℓ` steps of `U`, `O(2n_t ℓ m)`.
//!
//! Every buffer is sized at construction; nothing here allocates after it.

#![allow(clippy::needless_range_loop)] // index-heavy polynomial algebra

use super::model::{IoModel, Ring};
use crate::bocf::{DataWindow, IdentifiedModel, Realization};
use crate::internal_model::ToneAnnihilator;

/// The internal model of known tones of a PCAC ([`super::PcacParams::internal_model`]).
#[derive(Debug, Clone, PartialEq)]
pub struct InternalModel {
    /// The tones' frequencies `ω_i` (rad/sample, each in `(0, π)`).
    pub omegas: Vec<f64>,
    /// The notch radius `ρ` of `W(q) = D(q) / D(ρq)` (`0 < ρ < 1`).
    pub notch_radius: f64,
    /// `R_v` per input (`m` values, `> 0`): the weight on the notched input `V` (2.48').
    pub r_notch: Vec<f64>,
    /// `R_u` per input (`m` values, `≥ 0`): the weight on the input's level `U` (2.48').
    pub r_level: Vec<f64>,
}

/// The buffers of PCAC's internal model (module docs), sized once.
#[derive(Debug, Clone)]
pub(super) struct ToneModel {
    ann: ToneAnnihilator,
    n_hat: usize,
    p: usize,
    m: usize,
    /// `2 n_t`.
    nd: usize,
    /// `y_k, y_{k−1}, …` unfiltered (capacity `n̂ + 2n_t`).
    ys: Ring,
    /// `u_{k−1}, u_{k−2}, …` unfiltered (capacity `n̂ + 2n_t`).
    us: Ring,
    /// `v_{k−1}, v_{k−2}, …` (capacity `2n_t`).
    vs: Ring,
    /// `y_{f,k}` and `u_{f,k−1}` of the last sample.
    yf: Vec<f64>,
    uf: Vec<f64>,
    /// Scratch: the new `v_{k−1}`.
    v_new: Vec<f64>,
    /// `[F̄_1 … F̄_n̄ Ḡ_1 … Ḡ_n̄]`, `p × n̄(p+m)` row-major.
    coef: Vec<f64>,
    /// Scratch for one entry's polynomial (`n̂ + 1`) and its product (`n̄ + 1`).
    poly: Vec<f64>,
    prod: Vec<f64>,
    /// `v_free` of (2.47'), `ℓ m` step-major.
    v_free: Vec<f64>,
    /// Scratch for the filter run: inputs and outputs, `2n_t + ℓ + ℓ` each.
    run_u: Vec<f64>,
    run_v: Vec<f64>,
    ell: usize,
}

impl ToneModel {
    /// The buffers for `model`'s dimensions and the horizon `ℓ`.
    ///
    /// # Errors
    ///
    /// Those of [`ToneAnnihilator::new`].
    pub(super) fn new(model: &IoModel, im: &InternalModel, ell: usize) -> Result<Self, String> {
        let ann = ToneAnnihilator::new(&im.omegas, im.notch_radius).map_err(|e| e.to_string())?;
        let (n_hat, p, m) = (model.n_hat(), model.p(), model.m());
        let nd = ann.order();
        let nbar = n_hat + nd;
        let mut t = Self {
            ann,
            n_hat,
            p,
            m,
            nd,
            ys: Ring::new(p, nbar),
            us: Ring::new(m, nbar),
            vs: Ring::new(m, nd),
            yf: vec![0.0; p],
            uf: vec![0.0; m],
            v_new: vec![0.0; m],
            coef: vec![0.0; p * nbar * (p + m)],
            poly: vec![0.0; n_hat + 1],
            prod: vec![0.0; nbar + 1],
            v_free: vec![0.0; ell * m],
            run_u: vec![0.0; nd + 2 * ell],
            run_v: vec![0.0; nd + 2 * ell],
            ell,
        };
        t.refresh(model);
        Ok(t)
    }

    /// The samples a datum stays in the identification's regressor: `n̂ + 2n_t`.
    pub(super) fn window(&self) -> usize {
        self.n_hat + self.nd
    }

    /// Step 1–2 of the module docs: stores `u_{k−1}` (`u_prev`) and `y_k`, the new
    /// `v_{k−1}`, and forms `y_{f,k}`, `u_{f,k−1}` ([`ToneModel::filtered`]).
    pub(super) fn take_sample(&mut self, y: &[f64], u_prev: &[f64]) {
        self.us.push(u_prev);
        for j in 0..self.m {
            let uf = self.ann.annihilate(|i| self.us.back(i)[j]);
            self.uf[j] = uf;
            self.v_new[j] = self.ann.notch_output(uf, |i| self.vs.back(i - 1)[j]);
        }
        self.vs.push(&self.v_new);
        for r in 0..self.p {
            self.yf[r] = self
                .ann
                .annihilate(|i| if i == 0 { y[r] } else { self.ys.back(i - 1)[r] });
        }
        self.ys.push(y);
    }

    /// `y_{f,k}` and `u_{f,k−1}` of the last [`ToneModel::take_sample`].
    pub(super) fn filtered(&self) -> (&[f64], &[f64]) {
        (&self.yf, &self.uf)
    }

    /// Step 3 of the module docs: the product coefficients from `model`'s `Θ̃`.
    pub(super) fn refresh(&mut self, model: &IoModel) {
        let (n_hat, p, m, nd) = (self.n_hat, self.p, self.m, self.nd);
        let nbar = n_hat + nd;
        let (nr, nrbar) = (n_hat * (p + m), nbar * (p + m));
        let src = model.coefficients();
        for r in 0..p {
            let row = &src[r * nr..(r + 1) * nr];
            // F̄(r, s): D(q) (δ_{rs} + Σ F̂_i(r, s) q⁻ⁱ).
            for s in 0..p {
                self.poly[0] = if r == s { 1.0 } else { 0.0 };
                for i in 1..=n_hat {
                    self.poly[i] = row[(i - 1) * p + s];
                }
                self.ann.multiply(&self.poly, 1, &mut self.prod);
                for i in 1..=nbar {
                    self.coef[r * nrbar + (i - 1) * p + s] = self.prod[i];
                }
            }
            // Ḡ(r, s): D(q) Σ Ĝ_i(r, s) q⁻ⁱ.
            for s in 0..m {
                self.poly[0] = 0.0;
                for i in 1..=n_hat {
                    self.poly[i] = row[n_hat * p + (i - 1) * m + s];
                }
                self.ann.multiply(&self.poly, 1, &mut self.prod);
                for i in 1..=nbar {
                    self.coef[r * nrbar + nbar * p + (i - 1) * m + s] = self.prod[i];
                }
            }
        }
    }

    /// Step 4 of the module docs: `v_free` (`ℓ m`) for the `committed` inputs (rows of
    /// `m`, at most `ℓ` of them; none in same-step timing, whose `U` starts at `u_k`).
    pub(super) fn fill_v_free(&mut self, committed: &[f64]) -> &[f64] {
        let (m, nd, ell) = (self.m, self.nd, self.ell);
        let nc = (committed.len() / m).min(ell);
        for j in 0..m {
            // Positions 0..nd: the past, oldest first; then the committed inputs, then zeros.
            for i in 0..nd {
                self.run_u[i] = self.us.back(nd - 1 - i)[j];
                self.run_v[i] = self.vs.back(nd - 1 - i)[j];
            }
            let total = nd + nc + ell;
            for t in nd..total {
                let c = t - nd;
                self.run_u[t] = if c < nc { committed[c * m + j] } else { 0.0 };
                let (run_u, run_v) = (&self.run_u, &self.run_v);
                let uf = self.ann.annihilate(|i| run_u[t - i]);
                self.run_v[t] = self.ann.notch_output(uf, |i| run_v[t - i]);
            }
            for i in 0..ell {
                self.v_free[i * m + j] = self.run_v[nd + nc + i];
            }
        }
        &self.v_free
    }

    /// The last [`ToneModel::fill_v_free`].
    pub(super) fn v_free(&self) -> &[f64] {
        &self.v_free
    }

    /// Every history back to zeros (a reset or a restart of the histories).
    pub(super) fn clear(&mut self) {
        self.ys.clear();
        self.us.clear();
        self.vs.clear();
        self.yf.fill(0.0);
        self.uf.fill(0.0);
    }

    /// The product model for the realization at the current step.
    pub(super) fn view(&self) -> ToneProductModel<'_> {
        ToneProductModel { t: self }
    }
}

/// The product model `F̄ = D·F̂`, `Ḡ = D·Ĝ` of a PCAC with the internal model of known
/// tones at its current step, with the unfiltered data (module docs): an
/// [`IdentifiedModel`] for [`crate::bocf::HorizonPrediction`].
#[derive(Debug, Clone, Copy)]
pub struct ToneProductModel<'a> {
    t: &'a ToneModel,
}

impl ToneProductModel<'_> {
    /// `[F̄_1 … F̄_n̄ Ḡ_1 … Ḡ_n̄]` (`p × n̄(p+m)`, row-major, `n̄ = n̂ + 2n_t`).
    pub fn coefficients(&self) -> &[f64] {
        &self.t.coef
    }

    /// The order `n̄ = n̂ + 2n_t`.
    pub fn order(&self) -> usize {
        self.t.window()
    }
}

impl DataWindow for ToneProductModel<'_> {
    #[inline]
    fn past_output(&self, j: usize) -> &[f64] {
        self.t.ys.back(j)
    }

    #[inline]
    fn past_input(&self, j: usize) -> &[f64] {
        self.t.us.back(j.saturating_sub(1))
    }
}

impl IdentifiedModel for ToneProductModel<'_> {
    #[inline]
    fn realization(&self) -> Realization<'_> {
        Realization::new_unchecked(self.t.window(), self.t.p, self.t.m, &self.t.coef)
    }
}

#[cfg(test)]
mod tests;
