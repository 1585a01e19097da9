//! The tables of the discrete-time plants and of the generated command:
//! `[plant.discrete]`, `[plant.mrac-example]`, `[plant.input-disturbance]` and the table
//! form of `plant.command` (see [`crate::discrete`], [`crate::mrac_examples`],
//! [`crate::command`]). Every error names the file and the field.

use super::{Cx, MAX_TONES, ScenarioError, number};
use crate::command::{Command, FOUR_HARMONIC, TWO_HARMONIC};
use crate::discrete::{DiscreteTf, MAX_COEFFICIENTS};
use crate::harmonic::{Harmonic, MAX_FREQUENCY_RAD_STEP};
use crate::mrac_examples::{ExampleParams, MracExample, MracExampleError};
use serde::Deserialize;

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawDiscrete {
    num: Option<Vec<f64>>,
    den: Option<Vec<f64>>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawMracExample {
    example: Option<i64>,
    rho: Option<f64>,
    nu: Option<f64>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawInputDisturbance {
    harmonics: Option<Vec<RawHarmonic>>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawHarmonic {
    amplitude: Option<f64>,
    frequency_rad_step: Option<f64>,
    phase_rad: Option<f64>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawCommandTable {
    kind: Option<String>,
    amplitude: Option<f64>,
    start: Option<u64>,
    preset: Option<String>,
    terms: Option<Vec<RawHarmonic>>,
}

/// `[plant.discrete]`: `num`, `den` in ascending powers of `q⁻¹`.
pub(super) fn discrete_tf(cx: &Cx<'_>, raw: RawDiscrete) -> Result<DiscreteTf, ScenarioError> {
    let coeffs = |v: Option<Vec<f64>>, key: &str| -> Result<Vec<f64>, ScenarioError> {
        let f = format!("plant.discrete.{key}");
        let v = cx.required(v, &f)?;
        cx.count(v.len(), 0, MAX_COEFFICIENTS, &f, "coefficients")?;
        Ok(v)
    };
    let num = coeffs(raw.num, "num")?;
    let den = coeffs(raw.den, "den")?;
    DiscreteTf::new(num, den)
        .map_err(|e| cx.err(format!("plant.discrete.{}", e.key()), e.to_string()))
}

/// `[plant.mrac-example]`: `example = 1 | 2`, `rho`, `nu`.
pub(super) fn mrac_example(
    cx: &Cx<'_>,
    raw: RawMracExample,
) -> Result<(DiscreteTf, ExampleParams), ScenarioError> {
    let f = "plant.mrac-example.example";
    let n = cx.required(raw.example, f)?;
    let example = MracExample::from_number(n).ok_or_else(|| {
        cx.err(
            f,
            format!("{n} is not 1 (the minimum-phase plant (4.83)) or 2 (the nonminimum-phase plant (4.88))"),
        )
    })?;
    let rho = cx.required(raw.rho, "plant.mrac-example.rho")?;
    let nu = cx.required(raw.nu, "plant.mrac-example.nu")?;
    let tf = example.plant(rho, nu).map_err(|e| match e {
        MracExampleError::Rho(_) => cx.err("plant.mrac-example.rho", e.to_string()),
        MracExampleError::Nu(_) => cx.err("plant.mrac-example.nu", e.to_string()),
        MracExampleError::Tf(_) => cx.err("plant.mrac-example", e.to_string()),
    })?;
    Ok((tf, ExampleParams { example, rho, nu }))
}

/// `[plant.input-disturbance]`: `harmonics = [ { amplitude, frequency-rad-step, phase-rad } ]`.
pub(super) fn input_disturbance(
    cx: &Cx<'_>,
    raw: RawInputDisturbance,
) -> Result<Vec<Harmonic>, ScenarioError> {
    let f = "plant.input-disturbance.harmonics";
    let terms = cx.required(raw.harmonics, f)?;
    cx.count(terms.len(), 1, MAX_TONES, f, "harmonics")?;
    harmonics(cx, terms, f)
}

fn harmonics(
    cx: &Cx<'_>,
    terms: Vec<RawHarmonic>,
    field: &str,
) -> Result<Vec<Harmonic>, ScenarioError> {
    let mut out = Vec::with_capacity(terms.len());
    for (i, t) in terms.into_iter().enumerate() {
        let f = |k: &str| format!("{field}[{i}].{k}");
        let amplitude = cx.finite(cx.required(t.amplitude, &f("amplitude"))?, &f("amplitude"))?;
        let fw = f("frequency-rad-step");
        let omega = cx.required(t.frequency_rad_step, &fw)?;
        if !(omega.is_finite() && (0.0..=MAX_FREQUENCY_RAD_STEP).contains(&omega)) {
            return Err(cx.err(
                fw,
                format!("{omega} rad/step is not in [0, π] (π rad/step is the Nyquist frequency)"),
            ));
        }
        let phase = cx.finite(t.phase_rad.unwrap_or(0.0), &f("phase-rad"))?;
        out.push(Harmonic {
            amplitude,
            omega,
            phase,
        });
    }
    Ok(out)
}

/// `plant.command` given `plant.commands` (already bounded): an array (the constant
/// command, `commands` entries, default zeros) or a table (a generated command, one
/// channel).
pub(super) fn command(
    cx: &Cx<'_>,
    raw: Option<toml::Value>,
    commands: Option<usize>,
) -> Result<Command, ScenarioError> {
    let table = match raw {
        Some(toml::Value::Table(t)) => t,
        other => {
            let n_r = commands.unwrap_or(0);
            let values = match other {
                None => vec![0.0; n_r],
                Some(toml::Value::Array(a)) => {
                    let xs: Option<Vec<f64>> = a.iter().map(number).collect();
                    xs.ok_or_else(|| {
                        cx.err(
                            "plant.command",
                            "must be an array of numbers (a constant command) or a table \
                             (a generated command, [plant.command])",
                        )
                    })?
                }
                Some(_) => {
                    return Err(cx.err(
                        "plant.command",
                        "must be an array of numbers (a constant command) or a table \
                         (a generated command, [plant.command])",
                    ));
                }
            };
            cx.vector(
                &values,
                n_r,
                "plant.command",
                "command channel (plant.commands)",
            )?;
            return Ok(Command::Constant(values));
        }
    };
    if let Some(n) = commands.filter(|&n| n != 1) {
        return Err(cx.err(
            "plant.commands",
            format!(
                "{n}, but a generated command ([plant.command]) has one channel: give 1 or omit it"
            ),
        ));
    }
    let raw: RawCommandTable = toml::Value::Table(table)
        .try_into()
        .map_err(|e: toml::de::Error| cx.err("plant.command", e.message().to_string()))?;
    let kind = cx.required(raw.kind, "plant.command.kind")?;
    let refuse = |given: bool, key: &str, why: &str| {
        if given {
            Err(cx.err(format!("plant.command.{key}"), why.to_string()))
        } else {
            Ok(())
        }
    };
    match kind.as_str() {
        "step" => {
            let why = "is for kind = \"harmonics\", not a step";
            refuse(raw.preset.is_some(), "preset", why)?;
            refuse(raw.terms.is_some(), "terms", why)?;
            let amplitude = cx.finite(raw.amplitude.unwrap_or(1.0), "plant.command.amplitude")?;
            Ok(Command::Step {
                amplitude,
                start: raw.start.unwrap_or(0),
            })
        }
        "harmonics" => {
            let why = "is for kind = \"step\", not harmonics";
            refuse(raw.amplitude.is_some(), "amplitude", why)?;
            refuse(raw.start.is_some(), "start", why)?;
            match (raw.preset, raw.terms) {
                (Some(p), None) => match p.as_str() {
                    "two-harmonic" => Ok(Command::harmonics_at(&TWO_HARMONIC)),
                    "four-harmonic" => Ok(Command::harmonics_at(&FOUR_HARMONIC)),
                    other => Err(cx.err(
                        "plant.command.preset",
                        format!("'{other}' is not \"two-harmonic\" or \"four-harmonic\""),
                    )),
                },
                (None, Some(terms)) => {
                    let f = "plant.command.terms";
                    cx.count(terms.len(), 1, MAX_TONES, f, "terms")?;
                    Ok(Command::Harmonics(harmonics(cx, terms, f)?))
                }
                (Some(_), Some(_)) => {
                    Err(cx.err("plant.command.preset", "give preset or terms, not both"))
                }
                (None, None) => Err(cx.err(
                    "plant.command.preset",
                    "is missing (or give terms = [ { amplitude, frequency-rad-step, phase-rad } ])",
                )),
            }
        }
        other => Err(cx.err(
            "plant.command.kind",
            format!("'{other}' is not \"step\" or \"harmonics\""),
        )),
    }
}
