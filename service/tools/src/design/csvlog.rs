//! Reading signal logs: the service's CSV logs, or any DAQ's CSV export.
//!
//! ## Format
//!
//! ```text
//! # comment lines start with '#' (after optional leading whitespace) and are skipped
//! seq,t_sample_ns,status,flags,y0,z0,u0,u1
//! 0,0,0,0,0.0123,0.0121,-0.5,1.25e-3
//! 1,125000,0,0,NaN,0.0119,inf,-inf
//! ```
//!
//! - The first line that is neither blank nor a comment is the **header**: comma-separated
//!   column names (surrounding whitespace and one pair of double quotes around a name are
//!   removed). Names must be non-empty and distinct.
//! - Every following non-blank, non-comment line is a **row** with exactly as many
//!   comma-separated fields as the header; each field (surrounding whitespace removed) is
//!   a number as Rust's `f64` parser reads it: plain decimal or exponent notation, and the
//!   non-finite spellings `NaN`, `inf`, `-inf` the service's logger writes (see
//!   [`service::logging`]). A wrong field count or a non-numeric field is an error naming
//!   the file, the line and the column.
//! - Line ends may be `\n` or `\r\n`; a trailing newline (or none) is fine.
//!
//! Non-finite values are kept by [`parse`] (a log may legitimately record a rejected
//! measurement); [`Log::select`] refuses them in the columns an analysis uses, naming the
//! column and the line.
//!
//! The whole file is read into memory and parsed column-wise in one pass; a 10 s log at
//! 8 kHz (80 000 rows) takes a few tens of milliseconds.

use std::path::{Path, PathBuf};

/// A CSV log read into columns.
#[derive(Debug, Clone, PartialEq)]
pub struct Log {
    /// Where the text came from (the path, or what the caller of [`parse`] said), used in
    /// every error message.
    pub origin: String,
    /// Column names, in file order.
    pub names: Vec<String>,
    /// `columns[c][r]`: column `c`, row `r`.
    columns: Vec<Vec<f64>>,
    /// `lines[r]`: the 1-based line number of row `r` in the file.
    lines: Vec<usize>,
}

/// A CSV log that cannot be read or parsed, naming the file (its origin) and, for its
/// content, the line and the column.
#[derive(Debug, thiserror::Error)]
pub enum LogError {
    /// The file cannot be read.
    #[error("{}: cannot read the log: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// No header line.
    #[error("{origin}: no header line (the file is empty or all comments)")]
    NoHeader {
        /// The log.
        origin: String,
    },
    /// A column of the header has no name.
    #[error("{origin}: line {line}: column {column} of the header has no name")]
    Unnamed {
        /// The log.
        origin: String,
        /// The header's line.
        line: usize,
        /// The column, from 1.
        column: usize,
    },
    /// A column name appears twice.
    #[error("{origin}: line {line}: column name `{name}` appears twice in the header")]
    Twice {
        /// The log.
        origin: String,
        /// The header's line.
        line: usize,
        /// The name.
        name: String,
    },
    /// A field is not a number.
    #[error("{origin}: line {line}, column {column} (`{name}`): `{field}` is not a number")]
    NotANumber {
        /// The log.
        origin: String,
        /// The line.
        line: usize,
        /// The column, from 1.
        column: usize,
        /// The column's name.
        name: String,
        /// The field.
        field: String,
    },
    /// A row has more or fewer fields than the header.
    #[error("{origin}: line {line}: {count} fields, the header has {width} columns")]
    Fields {
        /// The log.
        origin: String,
        /// The line.
        line: usize,
        /// Its fields.
        count: usize,
        /// The header's columns.
        width: usize,
    },
    /// No column of that name.
    #[error("{origin}: no column `{name}`; the columns are: {columns}")]
    NoColumn {
        /// The log.
        origin: String,
        /// The name asked for.
        name: String,
        /// The columns there are, comma-separated.
        columns: String,
    },
    /// A NaN or infinite value in a column an analysis needs finite.
    #[error(
        "{origin}: line {line}: column `{name}` is {value} (row {row}); the analysis needs \
         finite values (cut the record or fix the acquisition)"
    )]
    NotFinite {
        /// The log.
        origin: String,
        /// The line.
        line: usize,
        /// The column.
        name: String,
        /// The value.
        value: f64,
        /// The row, from 0.
        row: usize,
    },
}

message_from!(LogError);

