//! The sampling-arm controller (Algorithm 3) in closed loop with the simulated
//! spacecraft ([`arm_support`]): robust and augmented control of the contact force, the
//! joint hold, faults, torque limits, a second contact, refused parameters.

#![allow(clippy::needless_range_loop)]

mod arm_support;

use arm_support::*;
use control::arm::controller::{ArmController, ArmControllerParams, ArmMode};
use control::{Controller, Dimensions, OutputLimits, StepInput, status};
use nalgebra::{Vector2, Vector4};

/// `χ = [ẋ, ẏ, e]` over a contact of `samples` at `surface`: the values per sample.
fn contact_run(c: &mut ArmController, surface: Surface, samples: u64) -> Vec<[f64; 3]> {
    let mut sc = Spacecraft::at_contact(surface);
    let mut chi = Vec::new();
    for k in 0..samples {
        let y = sc.measure();
        chi.push([y[4], y[5], y[6] - F_D]);
        let (u, s) = step(c, &sc, k, F_D);
        assert_eq!(s & status::CONTROLLER_FAULT, 0, "fault at sample {k}");
        sc.advance(&u);
    }
    chi
}

/// The largest `|χ_i| / scale_i` over the samples from `from` on.
fn worst_after(chi: &[[f64; 3]], from: usize) -> [f64; 3] {
    let mut w = [0.0_f64; 3];
    for c in &chi[from..] {
        for i in 0..3 {
            w[i] = w[i].max(c[i].abs());
        }
    }
    w
}

#[test]
fn robust_and_pcac_drive_chi_to_zero_on_the_linear_surface() {
    // Figure 7.4's surface; the gain is designed on it (K stands in for the LMI design).
    let surface = Surface {
        k_s: 2.0e5,
        c_s: 5.0,
        mu: 0.5,
    };
    let k = test_gain();
    assert!(closed_loop_radius(&k, surface.k_s, surface.c_s) < 1.0);
    let mut robust = ArmController::new(&ArmControllerParams::robust_only(k), rig()).unwrap();
    let mut augmented = augmented_with(k);
    let samples = 4000; // the 2 s contact phase
    for (name, c) in [("robust", &mut robust), ("robust + PCAC", &mut augmented)] {
        let chi = contact_run(c, surface, samples);
        let start = chi[0];
        let w = worst_after(&chi, 3000);
        eprintln!("{name}: χ_0 = {start:?}, max |χ| over the last 0.5 s = {w:?}");
        assert!(w[0] < 1e-3 && w[1] < 1e-3, "{name}: sampler velocity {w:?}");
        assert!(w[2] < 0.05 * F_D, "{name}: force error {}", w[2]);
        assert_eq!(c.mode(), ArmMode::Contact);
        assert_eq!(c.counts_of().contact_phases, 1);
    }
    let p = augmented.pcac().unwrap();
    assert!(p.counts_of().solved > 3900, "{:?}", p.counts_of());
    assert!(augmented.forgetting_factor().unwrap() <= 1.0);
    assert_eq!(augmented.model_coefficients().unwrap().len(), 35);
}

#[test]
fn out_of_contact_the_joints_hold_the_latched_angles() {
    let k = test_gain();
    let mut c = ArmController::new(&ArmControllerParams::robust_only(k), rig()).unwrap();
    // Above the surface (no contact force), the arm disturbed by a joint rate.
    let mut sc = Spacecraft::at_contact(Surface {
        k_s: 0.0,
        c_s: 0.0,
        mu: 0.0,
    });
    sc.q[3] = 0.5;
    sc.qd = Vector4::new(0.05, -0.05, 0.0, -0.1);
    let latched = Vector2::new(sc.q[0], sc.q[1]);
    for k in 0..6000 {
        let (u, s) = step(&mut c, &sc, k, 0.0);
        assert_eq!(s, status::OK);
        sc.advance(&u);
    }
    assert_eq!(c.mode(), ArmMode::Hold);
    let err = (Vector2::new(sc.q[0], sc.q[1]) - latched).amax();
    assert!(err < 2e-3, "joint angles moved by {err} rad from the latch");
    assert!(sc.qd[0].abs() + sc.qd[1].abs() < 1e-3);
    assert_eq!(c.counts_of().hold_phases, 1);
    // A second hold phase latches again.
    step(&mut c, &sc, 6000, F_D);
    step(&mut c, &sc, 6001, 0.0);
    assert_eq!(c.counts_of().hold_phases, 2);
    assert_eq!(c.counts_of().contact_phases, 1);
}

