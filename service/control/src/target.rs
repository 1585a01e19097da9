//! The RCAC target model `G_f` (2.19): what the design tools produce and RCAC's filter
//! (`rcac::TargetFilter`) reads.
//!
//! Two forms, both discrete at the rig's sample period, for `p` outputs (`z`) and `m`
//! control inputs:
//!
//! - **Dereverberated target model** (3.49) with the measured delays added back per input:
//!
//!   ```text
//!   G_f(z)_{o,i} = β · z^{−d_i} · Ĝ_{d,o,i}(z),   Ĝ_{d,o,i}(z) = num_{o,i}(z) / den_{o,i}(z)
//!   ```
//!
//!   with `num`/`den` in descending powers of `z` (`den` monic). `β` is stored apart
//!   from the coefficients, so it can be retuned without refitting.
//! - **FIR target model** (3.39): `G_f(q) = β Σ_{i=0}^{n_f} H_i q^{−i}` from the Markov
//!   parameters `H_i` (`p × m` each); the delays are already in the `H_i`.
//!
//! ## File format (read and written by the service's configuration)
//!
//! ```toml
//! [target-model]
//! form = "transfer-function"       # or "markov"
//! sample-period = 1.25e-4          # s; must equal the rig's
//! outputs = 1
//! inputs = 2
//! beta = 0.8                       # (3.49), in (0, 1]
//! source = "rig-design target …"   # free text: how it was made
//!
//! [[target-model.channel]]         # form = "transfer-function": one per (output, input)
//! output = 0
//! input = 0
//! delay = 9                        # samples, added back in front of Ĝ_d
//! num = [0.0123, 0.0045]
//! den = [1.0, -0.71]
//!
//! # form = "markov":
//! # markov = [ [[0.0, 0.0]], [[0.012, -0.004]], … ]   # H_0, H_1, …: p rows × m columns each
//! ```
//!
//! A missing `(output, input)` channel of a transfer-function model is zero.
//! [`TargetModel::validate`] checks every value and names the refused field.

use crate::ParamError;
use nalgebra::DMatrix;

/// One `(output, input)` entry of a transfer-function target model.
#[derive(Debug, Clone, PartialEq)]
pub struct TargetChannel {
    /// Output index `o`.
    pub output: usize,
    /// Input index `i`.
    pub input: usize,
    /// Pure delay `d_i` in samples.
    pub delay: usize,
    /// Numerator of `Ĝ_d`, descending powers of `z`.
    pub num: Vec<f64>,
    /// Denominator of `Ĝ_d`, descending powers of `z`, monic.
    pub den: Vec<f64>,
}

/// The two forms of a target model (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub enum TargetForm {
    /// Dereverberated target model (3.49): one transfer function per channel.
    TransferFunction(Vec<TargetChannel>),
    /// FIR target model (3.39): `H_0 … H_{n_f}`.
    Markov(Vec<DMatrix<f64>>),
}

/// A target model; [`TargetModel::validate`] checks it.
#[derive(Debug, Clone, PartialEq)]
pub struct TargetModel {
    /// Sample period, s.
    pub sample_period: f64,
    /// Number of outputs `p`.
    pub outputs: usize,
    /// Number of inputs `m`.
    pub inputs: usize,
    /// Scaling `β` of (3.49).
    pub beta: f64,
    /// How it was made.
    pub source: String,
    /// The model itself.
    pub form: TargetForm,
}

/// The largest delay in samples a channel may have.
const MAX_DELAY: usize = 1 << 16;

impl TargetModel {
    /// Checks every value: a positive period, at least one output and input, `β ∈ (0, 1]`
    /// (3.49); for the transfer-function form channels inside the model's size, each given
    /// once, monic, proper and finite, with a plausible delay; for the Markov form
    /// parameters of `p × m` finite values, not all zero. The error names the field.
    pub fn validate(&self) -> Result<(), ParamError> {
        if !(self.sample_period.is_finite() && self.sample_period > 0.0) {
            return Err(ParamError::new(
                "sample-period",
                format!("{} is not a period", self.sample_period),
            ));
        }
        if self.outputs == 0 || self.inputs == 0 {
            return Err(ParamError::new("outputs/inputs", "must both be at least 1"));
        }
        if !(self.beta > 0.0 && self.beta <= 1.0) {
            return Err(ParamError::new(
                "beta",
                format!("{} is outside (0, 1] (3.49)", self.beta),
            ));
        }
        match &self.form {
            TargetForm::TransferFunction(channels) => self.validate_channels(channels),
            TargetForm::Markov(hs) => self.validate_markov(hs),
        }
    }

