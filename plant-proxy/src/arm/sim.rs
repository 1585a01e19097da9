//! # The sampled-data simulation of the arm: ZOH torques, DP5 between samples, events
//!
//! The state is `x = [q; q̇] ∈ ℝ⁸`, `q = [θ_1 θ_2 x y]` (7.2). Between samples it follows
//!
//! ```text
//! q̈ = M(q)⁻¹ (Q − D(q, q̇) q̇),   Q = [τ_1 + τ_2, τ_2, F_f, F_c]ᵀ + D_busᵀ [0, f_thr]   (7.1), (7.26)
//! ```
//!
//! (`M`, `D`, `Q` from [`control::arm::dynamics::ArmModel`]) with the joint torques `τ`
//! held over the period (zero-order hold; with an apply offset `f`, the previous torques
//! over `[kT, kT + fT)` and the new ones after), the contact force and friction of
//! [`crate::arm::contact`] and the guidance's thrust `f_thr` ([`crate::arm::guidance`]).
//!
//! ## Integration and events
//!
//! Each period is integrated by [`crate::arm::dopri5`] in segments on which the
//! right-hand side is smooth: the contact state (in contact or free) is fixed within a
//! segment, and so are `τ` and `f_thr`. A segment ends
//!
//! - at the end of the period (or at the apply offset),
//! - at a phase change of the guidance on time (end of a contact phase, start of the
//!   second descent), reached exactly,
//! - at a contact event: the zero of the switching function `s = min(−y, F_raw)`
//!   ([`crate::arm::contact::Surface::switching`]) crossed downward while in contact
//!   (loss: the force reaches 0 or the sampler leaves the surface) or upward while free
//!   (onset: the sampler reaches the surface, `y` crossing 0 downward, or re-engages below
//!   it), located on the dense output to `event-time-tolerance`.
//!
//! After an event the contact state flips, the guidance is told (an onset starts the
//! contact phase and records `ẏ_0` for (7.28)), the thrust is re-evaluated and the next
//! segment starts from the event. The step into contact is thus resolved to the event
//! tolerance, not to the sample period. Every step attempt of the period counts against
//! `max-steps-per-sample`, and at most [`MAX_EVENTS_PER_SAMPLE`] events are handled in a
//! period; beyond either bound [`ArmSim::advance`] returns an error instead of looping.
//!
//! ## Outputs
//!
//! At sample `k` (before `u_k` is applied): `y = [θ_1, θ_2, θ̇_1, θ̇_2, ẋ, ẏ, F_c]`,
//! `z = F_c` (the true contact force), `r = F_d` during a contact phase and 0 otherwise
//! ([`ArmSim::write_outputs`]); measurement noise is added by [`crate::sim::PlantSim`].
//!
//! ## Real time
//!
//! [`ArmSim::new`] checks the parameters; nothing after it allocates (fixed-size nalgebra
//! vectors only) and nothing panics.

use super::contact::Surface;
use super::dopri5::{Dopri5, IntegrationError, OdeSystem, Stats, Stop, Tolerances};
use super::guidance::{Action, Guidance, Phase};
use super::{ArmParamError, ArmPlantParams};
use control::arm::dynamics::ArmModel;
use nalgebra::{SVector, Vector2, Vector4};
use std::fmt;

/// The state `[θ_1, θ_2, x, y, θ̇_1, θ̇_2, ẋ, ẏ]`.
pub type ArmState = SVector<f64, 8>;

/// The most events (contact onsets and losses, phase changes) handled in one period.
pub const MAX_EVENTS_PER_SAMPLE: usize = 64;

/// Why a period could not be simulated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ArmError {
    /// The integrator stopped (step budget, step underflow, equations not evaluable).
    Integration {
        /// The sample whose period failed.
        k: u64,
        /// Why.
        cause: IntegrationError,
    },
    /// More than [`MAX_EVENTS_PER_SAMPLE`] events in one period (a chattering contact).
    TooManyEvents {
        /// The sample whose period failed.
        k: u64,
        /// The time reached.
        t: f64,
    },
}

impl fmt::Display for ArmError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ArmError::Integration { k, cause } => {
                write!(f, "sampling arm, period of sample {k}: {cause}")
            }
            ArmError::TooManyEvents { k, t } => write!(
                f,
                "sampling arm, period of sample {k}: more than {MAX_EVENTS_PER_SAMPLE} contact \
                 events in one period (at t = {t} s): a chattering contact"
            ),
        }
    }
}

impl std::error::Error for ArmError {}

/// The right-hand side on one segment: everything held fixed.
struct Segment<'a> {
    model: &'a ArmModel,
    surface: &'a Surface,
    tau: Vector2<f64>,
    thrust: f64,
    in_contact: bool,
    yd0: f64,
}

