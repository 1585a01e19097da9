//! The plant process: the simulation as the I/O device of the plant side.
//!
//! plant-proxy is "simulated I/O + the plant side": [`SimIo`] implements
//! [`plant_side::PlantIo`] on a [`PlantSim`] (read = sample the simulation, with the
//! injected measurement faults; apply = advance it one period under the input, writing the
//! trace row), and [`run_plant`] connects a [`PlantSide`] with the `[proxy]` table's policy
//! and runs [`plant_side::run`]. What follows is the plant side's behaviour, as plant-proxy
//! configures it.
//!
//! At sample `k` the plant publishes `y_k`, `z_k`, `r_k` stamped with the sample time, and
//! applies an input for the period that starts at `k`: the service's actuation with
//! `seq = k` if it holds it at the application instant, else a **miss** resolved by
//! `proxy.late-policy` ([`plant_side::late_policy`]). Which input that is, is decided by the
//! plant's [`ActuationBook`](plant_side::actuation_book::ActuationBook), which keeps the actuations received ahead of their sample (a
//! service that sends ahead publishes the input for `k + 1` as soon as it has taken `y_k`
//! in), refuses late and invalid ones, and holds the newest plan.
//!
//! - **real-time mode**: samples are paced on `CLOCK_MONOTONIC` at `t_k = t_0 + kT`
//!   ([`SampleClock`](plant_side::sample_clock::SampleClock); `proxy.overrun` says what happens when the plant itself wakes more
//!   than a period late). The input for sample `k` is applied at `t_k + dT`
//!   (`proxy.deadline = d`, a fraction of the period, carried in the sample as
//!   `deadline_ns`). With `d > 0` the plant publishes at `t_k`, sleeps until the deadline and
//!   decides. With `d = 0` the input is latched at the sample clock, as a DAC driven by the
//!   ADC clock does: at `t_k` the plant decides the input for `k` from what it holds,
//!   then samples and publishes `M_k` (only a service that sends ahead can meet that). The
//!   simulation applies `u_k` over `[kT, (k+1)T)` as in the dissertation
//!   (`proxy.intersample = "ideal"`), or from `kT + dT` on, as the real hold would
//!   (`"at-deadline"`; the same for `d = 0`).
//! - **lockstep mode**: after publishing `M_k` the plant waits (on the service's event, up to
//!   `proxy.lockstep-timeout`) until the service has answered `M_k`: it holds a valid
//!   actuation with `reply_to ≥ k`, or, for an injected stall, the acknowledgement of `k`
//!   ([`ActuationBook::answers`](plant_side::actuation_book::ActuationBook::answers)). Then the input for `k` is the actuation with `seq = k` if
//!   the plant holds it (sent ahead during the previous step, or the answer itself), else a
//!   miss. The plant never publishes `M_{k+1}` before the service has answered (or
//!   acknowledged) `M_k`, so a run is as fast as possible and bit-for-bit deterministic for a
//!   seed, with compute-first and send-ahead services alike. `[proxy.faults] stalls` flags
//!   samples with `INJECTED_STALL` ([`crate::faults`]).
//!
//! Every measurement reports the period that ends at it: the input applied for sample
//! `k − 1` (`u_applied`), `PREVIOUS_ACTUATION_MISSED` when that was a miss, with
//! `PLAN_APPLIED` when a plan covered it, and `PLANT_SAFE_OUTPUT` while the watchdog holds the
//! safe output.
//!
//! A watchdog puts the plant into its safe output after `proxy.watchdog-periods`
//! consecutive misses (plan-covered or not), says so, removes the stale resources of dead
//! iceoryx2 nodes (so a restarted service can connect), and leaves the safe output on the
//! next valid actuation. In lockstep mode the plant does not wait for ever: when no service
//! has answered for `proxy.peer-timeout` after the watchdog tripped (the time a service is
//! given to connect at start-up), it gives up with [`PlantError::GaveUp`] (a non-zero exit
//! status).
//!
//! Only the service the plant connected to drives it: its publisher is pinned at connect
//! (`ipc_types::peer`), an actuation from any other publisher is refused and counted
//! ([`PlantReport::foreign_discarded`]), and a restarted service, which can only appear once
//! the old one's publisher is gone, is recognized and counted ([`PlantReport::new_services`]);
//! what the old one had sent is forgotten. `[proxy.faults]` also injects NaN, ±Inf and
//! out-of-range measurements at given samples, for testing the service's input validation.