    fn validate_channels(&self, channels: &[TargetChannel]) -> Result<(), ParamError> {
        if channels.is_empty() {
            return Err(ParamError::new("channel", "no channel given"));
        }
        let mut seen = vec![false; self.outputs * self.inputs];
        for (k, c) in channels.iter().enumerate() {
            if c.output >= self.outputs {
                return Err(ParamError::at(
                    "channel.output",
                    k,
                    format!("{} ≥ outputs = {}", c.output, self.outputs),
                ));
            }
            if c.input >= self.inputs {
                return Err(ParamError::at(
                    "channel.input",
                    k,
                    format!("{} ≥ inputs = {}", c.input, self.inputs),
                ));
            }
            let slot = &mut seen[c.output * self.inputs + c.input];
            if *slot {
                return Err(ParamError::at(
                    "channel.output",
                    k,
                    format!("channel ({}, {}) given twice", c.output, c.input),
                ));
            }
            *slot = true;
            if c.den.is_empty() || c.den[0] != 1.0 {
                return Err(ParamError::at(
                    "channel.den",
                    k,
                    "must be monic (leading coefficient 1)",
                ));
            }
            if c.num.len() > c.den.len() {
                return Err(ParamError::at(
                    "channel.num",
                    k,
                    "the degree exceeds the denominator's (improper)",
                ));
            }
            if c.num.iter().chain(&c.den).any(|v| !v.is_finite()) {
                return Err(ParamError::at(
                    "channel.num/den",
                    k,
                    "has a NaN or infinite coefficient",
                ));
            }
            if c.delay > MAX_DELAY {
                return Err(ParamError::at(
                    "channel.delay",
                    k,
                    format!("{} samples is not a plausible delay", c.delay),
                ));
            }
        }
        Ok(())
    }

    fn validate_markov(&self, hs: &[DMatrix<f64>]) -> Result<(), ParamError> {
        if hs.is_empty() {
            return Err(ParamError::new("markov", "no Markov parameter given"));
        }
        for (i, h) in hs.iter().enumerate() {
            if h.nrows() != self.outputs || h.ncols() != self.inputs {
                return Err(ParamError::at(
                    "markov",
                    i,
                    format!("must be {} rows of {} values", self.outputs, self.inputs),
                ));
            }
            if h.iter().any(|v| !v.is_finite()) {
                return Err(ParamError::at("markov", i, "has a NaN or infinite value"));
            }
        }
        if hs.iter().all(|h| h.iter().all(|v| *v == 0.0)) {
            return Err(ParamError::new("markov", "every Markov parameter is zero"));
        }
        Ok(())
    }

    /// The first `count` Markov parameters of `G_f` (β and delays included): the impulse
    /// response, by long division of each channel's transfer function.
    pub fn markov(&self, count: usize) -> Vec<DMatrix<f64>> {
        let (p, m) = (self.outputs, self.inputs);
        let mut out = vec![DMatrix::zeros(p, m); count];
        match &self.form {
            TargetForm::Markov(hs) => {
                for (o, h) in out.iter_mut().zip(hs) {
                    *o = h * self.beta;
                }
            }
            TargetForm::TransferFunction(ch) => {
                for c in ch {
                    // num(z)/den(z) = Σ h_k z^{−k}: h_k = num_k' − Σ_{j≥1} den_j h_{k−j},
                    // with num padded in front to the length of den.
                    let n = c.den.len();
                    let mut num = vec![0.0; n - c.num.len()];
                    num.extend_from_slice(&c.num);
                    let mut h = vec![0.0; count.saturating_sub(c.delay)];
                    for k in 0..h.len() {
                        let mut v = if k < n { num[k] } else { 0.0 };
                        for j in 1..n.min(k + 1) {
                            v -= c.den[j] * h[k - j];
                        }
                        h[k] = v;
                    }
                    for (k, v) in h.iter().enumerate() {
                        out[k + c.delay][(c.output, c.input)] = self.beta * v;
                    }
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tf_model() -> TargetModel {
        TargetModel {
            sample_period: 1.25e-4,
            outputs: 1,
            inputs: 2,
            beta: 0.8,
            source: "test".into(),
            form: TargetForm::TransferFunction(vec![
                TargetChannel {
                    output: 0,
                    input: 0,
                    delay: 9,
                    num: vec![0.5],
                    den: vec![1.0, -0.5],
                },
                TargetChannel {
                    output: 0,
                    input: 1,
                    delay: 16,
                    num: vec![0.2, 0.1],
                    den: vec![1.0, -1.2, 0.5],
                },
            ]),
        }
    }

    #[test]
    fn markov_parameters_are_the_impulse_response_of_the_transfer_functions() {
        let m = tf_model();
        let h = m.markov(30);
        // Channel 0: 0.8 · z^{-9} · 0.5/(z − 0.5) = 0.4 Σ 0.5^{k−10} z^{−k}, k ≥ 10.
        for (k, hk) in h.iter().enumerate() {
            let want = if k >= 10 {
                0.4 * 0.5f64.powi(k as i32 - 10)
            } else {
                0.0
            };
            assert!((hk[(0, 0)] - want).abs() < 1e-15, "k = {k}");
        }
        // Channel 1 starts at k = 16 + 1 with 0.8·0.2.
        assert_eq!(h[16][(0, 1)], 0.0);
        assert!((h[17][(0, 1)] - 0.16).abs() < 1e-15);
    }
}
