//! The claims record of the reproduction: each study checks the results its chapter of the
//! dissertation states against its own numbers and writes them, machine-readable, into
//! `claims.json` beside its figures; `study all` ([`crate::study::all`]) reads those files
//! and puts every claim into one report ([`crate::study::reproduction::report`]).
//!
//! A claim ([`Claim`]) is
//!
//! - **what the dissertation states** ([`Claim::claim`]), quoted or closely paraphrased,
//!   with where it says it ([`Claim::source`]: section, figure, equation);
//! - **what we measured** ([`Claim::ours`]): the study's numbers behind the verdict;
//! - **the criterion** ([`Claim::criterion`]): the test on those numbers that decides,
//!   written so that it can fail;
//! - **the verdict** ([`Verdict`]): PASS, FAIL, or NOT CHECKED with a reason
//!   ([`Claim::reason`]) when the runs it needs were not made or the study does not
//!   measure what the statement is about.
//!
//! The file ([`Claims`], [`CLAIMS_FILE`]) is JSON:
//!
//! ```json
//! {
//!   "study": "mrac",
//!   "chapter": 4,
//!   "run": "study mrac --example all --command all --grid 15",
//!   "claims": [
//!     {
//!       "chapter": 4,
//!       "id": "4.2",
//!       "source": "§4.8",
//!       "claim": "For minimum-phase systems, RC-MRAC outperforms APPC without the need for persistency.",
//!       "ours": "median log10‖e‖, step: RC-MRAC -6.23 vs APPC -2.12, …",
//!       "criterion": "Example 1: RC-MRAC's median log10‖e‖ over the grid below APPC's for every command",
//!       "verdict": "PASS",
//!       "figures": ["map-ex1-step-appc.png", "map-ex1-step-rc-mrac.png"]
//!     }
//!   ]
//! }
//! ```
//!
//! `figures` ([`Claim::figures`]) names the study's figures that show what the claim is
//! about; the report links them, and [`figures`] copies them beside a committed report.

pub mod figures;
pub mod report;
pub mod sensitivity;

use crate::file_error::{AtomicFileError, FileError, FileOp};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// The name of a study's claims file in its output folder.
pub const CLAIMS_FILE: &str = "claims.json";

/// Whether a claim holds on our numbers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Verdict {
    /// The criterion holds.
    #[serde(rename = "PASS")]
    Pass,
    /// The criterion does not hold.
    #[serde(rename = "FAIL")]
    Fail,
    /// The criterion was not evaluated ([`Claim::reason`] says why).
    #[serde(rename = "NOT CHECKED")]
    NotChecked,
}

impl Verdict {
    /// `PASS`, `FAIL` or `NOT CHECKED`.
    pub fn word(self) -> &'static str {
        match self {
            Verdict::Pass => "PASS",
            Verdict::Fail => "FAIL",
            Verdict::NotChecked => "NOT CHECKED",
        }
    }

    /// PASS when `ok`, else FAIL.
    pub fn of(ok: bool) -> Self {
        if ok { Verdict::Pass } else { Verdict::Fail }
    }
}

/// One result the dissertation states, beside ours.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Claim {
    /// The chapter of the dissertation.
    pub chapter: u8,
    /// A short identifier, unique within the study (e.g. `5.3`).
    pub id: String,
    /// Where the dissertation states it: section, figure, equation.
    pub source: String,
    /// What the dissertation states.
    pub claim: String,
    /// What we measured (empty when not checked).
    pub ours: String,
    /// The test on our numbers that decides the verdict.
    pub criterion: String,
    /// The verdict.
    pub verdict: Verdict,
    /// Why the claim was not checked (only with [`Verdict::NotChecked`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// The study's figures (file names in its output folder) that show what the claim is
    /// about, as the dissertation's figure does ([`with_figures`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub figures: Vec<String>,
}

/// A study's figures per claim: `(claim id, file names in the study's output folder)`.
pub type Figures = &'static [(&'static str, &'static [&'static str])];

/// `claims` with the figures `table` names for each (a claim the table does not name keeps
/// none).
pub fn with_figures(mut claims: Vec<Claim>, table: Figures) -> Vec<Claim> {
    for c in &mut claims {
        if let Some((_, files)) = table.iter().find(|(id, _)| *id == c.id) {
            c.figures = files.iter().map(|f| f.to_string()).collect();
        }
    }
    claims
}

