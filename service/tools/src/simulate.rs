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

use control::{Controller, MAX_INTERNALS, StepInput};

/// A simulation that cannot run, or a signal log that cannot be read as a trace, naming
/// the log (and its row) or the sample.
#[derive(Debug, thiserror::Error)]
pub enum SimulateError {
    /// The log lacks a column.
    #[error(transparent)]
    Log(#[from] crate::design::csvlog::LogError),
    /// The log has no rows.
    #[error("{origin}: the log has no rows")]
    NoRows {
        /// The log.
        origin: String,
    },
    /// The log's sequence numbers do not increase from first to last.
    #[error("{origin}: sequence numbers not increasing")]
    NotIncreasing {
        /// The log.
        origin: String,
    },
    /// A row out of order.
    #[error("{origin}: row {row}: sequence number {seq} out of order")]
    OutOfOrder {
        /// The log.
        origin: String,
        /// The row, from 0.
        row: usize,
        /// Its sequence number.
        seq: f64,
    },
    /// The plant cannot be simulated.
    #[error("plant: {0}")]
    Plant(#[source] plant_proxy::sim::SimError),
    /// The controller's signal counts are not the plant's.
    #[error("the controller has (n_y, n_z, n_r, n_u) = {controller:?}, the plant {plant:?}")]
    Counts {
        /// The controller's `(n_y, n_z, n_r, n_u)`.
        controller: (usize, usize, usize, usize),
        /// The plant's.
        plant: (usize, usize, usize, usize),
    },
    /// The plant refused a sample (non-finite input or state).
    #[error("plant at sample {k}: {source}")]
    Sample {
        /// The sample.
        k: usize,
        /// Why.
        #[source]
        source: plant_proxy::sim::SimError,
    },
}

message_from!(SimulateError);

/// Signals of one run, one vector per channel, one entry per sample.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
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
    /// Reads a service signal log (`signals.csv` of a run folder, see [`service::logging`])
    /// back into a trace with `sample_period` (s): the columns `y0…`, `z0…`, `u0…` and the
    /// controller internals that follow them. Sample `k` of the trace is the row with
    /// `seq = seq_0 + k`; rows missing from the log (lost samples, decimation) are filled
    /// with the previous row, and the returned mask says which samples were logged. Also
    /// returns the actuation status of each sample (0 where missing).
    pub fn from_signal_log(
        log: &crate::design::csvlog::Log,
        sample_period: f64,
    ) -> Result<(Trace, Vec<bool>, Vec<u32>), SimulateError> {
        let seq = log.column("seq")?;
        let status = log.column("status")?;
        if seq.is_empty() {
            return Err(SimulateError::NoRows {
                origin: log.origin.clone(),
            });
        }
        let first = seq[0];
        let last = seq[seq.len() - 1];
        if !(first.is_finite() && last >= first) {
            return Err(SimulateError::NotIncreasing {
                origin: log.origin.clone(),
            });
        }
        let n = (last - first) as usize + 1;
        let fixed = ["seq", "t_sample_ns", "status", "flags"];
        let group = |prefix: char| -> Vec<&str> {
            log.names
                .iter()
                .map(String::as_str)
                .filter(|n| {
                    n.len() > 1
                        && n.starts_with(prefix)
                        && n[1..].chars().all(|c| c.is_ascii_digit())
                })
                .collect()
        };
        let (ys, zs, us) = (group('y'), group('z'), group('u'));
        let internal: Vec<&str> = log
            .names
            .iter()
            .map(String::as_str)
            .filter(|n| !fixed.contains(n) && !ys.contains(n) && !zs.contains(n) && !us.contains(n))
            .collect();
        let mut logged = vec![false; n];
        let mut st = vec![0u32; n];
        let idx: Vec<usize> = seq.iter().map(|s| (s - first) as usize).collect();
        for (r, &k) in idx.iter().enumerate() {
            if k >= n || (r > 0 && k <= idx[r - 1]) {
                return Err(SimulateError::OutOfOrder {
                    origin: log.origin.clone(),
                    row: r,
                    seq: seq[r],
                });
            }
            logged[k] = true;
            st[k] = status[r] as u32;
        }
        let fill = |name: &str| -> Result<Vec<f64>, SimulateError> {
            let col = log.column(name)?;
            let mut out = vec![f64::NAN; n];
            for (&k, v) in idx.iter().zip(col) {
                out[k] = *v;
            }
            for k in 1..n {
                if !logged[k] {
                    out[k] = out[k - 1];
                }
            }
            Ok(out)
        };
        let cols = |names: &[&str]| -> Result<Vec<Vec<f64>>, SimulateError> {
            names.iter().map(|n| fill(n)).collect()
        };
        let trace = Trace {
            sample_period,
            y: cols(&ys)?,
            z: cols(&zs)?,
            u: cols(&us)?,
            internal_names: internal.iter().map(|s| s.to_string()).collect(),
            internals: cols(&internal)?,
            theta: Vec::new(),
        };
        Ok((trace, logged, st))
    }

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

    /// Samples `range` of this trace (every signal cut the same way).
    pub fn slice(&self, range: std::ops::Range<usize>) -> Trace {
        let cut = |v: &Vec<Vec<f64>>| -> Vec<Vec<f64>> {
            v.iter().map(|c| c[range.clone()].to_vec()).collect()
        };
        Trace {
            sample_period: self.sample_period,
            y: cut(&self.y),
            z: cut(&self.z),
            u: cut(&self.u),
            internal_names: self.internal_names.clone(),
            internals: cut(&self.internals),
            theta: Vec::new(),
        }
    }
}

/// Copies a controller's coefficients for [`Trace::theta`], every `every` samples.
pub type ThetaProbe<'a, C> = (&'a dyn Fn(&C) -> Vec<f64>, usize);

