//! The dissertation's numerical studies, run by the `study` binary, one folder per
//! chapter, each with its chapter's claims (`claims`) next to the study:
//!
//! - [`rcac`]: chapter 3, RCAC with dereverberated target models (§3.3.1 on (3.50),
//!   §3.3.2 on a 4-mode MISO structure).
//! - [`mrac`]: chapter 4, APPC against RC-MRAC over the pole plane (§4.5–4.7).
//! - [`forgetting`]: chapter 5, RLS with F-test variable-rate forgetting on the
//!   time-varying mass-spring-damper (5.8).
//! - [`pcac_truss`]: chapter 6, PCAC on the 4-bay truss (§6.2).
//! - [`arm`]: chapter 7, the spacecraft sampling arm's force control, robust against
//!   PCAC-augmented, over the surface grids and the double maneuvers (§7.3).
//! - [`reproduction`]: the record of the chapters' claims and the report of `study all`.
//! - [`all`]: `study all`, every study and the report.
//! - [`shard`]: a study's runs split over a cluster's job array, and merged back.
//! - [`common`]: what the studies share: writing their files, the heat maps' color scale.

pub mod all;
pub mod arm;
pub mod common;
pub mod forgetting;
pub mod mrac;
pub mod pcac_truss;
pub mod rcac;
pub mod reproduction;
pub mod shard;
