//! The head of a results page (`docs/results/*.md`) that a tool writes: its title, which
//! command wrote it, and where to read what it runs.

/// The head of a results page: the title `# {title}`, then that `writer` (e.g.
/// `rig stalls`) wrote it and that what it runs is read in the source file `source` and
/// in `doc` (a Markdown link or a reference), then a blank line.
pub fn head(title: &str, writer: &str, source: &str, doc: &str) -> String {
    format!(
        "# {title}\n\nWritten by `{writer}`: do not edit by hand. What it runs and how to read \
         it: `{source}` and {doc}.\n\n"
    )
}
