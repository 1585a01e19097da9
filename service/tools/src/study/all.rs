//! `study all`: every study of the dissertation in one command, each into its own folder,
//! several at a time, and one reproduction report beside them
//! ([`crate::study::reproduction::report`]).
//!
//! # The table of studies
//!
//! [`STUDIES`] lists what runs: per study its `study` subcommand (also its folder under
//! `--out`), its chapter, the options of the full reproduction and of `--quick`, its
//! summary file, and how its claims are read (each study writes `claims.json`,
//! [`crate::study::reproduction`]). A new study plugs in with one [`StudyEntry`].
//!
//! # How they run
//!
//! Each study is a child process of the same `study` binary,
//! `study <name> --out DIR/<name> <options>`, with its standard output and error in
//! `DIR/<name>/log.txt`. The studies are independent, so up to `jobs` of them run at once
//! (default: the number of cores), the most expensive first ([`StudyEntry::cost`]), and
//! each gets `RAYON_NUM_THREADS = max(1, cores / jobs)` so that the studies that use rayon
//! inside do not oversubscribe the cores. A study fails to run when its process exits
//! non-zero or leaves no readable `claims.json`; a FAIL claim is a result, not a failure.

use crate::file_error::{AtomicFileError, FileError, FileOp};
use std::collections::VecDeque;
use std::ffi::OsString;
use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Mutex;
use std::time::Instant;

use crate::study::reproduction::figures;
use crate::study::reproduction::report::{self, Links};
use crate::study::reproduction::{self, Claims, ClaimsError, Verdict};
use crate::study::shard::{Runs, ShardError};

/// How large the runs are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Size {
    /// Every study at its default options: the reproduction.
    Full,
    /// Reduced sizes for a quick check (tests); its verdicts are not the reproduction's.
    Quick,
}

/// One study of `study all`.
#[derive(Debug, Clone, Copy)]
pub struct StudyEntry {
    /// The `study` subcommand; also the folder under `--out`.
    pub name: &'static str,
    /// The chapter of the dissertation.
    pub chapter: u8,
    /// What it reproduces, with sections and figures.
    pub title: &'static str,
    /// Options of the full reproduction (after `--out`).
    pub full: &'static [&'static str],
    /// Options of `--quick`: the smallest runs whose claims still mean something.
    pub quick: &'static [&'static str],
    /// The summary file it writes into its folder.
    pub summary: &'static str,
    /// Reads its claims from its folder.
    pub claims: fn(&Path) -> Result<Claims, ClaimsError>,
    /// Relative cost of the full run (seconds on one core, roughly): the most expensive
    /// start first.
    pub cost: u32,
}

impl StudyEntry {
    /// The options of `size`.
    pub fn args(&self, size: Size) -> &'static [&'static str] {
        match size {
            Size::Full => self.full,
            Size::Quick => self.quick,
        }
    }
}

