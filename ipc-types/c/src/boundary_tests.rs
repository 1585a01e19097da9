//! Tests of the boundary: what each exported function does with null pointers, bad
//! arguments and a panic inside, through the functions C calls.

use crate::controller::*;
use crate::guard;
use crate::last_error;
use crate::plant::*;
use crate::plant_config::*;
use crate::report::*;
use crate::status::*;
use ipc_types::{Actuation, ChannelCounts, Measurement};
use std::ffi::{CString, c_char};
use std::ptr::{null, null_mut};

/// Asserts `code == want` and that the thread's message contains every part.
fn assert_failure(code: ArStatus, want: ArStatus, parts: &[&str]) {
    let message = last_error::get();
    assert_eq!(code, want, "message: {message}");
    for p in parts {
        assert!(message.contains(p), "'{p}' not in '{message}'");
    }
}

/// Asserts that a call returns `AR_ERR_INVALID_ARGUMENT` with a message containing `$msg`.
macro_rules! refused {
    ($call:expr, $msg:expr) => {
        assert_failure($call, AR_ERR_INVALID_ARGUMENT, &[$msg])
    };
}

/// A valid config for rig `rig` (1 channel each, 1 ms, lockstep, 0.2 s peer time-out).
fn config(rig: &CString) -> ArPlantConfig {
    let mut c = std::mem::MaybeUninit::<ArPlantConfig>::uninit();
    // SAFETY: c is writable for one config.
    assert_eq!(unsafe { ar_plant_config_init(c.as_mut_ptr()) }, AR_OK);
    // SAFETY: ar_plant_config_init wrote every field.
    let mut c = unsafe { c.assume_init() };
    c.rig = rig.as_ptr();
    c.counts = ChannelCounts::new(1, 1, 0, 1).unwrap();
    c.period_ns = 1_000_000;
    c.mode = AR_MODE_LOCKSTEP;
    c.peer_timeout_s = 0.2;
    c
}

/// `ar_plant_open` of `c`, which must fail before connecting: returns the code.
fn open(c: &ArPlantConfig) -> ArStatus {
    let mut plant: *mut ArPlant = null_mut();
    // SAFETY: c is a valid config whose pointers live for the call; plant is writable.
    let code = unsafe { ar_plant_open(c, &mut plant) };
    assert!(plant.is_null(), "no handle on failure");
    code
}

#[test]
fn the_defaults_are_those_of_plant_proxy() {
    let rig = CString::new("x").unwrap();
    let c = config(&rig);
    assert_eq!(c.late_policy, AR_LATE_HOLD);
    assert_eq!(c.plan_fallback, AR_LATE_HOLD);
    assert_eq!(c.deadline, 0.8);
    assert_eq!(c.watchdog_periods, 100);
    assert_eq!(c.lockstep_timeout_s, 1.0);
    assert_eq!(c.peer_timeout_s, 0.2);
    assert!(c.safe_input.is_null() && c.label.is_null());
    // SAFETY: a null config is refused without being written.
    let code = unsafe { ar_plant_config_init(null_mut()) };
    assert_failure(
        code,
        AR_ERR_INVALID_ARGUMENT,
        &["ar_plant_config_init: config: null pointer"],
    );
}

#[test]
fn open_refuses_null_pointers_naming_them() {
    let rig = CString::new("t-null").unwrap();
    let c = config(&rig);
    let mut plant: *mut ArPlant = null_mut();
    // SAFETY: null pointers are refused before any use.
    let code = unsafe { ar_plant_open(null(), &mut plant) };
    assert_failure(
        code,
        AR_ERR_INVALID_ARGUMENT,
        &["ar_plant_open: config: null pointer"],
    );
    // SAFETY: as above.
    let code = unsafe { ar_plant_open(&c, null_mut()) };
    assert_failure(
        code,
        AR_ERR_INVALID_ARGUMENT,
        &["ar_plant_open: out: null pointer"],
    );
    let mut no_rig = c;
    no_rig.rig = null();
    assert_failure(
        open(&no_rig),
        AR_ERR_INVALID_ARGUMENT,
        &["config->rig: null pointer"],
    );
}

