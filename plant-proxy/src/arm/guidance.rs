//! # The descent, contact and departure guidance (our design)
//!
//! §7.2 says that "the ascent and descent control follows the method given in \[83\]",
//! which we do not have. This is the simple guidance we designed in its place; it is part
//! of the plant (the spacecraft's own guidance, not the force controller under test) and
//! it also produces the command `r_k = F_d` the force controller follows.
//!
//! ## Phases
//!
//! 1. **Descent** (maneuver 1): the whole spacecraft starts moving down at the descent
//!    speed (0.1 m/s, `ẏ = −0.1`, `θ̇ = 0`) with the sampler at the initial height
//!    (0.2 m) and *coasts*: no thrust. Contact is therefore at `t = 0.2 / 0.1 = 2` s when
//!    nothing acts on the arm.
//! 2. **Contact** (from the contact onset, located as an event by the integrator, for
//!    `contact-duration` = 2 s): thrusters off; `r = F_d` (25 N) on every sample from the
//!    first one at or after the onset. The force controller holds the contact; bounces
//!    inside the phase are physical contact events only and do not restart it.
//! 3. **Departure**: `r = 0`, and a velocity loop on the bus's vertical velocity `v_sc,y`
//!    (7.8) drives it up at `ascent-speed`:
//!
//!    ```text
//!    f_thr = sat_{±f_max}( m_0 K_v (v_ref − v_sc,y) ),   applied to the bus as D_busᵀ [0, f_thr]
//!    ```
//!
//!    with the nominal total mass `m_0` (the spacecraft as launched: the guidance does not
//!    know what the sampler collected), the loop gain `K_v` (1/s) and the thrust limit
//!    `f_max` (N). The thrust is evaluated at every sample instant and at every event
//!    (contact onset or loss, phase change) and held until the next evaluation.
//!
//! For the **double sampling maneuver** (§7.3.3–7.3.4, `[plant.second-sampling]`):
//!
//! - when the first contact phase ends, the sampler's mass grows by `sample-mass`
//!   (0.5 kg, unknown to the controller); the collected material moves with the sampler,
//!   so the velocities are kept;
//! - the departure lasts `ascent-duration`, then the loop's reference becomes
//!   `−descent-speed` (maneuver 2's descent, thrusting), and the surface takes the second
//!   site's properties (at that instant, or at the first loss of contact after it if the
//!   sampler is still touching the first site);
//! - the second contact onset starts a second contact phase (thrusters off, `r = F_d`),
//!   followed by a departure for the rest of the run.
//!
//! With the loop's time constant `τ = 1/K_v` the second contact comes about
//! `2 · ascent-duration + τ` after the end of the first contact phase (the ascent gains
//! `v (A − τ)`, the reversal and descent lose it back in `A + τ`); the default
//! `ascent-duration = 1.75` s with `K_v = 2` 1/s puts it near the chapter's 8 s when the
//! controller holds the arm.

use super::contact::Surface;

/// The guidance's parameters (`[plant.guidance]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuidanceParams {
    /// `F_d`, the contact force the command asks for during a contact phase, N.
    pub force_set_point: f64,
    /// The length of a contact phase from its onset, s.
    pub contact_duration: f64,
    /// The bus's vertical velocity during a departure, m/s (> 0: up).
    pub ascent_speed: f64,
    /// `f_max`, the thrust limit, N.
    pub thrust_limit: f64,
    /// `K_v`, the velocity loop's gain, 1/s.
    pub loop_gain: f64,
}

impl GuidanceParams {
    /// `F_d = 25` N for 2 s (§7.3), departure at 0.1 m/s, `f_max = 100` N, `K_v = 2` 1/s.
    pub const DEFAULT: GuidanceParams = GuidanceParams {
        force_set_point: 25.0,
        contact_duration: 2.0,
        ascent_speed: 0.1,
        thrust_limit: 100.0,
        loop_gain: 2.0,
    };
}

/// The second sampling of the double maneuver (`[plant.second-sampling]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SecondSampling {
    /// The mass collected by the first sampling and added to the sampler, kg.
    pub sample_mass: f64,
    /// How long the first departure climbs before the second descent, s.
    pub ascent_duration: f64,
    /// The bus's downward speed in the second descent, m/s (> 0).
    pub descent_speed: f64,
    /// The second site's surface.
    pub surface: Surface,
}

