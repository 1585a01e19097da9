//! The target-model file: the `[target-model]` table that the design tools write and
//! RCAC's configuration reads (the format is documented in `control::target`).
//!
//! [`TargetModelFile`] adds reading and writing to [`TargetModel`]; the values are checked
//! by [`TargetModel::validate`], and errors name the file and the field. A Markov model
//! has at most 4096 parameters, a transfer-function channel an order of at most 64.

use super::bounds::{MAX_TARGET_MARKOV, MAX_TARGET_TF_ORDER};
use control::target::{TargetChannel, TargetForm, TargetModel};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// One `[[target-model.channel]]` entry as written in the file.
#[derive(Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawChannel {
    output: usize,
    input: usize,
    delay: usize,
    num: Vec<f64>,
    den: Vec<f64>,
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
    channel: Vec<RawChannel>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    markov: Vec<Vec<Vec<f64>>>,
}

#[derive(Serialize, Deserialize)]
struct RawFile {
    #[serde(rename = "target-model")]
    target_model: RawTarget,
}

/// Reading and writing a [`TargetModel`] as a file.
pub trait TargetModelFile: Sized {
    /// Reads a target-model file.
    fn load(path: &Path) -> Result<Self, String>;
    /// Parses the text of a target-model file (a `[target-model]` table); `origin` names
    /// it in errors.
    fn parse(text: &str, origin: &str) -> Result<Self, String>;
    /// Validates a `[target-model]` table already read from TOML (RCAC's configuration
    /// may hold it inline); `origin` names the file in errors.
    fn from_value(value: toml::Value, origin: &str) -> Result<Self, String>;
    /// The file text (a `[target-model]` table) that [`TargetModelFile::parse`] reads back.
    fn to_toml(&self) -> String;
    /// Writes the file.
    fn save(&self, path: &Path) -> Result<(), String>;
}

impl TargetModelFile for TargetModel {
    fn load(path: &Path) -> Result<Self, String> {
        let origin = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|e| format!("{origin}: cannot read the target model: {e}"))?;
        Self::parse(&text, &origin)
    }

    fn parse(text: &str, origin: &str) -> Result<Self, String> {
        let table: toml::Table =
            toml::from_str(text).map_err(|e| format!("{origin}: not valid TOML: {e}"))?;
        let value = table
            .get("target-model")
            .ok_or_else(|| format!("{origin}: the [target-model] table is missing"))?;
        Self::from_value(value.clone(), origin)
    }

    fn from_value(value: toml::Value, origin: &str) -> Result<Self, String> {
        read_table(value).map_err(|e| format!("{origin}: {}: {}", e.field, e.message))
    }

    fn to_toml(&self) -> String {
        let (form, channel, markov) = match &self.form {
            TargetForm::TransferFunction(ch) => (
                "transfer-function",
                ch.iter()
                    .map(|c| RawChannel {
                        output: c.output,
                        input: c.input,
                        delay: c.delay,
                        num: c.num.clone(),
                        den: c.den.clone(),
                    })
                    .collect(),
                Vec::new(),
            ),
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

    fn save(&self, path: &Path) -> Result<(), String> {
        std::fs::write(path, self.to_toml())
            .map_err(|e| format!("writing the target model {}: {e}", path.display()))
    }
}

/// A refused `[target-model]` table: the dotted field (`target-model.channel[0].den`, or
/// `target-model` for the table) and why.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct TableError {
    /// The field path from `target-model` on.
    pub field: String,
    /// Why it is refused.
    pub message: String,
}

/// Reads and validates a `[target-model]` table (the RCAC configuration may hold it
/// inline, under `controller.`).
pub(super) fn read_table(value: toml::Value) -> Result<TargetModel, TableError> {
    let raw: RawTarget = value.try_into().map_err(|e: toml::de::Error| TableError {
        field: "target-model".into(),
        message: e.to_string(),
    })?;
    let err = |field: &str, m: &str| TableError {
        field: format!("target-model.{field}"),
        message: m.to_string(),
    };
    if raw.markov.len() > MAX_TARGET_MARKOV {
        let m = format!(
            "has {} Markov parameters, at most {MAX_TARGET_MARKOV}",
            raw.markov.len()
        );
        return Err(err("markov", &m));
    }
    for (i, c) in raw.channel.iter().enumerate() {
        for (key, len) in [("num", c.num.len()), ("den", c.den.len())] {
            if len > MAX_TARGET_TF_ORDER + 1 {
                let m = format!(
                    "has {len} coefficients, at most {} (order {MAX_TARGET_TF_ORDER})",
                    MAX_TARGET_TF_ORDER + 1
                );
                return Err(err(&format!("channel[{i}].{key}"), &m));
            }
        }
    }
    let form = match raw.form.as_str() {
        "transfer-function" => {
            if !raw.markov.is_empty() {
                return Err(err("markov", "given with form = \"transfer-function\""));
            }
            TargetForm::TransferFunction(
                raw.channel
                    .into_iter()
                    .map(|c| TargetChannel {
                        output: c.output,
                        input: c.input,
                        delay: c.delay,
                        num: c.num,
                        den: c.den,
                    })
                    .collect(),
            )
        }
        "markov" => {
            if !raw.channel.is_empty() {
                return Err(err("channel", "given with form = \"markov\""));
            }
            let mut hs = Vec::with_capacity(raw.markov.len());
            for (i, h) in raw.markov.iter().enumerate() {
                if h.len() != raw.outputs || h.iter().any(|r| r.len() != raw.inputs) {
                    return Err(err(
                        &format!("markov[{i}]"),
                        &format!("must be {} rows of {} values", raw.outputs, raw.inputs),
                    ));
                }
                hs.push(DMatrix::from_fn(raw.outputs, raw.inputs, |r, c| h[r][c]));
            }
            TargetForm::Markov(hs)
        }
        other => {
            return Err(err(
                "form",
                &format!("'{other}' is not \"transfer-function\" or \"markov\""),
            ));
        }
    };
    let model = TargetModel {
        sample_period: raw.sample_period,
        outputs: raw.outputs,
        inputs: raw.inputs,
        beta: raw.beta,
        source: raw.source,
        form,
    };
    model.validate().map_err(|e| err(&e.path(), &e.message))?;
    Ok(model)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shared test fixture, as written in its file.
    const FIXTURE: &str = include_str!(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../tests/fixtures/target-model/two-input-transfer-function.toml"
    ));

    fn tf_model() -> TargetModel {
        TargetModel::parse(FIXTURE, "two-input-transfer-function.toml").unwrap()
    }

    #[test]
    fn the_fixture_reads_as_written() {
        let m = tf_model();
        assert_eq!(
            (m.sample_period, m.outputs, m.inputs, m.beta),
            (1.25e-4, 1, 2, 0.8)
        );
        let TargetForm::TransferFunction(ch) = &m.form else {
            panic!("not a transfer-function model");
        };
        let delays: Vec<usize> = ch.iter().map(|c| c.delay).collect();
        assert_eq!(delays, [9, 16]);
        assert_eq!(ch[1].den, [1.0, -1.2, 0.5]);
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
