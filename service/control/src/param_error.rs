//! The error a kernel returns when its parameters are refused.
//!
//! Every parameter struct of this crate validates itself when a controller or kernel is
//! built from it and reports the first field it refuses as a [`ParamError`]: the field's
//! name as written in the configuration (kebab-case, for example `"trace-limit"`), an
//! optional entry index for list fields (`channel[3].den`), and the reason. The service's
//! configuration adds the file and the table; nothing reads the message to find the field.

use std::fmt;

/// A refused parameter: which field, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParamError {
    /// The field as named in the configuration; a nested field is written with dots
    /// (`"forgetting.tau-n"`).
    pub field: &'static str,
    /// For a list field, the index of the refused entry; it is shown after the field's
    /// first segment (`channel[3].den`).
    pub index: Option<usize>,
    /// Why it is refused, for a person.
    pub message: String,
}

impl ParamError {
    /// A refused field.
    pub fn new(field: &'static str, message: impl Into<String>) -> Self {
        Self {
            field,
            index: None,
            message: message.into(),
        }
    }

    /// A refused entry `index` of a list field.
    pub fn at(field: &'static str, index: usize, message: impl Into<String>) -> Self {
        Self {
            field,
            index: Some(index),
            message: message.into(),
        }
    }

    /// The field path with its index, as a person reads it (`channel[3].den`).
    pub fn path(&self) -> String {
        match self.index {
            None => self.field.to_string(),
            Some(i) => match self.field.split_once('.') {
                Some((head, tail)) => format!("{head}[{i}].{tail}"),
                None => format!("{}[{i}]", self.field),
            },
        }
    }
}

impl fmt::Display for ParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path(), self.message)
    }
}

impl std::error::Error for ParamError {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_index_goes_after_the_first_segment_of_the_field() {
        assert_eq!(
            ParamError::at("channel.den", 3, "x").path(),
            "channel[3].den"
        );
        assert_eq!(ParamError::at("markov", 2, "x").path(), "markov[2]");
        assert_eq!(ParamError::new("beta", "x").to_string(), "beta: x");
    }
}