#[test]
fn open_refuses_bad_fields_naming_them() {
    let rig = CString::new("t-bad").unwrap();
    let base = config(&rig);
    let bad_utf8: [u8; 3] = [b'a', 0xff, 0];
    let cases: Vec<(ArPlantConfig, &[&str])> = vec![
        (
            ArPlantConfig {
                rig: bad_utf8.as_ptr().cast::<c_char>(),
                ..base
            },
            &["config->rig: not valid UTF-8"],
        ),
        (
            ArPlantConfig {
                counts: ChannelCounts {
                    n_y: 17,
                    ..base.counts
                },
                ..base
            },
            &[
                "config->counts: measurement channels y: 17 channels requested, the contract carries at most 16",
            ],
        ),
        (
            ArPlantConfig {
                counts: ChannelCounts {
                    n_u: 9,
                    ..base.counts
                },
                ..base
            },
            &["config->counts: actuation channels u: 9"],
        ),
        (
            ArPlantConfig {
                period_ns: 0,
                ..base
            },
            &["config->period_ns: the sample period must be positive"],
        ),
        (ArPlantConfig { mode: 7, ..base }, &["config->mode: 7"]),
        (
            ArPlantConfig {
                late_policy: 3,
                ..base
            },
            &["config->late_policy: 3"],
        ),
        (
            ArPlantConfig {
                plan_fallback: AR_LATE_PLAN,
                ..base
            },
            &["config->plan_fallback: 2"],
        ),
        (
            ArPlantConfig {
                deadline: 1.5,
                ..base
            },
            &["config->deadline: 1.5 is not a fraction of the period"],
        ),
        (
            ArPlantConfig {
                watchdog_periods: 0,
                ..base
            },
            &["config->watchdog_periods: must be at least 1"],
        ),
        (
            ArPlantConfig {
                lockstep_timeout_s: -1.0,
                ..base
            },
            &["config->lockstep_timeout_s: -1 is not a time-out"],
        ),
        (
            ArPlantConfig {
                peer_timeout_s: f64::NAN,
                ..base
            },
            &["config->peer_timeout_s: NaN is not a time-out"],
        ),
        (
            ArPlantConfig {
                label: bad_utf8.as_ptr().cast::<c_char>(),
                ..base
            },
            &["config->label: not valid UTF-8"],
        ),
    ];
    for (c, parts) in cases {
        assert_failure(open(&c), AR_ERR_INVALID_ARGUMENT, parts);
    }
    let nan = [f64::NAN];
    let c = ArPlantConfig {
        safe_input: nan.as_ptr(),
        ..base
    };
    assert_failure(
        open(&c),
        AR_ERR_INVALID_ARGUMENT,
        &["config->safe_input: every value must be finite"],
    );
    let bad_rig = CString::new("no spaces allowed").unwrap();
    let c = ArPlantConfig {
        rig: bad_rig.as_ptr(),
        ..base
    };
    assert_failure(
        open(&c),
        AR_ERR_INVALID_ARGUMENT,
        &["invalid rig name 'no spaces allowed'"],
    );
}

#[test]
fn a_plant_without_a_service_times_out_with_the_rust_message() {
    let rig = CString::new(format!("t-c-timeout-{}", std::process::id())).unwrap();
    let c = config(&rig);
    assert_failure(
        open(&c),
        AR_ERR_TIMEOUT,
        &[
            "no peer: 'adaptive-rig/t-c-timeout-",
            "did not appear within 0.2 s",
        ],
    );
}

