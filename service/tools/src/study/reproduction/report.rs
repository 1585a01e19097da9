//! The reproduction report of `study all` (`reproduction.md`): per chapter, each study's
//! claims ([`crate::study::reproduction::Claim`]) as a table, the dissertation's statement
//! beside our number, the criterion and the verdict, with links to the study's summary and
//! figures and its wall time; at the top one row per study with its counts and the wall
//! time of the whole.
//!
//! It is generated from the studies' `claims.json` files only ([`crate::study::all`]
//! reads them), never from their printed summaries.

use std::fmt::Write as _;
use std::path::Path;

use crate::study::all::{AllRun, CHAPTERS, Size, StudyRun};
use crate::study::reproduction::{CLAIMS_FILE, Verdict};

/// How the report refers to the files of the studies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Links<'a> {
    /// Markdown links relative to the output folder (the report written into it).
    Relative,
    /// Paths as text, under the output folder as given (a copy kept elsewhere, e.g. in
    /// `docs/results/`, where the studies' folders are not), and links to the claims'
    /// figures in the folder `figures`, relative to the report, where
    /// [`super::figures::copy_claim_figures`] put them.
    Committed {
        /// The figures' folder, relative to the report.
        figures: &'a str,
    },
}

/// A table cell: no line breaks, `|` escaped.
fn cell(s: &str) -> String {
    s.replace('\n', " ").replace('|', "\\|")
}

/// Seconds with one decimal.
fn secs(t: f64) -> String {
    format!("{t:.1} s")
}

/// Orders file names with their digit runs compared as numbers (`figure-3.5` before
/// `figure-3.10`).
fn natural_key(name: &str) -> Vec<(u8, u64, String)> {
    let mut key = Vec::new();
    let mut rest = name;
    while !rest.is_empty() {
        let digits = rest.chars().take_while(char::is_ascii_digit).count();
        if digits > 0 {
            let (d, r) = rest.split_at(digits);
            key.push((0, d.parse().unwrap_or(u64::MAX), String::new()));
            rest = r;
        } else {
            let text = rest.chars().take_while(|c| !c.is_ascii_digit()).count();
            let (t, r) =
                rest.split_at(rest.char_indices().nth(text).map_or(rest.len(), |(i, _)| i));
            key.push((1, 0, t.to_string()));
            rest = r;
        }
    }
    key
}

/// The PNG figures in `dir`, in natural order.
fn figures(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .filter_map(Result::ok)
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.ends_with(".png"))
                .collect()
        })
        .unwrap_or_default();
    names.sort_by_key(|n| natural_key(n));
    names
}

/// A reference to `file` of the study `name`.
fn file_ref(out: &Path, name: &str, file: &str, links: Links) -> String {
    match links {
        Links::Relative => format!("[{file}]({name}/{file})"),
        Links::Committed { .. } => format!("`{}`", out.join(name).join(file).display()),
    }
}

/// The figures cell of a claim: a link to each of its figures that its study wrote.
fn figures_cell(dir: &Path, name: &str, files: &[String], links: Links) -> String {
    let base = match links {
        Links::Relative => name.to_string(),
        Links::Committed { figures } => format!("{figures}/{name}"),
    };
    let cells: Vec<String> = files
        .iter()
        .map(|f| {
            let label = f.trim_end_matches(".png");
            if dir.join(f).is_file() {
                format!("[{label}]({base}/{f})")
            } else {
                format!("{label} (not written)")
            }
        })
        .collect();
    if cells.is_empty() {
        "–".into()
    } else {
        cells.join("<br>")
    }
}

/// The verdict cell: the word in bold, the reason after it.
fn verdict_cell(v: Verdict, reason: Option<&str>) -> String {
    match reason {
        Some(r) if v == Verdict::NotChecked => format!("**{}**: {}", v.word(), cell(r)),
        _ => format!("**{}**", v.word()),
    }
}