/// The studies, in the order of the chapters.
pub const STUDIES: &[StudyEntry] = &[
    StudyEntry {
        name: "rcac-siso",
        chapter: 3,
        title: "RCAC with dereverberated target models on the SISO structure (3.50), §3.3.1, Figures 3.5–3.10",
        full: &[],
        quick: &["--points", "3", "--update", "gradient"],
        summary: "summary.txt",
        claims: reproduction::read,
        cost: 35,
    },
    StudyEntry {
        name: "rcac-miso",
        chapter: 3,
        title: "RCAC on a 4-mode 2-input 1-output structure with an erroneous damping ratio, §3.3.2, Figures 3.11–3.17",
        full: &[],
        quick: &["--points", "3", "--update", "gradient"],
        summary: "summary.txt",
        claims: reproduction::read,
        cost: 23,
    },
    StudyEntry {
        name: "mrac",
        chapter: 4,
        title: "APPC against RC-MRAC over the plant's pole plane, §4.5–4.7, Figures 4.2–4.14",
        full: &[],
        quick: &["--grid", "3"],
        summary: "summary.md",
        claims: reproduction::read,
        cost: 10,
    },
    StudyEntry {
        name: "forgetting",
        chapter: 5,
        title: "RLS with F-test variable-rate forgetting against constant and RMS forgetting, §5.3, Figures 5.1–5.8",
        full: &[],
        quick: &["--runs", "40"],
        summary: "summary.txt",
        claims: reproduction::read,
        cost: 12,
    },
    StudyEntry {
        name: "pcac-truss",
        chapter: 6,
        title: "PCAC on the 4-bay truss under harmonic and broadband disturbances, with aliasing, §6.2, Figures 6.2–6.10",
        full: &[],
        quick: &["--duration", "20", "--settings", "printed"],
        summary: "summary.txt",
        claims: reproduction::read,
        cost: 7,
    },
    StudyEntry {
        name: "sampling-arm",
        chapter: 7,
        title: "Robust against PCAC-augmented force control of the spacecraft sampling arm over linear and Hunt–Crossley surfaces and in double maneuvers, §7.3, Figures 7.3–7.8",
        full: &[],
        quick: &["--quick"],
        summary: "summary.md",
        claims: reproduction::read,
        cost: 120,
    },
];

/// The dissertation's chapters with studies.
pub const CHAPTERS: &[(u8, &str)] = &[
    (
        3,
        "Retrospective Cost Adaptive Control Using Dereverberated Target Models",
    ),
    (4, "Retrospective Cost Model Reference Adaptive Control"),
    (5, "Variable-Rate Forgetting Using the F-Test"),
    (
        6,
        "Predictive Cost Adaptive Control of Flexible Structures with Harmonic and Broadband Disturbances",
    ),
    (
        7,
        "Adaptive Force-Control Augmentation for Small Celestial Body Sampling",
    ),
];

/// The name of the log file of a study in its folder.
pub const LOG_FILE: &str = "log.txt";

/// The name of the report in `--out`.
pub const REPORT_FILE: &str = "reproduction.md";

/// Options of `study all`.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// How large the runs are.
    pub size: Size,
    /// How many studies run at once.
    pub jobs: usize,
    /// `RAYON_NUM_THREADS` of each study.
    pub threads: usize,
    /// The command line, for the report.
    pub command: String,
}

impl Options {
    /// `jobs` studies at once (default: the number of cores), each with
    /// `max(1, cores / jobs)` threads.
    pub fn new(size: Size, jobs: Option<usize>, command: String) -> Result<Self, AllError> {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let jobs = jobs.unwrap_or(cores);
        if jobs == 0 {
            return Err(AllError::NoJobs);
        }
        Ok(Self {
            size,
            jobs,
            threads: (cores / jobs).max(1),
            command,
        })
    }
}

