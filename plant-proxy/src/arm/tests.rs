use super::dopri5::{Dopri5, IntegrationError, OdeSystem, Stop, Tolerances};
use super::guidance::{Action, Guidance};
use super::*;
use control::arm::dynamics::{ArmModel, TORQUE_MAP};
use nalgebra::{SVector, Vector2, Vector4};

const TS: f64 = 0.0005;

fn kv() -> ContactModel {
    ContactModel::kelvin_voigt(2e5, 5.0).unwrap()
}

/// A state with the arm swinging: joint rates and a sampler velocity off the vertical.
fn swinging(height: f64) -> ArmState {
    let mut x = ArmState::zeros();
    x[0] = std::f64::consts::FRAC_PI_4;
    x[1] = std::f64::consts::FRAC_PI_2;
    x[3] = height;
    x[4] = 0.3;
    x[5] = -0.5;
    x[6] = 0.02;
    x[7] = -0.1;
    x
}

/// The positions and velocities of the points `(a, b)` of the arm (module docs of
/// `control::arm::dynamics`), written out from (7.3)–(7.8) independently of `ArmModel`.
fn point(a: f64, b: f64, x: &ArmState) -> (Vector2<f64>, Vector2<f64>) {
    let (t1, t2) = (x[0], x[1]);
    let (s1, c1) = t1.sin_cos();
    let (s12, c12) = (t1 + t2).sin_cos();
    let (w1, w12) = (x[4], x[4] + x[5]);
    let p = Vector2::new(x[2] + a * c1 + b * c12, x[3] + a * s1 + b * s12);
    let v = Vector2::new(
        x[6] - a * w1 * s1 - b * w12 * s12,
        x[7] + a * w1 * c1 + b * w12 * c12,
    );
    (p, v)
}

/// The angular momentum about the origin: `Σ m (p × v) + Ī_1 θ̇_1 + Ī_2 (θ̇_1 + θ̇_2)`.
fn angular_momentum(p: &control::arm::dynamics::ArmParams, x: &ArmState) -> f64 {
    let bodies = [
        (p.m_s, 0.0, 0.0),
        (p.m1, p.r1, 0.0),
        (p.m2, p.l1, p.r2),
        (p.m_sc, p.l1, p.l2),
    ];
    let mut h = p.i1 * x[4] + p.i2 * (x[4] + x[5]);
    for (m, a, b) in bodies {
        let (pos, vel) = point(a, b, x);
        h += m * (pos.x * vel.y - pos.y * vel.x);
    }
    h
}

// ---------------------------------------------------------------------------------------
// Dormand–Prince on problems with known solutions.

/// `ẍ = −x`: `x = cos t`, `ẋ = −sin t` from `(1, 0)`.
struct Oscillator;

impl OdeSystem<2> for Oscillator {
    fn rhs(&self, _t: f64, x: &SVector<f64, 2>) -> Option<SVector<f64, 2>> {
        Some(SVector::<f64, 2>::new(x[1], -x[0]))
    }
}

fn tol(rtol: f64) -> Tolerances {
    Tolerances {
        rtol,
        atol: rtol,
        event_time: 1e-13,
    }
}

#[test]
fn dopri5_follows_the_oscillator_to_its_tolerance_and_tighter_tolerances_do_better() {
    let mut errors = Vec::new();
    for rtol in [1e-6, 1e-9, 1e-12] {
        let mut ode = Dopri5::<2>::new(tol(rtol), 1e-3, 1.0);
        let (mut t, mut x) = (0.0, SVector::<f64, 2>::new(1.0, 0.0));
        let mut budget = 1_000_000;
        let stop = ode
            .integrate(&Oscillator, &mut t, &mut x, 10.0, |_, _| 1.0, &mut budget)
            .unwrap();
        assert_eq!(stop, Stop::End);
        assert_eq!(t, 10.0);
        let err = (x[0] - 10f64.cos()).abs().max((x[1] + 10f64.sin()).abs());
        // A global error within a few hundred local tolerances over 10 s.
        assert!(err < 300.0 * rtol, "rtol {rtol}: error {err}");
        errors.push((err, ode.stats().accepted));
    }
    assert!(
        errors[1].0 < errors[0].0 && errors[2].0 < errors[1].0,
        "{errors:?}"
    );
    assert!(
        errors[1].1 > errors[0].1,
        "tighter tolerance, more steps: {errors:?}"
    );
}

