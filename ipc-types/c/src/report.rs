//! `ar_plant_report_t`: a plant's counters for C, as a struct ([`ar_plant_report`]) or as
//! the JSON of plant-proxy's `plant-report.json` ([`ar_plant_report_json`]).

use crate::args;
use crate::guard;
use crate::plant::ArPlant;
use crate::status::{AR_ERR_BUFFER_TOO_SMALL, ArStatus, Failure};
use plant_side::PlantReport;
use std::ffi::c_char;

/// `ar_plant_report_t`: the counters of a plant so far (plant-side's `PlantReport`; see
/// its documentation for each). `misses = plan_entries_applied + misses_held_or_safe`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ArPlantReport {
    /// Samples published.
    pub samples: u64,
    /// Valid actuations applied, each received by its application instant.
    pub actuations_applied: u64,
    /// Samples without a valid actuation by their application instant.
    pub misses: u64,
    /// Misses covered by a plan's entry.
    pub plan_entries_applied: u64,
    /// Misses that reached the plant as a held or a safe output.
    pub misses_held_or_safe: u64,
    /// Of those, the ones before the first valid actuation.
    pub misses_before_first_answer: u64,
    /// Actuations that arrived after their sample's input was decided.
    pub late_discarded: u64,
    /// Actuations refused as invalid (contract, counts, plan length, non-finite values).
    pub invalid_discarded: u64,
    /// Actuations received ahead and dropped for room.
    pub ahead_dropped: u64,
    /// Actuations refused because they did not come from the pinned service.
    pub foreign_discarded: u64,
    /// Times a new service replaced the pinned one.
    pub new_services: u64,
    /// Watchdog trips.
    pub watchdog_trips: u64,
    /// Recoveries from the safe output.
    pub watchdog_recoveries: u64,
    /// Samples spent in the safe output.
    pub safe_output_samples: u64,
    /// Samples published with `AR_MEAS_INJECTED_STALL`.
    pub stalls_injected: u64,
    /// Stall acknowledgements received.
    pub stall_acks: u64,
    /// Seconds from `ar_plant_open` to the latest input decided by `ar_plant_take` (0 before
    /// the first): the report changes only with the run.
    pub wall_time_s: f64,
    /// The pid of the pinned service, 0 when unknown.
    pub service_pid: u32,
    /// 1 once the plant gave up (`AR_ERR_GAVE_UP`), else 0.
    pub gave_up: u32,
}

impl From<&PlantReport> for ArPlantReport {
    fn from(r: &PlantReport) -> Self {
        Self {
            samples: r.samples,
            actuations_applied: r.actuations_applied,
            misses: r.misses,
            plan_entries_applied: r.plan_entries_applied,
            misses_held_or_safe: r.misses_held_or_safe,
            misses_before_first_answer: r.misses_before_first_answer,
            late_discarded: r.late_discarded,
            invalid_discarded: r.invalid_discarded,
            ahead_dropped: r.ahead_dropped,
            foreign_discarded: r.foreign_discarded,
            new_services: r.new_services,
            watchdog_trips: r.watchdog_trips,
            watchdog_recoveries: r.watchdog_recoveries,
            safe_output_samples: r.safe_output_samples,
            stalls_injected: r.stalls_injected,
            stall_acks: r.stall_acks,
            wall_time_s: r.wall_time_s,
            service_pid: r.service_pid.unwrap_or(0),
            gave_up: u32::from(r.gave_up.is_some()),
        }
    }
}

/// Writes the plant's counters so far to `*out`.
///
/// # Safety
/// `plant` is null or a live handle not used by another thread during the call; `out` is
/// null or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ar_plant_report(
    plant: *const ArPlant,
    out: *mut ArPlantReport,
) -> ArStatus {
    const F: &str = "ar_plant_report";
    guard::call(F, || {
        // SAFETY: null or a live handle, by this function's contract.
        let p = unsafe { args::read(plant, F, "plant") }?;
        // SAFETY: null or writable, by this function's contract.
        let out = unsafe { args::write(out, F, "out") }?;
        *out = ArPlantReport::from(&p.report());
        Ok(())
    })
}

/// Writes the plant's report so far as JSON (the fields of plant-proxy's
/// `plant-report.json`, with the RMS of `z`, the service's timing and the round trip
/// `round_trip` from publish to answer so far), NUL-terminated, into `buf` of `capacity` bytes. `*len_out` (unless
/// null) gets the JSON's length without the NUL. `AR_ERR_BUFFER_TOO_SMALL` when it does not
/// fit (nothing written to `buf`; `*len_out` says how much is needed, plus one for the NUL);
/// `buf` may be null with `capacity` 0 to ask for the length. The report does not change
/// until the next publish or take, so a buffer of that length plus one then fits.
///
/// # Safety
/// `plant` is null or a live handle not used by another thread during the call; `buf` is
/// null or has `capacity` writable bytes; `len_out` is null or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ar_plant_report_json(
    plant: *const ArPlant,
    buf: *mut c_char,
    capacity: usize,
    len_out: *mut usize,
) -> ArStatus {
    const F: &str = "ar_plant_report_json";
    guard::call(F, || {
        // SAFETY: null or a live handle, by this function's contract.
        let p = unsafe { args::read(plant, F, "plant") }?;
        let json = serde_json::to_string(&p.report())
            .map_err(|e| Failure::invalid(format!("{F}: the report as JSON: {e}")))?;
        // SAFETY: null or writable, by this function's contract.
        if let Some(len) = unsafe { len_out.as_mut() } {
            *len = json.len();
        }
        if json.len() >= capacity {
            return Err(Failure::new(
                AR_ERR_BUFFER_TOO_SMALL,
                format!(
                    "{F}: capacity: {capacity} bytes, the report needs {} (with its NUL)",
                    json.len() + 1
                ),
            ));
        }
        // SAFETY: capacity > json.len() >= 0, so buf must be non-null with capacity bytes by
        // this function's contract; checked for null all the same.
        let out = unsafe { args::values_out_bytes(buf, capacity, F, "buf") }?;
        out[..json.len()].copy_from_slice(json.as_bytes());
        out[json.len()] = 0;
        Ok(())
    })
}
