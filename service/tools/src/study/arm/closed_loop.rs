//! One closed-loop run of chapter 7 (§7.3): the sampling arm's controller, built from the
//! service's controller file exactly as `service` builds it, on plant-proxy's simulation
//! of the spacecraft (`PlantSim`, kind `sampling-arm`), in process.
//!
//! # The loop
//!
//! The service's order at every sample `k = 0, 1, …`: the plant publishes `y_k`, `z_k`
//! and the guidance's command `r_k = F_d` (25 N in a contact phase, 0 otherwise); the
//! controller steps on them and answers `τ_k = [τ1, τ2]`; the plant integrates over
//! `[kT_s, (k+1)T_s)` with `τ_k` held (zero-order hold). Algorithm 3 runs while `r_k > 0`
//! and the joints are held otherwise (docs/arm.md).
//!
//! # What is measured
//!
//! The contact phase is the set of samples with `r_k > 0` (the guidance's, from the
//! sample at which it detects the onset, for 2 s). Over the samples of one contact phase
//! with the true contact force `F_c = z_k`:
//!
//! - the **median contact force** (Figures 7.3 and 7.5): the median of `F_c` over the
//!   phase's samples;
//! - the **settling time**: the time from the phase's first sample after which `F_c`
//!   stays within `±5 %` of `F_d` to the phase's end (`+∞` when the last sample is
//!   outside the band).
//!
//! A run **fails** when the plant's integrator or the controller reports an error (a
//! non-finite torque, a controller fault status, or a `SimError`): the run stops there and
//! the study records it as failed instead of aborting.

use std::path::{Path, PathBuf};

use control::arm::controller::{ArmController, ArmControllerParams};
use control::{Controller, StepInput, status};
use plant_proxy::arm::{ContactModel, Phase};

use crate::study::arm::ArmError;
use plant_proxy::scenario::{self, Scenario};
use plant_proxy::sim::PlantSim;
use service::config::ServiceConfig;
use service::config::controller::ControllerConfig;

/// The desired contact force `F_d` of §7.3, N.
pub const F_D: f64 = 25.0;

/// The band of the settling time and of the "reaches 25 N" criteria: `±5 %` of `F_d`.
pub const BAND: f64 = 0.05;

/// The folder of the arm's scenario and controller files.
pub fn scenario_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios/arm")
}

/// The two controllers compared in §7.3.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Law {
    /// The robust controller alone (`scenarios/arm/robust.toml`).
    Robust,
    /// The robust controller with the PCAC augmentation (`scenarios/arm/pcac.toml`).
    Augmented,
}

impl Law {
    /// Both, robust first.
    pub const ALL: [Law; 2] = [Law::Robust, Law::Augmented];

    /// `robust` or `augmented` (CSV values, file names).
    pub fn name(self) -> &'static str {
        match self {
            Law::Robust => "robust",
            Law::Augmented => "augmented",
        }
    }

    /// The controller file in [`scenario_dir`].
    pub fn file(self) -> &'static str {
        match self {
            Law::Robust => "robust.toml",
            Law::Augmented => "pcac.toml",
        }
    }

    /// The chapter's label.
    pub fn label(self) -> &'static str {
        match self {
            Law::Robust => "robust controller",
            Law::Augmented => "PCAC augmented controller",
        }
    }
}

/// The contact models of §7.3.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Model {
    /// Kelvin–Voigt (7.27): `k_s`, `c_s`.
    Linear,
    /// Hunt–Crossley (7.28): `k_s`, `c_r`.
    HuntCrossley,
}

impl Model {
    /// Both, linear first.
    pub const ALL: [Model; 2] = [Model::Linear, Model::HuntCrossley];

    /// `linear` or `hunt-crossley` (CSV values, file names).
    pub fn name(self) -> &'static str {
        match self {
            Model::Linear => "linear",
            Model::HuntCrossley => "hunt-crossley",
        }
    }

    /// The name of the second parameter: `c_s` or `c_r`.
    pub fn second(self) -> &'static str {
        match self {
            Model::Linear => "c_s",
            Model::HuntCrossley => "c_r",
        }
    }

    /// The surface `(k_s, c)` of this model.
    pub fn surface(self, k_s: f64, c: f64) -> Result<ContactModel, ArmError> {
        match self {
            Model::Linear => ContactModel::kelvin_voigt(k_s, c),
            Model::HuntCrossley => ContactModel::hunt_crossley(k_s, c),
        }
        .map_err(|source| ArmError::Surface {
            model: self,
            k_s,
            c,
            source,
        })
    }
}

