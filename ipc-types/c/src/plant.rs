//! `ar_plant_t`: the plant side of one connection for a DAQ driver written in C, wrapping
//! plant-side's [`PlantSide`] call for call.
//!
//! Per sample `k` the driver reads its ADC at `t_k`, calls [`ar_plant_publish`], then
//! [`ar_plant_take`] for the input of `k` (lockstep: `AR_WAIT_LOCKSTEP`; real time:
//! `AR_WAIT_AT` at `t_k + d·T`, or `AR_WAIT_NOW` before the publish when the DAC is latched
//! at the sample clock), and writes the input to its DAC.

use crate::args;
use crate::guard;
use crate::plant_config::ArPlantConfig;
use crate::status::{AR_STOPPED, ArStatus, Failure};
use crate::stop::STOP;
use plant_side::{InputKind, PlantReport, PlantSide, PlantSideOptions, Wait};
use std::sync::Mutex;
use std::time::Instant;

/// `AR_WAIT_NOW`: decide from what has arrived.
pub const AR_WAIT_NOW: i32 = 0;
/// `AR_WAIT_AT`: sleep until `t_ns`, then decide from what has arrived.
pub const AR_WAIT_AT: i32 = 1;
/// `AR_WAIT_UNTIL`: decide as soon as the answer is there, at the latest at `t_ns`.
pub const AR_WAIT_UNTIL: i32 = 2;
/// `AR_WAIT_LOCKSTEP`: wait for the service's answer (at most `lockstep_timeout_s`).
pub const AR_WAIT_LOCKSTEP: i32 = 3;

/// `AR_INPUT_ANSWERED`: the service's actuation for the sample.
pub const AR_INPUT_ANSWERED: i32 = 0;
/// `AR_INPUT_PLAN`: a miss covered by the newest plan's entry.
pub const AR_INPUT_PLAN: i32 = 1;
/// `AR_INPUT_HELD`: a miss; the previous input, held.
pub const AR_INPUT_HELD: i32 = 2;
/// `AR_INPUT_SAFE`: a miss; the safe input.
pub const AR_INPUT_SAFE: i32 = 3;
/// `AR_INPUT_WATCHDOG_SAFE`: the watchdog holds the safe output.
pub const AR_INPUT_WATCHDOG_SAFE: i32 = 4;

/// The C code of an input's kind.
pub const fn kind_code(kind: InputKind) -> i32 {
    match kind {
        InputKind::Answered => AR_INPUT_ANSWERED,
        InputKind::Plan => AR_INPUT_PLAN,
        InputKind::Held => AR_INPUT_HELD,
        InputKind::Safe => AR_INPUT_SAFE,
        InputKind::WatchdogSafe => AR_INPUT_WATCHDOG_SAFE,
    }
}

/// `ar_plant_t`: one connected plant side. Opaque to C.
pub struct ArPlant {
    side: PlantSide<'static>,
    opened: Instant,
    /// When the latest `ar_plant_take` decided an input: the end of the run so far, so that
    /// the report does not change between two calls without a sample between them.
    last_take: Option<Instant>,
}

// SAFETY: iceoryx2's `ipc::Service` ports are `!Send` only because they share their state
// through non-atomic `Rc`s (its `SingleThreaded` policy; it keeps no thread-local state and
// no thread identity). Every clone of those `Rc`s lives inside this handle (its node, its
// services, its ports; no sample is held between calls), so the handle moves between
// threads as a whole and its reference counts are only ever touched by the one thread that
// holds it, which is the contract the header states (one thread at a time).
unsafe impl Send for ArPlant {}

impl ArPlant {
    /// The counters so far with the end-of-run figures (RMS of `z`, the service's timing,
    /// the round trip), and the wall time from open to the latest input decided.
    pub fn report(&self) -> PlantReport {
        let mut r = self.side.snapshot();
        r.wall_time_s = self
            .last_take
            .map_or(0.0, |t| (t - self.opened).as_secs_f64());
        r
    }
}

