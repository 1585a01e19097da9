//! The whole scenario, both halves, validated without starting anything (`rig check`):
//! the service's tables ([`ServiceConfig`], as `service check` reads them) and, when the
//! file has a `[plant]` table, the plant half as plant-proxy reads it (its scenario
//! loader, the exact discretization it runs and its `[proxy]` table), and the two halves
//! against each other: the channel counts, a deadline at the sample instant (`proxy.deadline
//! = 0`) only with a service that sends ahead, the late policy `"plan"` only with plans.
//! A scenario without `[plant]` is for a hardware plant: only the service half is checked.
//! This check lives in the tools because it needs both halves: the service links no
//! simulator.

use plant_proxy::runtime::ProxyConfig;
use plant_proxy::scenario::{Scenario, ScenarioError};
use plant_proxy::sim::PlantSim;
use service::config::{ConfigError, ServiceConfig};
use std::path::Path;

/// A scenario whose both halves were accepted.
#[derive(Debug)]
pub struct ScenarioCheck {
    /// The service half.
    pub service: ServiceConfig,
    /// The plant half, when the file has a `[plant]` table.
    pub plant: Option<PlantHalf>,
}

/// The plant half of a scenario, as plant-proxy reads it.
#[derive(Debug)]
pub struct PlantHalf {
    /// The `[rig]` and `[plant]` tables.
    pub scenario: Scenario,
    /// The states of the discretized simulation (plant, tones and filters).
    pub states: usize,
    /// The `[proxy]` table.
    pub proxy: ProxyConfig,
}

impl ScenarioCheck {
    /// Reads and validates the scenario at `path` (with the `[controller]` and `[log]`
    /// tables of `controller_file`, if given, for the service half).
    ///
    /// # Errors
    ///
    /// The first refusal of either half, naming the file and the field.
    pub fn load(path: &Path, controller_file: Option<&Path>) -> Result<Self, ConfigError> {
        let service = ServiceConfig::load_scenario(path, controller_file)?;
        let origin = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| ConfigError {
            file: origin.clone(),
            field: String::new(),
            message: format!("cannot read the file: {e}"),
        })?;
        let plant = plant_half(&text, &origin, &service)?;
        Ok(Self { service, plant })
    }

    /// [`ScenarioCheck::load`] of the text of a scenario file; `origin` names it.
    ///
    /// # Errors
    ///
    /// As [`ScenarioCheck::load`].
    pub fn parse(text: &str, origin: &str) -> Result<Self, ConfigError> {
        let service = ServiceConfig::parse(text, origin)?;
        let plant = plant_half(text, origin, &service)?;
        Ok(Self { service, plant })
    }

    /// One line: the rig, its rate, the channels, the controller and the plant.
    pub fn summary(&self) -> String {
        let mut s = self.service.summary();
        match &self.plant {
            Some(p) => s.push_str(&format!(
                "; plant {} with {} states, {} s, proxy {:?}",
                p.scenario.plant.kind.name(),
                p.states,
                p.scenario.rig.duration,
                p.proxy.plant.mode
            )),
            None => s.push_str("; no [plant] table: the plant half is a hardware plant's"),
        }
        s
    }
}

/// The plant half of the text, when it has a `[plant]` table, checked against the
/// service half.
fn plant_half(
    text: &str,
    origin: &str,
    service: &ServiceConfig,
) -> Result<Option<PlantHalf>, ConfigError> {
    let table: toml::Table = toml::from_str(text).map_err(|e| ConfigError {
        file: origin.to_string(),
        field: String::new(),
        message: format!("not valid TOML: {e}"),
    })?;
    if !table.contains_key("plant") {
        return Ok(None);
    }
    let err = |field: &str, message: String| ConfigError {
        file: origin.to_string(),
        field: field.to_string(),
        message,
    };
    let scenario = plant_proxy::scenario::parse(text, origin).map_err(|e| match e {
        ScenarioError::Field { field, problem, .. } => err(&field, problem),
        ScenarioError::Io { message, .. } => err("", format!("cannot read the file: {message}")),
        ScenarioError::Toml { message, .. } => err("", format!("not valid TOML: {message}")),
    })?;
    let p = &scenario.plant;
    let plant_counts = [p.n_y(), p.n_z(), p.n_r(), p.n_u()];
    let c = service.counts;
    let service_counts = [c.n_y, c.n_z, c.n_r, c.n_u].map(|n| n as usize);
    if plant_counts != service_counts {
        return Err(err(
            "service.channels",
            format!(
                "y, z, r, u = {service_counts:?}, but [plant] has {plant_counts:?}: the \
                 service would be refused at connect"
            ),
        ));
    }
    let sim = PlantSim::new(p, scenario.rig.sample_period)
        .map_err(|e| err("plant", format!("cannot be discretized: {e}")))?;
    let proxy = ProxyConfig::parse(text, origin, p.n_u()).map_err(|e| {
        // The message is "<origin>: field '<field>': <what>" or "<origin>: <what>".
        let m = e.0.strip_prefix(&format!("{origin}: ")).unwrap_or(&e.0);
        match m
            .strip_prefix("field '")
            .and_then(|rest| rest.split_once("': "))
        {
            Some((field, what)) => err(field, what.to_string()),
            None => err("proxy", m.to_string()),
        }
    })?;
    if proxy.applies() == ipc_types::ports::Applies::AtSample
        && service.answer.timing != ipc_types::Timing::SendAhead
    {
        return Err(err(
            "proxy.deadline",
            format!(
                "0 applies each input at its sample instant, which only a service that sends \
                 ahead can meet; this service answers {} (service.timing = \"send-ahead\", \
                 or a deadline inside the period)",
                service.answer.timing.name()
            ),
        ));
    }
    if proxy.plant.late_policy == plant_proxy::runtime::LatePolicy::Plan
        && service.answer.plan_length == 0
    {
        return Err(err(
            "proxy.late-policy",
            "\"plan\" needs plans, and this service sends none (service.plan-length = 0): \
             every miss would fall back to proxy.plan-fallback"
                .into(),
        ));
    }
    Ok(Some(PlantHalf {
        states: sim.n_plant_states() + sim.n_exosystem_states(),
        scenario,
        proxy,
    }))
}