/// The fixed text of a claim: everything but our numbers and the verdict.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Statement {
    /// The chapter.
    pub chapter: u8,
    /// The identifier ([`Claim::id`]).
    pub id: &'static str,
    /// Where the dissertation states it ([`Claim::source`]).
    pub source: &'static str,
    /// What it states ([`Claim::claim`]).
    pub claim: &'static str,
    /// The criterion ([`Claim::criterion`]).
    pub criterion: &'static str,
}

impl Statement {
    /// The claim checked: PASS when `ok`, with our numbers `ours`.
    pub fn check(&self, ok: bool, ours: impl Into<String>) -> Claim {
        self.claim_with(Verdict::of(ok), ours.into(), None)
    }

    /// The claim not checked, for `reason`.
    pub fn not_checked(&self, reason: impl Into<String>) -> Claim {
        self.claim_with(Verdict::NotChecked, String::new(), Some(reason.into()))
    }

    /// The claim not checked for `reason`, with the numbers the study has on the subject.
    pub fn not_checked_with(&self, reason: impl Into<String>, ours: impl Into<String>) -> Claim {
        self.claim_with(Verdict::NotChecked, ours.into(), Some(reason.into()))
    }

    fn claim_with(&self, verdict: Verdict, ours: String, reason: Option<String>) -> Claim {
        Claim {
            chapter: self.chapter,
            id: self.id.into(),
            source: self.source.into(),
            claim: self.claim.into(),
            ours,
            criterion: self.criterion.into(),
            verdict,
            reason,
            figures: Vec::new(),
        }
    }
}

/// A study's claims file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Claims {
    /// The study (its `study` subcommand).
    pub study: String,
    /// The chapter it reproduces.
    pub chapter: u8,
    /// What was run: the command and options the numbers come from.
    pub run: String,
    /// The claims, in the chapter's order.
    pub claims: Vec<Claim>,
    /// The settings the chapter leaves open, moved to alternatives, with the claims'
    /// verdicts under each ([`sensitivity`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sensitivity: Vec<sensitivity::Alternative>,
}

impl Claims {
    /// How many claims have `verdict`.
    pub fn count(&self, verdict: Verdict) -> usize {
        self.claims.iter().filter(|c| c.verdict == verdict).count()
    }
}

/// A claims file that cannot be written or read, naming the file.
#[derive(Debug, thiserror::Error)]
pub enum ClaimsError {
    /// A file or folder that could not be read, written or made.
    #[error(transparent)]
    File(#[from] FileError),
    /// A file that could not be written atomically.
    #[error(transparent)]
    Written(#[from] AtomicFileError),
    /// The claims are not the record's JSON (the line and the field in the message), or
    /// cannot be written as JSON.
    #[error("{}: {source}", path.display())]
    Json {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: serde_json::Error,
    },
    /// A claim with a reason and a verdict other than NOT CHECKED, or the other way round.
    #[error(
        "{}: claim {id}: a reason is given exactly when the verdict is NOT CHECKED",
        path.display()
    )]
    Reason {
        /// The file.
        path: PathBuf,
        /// The claim's id.
        id: String,
    },
    /// A sensitivity row that reads a claim the file does not have.
    #[error(
        "{}: sensitivity row \"{setting} = {value}\" reads claim {id}, which the file does not have",
        path.display()
    )]
    UnknownClaim {
        /// The file.
        path: PathBuf,
        /// The row's setting.
        setting: String,
        /// The row's value.
        value: String,
        /// The claim id it names.
        id: String,
    },
}

message_from!(ClaimsError);

/// Writes `claims` into `dir/claims.json`.
pub fn write(dir: &Path, claims: &Claims) -> Result<(), ClaimsError> {
    let path = dir.join(CLAIMS_FILE);
    let text = match serde_json::to_string_pretty(claims) {
        Ok(text) => text,
        Err(source) => return Err(ClaimsError::Json { path, source }),
    };
    ipc_types::files::write_atomic(&path, format!("{text}\n").as_bytes())
        .map_err(|source| FileError::new(FileOp::Access, path, source).into())
}

