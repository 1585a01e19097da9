//! # rig-scenario: the scenario file's schema, shared by both sides
//!
//! A scenario TOML file describes one rig for several programs: `[rig]` for all of them,
//! `[plant]` and `[proxy]` for the simulated plant (plant-proxy), `[service]`,
//! `[controller]` and `[log]` for the service. What both sides read is here, read once:
//!
//! - [`rig`]: the `[rig]` table (name, sample period `T_s`, duration) and its
//!   [`bounds`];
//! - [`spacecraft`]: the spacecraft of chapter 7 as a table, the true one of the plant
//!   (`[plant.sampling-arm]`) and the nominal one of the controller (`[controller.arm]`);
//! - [`plant_outline`]: the facts of a `[plant]` table a controller side may read (its
//!   channel counts, noise and tones) without linking the simulator;
//! - [`lti`]: transfer functions and state-space models, their realization (a controller's
//!   `[controller.tf]`, a plant's `[plant.tf]`), the generalized plant and the exact
//!   zero-order-hold discretization.
//!
//! With the feature `refusal-cases`, the module `refusal_cases` reads the refusal-case fixtures
//! both sides' tests share.
//!
//! Each side adds its own tables and the file name to the [`FieldError`]s it gets from
//! here. The service depends on this crate and not on the simulator; the simulator depends
//! on it and on the plant-side library.

#![warn(missing_docs)]

pub mod bounds;
mod field_error;
pub mod lti;
pub mod plant_outline;
#[cfg(feature = "refusal-cases")]
pub mod refusal_cases;
pub mod rig;
pub mod spacecraft;

pub use field_error::FieldError;