/// Reads and parses the CSV log at `path` (see the module documentation for the format).
/// Errors name the file and, for content errors, the line and column.
pub fn read(path: &Path) -> Result<Log, LogError> {
    let text = std::fs::read_to_string(path).map_err(|source| LogError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    parse(&text, &path.display().to_string())
}

/// Parses CSV `text` (see the module documentation); `origin` names the source in errors.
pub fn parse(text: &str, origin: &str) -> Result<Log, LogError> {
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim()));
    let (header_line, header) = lines
        .by_ref()
        .find(|(_, l)| !l.is_empty() && !l.starts_with('#'))
        .ok_or_else(|| LogError::NoHeader {
            origin: origin.into(),
        })?;
    let names: Vec<String> = header
        .split(',')
        .map(|n| {
            let n = n.trim();
            let n = n
                .strip_prefix('"')
                .and_then(|s| s.strip_suffix('"'))
                .unwrap_or(n);
            n.trim().to_string()
        })
        .collect();
    for (c, n) in names.iter().enumerate() {
        if n.is_empty() {
            return Err(LogError::Unnamed {
                origin: origin.into(),
                line: header_line,
                column: c + 1,
            });
        }
        if names[..c].contains(n) {
            return Err(LogError::Twice {
                origin: origin.into(),
                line: header_line,
                name: n.clone(),
            });
        }
    }
    let width = names.len();
    let rows_hint = text.len() / (8 * width).max(1);
    let mut columns: Vec<Vec<f64>> = (0..width).map(|_| Vec::with_capacity(rows_hint)).collect();
    let mut row_lines = Vec::with_capacity(rows_hint);
    for (line_no, line) in lines {
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut count = 0;
        for (c, field) in line.split(',').enumerate() {
            if c >= width {
                count = line.split(',').count();
                break;
            }
            let field = field.trim();
            let v: f64 = field.parse().map_err(|_| LogError::NotANumber {
                origin: origin.into(),
                line: line_no,
                column: c + 1,
                name: names[c].clone(),
                field: field.into(),
            })?;
            columns[c].push(v);
            count = c + 1;
        }
        if count != width {
            return Err(LogError::Fields {
                origin: origin.into(),
                line: line_no,
                count,
                width,
            });
        }
        row_lines.push(line_no);
    }
    Ok(Log {
        origin: origin.to_string(),
        names,
        columns,
        lines: row_lines,
    })
}

impl Log {
    /// Number of rows (samples).
    pub fn len(&self) -> usize {
        self.lines.len()
    }

    /// Whether the log has no rows.
    pub fn is_empty(&self) -> bool {
        self.lines.is_empty()
    }

    /// The column called `name` (all rows, non-finite values included). The error names
    /// the file and the missing column and lists the available ones.
    pub fn column(&self, name: &str) -> Result<&[f64], LogError> {
        match self.names.iter().position(|n| n == name) {
            Some(c) => Ok(&self.columns[c]),
            None => Err(LogError::NoColumn {
                origin: self.origin.clone(),
                name: name.into(),
                columns: self.names.join(", "),
            }),
        }
    }

