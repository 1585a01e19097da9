//! # control: the algorithms of the adaptive rig
//!
//! Pure kernels, with no IPC, no files and no plotting: each controller is built
//! (allocating) from its parameter struct, and then steps without allocating, locking,
//! doing I/O or panicking. The real-time service (`service`) runs them behind the
//! [`Controller`] trait; the offline tools (`rig-tools`) run the same kernels in studies.
//!
//! - [`controller`]: the [`Controller`] trait, [`StepInput`], [`Dimensions`], the
//!   [`status`] bits.
//! - [`ahead`]: the [`Ahead`] form of a controller whose input for sample `k` is ready
//!   before the sample (answer-first, send-ahead) and its plan for the samples after it.
//! - [`rls`]: recursive least squares with variable-rate forgetting (2.12)–(2.14), an
//!   allocation-free kernel and a textbook oracle.
//! - [`learned`]: what a controller learned (θ, P) apart from its data history: the
//!   blocks of a checkpoint, kept across a new plant session.
//! - [`forgetting`]: forgetting factors for RLS: constant, F-test (Algorithm 1,
//!   (5.1)–(5.7)) and RMS ratio (Proposition 5.2.1).
//! - [`target`]: the RCAC target model `G_f` (3.39), (3.49).
//! - [`rcac`]: retrospective cost adaptive control (2.15)–(2.23), (3.51)–(3.63).
//! - [`bocf`]: the block observable canonical realization of an identified input–output
//!   model (2.36)–(2.42), its Markov parameters and free response (2.43)–(2.46).
//! - [`pcac`]: predictive cost adaptive control (2.24)–(2.51): identification,
//!   realization, receding-horizon control.
//! - [`mrac`]: model reference adaptive control of chapter 4: APPC (4.7)–(4.43) and
//!   RC-MRAC (4.46)–(4.77).
//! - [`mpc`]: the receding-horizon optimization of PCAC (2.43)–(2.51): condensing and the
//!   dense QP solver (with clarabel as the reference under the `clarabel` feature).
//! - [`arm`]: the spacecraft sampling arm of chapter 7: its model (7.1)–(7.26), the
//!   feedback linearization (7.31), the robust gain (7.39)–(7.41) and Algorithm 3.
//! - [`lti`]: a discrete-time LTI controller; `excitation` (crate feature `excitation`,
//!   which brings the random number generator): white-noise inputs for identification
//!   runs.
//! - [`tones`]: amplitudes of known tones by least squares (run reports, studies).
//! - [`linalg`]: the small vector helpers the kernels share.
//! - [`output_limits`]: [`OutputLimits`] and the one rule that bounds every controller's
//!   inputs, with the meaning of its `SATURATED` and `CONTROLLER_FAULT` bits.
//! - [`ParamError`]: what a kernel says when it refuses a parameter.
//!
//! # Parameters and their defaults
//!
//! Every kernel's parameters start from one place that holds its defaults (those the
//! service's configuration uses when a table leaves a field out, each documented with
//! where it comes from), and are checked by the kernel, which names a refused field in a
//! [`ParamError`]:
//!
//! | parameters | from the required settings, defaults for the rest | checked by |
//! | --- | --- | --- |
//! | [`pcac::PcacParams`] | [`pcac::PcacParams::builder`]; the dissertation's examples [`pcac::PcacParams::chapter_6`], [`pcac::PcacParams::chapter_7`] | [`pcac::PcacParams::validate`] |
//! | [`RcacParams`] | [`RcacParams::builder`] ([`RcacBuilder`]), [`RcacParams::new`] | [`RcacBuilder::build`], [`RcacParams::validate`] |
//! | [`mrac::AppcParams`], [`mrac::RcMracParams`] | their `new`, then [`mrac::MracParams::into_builder`] | [`mrac::MracBuilder::build`], their `validate` |
//! | [`lti::LtiParams`] | [`lti::LtiParams::builder`] | [`lti::LtiBuilder::build`], [`lti::LtiParams::validate`] |
//! | [`rls::RlsConfig`] | [`rls::RlsConfig::new`] | [`rls::RlsConfig::checked`] |
//! | [`arm::controller::ArmControllerParams`] | [`arm::controller::ArmControllerParams::robust_only`] | [`arm::controller::ArmControllerParams::validate`] |
//! | `excitation::ExcitationParams` | `ExcitationParams::new` | `ExcitationParams::validate` |
//! | [`mpc::qp::QpSettings`] | [`Default`] | (its limits are the solver's) |
//! | [`forgetting::ForgettingRule`] | [`forgetting::ForgettingRule::DEFAULT`]; [`forgetting::ForgettingRule::PCAC_EXAMPLES`] | [`forgetting::ForgettingRule::validate`] |
//!
//! The small settings structs take the struct update syntax from their defaults
//! (`RlsConfig { rule, ..RlsConfig::new(n, p, p0) }`).

#![warn(missing_docs)]

pub mod ahead;
pub mod arm;
pub mod bocf;
pub mod controller;
#[cfg(feature = "excitation")]
pub mod excitation;
pub mod forgetting;
pub mod internal_model;
pub mod learned;
pub mod linalg;
pub mod lti;
pub mod mpc;
pub mod mrac;
pub mod output_limits;
mod param_error;
pub mod pcac;
pub mod rcac;
pub mod rls;
pub mod target;
#[cfg(test)]
mod test_support;
pub mod tones;

pub use ahead::Ahead;
pub use controller::{
    Adaptation, Controller, Dimensions, MAX_INTERNALS, OutputLimits, StepInput, status,
};
#[cfg(feature = "excitation")]
pub use excitation::ExcitationSource;
pub use lti::{ControllerInput, LtiController};
pub use output_limits::limit_output;
pub use param_error::ParamError;
pub use rcac::{
    GapBridge, GapRule, Rcac, RcacBuilder, RcacParams, RcacUpdate, StepSize, TargetFilter,
};
