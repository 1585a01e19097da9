//! A discrete-time plant inside [`PlantSim`]: the checks of its parameters and what
//! `describe` reports for it. The simulation itself is the exact recursion of
//! [`crate::discrete::DifferenceEquation`]: at step `k` the applied input is
//! `u_{k−d} + d_k` (the input delay `d` of `plant.input-delays`, then the input
//! disturbance `d_k = Σ A cos(ω k + φ)`), `y_k` is the recursion's output and `z_k = y_k`,
//! each with its own measurement noise from `[plant.noise]`.

use super::{PlantSim, SimError, param, poles};
use crate::command::Command;
use crate::discrete::DiscretePlant;
use crate::lti::ChannelDims;
use crate::scenario::PlantParams;
use serde_json::{Value, json};

/// Refuses a discrete plant whose parameters do not fit it: one `u`, no `w`, one `y`, one
/// `z`, a continuous model without state, no tone or band-limited disturbance, no initial
/// state, valid input-disturbance harmonics.
pub(super) fn check_discrete(params: &PlantParams, d: &DiscretePlant) -> Result<(), SimError> {
    let dims = params.model.dims();
    let expected = ChannelDims {
        n_u: 1,
        n_w: 0,
        n_y: 1,
        n_z: 1,
    };
    if dims != expected || params.model.n_x() != 0 {
        return Err(param(
            "model",
            format!(
                "a discrete plant needs a stateless model with 1 u, 0 w, 1 y and 1 z, not \
                 {dims:?} with {} states",
                params.model.n_x()
            ),
        ));
    }
    if !params.initial_state.is_empty() {
        return Err(param(
            "initial_state",
            "a discrete plant starts at rest".into(),
        ));
    }
    let dist = &params.disturbance;
    if !dist.tones.is_empty() || !dist.band_limited.is_empty() {
        return Err(param(
            "disturbance",
            "a discrete plant has no disturbance input w (its disturbance is \
             input_disturbance)"
                .into(),
        ));
    }
    if let Some(h) = d.input_disturbance.iter().find(|h| !h.is_valid()) {
        return Err(param(
            "discrete.input_disturbance",
            format!("{h:?} has an invalid value"),
        ));
    }
    Ok(())
}

/// The command as JSON: the constant vector as it always was, or the generator.
pub(super) fn command_json(c: &Command) -> Value {
    match c {
        Command::Constant(v) => json!(v),
        Command::Step { amplitude, start } => {
            json!({ "kind": "step", "amplitude": amplitude, "start": start })
        }
        Command::Harmonics(h) => json!({
            "kind": "harmonics",
            "terms": h.iter().map(|t| json!({
                "amplitude": t.amplitude,
                "frequency-rad-step": t.omega,
                "phase-rad": t.phase,
            })).collect::<Vec<_>>(),
        }),
    }
}

/// `describe` for a discrete plant: the difference equation, `G(z)` with its poles and
/// zeros, the channels `y0 ← u0`, `z0 ← u0` in the format of the continuous plants, the
/// input disturbance, the noise and the command.
pub(super) fn describe_discrete(sim: &PlantSim, plant: &DiscretePlant) -> Value {
    let tf = &plant.tf;
    let (num_z, den_z) = tf.descending();
    let roots = |r: Result<Vec<nalgebra::Complex<f64>>, _>| match r {
        Ok(p) => poles(&p),
        Err(e) => json!({ "error": format!("{e}") }),
    };
    let (p, z) = (roots(tf.poles()), roots(tf.zeros()));
    let channel = |output: &str| {
        json!({
            "output": output,
            "input": "u0",
            "order": den_z.len() - 1,
            "num": num_z,
            "den": den_z,
            "poles": p,
            "zeros": z,
            "delay-samples": sim.delays[0],
        })
    };
    let example = plant.example.map(|e| {
        json!({
            "example": e.example.number(),
            "equation": e.example.equation(),
            "rho": e.rho,
            "nu": e.nu,
            "zero": e.example.zero(),
        })
    });
    json!({
        "sample-period": sim.ts,
        "apply-offset": Value::Null,
        "time": "discrete: one step of the plant per sample, no discretization",
        "difference-equation": {
            "form": "y_k = sum_{j=1..m} b_j u_{k-j} - sum_{i=1..n} a_i y_{k-i}, z_k = y_k",
            "num-q-inverse": tf.num(),
            "den-q-inverse": tf.den(),
            "state": "[y_{k-1} .. y_{k-n}, u_{k-1} .. u_{k-m}]",
        },
        "mrac-example": example,
        "measurement-convention":
            "y_k from u up to k-1 (b_0 = 0): published before u_k is applied",
        "states": { "plant": tf.n_states(), "exosystem": 0, "total": tf.n_states() },
        "inputs": { "u": 1, "w": 0 },
        "outputs": { "y": 1, "z": 1, "r": sim.n_r },
        "input-delays": sim.delays,
        "input-disturbance": plant.input_disturbance.iter().map(|h| json!({
            "amplitude": h.amplitude,
            "frequency-rad-step": h.omega,
            "phase-rad": h.phase,
        })).collect::<Vec<_>>(),
        "noise": { "y-std": sim.y_std, "z-std": sim.z_std, "seed": sim.seed },
        "command": command_json(&sim.command),
        "plant-poles": p,
        "channels": [channel("y0"), channel("z0")],
    })
}