    /// The columns called `names`, in that order, for an analysis that needs finite
    /// numbers: besides a missing column (as [`Log::column`]), a NaN or infinite value in
    /// a selected column is an error naming the file, the column and the line.
    pub fn select(&self, names: &[&str]) -> Result<Vec<&[f64]>, LogError> {
        let mut out = Vec::with_capacity(names.len());
        for &name in names {
            let col = self.column(name)?;
            if let Some(r) = col.iter().position(|v| !v.is_finite()) {
                return Err(LogError::NotFinite {
                    origin: self.origin.clone(),
                    line: self.lines[r],
                    name: name.into(),
                    value: col[r],
                    row: r,
                });
            }
            out.push(col);
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SERVICE_LOG: &str = "seq,t_sample_ns,status,flags,y0,z0,u0,u1\n\
        0,0,0,0,0.0123,0.0121,-0.5,1.25e-3\n\
        1,125000,0,0,NaN,0.0119,inf,-inf\n\
        2,250000,0,0,-1e-300,0,0.25,3\n";

    #[test]
    fn reads_the_service_format() {
        let log = parse(SERVICE_LOG, "run.csv").unwrap();
        assert_eq!(log.len(), 3);
        assert!(!log.is_empty());
        assert_eq!(log.names[4], "y0");
        assert_eq!(
            log.column("u1").unwrap(),
            &[1.25e-3, f64::NEG_INFINITY, 3.0]
        );
        let y = log.column("y0").unwrap();
        assert!(y[1].is_nan());
        assert_eq!(y[2], -1e-300);
        assert_eq!(log.column("u0").unwrap()[1], f64::INFINITY);
        // Shortest round-trip formatting parses back to the same bits.
        let v = 0.1f64 + 0.2;
        let log = parse(&format!("a\n{v}\n"), "x").unwrap();
        assert_eq!(log.column("a").unwrap()[0].to_bits(), v.to_bits());
    }

    #[test]
    fn tolerates_comments_whitespace_crlf_and_no_trailing_newline() {
        let text = "# exported by the DAQ\r\n\r\n  time , \"ch 1\" ,u\r\n# mid comment\r\n 0.0, 1 ,2\r\n\r\n1e-3,-3.5 , 4";
        let log = parse(text, "daq.csv").unwrap();
        assert_eq!(log.names, vec!["time", "ch 1", "u"]);
        assert_eq!(log.len(), 2);
        assert_eq!(log.column("ch 1").unwrap(), &[1.0, -3.5]);
        assert_eq!(log.column("u").unwrap(), &[2.0, 4.0]);
    }

    #[test]
    fn bad_rows_name_file_line_and_column() {
        for (text, want) in [
            (
                "a,b\n1,2\n3\n",
                "f.csv: line 3: 1 fields, the header has 2 columns",
            ),
            ("a,b\n1,2,3\n", "line 2: 3 fields"),
            (
                "a,b\n1,2\n# c\n3,x1\n",
                "f.csv: line 4, column 2 (`b`): `x1` is not a number",
            ),
            ("a,b\n1,\n", "line 2, column 2"),
            ("# only\n\n", "no header"),
            ("a,,b\n", "column 2 of the header has no name"),
            ("a,b,a\n", "`a` appears twice"),
        ] {
            let e = parse(text, "f.csv").unwrap_err().to_string();
            assert!(e.contains(want), "{text:?}: {e}");
        }
    }

    #[test]
    fn missing_column_lists_the_available_ones() {
        let log = parse(SERVICE_LOG, "run.csv").unwrap();
        let e = log.column("y3").unwrap_err().to_string();
        assert!(e.contains("run.csv: no column `y3`"), "{e}");
        assert!(
            e.contains("seq, t_sample_ns, status, flags, y0, z0, u0, u1"),
            "{e}"
        );
        let e = log.select(&["z0", "nope"]).unwrap_err().to_string();
        assert!(e.contains("no column `nope`"), "{e}");
    }

    #[test]
    fn select_refuses_non_finite_values_with_the_line() {
        let log = parse(&format!("# header next\n{SERVICE_LOG}"), "run.csv").unwrap();
        let cols = log.select(&["z0", "seq"]).unwrap();
        assert_eq!(cols[0], &[0.0121, 0.0119, 0.0]);
        assert_eq!(cols[1], &[0.0, 1.0, 2.0]);
        let e = log.select(&["z0", "y0"]).unwrap_err().to_string();
        assert!(e.contains("run.csv: line 4: column `y0` is NaN"), "{e}");
        let e = log.select(&["u1"]).unwrap_err().to_string();
        assert!(e.contains("line 4: column `u1` is -inf"), "{e}");
    }

    #[test]
    fn reads_a_file_and_reports_a_missing_one() {
        let dir = std::env::temp_dir().join(format!("csvlog-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("log.csv");
        let mut text = String::from("seq,y0,u0\n");
        for k in 0..80_000u32 {
            let t = f64::from(k) * 1.25e-4;
            text.push_str(&format!("{k},{},{}\n", (t * 1e3).sin(), -t));
        }
        std::fs::write(&path, &text).unwrap();
        let t0 = std::time::Instant::now();
        let log = read(&path).unwrap();
        let took = t0.elapsed();
        assert_eq!(log.len(), 80_000);
        assert_eq!(log.column("u0").unwrap()[79_999], -(79_999.0 * 1.25e-4));
        assert!(log.origin.ends_with("log.csv"));
        // Generous: a debug build takes a few hundred ms, a release build a few tens.
        assert!(took.as_secs_f64() < 5.0, "{took:?}");
        std::fs::remove_dir_all(&dir).unwrap();
        let e = read(&dir.join("missing.csv")).unwrap_err().to_string();
        assert!(e.contains("missing.csv: cannot read the log"), "{e}");
    }
}