#[test]
fn dopri5_locates_a_zero_crossing_on_its_dense_output() {
    // x = cos t crosses 0 downward at π/2 and upward at 3π/2; g = x stops at the first.
    let mut ode = Dopri5::<2>::new(tol(1e-10), 0.3, 1.0);
    let (mut t, mut x) = (0.0, SVector::<f64, 2>::new(1.0, 0.0));
    let mut budget = 100_000;
    let stop = ode
        .integrate(&Oscillator, &mut t, &mut x, 10.0, |_, x| x[0], &mut budget)
        .unwrap();
    let Stop::Event { t_lo } = stop else {
        panic!("no event: {stop:?}")
    };
    let half_pi = std::f64::consts::FRAC_PI_2;
    assert!(t_lo <= t && t - t_lo <= 1e-13, "bracket [{t_lo}, {t}]");
    assert!((t - half_pi).abs() < 1e-9, "located at {t}");
    assert!(x[0] < 0.0 && x[0] > -1e-9, "x at the event: {}", x[0]);
    assert!((x[1] + 1.0).abs() < 1e-9);
    assert_eq!(ode.stats().events, 1);
    // Going on with the opposite sign finds the next crossing, at 3π/2.
    let stop = ode
        .integrate(&Oscillator, &mut t, &mut x, 10.0, |_, x| -x[0], &mut budget)
        .unwrap();
    assert!(matches!(stop, Stop::Event { .. }));
    assert!((t - 3.0 * half_pi).abs() < 1e-9, "located at {t}");
}

#[test]
fn dopri5_stops_with_an_error_instead_of_looping() {
    let mut ode = Dopri5::<2>::new(tol(1e-12), 1e-3, 1.0);
    let (mut t, mut x) = (0.0, SVector::<f64, 2>::new(1.0, 0.0));
    let mut budget = 5;
    let e = ode
        .integrate(&Oscillator, &mut t, &mut x, 10.0, |_, _| 1.0, &mut budget)
        .unwrap_err();
    assert!(matches!(e, IntegrationError::StepBudget { .. }), "{e}");
    assert_eq!(budget, 0);
    assert!(t > 0.0 && t < 10.0);

    struct Broken;
    impl OdeSystem<1> for Broken {
        fn rhs(&self, t: f64, _x: &SVector<f64, 1>) -> Option<SVector<f64, 1>> {
            (t < 0.5).then(|| SVector::<f64, 1>::new(1.0))
        }
    }
    let mut ode = Dopri5::<1>::new(tol(1e-8), 0.1, 1.0);
    let (mut t, mut x) = (0.0, SVector::<f64, 1>::new(0.0));
    let mut budget = 1000;
    let e = ode
        .integrate(&Broken, &mut t, &mut x, 1.0, |_, _| 1.0, &mut budget)
        .unwrap_err();
    assert!(matches!(e, IntegrationError::Rhs { t } if t >= 0.5), "{e}");
}

#[test]
fn dopri5_steps_over_an_interval_below_the_resolution_of_t() {
    // What an event or a phase change a hair before the end of a period leaves.
    let mut ode = Dopri5::<2>::new(tol(1e-10), 1e-4, 1.0);
    let x0 = SVector::<f64, 2>::new(1.0, 0.0);
    let (mut t, mut x) = (2.0, x0);
    let t_end = 2.0 + 4.0 * f64::EPSILON;
    let mut budget = 10;
    let stop = ode
        .integrate(&Oscillator, &mut t, &mut x, t_end, |_, _| 1.0, &mut budget)
        .unwrap();
    assert_eq!((stop, t, x), (Stop::End, t_end, x0));
    assert_eq!(budget, 10);
}

/// The arm's equations with constant torques and no contact, for the reference crate.
struct FreeArm {
    model: ArmModel,
    tau: Vector2<f64>,
}

impl FreeArm {
    fn derivative(&self, x: &[f64]) -> [f64; 8] {
        let q = Vector4::new(x[0], x[1], x[2], x[3]);
        let qd = Vector4::new(x[4], x[5], x[6], x[7]);
        let force = ArmModel::generalized_force(&self.tau, 0.0, 0.0);
        let qdd = self.model.accelerations(&q, &qd, &force).unwrap();
        [qd[0], qd[1], qd[2], qd[3], qdd[0], qdd[1], qdd[2], qdd[3]]
    }
}

