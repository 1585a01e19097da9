//! What a run reports: the rows it measured ([`Measured`]), what the phases collect on the
//! way ([`Collected`]), and the files written at the end ([`finish`], [`write_results`]).
//!
//! A run writes, into its output folder, `table.txt` (what was printed) and
//! `summary.json` (every figure, the settings and the service's run reports), and into
//! the **results file** (`--results FILE`, else [`RESULTS_FILE_NAME`] in the output
//! folder) one Markdown section holding the printed table with the machine description,
//! the date and the exact command line. The repository's results file,
//! `docs/results/latency-bench.md`, is the one place where measured figures live (the
//! docs link to it instead of copying numbers); a run writes it only when `--results`
//! names it.
//!
//! The file has one section per kind of run ([`RunKind`]), between HTML comment markers
//! (`<!-- latency-bench:full:begin -->` … `<!-- latency-bench:full:end -->`): a run
//! replaces its own section and keeps the others, so that `latency-bench pcac` does not
//! erase the figures of the last full run.

use crate::machine::MachineFacts;
use crate::table::{self, Row};
use serde_json::{Map, Value, json};
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

/// One measurement's outcome, for the table and `summary.json`.
#[derive(Debug, Clone)]
pub struct Measured {
    /// Stable identifier (`summary.json`).
    pub id: String,
    /// The table's label.
    pub label: String,
    /// Number of values behind the percentiles.
    pub count: Option<u64>,
    /// p50, p99, p99.9 and max in µs.
    pub us: [Option<f64>; 4],
    /// The full summary, when the row comes from an HdrHistogram.
    pub summary: Option<crate::hist::Summary>,
    /// The table's note (ratios, budget share, why the row is empty).
    pub note: String,
    /// The distribution files written for it.
    pub files: Vec<PathBuf>,
    /// Why the measurement failed, if it did.
    pub error: Option<String>,
}

impl Measured {
    /// A row from a summary and its files.
    pub fn from_summary(
        id: &str,
        label: &str,
        s: crate::hist::Summary,
        files: Vec<PathBuf>,
    ) -> Self {
        Self {
            id: id.into(),
            label: label.into(),
            count: Some(s.count),
            us: s.columns_us(),
            summary: Some(s),
            note: String::new(),
            files,
            error: None,
        }
    }

    /// A row without values (a skipped measurement), with its reason as the note.
    pub fn empty(id: &str, label: &str, note: &str) -> Self {
        Self {
            id: id.into(),
            label: label.into(),
            count: None,
            us: [None; 4],
            summary: None,
            note: note.into(),
            files: Vec::new(),
            error: None,
        }
    }

    /// A failed measurement.
    pub fn failed(id: &str, label: &str, why: String) -> Self {
        Self {
            error: Some(why),
            ..Self::empty(id, label, "")
        }
    }

    /// The table row (a failure shows the first line of its error).
    pub fn row(&self) -> Row {
        let note = match &self.error {
            Some(e) => format!("FAILED: {}", e.lines().next().unwrap_or("")),
            None => self.note.clone(),
        };
        Row::new(self.label.clone(), self.count, self.us, note)
    }

    /// The row's entry in `summary.json`.
    pub fn json(&self) -> Value {
        json!({
            "id": self.id,
            "label": self.label,
            "summary": self.summary,
            "p50_us": self.us[0], "p99_us": self.us[1], "p99_9_us": self.us[2], "max_us": self.us[3],
            "note": self.note,
            "files": self.files,
            "error": self.error,
        })
    }
}

/// What the phases of a run collect: the rows in table order, the lines printed under
/// the table, the phase-specific blocks of `summary.json` (`extra`) and the service's run
/// reports.
#[derive(Debug, Default)]
pub struct Collected {
    /// The rows, in table order.
    pub measured: Vec<Measured>,
    /// Lines printed under the table.
    pub details: Vec<String>,
    /// `summary.json` → `extra`.
    pub extra: Map<String, Value>,
    /// `summary.json` → `service_reports`.
    pub reports: Map<String, Value>,
}

/// The kind of a run, which names its section of the results file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunKind {
    /// `latency-bench`: every phase.
    Full,
    /// `latency-bench pcac`: the PCAC phase alone.
    Pcac,
    /// `latency-bench jack`: the acoustic rig through a sound card under JACK.
    Jack,
}