impl SecondSampling {
    /// The chapter's double maneuver (§7.3.3): 0.5 kg collected, an ascent of 1.75 s,
    /// the second descent at 0.1 m/s, onto `surface`.
    pub fn chapter(surface: Surface) -> Self {
        Self {
            sample_mass: 0.5,
            ascent_duration: 1.75,
            descent_speed: 0.1,
            surface,
        }
    }
}

/// The guidance's phase (module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Before the maneuver's contact: coasting (maneuver 1) or the velocity loop driving
    /// down (maneuver 2).
    Descent,
    /// The contact phase: thrusters off, `r = F_d`.
    Contact,
    /// Climbing away with the velocity loop, `r = 0`.
    Departure,
}

impl Phase {
    /// `"descent"`, `"contact"` or `"departure"`.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Descent => "descent",
            Phase::Contact => "contact",
            Phase::Departure => "departure",
        }
    }
}

/// What the plant must do when the guidance changes phase on time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    /// Nothing besides the phase change.
    None,
    /// Add the collected mass to the sampler (end of the first contact phase).
    AddSampleMass,
    /// Switch to the second site's surface (start of the second descent).
    SwitchSurface,
}

/// The guidance's state (module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct Guidance {
    params: GuidanceParams,
    second: Option<SecondSampling>,
    /// `m_0` of the spacecraft as launched, kg.
    nominal_mass: f64,
    phase: Phase,
    /// 1 or 2.
    maneuver: u8,
    onset: [Option<f64>; 2],
    /// The time of the next phase change on time (∞: none).
    next_event: f64,
}

impl Guidance {
    /// The guidance at `t = 0`: descent of maneuver 1.
    pub fn new(params: GuidanceParams, second: Option<SecondSampling>, nominal_mass: f64) -> Self {
        Self {
            params,
            second,
            nominal_mass,
            phase: Phase::Descent,
            maneuver: 1,
            onset: [None; 2],
            next_event: f64::INFINITY,
        }
    }

    /// The current phase.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// The current maneuver: 1, or 2 from the start of the second descent.
    pub fn maneuver(&self) -> u8 {
        self.maneuver
    }

    /// The contact onset times of maneuvers 1 and 2, s (`None`: not yet).
    pub fn onsets(&self) -> [Option<f64>; 2] {
        self.onset
    }

    /// The time of the next phase change on time (∞ when none is scheduled).
    pub fn next_event(&self) -> f64 {
        self.next_event
    }

    /// The parameters.
    pub fn params(&self) -> &GuidanceParams {
        &self.params
    }

    /// The command `r`: `F_d` in a contact phase, 0 otherwise.
    pub fn command(&self) -> f64 {
        match self.phase {
            Phase::Contact => self.params.force_set_point,
            _ => 0.0,
        }
    }

    /// The vertical thrust on the bus for its vertical velocity `v_sc_y`, N.
    pub fn thrust(&self, v_sc_y: f64) -> f64 {
        let v_ref = match (self.phase, self.maneuver) {
            (Phase::Contact, _) | (Phase::Descent, 1) => return 0.0,
            (Phase::Descent, _) => -self.second.map_or(0.0, |s| s.descent_speed),
            (Phase::Departure, _) => self.params.ascent_speed,
        };
        let f_max = self.params.thrust_limit;
        (self.nominal_mass * self.params.loop_gain * (v_ref - v_sc_y)).clamp(-f_max, f_max)
    }

    /// A contact onset at `t`: starts the maneuver's contact phase when descending.
    /// Returns true when it did (the plant then records the contact velocity `ẏ_0`).
    pub fn on_contact_onset(&mut self, t: f64) -> bool {
        if self.phase != Phase::Descent {
            return false;
        }
        self.phase = Phase::Contact;
        self.onset[usize::from(self.maneuver - 1)] = Some(t);
        self.next_event = t + self.params.contact_duration;
        true
    }

    /// The phase change due at `t ≥` [`Guidance::next_event`].
    pub fn on_time(&mut self, t: f64) -> Action {
        match (self.phase, self.maneuver, self.second) {
            (Phase::Contact, 1, Some(s)) => {
                self.phase = Phase::Departure;
                self.next_event = t + s.ascent_duration;
                Action::AddSampleMass
            }
            (Phase::Departure, 1, Some(_)) => {
                self.phase = Phase::Descent;
                self.maneuver = 2;
                self.next_event = f64::INFINITY;
                Action::SwitchSurface
            }
            (Phase::Contact, _, _) => {
                self.phase = Phase::Departure;
                self.next_event = f64::INFINITY;
                Action::None
            }
            _ => {
                self.next_event = f64::INFINITY;
                Action::None
            }
        }
    }
}