impl ode_solvers::System<f64, ode_solvers::SVector<f64, 8>> for FreeArm {
    fn system(
        &self,
        _t: f64,
        y: &ode_solvers::SVector<f64, 8>,
        dy: &mut ode_solvers::SVector<f64, 8>,
    ) {
        let d = self.derivative(y.as_slice());
        dy.as_mut_slice().copy_from_slice(&d);
    }
}

/// The reference crate's Dormand–Prince from `y0` to `t_end` (its per-step output: the
/// last entry is at `t_end`).
fn reference(
    system: FreeArm,
    y0: ode_solvers::SVector<f64, 8>,
    t_end: f64,
) -> ode_solvers::SVector<f64, 8> {
    let mut ode = ode_solvers::Dopri5::new(system, 0.0, t_end, t_end, y0, 1e-12, 1e-14);
    ode.set_output(ode_solvers::OutputType::Sparse);
    ode.integrate().expect("reference integration");
    assert_eq!(*ode.x_out().last().unwrap(), t_end);
    *ode.y_out().last().unwrap()
}

/// A free-flying arm (no contact, thrust off) from `x0`, advanced `n` samples with `tau`.
fn free_flight(x0: ArmState, tau: [f64; 2], n: usize, rtol: f64) -> ArmSim {
    let mut p = ArmPlantParams::chapter(kv());
    p.initial_height = 1000.0;
    p.integrator.rtol = rtol;
    p.integrator.atol = rtol * 1e-2;
    let mut sim = ArmSim::new(&p, TS).unwrap();
    sim.set_state(x0);
    for _ in 0..n {
        sim.advance(tau).unwrap();
    }
    sim
}

#[test]
fn dopri5_matches_the_reference_crate_on_a_free_flight_with_torques() {
    let x0 = swinging(1000.0);
    let tau = [0.8, -0.3];
    let n = 2000; // 1 s
    let sim = free_flight(x0, tau, n, 1e-11);
    let system = FreeArm {
        model: ArmModel::new(control::arm::dynamics::ArmParams::CHAPTER_7),
        tau: Vector2::new(tau[0], tau[1]),
    };
    let y0 = ode_solvers::SVector::<f64, 8>::from_column_slice(x0.as_slice());
    let t_end = n as f64 * TS;
    let y_ref = reference(system, y0, t_end);
    let x = sim.state();
    for i in 0..8 {
        assert!(
            (x[i] - y_ref[i]).abs() < 1e-8 * (1.0 + y_ref[i].abs()),
            "component {i}: {} vs the reference {}",
            x[i],
            y_ref[i]
        );
    }
    // The torques moved the arm: the comparison is not of a trivial trajectory.
    assert!((x[5] - x0[5]).abs() > 0.1, "θ̇_2 barely changed: {}", x[5]);
}

// ---------------------------------------------------------------------------------------
// Conservation and the energy identity along the plant's trajectories.

#[test]
fn a_free_flight_without_torque_or_thrust_conserves_energy_and_momenta() {
    let x0 = swinging(1000.0);
    let model = ArmModel::new(control::arm::dynamics::ArmParams::CHAPTER_7);
    let q = |x: &ArmState| Vector4::new(x[0], x[1], x[2], x[3]);
    let qd = |x: &ArmState| Vector4::new(x[4], x[5], x[6], x[7]);
    let t0 = model.kinetic_energy(&q(&x0), &qd(&x0));
    let p0 = model.linear_momentum(&q(&x0), &qd(&x0));
    let h0 = angular_momentum(&model.params, &x0);
    let rtol = 1e-8;
    let mut p = ArmPlantParams::chapter(kv());
    p.initial_height = 1000.0;
    p.integrator.rtol = rtol;
    p.integrator.atol = 1e-10;
    let mut sim = ArmSim::new(&p, TS).unwrap();
    sim.set_state(x0);
    let (mut max_dt, mut max_dp, mut max_dh) = (0.0f64, 0.0f64, 0.0f64);
    for k in 0..40_000 {
        // 20 s
        sim.advance([0.0, 0.0]).unwrap();
        if k % 100 == 0 {
            let x = sim.state();
            max_dt = max_dt.max((sim.kinetic_energy() - t0).abs() / t0);
            max_dp = max_dp.max((sim.linear_momentum() - p0).norm() / p0.norm());
            max_dh = max_dh.max((angular_momentum(&model.params, x) - h0).abs() / h0.abs());
        }
    }
    assert_eq!(sim.phase(), Phase::Descent, "the thrusters stayed off");
    assert!(!sim.in_contact());
    // The arm really moved: its joints turned by more than a radian.
    assert!(
        (sim.state()[1] - x0[1]).abs() > 1.0,
        "θ_2 = {}",
        sim.state()[1]
    );
    // Measured: about 1e-13 relative; the bound is the tolerance itself.
    let bound = rtol;
    assert!(
        max_dt < bound,
        "kinetic energy drifted by {max_dt:e} (relative)"
    );
    assert!(
        max_dp < bound,
        "linear momentum drifted by {max_dp:e} (relative)"
    );
    assert!(
        max_dh < bound,
        "angular momentum drifted by {max_dh:e} (relative)"
    );
}

