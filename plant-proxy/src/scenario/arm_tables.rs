//! The tables of the sampling-arm plant (`kind = "sampling-arm"`, [`crate::arm`]):
//! `[plant.sampling-arm]`, `[plant.surface]`, `[plant.guidance]`,
//! `[plant.second-sampling]` (with its `surface`) and `[plant.integrator]`. Every field
//! but the surface's model and coefficients has the chapter's value as its default;
//! every error names the file and the field.

use super::{Cx, ScenarioError};
use crate::arm::{
    ArmPlantParams, ContactModel, GuidanceParams, IntegratorParams, SecondSampling, Surface,
    contact,
};
use rig_scenario::spacecraft::{self, SpacecraftTable};
use serde::Deserialize;

/// `[plant.sampling-arm]`: the spacecraft's fields ([`SpacecraftTable`], the schema's) and
/// where the arm starts.
#[derive(Default)]
pub(super) struct RawSamplingArm {
    spacecraft: SpacecraftTable,
    start: RawStart,
}

/// The fields of `[plant.sampling-arm]` that are the plant's own: the initial angles, the
/// sampler's height and the descent speed.
#[derive(Deserialize, Default)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawStart {
    theta1: Option<f64>,
    theta2: Option<f64>,
    initial_height: Option<f64>,
    descent_speed: Option<f64>,
}

/// The keys of [`RawStart`].
const START_KEYS: [&str; 4] = ["theta1", "theta2", "initial-height", "descent-speed"];

