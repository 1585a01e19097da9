//! The sampling arm inside [`PlantSim`]: the checks of its parameters and what
//! `describe` reports for it. The simulation itself is [`crate::arm::ArmSim`].

use super::{PlantSim, SimError, param};
use crate::arm::{self, ArmPlantParams, ArmSim, ContactModel, Surface};
use crate::scenario::PlantParams;
use serde_json::{Value, json};

/// Checks that `params` fit the arm (its channel counts, a stateless model, no
/// disturbance, no initial state, one command channel) and builds its simulation.
pub(super) fn build(params: &PlantParams, a: &ArmPlantParams, ts: f64) -> Result<ArmSim, SimError> {
    let dims = params.model.dims();
    if dims != arm::dims() || params.model.n_x() != 0 {
        return Err(param(
            "model",
            format!(
                "the sampling arm needs a stateless model with 2 u, 0 w, 7 y and 1 z, not \
                 {dims:?} with {} states",
                params.model.n_x()
            ),
        ));
    }
    if !params.initial_state.is_empty() {
        return Err(param(
            "initial_state",
            "the sampling arm starts from its own parameters".into(),
        ));
    }
    let dist = &params.disturbance;
    if !dist.tones.is_empty() || !dist.band_limited.is_empty() {
        return Err(param(
            "disturbance",
            "the sampling arm has no disturbance input w".into(),
        ));
    }
    if params.command.n_r() != arm::N_R {
        return Err(param(
            "command",
            format!(
                "the sampling arm publishes one command channel (F_d), not {}",
                params.command.n_r()
            ),
        ));
    }
    ArmSim::new(a, ts).map_err(|e| param("arm", e.to_string()))
}

fn surface_json(s: &Surface) -> Value {
    let law = match s.model {
        ContactModel::KelvinVoigt { stiffness, damping } => json!({
            "model": "kelvin-voigt",
            "equation": "(7.27) F_c = -k_s y - c_s dy",
            "stiffness": stiffness,
            "damping": damping,
        }),
        ContactModel::HuntCrossley {
            stiffness,
            restitution,
        } => json!({
            "model": "hunt-crossley",
            "equation": "(7.28) F_c = k_s (-y)^(3/2) (1 + 3(1 - c_r)/2 dy/dy_0)",
            "stiffness": stiffness,
            "restitution": restitution,
        }),
        ContactModel::Hysteretic {
            stiffness,
            exponent,
            hysteresis,
        } => json!({
            "model": "hysteretic",
            "equation": "F_c = k_s (-y)^n (1 + chi dy/dy_0)",
            "stiffness": stiffness,
            "exponent": exponent,
            "hysteresis": hysteresis,
        }),
    };
    json!({
        "law": law,
        "friction": s.friction,
        "friction-regularization": s.friction_regularization,
    })
}

/// `describe` for the sampling arm: the parameters, the wire channels, the guidance, the
/// integrator, the noise.
pub(super) fn describe(sim: &PlantSim, a: &ArmSim) -> Value {
    let p = a.params();
    let sc = &p.spacecraft;
    let g = &p.guidance;
    let i = &p.integrator;
    json!({
        "sample-period": sim.ts,
        "apply-offset": a.apply_offset(),
        "time": "continuous: adaptive Dormand-Prince 5(4) between samples, torques held, \
                 contact onset and loss located as events",
        "model": "(7.1)-(7.26): M(q) q'' + D(q, q') q' = Q, q = [theta1, theta2, x, y]",
        "spacecraft": {
            "m-sc": sc.m_sc, "m1": sc.m1, "m2": sc.m2, "m-s": sc.m_s,
            "l1": sc.l1, "l2": sc.l2, "r1": sc.r1, "r2": sc.r2, "i1": sc.i1, "i2": sc.i2,
        },
        "initial": {
            "theta1": p.theta1,
            "theta2": p.theta2,
            "height": p.initial_height,
            "descent-speed": p.descent_speed,
        },
        "surface": surface_json(&p.surface),
        "guidance": {
            "force-set-point": g.force_set_point,
            "contact-duration": g.contact_duration,
            "ascent-speed": g.ascent_speed,
            "thrust-limit": g.thrust_limit,
            "loop-gain": g.loop_gain,
        },
        "second-sampling": p.second.map(|s| json!({
            "sample-mass": s.sample_mass,
            "ascent-duration": s.ascent_duration,
            "descent-speed": s.descent_speed,
            "surface": surface_json(&s.surface),
        })),
        "integrator": {
            "method": "Dormand-Prince 5(4), PI step control, dense output of order 4",
            "rtol": i.rtol,
            "atol": i.atol,
            "max-steps-per-sample": i.max_steps_per_sample,
            "event-time-tolerance": i.event_time_tolerance,
        },
        "states": { "plant": arm::N_STATES, "exosystem": 0, "total": arm::N_STATES },
        "inputs": { "u": ["tau1", "tau2"], "w": 0 },
        "outputs": {
            "y": ["theta1", "theta2", "dtheta1", "dtheta2", "dx", "dy", "F_c"],
            "z": ["F_c (true)"],
            "r": ["F_d during a contact phase, else 0"],
        },
        "measurement-convention": "y_k at t = kT, before u_k is applied",
        "input-delays": sim.delays,
        "noise": { "y-std": sim.y_std, "z-std": sim.z_std, "seed": sim.seed },
        "command": "r = F_d (guidance.force-set-point) during a contact phase, else 0",
    })
}