/// One study's section.
fn study_section(s: &mut String, all: &AllRun, r: &StudyRun, links: Links) {
    let e = &r.entry;
    let _ = writeln!(s, "<a id=\"{}\"></a>\n", anchor(r));
    let _ = writeln!(s, "### `{}`: {}\n", e.name, e.title);
    let command = std::iter::once(format!(
        "study {} --out {}",
        e.name,
        all.out.join(e.name).display()
    ))
    .chain(r.args.iter().cloned())
    .collect::<Vec<_>>()
    .join(" ");
    let _ = writeln!(s, "Ran `{command}` in {}.", secs(r.wall));
    let claims = match &r.claims {
        Ok(c) => c,
        Err(err) => {
            let _ = writeln!(
                s,
                "\n**Failed to run**: {}. Log: {}.\n",
                cell(&err.to_string()),
                file_ref(&all.out, e.name, crate::study::all::LOG_FILE, links)
            );
            return;
        }
    };
    let figs = figures(&r.dir);
    let figures_text = match links {
        Links::Relative => figs
            .iter()
            .map(|f| file_ref(&all.out, e.name, f, links))
            .collect::<Vec<_>>()
            .join(", "),
        Links::Committed { .. } => format!(
            "{} PNG files in `{}`",
            figs.len(),
            all.out.join(e.name).display()
        ),
    };
    let _ = writeln!(
        s,
        "The numbers come from `{}`. Summary: {}; claims: {}; figures: {}.\n",
        claims.run,
        file_ref(&all.out, e.name, e.summary, links),
        file_ref(&all.out, e.name, CLAIMS_FILE, links),
        if figs.is_empty() {
            "none".into()
        } else {
            figures_text
        }
    );
    let _ = writeln!(
        s,
        "| # | the dissertation | ours | criterion | verdict | figures |\n| --- | --- | --- | --- | --- | --- |"
    );
    for c in &claims.claims {
        let ours = if c.ours.is_empty() { "–" } else { &c.ours };
        let _ = writeln!(
            s,
            "| {} | {}: {} | {} | {} | {} | {} |",
            cell(&c.id),
            cell(&c.source),
            cell(&c.claim),
            cell(ours),
            cell(&c.criterion),
            verdict_cell(c.verdict, c.reason.as_deref()),
            figures_cell(&r.dir, e.name, &c.figures, links)
        );
    }
    s.push('\n');
    sensitivity_table(s, &claims.sensitivity);
}

/// A study's sensitivity table ([`super::sensitivity`]): one row per alternative, one
/// column per claim the rows bear on, with a line before it that counts, per claim, the
/// alternatives under which it holds. Nothing when the study has none.
pub fn sensitivity_table(s: &mut String, rows: &[super::sensitivity::Alternative]) {
    if rows.is_empty() {
        return;
    }
    let tally = super::sensitivity::tally(rows);
    let counts: Vec<String> = tally
        .iter()
        .map(|(id, pass, n)| format!("{id} holds under {pass} of {n}"))
        .collect();
    let _ = writeln!(
        s,
        "**Sensitivity.** The settings the chapter leaves open or states ambiguously, each moved from the \
         study's value to alternatives, all else as the study ran it; under each, the verdict of the claims it \
         bears on by their own criteria (a row whose alternative is the study's value is the study's run). \
         Over the alternatives: {}.\n",
        counts.join("; ")
    );
    let ids: Vec<&str> = tally.iter().map(|(id, _, _)| id.as_str()).collect();
    let _ = writeln!(
        s,
        "| setting | why it is open | ours | alternative |{}\n| --- | --- | --- | --- |{}",
        ids.iter()
            .map(|id| format!(" {} |", cell(id)))
            .collect::<String>(),
        " --- |".repeat(ids.len())
    );
    let mut previous: Option<&str> = None;
    for row in rows {
        let why = if previous == Some(row.setting.as_str()) {
            ""
        } else {
            row.why_open.as_str()
        };
        previous = Some(row.setting.as_str());
        let verdicts: String = ids
            .iter()
            .map(|id| match row.readings.iter().find(|r| r.claim == *id) {
                Some(r) => format!(" **{}** {} |", r.verdict.word(), cell(&r.measured)),
                None => " |".into(),
            })
            .collect();
        let value = if row.is_ours() {
            format!("*{}* (ours)", cell(&row.value))
        } else {
            cell(&row.value)
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} |{verdicts}",
            cell(&row.setting),
            cell(why),
            cell(&row.ours),
            value
        );
    }
    s.push('\n');
}