/// The labels given so far, kept for the life of the process: plant-side's options tie the
/// label's lifetime to the handle's (which C owns, so `'static`). One copy per distinct
/// label.
fn intern(label: String) -> &'static str {
    static LABELS: Mutex<Vec<&'static str>> = Mutex::new(Vec::new());
    let mut labels = LABELS.lock().unwrap_or_else(|p| p.into_inner());
    if let Some(l) = labels.iter().find(|l| **l == label) {
        return l;
    }
    let l: &'static str = Box::leak(label.into_boxed_str());
    labels.push(l);
    l
}

/// Connects to the service of `config->rig` as its plant and gives the handle in `*out`.
/// Waits up to `config->peer_timeout_s` for the service. Refuses a service whose contract
/// differs (`AR_ERR_MISMATCH`, [`ar_last_error`](crate::last_error::ar_last_error) naming
/// each difference), a rig that already has a plant (`AR_ERR_IN_USE`), a bad config
/// (`AR_ERR_INVALID_ARGUMENT` naming the field); `AR_ERR_TIMEOUT` when no service came,
/// `AR_STOPPED` on `ar_request_stop`. `*out` is set only on success.
///
/// # Safety
/// `config` is null or points to a valid `ar_plant_config_t` whose strings and
/// `safe_input` are as it documents; `out` is null or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ar_plant_open(
    config: *const ArPlantConfig,
    out: *mut *mut ArPlant,
) -> ArStatus {
    const F: &str = "ar_plant_open";
    guard::call(F, || {
        // SAFETY: null or a valid config, by this function's contract.
        let config = unsafe { args::read(config, F, "config") }?;
        // SAFETY: null or writable, by this function's contract.
        let out = unsafe { args::write(out, F, "out") }?;
        // SAFETY: the config's pointers are as it documents, by this function's contract.
        let setup = unsafe { config.setup() }?;
        let opts = PlantSideOptions {
            label: intern(setup.label),
            node_name: "adaptive-rig-plant",
            verbose: setup.verbose,
            shutdown: Some(&STOP),
        };
        let side = PlantSide::connect(
            &setup.rig,
            setup.counts,
            setup.period_ns,
            setup.policy,
            opts,
        )?;
        *out = Box::into_raw(Box::new(ArPlant {
            side,
            opened: Instant::now(),
            last_take: None,
        }));
        Ok(())
    })
}

/// The plant behind a handle.
///
/// # Safety
/// `plant` is null or a handle from `ar_plant_open`, not closed, used by no other thread.
unsafe fn plant_mut<'a>(plant: *mut ArPlant, function: &str) -> Result<&'a mut ArPlant, Failure> {
    // SAFETY: null or a live handle used by this thread only, by the caller's contract.
    unsafe { args::write(plant, function, "plant") }
}

/// Publishes the measurement of sample `k` taken at `t_sample_ns` (`CLOCK_MONOTONIC`, see
/// `ar_monotonic_ns`): `counts.n_y` values at `y`, `n_z` at `z`, `n_r` at `r` (a pointer
/// may be null when its count is 0). `extra_flags`: `AR_MEAS_LAST_SAMPLE` on the last
/// sample of a run (and `AR_MEAS_INJECTED_STALL` in lockstep tests); the other flags are the
/// plant side's. The flags published go to `*flags_out` unless it is null.
///
/// # Safety
/// `plant` is null or a live handle used by this thread only; `y`, `z`, `r` are null or
/// point to their counts of values; `flags_out` is null or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ar_plant_publish(
    plant: *mut ArPlant,
    k: u64,
    t_sample_ns: u64,
    y: *const f64,
    z: *const f64,
    r: *const f64,
    extra_flags: u32,
    flags_out: *mut u32,
) -> ArStatus {
    const F: &str = "ar_plant_publish";
    guard::call(F, || {
        // SAFETY: by this function's contract.
        let p = unsafe { plant_mut(plant, F) }?;
        let c = p.side.counts();
        // SAFETY: null or their counts of values, by this function's contract.
        let (y, z, r) = unsafe {
            (
                args::values(y, c.n_y as usize, F, "y")?,
                args::values(z, c.n_z as usize, F, "z")?,
                args::values(r, c.n_r as usize, F, "r")?,
            )
        };
        let flags = p.side.publish(k, t_sample_ns, [y, z, r], extra_flags)?;
        // SAFETY: null or writable, by this function's contract.
        if let Some(f) = unsafe { flags_out.as_mut() } {
            *f = flags;
        }
        Ok(())
    })
}

