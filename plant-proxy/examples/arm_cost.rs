//! The sampling arm's cost per sample: runs each arm scenario through `PlantSim` with a
//! stand-in controller (the joint hold of the arm rig's contract:
//! `τ = L⁻¹(−K_p (θ̄ − θ̄_0) − K_d θ̄̇)`) or with zero torque, and prints the wall time per
//! sample overall and in contact, the integrator's steps per sample, the contact onsets
//! and the largest contact force. With `grid`, the corners of the study's surface grids
//! instead (Kelvin–Voigt `k_s ∈ {300, 2.7e5}` × `c_s ∈ {0.35, 1e3}`, Hunt–Crossley
//! `k_s ∈ {300, 2.7e5}` × `c_r ∈ {0.1, 1}`) on `linear.toml`.
//!
//! ```sh
//! cargo run --release -p plant-proxy --example arm_cost [-- zero] [-- grid]
//! ```

use plant_proxy::arm::ContactModel;
use plant_proxy::scenario::{self, Scenario};
use plant_proxy::sim::PlantSim;
use std::path::Path;
use std::time::Instant;

fn main() {
    let zero = std::env::args().any(|a| a == "zero");
    let grid = std::env::args().any(|a| a == "grid");
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let load = |name: &str| -> Scenario {
        scenario::load(&root.join(format!("scenarios/arm/{name}.toml"))).expect("scenario")
    };
    let mut runs: Vec<(String, Scenario)> = Vec::new();
    if grid {
        for k in [300.0, 2.7e5] {
            let surfaces = [
                ContactModel::kelvin_voigt(k, 0.35),
                ContactModel::kelvin_voigt(k, 1e3),
                ContactModel::hunt_crossley(k, 0.1),
                ContactModel::hunt_crossley(k, 1.0),
            ];
            for m in surfaces {
                let m = m.expect("surface");
                let mut sc = load("linear");
                sc.plant.arm_mut().expect("arm").surface.model = m;
                runs.push((format!("{m:?}"), sc));
            }
        }
    } else {
        for name in [
            "linear",
            "hunt-crossley",
            "double-linear",
            "double-hunt-crossley",
        ] {
            runs.push((name.to_string(), load(name)));
        }
    }
    for (name, sc) in runs {
        let ts = sc.rig.sample_period;
        let mut sim = PlantSim::new(&sc.plant, ts).expect("sim");
        let steps = sc.run_steps(None).expect("steps");
        let (mut y, mut z, mut r) = ([0.0; 7], [0.0; 1], [0.0; 1]);
        sim.sample(&mut y, &mut z, &mut r).unwrap();
        let hold = [y[0], y[1]];
        let (kp, kd) = (2000.0, 300.0);
        let mut f_max: f64 = 0.0;
        let (mut t_contact, mut n_contact) = (0.0, 0u64);
        let start = Instant::now();
        let mut failed = None;
        for k in 0..steps {
            sim.sample(&mut y, &mut z, &mut r).unwrap();
            f_max = f_max.max(z[0]);
            // Q_θ = L τ = −K_p (θ − θ_0) − K_d θ̇  ⇒  τ = L⁻¹ Q_θ, L⁻¹ = [[1, −1], [0, 1]].
            let q1 = -kp * (y[0] - hold[0]) - kd * y[2];
            let q2 = -kp * (y[1] - hold[1]) - kd * y[3];
            let u = if zero { [0.0, 0.0] } else { [q1 - q2, q2] };
            let in_contact = sim.arm().unwrap().in_contact();
            let t0 = Instant::now();
            if let Err(e) = sim.advance(&u) {
                failed = Some(format!("sample {k}: {e}"));
                break;
            }
            if in_contact {
                t_contact += t0.elapsed().as_secs_f64();
                n_contact += 1;
            }
        }
        let wall = start.elapsed().as_secs_f64();
        let arm = sim.arm().unwrap();
        let st = arm.stats();
        println!(
            "{name:>22}: {:.2} µs/sample ({} samples, {:.3} s wall), in contact {:.2} µs/sample \
             over {n_contact}; steps/sample {:.2}, in contact {:.2}, max {}; rejected {}; \
             events {}; onsets {:?}; max F_c {f_max:.2} N; phase at end {:?}{}",
            wall / steps as f64 * 1e6,
            sim.k(),
            wall,
            if n_contact > 0 {
                t_contact / n_contact as f64 * 1e6
            } else {
                0.0
            },
            st.steps_per_sample(),
            st.steps_per_contact_sample(),
            st.max_steps_in_a_sample,
            st.integrator.rejected,
            st.integrator.events,
            arm.contact_onsets(),
            arm.phase(),
            failed
                .map(|f| format!("; FAILED at {f}"))
                .unwrap_or_default(),
        );
    }
}