impl OdeSystem<8> for Segment<'_> {
    #[inline]
    fn rhs(&self, _t: f64, x: &ArmState) -> Option<ArmState> {
        let q = x.fixed_rows::<4>(0).into_owned();
        let qd = x.fixed_rows::<4>(4).into_owned();
        let (f_c, f_f) = if self.in_contact {
            let f_c = self.surface.raw_force(q[3], qd[3], self.yd0);
            (f_c, self.surface.friction_force(f_c, qd[2]))
        } else {
            (0.0, 0.0)
        };
        let mut force = ArmModel::generalized_force(&self.tau, f_f, f_c);
        if self.thrust != 0.0 {
            force += self.model.bus_force(&q, &Vector2::new(0.0, self.thrust));
        }
        let qdd = self.model.accelerations(&q, &qd, &force)?;
        let mut dx = ArmState::zeros();
        dx.fixed_rows_mut::<4>(0).copy_from(&qd);
        dx.fixed_rows_mut::<4>(4).copy_from(&qdd);
        Some(dx)
    }
}

/// Work counters of a simulation ([`ArmSim::stats`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ArmStats {
    /// The integrator's counters (steps, rejections, evaluations, located events).
    pub integrator: Stats,
    /// Periods simulated.
    pub samples: u64,
    /// Periods that were in contact at their start or end.
    pub contact_samples: u64,
    /// Step attempts (accepted and rejected) in those periods.
    pub contact_steps: u64,
    /// The most step attempts of one period.
    pub max_steps_in_a_sample: u64,
}

impl ArmStats {
    /// Step attempts per period in contact (0 when none).
    pub fn steps_per_contact_sample(&self) -> f64 {
        if self.contact_samples == 0 {
            0.0
        } else {
            self.contact_steps as f64 / self.contact_samples as f64
        }
    }

    /// Step attempts per period overall (0 when none).
    pub fn steps_per_sample(&self) -> f64 {
        if self.samples == 0 {
            0.0
        } else {
            (self.integrator.accepted + self.integrator.rejected) as f64 / self.samples as f64
        }
    }
}

/// The sampled-data simulation of the spacecraft with its sampling arm (module docs).
#[derive(Debug, Clone)]
pub struct ArmSim {
    params: ArmPlantParams,
    ts: f64,
    apply_offset: Option<f64>,
    model: ArmModel,
    surface: Surface,
    surface_switch_pending: bool,
    guidance: Guidance,
    x0: ArmState,
    x: ArmState,
    k: u64,
    in_contact: bool,
    /// `ẏ_0` of (7.28): the velocity at the maneuver's contact onset.
    yd0: f64,
    /// The torques applied over the previous period.
    tau_prev: Vector2<f64>,
    integrator: Dopri5<8>,
    stats: ArmStats,
}

impl ArmSim {
    /// The simulation of `params` at sample period `ts` (s), at `k = 0` in the initial
    /// state: the sampler `initial-height` above the surface, everything moving down at
    /// the descent speed.
    pub fn new(params: &ArmPlantParams, ts: f64) -> Result<Self, ArmParamError> {
        params.validate()?;
        if !(ts.is_finite() && ts > 0.0) {
            return Err(ArmParamError::new(
                "sample-period",
                format!("{ts} is not positive"),
            ));
        }
        let model = ArmModel::new(params.spacecraft);
        let mut x0 = ArmState::zeros();
        x0[0] = params.theta1;
        x0[1] = params.theta2;
        x0[3] = params.initial_height;
        x0[7] = -params.descent_speed;
        let tol = Tolerances {
            rtol: params.integrator.rtol,
            atol: params.integrator.atol,
            event_time: params.integrator.event_time_tolerance,
        };
        let mut sim = Self {
            params: *params,
            ts,
            apply_offset: None,
            model,
            surface: params.surface,
            surface_switch_pending: false,
            guidance: Guidance::new(
                params.guidance,
                params.second,
                params.spacecraft.total_mass(),
            ),
            x0,
            x: x0,
            k: 0,
            in_contact: false,
            yd0: -params.descent_speed,
            tau_prev: Vector2::zeros(),
            integrator: Dopri5::new(tol, 0.1 * ts, ts),
            stats: ArmStats::default(),
        };
        sim.reset();
        Ok(sim)
    }

    /// Back to `k = 0` and the initial state, the guidance and the surface as at the start.
    pub fn reset(&mut self) {
        self.model = ArmModel::new(self.params.spacecraft);
        self.surface = self.params.surface;
        self.surface_switch_pending = false;
        self.guidance = Guidance::new(
            self.params.guidance,
            self.params.second,
            self.params.spacecraft.total_mass(),
        );
        self.x = self.x0;
        self.k = 0;
        self.in_contact = self.switching(&self.x0) > 0.0;
        self.yd0 = -self.params.descent_speed;
        self.tau_prev = Vector2::zeros();
        self.integrator.reset(0.1 * self.ts);
        self.stats = ArmStats::default();
    }