/// Decides the input of sample `k` when `wait` says: `AR_WAIT_NOW`, `AR_WAIT_AT` (at the
/// absolute `CLOCK_MONOTONIC` time `t_ns`), `AR_WAIT_UNTIL` (as soon as the answer is there,
/// at the latest at `t_ns`) or `AR_WAIT_LOCKSTEP` (`t_ns` unused). Writes `counts.n_u`
/// values to `u_out` and the input's kind (`AR_INPUT_*`) to `*kind_out` unless it is null.
/// Call it once per sample, `k` increasing. `AR_STOPPED`: `ar_request_stop` was called while
/// the sample was unanswered (nothing written, nothing applied); `AR_ERR_GAVE_UP`: lockstep,
/// no service answered for `peer_timeout_s` after the watchdog tripped (close the handle).
///
/// # Safety
/// `plant` is null or a live handle used by this thread only; `u_out` is null or has room
/// for `counts.n_u` values; `kind_out` is null or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ar_plant_take(
    plant: *mut ArPlant,
    k: u64,
    wait: i32,
    t_ns: u64,
    u_out: *mut f64,
    kind_out: *mut i32,
) -> ArStatus {
    const F: &str = "ar_plant_take";
    guard::call(F, || {
        // SAFETY: by this function's contract.
        let p = unsafe { plant_mut(plant, F) }?;
        let n_u = p.side.counts().n_u as usize;
        // SAFETY: null or room for n_u values, by this function's contract.
        let u = unsafe { args::values_out(u_out, n_u, F, "u_out") }?;
        let wait = match wait {
            AR_WAIT_NOW => Wait::Now,
            AR_WAIT_AT => Wait::At(t_ns),
            AR_WAIT_UNTIL => Wait::Until(t_ns),
            AR_WAIT_LOCKSTEP => Wait::Lockstep,
            w => {
                return Err(Failure::invalid(format!(
                    "{F}: wait: {w} is none of AR_WAIT_NOW, AR_WAIT_AT, AR_WAIT_UNTIL, AR_WAIT_LOCKSTEP"
                )));
            }
        };
        let Some(input) = p.side.take(k, wait)? else {
            return Err(Failure::new(
                AR_STOPPED,
                format!(
                    "{F}: stopped (ar_request_stop) before the input of sample {k} was decided"
                ),
            ));
        };
        p.last_take = Some(Instant::now());
        u.copy_from_slice(&input.u[..n_u]);
        // SAFETY: null or writable, by this function's contract.
        if let Some(kind) = unsafe { kind_out.as_mut() } {
            *kind = kind_code(input.kind);
        }
        Ok(())
    })
}

/// The deadline offset `d·T` of the measurements, ns (0 in lockstep): `AR_WAIT_AT` at
/// `t_sample_ns + *out` is the application instant of the policy.
///
/// # Safety
/// `plant` is null or a live handle; `out` is null or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ar_plant_deadline_offset_ns(
    plant: *const ArPlant,
    out: *mut u64,
) -> ArStatus {
    const F: &str = "ar_plant_deadline_offset_ns";
    guard::call(F, || {
        // SAFETY: null or a live handle, by this function's contract.
        let p = unsafe { args::read(plant, F, "plant") }?;
        // SAFETY: null or writable, by this function's contract.
        let out = unsafe { args::write(out, F, "out") }?;
        *out = p.side.deadline_offset_ns();
        Ok(())
    })
}

/// Disconnects and frees the handle (a null handle is ignored). The service sees the plant
/// go; with `AR_MEAS_LAST_SAMPLE` on the last sample it ends its run cleanly. Prints the
/// trust counters when verbose or when a foreign actuation was refused.
///
/// # Safety
/// `plant` is null or a live handle from `ar_plant_open`, not used afterwards.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ar_plant_close(plant: *mut ArPlant) -> ArStatus {
    guard::call("ar_plant_close", || {
        if !plant.is_null() {
            // SAFETY: a live handle from Box::into_raw in ar_plant_open, given back once.
            let p = unsafe { Box::from_raw(plant) };
            let _report = p.side.finish();
        }
        Ok(())
    })
}