#[test]
fn a_bad_sample_holds_the_last_torques_and_teaches_pcac_nothing() {
    let k = test_gain();
    let mut c = augmented_with(k);
    let sc = Spacecraft::at_contact(Surface {
        k_s: 2.0e5,
        c_s: 5.0,
        mu: 0.5,
    });
    let (u0, _) = step(&mut c, &sc, 0, F_D);
    let (u1, _) = step(&mut c, &sc, 1, F_D);
    let theta = c.model_coefficients().unwrap().to_vec();
    for (i, bad) in [f64::NAN, f64::INFINITY].into_iter().enumerate() {
        let mut y = sc.measure();
        y[5] = bad;
        let mut u = [0.0; 2];
        let s = c.step(
            &StepInput {
                seq: 2 + i as u64,
                y: &y,
                z: &[0.0],
                r: &[F_D],
                u_applied: None,
                lost: 0,
            },
            &mut u,
        );
        assert_eq!(s, status::CONTROLLER_FAULT);
        assert_eq!(u, u1, "the last torques are held");
        assert_eq!(c.model_coefficients().unwrap(), &theta[..]);
    }
    // A non-finite command, and a stretched arm (no linearization), are faults too.
    let mut u = [0.0; 2];
    let y = sc.measure();
    let s = c.step(
        &StepInput {
            y: &y,
            r: &[f64::NAN],
            ..Default::default()
        },
        &mut u,
    );
    assert_eq!((s, u), (status::CONTROLLER_FAULT, u1));
    let mut stretched = y;
    stretched[1] = 0.0;
    let s = c.step(
        &StepInput {
            y: &stretched,
            r: &[F_D],
            ..Default::default()
        },
        &mut u,
    );
    assert_eq!((s, u), (status::CONTROLLER_FAULT, u1));
    assert_eq!(c.counts_of().faults, 4);
    assert_eq!(c.counts_of().singular, 1);
    // PCAC counts the faulty samples as lost and bridges them.
    let bridged = c.pcac().unwrap().counts_of().bridged;
    let (u2, s) = step(&mut c, &sc, 6, F_D);
    assert_eq!(s & status::CONTROLLER_FAULT, 0);
    assert!(u2.iter().all(|v| v.is_finite()) && u0.iter().all(|v| v.is_finite()));
    assert_eq!(c.pcac().unwrap().counts_of().bridged, bridged + 4);
}

#[test]
fn torque_limits_clip_and_pcac_learns_from_the_clipped_input() {
    let k = test_gain();
    let params = ArmControllerParams {
        pcac: Some(chapter_pcac()),
        limits: Some(OutputLimits::symmetric(20.0, 2)),
        ..ArmControllerParams::robust_only(k)
    };
    let mut c = ArmController::new(&params, rig()).unwrap();
    let mut sc = Spacecraft::at_contact(Surface {
        k_s: 2.0e5,
        c_s: 5.0,
        mu: 0.5,
    });
    let mut saturated = 0;
    for k in 0..400 {
        let (u, s) = step(&mut c, &sc, k, F_D);
        assert!(u.iter().all(|v| v.abs() <= 20.0));
        if s & status::SATURATED != 0 {
            saturated += 1;
            // The u_aug the plant received is what the clipped torques amount to.
            let terms = c
                .linearization()
                .terms(&Vector2::new(sc.q[0], sc.q[1]), &sc.qd, sc.measure()[6])
                .unwrap();
            let eff = terms.virtual_input(&Vector2::new(u[0], u[1])).unwrap();
            let ur = c.robust_input();
            let want = [eff[0] - ur[0], eff[1] - ur[1]];
            assert!((c.applied_augmentation()[0] - want[0]).abs() < 1e-9);
            assert!((c.applied_augmentation()[1] - want[1]).abs() < 1e-9);
        }
        sc.advance(&u);
    }
    assert!(saturated > 0, "the limits never bound");
    assert_eq!(c.counts_of().saturated, saturated);
}

