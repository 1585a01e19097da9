//! # service: the adaptive real-time control service
//!
//! The control side of the contract in `ipc-types`. A pinned real-time thread waits for
//! measurement `k`, runs the controller step and publishes actuation `k`; non-real-time
//! threads write signal logs, latency histograms and the run report.
//!
//! - [`rls`]: recursive least squares with variable-rate forgetting (2.12)–(2.14), an
//!   allocation-free kernel and a textbook oracle.
//! - [`forgetting`]: forgetting factors for RLS: constant, F-test (Algorithm 1, (5.1)–(5.7))
//!   and RMS ratio (Proposition 5.2.1).
//! - [`controller`]: the controller interface and the controllers (pure math kernels, no I/O).
//! - [`config`]: the service's TOML configuration, read once and validated into typed
//!   parameters.
//! - [`telemetry`]: pre-sized latency histograms recorded in the RT thread and reported
//!   outside it (HdrHistogram interval logs, cyclictest-style summaries).
//! - [`logging`]: the bounded lock-free queue that carries signal logs out of the RT thread
//!   and the CSV writer behind it.
//! - [`runtime`]: the RT loop, the deadline and silence policy, the run report.
//! - [`design`]: offline design tools: model and measured frequency responses, Markov
//!   parameters, dereverberated transfer functions and RCAC target models (section 3.2).
//! - [`plot`]: PNG figures (line panels, pole–zero maps) for the offline tools.
//! - [`analysis`]: amplitudes of known tones (least squares) and Welch PSDs, for run
//!   reports and studies.
//! - [`simulate`]: a controller against the simulated plant in one process (lockstep),
//!   for studies.
//! - [`figures`]: figures of adaptive runs (z open and closed loop, u, coefficients, PSD) in
//!   the manner of Figures 3.7/3.10/3.14/3.17, from simulations or run folders.
//! - [`mpc`]: PCAC's receding-horizon optimization (2.43)–(2.51): condensing and the dense
//!   QP solver.
//! - [`rt_alloc`]: the global allocator that serves the RT thread from a private pool and
//!   counts every allocation made on it.

#![warn(missing_docs)]

pub mod analysis;
pub mod config;
pub mod controller;
pub mod design;
pub mod figures;
pub mod forgetting;
pub mod logging;
pub mod mpc;
pub mod plot;
pub mod rls;
pub mod rt_alloc;
pub mod runtime;
pub mod simulate;
pub mod telemetry;
#[cfg(test)]
mod test_support;