pub use crate::faults::{Faults, Stall};
pub use crate::proxy_config::{Intersample, Mode, ProxyConfig, ProxyConfigError};
pub use plant_side::plant_side::trust_line;
pub use plant_side::{LatePolicy, Overrun, PlanFallback, PlantError, PlantReport};

use crate::scenario::Scenario;
use crate::sim::PlantSim;
use ipc_types::ChannelCounts;
use plant_side::{Input, PlantIo, PlantSide, PlantSideOptions, Sensors};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

/// Options of one plant run that do not belong in the scenario.
#[derive(Debug, Clone, Default)]
pub struct PlantRunOptions {
    /// Number of samples to run (default: the scenario's duration).
    pub steps: Option<u64>,
    /// Write a CSV trace (k, y, z, u applied, flags) here.
    pub trace: Option<PathBuf>,
    /// Print progress and events.
    pub verbose: bool,
}

struct Trace {
    out: std::io::BufWriter<std::fs::File>,
}

impl Trace {
    fn create(path: &Path, n_y: usize, n_z: usize, n_u: usize) -> Result<Self, PlantError> {
        let f = std::fs::File::create(path)
            .map_err(|e| PlantError::Io(format!("creating trace {}: {e}", path.display())))?;
        let mut out = std::io::BufWriter::new(f);
        let mut header = String::from("k,t");
        for i in 0..n_y {
            header += &format!(",y{i}");
        }
        for i in 0..n_z {
            header += &format!(",z{i}");
        }
        for i in 0..n_u {
            header += &format!(",u{i}");
        }
        header += ",flags,actuation_status\n";
        out.write_all(header.as_bytes())
            .map_err(|e| PlantError::Io(e.to_string()))?;
        Ok(Self { out })
    }

    /// One row: sample `k` at time `t`, the signals `[y, z, u]`, the flags and status.
    fn row(&mut self, k: u64, t: f64, [y, z, u]: [&[f64]; 3], flags: u32, status: u32) {
        let _ = write!(self.out, "{k},{t}");
        for v in y.iter().chain(z).chain(u) {
            let _ = write!(self.out, ",{v:e}");
        }
        let _ = writeln!(self.out, ",{flags},{status}");
    }
}

/// The simulation as a plant's I/O device: reading samples it (with `[proxy.faults]`'s
/// measurement faults in `y_0`), applying advances it one period under the input (and
/// writes the trace row of the sample).
pub struct SimIo<'a> {
    sim: PlantSim,
    faults: &'a Faults,
    trace: Option<Trace>,
    /// The sensor values of the latest sample, for the trace.
    y: Vec<f64>,
    z: Vec<f64>,
}

impl<'a> SimIo<'a> {
    /// The device of `sim`, injecting `faults`, tracing to `trace` (a CSV file) if given.
    pub fn new(
        sim: PlantSim,
        faults: &'a Faults,
        trace: Option<&Path>,
    ) -> Result<Self, PlantError> {
        let (n_y, n_z, n_u) = (sim.n_y(), sim.n_z(), sim.n_u());
        let trace = match trace {
            Some(p) => Some(Trace::create(p, n_y, n_z, n_u)?),
            None => None,
        };
        Ok(Self {
            sim,
            faults,
            trace,
            y: vec![0.0; n_y],
            z: vec![0.0; n_z],
        })
    }