impl RunKind {
    /// Every kind, in the order of their sections in the results file.
    pub const ALL: [RunKind; 3] = [RunKind::Full, RunKind::Pcac, RunKind::Jack];

    /// The key in the section markers.
    pub fn key(self) -> &'static str {
        match self {
            RunKind::Full => "full",
            RunKind::Pcac => "pcac",
            RunKind::Jack => "jack",
        }
    }

    /// The section's heading.
    pub fn title(self) -> &'static str {
        match self {
            RunKind::Full => "Full run (`latency-bench`)",
            RunKind::Pcac => "PCAC step cost alone (`latency-bench pcac`)",
            RunKind::Jack => "A sound card under JACK (`latency-bench jack`)",
        }
    }

    /// The caption of the section's table.
    fn caption(self) -> &'static str {
        match self {
            RunKind::Full | RunKind::Pcac => "Results (µs):",
            RunKind::Jack => "Results:",
        }
    }

    fn begin(self) -> String {
        format!("<!-- latency-bench:{}:begin -->", self.key())
    }

    fn end(self) -> String {
        format!("<!-- latency-bench:{}:end -->", self.key())
    }
}

/// The results file's name in a run's output folder, its default place.
pub const RESULTS_FILE_NAME: &str = "latency-bench.md";

/// The results file of a run whose output folder is `out`: `given` (`--results`), else
/// [`RESULTS_FILE_NAME`] in `out`.
pub fn results_file(given: Option<&Path>, out: &Path) -> PathBuf {
    given.map_or_else(|| out.join(RESULTS_FILE_NAME), Path::to_path_buf)
}

/// Seconds since the Unix epoch (0 if the clock is before it).
pub fn unix_now() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0)
}

/// `unix` seconds as a UTC date and time, `YYYY-MM-DD HH:MM:SS UTC`.
pub fn utc_date(unix: u64) -> String {
    let (mut days, secs) = (unix / 86_400, unix % 86_400);
    let leap = |y: u64| (y.is_multiple_of(4) && !y.is_multiple_of(100)) || y.is_multiple_of(400);
    let mut year = 1970;
    loop {
        let len = if leap(year) { 366 } else { 365 };
        if days < len {
            break;
        }
        days -= len;
        year += 1;
    }
    let feb = if leap(year) { 29 } else { 28 };
    let months = [31, feb, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31];
    let mut month = 0;
    while days >= months[month] {
        days -= months[month];
        month += 1;
    }
    format!(
        "{year:04}-{:02}-{:02} {:02}:{:02}:{:02} UTC",
        month + 1,
        days + 1,
        secs / 3_600,
        secs / 60 % 60,
        secs % 60
    )
}

/// `args` as one shell command line, each argument quoted when it needs it.
pub fn shell_line(args: &[String]) -> String {
    args.iter()
        .map(|a| {
            let plain = !a.is_empty()
                && a.chars()
                    .all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c));
            if plain {
                a.clone()
            } else {
                format!("'{}'", a.replace('\'', r"'\''"))
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// What a run writes into its section of the results file, beside the table.
#[derive(Debug, Clone)]
pub struct RunRecord<'a> {
    /// Which section.
    pub kind: RunKind,
    /// When the run started, Unix seconds.
    pub started_unix: u64,
    /// The command line, `argv[0]` included.
    pub command: Vec<String>,
    /// The machine.
    pub facts: &'a MachineFacts,
    /// The resolved settings, as in `summary.json`.
    pub settings: Value,
    /// The output folder.
    pub out: &'a Path,
    /// The results file.
    pub results: &'a Path,
}

impl RunRecord<'_> {
    /// The Markdown section (markers excluded) for `table` and the lines printed under it.
    pub fn section(&self, table: &str, lines: &[String]) -> String {
        let args = self.command.get(1..).unwrap_or(&[]);
        let cargo: Vec<String> = ["cargo", "run", "--release", "-p", "latency-bench"]
            .iter()
            .map(|s| s.to_string())
            .chain((!args.is_empty()).then(|| "--".to_string()))
            .chain(args.iter().cloned())
            .collect();
        let mut s = format!("## {}\n\n", self.kind.title());
        s.push_str(&format!("- date: {}\n", utc_date(self.started_unix)));
        s.push_str(&format!("- command: `{}`\n", shell_line(&self.command)));
        s.push_str(&format!("  (as `{}`)\n", shell_line(&cargo)));
        s.push_str(&format!(
            "- output folder: `{}` (`summary.json`, `table.txt`, the `.hgrm`/`.hlog` files)\n",
            self.out.display()
        ));
        s.push_str(&format!("- settings: `{}`\n\n", self.settings));
        s.push_str("Machine:\n\n```text\n");
        s.push_str(self.facts.render().trim_end());
        s.push_str(&format!("\n```\n\n{}\n\n```text\n", self.kind.caption()));
        s.push_str(table.trim_end());
        s.push_str("\n```\n");
        if !lines.is_empty() {
            s.push_str("\nDetails:\n\n```text\n");
            s.push_str(lines.join("\n").trim_end());
            s.push_str("\n```\n");
        }
        s
    }
}

