//! The dissertation's numerical studies, run by the `study` binary.
//!
//! - [`experiment`], [`plant`], [`montecarlo`], [`output`]: chapter 5, RLS with F-test
//!   variable-rate forgetting on the time-varying mass-spring-damper (5.8).
//! - [`rcac_common`], [`rcac_study`], [`rcac_sweep_csv`], [`rcac_sweep_stats`],
//!   [`rcac_siso`], [`rcac_miso`]: chapter 3, RCAC with dereverberated
//!   target models (§3.3.1 on (3.50), §3.3.2 on a 4-mode MISO structure).
//! - [`pcac_truss`]: chapter 6, PCAC on the 4-bay truss (§6.2).
//! - [`mrac`], [`mrac_setup`], [`mrac_run`], [`mrac_grid`], [`mrac_summary`],
//!   [`mrac_figures`]: chapter 4, APPC against RC-MRAC over the pole plane (§4.5–4.7).
//! - [`arm`], [`arm_run`], [`arm_grid`], [`arm_figures`], [`reproduction_sampling_arm`]:
//!   chapter 7, the spacecraft sampling arm's force control, robust against
//!   PCAC-augmented, over the surface grids and the double maneuvers (§7.3).

pub mod all;
pub mod arm;
pub mod arm_figures;
pub mod arm_grid;
pub mod arm_run;
pub mod experiment;
pub mod montecarlo;
pub mod mrac;
pub mod mrac_figures;
pub mod mrac_grid;
pub mod mrac_run;
pub mod mrac_setup;
pub mod mrac_summary;
pub mod output;
pub mod pcac_truss;
pub mod plant;
pub mod rcac_common;
pub mod rcac_miso;
pub mod rcac_siso;
pub mod rcac_study;
pub mod rcac_sweep_csv;
pub mod rcac_sweep_stats;
pub mod reproduction;
pub mod reproduction_forgetting;
pub mod reproduction_mrac;
pub mod reproduction_pcac_truss;
pub mod reproduction_rcac;
pub mod reproduction_report;
pub mod reproduction_sampling_arm;