/// The controller dimensions that fit `plant`: its channel counts as the service contract
/// carries them.
pub fn plant_dimensions(plant: &PlantParams) -> control::Dimensions {
    service::wire::dimensions(ipc_types::ChannelCounts {
        n_y: plant.n_y() as u16,
        n_z: plant.n_z() as u16,
        n_r: plant.n_r() as u16,
        n_u: plant.n_u() as u16,
    })
}

/// Runs `steps` samples of the plant without control (`u ≡ 0`).
pub fn open_loop(plant: &PlantParams, ts: f64, steps: usize) -> Result<Trace, SimulateError> {
    closed_loop::<control::Rcac>(plant, ts, None, steps, None)
}

/// Runs `steps` samples of the plant `plant` (sample period `ts`) in closed loop with
/// `controller`, or open loop when it is `None`; `theta` records the coefficients.
pub fn closed_loop<C: Controller + ?Sized>(
    plant: &PlantParams,
    ts: f64,
    mut controller: Option<&mut C>,
    steps: usize,
    theta: Option<ThetaProbe<'_, C>>,
) -> Result<Trace, SimulateError> {
    let mut sim = PlantSim::new(plant, ts).map_err(SimulateError::Plant)?;
    let (n_y, n_z, n_r, n_u) = (sim.n_y(), sim.n_z(), sim.n_r(), sim.n_u());
    if let Some(c) = controller.as_deref() {
        let counts = c.counts();
        let want = (n_y, n_z, n_r, n_u);
        let got = (counts.n_y, counts.n_z, counts.n_r, counts.n_u);
        if want != got {
            return Err(SimulateError::Counts {
                controller: got,
                plant: want,
            });
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
            .map_err(|source| SimulateError::Sample { k, source })?;
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
            .map_err(|source| SimulateError::Sample { k, source })?;
    }
    Ok(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_signal_log_reads_back_with_its_gaps_filled() {
        let text = "seq,t_sample_ns,status,flags,y0,z0,u0,u1,theta_norm\n\
            10,0,32,17,1.0,1.5,0,0,0\n\
            11,0,32,17,2.0,2.5,0,0,0\n\
            13,0,0,17,4.0,4.5,0.1,0.2,3\n";
        let log = crate::design::csvlog::parse(text, "signals.csv").unwrap();
        let (t, logged, status) = Trace::from_signal_log(&log, 0.5).unwrap();
        assert_eq!(t.len(), 4);
        assert_eq!(t.z[0], vec![1.5, 2.5, 2.5, 4.5]);
        assert_eq!(t.u.len(), 2);
        assert_eq!(t.internal_names, vec!["theta_norm".to_string()]);
        assert_eq!(logged, vec![true, true, false, true]);
        assert_eq!(status, vec![32, 32, 0, 0]);
        assert_eq!(t.slice(1..3).z[0], vec![2.5, 2.5]);
        let bad = crate::design::csvlog::parse("seq,status\n3,0\n2,0\n", "x").unwrap();
        assert!(Trace::from_signal_log(&bad, 1.0).is_err());
    }
}
