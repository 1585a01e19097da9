//! # plant-side: the plant side of the adaptive-rig contract, for any plant process
//!
//! A plant process (a DAQ driver, a servo drive, plant-proxy's simulation) is the clock
//! master of the contract in `ipc-types`: it publishes the measurement of sample `k` and
//! applies the service's input for it. This crate is everything of that but the device:
//!
//! - [`plant_side`]: [`PlantSide`], one connection to the service: connect (the contract's
//!   attributes verified, the service pinned), [`PlantSide::publish`] the measurement of
//!   sample `k`, [`PlantSide::take`] the input of sample `k` when [`Wait`] says (latched at
//!   the sample clock, at a deadline, as soon as it is there, or in lockstep), the late
//!   policy, the watchdog and its safe output, `u_applied` and the flags of each
//!   measurement, the report.
//! - [`plant_loop`]: the [`PlantIo`] trait (read the sensors of sample `k`, apply an input,
//!   apply the safe output) and [`run`], the loop around it paced on `CLOCK_MONOTONIC` or
//!   in lockstep. A Rust DAQ process is a `PlantIo` and a call to [`run`]; see the
//!   `loopback_daq` example.
//! - [`policy`]: [`PlantPolicy`], how the plant side runs.
//! - [`actuation_book`]: which input applies to each sample: the actuations received ahead
//!   of their sample, late and invalid ones refused, the newest plan; pure and
//!   allocation-free.
//! - [`late_policy`]: what a miss applies (`hold`, `safe`, or the newest plan's entry).
//! - [`sample_clock`]: the real-time sample clock, and what it does when the loop itself
//!   wakes more than a period late (`slip` or `catch-up`).
//! - [`plant_report`]: the run's counters.
//!
//! The C interface (`ipc-types/c`) and the Python package (`ipc-types/python`) offer the
//! same plant side to DAQ processes written in those languages.

#![warn(missing_docs)]

pub mod actuation_book;
pub mod late_policy;
pub mod plant_loop;
pub mod plant_report;
pub mod plant_side;
pub mod policy;
pub mod sample_clock;

pub use late_policy::{LatePolicy, PlanFallback};
pub use plant_loop::{PlantIo, Sensors, run};
pub use plant_report::PlantReport;
pub use plant_side::{Input, InputKind, PlantError, PlantSide, PlantSideOptions, Wait};
pub use policy::{Mode, PlantPolicy};
pub use sample_clock::Overrun;
