//! # The spacecraft sampling arm of chapter 7 as a nonlinear sampled-data plant
//!
//! `[plant] kind = "sampling-arm"`: the planar spacecraft with a two-link sampling arm of
//! §7.1 touching a small body's surface. The dynamics (7.1)–(7.26) are
//! [`control::arm::dynamics::ArmModel`] (the same code the controller's feedback
//! linearization uses); this module adds what makes it a plant:
//!
//! - [`contact`]: the surface: Kelvin–Voigt (7.27) or Hunt–Crossley (7.28) contact force,
//!   never adhesive, and the regularized Coulomb friction (7.29);
//! - [`dopri5`]: the adaptive Dormand–Prince 5(4) integrator with dense output and event
//!   location, allocation-free;
//! - [`guidance`]: the descent, contact and departure guidance (our design; the
//!   dissertation's follows \[83\], which we do not have), the double sampling maneuver and
//!   the command `r = F_d`;
//! - [`sim`]: [`ArmSim`], the period-by-period simulation: torques under zero-order hold,
//!   contact onset and loss located as events.
//!
//! The wire contract of the arm rig (2 kHz): `u = [τ_1, τ_2]` (N m); `y = [θ_1, θ_2, θ̇_1,
//! θ̇_2, ẋ, ẏ, F_c]` (rad, rad/s, m/s, N) with measurement noise per sensor
//! (`[plant.noise] y-std`); `z = [F_c]`, the true contact force; `r = [F_d]` during a
//! contact phase, 0 otherwise. [`crate::sim::PlantSim`] runs it like every other plant
//! kind (noise, input delays, apply offset), so plant-proxy's loops and the offline
//! studies use it unchanged; [`crate::sim::PlantSim::arm`] gives the simulation's truth
//! (phase, onset times, contact force, state).
//!
//! The parameters ([`ArmPlantParams`]) default to the chapter's (§7.3): `m_sc = 420` kg,
//! `m_1 = m_2 = m_s = 1` kg, `L_1 = L_2 = 2` m, `R_1 = R_2 = 1` m, `Ī_1 = Ī_2 = 1/3` kg m²,
//! `θ_1,0 = π/4`, `θ_2,0 = π/2`, the sampler 0.2 m above the surface and everything
//! descending at 0.1 m/s, `μ = 0.5`, `F_d = 25` N for 2 s.

pub mod contact;
pub mod dopri5;
pub mod guidance;
pub mod sim;

pub use contact::{ContactModel, Surface, SurfaceError};
pub use guidance::{GuidanceParams, Phase, SecondSampling};
pub use sim::{ArmError, ArmSim, ArmState, ArmStats};

use control::arm::dynamics::ArmParams;
use std::f64::consts::PI;
use std::fmt;

/// The number of control inputs: `[τ_1, τ_2]`.
pub const N_U: usize = 2;
/// The number of measurements: `[θ_1, θ_2, θ̇_1, θ̇_2, ẋ, ẏ, F_c]`.
pub const N_Y: usize = 7;
/// The number of performance outputs: `[F_c]`.
pub const N_Z: usize = 1;
/// The number of command channels: `[F_d]`.
pub const N_R: usize = 1;
/// The number of states: `[θ_1, θ_2, x, y, θ̇_1, θ̇_2, ẋ, ẏ]`.
pub const N_STATES: usize = 8;

/// The channel counts of the arm's model in a [`crate::scenario::PlantParams`]: 2 `u`,
/// no `w`, 7 `y`, 1 `z`.
pub fn dims() -> crate::lti::ChannelDims {
    crate::lti::ChannelDims {
        n_u: N_U,
        n_w: 0,
        n_y: N_Y,
        n_z: N_Z,
    }
}

/// The integrator's settings (`[plant.integrator]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IntegratorParams {
    /// Relative tolerance.
    pub rtol: f64,
    /// Absolute tolerance (rad, m, rad/s, m/s alike).
    pub atol: f64,
    /// The most step attempts (accepted and rejected) in one sample period.
    pub max_steps_per_sample: u64,
    /// The length of the bracket an event is located to, s.
    pub event_time_tolerance: f64,
}

impl IntegratorParams {
    /// `rtol = 1e-8`, `atol = 1e-10`, at most 20 000 steps per period, events to 1e-12 s.
    pub const DEFAULT: IntegratorParams = IntegratorParams {
        rtol: 1e-8,
        atol: 1e-10,
        max_steps_per_sample: 20_000,
        event_time_tolerance: 1e-12,
    };
}

/// The validated parameters of a sampling-arm plant (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmPlantParams {
    /// The spacecraft (`[plant.sampling-arm]`).
    pub spacecraft: ArmParams,
    /// `θ_1` at `t = 0`, rad.
    pub theta1: f64,
    /// `θ_2` at `t = 0`, rad.
    pub theta2: f64,
    /// The sampler's height above the surface at `t = 0`, m.
    pub initial_height: f64,
    /// The speed at which everything descends at `t = 0`, m/s.
    pub descent_speed: f64,
    /// The (first) surface (`[plant.surface]`).
    pub surface: Surface,
    /// The guidance (`[plant.guidance]`).
    pub guidance: GuidanceParams,
    /// The double maneuver's second sampling (`[plant.second-sampling]`), if any.
    pub second: Option<SecondSampling>,
    /// The integrator (`[plant.integrator]`).
    pub integrator: IntegratorParams,
}

/// A refused parameter: the field, as a dotted path under `plant.` in the scenario
/// (`surface.stiffness`, `second-sampling.surface.restitution`), and what is wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmParamError {
    /// The field.
    pub field: String,
    /// What is wrong.
    pub problem: String,
}

