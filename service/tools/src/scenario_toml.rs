//! A scenario file read as a TOML table, as the campaigns (`rig stalls`, `rig gaps`,
//! `rig soak`) read it to derive their runs' scenarios from it, and its sample period.

use std::path::{Path, PathBuf};

/// A scenario file that cannot be read or lacks what a campaign needs, naming the file
/// (and the field).
#[derive(Debug, thiserror::Error)]
pub enum ScenarioTomlError {
    /// The file cannot be read.
    #[error("{}: cannot read the file: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The file is not TOML.
    #[error("{}: not valid TOML: {source}", path.display())]
    Toml {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: toml::de::Error,
    },
    /// A field the campaign needs is missing (or not a number).
    #[error("{}: field '{field}' is missing", path.display())]
    Missing {
        /// The file.
        path: PathBuf,
        /// The field, dotted (`rig.sample-period`).
        field: &'static str,
    },
}

impl From<ScenarioTomlError> for String {
    fn from(e: ScenarioTomlError) -> String {
        e.to_string()
    }
}

/// The file `path` as a TOML table.
pub fn read(path: &Path) -> Result<toml::Table, ScenarioTomlError> {
    let text = std::fs::read_to_string(path).map_err(|source| ScenarioTomlError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    toml::from_str(&text).map_err(|source| ScenarioTomlError::Toml {
        path: path.to_path_buf(),
        source,
    })
}

/// The sample period `rig.sample-period` (s) of the scenario `table` read from `path`.
pub fn sample_period(table: &toml::Table, path: &Path) -> Result<f64, ScenarioTomlError> {
    table
        .get("rig")
        .and_then(|r| r.get("sample-period"))
        .and_then(|v| v.as_float())
        .ok_or_else(|| ScenarioTomlError::Missing {
            path: path.to_path_buf(),
            field: "rig.sample-period",
        })
}
