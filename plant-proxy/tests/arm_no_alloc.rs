//! The sampling arm's per-sample path allocates nothing: `PlantSim::sample` and
//! `PlantSim::advance` of `scenarios/arm/double-linear.toml` (with measurement noise and an
//! apply offset), through the descent, both contact phases with their events, the mass
//! change and the surface switch, run under the RT-aware allocator of `ipc_types::rt_alloc`
//! with the thread's pool entered: neither the pool nor the system allocator serves
//! anything.

use ipc_types::rt_alloc::{RtAwareAllocator, enter_rt_thread, thread_stats};
use plant_proxy::scenario;
use plant_proxy::sim::PlantSim;
use std::path::Path;

#[global_allocator]
static ALLOCATOR: RtAwareAllocator = RtAwareAllocator;

#[test]
fn stepping_the_arm_through_a_double_maneuver_does_not_allocate() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/arm/double-linear.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let noisy = text.replace(
        "y-std = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]",
        "y-std = [1e-4, 1e-4, 1e-3, 1e-3, 1e-4, 1e-4, 0.05]",
    );
    let s = scenario::parse(&noisy, "double-linear").unwrap();
    let mut sim = PlantSim::new(&s.plant, s.rig.sample_period).unwrap();
    sim.set_apply_offset(Some(0.25)).unwrap();
    let (mut y, mut z, mut r) = ([0.0; 7], [0.0; 1], [0.0; 1]);
    let mut u = [0.0; 2];
    sim.sample(&mut y, &mut z, &mut r).unwrap();
    let hold = [y[0], y[1]];
    let steps = s.run_steps(None).unwrap();

    enter_rt_thread(64);
    let before = thread_stats();
    let mut in_contact = 0u64;
    for _ in 0..steps {
        sim.sample(&mut y, &mut z, &mut r).unwrap();
        // A stand-in joint hold: τ = L⁻¹(−K_p (θ̄ − θ̄_0) − K_d θ̄̇).
        let q1 = -2000.0 * (y[0] - hold[0]) - 300.0 * y[2];
        let q2 = -2000.0 * (y[1] - hold[1]) - 300.0 * y[3];
        u[0] = q1 - q2;
        u[1] = q2;
        sim.advance(&u).unwrap();
        in_contact += u64::from(r[0] > 0.0);
    }
    let used = thread_stats().since(&before);

    assert!(used.installed && used.counted, "{used:?}");
    assert_eq!(used.system_on_rt_thread, 0, "{used:?}");
    assert_eq!(used.pool_served, 0, "{used:?}");
    // The run went through both contact phases and the events they bring.
    let arm = sim.arm().unwrap();
    let [first, second] = arm.contact_onsets();
    assert!(
        first.is_some() && second.is_some(),
        "{:?}",
        arm.contact_onsets()
    );
    assert!(in_contact >= 7900, "{in_contact} samples with r = F_d");
    assert!(arm.stats().integrator.events >= 2);
    assert_eq!(arm.model().params.m_s, 1.5);
}