/// The first lines of a new results file.
const HEADER: &str = "# latency-bench results

Written by `latency-bench`: do not edit by hand. How to run it, what each phase measures
and how to read the figures: `latency-bench/README.md`. Each kind of run replaces its own
section below and records the machine, the date and the exact command line that produced
it.
";

/// `existing` (a results file, or `None` for a new one) with the section of `kind`
/// replaced by `body`, or inserted in the order of [`RunKind::ALL`] when it is absent.
pub fn merge_section(existing: Option<&str>, kind: RunKind, body: &str) -> String {
    let (begin, end) = (kind.begin(), kind.end());
    let block = format!("{begin}\n{}\n{end}", body.trim_end());
    let text = existing.unwrap_or(HEADER);
    if let Some(b) = text.find(&begin)
        && let Some(e) = text[b..].find(&end)
    {
        let e = b + e + end.len();
        return format!("{}{block}{}", &text[..b], &text[e..]);
    }
    // Absent: before the first section of a later kind, else at the end.
    let later = RunKind::ALL
        .iter()
        .skip_while(|k| **k != kind)
        .skip(1)
        .find_map(|k| text.find(&k.begin()));
    match later {
        Some(at) => format!("{}{block}\n\n{}", &text[..at], &text[at..]),
        None => format!("{}\n\n{block}\n", text.trim_end()),
    }
}

/// Writes `table.txt` and `summary.json` into `out`, and the section of `record` (the table
/// and `lines`) into the results file; the exit code: 1 when the summary or the results
/// file cannot be written or a measurement failed, else 0.
pub fn write_results(
    out: &Path,
    table_text: &str,
    summary: &Value,
    measured: &[Measured],
    record: &RunRecord,
    table: &str,
    lines: &[String],
) -> i32 {
    let _ = std::fs::write(out.join("table.txt"), table_text);
    let text = serde_json::to_string_pretty(summary).expect("the summary serializes");
    if let Err(e) = std::fs::write(out.join("summary.json"), text) {
        eprintln!("writing summary.json: {e}");
        return 1;
    }
    if let Err(e) = write_section(record.results, record.kind, &record.section(table, lines)) {
        eprintln!("writing the results file {}: {e}", record.results.display());
        return 1;
    }
    if measured.iter().any(|m| m.error.is_some()) {
        1
    } else {
        0
    }
}

/// Replaces the section of `kind` in the results file `path` by `body` (creating the file
/// and its folder when needed), through a temporary file and a rename.
fn write_section(path: &Path, kind: RunKind, body: &str) -> std::io::Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    let existing = match std::fs::read_to_string(path) {
        Ok(t) => Some(t),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
        Err(e) => return Err(e),
    };
    let text = merge_section(existing.as_deref(), kind, body);
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(format!(".tmp-{}", std::process::id()));
    std::fs::write(&tmp, text)?;
    std::fs::rename(&tmp, path)
}

