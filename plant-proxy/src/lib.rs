//! # plant-proxy: the simulated plant behind the adaptive-rig contract
//!
//! A separate process that plays the plant side of the contract in `ipc-types`: the clock
//! master that publishes `y_k`, `z_k`, `r_k` at sample `k` and applies the service's `u_k`.
//! A hardware DAQ I/O process can take its place without any change to the service.
//!
//! - [`lti`] (from the `rig-scenario` crate): continuous and discrete linear time-invariant
//!   models, realization of transfer function matrices, exact zero-order-hold
//!   discretization by the matrix exponential of the augmented matrix.
//! - [`sim`]: the sampled-data simulation of a scenario plant with per-input delays, harmonic
//!   disturbances integrated exactly through an exosystem, and seeded white noise.
//! - [`scenario`]: the plant part of a scenario TOML file, validated into typed parameters.
//! - [`truss`]: the planar truss of chapter 6 (pinned members, (6.2)), assembled into a
//!   modal plant at load time (`kind = "truss"`).
//! - [`discrete`]: discrete-time transfer-function plants `N(q⁻¹)/D(q⁻¹)` run exactly by
//!   their difference equation at the sample rate (`kind = "discrete"`).
//! - [`mrac_examples`]: the plants (4.83) and (4.88) of chapter 4 from the pole radius and
//!   angle `(ρ, ν)` (`kind = "mrac-example"`).
//! - [`arm`]: the spacecraft with a two-link sampling arm of chapter 7 (`kind =
//!   "sampling-arm"`): contact and friction (7.27)–(7.29), an adaptive Dormand–Prince
//!   integrator with contact events, and the descent/contact/departure guidance.
//! - [`harmonic`]: a cosine of the step index, `A cos(ω k + φ)`, for the generated commands
//!   and the discrete plants' input disturbance.
//! - [`command`]: the command `r_k` the plant publishes: constant, a step, or a sum of
//!   harmonics (the two- and four-harmonic commands of chapter 4).
//! - [`runtime`]: the plant process: the simulation as the I/O device of the plant side.
//! - [`proxy_config`]: the `[proxy]` table, validated into [`proxy_config::ProxyConfig`].
//! - [`run_args`]: the options of a plant process's `run` command and what they resolve to.
//! - [`faults`]: the faults the plant injects on purpose (bad measurements, stalls).
//!
//! The plant side of the contract itself (clock, deadlines, the actuation book, the late
//! policy, the watchdog, the report) is the `plant-side` crate, which a DAQ process uses
//! the same way; its modules are re-exported here under their old names.

#![warn(missing_docs)]

pub mod arm;
pub mod command;
pub mod discrete;
pub mod faults;
pub mod harmonic;
pub mod mrac_examples;
pub mod proxy_config;
pub mod run_args;
pub mod runtime;
pub mod scenario;
pub mod sim;
pub mod truss;

pub use plant_side::{actuation_book, late_policy, plant_report, sample_clock};
/// The LTI models, their realization and discretization, from the scenario schema.
pub use rig_scenario::lti;
