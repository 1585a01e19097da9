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
//! - [`stalls`]: the stall study (`rig stalls`).
//! - [`soak`]: real time under load, in one sitting (`rig soak`).
//! - [`gaps`]: the gap campaign: RCAC's suppression against the share of samples lost, per
//!   gap rule, in lockstep (`rig gaps`).
//! - [`simulate`]: a controller against the simulated plant in one process (lockstep).
//! - [`figures`]: figures of adaptive runs in the manner of Figures 3.7/3.10/3.14/3.17.
//! - [`plot`]: PNG figures (line panels, pole–zero maps).
//! - [`analysis`]: Welch power spectral densities.

#![warn(missing_docs)]

pub mod analysis;
pub mod design;
pub mod figures;
pub mod gaps;
pub mod launch;
pub mod plot;
pub mod simulate;
pub mod soak;
pub mod stalls;
pub mod stats;
pub mod study;
