//! The internal model of known tones: the tones' annihilator `D(q)` and the tone notch
//! `W(q) = D(q) / D(ρq)` that PCAC's internal-model law uses (an extension of the
//! dissertation's §2.3.2, see below).
//!
//! # The annihilator
//!
//! A disturbance made of `n_t` tones at known frequencies `f_i` (sampled at `f_s`,
//! `ω_i = 2π f_i / f_s` rad/sample) satisfies, whatever its amplitudes and phases,
//!
//! ```text
//! D(q) d_k = 0,    D(q) = Π_{i=1}^{n_t} (1 − 2 cos ω_i q⁻¹ + q⁻²) = Σ_{j=0}^{2n_t} δ_j q⁻ʲ
//! ```
//!
//! (each factor has the roots `e^{±jω_i}`; `δ_0 = δ_{2n_t} = 1`, the coefficients are
//! palindromic). [`ToneAnnihilator::coefficients`] are `δ_0 … δ_{2n_t}`.
//!
//! # How PCAC uses it
//!
//! - **Identification of the plant part.** With `y_f = D(q) y` and `u_f = D(q) u`, the
//!   model (2.24) `y_k = −Σ F̂_i y_{k−i} + Σ Ĝ_i u_{k−i} + d_k` becomes, `D` being scalar,
//!   `y_{f,k} = −Σ F̂_i y_{f,k−i} + Σ Ĝ_i u_{f,k−i}` with the tones removed: RLS
//!   (2.30)–(2.32) runs on the regressor (2.28) built from `y_f`, `u_f`, and the residual
//!   (2.26) is `z_k = D(q)[y_k + Σ F̂_i y_{k−i} − Σ Ĝ_i u_{k−i}]`.
//! - **Prediction with the tones.** The block observable canonical form (2.36)–(2.42) used
//!   in (2.43) is that of the product model
//!   `F̄(q) = D(q)(I + Σ F̂_i q⁻ⁱ)`, `Ḡ(q) = D(q) Σ Ĝ_i q⁻ⁱ` of order `n̂ + 2n_t`
//!   ([`ToneAnnihilator::multiply`]), with its state (2.38)–(2.39) from the unfiltered
//!   `y`, `u`. `D` cancels in `Ḡ/F̄`, so its Markov parameters `H_i` (2.46) are those of
//!   the plant part; only the free response `Γ̂ x_{1|k}` (2.45) differs: it continues the
//!   tones present in the data.
//! - **The input cost.** (2.47)–(2.48) penalize the moves `ΔU`; the internal-model law
//!   penalizes instead the input filtered by the tone notch, and the input's level:
//!
//! ```text
//! v_k = W(q) u_k,   W(q) = D(q) / D(ρq) = Π_i (1 − 2cos ω_i q⁻¹ + q⁻²) / (1 − 2ρ cos ω_i q⁻¹ + ρ² q⁻²)
//! V = [v_{1|k}; …; v_{ℓ|k}] = 𝒲 U + v_free                                      (2.47')
//! min_U (Y_t − 𝓡)ᵀ Q (Y_t − 𝓡) + Vᵀ R_v V + Uᵀ R_u U + ΔUᵀ R ΔU                   (2.48')
//! ```
//!
//! with `0 < ρ < 1` (the notches' width: about `(1 − ρ) f_s / π` Hz), `𝒲` the lower
//! triangular block Toeplitz matrix of `W`'s impulse response (block `(i, j)` is
//! `w_{i−j} I_m`, [`ToneAnnihilator::notch_impulse_response`]), and `v_free` the response of
//! `W`'s state from the past inputs with `U = 0`. (2.47)'s move penalty is the special
//! case `W(q) = 1 − q⁻¹`. An input that is a pure tone at `ω_i` costs nothing in `V`, so
//! the optimum cancels the tones up to `R_u` (zero on the loudspeaker that cancels): the
//! law has poles at `e^{±jω_i}` and the sensitivity is zero there for any `Q`.
//!
//! (2.47') and (2.48') are this product's extension beyond the dissertation, which
//! penalizes only the moves (2.47)–(2.48); (2.24)–(2.46) are used unchanged, on filtered
//! data and on the product polynomials.
//!
//! # Real time
//!
//! Everything here is computed once, at construction ([`ToneAnnihilator::new`] allocates
//! its coefficients); the per-sample filters of PCAC are in
//! [`crate::pcac::tone_model`].

/// The most tones an annihilator takes (its order is twice this).
pub const MAX_TONES: usize = 32;

/// Why [`ToneAnnihilator::new`] refused its arguments: which one, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ToneError {
    /// The frequencies: none, more than [`MAX_TONES`], or one outside `(0, π)`.
    Tones(String),
    /// The notch radius `ρ`: outside `(0, 1)`.
    Radius(String),
}

impl core::fmt::Display for ToneError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ToneError::Tones(why) | ToneError::Radius(why) => f.write_str(why),
        }
    }
}

impl std::error::Error for ToneError {}

