//! `study rcac-siso` and `study rcac-miso`: chapter 3, RCAC with dereverberated target
//! models (DTMs), §3.3.1 on the SISO structure (3.50) (Figures 3.5–3.10) and §3.3.2 on a
//! 4-mode, 2-input, 1-output structure (Figures 3.11–3.17).
//!
//! - [`common`]: what both share: the DTMs, the RCAC settings, one sampled-data run and
//!   its measurements, the error-plane panel.
//! - [`driver`]: the run of either study ([`driver::RcacStudy`]): designs, the sweep in
//!   parallel, the figures, the single runs and the summary.
//! - [`siso`], [`miso`]: the two studies, each what is its own.
//! - [`sweep_csv`], [`sweep_stats`]: the sweep's CSV columns and its summary statistics.
//! - [`claims`]: the chapter's claims checked on the sweeps and the single runs.
//! - [`sensitivity`]: the settings §3.3 leaves open, moved to alternatives, and the claims
//!   under each (the sensitivity table, `sensitivity.csv`).

use crate::file_error::FileError;

use crate::design::GridError;
use crate::design::dtf::DtfError;
use crate::design::model::ModelError;
use crate::figures::FigureError;
use crate::plot::PlotError;
use crate::simulate::SimulateError;
use crate::study::reproduction::ClaimsError;

/// Why `study rcac-siso` or `study rcac-miso` failed, naming the option, the step or the
/// file at fault.
#[derive(Debug, thiserror::Error)]
pub enum RcacError {
    /// The study's runs could not be sharded or merged, or (not a failure) its shard is done.
    #[error(transparent)]
    Shard(#[from] crate::study::shard::ShardError),
    /// A file or folder that could not be read, written or made.
    #[error(transparent)]
    File(#[from] FileError),
    /// `--update` is not a known update law.
    #[error("--update {0}: expected gradient, rls or both")]
    Update(String),
    /// A study's scenario does not parse.
    #[error(transparent)]
    Scenario(#[from] plant_proxy::scenario::ScenarioError),
    /// The plant cannot be modelled.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// A plant with an input delay (the studies' have none).
    #[error("the studies' plants have no input delay")]
    InputDelay,
    /// A frequency grid cannot be made.
    #[error(transparent)]
    Grid(#[from] GridError),
    /// A DTF cannot be designed.
    #[error(transparent)]
    Dtf(#[from] DtfError),
    /// The generated target model does not read back (the configuration's message).
    #[error("{0}")]
    Target(String),
    /// A method has no DTM.
    #[error("missing DTM")]
    MissingDtm,
    /// RCAC's parameters are refused.
    #[error(transparent)]
    Controller(#[from] control::ParamError),
    /// A run cannot be simulated.
    #[error(transparent)]
    Simulate(#[from] SimulateError),
    /// A run shorter than the two measurement windows.
    #[error("a run of {0} samples is shorter than two windows")]
    Short(usize),
    /// The tone amplitudes cannot be fitted (`control::tones`' message).
    #[error("{0}")]
    Tones(String),
    /// A figure cannot be drawn.
    #[error(transparent)]
    Plot(#[from] PlotError),
    /// A figure of a single run cannot be made.
    #[error(transparent)]
    Figure(#[from] FigureError),
    /// The claims cannot be written.
    #[error(transparent)]
    Claims(#[from] ClaimsError),
    /// A sweep point's runs failed (the message, as the run recorded it: a shard records a
    /// failed run's message, and the merge reports it as the study run whole does).
    #[error("{0}")]
    Run(String),
}

message_from!(RcacError);

pub mod claims;
pub mod common;
pub mod driver;
pub mod miso;
pub mod sensitivity;
pub mod siso;
pub mod sweep_csv;
pub mod sweep_stats;
