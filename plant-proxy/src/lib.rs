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
//! - [`runtime`]: the plant process: real-time (paced on `CLOCK_MONOTONIC`) and lockstep modes,
//!   deadline handling, watchdog, fault injection.
//! - [`proxy_config`]: the `[proxy]` table, validated into [`proxy_config::ProxyConfig`].
//! - [`actuation_book`]: which input the plant applies for each sample: the actuations
//!   received ahead of their sample, late and invalid ones refused, the newest plan; pure and
//!   allocation-free, for any plant side (a DAQ process as well as this one).
//! - [`late_policy`]: what a miss applies (`hold`, `safe`, or the newest plan's entry).
//! - [`sample_clock`]: the real-time sample clock, and what it does when the plant itself
//!   wakes more than a period late (`slip` or `catch-up`).
//! - [`faults`]: the faults the plant injects on purpose (bad measurements, stalls).
//! - [`plant_report`]: the run's counters (`plant-report.json`, the `done:` line).

#![warn(missing_docs)]

pub mod actuation_book;
pub mod faults;
pub mod late_policy;
pub mod lti;
pub mod plant_report;
pub mod proxy_config;
pub mod runtime;
pub mod sample_clock;
pub mod scenario;
pub mod sim;
pub mod truss;
