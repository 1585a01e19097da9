//! `[controller]`: which controller runs, chosen by `kind`, and what every kind shares.
//!
//! ```toml
//! [controller]
//! kind = "lti"                    # "lti", "excitation", "rcac", "pcac", "appc", "rc-mrac"
//!                                 # or "sampling-arm"
//! u-min = -1.0                    # optional saturation, scalar or one per input u
//! u-max = 1.0
//! ```
//!
//! The other fields depend on the kind and are listed in the kind's module: `lti`
//! ([`ControllerConfig::Lti`]), `excitation` ([`ControllerConfig::Excitation`]), `rcac`
//! ([`ControllerConfig::Rcac`]), `pcac` ([`ControllerConfig::Pcac`]), `appc`
//! ([`ControllerConfig::Appc`]) and `rc-mrac` ([`ControllerConfig::RcMrac`]) (both in
//! `mrac`), `sampling-arm` ([`ControllerConfig::SamplingArm`], in `arm`).
//!
//! Each kind's `parse` turns its table into the kernel's parameter struct (defaults from
//! the kernel's constants) and calls the struct's `validate`, which builds nothing; the
//! runtime builds the controller once, with [`ControllerConfig::build`]. A kernel's
//! [`ParamError`] names the field as the table does, so the error is `controller.` and
//! its path. A new kind adds a variant, a module with its `parse`, and a line in this
//! module's `parse` and in the two `match`es of [`ControllerConfig`].

use super::values::{ScalarOrVec, per_channel};
use super::{ConfigError, ErrFn, arm, excitation, lti, mrac, pcac, rcac};
use control::arm::controller::{ArmController, ArmControllerParams};
use control::excitation::ExcitationParams;
use control::lti::LtiParams;
use control::mrac::{Appc, AppcParams, RcMrac, RcMracParams};
use control::pcac::{Pcac, PcacParams};
use control::{
    Controller, ExcitationSource, LtiController, OutputLimits, ParamError, Rcac, RcacParams,
};
use ipc_types::ChannelCounts;
use std::path::Path;

/// The controller as configured: validated ([`ControllerConfig::validate`] passed when
/// the file was read), not yet built. The runtime builds it once, with
/// [`ControllerConfig::build`].
#[derive(Debug, Clone, PartialEq)]
pub enum ControllerConfig {
    /// A discrete LTI controller ([`LtiController`]).
    Lti {
        /// The validated parameters.
        params: Box<LtiParams>,
    },
    /// Independent white Gaussian inputs for identification ([`ExcitationSource`]).
    Excitation {
        /// The validated parameters.
        params: Box<ExcitationParams>,
    },
    /// Retrospective cost adaptive control ([`Rcac`]).
    Rcac {
        /// The validated parameters.
        params: Box<RcacParams>,
    },
    /// Predictive cost adaptive control ([`Pcac`]).
    Pcac {
        /// The validated parameters.
        params: Box<PcacParams>,
    },
    /// Adaptive pole placement control ([`Appc`], chapter 4).
    Appc {
        /// The validated parameters.
        params: Box<AppcParams>,
    },
    /// Retrospective cost model reference adaptive control ([`RcMrac`], chapter 4).
    RcMrac {
        /// The validated parameters.
        params: Box<RcMracParams>,
    },
    /// The sampling arm's adaptive force control ([`ArmController`], chapter 7).
    SamplingArm {
        /// The validated parameters.
        params: Box<ArmControllerParams>,
    },
}