    /// Flushes the trace.
    pub fn finish(self) -> Result<(), PlantError> {
        match self.trace {
            Some(mut t) => t
                .out
                .flush()
                .map_err(|e| PlantError::Io(format!("writing the trace: {e}"))),
            None => Ok(()),
        }
    }
}

impl PlantIo for SimIo<'_> {
    type Error = String;

    fn read(&mut self, k: u64, s: Sensors<'_>) -> Result<(), String> {
        self.sim.sample(s.y, s.z, s.r).map_err(|e| e.to_string())?;
        if let Some(v) = self.faults.at(k)
            && let Some(y0) = s.y.first_mut()
        {
            *y0 = v;
        }
        self.y.copy_from_slice(s.y);
        self.z.copy_from_slice(s.z);
        Ok(())
    }

    fn apply(&mut self, k: u64, input: &Input) -> Result<(), String> {
        let n_u = self.sim.n_u();
        if let Some(t) = self.trace.as_mut() {
            t.row(
                k,
                self.sim.time(),
                [&self.y, &self.z, &input.u[..n_u]],
                input.published_flags,
                input.status.unwrap_or(u32::MAX),
            );
        }
        self.sim.advance(&input.u[..n_u]).map_err(|e| e.to_string())
    }

    fn stalled(&self, k: u64) -> bool {
        self.faults.stalled(k)
    }

    fn lost(&self, k: u64) -> bool {
        self.faults.lost(k)
    }
}

/// Runs the plant of `scenario` against the service until `steps` samples are done or
/// `shutdown` is set.
pub fn run_plant(
    scenario: &Scenario,
    proxy: &ProxyConfig,
    opts: &PlantRunOptions,
    shutdown: &AtomicBool,
) -> Result<PlantReport, PlantError> {
    proxy
        .check_mode(&format!("rig '{}'", scenario.rig.name))
        .map_err(|e| PlantError::Config(e.0))?;
    let ts = scenario.rig.sample_period;
    let period_ns = (ts * 1e9).round() as u64;
    let mut sim =
        PlantSim::new(&scenario.plant, ts).map_err(|e| PlantError::Config(e.to_string()))?;
    // At deadline 0 (or 1) the real hold and the ideal one are the same.
    if proxy.intersample == Intersample::AtDeadline
        && proxy.plant.deadline > 0.0
        && proxy.plant.deadline < 1.0
    {
        sim.set_apply_offset(Some(proxy.plant.deadline))
            .map_err(|e| PlantError::Config(e.to_string()))?;
    }
    let (n_y, n_z, n_r, n_u) = (sim.n_y(), sim.n_z(), sim.n_r(), sim.n_u());
    let counts = ChannelCounts::new(n_y, n_z, n_r, n_u).map_err(PlantError::Config)?;
    if proxy.plant.safe_input.len() != n_u {
        return Err(PlantError::Config(format!(
            "proxy.safe-input needs {n_u} values"
        )));
    }
    let steps = opts
        .steps
        .unwrap_or_else(|| (scenario.rig.duration / ts).round() as u64);
    let mut io = SimIo::new(sim, &proxy.faults, opts.trace.as_deref())?;
    let policy = proxy.plant.clone();
    let side_opts = PlantSideOptions {
        label: "plant-proxy",
        node_name: "adaptive-rig-plant",
        verbose: opts.verbose,
        shutdown: Some(shutdown),
    };
    let mut side = PlantSide::connect(&scenario.rig.name, counts, period_ns, policy, side_opts)?;
    side.report_mut().faults_injected = proxy.faults.total() as u64;
    if opts.verbose {
        eprintln!(
            "[plant-proxy] connected; {} steps at {:.1} Hz in {:?} mode, inputs applied {}, late policy {}",
            steps,
            1.0 / ts,
            proxy.plant.mode,
            proxy.applies().name(),
            proxy.describe_late_policy()
        );
    }
    plant_side::run(&mut side, &mut io, steps, Some(shutdown))?;
    io.finish()?;
    Ok(side.finish())
}