#[test]
fn the_calls_on_a_plant_refuse_a_null_handle_and_null_outputs() {
    let y = [0.0];
    let mut u = [0.0];
    let mut kind = 0;
    let mut report = ArPlantReport::default();
    let mut len = 0usize;
    // SAFETY: every call below refuses its null handle before using any other pointer.
    unsafe {
        refused!(
            ar_plant_publish(
                null_mut(),
                0,
                0,
                y.as_ptr(),
                y.as_ptr(),
                null(),
                0,
                null_mut(),
            ),
            "ar_plant_publish: plant: null pointer"
        );
        refused!(
            ar_plant_take(null_mut(), 0, AR_WAIT_NOW, 0, u.as_mut_ptr(), &mut kind),
            "ar_plant_take: plant: null pointer"
        );
        refused!(
            ar_plant_report(null(), &mut report),
            "ar_plant_report: plant: null pointer"
        );
        refused!(
            ar_plant_report_json(null(), null_mut(), 0, &mut len),
            "ar_plant_report_json: plant: null pointer"
        );
        refused!(
            ar_plant_deadline_offset_ns(null(), null_mut()),
            "ar_plant_deadline_offset_ns: plant: null pointer"
        );
    }
    // SAFETY: closing a null handle is allowed and does nothing.
    assert_eq!(unsafe { ar_plant_close(null_mut()) }, AR_OK);
}

#[test]
fn the_calls_on_a_controller_refuse_null_pointers_and_bad_arguments() {
    let counts = ChannelCounts::new(1, 1, 0, 1).unwrap();
    let rig = CString::new("t-ctrl").unwrap();
    let mut ctrl: *mut ArController = null_mut();
    let mut m = Measurement::zeroed(counts);
    let a = Actuation::zeroed(counts);
    // SAFETY: every call below refuses a null or bad argument before using the others.
    unsafe {
        refused!(
            ar_controller_open(null(), counts, 1_000_000, 0, 0.1, &mut ctrl),
            "ar_controller_open: rig: null pointer"
        );
        refused!(
            ar_controller_open(rig.as_ptr(), counts, 1_000_000, 0, 0.1, null_mut()),
            "ar_controller_open: out: null pointer"
        );
        refused!(
            ar_controller_open(rig.as_ptr(), counts, 1_000_000, 9, 0.1, &mut ctrl),
            "ar_controller_open: timing: 9"
        );
        refused!(
            ar_controller_open(rig.as_ptr(), counts, 0, 0, 0.1, &mut ctrl),
            "ar_controller_open: period_ns"
        );
        refused!(
            ar_controller_open(
                rig.as_ptr(),
                ChannelCounts { n_r: 40, ..counts },
                1_000_000,
                0,
                0.1,
                &mut ctrl,
            ),
            "ar_controller_open: counts: command channels r: 40"
        );
        refused!(
            ar_controller_receive(null_mut(), &mut m, 0),
            "ar_controller_receive: ctrl: null pointer"
        );
        refused!(
            ar_controller_send(null_mut(), &a),
            "ar_controller_send: ctrl: null pointer"
        );
        refused!(
            ar_controller_actuation_init(null(), null_mut()),
            "ar_controller_actuation_init: ctrl: null pointer"
        );
    }
    assert!(ctrl.is_null());
    // SAFETY: closing a null handle is allowed and does nothing.
    assert_eq!(unsafe { ar_controller_close(null_mut()) }, AR_OK);
}

#[test]
fn a_panic_inside_an_exported_function_returns_ar_err_panic() {
    let mut report = ArPlantReport::default();
    guard::panic_in_next_call();
    // SAFETY: the hook panics before the arguments are used.
    let code = unsafe { ar_plant_report(null(), &mut report) };
    assert_failure(
        code,
        AR_ERR_PANIC,
        &["ar_plant_report: internal panic caught: test hook: a panic inside ar_plant_report"],
    );
    // The boundary is whole again: the next call fails for its own reason.
    // SAFETY: a null handle is refused.
    let code = unsafe { ar_plant_report(null(), &mut report) };
    assert_failure(code, AR_ERR_INVALID_ARGUMENT, &["plant: null pointer"]);
}
