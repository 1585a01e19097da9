//! Both sides of the C interface in one process: a plant handle and a controller handle,
//! each moved to its own thread, close a lockstep loop over iceoryx2 through the exported
//! functions only, and the loop computes what the hand-computed recursion says.

use adaptive_rig::controller::*;
use adaptive_rig::last_error::get as last_error;
use adaptive_rig::plant::*;
use adaptive_rig::plant_config::*;
use adaptive_rig::report::*;
use adaptive_rig::status::*;
use ipc_types::{Actuation, ChannelCounts, Measurement, Timing, measurement_flags};
use std::ffi::CString;
use std::ptr::{null, null_mut};

/// A handle moved to another thread (the interface allows it: one thread at a time).
struct Moved<T>(*mut T);
// SAFETY: the handles are `Send` (see their documentation); the wrapper only carries the
// pointer to the one thread that uses it next.
unsafe impl<T: Send> Send for Moved<T> {}

const STEPS: u64 = 300;
const GAIN: f64 = 2.0;

/// The plant of `scenarios/first-order-lockstep.toml`: x⁺ = a x + b u.
fn first_order_ab() -> (f64, f64) {
    let a = (-5.0_f64 * 0.001).exp();
    (a, (1.0 - a) / 5.0)
}

fn counts() -> ChannelCounts {
    ChannelCounts::new(1, 1, 0, 1).unwrap()
}

/// Runs the controller side: u = −K y for every measurement, `STEPS` of them.
fn controller(rig: CString) -> Vec<u64> {
    let mut ctrl: *mut ArController = null_mut();
    // SAFETY: rig is NUL-terminated and lives for the call; ctrl is writable.
    let code = unsafe {
        ar_controller_open(
            rig.as_ptr(),
            counts(),
            1_000_000,
            Timing::ComputeFirst.wire(),
            20.0,
            &mut ctrl,
        )
    };
    assert_eq!(code, AR_OK, "{}", last_error());
    let ctrl = Moved(ctrl);
    std::thread::spawn(move || {
        let ctrl = ctrl;
        let mut seqs = Vec::new();
        let mut m = Measurement::zeroed(ChannelCounts::default());
        let mut a = Actuation::zeroed(ChannelCounts::default());
        // SAFETY: a live handle used by this thread only; m and a are valid for writing.
        unsafe {
            assert_eq!(ar_controller_actuation_init(ctrl.0, &mut a), AR_OK);
            assert_eq!(a.counts, counts());
            // Another shape than the controller's is refused.
            let mut wrong = a;
            wrong.counts.n_u = 2;
            let code = ar_controller_send(ctrl.0, &wrong);
            assert_eq!(code, AR_ERR_INVALID_ARGUMENT);
            assert!(
                last_error()
                    .contains("actuation channels (u): actuation uses 2, controller uses 1"),
                "{}",
                last_error()
            );
            for _ in 0..STEPS {
                let code = ar_controller_receive(ctrl.0, &mut m, 10_000_000_000);
                assert_eq!(code, AR_OK, "{}", last_error());
                seqs.push(m.seq);
                a.seq = m.seq;
                a.reply_to = m.seq;
                a.t_sample_ns = m.t_sample_ns;
                a.u[0] = -GAIN * m.y[0];
                assert_eq!(ar_controller_send(ctrl.0, &a), AR_OK, "{}", last_error());
            }
            assert_ne!(m.flags & measurement_flags::LAST_SAMPLE, 0);
            // Nothing more comes.
            assert_eq!(ar_controller_receive(ctrl.0, &mut m, 0), AR_ERR_TIMEOUT);
            assert_eq!(ar_controller_close(ctrl.0), AR_OK);
        }
        seqs
    })
    .join()
    .unwrap()
}