/// The loaded files of the study: the plant scenarios and the two controllers'
/// parameters, read once.
#[derive(Debug, Clone)]
pub struct Setup {
    /// `linear.toml` (its surface replaced per run).
    pub single: Scenario,
    /// `double-linear.toml`.
    pub double_linear: Scenario,
    /// `double-hunt-crossley.toml`.
    pub double_hunt_crossley: Scenario,
    /// The robust controller's parameters.
    pub robust: ArmControllerParams,
    /// The augmented controller's parameters.
    pub augmented: ArmControllerParams,
    /// The rig's channel counts as the service reads them.
    pub dims: control::Dimensions,
}

impl Setup {
    /// Reads the files of `dir` (normally [`scenario_dir`]).
    pub fn load(dir: &Path) -> Result<Self, ArmError> {
        let sc = |name: &str| {
            let path = dir.join(name);
            scenario::load(&path).map_err(|source| ArmError::Scenario { path, source })
        };
        let ctl = |law: Law| -> Result<(ArmControllerParams, control::Dimensions), ArmError> {
            let cfg = ServiceConfig::load_with_controller(
                &dir.join("linear.toml"),
                &dir.join(law.file()),
            )?;
            match cfg.controller {
                ControllerConfig::SamplingArm { params } => {
                    Ok((*params, service::wire::dimensions(cfg.counts)))
                }
                other => Err(ArmError::Kind {
                    file: law.file(),
                    kind: other.kind_name(),
                }),
            }
        };
        let (robust, dims) = ctl(Law::Robust)?;
        let (augmented, _) = ctl(Law::Augmented)?;
        Ok(Self {
            single: sc("linear.toml")?,
            double_linear: sc("double-linear.toml")?,
            double_hunt_crossley: sc("double-hunt-crossley.toml")?,
            robust,
            augmented,
            dims,
        })
    }

    /// The same setup with the robust gain `K` (2×3 row-major, `τ_f = K χ`) of both
    /// controllers replaced (the robust controller alone and the one PCAC augments).
    pub fn with_gain(&self, gain: [f64; 6]) -> Setup {
        let mut s = self.clone();
        s.robust.robust_gain = gain;
        s.augmented.robust_gain = gain;
        s
    }

    /// The parameters of `law`.
    pub fn params(&self, law: Law) -> &ArmControllerParams {
        match law {
            Law::Robust => &self.robust,
            Law::Augmented => &self.augmented,
        }
    }

    /// The single-maneuver scenario with the surface `model(k_s, c)`.
    pub fn single_on(&self, model: Model, k_s: f64, c: f64) -> Result<Scenario, ArmError> {
        self.single_with(model.surface(k_s, c)?)
    }

    /// The single-maneuver scenario with the normal-force law `law`.
    pub fn single_with(&self, law: ContactModel) -> Result<Scenario, ArmError> {
        let mut sc = self.single.clone();
        sc.plant.arm_mut().ok_or(ArmError::NotArm)?.surface.model = law;
        Ok(sc)
    }

    /// The scenario of `m`.
    pub fn scenario(&self, m: Maneuver) -> Result<Scenario, ArmError> {
        match m {
            Maneuver::Single(model, k_s, c) => self.single_on(model, k_s, c),
            Maneuver::DoubleLinear => Ok(self.double_linear.clone()),
            Maneuver::DoubleHuntCrossley => Ok(self.double_hunt_crossley.clone()),
        }
    }
}

/// The maneuvers of §7.3.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Maneuver {
    /// The single maneuver (`linear.toml`) on the surface `model(k_s, c)`.
    Single(Model, f64, f64),
    /// `double-linear.toml` (Figure 7.7).
    DoubleLinear,
    /// `double-hunt-crossley.toml` (Figure 7.8).
    DoubleHuntCrossley,
}