    /// Sets when new torques take effect inside the period (`Some(f)`, `0 < f < 1`: at
    /// `kT + fT`; `None`: at `kT`, the ideal zero-order hold). The caller checks `f`.
    pub fn set_apply_offset(&mut self, offset: Option<f64>) {
        self.apply_offset = offset;
    }

    /// The apply offset in use.
    pub fn apply_offset(&self) -> Option<f64> {
        self.apply_offset
    }

    /// The parameters it was built from.
    pub fn params(&self) -> &ArmPlantParams {
        &self.params
    }

    /// The sample period, s.
    pub fn sample_period(&self) -> f64 {
        self.ts
    }

    /// The current sample `k`.
    pub fn k(&self) -> u64 {
        self.k
    }

    /// The current time `kT`, s.
    pub fn time(&self) -> f64 {
        self.k as f64 * self.ts
    }

    /// The state `[θ_1, θ_2, x, y, θ̇_1, θ̇_2, ẋ, ẏ]` at `kT`.
    pub fn state(&self) -> &ArmState {
        &self.x
    }

    /// Replaces the state at `kT` (tests, studies that start elsewhere); the contact state
    /// follows from the surface's switching function. The guidance is not told: a state
    /// below the surface does not start a contact phase until the next onset.
    pub fn set_state(&mut self, x: ArmState) {
        self.x = x;
        self.in_contact = self.switching(&x) > 0.0;
    }

    /// `q = [θ_1, θ_2, x, y]` at `kT`.
    pub fn q(&self) -> Vector4<f64> {
        self.x.fixed_rows::<4>(0).into_owned()
    }

    /// `q̇` at `kT`.
    pub fn qd(&self) -> Vector4<f64> {
        self.x.fixed_rows::<4>(4).into_owned()
    }

    /// The model in use (its sampler mass grows in a double maneuver).
    pub fn model(&self) -> &ArmModel {
        &self.model
    }

    /// The surface in use.
    pub fn surface(&self) -> &Surface {
        &self.surface
    }

    /// The guidance (phase, maneuver, onset times).
    pub fn guidance(&self) -> &Guidance {
        &self.guidance
    }

    /// The guidance's phase at `kT`.
    pub fn phase(&self) -> Phase {
        self.guidance.phase()
    }

    /// The contact onset times of maneuvers 1 and 2, s, located by the integrator.
    pub fn contact_onsets(&self) -> [Option<f64>; 2] {
        self.guidance.onsets()
    }

    /// True when the sampler touches the surface at `kT` (the contact force is active).
    pub fn in_contact(&self) -> bool {
        self.in_contact
    }

    /// The true contact force `F_c` at `kT`, N.
    pub fn contact_force(&self) -> f64 {
        if self.in_contact {
            self.surface.contact_force(self.x[3], self.x[7], self.yd0)
        } else {
            0.0
        }
    }

    /// The friction force `F_f` (7.29) at `kT`, N.
    pub fn friction_force(&self) -> f64 {
        self.surface.friction_force(self.contact_force(), self.x[6])
    }

    /// The command `r_k`: `F_d` during a contact phase, else 0.
    pub fn command(&self) -> f64 {
        self.guidance.command()
    }

    /// The kinetic energy `T` (7.15) at `kT`, J.
    pub fn kinetic_energy(&self) -> f64 {
        self.model.kinetic_energy(&self.q(), &self.qd())
    }

    /// The total linear momentum at `kT`, N s.
    pub fn linear_momentum(&self) -> Vector2<f64> {
        self.model.linear_momentum(&self.q(), &self.qd())
    }

    /// The bus's velocity (7.8) at `kT`, m/s.
    pub fn bus_velocity(&self) -> Vector2<f64> {
        self.model.bus_velocity(&self.q(), &self.qd())
    }

    /// The bus's position (7.5) at `kT` (its height above the surface is the second
    /// entry), m.
    pub fn bus_position(&self) -> Vector2<f64> {
        self.model.bus_position(&self.q())
    }

    /// The work counters.
    pub fn stats(&self) -> ArmStats {
        let mut s = self.stats;
        s.integrator = self.integrator.stats();
        s
    }

