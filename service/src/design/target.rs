//! The RCAC target model `G_f` as a file: what the design tools write and RCAC's
//! configuration reads.
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
//! ## File format
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
//! A missing `(output, input)` channel of a transfer-function model is zero. Every value
//! is checked on reading; errors name the file and the field.

use super::{C64, Frf, horner};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// One `(output, input)` entry of a transfer-function target model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
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

/// A validated target model.
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

#[derive(Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawTarget {
    form: String,
    sample_period: f64,
    outputs: usize,
    inputs: usize,
    beta: f64,
    #[serde(default)]
    source: String,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    channel: Vec<TargetChannel>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    markov: Vec<Vec<Vec<f64>>>,
}

#[derive(Serialize, Deserialize)]
struct RawFile {
    #[serde(rename = "target-model")]
    target_model: RawTarget,
}

impl TargetModel {
    /// Reads a target-model file.
    pub fn load(path: &Path) -> Result<Self, String> {
        let origin = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|e| format!("{origin}: cannot read the target model: {e}"))?;
        Self::parse(&text, &origin)
    }

    /// Parses the text of a target-model file (a `[target-model]` table); `origin` names
    /// it in errors.
    pub fn parse(text: &str, origin: &str) -> Result<Self, String> {
        let table: toml::Table =
            toml::from_str(text).map_err(|e| format!("{origin}: not valid TOML: {e}"))?;
        let value = table
            .get("target-model")
            .ok_or_else(|| format!("{origin}: the [target-model] table is missing"))?;
        Self::from_value(value.clone(), origin)
    }

    /// Validates a `[target-model]` table already read from TOML (RCAC's configuration
    /// may hold it inline); `origin` names the file in errors.
    pub fn from_value(value: toml::Value, origin: &str) -> Result<Self, String> {
        let raw: RawTarget = value
            .try_into()
            .map_err(|e: toml::de::Error| format!("{origin}: target-model: {e}"))?;
        let err = |field: &str, m: String| format!("{origin}: target-model.{field}: {m}");
        if !(raw.sample_period.is_finite() && raw.sample_period > 0.0) {
            return Err(err(
                "sample-period",
                format!("{} is not a period", raw.sample_period),
            ));
        }
        if raw.outputs == 0 || raw.inputs == 0 {
            return Err(err("outputs/inputs", "must both be at least 1".into()));
        }
        if !(raw.beta > 0.0 && raw.beta <= 1.0) {
            return Err(err(
                "beta",
                format!("{} is outside (0, 1] (3.49)", raw.beta),
            ));
        }
        let form = match raw.form.as_str() {
            "transfer-function" => {
                if !raw.markov.is_empty() {
                    return Err(err(
                        "markov",
                        "given with form = \"transfer-function\"".into(),
                    ));
                }
                if raw.channel.is_empty() {
                    return Err(err("channel", "no channel given".into()));
                }
                let mut seen = vec![false; raw.outputs * raw.inputs];
                for (k, c) in raw.channel.iter().enumerate() {
                    let f = |name: &str| format!("channel[{k}].{name}");
                    if c.output >= raw.outputs {
                        return Err(err(
                            &f("output"),
                            format!("{} ≥ outputs = {}", c.output, raw.outputs),
                        ));
                    }
                    if c.input >= raw.inputs {
                        return Err(err(
                            &f("input"),
                            format!("{} ≥ inputs = {}", c.input, raw.inputs),
                        ));
                    }
                    let slot = &mut seen[c.output * raw.inputs + c.input];
                    if *slot {
                        return Err(err(
                            &f("output"),
                            format!("channel ({}, {}) given twice", c.output, c.input),
                        ));
                    }
                    *slot = true;
                    if c.den.is_empty() || c.den[0] != 1.0 {
                        return Err(err(
                            &f("den"),
                            "must be monic (leading coefficient 1)".into(),
                        ));
                    }
                    if c.num.len() > c.den.len() {
                        return Err(err(
                            &f("num"),
                            "the degree exceeds the denominator's (improper)".into(),
                        ));
                    }
                    if c.num.iter().chain(&c.den).any(|v| !v.is_finite()) {
                        return Err(err(
                            &f("num/den"),
                            "has a NaN or infinite coefficient".into(),
                        ));
                    }
                    if c.delay > 1 << 16 {
                        return Err(err(
                            &f("delay"),
                            format!("{} samples is not a plausible delay", c.delay),
                        ));
                    }
                }
                TargetForm::TransferFunction(raw.channel)
            }
            "markov" => {
                if !raw.channel.is_empty() {
                    return Err(err("channel", "given with form = \"markov\"".into()));
                }
                if raw.markov.is_empty() {
                    return Err(err("markov", "no Markov parameter given".into()));
                }
                let mut hs = Vec::with_capacity(raw.markov.len());
                for (i, h) in raw.markov.iter().enumerate() {
                    if h.len() != raw.outputs || h.iter().any(|r| r.len() != raw.inputs) {
                        return Err(err(
                            &format!("markov[{i}]"),
                            format!("must be {} rows of {} values", raw.outputs, raw.inputs),
                        ));
                    }
                    if h.iter().flatten().any(|v| !v.is_finite()) {
                        return Err(err(
                            &format!("markov[{i}]"),
                            "has a NaN or infinite value".into(),
                        ));
                    }
                    hs.push(DMatrix::from_fn(raw.outputs, raw.inputs, |r, c| h[r][c]));
                }
                if hs.iter().all(|h| h.iter().all(|v| *v == 0.0)) {
                    return Err(err("markov", "every Markov parameter is zero".into()));
                }
                TargetForm::Markov(hs)
            }
            other => {
                return Err(err(
                    "form",
                    format!("'{other}' is not \"transfer-function\" or \"markov\""),
                ));
            }
        };
        Ok(Self {
            sample_period: raw.sample_period,
            outputs: raw.outputs,
            inputs: raw.inputs,
            beta: raw.beta,
            source: raw.source,
            form,
        })
    }

    /// The file text (a `[target-model]` table) that [`TargetModel::parse`] reads back.
    pub fn to_toml(&self) -> String {
        let (form, channel, markov) = match &self.form {
            TargetForm::TransferFunction(ch) => ("transfer-function", ch.clone(), Vec::new()),
            TargetForm::Markov(hs) => (
                "markov",
                Vec::new(),
                hs.iter()
                    .map(|h| {
                        (0..h.nrows())
                            .map(|r| h.row(r).iter().copied().collect())
                            .collect()
                    })
                    .collect(),
            ),
        };
        let raw = RawFile {
            target_model: RawTarget {
                form: form.into(),
                sample_period: self.sample_period,
                outputs: self.outputs,
                inputs: self.inputs,
                beta: self.beta,
                source: self.source.clone(),
                channel,
                markov,
            },
        };
        toml::to_string(&raw).expect("a target model always serializes")
    }

    /// Writes the file.
    pub fn save(&self, path: &Path) -> Result<(), String> {
        std::fs::write(path, self.to_toml())
            .map_err(|e| format!("writing the target model {}: {e}", path.display()))
    }

    /// `G_f(e^{jθ})` of every channel on the grid `theta` (β and delays included).
    pub fn frf(&self, theta: &[f64]) -> Frf {
        let (p, m) = (self.outputs, self.inputs);
        let mut response = vec![vec![C64::new(0.0, 0.0); theta.len()]; p * m];
        for (k, &th) in theta.iter().enumerate() {
            let zinv = C64::from_polar(1.0, -th);
            match &self.form {
                TargetForm::TransferFunction(ch) => {
                    let z = zinv.inv();
                    for c in ch {
                        let g = horner(&c.num, z) / horner(&c.den, z);
                        response[c.output * m + c.input][k] =
                            g * zinv.powu(c.delay as u32) * self.beta;
                    }
                }
                TargetForm::Markov(hs) => {
                    for o in 0..p {
                        for i in 0..m {
                            let mut acc = C64::new(0.0, 0.0);
                            for h in hs.iter().rev() {
                                acc = acc * zinv + h[(o, i)];
                            }
                            response[o * m + i][k] = acc * self.beta;
                        }
                    }
                }
            }
        }
        Frf {
            ts: self.sample_period,
            theta: theta.to_vec(),
            n_outputs: p,
            n_inputs: m,
            response,
        }
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
    fn a_written_model_reads_back_unchanged() {
        let m = tf_model();
        let back = TargetModel::parse(&m.to_toml(), "mem").unwrap();
        assert_eq!(back, m);
        let mk = TargetModel {
            form: TargetForm::Markov(m.markov(40)),
            beta: 1.0,
            ..m.clone()
        };
        assert_eq!(TargetModel::parse(&mk.to_toml(), "mem").unwrap(), mk);
    }

    #[test]
    fn markov_parameters_and_response_agree_with_the_transfer_functions() {
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
        // The FIR form built from 400 Markov parameters has the same response (the poles
        // are well inside the unit circle, so the tail is negligible).
        let fir = TargetModel {
            form: TargetForm::Markov(m.markov(400)),
            beta: 1.0,
            ..m.clone()
        };
        let th = [0.01, 0.3, 1.0, 2.5];
        let (a, b) = (m.frf(&th), fir.frf(&th));
        for c in 0..2 {
            for k in 0..th.len() {
                assert!((a.response[c][k] - b.response[c][k]).norm() < 1e-9);
            }
        }
    }

    #[test]
    fn bad_files_are_refused_naming_the_field() {
        let good = tf_model().to_toml();
        let bad = |from: &str, to: &str| {
            let t = good.replacen(from, to, 1);
            assert_ne!(t, good, "{from}");
            TargetModel::parse(&t, "tm.toml").unwrap_err()
        };
        assert!(bad("beta = 0.8", "beta = 1.5").contains("target-model.beta"));
        assert!(bad("den = [1.0, -0.5]", "den = [2.0, -0.5]").contains("channel[0].den"));
        assert!(bad("input = 1", "input = 2").contains("channel[1].input"));
        assert!(bad("input = 1", "input = 0").contains("given twice"));
        assert!(bad("form = \"transfer-function\"", "form = \"ss\"").contains("target-model.form"));
        let e = TargetModel::parse("[other]\n", "tm.toml").unwrap_err();
        assert!(e.contains("tm.toml") && e.contains("[target-model]"), "{e}");
    }
}
