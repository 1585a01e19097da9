//! `study all --quick`: every study of the table runs into its folder, writes its claims,
//! and the reproduction report has a section per study with every claim and its verdict;
//! a study that cannot run is reported as such, and a claims file left by an earlier run
//! does not stand in for it.

use std::path::{Path, PathBuf};
use std::process::Command;

use rig_tools::study::all::{self, Options, STUDIES, Size, StudyEntry};
use rig_tools::study::reproduction::report::{self, Links};
use rig_tools::study::reproduction::{self, Verdict};

fn out_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("study-all-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn exe() -> &'static Path {
    Path::new(env!("CARGO_BIN_EXE_study"))
}

#[test]
fn study_all_quick_reports_every_studys_claims_with_verdicts() {
    let out = out_dir("quick");
    let committed = out.join("committed").join("reproduction.md");
    std::fs::create_dir_all(committed.parent().unwrap()).unwrap();
    let output = Command::new(exe())
        .args(["all", "--quick", "--out"])
        .arg(&out)
        .arg("--results")
        .arg(&committed)
        .output()
        .expect("study all runs");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let report = std::fs::read_to_string(out.join(all::REPORT_FILE)).expect("the report");
    assert!(report.contains("**Quick run**"), "{report}");
    let copy = std::fs::read_to_string(&committed).expect("the --results copy");
    let mut totals = [0usize; 3];
    for s in STUDIES {
        let dir = out.join(s.name);
        let claims = reproduction::read(&dir).unwrap_or_else(|e| panic!("{}: {e}", s.name));
        assert_eq!(claims.study, s.name);
        assert_eq!(claims.chapter, s.chapter, "{}", s.name);
        assert!(!claims.claims.is_empty(), "{}: no claims", s.name);
        assert!(
            dir.join(s.summary).is_file(),
            "{}: no {}",
            s.name,
            s.summary
        );
        assert!(
            report.contains(&format!("### `{}`", s.name)),
            "{}: no section",
            s.name
        );
        assert!(
            report.contains(&format!("## Chapter {}:", s.chapter)),
            "chapter {}",
            s.chapter
        );
        assert!(
            report.contains(&format!("]({}/{})", s.name, s.summary)),
            "{}: no link to the summary",
            s.name
        );
        for c in &claims.claims {
            assert_eq!(c.chapter, s.chapter, "{} {}", s.name, c.id);
            assert!(!c.claim.is_empty() && !c.criterion.is_empty() && !c.source.is_empty());
            let row = report
                .lines()
                .find(|l| l.starts_with(&format!("| {} | ", c.id)))
                .unwrap_or_else(|| panic!("{}: no row for claim {}", s.name, c.id));
            assert!(
                row.contains(&format!("**{}** |", c.verdict.word()))
                    || row.contains(&format!("**{}**: ", c.verdict.word())),
                "{row}"
            );
            // Every claim shows its figures: the study wrote them, the report links them,
            // and the --results copy has them reduced beside it and links the copies.
            assert!(!c.figures.is_empty(), "{} {}: no figure", s.name, c.id);
            for f in &c.figures {
                assert!(
                    dir.join(f).is_file(),
                    "{} {}: {f} not written",
                    s.name,
                    c.id
                );
                assert!(row.contains(&format!("]({}/{f})", s.name)), "{row}");
                let copied = committed
                    .parent()
                    .unwrap()
                    .join("reproduction")
                    .join(s.name)
                    .join(f);
                assert!(copied.is_file(), "{}", copied.display());
                assert!(
                    copy.contains(&format!("](reproduction/{}/{f})", s.name)),
                    "{} {}: the copy does not link {f}",
                    s.name,
                    c.id
                );
            }
            match c.verdict {
                Verdict::NotChecked => assert!(c.reason.is_some(), "{} {}", s.name, c.id),
                _ => assert!(!c.ours.is_empty(), "{} {}: no number", s.name, c.id),
            }
        }
        // Every study shows the settings its chapter leaves open: alternatives beyond its
        // own choice, each reading a claim of the file (`reproduction::read` refuses a
        // reading of a claim it does not have), and the report's table of them.
        assert!(
            claims.sensitivity.iter().any(|r| !r.is_ours()),
            "{}: no sensitivity alternatives",
            s.name
        );
        assert!(
            claims.sensitivity.iter().all(|r| !r.readings.is_empty()),
            "{}: a sensitivity row reads no claim",
            s.name
        );
        for (t, v) in [Verdict::Pass, Verdict::Fail, Verdict::NotChecked]
            .iter()
            .enumerate()
        {
            totals[t] += claims.count(*v);
        }
    }
    assert_eq!(
        report.matches("**Sensitivity.**").count(),
        STUDIES.len(),
        "one sensitivity table per study"
    );
    // The totals row and the printed count agree with the claims files.
    let totals_row = format!(
        "| {} of {} | {} | {} | {} |",
        STUDIES.len(),
        STUDIES.len(),
        totals[0],
        totals[1],
        totals[2]
    );
    assert!(report.contains(&totals_row), "{totals_row}\n{report}");
    assert!(
        stdout.contains(&format!(
            "claims: {} PASS, {} FAIL, {} NOT CHECKED",
            totals[0], totals[1], totals[2]
        )),
        "{stdout}"
    );
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn a_study_that_cannot_run_is_reported_and_a_stale_claims_file_does_not_stand_in() {
    let out = out_dir("failing");
    let mrac = *STUDIES.iter().find(|s| s.name == "mrac").expect("mrac");
    let missing = StudyEntry {
        name: "no-such-study",
        chapter: 7,
        title: "a study the binary does not have",
        ..mrac
    };
    // A claims file from an earlier run in the missing study's folder.
    let stale = out.join(missing.name);
    std::fs::create_dir_all(&stale).unwrap();
    reproduction::write(
        &stale,
        &reproduction::Claims {
            study: missing.name.into(),
            chapter: 7,
            run: "an earlier run".into(),
            claims: Vec::new(),
            sensitivity: Vec::new(),
        },
    )
    .unwrap();
    let options = Options::new(Size::Quick, Some(2), "test".into()).unwrap();
    let run = all::run(
        exe(),
        &out,
        &[mrac, missing],
        &options,
        &all::Sharding::Whole,
    );
    assert_eq!(run.runs.len(), 2);
    assert!(run.runs[0].claims.is_ok(), "{:?}", run.runs[0].claims);
    let failed = run.failed();
    assert_eq!(failed.len(), 1);
    assert_eq!(failed[0].entry.name, "no-such-study");
    let err = failed[0].claims.as_ref().unwrap_err().to_string();
    assert!(err.contains("exited with"), "{err}");
    assert!(stale.join(all::LOG_FILE).is_file());
    let report = report::render(&run, Links::Relative);
    assert!(report.contains("**Failed to run**"), "{report}");
    assert!(report.contains("| 1 of 2 |"), "{report}");
    // In the copy for docs/results the files are paths under the output folder.
    let copy = report::render(
        &run,
        Links::Committed {
            figures: "reproduction",
        },
    );
    assert!(copy.contains(&format!(
        "`{}`",
        out.join("mrac").join("summary.md").display()
    )));
    let _ = std::fs::remove_dir_all(&out);
}
