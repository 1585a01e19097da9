//! What the studies of every chapter share.
//!
//! - [`files`]: writing a study's text files, with the file at fault in the error.
//! - [`color_scale`]: the color scale and color bar of the heat maps.
//! - [`convergence`]: when a signal has converged to its late level (chapters 5 and 6).

pub mod color_scale;
pub mod convergence;
pub mod files;