impl ControllerConfig {
    /// The `kind` of the `[controller]` table.
    pub fn kind_name(&self) -> &'static str {
        match self {
            ControllerConfig::Lti { .. } => "lti",
            ControllerConfig::Excitation { .. } => "excitation",
            ControllerConfig::Rcac { .. } => "rcac",
            ControllerConfig::Pcac { .. } => "pcac",
            ControllerConfig::Appc { .. } => "appc",
            ControllerConfig::RcMrac { .. } => "rc-mrac",
            ControllerConfig::SamplingArm { .. } => "sampling-arm",
        }
    }

    /// True when the controller has an ahead form ([`control::ahead`]): its input for
    /// sample `k` depends only on the data up to `k − 1`, so it can answer ahead. Each
    /// kernel's parameters say so; the built controller's `Controller::ahead` agrees.
    pub fn answers_ahead(&self) -> bool {
        match self {
            ControllerConfig::Lti { params } => params.answers_ahead(),
            ControllerConfig::Excitation { params } => params.answers_ahead(),
            ControllerConfig::Rcac { params } => params.answers_ahead(),
            ControllerConfig::Pcac { params } => params.answers_ahead(),
            // u_k needs the command r_k of the same sample ((4.43), (4.77)).
            ControllerConfig::Appc { .. } | ControllerConfig::RcMrac { .. } => false,
            // The torques (7.31) linearize at the measurement of the same sample.
            ControllerConfig::SamplingArm { .. } => false,
        }
    }

    /// Why the controller has no ahead form, for a refusal (empty when it has one).
    pub fn why_not_ahead(&self) -> &'static str {
        match self {
            _ if self.answers_ahead() => "",
            ControllerConfig::Lti { .. } => "its feedthrough D is not zero",
            ControllerConfig::Pcac { .. } => {
                "controller.timing = \"same-step\" chooses u_k from y_k; \"next-step\", the \
                 dissertation's timing, answers ahead"
            }
            ControllerConfig::Appc { .. } | ControllerConfig::RcMrac { .. } => {
                "its input u_k needs the command r_k of the same sample ((4.43), (4.77))"
            }
            ControllerConfig::SamplingArm { .. } => {
                "its torques (7.31) linearize the arm at the measurement y_k of the same sample"
            }
            ControllerConfig::Rcac { .. } | ControllerConfig::Excitation { .. } => "",
        }
    }

    /// Checks the parameters for the rig's channels without building the controller.
    ///
    /// # Errors
    ///
    /// The kernel's [`ParamError`], its field named as in the `[controller]` table.
    pub fn validate(&self, counts: ChannelCounts) -> Result<(), ParamError> {
        let dims = crate::wire::dimensions(counts);
        match self {
            ControllerConfig::Lti { params } => params.validate(dims),
            ControllerConfig::Excitation { params } => params.validate(dims),
            ControllerConfig::Rcac { params } => params.validate(dims),
            ControllerConfig::Pcac { params } => params.validate(dims),
            // The kernels check the channels when built; building allocates, which is
            // fine here (configuration time).
            ControllerConfig::Appc { params } => Appc::new(params, dims).map(|_| ()),
            ControllerConfig::RcMrac { params } => RcMrac::new(params, dims).map(|_| ()),
            ControllerConfig::SamplingArm { params } => params.validate(dims),
        }
    }

    /// Builds the controller (allocating; before the RT thread starts).
    ///
    /// # Errors
    ///
    /// Only for parameters that [`ControllerConfig::validate`] refuses (a configuration
    /// read by [`ServiceConfig::parse`](super::ServiceConfig::parse) has passed it): the
    /// field in the `[controller]` table and the reason, as text.
    pub fn build(&self, counts: ChannelCounts) -> Result<Box<dyn Controller>, String> {
        let dims = crate::wire::dimensions(counts);
        let built: Result<Box<dyn Controller>, ParamError> = match self {
            ControllerConfig::Lti { params } => {
                LtiController::from_params(params, dims).map(|c| Box::new(c) as Box<dyn Controller>)
            }
            ControllerConfig::Excitation { params } => ExcitationSource::from_params(params, dims)
                .map(|c| Box::new(c) as Box<dyn Controller>),
            ControllerConfig::Rcac { params } => {
                Rcac::new(params, dims).map(|c| Box::new(c) as Box<dyn Controller>)
            }
            ControllerConfig::Pcac { params } => {
                Pcac::new(params, dims).map(|c| Box::new(c) as Box<dyn Controller>)
            }
            ControllerConfig::Appc { params } => {
                Appc::new(params, dims).map(|c| Box::new(c) as Box<dyn Controller>)
            }
            ControllerConfig::RcMrac { params } => {
                RcMrac::new(params, dims).map(|c| Box::new(c) as Box<dyn Controller>)
            }
            ControllerConfig::SamplingArm { params } => {
                ArmController::new(params, dims).map(|c| Box::new(c) as Box<dyn Controller>)
            }
        };
        built.map_err(|e| format!("{}: {}", table_field(&e), e.message))
    }
}