impl ArmParamError {
    /// The error for `field`.
    pub fn new(field: impl Into<String>, problem: impl Into<String>) -> Self {
        Self {
            field: field.into(),
            problem: problem.into(),
        }
    }
}

impl fmt::Display for ArmParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.field, self.problem)
    }
}

impl std::error::Error for ArmParamError {}

/// The largest accepted angle magnitude, rad.
const MAX_ANGLE: f64 = 4.0 * PI;

impl ArmPlantParams {
    /// The chapter's spacecraft, initial condition and guidance (§7.3) on the surface
    /// `model` (with `μ = 0.5`), one sampling, the default integrator.
    pub fn chapter(model: ContactModel) -> Self {
        Self {
            spacecraft: ArmParams::CHAPTER_7,
            theta1: PI / 4.0,
            theta2: PI / 2.0,
            initial_height: 0.2,
            descent_speed: 0.1,
            surface: Surface::chapter(model),
            guidance: GuidanceParams::DEFAULT,
            second: None,
            integrator: IntegratorParams::DEFAULT,
        }
    }

    /// These parameters with the double maneuver of §7.3.3–7.3.4: 0.5 kg collected,
    /// the second site's surface `model` (with `μ = 0.5`), the default ascent (1.75 s)
    /// and second descent (0.1 m/s).
    pub fn with_second_sampling(mut self, model: ContactModel) -> Self {
        self.second = Some(SecondSampling::chapter(Surface::chapter(model)));
        self
    }

    /// Checks every value; the error names the field as in the scenario (under `plant.`).
    pub fn validate(&self) -> Result<(), ArmParamError> {
        if let Some(f) = self.spacecraft.invalid_field() {
            return Err(ArmParamError::new(
                format!("sampling-arm.{f}"),
                "is not positive and finite",
            ));
        }
        let p = &self.spacecraft;
        if p.r1 > p.l1 || p.r2 > p.l2 {
            let f = if p.r1 > p.l1 { "r1" } else { "r2" };
            return Err(ArmParamError::new(
                format!("sampling-arm.{f}"),
                "the centre of mass must lie on its link (r1 ≤ l1, r2 ≤ l2)",
            ));
        }
        for (f, v) in [("theta1", self.theta1), ("theta2", self.theta2)] {
            if !(v.is_finite() && v.abs() <= MAX_ANGLE) {
                return Err(ArmParamError::new(
                    format!("sampling-arm.{f}"),
                    format!("{v} is not an angle in [−4π, 4π] rad"),
                ));
            }
        }
        positive("sampling-arm.initial-height", self.initial_height)?;
        positive("sampling-arm.descent-speed", self.descent_speed)?;
        // Only the sampler may touch the surface: the joint and the bus start above it.
        let (s1, s12) = (self.theta1.sin(), (self.theta1 + self.theta2).sin());
        let joint = self.initial_height + p.l1 * s1;
        let bus = joint + p.l2 * s12;
        if joint <= 0.0 || bus <= 0.0 {
            return Err(ArmParamError::new(
                "sampling-arm.theta1",
                format!(
                    "with theta2 = {} the arm starts below the surface (joint at {joint:.3} m, \
                     bus at {bus:.3} m): only the sampler may touch it",
                    self.theta2
                ),
            ));
        }
        surface("surface", &self.surface)?;
        let g = &self.guidance;
        non_negative("guidance.force-set-point", g.force_set_point)?;
        positive("guidance.contact-duration", g.contact_duration)?;
        positive("guidance.ascent-speed", g.ascent_speed)?;
        positive("guidance.thrust-limit", g.thrust_limit)?;
        positive("guidance.loop-gain", g.loop_gain)?;
        if let Some(s) = &self.second {
            non_negative("second-sampling.sample-mass", s.sample_mass)?;
            positive("second-sampling.ascent-duration", s.ascent_duration)?;
            positive("second-sampling.descent-speed", s.descent_speed)?;
            surface("second-sampling.surface", &s.surface)?;
        }
        let i = &self.integrator;
        for (f, v) in [("integrator.rtol", i.rtol), ("integrator.atol", i.atol)] {
            positive(f, v)?;
            if v >= 1.0 {
                return Err(ArmParamError::new(f, format!("{v} is not below 1")));
            }
        }
        if i.rtol < 1e-14 && i.atol < 1e-14 {
            return Err(ArmParamError::new(
                "integrator.rtol",
                "rtol and atol are both below 1e-14: beyond f64's resolution",
            ));
        }
        if !(1..=10_000_000).contains(&i.max_steps_per_sample) {
            return Err(ArmParamError::new(
                "integrator.max-steps-per-sample",
                format!("{} is not between 1 and 10000000", i.max_steps_per_sample),
            ));
        }
        positive("integrator.event-time-tolerance", i.event_time_tolerance)?;
        if i.event_time_tolerance > 1e-3 {
            return Err(ArmParamError::new(
                "integrator.event-time-tolerance",
                format!("{} s is above 1e-3 s", i.event_time_tolerance),
            ));
        }
        Ok(())
    }
}

fn positive(field: &str, v: f64) -> Result<f64, ArmParamError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(ArmParamError::new(
            field,
            format!("{v} is not positive and finite"),
        ))
    }
}

fn non_negative(field: &str, v: f64) -> Result<f64, ArmParamError> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(ArmParamError::new(
            field,
            format!("{v} is negative or not finite"),
        ))
    }
}

fn surface(prefix: &str, s: &Surface) -> Result<(), ArmParamError> {
    s.validate()
        .map_err(|e| ArmParamError::new(format!("{prefix}.{}", e.field), e.problem))
}

#[cfg(test)]
mod tests;