#[test]
fn the_kinetic_energy_changes_by_the_work_of_the_torques() {
    // dT/dt = q̇ᵀ Q = τ_1 θ̇_1 + τ_2 (θ̇_1 + θ̇_2) with Q = L τ (the energy identity
    // q̇ᵀ(Ṁ − 2D)q̇ = 0 along the plant's own trajectory); the work by the trapezoid rule
    // on the samples.
    let x0 = swinging(1000.0);
    let tau = [1.5, -0.7];
    let mut p = ArmPlantParams::chapter(kv());
    p.initial_height = 1000.0;
    p.integrator.rtol = 1e-11;
    p.integrator.atol = 1e-13;
    let mut sim = ArmSim::new(&p, TS).unwrap();
    sim.set_state(x0);
    let power = |x: &ArmState| tau[0] * x[4] + tau[1] * (x[4] + x[5]);
    let t_start = sim.kinetic_energy();
    let mut work = 0.0;
    for _ in 0..4000 {
        let before = power(sim.state());
        sim.advance(tau).unwrap();
        work += 0.5 * TS * (before + power(sim.state()));
    }
    let change = sim.kinetic_energy() - t_start;
    assert!(change.abs() > 0.1, "the torques did little work: {change}");
    assert!(
        (change - work).abs() < 1e-5 * change.abs(),
        "ΔT = {change}, work = {work}"
    );
}