/// The annihilator `D(q)` of a set of tones and its notch `W(q) = D(q) / D(ρq)` (module
/// docs).
#[derive(Debug, Clone, PartialEq)]
pub struct ToneAnnihilator {
    /// `δ_0 … δ_{2n_t}` of `D(q)`.
    d: Vec<f64>,
    /// `δ_j ρʲ`, the coefficients of `D(ρq)`.
    d_rho: Vec<f64>,
    rho: f64,
}

impl ToneAnnihilator {
    /// `D(q)` for the frequencies `omegas` (rad/sample, each in `(0, π)`) and the notch
    /// radius `rho` (`0 < ρ < 1`).
    ///
    /// # Errors
    ///
    /// No tone or more than [`MAX_TONES`], a frequency outside `(0, π)` or non-finite, or
    /// `ρ` outside `(0, 1)`.
    pub fn new(omegas: &[f64], rho: f64) -> Result<Self, ToneError> {
        if omegas.is_empty() || omegas.len() > MAX_TONES {
            return Err(ToneError::Tones(format!(
                "{} tones: need 1 to {MAX_TONES}",
                omegas.len()
            )));
        }
        if let Some(w) = omegas
            .iter()
            .find(|w| !(w.is_finite() && **w > 0.0 && **w < std::f64::consts::PI))
        {
            return Err(ToneError::Tones(format!(
                "a tone at {w} rad/sample: each must lie strictly between 0 and the Nyquist \
                 frequency (π)"
            )));
        }
        if !(rho > 0.0 && rho < 1.0) {
            return Err(ToneError::Radius(format!(
                "the notch radius ρ = {rho} must lie strictly between 0 and 1"
            )));
        }
        let mut d = vec![1.0];
        for w in omegas {
            let c = -2.0 * w.cos();
            let mut next = vec![0.0; d.len() + 2];
            for (j, dj) in d.iter().enumerate() {
                next[j] += dj;
                next[j + 1] += c * dj;
                next[j + 2] += dj;
            }
            d = next;
        }
        let d_rho = d
            .iter()
            .enumerate()
            .map(|(j, v)| v * rho.powi(j as i32))
            .collect();
        Ok(Self { d, d_rho, rho })
    }

    /// [`ToneAnnihilator::new`] for frequencies in hertz at the sample rate `fs` (Hz).
    ///
    /// # Errors
    ///
    /// As [`ToneAnnihilator::new`], with the frequency in hertz.
    pub fn from_hz(tones_hz: &[f64], fs: f64, rho: f64) -> Result<Self, ToneError> {
        if let Some(f) = tones_hz
            .iter()
            .find(|f| !(f.is_finite() && **f > 0.0 && **f < fs / 2.0))
        {
            return Err(ToneError::Tones(format!(
                "a tone at {f} Hz: each must lie strictly between 0 and the Nyquist frequency \
                 ({} Hz)",
                fs / 2.0
            )));
        }
        let omegas: Vec<f64> = tones_hz
            .iter()
            .map(|f| 2.0 * std::f64::consts::PI * f / fs)
            .collect();
        Self::new(&omegas, rho)
    }

    /// `δ_0 … δ_{2n_t}` of `D(q)`.
    pub fn coefficients(&self) -> &[f64] {
        &self.d
    }

    /// `δ_j ρʲ`, `j = 0 … 2n_t`: the coefficients of `D(ρq)`, `W`'s denominator.
    pub fn notch_denominator(&self) -> &[f64] {
        &self.d_rho
    }

    /// The order `2n_t` of `D(q)`.
    pub fn order(&self) -> usize {
        self.d.len() - 1
    }

    /// The notch radius `ρ`.
    pub fn rho(&self) -> f64 {
        self.rho
    }

    /// The first `len` samples `w_0 = 1, w_1, …` of `W(q) = D(q) / D(ρq)`'s impulse
    /// response: `w_j = δ_j − Σ_{i=1}^{min(j, 2n_t)} δ_i ρⁱ w_{j−i}` (`δ_j = 0` beyond
    /// `2n_t`). Allocates.
    pub fn notch_impulse_response(&self, len: usize) -> Vec<f64> {
        let mut w = vec![0.0; len];
        for j in 0..len {
            let uf = self.d.get(j).copied().unwrap_or(0.0);
            w[j] = self.notch_output(uf, |i| if i <= j { w[j - i] } else { 0.0 });
        }
        w
    }

    /// `(D(q) x)_t = Σ_{i=0}^{2n_t} δ_i x_{t−i}`, with `past(i) = x_{t−i}`. Allocation-free.
    #[inline]
    pub fn annihilate(&self, past: impl Fn(usize) -> f64) -> f64 {
        let mut acc = 0.0;
        for (i, di) in self.d.iter().enumerate() {
            acc += di * past(i);
        }
        acc
    }

    /// One output of the notch `W(q) = D(q) / D(ρq)`:
    /// `v_t = (D(q) u)_t − Σ_{i=1}^{2n_t} δ_i ρⁱ v_{t−i}`, with `uf = (D(q) u)_t`
    /// ([`ToneAnnihilator::annihilate`]) and `past_v(i) = v_{t−i}`. Allocation-free.
    #[inline]
    pub fn notch_output(&self, uf: f64, past_v: impl Fn(usize) -> f64) -> f64 {
        let mut v = uf;
        for (i, di) in self.d_rho.iter().enumerate().skip(1) {
            v -= di * past_v(i);
        }
        v
    }