impl<'de> Deserialize<'de> for RawSamplingArm {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        let mut spacecraft = toml::Table::deserialize(d)?;
        let mut start = toml::Table::new();
        for k in START_KEYS {
            if let Some(v) = spacecraft.remove(k) {
                start.insert(k.to_string(), v);
            }
        }
        if let Some(k) = spacecraft
            .keys()
            .find(|k| !spacecraft::KEYS.contains(&k.as_str()))
        {
            return Err(D::Error::custom(format!(
                "unknown field `{k}`, expected one of {}",
                spacecraft::KEYS
                    .iter()
                    .chain(&START_KEYS)
                    .map(|k| format!("`{k}`"))
                    .collect::<Vec<_>>()
                    .join(", ")
            )));
        }
        Ok(Self {
            spacecraft: spacecraft.try_into().map_err(D::Error::custom)?,
            start: start.try_into().map_err(D::Error::custom)?,
        })
    }
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawSurface {
    model: Option<String>,
    stiffness: Option<f64>,
    damping: Option<f64>,
    restitution: Option<f64>,
    friction: Option<f64>,
    friction_regularization: Option<f64>,
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawGuidance {
    force_set_point: Option<f64>,
    contact_duration: Option<f64>,
    ascent_speed: Option<f64>,
    thrust_limit: Option<f64>,
    loop_gain: Option<f64>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawSecondSampling {
    sample_mass: Option<f64>,
    ascent_duration: Option<f64>,
    descent_speed: Option<f64>,
    surface: Option<RawSurface>,
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawIntegrator {
    rtol: Option<f64>,
    atol: Option<f64>,
    max_steps_per_sample: Option<u64>,
    event_time_tolerance: Option<f64>,
}

/// The tables of a sampling-arm plant, by their name under `plant.`.
pub(super) const TABLES: [&str; 5] = [
    "sampling-arm",
    "surface",
    "guidance",
    "second-sampling",
    "integrator",
];

/// The raw tables of a sampling-arm plant, as read from `[plant]`.
pub(super) struct RawArmTables {
    pub sampling_arm: Option<RawSamplingArm>,
    pub surface: Option<RawSurface>,
    pub guidance: Option<RawGuidance>,
    pub second_sampling: Option<RawSecondSampling>,
    pub integrator: Option<RawIntegrator>,
}

impl RawArmTables {
    /// The tables that are present, by their name under `plant.`.
    pub fn present(&self) -> [(&'static str, bool); 5] {
        let [a, s, g, ss, i] = TABLES;
        [
            (a, self.sampling_arm.is_some()),
            (s, self.surface.is_some()),
            (g, self.guidance.is_some()),
            (ss, self.second_sampling.is_some()),
            (i, self.integrator.is_some()),
        ]
    }
}

/// A surface table at `prefix` (`plant.surface` or `plant.second-sampling.surface`).
fn surface(cx: &Cx<'_>, raw: RawSurface, prefix: &str) -> Result<Surface, ScenarioError> {
    let f = |k: &str| format!("{prefix}.{k}");
    let name = cx.required(raw.model, &f("model"))?;
    let stiffness = cx.required(raw.stiffness, &f("stiffness"))?;
    let model = match name.as_str() {
        "kelvin-voigt" => {
            if raw.restitution.is_some() {
                return Err(cx.err(
                    f("restitution"),
                    "is for model = \"hunt-crossley\"; Kelvin–Voigt (7.27) takes damping",
                ));
            }
            let damping = cx.required(raw.damping, &f("damping"))?;
            ContactModel::kelvin_voigt(stiffness, damping)
        }
        "hunt-crossley" => {
            if raw.damping.is_some() {
                return Err(cx.err(
                    f("damping"),
                    "is for model = \"kelvin-voigt\"; Hunt–Crossley (7.28) takes restitution",
                ));
            }
            let restitution = cx.required(raw.restitution, &f("restitution"))?;
            ContactModel::hunt_crossley(stiffness, restitution)
        }
        other => {
            return Err(cx.err(
                f("model"),
                format!("'{other}' is not \"kelvin-voigt\" (7.27) or \"hunt-crossley\" (7.28)"),
            ));
        }
    }
    .map_err(|e| cx.err(f(e.field), e.problem))?;
    Ok(Surface {
        model,
        friction: raw.friction.unwrap_or(contact::CHAPTER_FRICTION),
        friction_regularization: raw
            .friction_regularization
            .unwrap_or(contact::CHAPTER_FRICTION_REGULARIZATION),
    })
}

/// The validated parameters of a sampling-arm plant from its tables.
pub(super) fn arm_params(cx: &Cx<'_>, raw: RawArmTables) -> Result<ArmPlantParams, ScenarioError> {
    let s = cx.required(raw.surface, "plant.surface")?;
    let mut p = ArmPlantParams::chapter(ContactModel::KelvinVoigt {
        stiffness: 1.0,
        damping: 0.0,
    });
    p.surface = surface(cx, s, "plant.surface")?;
    let a = raw.sampling_arm.unwrap_or_default();
    p.spacecraft = a.spacecraft.params();
    let start = a.start;
    for (dst, v) in [
        (&mut p.theta1, start.theta1),
        (&mut p.theta2, start.theta2),
        (&mut p.initial_height, start.initial_height),
        (&mut p.descent_speed, start.descent_speed),
    ] {
        if let Some(v) = v {
            *dst = v;
        }
    }
    let g = raw.guidance.unwrap_or_default();
    let d = GuidanceParams::DEFAULT;
    p.guidance = GuidanceParams {
        force_set_point: g.force_set_point.unwrap_or(d.force_set_point),
        contact_duration: g.contact_duration.unwrap_or(d.contact_duration),
        ascent_speed: g.ascent_speed.unwrap_or(d.ascent_speed),
        thrust_limit: g.thrust_limit.unwrap_or(d.thrust_limit),
        loop_gain: g.loop_gain.unwrap_or(d.loop_gain),
    };
    if let Some(s2) = raw.second_sampling {
        let prefix = "plant.second-sampling.surface";
        let surface = surface(cx, cx.required(s2.surface, prefix)?, prefix)?;
        let d = SecondSampling::chapter(surface);
        p.second = Some(SecondSampling {
            sample_mass: s2.sample_mass.unwrap_or(d.sample_mass),
            ascent_duration: s2.ascent_duration.unwrap_or(d.ascent_duration),
            descent_speed: s2.descent_speed.unwrap_or(d.descent_speed),
            surface,
        });
    }
    let i = raw.integrator.unwrap_or_default();
    let d = IntegratorParams::DEFAULT;
    p.integrator = IntegratorParams {
        rtol: i.rtol.unwrap_or(d.rtol),
        atol: i.atol.unwrap_or(d.atol),
        max_steps_per_sample: i.max_steps_per_sample.unwrap_or(d.max_steps_per_sample),
        event_time_tolerance: i.event_time_tolerance.unwrap_or(d.event_time_tolerance),
    };
    p.validate()
        .map_err(|e| cx.err(format!("plant.{}", e.field), e.problem))?;
    Ok(p)
}