#[test]
fn the_mass_matrix_is_symmetric_positive_definite_over_the_workspace() {
    for m_s in [1.0, 1.5] {
        let mut params = control::arm::dynamics::ArmParams::CHAPTER_7;
        params.m_s = m_s;
        let model = ArmModel::new(params);
        let n = 48;
        for i in 0..n {
            for j in 0..n {
                let th1 = -std::f64::consts::PI + 2.0 * std::f64::consts::PI * i as f64 / n as f64;
                let th2 = -std::f64::consts::PI + 2.0 * std::f64::consts::PI * j as f64 / n as f64;
                let q = Vector4::new(th1, th2, 0.3, -0.01);
                let m = model.mass_matrix(&q);
                assert!((m - m.transpose()).abs().max() < 1e-12);
                let eig = m.symmetric_eigen().eigenvalues;
                let min = eig.iter().cloned().fold(f64::INFINITY, f64::min);
                // Bounded away from 0 by the inertias: no singular configuration.
                assert!(
                    min > 0.05,
                    "λ_min(M) = {min} at θ = ({th1}, {th2}), m_s = {m_s}"
                );
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// Contact and friction.

#[test]
fn kelvin_voigt_gives_7_27_in_contact_and_nothing_else() {
    let s = Surface::chapter(kv());
    // In contact: −k_s y − c_s ẏ.
    assert!((s.contact_force(-1e-3, -0.01, -0.1) - (200.0 + 0.05)).abs() < 1e-12);
    assert!((s.contact_force(-1e-4, 0.001, -0.1) - (20.0 - 0.005)).abs() < 1e-12);
    // Above the surface: no force, whatever the velocity.
    assert_eq!(s.contact_force(1e-6, -1.0, -0.1), 0.0);
    assert_eq!(s.contact_force(0.0, -1.0, -0.1), 0.0);
    // Never adhesive: leaving faster than the material recovers gives 0, not a pull.
    assert_eq!(s.raw_force(-1e-4, 10.0, -0.1), 20.0 - 50.0);
    assert_eq!(s.contact_force(-1e-4, 10.0, -0.1), 0.0);
    // The switching function is positive exactly when the force acts.
    assert!(s.switching(-1e-4, 0.001, -0.1) > 0.0);
    assert!(s.switching(-1e-4, 10.0, -0.1) < 0.0);
    assert!(s.switching(1e-4, -1.0, -0.1) < 0.0);
}

#[test]
fn hunt_crossley_gives_7_28_with_the_recorded_contact_velocity() {
    let s = Surface::chapter(ContactModel::hunt_crossley(2e5, 0.9).unwrap());
    let (y, yd, yd0) = (-1e-4, -0.05, -0.1);
    // k_s (−y)^{3/2} (1 + 3(1 − c_r)/2 · ẏ/ẏ_0) = 2e5 · 1e-6 · (1 + 0.15 · 0.5).
    let expected = 2e5 * 1e-6 * (1.0 + 0.15 * 0.5);
    assert!((s.contact_force(y, yd, yd0) - expected).abs() < 1e-12);
    // Restitution phase (ẏ > 0): less force; c_r = 1 removes the velocity term.
    assert!(s.contact_force(y, 0.05, yd0) < 2e5 * 1e-6);
    let elastic = Surface::chapter(ContactModel::hunt_crossley(2e5, 1.0).unwrap());
    assert!((elastic.contact_force(y, 0.05, yd0) - 0.2).abs() < 1e-12);
    // Never adhesive, nothing above the surface.
    let fast_up = 2.0 * 0.1 / (3.0 * 0.1) + 1.0; // beyond −ẏ_0 · 2/(3(1 − c_r))
    assert!(s.raw_force(y, fast_up, yd0) < 0.0);
    assert_eq!(s.contact_force(y, fast_up, yd0), 0.0);
    assert_eq!(s.contact_force(1e-3, -0.1, yd0), 0.0);
    assert_eq!(s.raw_force(1e-3, -0.1, yd0), 0.0);
}

#[test]
fn the_hysteretic_family_holds_7_28_and_its_other_readings() {
    let (y, yd, yd0) = (-1e-4, -0.05, -0.1);
    for (k, c_r) in [(2e5, 0.9), (300.0, 0.1), (1e4, 1.0)] {
        let printed = Surface::chapter(ContactModel::hunt_crossley(k, c_r).unwrap());
        let family = Surface::chapter(ContactModel::hysteretic(k, 1.5, 1.5 * (1.0 - c_r)).unwrap());
        let (a, b) = (printed.raw_force(y, yd, yd0), family.raw_force(y, yd, yd0));
        assert!((a - b).abs() <= 1e-12 * a.abs(), "{k} {c_r}: {a} {b}");
    }
    // n = 1 with χ = 0.5 while pressing in at half the onset speed: k δ (1 + 0.25).
    let linear = Surface::chapter(ContactModel::hysteretic(2e5, 1.0, 0.5).unwrap());
    assert!((linear.contact_force(y, yd, yd0) - 2e5 * 1e-4 * 1.25).abs() < 1e-9);
    // χ < 0: less force while pressing in than the elastic part alone.
    let speed = Surface::chapter(ContactModel::hysteretic(2e5, 1.5, -0.15).unwrap());
    assert!(speed.contact_force(y, yd, yd0) < 2e5 * 1e-6);
    assert_eq!(
        ContactModel::hysteretic(2e5, 0.0, 0.1).unwrap_err().field,
        "exponent"
    );
    assert_eq!(
        ContactModel::hysteretic(2e5, 1.5, f64::NAN)
            .unwrap_err()
            .field,
        "hysteresis"
    );
}

#[test]
fn friction_is_regularized_coulomb_7_29() {
    let s = Surface::chapter(kv());
    let f_c = 25.0;
    // Sliding: −μ F_c sgn(ẋ).
    assert_eq!(s.friction_force(f_c, 1e-3), -12.5);
    assert_eq!(s.friction_force(f_c, -0.2), 12.5);
    assert_eq!(s.friction_force(f_c, 1e-4), -12.5);
    // Below 1e-4 m/s: linear in ẋ, through 0.
    assert!((s.friction_force(f_c, 5e-5) + 6.25).abs() < 1e-12);
    assert!((s.friction_force(f_c, -2.5e-5) - 3.125).abs() < 1e-12);
    assert_eq!(s.friction_force(f_c, 0.0), 0.0);
    // No normal force, no friction.
    assert_eq!(s.friction_force(0.0, 1.0), 0.0);
}

#[test]
fn bad_surfaces_are_refused_naming_the_coefficient() {
    assert_eq!(
        ContactModel::kelvin_voigt(0.0, 1.0).unwrap_err().field,
        "stiffness"
    );
    assert_eq!(
        ContactModel::kelvin_voigt(1.0, -1.0).unwrap_err().field,
        "damping"
    );
    assert_eq!(
        ContactModel::kelvin_voigt(f64::NAN, 1.0).unwrap_err().field,
        "stiffness"
    );
    assert_eq!(
        ContactModel::hunt_crossley(1.0, 1.5).unwrap_err().field,
        "restitution"
    );
    assert_eq!(
        ContactModel::hunt_crossley(-1.0, 0.5).unwrap_err().field,
        "stiffness"
    );
    let mut s = Surface::chapter(kv());
    s.friction = -0.1;
    assert_eq!(s.validate().unwrap_err().field, "friction");
    s.friction = 0.5;
    s.friction_regularization = 0.0;
    assert_eq!(s.validate().unwrap_err().field, "friction-regularization");
}

// ---------------------------------------------------------------------------------------
// Events, the hold and the guidance.

#[test]
fn contact_onset_is_located_at_two_seconds_with_zero_torque() {
    let mut sim = ArmSim::new(&ArmPlantParams::chapter(kv()), TS).unwrap();
    for _ in 0..4100 {
        sim.advance([0.0, 0.0]).unwrap();
        if sim.contact_onsets()[0].is_some() {
            break;
        }
    }
    let onset = sim.contact_onsets()[0].expect("no contact");
    // 0.2 m at 0.1 m/s.
    assert!((onset - 2.0).abs() < 1e-9, "onset at {onset}");
    // The first sample at or after the onset is in the contact phase, with r = F_d.
    assert_eq!(sim.k(), (onset / TS).ceil() as u64);
    assert_eq!(sim.phase(), Phase::Contact);
    assert_eq!(sim.command(), 25.0);
    assert!(sim.in_contact());
    // Half a period after the onset the sampler has gone 5e-5 m into the surface
    // (the bodies barely slowed), and the force is Kelvin–Voigt's.
    let x = sim.state();
    assert!((x[3] + 0.1 * TS).abs() < 1e-6, "y = {}", x[3]);
    let expected = -2e5 * x[3] - 5.0 * x[7];
    assert!((sim.contact_force() - expected).abs() < 1e-9);
}

#[test]
fn the_located_onset_is_where_the_reference_trajectory_reaches_the_surface() {
    // A swinging arm: the sampler's height is not linear in time.
    let mut p = ArmPlantParams::chapter(kv());
    p.integrator.rtol = 1e-11;
    p.integrator.atol = 1e-13;
    let mut sim = ArmSim::new(&p, TS).unwrap();
    let mut x0 = swinging(0.2);
    x0[4] = 0.05;
    x0[5] = -0.05;
    sim.set_state(x0);
    let mut n = 0;
    while sim.contact_onsets()[0].is_none() {
        sim.advance([0.0, 0.0]).unwrap();
        n += 1;
        assert!(n < 20_000, "no contact in 10 s");
    }
    let onset = sim.contact_onsets()[0].unwrap();
    let system = FreeArm {
        model: ArmModel::new(control::arm::dynamics::ArmParams::CHAPTER_7),
        tau: Vector2::zeros(),
    };
    let y0 = ode_solvers::SVector::<f64, 8>::from_column_slice(x0.as_slice());
    let at_onset = reference(system, y0, onset);
    // |y(t_onset)| within the event tolerance times the speed, plus the integration error.
    assert!(
        at_onset[3].abs() < 1e-9,
        "y at the located onset: {}",
        at_onset[3]
    );
    assert!(
        at_onset[7] < -0.01,
        "the sampler arrives moving down: {}",
        at_onset[7]
    );
    assert!(
        (onset - 2.0).abs() > 1e-3,
        "the swing did not change the onset: {onset}"
    );
}

#[test]
fn torques_are_held_over_the_period_and_enter_through_l() {
    let p = ArmPlantParams::chapter(kv());
    let model = ArmModel::new(p.spacecraft);
    let mut sim = ArmSim::new(&p, TS).unwrap();
    let (q0, qd0) = (sim.q(), sim.qd());
    let tau = Vector2::new(0.0, 2.0);
    let force = ArmModel::generalized_force(&tau, 0.0, 0.0);
    let qdd = model.accelerations(&q0, &qd0, &force).unwrap();
    // The measurement at k = 0 does not see τ_0.
    let (mut y, mut z) = ([0.0; 7], [0.0; 1]);
    sim.write_outputs(&mut y, &mut z);
    assert_eq!([y[2], y[3]], [0.0, 0.0]);
    sim.advance([tau[0], tau[1]]).unwrap();
    let dqd = sim.qd() - qd0;
    // Over one period the held torque gives q̈ T (q̈ barely changes in 0.5 ms).
    let scale = (qdd * TS).norm();
    for i in 0..4 {
        assert!(
            (dqd[i] - qdd[i] * TS).abs() < 1e-3 * scale,
            "q̇_{i}: {} vs q̈ T = {}",
            dqd[i],
            qdd[i] * TS
        );
    }
    // The torques do positive work: (L τ)ᵀ Δθ̇ > 0 (M is positive definite).
    let q_theta = TORQUE_MAP * tau;
    assert!(q_theta[0] * dqd[0] + q_theta[1] * dqd[1] > 0.0);
    // τ_2 alone (Q_θ = [τ_2, τ_2]) turns the elbow the way it pushes it.
    assert!(dqd[1] > 0.0, "θ̇_2 changed by {}", dqd[1]);
    // The opposite torque, the opposite response.
    let mut sim2 = ArmSim::new(&p, TS).unwrap();
    sim2.advance([0.0, -2.0]).unwrap();
    assert!(((sim2.qd() - qd0) + dqd).norm() < 1e-3 * dqd.norm());
    // With an apply offset of one half, τ_0 acts over the second half only.
    let mut sim3 = ArmSim::new(&p, TS).unwrap();
    sim3.set_apply_offset(Some(0.5));
    sim3.advance([tau[0], tau[1]]).unwrap();
    let half = sim3.qd() - qd0;
    assert!((half[1] - 0.5 * dqd[1]).abs() < 1e-3 * dqd[1].abs());
}

#[test]
fn the_guidance_sequences_the_double_maneuver() {
    let p = ArmPlantParams::chapter(kv()).with_second_sampling(kv());
    let second = p.second.unwrap();
    let mut g = Guidance::new(p.guidance, p.second, 423.0);
    assert_eq!(
        (g.phase(), g.maneuver(), g.command()),
        (Phase::Descent, 1, 0.0)
    );
    assert_eq!(g.thrust(-0.1), 0.0, "maneuver 1 descends coasting");
    assert!(g.on_contact_onset(2.0));
    assert_eq!(
        (g.phase(), g.command(), g.thrust(-0.1)),
        (Phase::Contact, 25.0, 0.0)
    );
    assert!(
        !g.on_contact_onset(2.5),
        "a bounce does not restart the phase"
    );
    assert_eq!(g.next_event(), 4.0);
    assert_eq!(g.on_time(4.0), Action::AddSampleMass);
    assert_eq!((g.phase(), g.command()), (Phase::Departure, 0.0));
    // The loop: m_0 K_v (v_ref − v), saturated.
    assert!((g.thrust(0.05) - 423.0 * 2.0 * 0.05).abs() < 1e-9);
    assert_eq!(g.thrust(-1.0), 100.0);
    assert_eq!(g.next_event(), 4.0 + second.ascent_duration);
    assert_eq!(g.on_time(g.next_event()), Action::SwitchSurface);
    assert_eq!((g.phase(), g.maneuver()), (Phase::Descent, 2));
    assert!(
        (g.thrust(-0.1)).abs() < 1e-9,
        "at −0.1 m/s the second descent needs no thrust"
    );
    assert!(g.thrust(0.0) < 0.0);
    assert!(g.on_contact_onset(8.0));
    assert_eq!(g.onsets(), [Some(2.0), Some(8.0)]);
    assert_eq!(g.on_time(10.0), Action::None);
    assert_eq!(g.phase(), Phase::Departure);
    assert_eq!(g.next_event(), f64::INFINITY);
}

#[test]
fn the_sample_mass_and_the_second_surface_arrive_when_the_guidance_says() {
    let second = ContactModel::kelvin_voigt(200.0, 500.0).unwrap();
    let p = ArmPlantParams::chapter(kv()).with_second_sampling(second);
    let mut sim = ArmSim::new(&p, TS).unwrap();
    // A stand-in joint hold keeps the arm's shape.
    let hold = [sim.state()[0], sim.state()[1]];
    let mut mass_added_at = None;
    let mut switched_at = None;
    for k in 0..22_000 {
        let x = *sim.state();
        let q1 = -2000.0 * (x[0] - hold[0]) - 300.0 * x[4];
        let q2 = -2000.0 * (x[1] - hold[1]) - 300.0 * x[5];
        sim.advance([q1 - q2, q2]).unwrap();
        if mass_added_at.is_none() && sim.model().params.m_s > 1.0 {
            mass_added_at = Some(k);
        }
        if switched_at.is_none() && sim.surface().model == second {
            switched_at = Some(k);
            assert!(!sim.in_contact());
        }
    }
    let [t1, t2] = sim.contact_onsets();
    let t1 = t1.expect("first contact");
    let t2 = t2.expect("second contact");
    assert!((t1 - 2.0).abs() < 1e-9);
    assert_eq!(sim.model().params.m_s, 1.5);
    let added = mass_added_at.unwrap() as f64 * TS;
    assert!((added - (t1 + 2.0)).abs() <= TS, "mass added at {added}");
    let switched = switched_at.unwrap() as f64 * TS;
    assert!(
        (switched - (t1 + 2.0 + 1.75)).abs() <= TS,
        "surface switched at {switched}"
    );
    assert!((7.0..9.0).contains(&t2), "second contact at {t2}");
    assert_eq!(sim.phase(), Phase::Departure);
}

#[test]
fn the_chapter_parameters_are_the_defaults_and_bad_ones_are_named() {
    let p = ArmPlantParams::chapter(kv());
    assert!(p.validate().is_ok());
    assert_eq!(p.spacecraft, control::arm::dynamics::ArmParams::CHAPTER_7);
    assert_eq!((p.initial_height, p.descent_speed), (0.2, 0.1));
    assert_eq!(p.surface.friction, 0.5);
    assert_eq!(p.guidance.force_set_point, 25.0);
    let field = |f: &dyn Fn(&mut ArmPlantParams)| {
        let mut q = p;
        f(&mut q);
        q.validate().unwrap_err().field
    };
    assert_eq!(field(&|q| q.spacecraft.m_sc = 0.0), "sampling-arm.m-sc");
    assert_eq!(field(&|q| q.spacecraft.r1 = 3.0), "sampling-arm.r1");
    assert_eq!(field(&|q| q.theta1 = f64::NAN), "sampling-arm.theta1");
    assert_eq!(
        field(&|q| q.theta1 = -std::f64::consts::FRAC_PI_2),
        "sampling-arm.theta1"
    );
    assert_eq!(
        field(&|q| q.initial_height = 0.0),
        "sampling-arm.initial-height"
    );
    assert_eq!(
        field(&|q| q.descent_speed = -0.1),
        "sampling-arm.descent-speed"
    );
    assert_eq!(field(&|q| q.surface.friction = -1.0), "surface.friction");
    assert_eq!(field(&|q| q.guidance.loop_gain = 0.0), "guidance.loop-gain");
    assert_eq!(
        field(&|q| q.guidance.contact_duration = 0.0),
        "guidance.contact-duration"
    );
    assert_eq!(field(&|q| q.integrator.rtol = 0.0), "integrator.rtol");
    assert_eq!(field(&|q| q.integrator.atol = 2.0), "integrator.atol");
    assert_eq!(
        field(&|q| q.integrator.max_steps_per_sample = 0),
        "integrator.max-steps-per-sample"
    );
    let mut q = p.with_second_sampling(kv());
    q.second.as_mut().unwrap().surface.model = ContactModel::HuntCrossley {
        stiffness: 1.0,
        restitution: 2.0,
    };
    assert_eq!(
        q.validate().unwrap_err().field,
        "second-sampling.surface.restitution"
    );
    assert!(ArmSim::new(&q, TS).is_err());
}

#[test]
fn a_period_that_needs_more_steps_than_allowed_is_an_error_not_a_hang() {
    let mut p = ArmPlantParams::chapter(kv());
    p.integrator.max_steps_per_sample = 3;
    p.integrator.rtol = 1e-12;
    p.integrator.atol = 1e-14;
    let mut sim = ArmSim::new(&p, TS).unwrap();
    let mut x = swinging(0.2);
    x[4] = 30.0;
    sim.set_state(x);
    let e = sim.advance([50.0, -50.0]).unwrap_err();
    assert!(
        matches!(
            e,
            ArmError::Integration {
                k: 0,
                cause: IntegrationError::StepBudget { .. }
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("max-steps-per-sample"));
}