/// The report of `all`, referring to the studies' files as `links` says.
pub fn render(all: &AllRun, links: Links) -> String {
    let mut s = String::new();
    let docs = match links {
        Links::Relative => {
            "`docs/studies.md` (section \"Every chapter in one command\")".to_string()
        }
        Links::Committed { .. } => {
            "[studies.md](../studies.md#every-chapter-in-one-command-study-all)".to_string()
        }
    };
    let _ = writeln!(
        s,
        "# Reproduction of the dissertation's numerical results\n\n\
         Written by `study all` from the studies' `claims.json`: do not edit by hand. How it is made and \
         how to read it: {docs}.\n"
    );
    let _ = writeln!(s, "Command: `{}`.", all.options.command);
    match all.options.size {
        Size::Full => {
            let _ = writeln!(
                s,
                "Full reproduction: every study with its default options."
            );
        }
        Size::Quick => {
            let _ = writeln!(
                s,
                "**Quick run** (`--quick`): reduced sizes; the verdicts below are those of the reduced runs, \
                 not the reproduction's."
            );
        }
    }
    let _ = writeln!(
        s,
        "{} at a time, each with `RAYON_NUM_THREADS={}`, on a machine with {} core(s). Wall time of the whole: \
         **{}** (wall times vary with the machine's load).\n",
        all.options.jobs,
        all.options.threads,
        std::thread::available_parallelism().map_or(1, |n| n.get()),
        secs(all.wall)
    );
    let _ = writeln!(
        s,
        "A claim is what the dissertation states, quoted, with where it says it; *ours* is what the study \
         measured; the *criterion* is the test on our numbers that decides the verdict: **PASS**, **FAIL**, or \
         **NOT CHECKED** with the reason.\n"
    );
    let _ = writeln!(
        s,
        "| chapter | study | wall time | ran | PASS | FAIL | NOT CHECKED |\n| --- | --- | --- | --- | --- | --- | --- |"
    );
    for r in &all.runs {
        let _ = writeln!(
            s,
            "| {} | [`{}`](#{}) | {} | {} | {} | {} | {} |",
            r.entry.chapter,
            r.entry.name,
            anchor(r),
            secs(r.wall),
            if r.claims.is_ok() { "yes" } else { "**no**" },
            r.count(Verdict::Pass),
            r.count(Verdict::Fail),
            r.count(Verdict::NotChecked)
        );
    }
    let _ = writeln!(
        s,
        "| | **all** | **{}** | {} of {} | {} | {} | {} |\n",
        secs(all.wall),
        all.runs.len() - all.failed().len(),
        all.runs.len(),
        all.count(Verdict::Pass),
        all.count(Verdict::Fail),
        all.count(Verdict::NotChecked)
    );
    for (chapter, title) in CHAPTERS {
        let runs: Vec<&StudyRun> = all
            .runs
            .iter()
            .filter(|r| r.entry.chapter == *chapter)
            .collect();
        if runs.is_empty() {
            continue;
        }
        let _ = writeln!(s, "## Chapter {chapter}: {title}\n");
        for r in runs {
            study_section(&mut s, all, r, links);
        }
    }
    s
}

/// The anchor of `r`'s section.
fn anchor(r: &StudyRun) -> String {
    format!("study-{}", r.entry.name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figure_names_sort_with_their_numbers_as_numbers() {
        let mut v = vec![
            "figure-3.10-b.png",
            "figure-3.5-a.png",
            "figure-3.9.png",
            "figure-3.5-b.png",
        ];
        v.sort_by_key(|n| natural_key(n));
        assert_eq!(
            v,
            [
                "figure-3.5-a.png",
                "figure-3.5-b.png",
                "figure-3.9.png",
                "figure-3.10-b.png"
            ]
        );
    }

    #[test]
    fn the_sensitivity_table_has_a_column_per_claim_and_marks_the_studys_row() {
        use crate::study::reproduction::sensitivity::{Alternative, Reading};
        let rows = vec![
            Alternative::new(
                "P_0",
                "not given",
                "1 I",
                "1 I",
                vec![Reading::of("6.4", false, "27.6 s")],
            ),
            Alternative::new(
                "P_0",
                "not given",
                "1 I",
                "10 I",
                vec![
                    Reading::of("6.4", false, "15.0 s"),
                    Reading::of("6.5", true, "node 8 4 s"),
                ],
            ),
        ];
        let mut s = String::new();
        sensitivity_table(&mut s, &rows);
        assert!(
            s.contains("6.4 holds under 0 of 1; 6.5 holds under 1 of 1"),
            "{s}"
        );
        assert!(
            s.contains("| setting | why it is open | ours | alternative | 6.4 | 6.5 |"),
            "{s}"
        );
        assert!(
            s.contains("| P_0 | not given | 1 I | *1 I* (ours) | **FAIL** 27.6 s | |"),
            "{s}"
        );
        assert!(
            s.contains("| P_0 |  | 1 I | 10 I | **FAIL** 15.0 s | **PASS** node 8 4 s |"),
            "{s}"
        );
        let mut empty = String::new();
        sensitivity_table(&mut empty, &[]);
        assert!(empty.is_empty());
    }

    #[test]
    fn cells_keep_the_table_intact() {
        assert_eq!(cell("|u| ≤ 10 N\nok"), "\\|u\\| ≤ 10 N ok");
    }
}
