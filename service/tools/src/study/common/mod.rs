//! What the studies of every chapter share.
//!
//! - [`files`]: writing a study's text files, with the file at fault in the error.
//! - [`color_scale`]: the color scale and color bar of the heat maps.

pub mod color_scale;
pub mod files;
