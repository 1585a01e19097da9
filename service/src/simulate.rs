//! Offline closed loop: a controller of the service against plant-proxy's simulated plant
//! in one process, in lockstep, for studies and design checks.
//!
//! This is the loop of Figure 3.1 of the dissertation with the sample-and-hold timing of
//! the service contract: at sample `k` the plant is sampled (`y_k`, `z_k`, `r_k`), the
//! controller step computes `u_k` from them, and `u_k` is held over `[kT_s, (k+1)T_s)`
//! while the plant advances exactly under zero-order hold ([`PlantSim::advance`]). It runs
//! the same `PlantSim` that `plant-proxy` serves and the same [`Controller::step`] that
//! the real-time service calls, so a study reproduces what a lockstep run across
//! processes gives, without the processes. Without a controller it is the open loop
//! (`u ≡ 0`).

use plant_proxy::scenario::PlantParams;
use plant_proxy::sim::PlantSim;

use crate::controller::{Controller, MAX_INTERNALS, StepInput};

/// Signals of one run, one vector per channel, one entry per sample.
#[derive(Debug, Clone, Default)]
pub struct Trace {
    /// Sample period in s.
    pub sample_period: f64,
    /// Measurements `y`, per channel.
    pub y: Vec<Vec<f64>>,
    /// Performance variables `z`, per channel.
    pub z: Vec<Vec<f64>>,
    /// Control inputs `u`, per channel.
    pub u: Vec<Vec<f64>>,
    /// Names of the controller's internal signals.
    pub internal_names: Vec<String>,
    /// The controller's internal signals, per signal.
    pub internals: Vec<Vec<f64>>,
    /// Controller coefficients every `theta_every` samples (empty unless asked for).
    pub theta: Vec<Vec<f64>>,
}

impl Trace {
    /// Time of sample `k` in s.
    pub fn time(&self, k: usize) -> f64 {
        k as f64 * self.sample_period
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.z.first().map_or(0, Vec::len)
    }

    /// True when no sample was recorded.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Copies a controller's coefficients for [`Trace::theta`], every `every` samples.
pub type ThetaProbe<'a, C> = (&'a dyn Fn(&C) -> Vec<f64>, usize);

/// Runs `steps` samples of the plant without control (`u ≡ 0`).
pub fn open_loop(plant: &PlantParams, ts: f64, steps: usize) -> Result<Trace, String> {
    closed_loop::<crate::controller::Rcac>(plant, ts, None, steps, None)
}

/// Runs `steps` samples of the plant `plant` (sample period `ts`) in closed loop with
/// `controller`, or open loop when it is `None`; `theta` records the coefficients.
pub fn closed_loop<C: Controller + ?Sized>(
    plant: &PlantParams,
    ts: f64,
    mut controller: Option<&mut C>,
    steps: usize,
    theta: Option<ThetaProbe<'_, C>>,
) -> Result<Trace, String> {
    let mut sim = PlantSim::new(plant, ts).map_err(|e| format!("plant: {e}"))?;
    let (n_y, n_z, n_r, n_u) = (sim.n_y(), sim.n_z(), sim.n_r(), sim.n_u());
    if let Some(c) = controller.as_deref() {
        let counts = c.counts();
        let want = (n_y, n_z, n_r, n_u);
        let got = (
            counts.n_y as usize,
            counts.n_z as usize,
            counts.n_r as usize,
            counts.n_u as usize,
        );
        if want != got {
            return Err(format!(
                "the controller has (n_y, n_z, n_r, n_u) = {got:?}, the plant {want:?}"
            ));
        }
    }
    let names = controller
        .as_deref()
        .map(|c| c.internal_names())
        .unwrap_or_default();
    let mut t = Trace {
        sample_period: ts,
        y: vec![Vec::with_capacity(steps); n_y],
        z: vec![Vec::with_capacity(steps); n_z],
        u: vec![Vec::with_capacity(steps); n_u],
        internals: vec![Vec::with_capacity(steps); names.len()],
        internal_names: names,
        theta: Vec::new(),
    };
    let (mut y, mut z, mut r) = (vec![0.0; n_y], vec![0.0; n_z], vec![0.0; n_r]);
    let mut u = vec![0.0; n_u];
    let mut internals = [0.0; MAX_INTERNALS];
    for k in 0..steps {
        sim.sample(&mut y, &mut z, &mut r)
            .map_err(|e| format!("plant at sample {k}: {e}"))?;
        if let Some(c) = controller.as_deref_mut() {
            c.step(
                &StepInput {
                    seq: k as u64,
                    y: &y,
                    z: &z,
                    r: &r,
                    ..Default::default()
                },
                &mut u,
            );
            let n = c.internals(&mut internals);
            for (dst, v) in t.internals.iter_mut().zip(&internals[..n]) {
                dst.push(*v);
            }
            if let Some((f, every)) = theta
                && k % every.max(1) == 0
            {
                t.theta.push(f(c));
            }
        }
        for (dst, v) in t.y.iter_mut().zip(&y) {
            dst.push(*v);
        }
        for (dst, v) in t.z.iter_mut().zip(&z) {
            dst.push(*v);
        }
        for (dst, v) in t.u.iter_mut().zip(&u) {
            dst.push(*v);
        }
        sim.advance(&u)
            .map_err(|e| format!("plant at sample {k}: {e}"))?;
    }
    Ok(t)
}