/// Reads `dir/claims.json`; the error names the file and, for bad content, the line and
/// the field.
pub fn read(dir: &Path) -> Result<Claims, ClaimsError> {
    let path = dir.join(CLAIMS_FILE);
    let text = match std::fs::read_to_string(&path) {
        Ok(text) => text,
        Err(source) => return Err(FileError::new(FileOp::Access, path, source).into()),
    };
    let claims: Claims = match serde_json::from_str(&text) {
        Ok(claims) => claims,
        Err(source) => return Err(ClaimsError::Json { path, source }),
    };
    if let Some(c) = claims
        .claims
        .iter()
        .find(|c| (c.verdict == Verdict::NotChecked) != c.reason.is_some())
    {
        return Err(ClaimsError::Reason {
            path,
            id: c.id.clone(),
        });
    }
    for row in &claims.sensitivity {
        if let Some(r) = row
            .readings
            .iter()
            .find(|r| !claims.claims.iter().any(|c| c.id == r.claim))
        {
            return Err(ClaimsError::UnknownClaim {
                path,
                setting: row.setting.clone(),
                value: row.value.clone(),
                id: r.claim.clone(),
            });
        }
    }
    Ok(claims)
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: Statement = Statement {
        chapter: 5,
        id: "5.1",
        source: "§5.3.1, Figure 5.2",
        claim: "all simulations converge in less than 20 steps",
        criterion: "the slowest run settles within 20 steps",
    };

    fn dir(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("claims-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn claims_round_trip_through_the_file_with_the_verdict_words() {
        let d = dir("round-trip");
        let c = Claims {
            study: "forgetting".into(),
            chapter: 5,
            run: "study forgetting --runs 10".into(),
            claims: vec![
                S.check(true, "slowest 12 steps"),
                S.check(false, "slowest 34 steps"),
                S.not_checked("not run"),
            ],
            sensitivity: vec![sensitivity::Alternative::new(
                "F-test window",
                "not given",
                "10",
                "20",
                vec![sensitivity::Reading::of("5.1", false, "slowest 25 steps")],
            )],
        };
        write(&d, &c).unwrap();
        let text = std::fs::read_to_string(d.join(CLAIMS_FILE)).unwrap();
        for w in [
            "\"PASS\"",
            "\"FAIL\"",
            "\"NOT CHECKED\"",
            "\"reason\": \"not run\"",
        ] {
            assert!(text.contains(w), "{w} in {text}");
        }
        assert_eq!(read(&d).unwrap(), c);
        assert_eq!(
            (
                c.count(Verdict::Pass),
                c.count(Verdict::Fail),
                c.count(Verdict::NotChecked)
            ),
            (1, 1, 1)
        );
    }

    #[test]
    fn a_bad_claims_file_is_an_error_naming_the_file_and_the_field() {
        let d = dir("bad");
        // A claims file of one claim `id` with the verdict `verdict` and nothing else.
        let one_claim = |id: &str, verdict: &str| {
            let claim = format!(
                r#"{{"chapter": 5, "id": "{id}", "source": "", "claim": "", "ours": "", "criterion": "", "verdict": "{verdict}"}}"#
            );
            let text = format!(r#"{{"study": "x", "chapter": 5, "run": "", "claims": [{claim}]}}"#);
            std::fs::write(d.join(CLAIMS_FILE), text).unwrap();
        };
        one_claim("1", "MAYBE");
        let e = read(&d).unwrap_err().to_string();
        assert!(e.contains(CLAIMS_FILE) && e.contains("MAYBE"), "{e}");
        one_claim("7", "NOT CHECKED");
        let e = read(&d).unwrap_err().to_string();
        assert!(e.contains("claim 7") && e.contains("reason"), "{e}");
        let row = r#"{"setting": "window", "why_open": "", "ours": "1", "value": "2", "readings": [{"claim": "9.9", "verdict": "PASS", "measured": ""}]}"#;
        let claim = r#"{"chapter": 5, "id": "1", "source": "", "claim": "", "ours": "", "criterion": "", "verdict": "PASS"}"#;
        std::fs::write(
            d.join(CLAIMS_FILE),
            format!(r#"{{"study": "x", "chapter": 5, "run": "", "claims": [{claim}], "sensitivity": [{row}]}}"#),
        )
        .unwrap();
        let e = read(&d).unwrap_err().to_string();
        assert!(e.contains("window = 2") && e.contains("claim 9.9"), "{e}");
        let e = read(&d.join("missing")).unwrap_err().to_string();
        assert!(e.contains("missing"), "{e}");
    }
}