/// The end of a run: prints the table, `details` and `footer`, then writes the output
/// folder's files and the results file ([`write_results`]); `summary` is completed with
/// the rows and the details. Returns the exit code.
pub fn finish(
    record: &RunRecord,
    collected: &Collected,
    footer: &[String],
    mut summary: Map<String, Value>,
) -> i32 {
    let rows: Vec<Row> = collected.measured.iter().map(Measured::row).collect();
    let table = table::render(&rows);
    println!("{table}");
    for d in collected.details.iter().chain(footer) {
        println!("{d}");
    }
    println!("results: {}", record.out.display());
    let table_text = format!(
        "{}\n{table}\n{}\n",
        record.facts.render(),
        collected.details.join("\n")
    );
    summary.insert(
        "measurements".into(),
        collected.measured.iter().map(Measured::json).collect(),
    );
    summary.insert("details".into(), json!(collected.details));
    let lines: Vec<String> = collected.details.iter().chain(footer).cloned().collect();
    let code = write_results(
        record.out,
        &table_text,
        &Value::Object(summary),
        &collected.measured,
        record,
        &table,
        &lines,
    );
    println!("results file: {}", record.results.display());
    code
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_writes_its_results_into_its_output_folder_unless_told_otherwise() {
        let out = Path::new("bench-results/7");
        assert_eq!(
            results_file(None, out),
            Path::new("bench-results/7/latency-bench.md")
        );
        let docs = Path::new("docs/results/latency-bench.md");
        assert_eq!(results_file(Some(docs), out), docs);
    }

    #[test]
    fn dates_are_utc_calendar_dates() {
        assert_eq!(utc_date(0), "1970-01-01 00:00:00 UTC");
        assert_eq!(utc_date(951_782_400), "2000-02-29 00:00:00 UTC");
        assert_eq!(utc_date(1_764_616_708), "2025-12-01 19:18:28 UTC");
        assert_eq!(utc_date(4_107_542_399), "2100-02-28 23:59:59 UTC");
        assert_eq!(utc_date(4_107_542_400), "2100-03-01 00:00:00 UTC");
    }

    #[test]
    fn arguments_are_quoted_only_when_they_need_it() {
        let args = ["latency-bench", "--out", "a b", "--x=it's", ""].map(String::from);
        assert_eq!(
            shell_line(&args),
            r"latency-bench --out 'a b' '--x=it'\''s' ''"
        );
    }

    #[test]
    fn a_run_replaces_its_own_section_and_keeps_the_others() {
        let first = merge_section(None, RunKind::Pcac, "pcac one");
        assert!(first.starts_with("# latency-bench results"));
        let both = merge_section(Some(&first), RunKind::Full, "full one");
        let (f, p) = (
            both.find("full one").unwrap(),
            both.find("pcac one").unwrap(),
        );
        assert!(f < p, "the full section comes first:\n{both}");
        let again = merge_section(Some(&both), RunKind::Pcac, "pcac two");
        assert!(again.contains("full one") && again.contains("pcac two"));
        assert!(!again.contains("pcac one"));
        assert_eq!(again.matches("latency-bench:pcac:begin").count(), 1);
        let same = merge_section(Some(&again), RunKind::Full, "full one");
        assert_eq!(same, again);
    }

    #[test]
    fn a_section_records_the_command_the_machine_and_the_table() {
        let setup = ipc_types::rt::RtSetup {
            affinity: ipc_types::rt::StepOutcome::Skipped,
            fifo: ipc_types::rt::StepOutcome::Skipped,
            mlockall: ipc_types::rt::StepOutcome::Skipped,
            cpu_latency: ipc_types::rt::StepOutcome::Skipped,
        };
        let facts = crate::machine::collect(&setup, 0);
        let record = RunRecord {
            kind: RunKind::Pcac,
            started_unix: 0,
            command: ["target/release/latency-bench", "pcac", "--quick"]
                .map(String::from)
                .into(),
            facts: &facts,
            settings: json!({"steps": 300}),
            out: Path::new("bench-results/pcac-0"),
            results: Path::new("r.md"),
        };
        let s = record.section("measurement  count\nrow  1\n", &["a detail".into()]);
        assert!(s.contains("1970-01-01 00:00:00 UTC"), "{s}");
        assert!(
            s.contains("`target/release/latency-bench pcac --quick`"),
            "{s}"
        );
        assert!(
            s.contains("`cargo run --release -p latency-bench -- pcac --quick`"),
            "{s}"
        );
        assert!(s.contains(&facts.render().lines().next().unwrap().to_string()));
        assert!(s.contains("row  1") && s.contains("a detail"), "{s}");
    }
}
