//! The refusal cases both sides' tests share the format of (`tests/fixtures/refusals/`):
//! each case names a text `from` that occurs in a good scenario, the text `to` that
//! replaces its first occurrence, and the field the edited file must be refused naming
//! (empty where the TOML reader refuses it, e.g. an unknown table). The data lives in
//! files, so that a case is added without writing code.
//!
//! ```toml
//! [[case]]
//! from = "m-sc = 420.0"
//! to = "m-sc = 0.0"
//! field = "plant.sampling-arm.m-sc"
//! ```

use serde::Deserialize;

/// One edit of a good file and the field its refusal must name.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RefusalCase {
    /// The text replaced (its first occurrence).
    pub from: String,
    /// The text put in its place.
    pub to: String,
    /// The dotted field the refusal names; empty for a refusal of the TOML reader.
    pub field: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CaseFile {
    case: Vec<RefusalCase>,
}

/// The cases of a fixture file's text.
///
/// # Errors
///
/// A text that is not a list of `[[case]]` tables with `from`, `to` and `field`.
pub fn parse(text: &str) -> Result<Vec<RefusalCase>, String> {
    toml::from_str::<CaseFile>(text)
        .map(|f| f.case)
        .map_err(|e| format!("not a refusal-case file: {e}"))
}

impl RefusalCase {
    /// `base` with the first occurrence of `from` replaced by `to`.
    ///
    /// # Errors
    ///
    /// `from` does not occur in `base` (the good file changed under the case).
    pub fn edit(&self, base: &str) -> Result<String, String> {
        if base.contains(&self.from) {
            Ok(base.replacen(&self.from, &self.to, 1))
        } else {
            Err(format!("the good file has no '{}'", self.from))
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_case_file_is_read_and_edits_its_base() {
        let cases =
            super::parse("[[case]]\nfrom = \"a = 1\"\nto = \"a = 2\"\nfield = \"a\"").unwrap();
        assert_eq!(cases[0].edit("b = 0\na = 1\n").unwrap(), "b = 0\na = 2\n");
        assert!(cases[0].edit("b = 0").is_err());
        assert!(super::parse("[[case]]\nfrom = \"a\"").is_err());
    }
}