    /// The product `D(q) · Σ_{i=0}^{n} a_i q⁻ⁱ` of `D` with a polynomial whose
    /// coefficients are `blocks` of `len` values each (`a_i` at `i·len`; e.g. the
    /// entries of `F̂_i` or `Ĝ_i`), into `out` (`(n + 1 + 2n_t)·len` values):
    /// `out_j = Σ_i δ_i a_{j−i}`. Allocation-free.
    ///
    /// # Panics
    ///
    /// Never with `out.len() == blocks.len() + 2n_t·len` and `len ≥ 1`; other lengths
    /// write what fits.
    pub fn multiply(&self, blocks: &[f64], len: usize, out: &mut [f64]) {
        out.fill(0.0);
        if len == 0 {
            return;
        }
        for (i, a) in blocks.chunks_exact(len).enumerate() {
            for (j, dj) in self.d.iter().enumerate() {
                let Some(dst) = out.get_mut((i + j) * len..(i + j + 1) * len) else {
                    continue;
                };
                for (o, x) in dst.iter_mut().zip(a) {
                    *o += dj * x;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn the_annihilator_cancels_any_sum_of_its_tones() {
        let omegas = [0.3, 1.1, 2.5];
        let d = ToneAnnihilator::new(&omegas, 0.97).unwrap();
        assert_eq!(d.order(), 6);
        let x: Vec<f64> = (0..200)
            .map(|k| {
                let k = k as f64;
                1.3 * (0.3 * k + 0.2).sin() + 0.7 * (1.1 * k - 1.0).cos() + 2.0 * (2.5 * k).sin()
            })
            .collect();
        let c = d.coefficients();
        for k in c.len()..x.len() {
            let v: f64 = c.iter().enumerate().map(|(j, dj)| dj * x[k - j]).sum();
            assert!(v.abs() < 1e-10, "D(q) x at {k} = {v}");
        }
    }

    #[test]
    fn the_notch_response_is_one_at_lag_zero_and_filters_like_d_over_d_rho() {
        let d = ToneAnnihilator::from_hz(&[800.0, 3000.0], 8000.0, 0.9).unwrap();
        let w = d.notch_impulse_response(40);
        assert_eq!(w[0], 1.0);
        // Convolving w with D(ρq) gives D(q) (then zeros).
        let den = d.notch_denominator();
        for j in 0..40 {
            let v: f64 = (0..=j.min(d.order())).map(|i| den[i] * w[j - i]).sum();
            let want = d.coefficients().get(j).copied().unwrap_or(0.0);
            assert!((v - want).abs() < 1e-12, "lag {j}: {v} vs {want}");
        }
        // Its gain is 0 at a tone and near 1 away from them.
        let gain = |om: f64| {
            let (mut re, mut im) = (0.0, 0.0);
            for (j, wj) in d.notch_impulse_response(4000).iter().enumerate() {
                re += wj * (om * j as f64).cos();
                im -= wj * (om * j as f64).sin();
            }
            (re * re + im * im).sqrt()
        };
        assert!(gain(2.0 * PI * 800.0 / 8000.0) < 1e-6);
        // |W(e^{jω})| at 2 kHz: Π |e^{jω} − e^{±jω_i}| / |e^{jω} − ρ e^{±jω_i}| = 1.2108 at
        // ρ = 0.9, computed independently.
        assert!((gain(2.0 * PI * 2000.0 / 8000.0) - 1.2108).abs() < 1e-3);
    }

    #[test]
    fn multiplying_by_the_annihilator_convolves_blockwise() {
        let d = ToneAnnihilator::new(&[0.5], 0.5).unwrap();
        // a(q) = [1 2] + [3 4] q⁻¹ (two entries per block).
        let mut out = vec![0.0; 8];
        d.multiply(&[1.0, 2.0, 3.0, 4.0], 2, &mut out);
        let c = -2.0 * 0.5f64.cos();
        let want = [
            1.0,
            2.0,
            3.0 + c,
            4.0 + 2.0 * c,
            1.0 + 3.0 * c,
            2.0 + 4.0 * c,
            3.0,
            4.0,
        ];
        for (o, w) in out.iter().zip(want) {
            assert!((o - w).abs() < 1e-14);
        }
    }

    #[test]
    fn bad_tones_and_radii_are_refused() {
        assert!(ToneAnnihilator::new(&[], 0.9).is_err());
        assert!(ToneAnnihilator::new(&[0.0], 0.9).is_err());
        assert!(ToneAnnihilator::new(&[PI], 0.9).is_err());
        assert!(ToneAnnihilator::new(&[1.0], 1.0).is_err());
        assert!(ToneAnnihilator::new(&[1.0], 0.0).is_err());
        assert!(ToneAnnihilator::from_hz(&[4000.0], 8000.0, 0.9).is_err());
    }
}