#[test]
fn a_second_contact_with_another_surface_makes_lambda_drop_at_once() {
    let k = test_gain();
    let mut c = augmented_with(k);
    // §7.3.3: first surface k_s = 2·10⁵, c_s = 5; the second k_s = 200, c_s = 500.
    let first = Surface {
        k_s: 2.0e5,
        c_s: 5.0,
        mu: 0.5,
    };
    let second = Surface {
        k_s: 200.0,
        c_s: 500.0,
        mu: 0.5,
    };
    contact_run(&mut c, first, 4000);
    let trace_before = c.covariance_trace().unwrap();
    // The hold between the contacts (PCAC is not stepped), then the second contact.
    let sc = Spacecraft::at_contact(first);
    for k in 0..200 {
        step(&mut c, &sc, k, 0.0);
    }
    assert_eq!(c.mode(), ArmMode::Hold);
    let mut sc = Spacecraft::at_contact(second);
    let mut lambdas = Vec::new();
    for k in 0..400 {
        let (u, _) = step(&mut c, &sc, k, F_D);
        lambdas.push(c.forgetting_factor().unwrap());
        sc.advance(&u);
    }
    let first_drop = lambdas.iter().position(|&l| l < 1.0);
    eprintln!(
        "λ first below 1 at sample {first_drop:?} of the second contact, min λ = {}, tr P \
         {trace_before:.3e} → {:.3e}",
        lambdas.iter().copied().fold(1.0, f64::min),
        c.covariance_trace().unwrap()
    );
    // "Immediately": within the short window τ_n = 40 of the F-test.
    assert!(first_drop.is_some_and(|k| k <= 40), "{first_drop:?}");
    assert!(c.covariance_trace().unwrap() > trace_before);
    assert_eq!(c.counts_of().contact_phases, 2);
}

#[test]
fn bad_parameters_are_refused_naming_the_field() {
    let k = [0.0; 6];
    let field = |p: &ArmControllerParams, counts: Dimensions| {
        ArmController::new(p, counts).err().map(|e| e.field)
    };
    let ok = ArmControllerParams::robust_only(k);
    assert_eq!(field(&ok, rig()), None);
    assert_eq!(field(&ok, Dimensions::new(6, 1, 1, 2)), Some(""));
    assert_eq!(field(&ok, Dimensions::new(7, 1, 0, 2)), Some(""));
    let mut p = ok.clone();
    p.arm.l2 = -1.0;
    assert_eq!(field(&p, rig()), Some("arm.l2"));
    let mut p = ok.clone();
    p.robust_gain[4] = f64::NAN;
    assert_eq!(field(&p, rig()), Some("robust-gain"));
    let mut p = ok.clone();
    p.hold.kd = [1.0, -1.0];
    assert_eq!(field(&p, rig()), Some("hold.kd"));
    let mut p = ok.clone();
    let mut pcac = chapter_pcac();
    pcac.mpc.horizon = 1;
    p.pcac = Some(pcac);
    let e = ArmController::new(&p, rig()).err().unwrap();
    assert_eq!(e.field, "pcac");
    assert!(e.message.contains("horizon"), "{}", e.message);
    let mut p = ok;
    p.limits = Some(OutputLimits {
        min: vec![1.0; 2],
        max: vec![-1.0; 2],
    });
    assert_eq!(field(&p, rig()), Some("u-min"));
}

/// The committed LMI gain (`scenarios/arm/robust-gain.toml`) on a soft surface at the
/// corner of §7.3's box (`k_s = 300` N/m, `c_s = 0.35` N s/m): as in Figure 7.3, the
/// robust controller alone stays far below `F_d` over the 2 s contact, and with the PCAC
/// augmentation the contact force reaches `F_d` and `χ → 0`.
#[test]
fn with_the_lmi_gain_pcac_reaches_the_force_the_robust_controller_misses_on_a_soft_surface() {
    let k = committed_gain();
    let surface = Surface {
        k_s: 300.0,
        c_s: 0.35,
        mu: 0.5,
    };
    let mut medians = Vec::new();
    for pcac in [false, true] {
        let params = ArmControllerParams {
            pcac: pcac.then(chapter_pcac),
            ..ArmControllerParams::robust_only(k)
        };
        let mut c = ArmController::new(&params, rig()).unwrap();
        let chi = contact_run(&mut c, surface, 4000);
        let mut force: Vec<f64> = chi.iter().map(|c| c[2] + F_D).collect();
        force.sort_by(f64::total_cmp);
        let median = force[force.len() / 2];
        let w = worst_after(&chi, 3000);
        eprintln!("pcac {pcac}: median F_c {median:.2} N, max |χ| over the last 0.5 s {w:?}");
        medians.push(median);
        if pcac {
            assert!(w[0] < 1e-3 && w[1] < 1e-3 && w[2] < 0.02 * F_D, "{w:?}");
        }
    }
    assert!(
        medians[0] < 0.2 * F_D,
        "robust alone: median {}",
        medians[0]
    );
    assert!(
        (medians[1] - F_D).abs() < 0.02 * F_D,
        "augmented: median {}",
        medians[1]
    );
}
