//! The sensitivity record of a study: the settings its chapter leaves open (or states
//! ambiguously) that the study had to choose, each moved to alternatives, and the verdicts
//! of the claims it bears on under each.
//!
//! A verdict that holds under the study's choice alone is a reading of the text, not a
//! reproduction; one that fails under every alternative is a measured argument that no
//! reading of that setting gives the claim. Each [`Alternative`] is one row of the
//! chapter's sensitivity table in the report
//! ([`crate::study::reproduction::report`]): the setting, why it is open, the study's
//! value, the alternative, and for each claim it bears on the verdict under it with the
//! number behind it ([`Reading`]). The row whose [`Alternative::value`] equals
//! [`Alternative::ours`] is the study's own run, repeated so that the table can be read
//! alone.
//!
//! In `claims.json` it is the `sensitivity` list beside `claims`:
//!
//! ```json
//! "sensitivity": [
//!   {
//!     "setting": "P_0",
//!     "why_open": "printed, but its scale depends on the unit of y",
//!     "ours": "I",
//!     "value": "10 I",
//!     "readings": [{"claim": "6.4", "verdict": "FAIL", "measured": "15.0 s"}]
//!   }
//! ]
//! ```

use serde::{Deserialize, Serialize};

use super::Verdict;

/// A claim's verdict under one alternative.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Reading {
    /// The claim's id ([`super::Claim::id`]), in the same file.
    pub claim: String,
    /// Its verdict under the alternative, by the claim's own criterion.
    pub verdict: Verdict,
    /// The number behind it (e.g. `15.0 s`).
    pub measured: String,
}

impl Reading {
    /// The verdict of `claim` under an alternative: PASS when `ok`.
    pub fn of(claim: &str, ok: bool, measured: impl Into<String>) -> Self {
        Self {
            claim: claim.into(),
            verdict: Verdict::of(ok),
            measured: measured.into(),
        }
    }
}

/// One setting moved to one alternative value.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Alternative {
    /// The setting (e.g. `convergence window`).
    pub setting: String,
    /// Why the chapter leaves it open (e.g. `not given`).
    pub why_open: String,
    /// The study's value.
    pub ours: String,
    /// The alternative value (equal to [`Self::ours`] in the study's own row).
    pub value: String,
    /// The verdicts of the claims it bears on.
    pub readings: Vec<Reading>,
}

impl Alternative {
    /// The row of `setting` at `value`, the study's choice being `ours`.
    pub fn new(
        setting: impl Into<String>,
        why_open: impl Into<String>,
        ours: impl Into<String>,
        value: impl Into<String>,
        readings: Vec<Reading>,
    ) -> Self {
        Self {
            setting: setting.into(),
            why_open: why_open.into(),
            ours: ours.into(),
            value: value.into(),
            readings,
        }
    }

    /// Whether this row is the study's own choice.
    pub fn is_ours(&self) -> bool {
        self.value == self.ours
    }

    /// The alternative as a summary shows it: `(ours)` in the study's own row.
    pub fn shown_value(&self) -> &str {
        if self.is_ours() {
            "(ours)"
        } else {
            &self.value
        }
    }
}

/// For each claim the rows bear on, in order of first appearance: how many of the
/// alternatives (the study's own rows not counted) give PASS, and how many there are.
pub fn tally(rows: &[Alternative]) -> Vec<(String, usize, usize)> {
    let mut out: Vec<(String, usize, usize)> = Vec::new();
    for row in rows.iter().filter(|r| !r.is_ours()) {
        for r in &row.readings {
            let i = match out.iter().position(|(id, _, _)| *id == r.claim) {
                Some(i) => i,
                None => {
                    out.push((r.claim.clone(), 0, 0));
                    out.len() - 1
                }
            };
            out[i].2 += 1;
            if r.verdict == Verdict::Pass {
                out[i].1 += 1;
            }
        }
    }
    out
}

/// The [`tally`] as one line's text: `4.1 7/12, 4.2 10/12, …`.
pub fn tally_text(rows: &[Alternative]) -> String {
    tally(rows)
        .iter()
        .map(|(id, pass, n)| format!("{id} {pass}/{n}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Points each claim's [`super::Claim::ours`] to the table: appends `; sensitivity table:
/// holds under p of n alternatives` ([`tally`]) to every claim the rows bear on.
pub fn annotate(claims: &mut [super::Claim], rows: &[Alternative]) {
    for (id, pass, n) in tally(rows) {
        if let Some(c) = claims.iter_mut().find(|c| c.id == id) {
            c.ours.push_str(&format!(
                "; sensitivity table: holds under {pass} of {n} alternatives"
            ));
        }
    }
}

/// The rows as CSV, one line per alternative and claim it bears on: `setting, ours, value,
/// claim, verdict, measured` (every field quoted, `"` doubled); a row with no reading
/// gives one line with the last three empty. This is the `sensitivity.csv` a study writes
/// beside its `claims.json`.
pub fn csv(rows: &[Alternative]) -> String {
    let q = |s: &str| format!("\"{}\"", s.replace('"', "\"\""));
    let mut out = String::from("setting,ours,value,claim,verdict,measured\n");
    for row in rows {
        let head = format!("{},{},{}", q(&row.setting), q(&row.ours), q(&row.value));
        if row.readings.is_empty() {
            out.push_str(&format!("{head},,,\n"));
        }
        for r in &row.readings {
            out.push_str(&format!(
                "{head},{},{},{}\n",
                q(&r.claim),
                r.verdict.word(),
                q(&r.measured)
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tally_counts_passes_per_claim_without_the_studys_own_row() {
        let rows = vec![
            Alternative::new(
                "P_0",
                "not given",
                "I",
                "I",
                vec![Reading::of("6.4", true, "9 s")],
            ),
            Alternative::new(
                "P_0",
                "not given",
                "I",
                "10 I",
                vec![
                    Reading::of("6.4", false, "15 s"),
                    Reading::of("6.11", true, "8 s"),
                ],
            ),
            Alternative::new(
                "seed",
                "not given",
                "1",
                "2",
                vec![Reading::of("6.4", true, "7 s")],
            ),
        ];
        assert!(rows[0].is_ours() && !rows[1].is_ours());
        assert_eq!(
            (rows[0].shown_value(), rows[1].shown_value()),
            ("(ours)", "10 I")
        );
        assert_eq!(tally_text(&rows), "6.4 1/2, 6.11 1/1");
        let text = csv(&rows);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 1 + 4);
        assert_eq!(lines[0], "setting,ours,value,claim,verdict,measured");
        assert_eq!(lines[2], "\"P_0\",\"I\",\"10 I\",\"6.4\",FAIL,\"15 s\"");
        let st = |id| super::super::Statement {
            chapter: 6,
            id,
            source: "",
            claim: "",
            criterion: "",
        };
        let mut claims = vec![st("6.4").check(false, "27 s"), st("6.5").check(true, "x")];
        annotate(&mut claims, &rows);
        assert_eq!(
            claims[0].ours,
            "27 s; sensitivity table: holds under 1 of 2 alternatives"
        );
        assert_eq!(claims[1].ours, "x");
        let quoted = csv(&[Alternative::new("a \"b\"", "", "1", "2", vec![])]);
        assert!(
            quoted.ends_with("\"a \"\"b\"\"\",\"1\",\"2\",,,\n"),
            "{quoted}"
        );
        assert_eq!(
            tally(&rows),
            vec![("6.4".to_string(), 1, 2), ("6.11".to_string(), 1, 1)]
        );
    }
}