/// The dotted path of a kernel's refused field in the file: `controller.` and the
/// field's path (`controller.forgetting.tau-d`), or `controller` for the whole table (the
/// empty field).
pub(super) fn table_field(e: &ParamError) -> String {
    if e.field.is_empty() {
        "controller".to_string()
    } else {
        format!("controller.{}", e.path())
    }
}

/// A kernel's [`ParamError`] as the [`ConfigError`] of the file being read.
pub(super) fn param_error(e: ParamError, err: &ErrFn<'_>) -> ConfigError {
    err(&table_field(&e), e.message)
}

/// The kinds [`parse`] knows, for the error messages.
const CONTROLLER_KINDS: &str = "lti, excitation, rcac, pcac, appc, rc-mrac, sampling-arm";

/// What a kind's `parse` reads besides its own table.
pub(super) struct Rig<'a> {
    /// The rig's channels.
    pub counts: ChannelCounts,
    /// The sampling period, s.
    pub period: f64,
    /// The folder relative file names of the table are found from.
    pub base_dir: &'a Path,
}

/// A kind's `parse`: its raw table, the rig, the file's errors.
type KindParse<R> = fn(R, &Rig<'_>, &ErrFn<'_>) -> Result<ControllerConfig, ConfigError>;

/// Reads the `[controller]` table of the kind it names.
pub(super) fn parse(
    value: toml::Value,
    rig: &Rig<'_>,
    err: &ErrFn<'_>,
) -> Result<ControllerConfig, ConfigError> {
    let kind = value.get("kind").and_then(|v| v.as_str()).unwrap_or("");
    match kind {
        "lti" => read(value, rig, err, lti::parse),
        "excitation" => read(value, rig, err, excitation::parse),
        "rcac" => read(value, rig, err, rcac::parse),
        "pcac" => read(value, rig, err, pcac::parse),
        "appc" => read(value, rig, err, mrac::parse_appc),
        "rc-mrac" => read(value, rig, err, mrac::parse_rc_mrac),
        "sampling-arm" => read(value, rig, err, arm::parse),
        "" => Err(err(
            "controller.kind",
            format!("missing; known kinds: {CONTROLLER_KINDS}"),
        )),
        other => Err(err(
            "controller.kind",
            format!("unknown controller '{other}'; known kinds: {CONTROLLER_KINDS}"),
        )),
    }
}

/// Deserializes the table into the kind's raw form (naming the table on an unknown or
/// mistyped field) and reads it with the kind's `parse`.
fn read<R: serde::de::DeserializeOwned>(
    value: toml::Value,
    rig: &Rig<'_>,
    err: &ErrFn<'_>,
    parse: KindParse<R>,
) -> Result<ControllerConfig, ConfigError> {
    let raw = value
        .try_into()
        .map_err(|e: toml::de::Error| err("controller", e.to_string()))?;
    parse(raw, rig, err)
}

/// The optional `u-min`/`u-max` pair of a controller table (scalar or one per input).
pub(super) fn output_limits(
    lo: &Option<ScalarOrVec>,
    hi: &Option<ScalarOrVec>,
    n_u: usize,
    err: &ErrFn<'_>,
) -> Result<Option<OutputLimits>, ConfigError> {
    if lo.is_none() && hi.is_none() {
        return Ok(None);
    }
    Ok(Some(OutputLimits {
        min: per_channel(lo, n_u, f64::NEG_INFINITY, "controller.u-min", err)?,
        max: per_channel(hi, n_u, f64::INFINITY, "controller.u-max", err)?,
    }))
}
