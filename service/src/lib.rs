//! # service: the adaptive real-time control service
//!
//! The control side of the contract in `ipc-types`. A pinned real-time thread waits for
//! measurement `k`, runs the controller step and publishes actuation `k`; non-real-time
//! threads write signal logs, latency histograms and the run report. The controllers
//! themselves are the pure kernels of the `control` crate; this crate builds them from
//! the configuration and maps their [`Dimensions`](control::Dimensions) and
//! [`status`](control::status) bits to the wire. It links nothing that plots or runs
//! offline studies: what is here may run next to the hardware.
//!
//! - [`config`]: the service's TOML configuration, read once and validated into typed
//!   parameters.
//! - [`runtime`]: the RT loop, the deadline and silence policy, the run report.
//! - [`telemetry`]: pre-sized latency histograms recorded in the RT thread and reported
//!   outside it (HdrHistogram interval logs, cyclictest-style summaries).
//! - [`logging`]: the bounded lock-free queue that carries signal logs out of the RT thread
//!   and the CSV writer behind it.
//! - [`record`]: `record.bin`, every input and output of the loop at full precision,
//!   written off the RT thread like the signal log.
//! - [`replay`]: `service replay`, the loop re-run offline on a record, compared bit for
//!   bit (or, with another controller, open loop).
//! - [`wire`]: controller dimensions and status bits to and from the contract.
//! - [`system_check`]: what the box does to a real-time loop (PREEMPT_RT, isolated
//!   cores, throttling, governor, SMT, IRQs, swap, huge pages, privileges), with fixes.
//! - [`scheduling`]: why a real-time run lost samples: the RT thread's on-CPU time,
//!   run-queue wait and preemptions, steal time, and the other tasks seen on the RT core.
//! - [`rt_alloc`]: the global allocator that serves the RT thread from a private pool and
//!   counts every allocation made on it.

#![warn(missing_docs)]

pub mod config;
pub mod live;
pub mod logging;
pub mod operator;
pub mod record;
pub mod replay;
pub use ipc_types::rt_alloc;
pub mod runtime;
pub mod scheduling;
pub mod system_check;
pub mod telemetry;
pub mod wire;
