//! The refusal of one field of a table, without the file: each side adds the file it read
//! (the service's `ConfigError`, plant-proxy's `ScenarioError`).

/// A field with a missing, inconsistent or out-of-range value.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("field '{field}': {problem}")]
pub struct FieldError {
    /// The dotted path of the field, e.g. `rig.sample-period`.
    pub field: String,
    /// What is wrong.
    pub problem: String,
}

impl FieldError {
    /// The refusal of `field` for `problem`.
    pub fn new(field: impl Into<String>, problem: impl Into<String>) -> Self {
        Self {
            field: field.into(),
            problem: problem.into(),
        }
    }
}