/// Why `study all` failed.
#[derive(Debug, thiserror::Error)]
pub enum AllError {
    /// A file or folder that could not be read, written or made.
    #[error(transparent)]
    File(#[from] FileError),
    /// A file that could not be written atomically.
    #[error(transparent)]
    Written(#[from] AtomicFileError),
    /// `--jobs 0`.
    #[error("--jobs 0: at least one study must run at a time")]
    NoJobs,
    /// Sharding failed, or (not a failure) the shard is done.
    #[error(transparent)]
    Shard(#[from] ShardError),
    /// A figure of the claims could not be copied beside `--results`.
    #[error(transparent)]
    Figure(#[from] figures::FigureError),
    /// The running executable cannot be found (to run the studies with).
    #[error("the study executable: {0}")]
    Executable(#[source] std::io::Error),
    /// Studies failed to run (their names; the report says why).
    #[error(
        "{} failed to run: {}",
        if .0.len() == 1 { "a study" } else { "studies" },
        .0.join(", ")
    )]
    Failed(Vec<&'static str>),
}

message_from!(AllError);

/// Why one study of `study all` failed to run.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// A file or folder that could not be read, written or made.
    #[error(transparent)]
    File(#[from] FileError),
    /// The study exited with a failure.
    #[error("`study {study}` exited with {status}; see {}", log.display())]
    Exited {
        /// The study.
        study: &'static str,
        /// Its exit status.
        status: std::process::ExitStatus,
        /// Its log.
        log: PathBuf,
    },
    /// Its claims file cannot be read.
    #[error(transparent)]
    Claims(#[from] ClaimsError),
    /// Not a failure: the study ran as a shard; its claims are the merge's.
    #[error("ran as a shard: its claims are the merge's")]
    Shard,
}

/// How `study all` runs its studies.
#[derive(Debug)]
pub enum Sharding<'a> {
    /// Each study whole (`--shard none`, whatever the environment says).
    Whole,
    /// Shard I/N of each study, into `--out/<study>/shards/I-of-N/`; `study all`'s own
    /// manifest is `runs`'.
    Shard(&'a Runs),
    /// Each study merged from its shards under `from/<study>/`.
    Merge(PathBuf),
}

impl Sharding<'_> {
    /// The command line of the study `entry` with its options `args`, into `dir`.
    fn command_line(&self, entry: &StudyEntry, dir: &Path, args: &[String]) -> Vec<OsString> {
        let mut line: Vec<OsString> = Vec::new();
        if let Sharding::Merge(from) = self {
            line.extend(["merge".into(), from.join(entry.name).into_os_string()]);
            line.extend(["--out".into(), dir.as_os_str().to_owned()]);
            return line;
        }
        line.extend([
            entry.name.into(),
            "--out".into(),
            dir.as_os_str().to_owned(),
        ]);
        line.extend(args.iter().map(OsString::from));
        let slice = match self {
            Sharding::Shard(runs) => runs.slice().map_or("none".into(), |s| s.to_string()),
            _ => "none".to_string(),
        };
        line.extend(["--shard".into(), slice.into()]);
        line
    }
}

/// How one study went.
#[derive(Debug)]
pub struct StudyRun {
    /// The table's entry.
    pub entry: StudyEntry,
    /// Its folder.
    pub dir: PathBuf,
    /// The options it ran with (after `--out`).
    pub args: Vec<String>,
    /// Wall time, s.
    pub wall: f64,
    /// Its claims, or why it failed to run.
    pub claims: Result<Claims, RunError>,
}

impl StudyRun {
    /// The number of claims with `verdict` (0 when it failed to run).
    pub fn count(&self, verdict: Verdict) -> usize {
        self.claims.as_ref().map_or(0, |c| c.count(verdict))
    }
}

/// What `study all` did.
#[derive(Debug)]
pub struct AllRun {
    /// Where.
    pub out: PathBuf,
    /// With what.
    pub options: Options,
    /// Per study, in the table's order.
    pub runs: Vec<StudyRun>,
    /// Wall time of the whole, s.
    pub wall: f64,
}

impl AllRun {
    /// The studies that failed to run.
    pub fn failed(&self) -> Vec<&StudyRun> {
        self.runs.iter().filter(|r| r.claims.is_err()).collect()
    }

    /// The number of claims with `verdict` over every study.
    pub fn count(&self, verdict: Verdict) -> usize {
        self.runs.iter().map(|r| r.count(verdict)).sum()
    }
}

/// Runs one study: `exe <name> --out <dir> <args>` with its log in `dir`, then reads its
/// claims.
fn run_one(
    exe: &Path,
    entry: &StudyEntry,
    dir: &Path,
    args: &[String],
    (threads, sharding): (usize, &Sharding),
) -> StudyRun {
    let t0 = Instant::now();
    let claims = (|| {
        std::fs::create_dir_all(dir).map_err(|e| FileError::new(FileOp::Access, dir, e))?;
        // A claims file of an earlier run must not stand in for this one's.
        let old = dir.join(reproduction::CLAIMS_FILE);
        if old.exists() {
            std::fs::remove_file(&old).map_err(|e| FileError::new(FileOp::Access, &old, e))?;
        }
        let log_path = dir.join(LOG_FILE);
        let log =
            File::create(&log_path).map_err(|e| FileError::new(FileOp::Access, &log_path, e))?;
        let err = log
            .try_clone()
            .map_err(|e| FileError::new(FileOp::Access, &log_path, e))?;
        let status = Command::new(exe)
            .args(sharding.command_line(entry, dir, args))
            .env("RAYON_NUM_THREADS", threads.to_string())
            .stdin(Stdio::null())
            .stdout(log)
            .stderr(err)
            .status()
            .map_err(|e| FileError::new(FileOp::Access, exe, e))?;
        if !status.success() {
            return Err(RunError::Exited {
                study: entry.name,
                status,
                log: log_path,
            });
        }
        if let Sharding::Shard(_) = sharding {
            return Err(RunError::Shard);
        }
        Ok((entry.claims)(dir)?)
    })();
    StudyRun {
        entry: *entry,
        dir: dir.to_path_buf(),
        args: args.to_vec(),
        wall: t0.elapsed().as_secs_f64(),
        claims,
    }
}

/// Runs `studies` with the `study` binary `exe`, each into `out/<name>`, up to
/// `options.jobs` at a time, the most expensive first, whole, as shards or merged as
/// `sharding` says; prints a line as each starts and ends. The studies' failures are in
/// the result, not an error.
pub fn run(
    exe: &Path,
    out: &Path,
    studies: &[StudyEntry],
    options: &Options,
    sharding: &Sharding,
) -> AllRun {
    let t0 = Instant::now();
    let mut order: Vec<usize> = (0..studies.len()).collect();
    order.sort_by_key(|&i| std::cmp::Reverse(studies[i].cost));
    let queue = Mutex::new(order.into_iter().collect::<VecDeque<usize>>());
    let done: Mutex<Vec<(usize, StudyRun)>> = Mutex::new(Vec::new());
    let next = || queue.lock().ok().and_then(|mut q| q.pop_front());
    std::thread::scope(|s| {
        for _ in 0..options.jobs.min(studies.len()) {
            s.spawn(|| {
                while let Some(i) = next() {
                    let entry = &studies[i];
                    let args: Vec<String> = entry
                        .args(options.size)
                        .iter()
                        .map(|a| a.to_string())
                        .collect();
                    println!("study all: {} started", entry.name);
                    let r = run_one(
                        exe,
                        entry,
                        &out.join(entry.name),
                        &args,
                        (options.threads, sharding),
                    );
                    println!("study all: {} {}", entry.name, outcome_line(&r));
                    if let Ok(mut d) = done.lock() {
                        d.push((i, r));
                    }
                }
            });
        }
    });
    let mut runs = done.into_inner().unwrap_or_default();
    runs.sort_by_key(|(i, _)| *i);
    AllRun {
        out: out.to_path_buf(),
        options: options.clone(),
        runs: runs.into_iter().map(|(_, r)| r).collect(),
        wall: t0.elapsed().as_secs_f64(),
    }
}

/// How a study went, in one line.
fn outcome_line(r: &StudyRun) -> String {
    match &r.claims {
        Ok(c) => format!(
            "done in {:.1} s: {} PASS, {} FAIL, {} NOT CHECKED",
            r.wall,
            c.count(Verdict::Pass),
            c.count(Verdict::Fail),
            c.count(Verdict::NotChecked)
        ),
        Err(RunError::Shard) => format!("shard done in {:.1} s", r.wall),
        Err(e) => format!("FAILED TO RUN after {:.1} s: {e}", r.wall),
    }
}

/// `study all`: runs [`STUDIES`] with this executable into `out` (as `sharding` says),
/// writes `out/reproduction.md` (and `results`, if given), prints the totals; an error
/// when a study failed to run. As a shard it writes no report: each study's shard is in
/// `out/<study>/shards/`, and the shard ends with [`ShardError::ShardDone`].
pub fn command(
    out: &Path,
    size: Size,
    jobs: Option<usize>,
    results: Option<&Path>,
    command: String,
    sharding: &Sharding,
) -> Result<(), AllError> {
    let options = Options::new(size, jobs, command)?;
    let exe = std::env::current_exe().map_err(AllError::Executable)?;
    std::fs::create_dir_all(out)
        .map_err(|source| FileError::new(FileOp::Out, out.to_path_buf(), source))?;
    println!(
        "study all: {} studies into {}, {} at a time, {} thread(s) each{}",
        STUDIES.len(),
        out.display(),
        options.jobs,
        options.threads,
        if size == Size::Quick {
            " (--quick: reduced sizes)"
        } else {
            ""
        }
    );
    let all = run(&exe, out, STUDIES, &options, sharding);
    if let Sharding::Shard(runs) = sharding {
        let failed: Vec<&'static str> = all
            .runs
            .iter()
            .filter(|r| !matches!(r.claims, Err(RunError::Shard)))
            .map(|r| r.entry.name)
            .collect();
        if !failed.is_empty() {
            return Err(AllError::Failed(failed));
        }
        let slice = runs.slice().map_or(String::new(), |s| s.to_string());
        let ended = runs.gather();
        runs.describe_done(format!(
            "study all: shard {slice} of every study recorded under {}/<study>/shards/ in {:.1} s; when every shard is done: study merge {}",
            out.display(),
            all.wall,
            out.display()
        ));
        return ended.map_err(AllError::from);
    }
    let report = out.join(REPORT_FILE);
    ipc_types::files::write_atomic(&report, report::render(&all, Links::Relative).as_bytes())
        .map_err(|source| FileError::new(FileOp::Access, report.clone(), source))?;
    if let Some(path) = results {
        let (dir, name) = figures::folder_of(path);
        let copied = figures::copy_claim_figures(&all, &dir)?;
        for m in &copied.missing {
            eprintln!(
                "study all: WARNING: a claim names the figure {m}, which its study did not write"
            );
        }
        println!(
            "study all: {} figures of the claims, {:.1} MB, copied (reduced) into {}",
            copied.written,
            copied.bytes as f64 / 1e6,
            dir.display()
        );
        let links = Links::Committed { figures: &name };
        ipc_types::files::write_atomic(path, report::render(&all, links).as_bytes())
            .map_err(|source| FileError::new(FileOp::Results, path.to_path_buf(), source))?;
    }
    println!(
        "study all: {} of {} studies ran in {:.1} s; claims: {} PASS, {} FAIL, {} NOT CHECKED; report {}{}",
        all.runs.len() - all.failed().len(),
        all.runs.len(),
        all.wall,
        all.count(Verdict::Pass),
        all.count(Verdict::Fail),
        all.count(Verdict::NotChecked),
        report.display(),
        results.map_or(String::new(), |p| format!(", results {}", p.display()))
    );
    let failed = all.failed();
    if failed.is_empty() {
        Ok(())
    } else {
        Err(AllError::Failed(
            failed.iter().map(|r| r.entry.name).collect::<Vec<_>>(),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_names_each_study_once_with_a_chapter_and_quick_options() {
        let mut names: Vec<&str> = STUDIES.iter().map(|s| s.name).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), STUDIES.len());
        for s in STUDIES {
            assert!(
                CHAPTERS.iter().any(|(c, _)| *c == s.chapter),
                "{}: chapter {} has no title",
                s.name,
                s.chapter
            );
            assert!(!s.quick.is_empty(), "{}: no --quick options", s.name);
            assert!(
                !s.full.iter().chain(s.quick).any(|a| *a == "--out"),
                "{}: --out is set by study all",
                s.name
            );
        }
    }

    #[test]
    fn jobs_and_threads_share_the_cores() {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let o = Options::new(Size::Quick, None, String::new()).unwrap();
        assert_eq!((o.jobs, o.threads), (cores, 1));
        let o = Options::new(Size::Full, Some(1), String::new()).unwrap();
        assert_eq!((o.jobs, o.threads), (1, cores));
        assert!(Options::new(Size::Full, Some(0), String::new()).is_err());
    }
}
