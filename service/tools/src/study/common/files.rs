//! Writing a study's text files (CSV, summaries): the whole text at once, and on failure
//! an error that names the file.

use std::path::Path;

use crate::file_error::{FileError, FileOp};

/// Writes `text` into the file `path` (created or replaced).
pub fn write(path: &Path, text: &str) -> Result<(), FileError> {
    std::fs::write(path, text).map_err(|source| FileError::new(FileOp::Writing, path, source))
}
