//! # rig-tools: the offline tools of the adaptive rig
//!
//! Everything that runs away from the hardware: the launcher of the main job and its
//! figure, the design of RCAC target models, the dissertation's studies, plots and signal
//! analysis. It uses the kernels of `control` and the configuration and log formats of
//! `service`; neither of them uses it.
//!
//! - [`launch`]: the main job: `plant-proxy run` and `service run` as two processes on one
//!   scenario, then the run's figure.
//! - [`design`]: model and measured frequency responses, Markov parameters, dereverberated
//!   transfer functions and RCAC target models (section 3.2).
//! - [`study`]: the studies of chapters 3, 4, 5 and 6.
//! - [`scenario_check`]: both halves of a scenario checked against each other (`rig check`).
//! - [`stalls`]: the stall study (`rig stalls`).
//! - [`soak`]: real time under load, in one sitting (`rig soak`).
//! - [`gaps`]: the gap campaign: RCAC's suppression against the share of samples lost, per
//!   gap rule, in lockstep (`rig gaps`).
//! - [`simulate`]: a controller against the simulated plant in one process (lockstep).
//! - [`figures`]: figures of adaptive runs in the manner of Figures 3.7/3.10/3.14/3.17.
//! - [`file_error`]: a file that could not be read, written or made.
//! - [`plot`]: PNG figures (line panels, pole–zero maps).
//! - [`results_page`]: the head of a results page under `docs/results/`.
//! - [`scenario_toml`]: a campaign's scenario file as a TOML table.
//! - [`analysis`]: Welch power spectral densities.
//! - [`monitor`]: `rig monitor`, the live watcher of running rigs (web page, JSON,
//!   Prometheus metrics, Foxglove), and the operator commands of `rig command`.

#![warn(missing_docs)]

/// `impl From<E> for String` (the error's message) for each typed error `E`, so that a
/// caller that still carries its errors as text takes a typed one with `?`.
macro_rules! message_from {
    ($($e:ty),+ $(,)?) => {
        $(impl From<$e> for String {
            fn from(e: $e) -> String {
                e.to_string()
            }
        })+
    };
}

pub mod analysis;
pub mod design;
pub mod figures;
pub mod file_error;
pub mod gaps;
pub mod launch;
pub mod monitor;
pub mod plot;
pub mod results_page;
pub mod scenario_check;
pub mod scenario_toml;
pub mod simulate;
pub mod soak;
pub mod stalls;
pub mod stats;
pub mod study;