    /// Writes `y_k = [θ_1, θ_2, θ̇_1, θ̇_2, ẋ, ẏ, F_c]` and `z_k = [F_c]` (noiseless).
    /// `y` must have 7 entries and `z` one (the caller checks).
    pub fn write_outputs(&self, y: &mut [f64], z: &mut [f64]) {
        let f_c = self.contact_force();
        let x = &self.x;
        let values = [x[0], x[1], x[4], x[5], x[6], x[7], f_c];
        for (dst, v) in y.iter_mut().zip(values) {
            *dst = v;
        }
        if let Some(z0) = z.first_mut() {
            *z0 = f_c;
        }
    }

    fn switching(&self, x: &ArmState) -> f64 {
        self.surface.switching(x[3], x[7], self.yd0)
    }

    /// Applies the torques `tau` over the period `[kT, (k+1)T)` (from `kT + fT` with an
    /// apply offset) and steps to `k + 1`. On an error the state is left where the
    /// integration stopped. Does not allocate.
    pub fn advance(&mut self, tau: [f64; 2]) -> Result<(), ArmError> {
        let tau = Vector2::new(tau[0], tau[1]);
        let t0 = self.k as f64 * self.ts;
        let t1 = (self.k + 1) as f64 * self.ts;
        let mut budget = self.params.integrator.max_steps_per_sample;
        let before = self.integrator.stats();
        let was_in_contact = self.in_contact;
        let mut events = 0usize;
        let mut t = t0;
        if let Some(f) = self.apply_offset {
            let tau_prev = self.tau_prev;
            self.run_to(&mut t, t0 + f * self.ts, tau_prev, &mut budget, &mut events)?;
        }
        self.run_to(&mut t, t1, tau, &mut budget, &mut events)?;
        self.tau_prev = tau;
        self.k += 1;
        let after = self.integrator.stats();
        let steps = (after.accepted + after.rejected) - (before.accepted + before.rejected);
        self.stats.samples += 1;
        self.stats.max_steps_in_a_sample = self.stats.max_steps_in_a_sample.max(steps);
        if was_in_contact || self.in_contact {
            self.stats.contact_samples += 1;
            self.stats.contact_steps += steps;
        }
        Ok(())
    }

    /// Integrates from `*t` to `t_end` with the torques `tau`, handling the events.
    fn run_to(
        &mut self,
        t: &mut f64,
        t_end: f64,
        tau: Vector2<f64>,
        budget: &mut u64,
        events: &mut usize,
    ) -> Result<(), ArmError> {
        let k = self.k;
        while *t < t_end {
            let stop_at = t_end.min(self.guidance.next_event());
            let q = self.x.fixed_rows::<4>(0).into_owned();
            let qd = self.x.fixed_rows::<4>(4).into_owned();
            let thrust = self.guidance.thrust(self.model.bus_velocity(&q, &qd)[1]);
            let seg = Segment {
                model: &self.model,
                surface: &self.surface,
                tau,
                thrust,
                in_contact: self.in_contact,
                yd0: self.yd0,
            };
            let (surface, yd0, in_contact) = (self.surface, self.yd0, self.in_contact);
            // Integrate while the contact state holds: g ≥ 0 inside.
            let g = |_t: f64, x: &ArmState| {
                let s = surface.switching(x[3], x[7], yd0);
                if in_contact { s } else { -s }
            };
            let stop = if stop_at > *t {
                self.integrator
                    .integrate(&seg, t, &mut self.x, stop_at, g, budget)
                    .map_err(|cause| ArmError::Integration { k, cause })?
            } else {
                Stop::End
            };
            match stop {
                Stop::Event { .. } => {
                    *events += 1;
                    self.in_contact = !self.in_contact;
                    if self.in_contact {
                        if self.guidance.on_contact_onset(*t) {
                            self.yd0 = self.x[7];
                        }
                    } else if self.surface_switch_pending {
                        self.switch_surface();
                    }
                }
                Stop::End => {
                    if *t >= self.guidance.next_event() {
                        *events += 1;
                        match self.guidance.on_time(*t) {
                            Action::None => {}
                            Action::AddSampleMass => {
                                if let Some(s) = self.params.second {
                                    self.model.params.m_s += s.sample_mass;
                                }
                            }
                            Action::SwitchSurface => {
                                if self.in_contact {
                                    self.surface_switch_pending = true;
                                } else {
                                    self.switch_surface();
                                }
                            }
                        }
                    }
                }
            }
            if *events > MAX_EVENTS_PER_SAMPLE {
                return Err(ArmError::TooManyEvents { k, t: *t });
            }
        }
        Ok(())
    }

    fn switch_surface(&mut self) {
        if let Some(s) = self.params.second {
            self.surface = s.surface;
        }
        self.surface_switch_pending = false;
        // The new surface's law decides whether a sampler below the old surface level
        // touches it.
        self.in_contact = self.switching(&self.x) > 0.0;
    }
}
