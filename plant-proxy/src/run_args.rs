//! The options of a plant process's `run` command, shared by every plant process of this
//! workspace (`plant-proxy run`, `plant-jack run`), and what they resolve to: the scenario
//! with `--duration` applied, the number of samples, the `[proxy]` table with `--mode`.

use crate::proxy_config::{Mode, ProxyConfig};
use crate::scenario::Scenario;
use std::path::PathBuf;

/// `run <scenario> [--mode …] [--steps N | --duration S] [--report out.json] [--quiet]`.
#[derive(clap::Args, Debug, Clone)]
pub struct RunArgs {
    /// Scenario TOML file (`[rig]`, `[plant]`, optional `[proxy]`; plant-jack also reads `[jack]`).
    pub scenario: PathBuf,
    /// Override proxy.mode.
    #[arg(long, value_parser = parse_mode)]
    pub mode: Option<Mode>,
    /// Number of samples (default: rig.duration / sample period).
    #[arg(long, conflicts_with = "duration")]
    pub steps: Option<u64>,
    /// Seconds of plant time (overrides rig.duration, with the same bounds).
    #[arg(long, allow_negative_numbers = true)]
    pub duration: Option<f64>,
    /// Write the run report as JSON.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Print less.
    #[arg(long)]
    pub quiet: bool,
}

/// `--mode`: `lockstep` or `real-time` (`realtime`).
pub fn parse_mode(s: &str) -> Result<Mode, String> {
    match s {
        "lockstep" => Ok(Mode::Lockstep),
        "real-time" | "realtime" => Ok(Mode::RealTime),
        _ => Err(format!("'{s}' is not lockstep or real-time")),
    }
}

/// What the options resolve to.
#[derive(Debug, Clone)]
pub struct ResolvedRun {
    /// The scenario, `--duration` applied.
    pub scenario: Scenario,
    /// Samples to run.
    pub steps: u64,
    /// The `[proxy]` table, `--mode` applied (and the checks that depend on the mode made
    /// for it).
    pub proxy: ProxyConfig,
    /// The scenario file's text.
    pub text: String,
}

impl RunArgs {
    /// Reads and checks the scenario as the options say; the message of a refusal names
    /// the file and the field.
    pub fn resolve(&self) -> Result<ResolvedRun, String> {
        let sc = crate::scenario::load(&self.scenario).map_err(|e| e.to_string())?;
        let sc = match self.duration {
            None => sc,
            Some(d) => sc.with_duration(d).map_err(|e| e.to_string())?,
        };
        let steps = sc.run_steps(self.steps).map_err(|e| e.to_string())?;
        let origin = self.scenario.display().to_string();
        let text = std::fs::read_to_string(&self.scenario).map_err(|e| format!("{origin}: {e}"))?;
        let proxy = ProxyConfig::parse_with_mode(&text, &origin, sc.plant.n_u(), self.mode)
            .map_err(|e| e.to_string())?;
        Ok(ResolvedRun {
            scenario: sc,
            steps,
            proxy,
            text,
        })
    }
}