/// How much of a run to record.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Record {
    /// The contact-phase forces only; the run stops at the end of the first contact
    /// phase (the grids).
    FirstContact,
    /// Every sample to the scenario's end (the single runs' figures).
    Everything,
}

/// The signals of one run, sample by sample.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct Trace {
    /// `t_k = k T_s`, s.
    pub t: Vec<f64>,
    /// `r_k = F_d` or 0.
    pub r: Vec<f64>,
    /// The true contact force `F_c` (z), N.
    pub force: Vec<f64>,
    /// The sampler velocity `ẋ` (y₅), m/s.
    pub xd: Vec<f64>,
    /// The sampler velocity `ẏ` (y₆), m/s.
    pub yd: Vec<f64>,
    /// `τ1`, N·m.
    pub tau1: Vec<f64>,
    /// `τ2`, N·m.
    pub tau2: Vec<f64>,
    /// `λ_k` of PCAC's identification (NaN without PCAC).
    pub lambda: Vec<f64>,
    /// `tr P_k` (NaN without PCAC).
    pub trace_p: Vec<f64>,
    /// PCAC's model coefficients `Θ̃_k` (empty without PCAC).
    pub theta: Vec<Vec<f64>>,
}

/// One contact phase's statistics.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ContactStats {
    /// The first sample with `r > 0`.
    pub first: usize,
    /// Its number of samples.
    pub samples: usize,
    /// The median of `F_c` over its samples, N.
    pub median: f64,
    /// The settling time into `±5 %` of `F_d`, s (`+∞` if never).
    pub settling: f64,
}

/// The outcome of one run.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Outcome {
    /// Per contact phase (in order).
    pub contacts: Vec<ContactStats>,
    /// Why the run stopped early, if it did.
    pub failure: Option<String>,
    /// The signals, for [`Record::Everything`].
    pub trace: Option<Trace>,
}

impl Outcome {
    /// The first contact's median force (NaN when there was no contact phase).
    pub fn median(&self) -> f64 {
        self.contacts.first().map_or(f64::NAN, |c| c.median)
    }

    /// The first contact's settling time (NaN when there was no contact phase).
    pub fn settling(&self) -> f64 {
        self.contacts.first().map_or(f64::NAN, |c| c.settling)
    }
}

pub use crate::stats::median;

/// The settling time of the forces `f` sampled every `ts` into `F_d (1 ± BAND)`: the
/// time from the first sample to the first after which every sample is in the band
/// (`+∞` when the last one is not).
pub fn settling_time(f: &[f64], ts: f64) -> f64 {
    settling_time_within(f, ts, BAND)
}

/// [`settling_time`] into `F_d (1 ± band)` (the sensitivity of the band).
pub fn settling_time_within(f: &[f64], ts: f64, band: f64) -> f64 {
    let inside = |v: f64| (v - F_D).abs() <= band * F_D;
    match f.iter().rposition(|&v| !inside(v)) {
        None => 0.0,
        Some(i) if i + 1 == f.len() => f64::INFINITY,
        Some(i) => (i + 1) as f64 * ts,
    }
}

/// The contact phases of the samples `(r_k, F_c,k)` sampled every `ts`.
pub fn contact_stats(r: &[f64], force: &[f64], ts: f64) -> Vec<ContactStats> {
    contact_stats_within(r, force, ts, BAND)
}

/// [`contact_stats`] with the settling time into `F_d (1 ± band)`.
pub fn contact_stats_within(r: &[f64], force: &[f64], ts: f64, band: f64) -> Vec<ContactStats> {
    let mut out = Vec::new();
    let mut k = 0;
    while k < r.len() {
        if r[k] > 0.0 {
            let first = k;
            while k < r.len() && r[k] > 0.0 {
                k += 1;
            }
            let f = &force[first..k];
            out.push(ContactStats {
                first,
                samples: k - first,
                median: median(f),
                settling: settling_time_within(f, ts, band),
            });
        } else {
            k += 1;
        }
    }
    out
}

