//! # plant-proxy: the simulated plant behind the adaptive-rig contract
//!
//! A separate process that plays the plant side of the contract in `ipc-types`: the clock
//! master that publishes `y_k`, `z_k`, `r_k` at sample `k` and applies the service's `u_k`.
//! A hardware DAQ I/O process can take its place without any change to the service.
//!
//! - [`lti`]: continuous and discrete linear time-invariant models, realization of transfer
//!   function matrices, exact zero-order-hold discretization by the matrix exponential of the
//!   augmented matrix.
//! - [`sim`]: the sampled-data simulation of a scenario plant with per-input delays, harmonic
//!   disturbances integrated exactly through an exosystem, and seeded white noise.
//! - [`scenario`]: the plant part of a scenario TOML file, validated into typed parameters.
//! - [`truss`]: the planar truss of chapter 6 (pinned members, (6.2)), assembled into a
//!   modal plant at load time (`kind = "truss"`).
//! - [`runtime`]: the plant process: the simulation as the I/O device of the plant side.
//! - [`proxy_config`]: the `[proxy]` table, validated into [`proxy_config::ProxyConfig`].
//! - [`faults`]: the faults the plant injects on purpose (bad measurements, stalls).
//!
//! The plant side of the contract itself (clock, deadlines, the actuation book, the late
//! policy, the watchdog, the report) is the `plant-side` crate, which a DAQ process uses
//! the same way; its modules are re-exported here under their old names.

#![warn(missing_docs)]

pub mod faults;
pub mod lti;
pub mod proxy_config;
pub mod runtime;
pub mod scenario;
pub mod sim;
pub mod truss;

pub use plant_side::{actuation_book, late_policy, plant_report, sample_clock};
