//! The printed result table: one row per measurement, four latency columns in µs and a
//! free-text note (ratios, budget share, failures).

/// One row of the table.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// What was measured.
    pub label: String,
    /// Number of values behind the percentiles (`None`: not applicable).
    pub count: Option<u64>,
    /// p50, p99, p99.9 and max in µs; `None` prints as `-`.
    pub us: [Option<f64>; 4],
    /// Ratios, shares of the budget, or why the row is empty.
    pub note: String,
}

impl Row {
    /// A row with values.
    pub fn new(
        label: impl Into<String>,
        count: Option<u64>,
        us: [Option<f64>; 4],
        note: impl Into<String>,
    ) -> Self {
        Self {
            label: label.into(),
            count,
            us,
            note: note.into(),
        }
    }

    /// A row without values, e.g. a skipped or failed measurement.
    pub fn empty(label: impl Into<String>, note: impl Into<String>) -> Self {
        Self::new(label, None, [None; 4], note)
    }
}

/// A value in µs with a precision that suits its size (`-` for `None`).
pub fn fmt_us(v: Option<f64>) -> String {
    match v {
        None => "-".to_string(),
        Some(v) if !v.is_finite() => "-".to_string(),
        Some(v) if v < 10.0 => format!("{v:.3}"),
        Some(v) if v < 1_000.0 => format!("{v:.2}"),
        Some(v) => format!("{v:.0}"),
    }
}

/// A ratio with two decimals (`-` for `None`).
pub fn fmt_ratio(v: Option<f64>) -> String {
    match v {
        Some(v) if v.is_finite() => format!("{v:.2}"),
        _ => "-".to_string(),
    }
}

/// Renders the rows under a header; the label column is as wide as the longest label.
pub fn render(rows: &[Row]) -> String {
    let w = rows
        .iter()
        .map(|r| r.label.chars().count())
        .max()
        .unwrap_or(0)
        .max("measurement".len());
    let mut out = format!(
        "{:<w$}  {:>9}  {:>9}  {:>9}  {:>9}  {:>9}  {}\n",
        "measurement", "count", "p50 µs", "p99 µs", "p99.9 µs", "max µs", "notes"
    );
    out.push_str(&format!("{}\n", "-".repeat(w + 2 + 5 * 11 + 5)));
    for r in rows {
        let count = r.count.map(|c| c.to_string()).unwrap_or_else(|| "-".into());
        let line = format!(
            "{:<w$}  {:>9}  {:>9}  {:>9}  {:>9}  {:>9}  {}",
            r.label,
            count,
            fmt_us(r.us[0]),
            fmt_us(r.us[1]),
            fmt_us(r.us[2]),
            fmt_us(r.us[3]),
            r.note
        );
        out.push_str(line.trim_end());
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_get_a_precision_that_suits_their_size() {
        assert_eq!(fmt_us(Some(1.23456)), "1.235");
        assert_eq!(fmt_us(Some(12.3456)), "12.35");
        assert_eq!(fmt_us(Some(12_345.6)), "12346");
        assert_eq!(fmt_us(None), "-");
        assert_eq!(fmt_us(Some(f64::NAN)), "-");
        assert_eq!(fmt_ratio(Some(1.234)), "1.23");
        assert_eq!(fmt_ratio(None), "-");
    }

    #[test]
    fn rows_line_up_under_the_header() {
        let rows = [
            Row::new(
                "contract round trip",
                Some(50_000),
                [Some(4.1), Some(6.0), Some(12.5), Some(80.0)],
                "x 1.10",
            ),
            Row::empty("cyclictest (core 1, 125 µs)", "cyclictest not installed"),
        ];
        let t = render(&rows);
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines.len(), 4);
        let col = |line: &str, pat: &str| line.find(pat).unwrap();
        // The right edge of the p50 column is the same in the header and in a row.
        let header_end = col(lines[0], "p50 µs") + "p50 µs".len();
        let row_end = col(lines[2], "4.100") + "4.100".len();
        assert_eq!(
            lines[0][..header_end].chars().count(),
            lines[2][..row_end].chars().count()
        );
        assert!(lines[3].starts_with("cyclictest (core 1, 125 µs)"));
        assert!(lines[3].ends_with("cyclictest not installed"));
        assert!(lines[3].contains("  -  "));
    }
}
