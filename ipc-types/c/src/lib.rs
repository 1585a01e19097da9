//! # adaptive_rig: the C interface of the adaptive-rig contract
//!
//! A DAQ driver written in C or C++ becomes the plant of the contract through this library
//! (`libadaptive_rig.a` / `libadaptive_rig.so`, header `ipc-types/include/adaptive_rig.h`).
//! It wraps plant-side's [`PlantSide`](plant_side::PlantSide) call for call, so a C plant
//! behaves exactly as plant-proxy: the same attributes and checks at connect, the same
//! deadlines, late policy, watchdog, flags and counters.
//!
//! - [`plant`]: `ar_plant_open`, `ar_plant_publish`, `ar_plant_take`, `ar_plant_close`
//!   (and [`plant_config`] for `ar_plant_config_t`, [`report`] for the counters);
//! - [`controller`]: the service side, for a controller written in C;
//! - [`clock`]: `CLOCK_MONOTONIC` in ns and an absolute sleep; [`stop`]: the stop request a
//!   signal handler makes;
//! - [`status`]: the return codes; [`last_error`]: the message of the calling thread's last
//!   failure; [`guard`]: the boundary (no panic crosses it); [`args`]: checking what C
//!   passes.
//!
//! ## Thread safety
//!
//! A handle (`ar_plant_t*`, `ar_controller_t*`) is used by one thread at a time; it may move
//! from one thread to another between calls (it owns its iceoryx2 node and every port made
//! from it, all of which move together; see the `Send` implementations of
//! [`plant::ArPlant`] and [`controller::ArController`]). Different handles are independent and may be used
//! from different threads at once. [`ar_last_error`](last_error::ar_last_error) is per
//! thread. [`ar_request_stop`](stop::ar_request_stop) is async-signal-safe.
//!
//! ## Errors
//!
//! Every function that can fail returns an `ar_status_t` ([`status`]): `AR_OK` (0),
//! `AR_STOPPED` (1), or a negative `AR_ERR_*` code whose message `ar_last_error()` gives.
//! No panic crosses into C: each body runs inside `catch_unwind` and a panic returns
//! `AR_ERR_PANIC`.

#![warn(missing_docs)]

pub mod args;
pub mod clock;
pub mod controller;
pub mod guard;
pub mod last_error;
pub mod plant;
pub mod plant_config;
pub mod report;
pub mod status;
pub mod stop;

/// The C header of this interface (`ipc-types/include/adaptive_rig.h`).
pub const C_HEADER: &str = include_str!("../../include/adaptive_rig.h");

#[cfg(test)]
mod boundary_tests;