#[test]
fn a_c_plant_and_a_c_controller_close_a_lockstep_loop_across_threads() {
    let rig = CString::new(format!("t-c-inproc-{}", std::process::id())).unwrap();
    let ctrl_rig = rig.clone();
    let ctrl = std::thread::spawn(move || controller(ctrl_rig));

    let mut config = std::mem::MaybeUninit::<ArPlantConfig>::uninit();
    // SAFETY: writable for one config; ar_plant_config_init fills every field.
    let mut config = unsafe {
        assert_eq!(ar_plant_config_init(config.as_mut_ptr()), AR_OK);
        config.assume_init()
    };
    config.rig = rig.as_ptr();
    config.counts = counts();
    config.period_ns = 1_000_000;
    config.mode = AR_MODE_LOCKSTEP;
    config.peer_timeout_s = 20.0;
    let mut plant: *mut ArPlant = null_mut();
    // SAFETY: config's strings live for the call; plant is writable.
    let code = unsafe { ar_plant_open(&config, &mut plant) };
    assert_eq!(code, AR_OK, "{}", last_error());
    let plant = Moved(plant);

    let (ys, us, report, json) = std::thread::spawn(move || {
        let plant = plant;
        let (a, b) = first_order_ab();
        let (mut x, mut ys, mut us) = (1.0_f64, Vec::new(), Vec::new());
        // SAFETY: a live handle used by this thread only; every pointer is valid.
        unsafe {
            let mut offset = 1;
            assert_eq!(ar_plant_deadline_offset_ns(plant.0, &mut offset), AR_OK);
            assert_eq!(offset, 0, "no deadline in lockstep");
            for k in 0..STEPS {
                let y = [x];
                let extra = if k + 1 == STEPS {
                    measurement_flags::LAST_SAMPLE
                } else {
                    0
                };
                let mut flags = 0;
                let code = ar_plant_publish(
                    plant.0,
                    k,
                    k * 1_000_000,
                    y.as_ptr(),
                    y.as_ptr(),
                    null(),
                    extra,
                    &mut flags,
                );
                assert_eq!(code, AR_OK, "{}", last_error());
                assert_ne!(flags & measurement_flags::LOCKSTEP, 0);
                if k == 0 {
                    // A null output on a live handle is refused; the sample stays undecided.
                    let code =
                        ar_plant_take(plant.0, k, AR_WAIT_LOCKSTEP, 0, null_mut(), null_mut());
                    assert_eq!(code, AR_ERR_INVALID_ARGUMENT);
                    assert!(
                        last_error().contains("ar_plant_take: u_out: null pointer for 1 value(s)")
                    );
                    let mut u = [0.0];
                    let code = ar_plant_take(plant.0, k, 9, 0, u.as_mut_ptr(), null_mut());
                    assert_eq!(code, AR_ERR_INVALID_ARGUMENT);
                    assert!(last_error().contains("ar_plant_take: wait: 9"));
                    let code =
                        ar_plant_publish(plant.0, k, 0, null(), y.as_ptr(), null(), 0, null_mut());
                    assert_eq!(code, AR_ERR_INVALID_ARGUMENT);
                    assert!(
                        last_error().contains("ar_plant_publish: y: null pointer for 1 value(s)")
                    );
                }
                let (mut u, mut kind) = ([f64::NAN], -1);
                let code =
                    ar_plant_take(plant.0, k, AR_WAIT_LOCKSTEP, 0, u.as_mut_ptr(), &mut kind);
                assert_eq!(code, AR_OK, "{}", last_error());
                assert_eq!(kind, AR_INPUT_ANSWERED, "at k = {k}");
                ys.push(x);
                us.push(u[0]);
                x = a * x + b * u[0];
            }
            let mut report = ArPlantReport::default();
            assert_eq!(ar_plant_report(plant.0, &mut report), AR_OK);
            let mut len = 0usize;
            let code = ar_plant_report_json(plant.0, null_mut(), 0, &mut len);
            assert_eq!(code, AR_ERR_BUFFER_TOO_SMALL);
            let mut buf = vec![0u8; len + 1];
            let code =
                ar_plant_report_json(plant.0, buf.as_mut_ptr().cast(), buf.len(), null_mut());
            assert_eq!(code, AR_OK, "{}", last_error());
            let json = String::from_utf8(buf[..len].to_vec()).unwrap();
            assert_eq!(ar_plant_close(plant.0), AR_OK);
            (ys, us, report, json)
        }
    })
    .join()
    .unwrap();

    let seqs = ctrl.join().unwrap();
    assert_eq!(
        seqs,
        (0..STEPS).collect::<Vec<_>>(),
        "every sample once, in order"
    );
    let (a, b) = first_order_ab();
    for (k, (y, u)) in ys.iter().zip(&us).enumerate() {
        let expected = (a - b * GAIN).powi(k as i32);
        assert!(
            (y - expected).abs() < 1e-12,
            "y at k = {k}: {y} vs {expected}"
        );
        assert_eq!(*u, -GAIN * y, "u at k = {k}");
    }
    assert_eq!(report.samples, STEPS);
    assert_eq!(report.actuations_applied, STEPS);
    assert_eq!(report.misses, 0);
    assert_eq!(report.service_pid, std::process::id());
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(v["samples"], STEPS);
    assert_eq!(v["applies"], "lockstep");
}