/// Runs `law` on the plant of `scenario` for the scenario's duration (or to the end of
/// the first contact phase, for [`Record::FirstContact`]).
pub fn run(
    setup: &Setup,
    scenario: &Scenario,
    law: Law,
    record: Record,
) -> Result<Outcome, ArmError> {
    let ts = scenario.rig.sample_period;
    let mut sim = PlantSim::new(&scenario.plant, ts).map_err(|source| ArmError::Sim {
        origin: scenario.origin.clone(),
        source,
    })?;
    let mut ctl = ArmController::new(setup.params(law), setup.dims).map_err(|source| {
        ArmError::Controller {
            file: law.file(),
            source,
        }
    })?;
    let steps = (scenario.rig.duration / ts).round() as u64;
    let (mut y, mut z, mut r) = ([0.0; 7], [0.0; 1], [0.0; 1]);
    let mut u = [0.0; 2];
    let mut rs = Vec::new();
    let mut fs = Vec::new();
    let mut trace = Trace::default();
    let mut failure = None;
    let mut was_contact = false;
    for k in 0..steps {
        if let Err(e) = sim.sample(&mut y, &mut z, &mut r) {
            failure = Some(format!("plant at sample {k}: {e}"));
            break;
        }
        let st = ctl.step(
            &StepInput {
                seq: k,
                y: &y,
                z: &z,
                r: &r,
                u_applied: None,
                lost: 0,
            },
            &mut u,
        );
        rs.push(r[0]);
        fs.push(z[0]);
        if record == Record::Everything {
            trace.t.push(k as f64 * ts);
            trace.r.push(r[0]);
            trace.force.push(z[0]);
            trace.xd.push(y[4]);
            trace.yd.push(y[5]);
            trace.tau1.push(u[0]);
            trace.tau2.push(u[1]);
            trace
                .lambda
                .push(ctl.forgetting_factor().unwrap_or(f64::NAN));
            trace
                .trace_p
                .push(ctl.covariance_trace().unwrap_or(f64::NAN));
            if let Some(c) = ctl.model_coefficients() {
                trace.theta.push(c.to_vec());
            }
        }
        if st & status::CONTROLLER_FAULT != 0 || !u.iter().all(|v| v.is_finite()) {
            failure = Some(format!("controller fault at sample {k} (status {st:#x})"));
            break;
        }
        let contact = r[0] > 0.0;
        if record == Record::FirstContact && was_contact && !contact {
            break;
        }
        was_contact |= contact;
        if let Err(e) = sim.advance(&u) {
            failure = Some(format!("plant at sample {k}: {e}"));
            break;
        }
    }
    // A run that never reached its contact phase is a failure too.
    let contacts = contact_stats(&rs, &fs, ts);
    if failure.is_none() && contacts.is_empty() {
        let phase = sim.arm().map_or(Phase::Descent, |a| a.phase());
        failure = Some(format!("no contact phase (plant phase {})", phase.name()));
    }
    Ok(Outcome {
        contacts,
        failure,
        trace: (record == Record::Everything).then_some(trace),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_and_settling_follow_their_definitions() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
        assert!(median(&[]).is_nan());
        let ts = 0.5;
        assert_eq!(settling_time(&[25.0, 25.0], ts), 0.0);
        assert_eq!(settling_time(&[0.0, 30.0, 24.0, 25.5], ts), 1.0);
        assert_eq!(settling_time(&[25.0, 0.0], ts), f64::INFINITY);
        let c = contact_stats(
            &[0.0, 25.0, 25.0, 0.0, 25.0],
            &[9.0, 1.0, 25.0, 9.0, 25.0],
            ts,
        );
        assert_eq!(c.len(), 2);
        assert_eq!((c[0].first, c[0].samples, c[0].median), (1, 2, 13.0));
        assert_eq!(c[0].settling, 0.5);
        assert_eq!((c[1].first, c[1].settling), (4, 0.0));
        // A wider band settles earlier, a narrower one later.
        let f = [0.0, 22.0, 24.0, 25.2, 25.0];
        assert_eq!(settling_time_within(&f, ts, 0.15), 0.5);
        assert_eq!(settling_time_within(&f, ts, 0.05), 1.0);
        assert_eq!(settling_time_within(&f, ts, 0.005), 2.0);
    }
}
