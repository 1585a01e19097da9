//! The gap campaign: what lost samples cost RCAC's suppression under each gap rule,
//! measured deterministically in lockstep.
//!
//! A scenario runs as the main job does (the two real processes over shared memory), in
//! lockstep, for [`DURATION_S`] s, once per controller variant, gap rule, lost share and
//! burst length. The plant injects lost samples (`[proxy.faults] lost`): samples it
//! simulates and whose inputs it decides by its late policy, but never publishes, so the
//! service sees a gap in the sequence. The lost samples come in bursts of `b` ∈ [`BURSTS`]
//! samples at seeded random positions after the open loop (`service.open-loop`), so many
//! bursts that they make up the share `s` ∈ [`SHARES`] of the closed-loop samples:
//!
//! ```text
//! bursts = round(s · (N − N_open) / b)
//! ```
//!
//! with `N` the samples of the run and `N_open` those of the open loop. The bursts sit in
//! distinct slots of `b + 1` samples (so two bursts never merge into one gap), chosen by
//! ChaCha8 seeded with [`SEED`], the share's index and the burst length: every rule and
//! every controller sees the same losses. What a run gives, from its `report.json`: the
//! smallest suppression of the seven tones (`tones.tones[].suppression_db`, the end of the
//! open loop against the end of the run), the share of closed-loop steps on which the
//! update ran (`adaptation`), the measured lost share (`stats.lost_past_startup`) and the
//! verdict. The loss-free run (0 %) never meets a gap, so it is the same for every rule:
//! it runs once per controller.
//!
//! A gap rule is given as `gap-rule[:pause]` (`suspend`, `resume-hold:50`,
//! `resume-plan:0`, …): the `[controller]` keys `gap-rule` and `gap-pause`.
//!
//! The edited scenario and controller files are written into a temporary folder, with
//! their relative file names resolved first, never next to the originals.

use crate::file_error::{FileError, FileOp};
use crate::launch::LaunchError;
use crate::launch::{LaunchOptions, launch};
use crate::scenario_toml::{self, ScenarioTomlError};
use rand::SeedableRng;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Why the gap campaign failed, naming the rule, the run (its slug and folder) or the file
/// at fault.
#[derive(Debug, thiserror::Error)]
pub enum GapsError {
    /// A file or folder that could not be read, written or made.
    #[error(transparent)]
    File(#[from] FileError),
    /// A rule's pause that is not a number.
    #[error("'{rule}': the pause '{pause}' is not a number")]
    Pause {
        /// The rule as given.
        rule: String,
        /// The pause.
        pause: String,
    },
    /// The scenario or a controller file cannot be read or lacks the sample period.
    #[error(transparent)]
    ScenarioFile(#[from] ScenarioTomlError),
    /// A run's scenario cannot be written as TOML.
    #[error("writing the scenario: {0}")]
    Scenario(#[source] toml::ser::Error),
    /// A run's controller file cannot be written as TOML.
    #[error("writing the controller: {0}")]
    Controller(#[source] toml::ser::Error),
    /// A run failed and left no report.
    #[error("{run} ({}): {source}", folder.display())]
    Launch {
        /// The run.
        run: String,
        /// Its folder.
        folder: PathBuf,
        /// Why.
        #[source]
        source: LaunchError,
    },
    /// A run left no readable report.
    #[error("{run} ({}): report.json: {source}", folder.display())]
    NoReport {
        /// The run.
        run: String,
        /// Its folder.
        folder: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A run's report is not JSON.
    #[error("{run}: report.json: {source}")]
    Report {
        /// The run.
        run: String,
        /// Why.
        #[source]
        source: serde_json::Error,
    },
    /// A run's report has no tones.
    #[error("{run}: report.json has no tones")]
    NoTones {
        /// The run.
        run: String,
    },
    /// A run's thread panicked.
    #[error("a run panicked")]
    Panicked,
}

message_from!(GapsError);

/// Lost shares of the closed-loop samples.
pub const SHARES: [f64; 6] = [0.0, 0.001, 0.003, 0.01, 0.03, 0.10];
/// Burst lengths in samples.
pub const BURSTS: [u64; 3] = [1, 4, 16];
/// Length of every run, s.
pub const DURATION_S: f64 = 10.0;
/// The seed of the loss positions.
pub const SEED: u64 = 0x6a9_2024;

/// A gap rule of the campaign: `gap-rule` and the optional `gap-pause`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Rule {
    /// `controller.gap-rule`.
    pub rule: String,
    /// `controller.gap-pause` (`None`: the rule's default).
    pub pause: Option<u64>,
}

impl Rule {
    /// Parses `gap-rule[:pause]`.
    ///
    /// # Errors
    ///
    /// A pause that is not a number.
    pub fn parse(s: &str) -> Result<Self, GapsError> {
        match s.split_once(':') {
            None => Ok(Self {
                rule: s.to_string(),
                pause: None,
            }),
            Some((r, p)) => Ok(Self {
                rule: r.to_string(),
                pause: Some(p.parse().map_err(|_| GapsError::Pause {
                    rule: s.into(),
                    pause: p.into(),
                })?),
            }),
        }
    }

    /// `resume-plan:50`, or the rule alone.
    pub fn name(&self) -> String {
        match self.pause {
            Some(p) => format!("{}:{p}", self.rule),
            None => self.rule.clone(),
        }
    }
}

/// A controller of the campaign: the scenario's own, or a controller file's.
#[derive(Debug, Clone, Serialize)]
pub struct Variant {
    /// A short name ("gradient", "rls").
    pub name: String,
    /// The file whose `[controller]` replaces the scenario's (`rig launch --controller`).
    pub controller: Option<PathBuf>,
}

/// One run of the campaign.
#[derive(Debug, Clone, Serialize)]
pub struct Cell {
    /// The controller variant's name.
    pub variant: String,
    /// The gap rule (`None`: the loss-free run, the same for every rule).
    pub rule: Option<String>,
    /// The lost share asked for.
    pub share: f64,
    /// The burst length.
    pub burst: u64,
    /// Bursts injected.
    pub bursts: usize,
    /// Lost share measured by the service (lost / samples past start-up).
    pub lost_share: f64,
    /// The smallest suppression of the tones, dB.
    pub min_suppression_db: f64,
    /// Closed-loop steps updated.
    pub updated: u64,
    /// Closed-loop steps suspended (every cause).
    pub suspended: u64,
    /// The verdict.
    pub verdict_ok: bool,
    /// The run folder.
    pub folder: PathBuf,
}

impl Cell {
    /// Share of the closed-loop steps on which the update ran.
    pub fn updated_share(&self) -> f64 {
        let all = self.updated + self.suspended;
        if all == 0 {
            0.0
        } else {
            self.updated as f64 / all as f64
        }
    }
}

/// The whole campaign.
#[derive(Debug, Clone, Serialize)]
pub struct GapCampaign {
    /// The scenario.
    pub scenario: PathBuf,
    /// The controllers.
    pub variants: Vec<Variant>,
    /// The gap rules.
    pub rules: Vec<Rule>,
    /// Every run.
    pub cells: Vec<Cell>,
}

/// The first sample of each burst of `burst` samples making up `share` of the samples
/// `[start, end)` (module docs), sorted; `seed_index` tells the shares apart.
pub fn positions(start: u64, end: u64, share: f64, burst: u64, seed_index: u64) -> Vec<u64> {
    if share <= 0.0 || burst == 0 || end <= start {
        return Vec::new();
    }
    let span = end - start;
    let count = (share * span as f64 / burst as f64).round().max(1.0) as usize;
    // Slots of burst + 1 samples, the last one ending before `end`, so that a received
    // sample follows every burst.
    let slots = ((span - 1) / (burst + 1)) as usize;
    let count = count.min(slots);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(SEED ^ (seed_index << 32) ^ burst);
    let mut picked: Vec<u64> = rand::seq::index::sample(&mut rng, slots, count)
        .into_iter()
        .map(|s| start + s as u64 * (burst + 1))
        .collect();
    picked.sort_unstable();
    picked
}

/// One run to do.
struct Job {
    variant: usize,
    rule: Option<usize>,
    share_index: usize,
    burst: u64,
}

/// Runs the campaign on `scenario` for `variants` and `rules`, every run in a folder under
/// `runs`, `jobs` runs at a time.
///
/// # Errors
///
/// A scenario or controller file that cannot be read, a run that left no report (naming
/// its folder).
pub fn run(
    scenario: &Path,
    variants: &[Variant],
    rules: &[Rule],
    runs: &Path,
    jobs: usize,
) -> Result<GapCampaign, GapsError> {
    let base = scenario_toml::read(scenario)?;
    let dir = scenario.parent().unwrap_or(Path::new("."));
    let period = scenario_toml::sample_period(&base, scenario)?;
    let open_loop = base
        .get("service")
        .and_then(|s| s.get("open-loop"))
        .and_then(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)))
        .unwrap_or(0.0);
    let (start, end) = (
        (open_loop / period).round() as u64,
        (DURATION_S / period).round() as u64,
    );
    let controllers: Vec<Option<(toml::Table, PathBuf)>> = variants
        .iter()
        .map(|v| {
            v.controller
                .as_ref()
                .map(|f| {
                    scenario_toml::read(f).map(|t| (t, f.parent().unwrap_or(Path::new(".")).into()))
                })
                .transpose()
        })
        .collect::<Result<_, _>>()?;
    let mut todo = Vec::new();
    for variant in 0..variants.len() {
        todo.push(Job {
            variant,
            rule: None,
            share_index: 0,
            burst: 0,
        });
        for rule in 0..rules.len() {
            for &burst in &BURSTS {
                for share_index in 1..SHARES.len() {
                    todo.push(Job {
                        variant,
                        rule: Some(rule),
                        share_index,
                        burst,
                    });
                }
            }
        }
    }
    let tmp = std::env::temp_dir().join(format!("rig-gaps-{}", std::process::id()));
    std::fs::create_dir_all(&tmp)
        .map_err(|source| FileError::new(FileOp::Access, tmp.clone(), source))?;
    let next = AtomicUsize::new(0);
    let done: Mutex<Vec<(usize, Result<Cell, GapsError>)>> = Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..jobs.max(1) {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(job) = todo.get(i) else { break };
                    let lost = positions(
                        start + 1,
                        end,
                        SHARES[job.share_index],
                        job.burst,
                        job.share_index as u64,
                    );
                    let cell = one_run(RunSpec {
                        base: &base,
                        dir,
                        controller: controllers[job.variant].as_ref(),
                        variant: &variants[job.variant],
                        rule: job.rule.map(|r| &rules[r]),
                        share: SHARES[job.share_index],
                        burst: job.burst,
                        lost: &lost,
                        runs,
                        tmp: &tmp,
                        index: i,
                    });
                    if let Ok(c) = &cell {
                        eprintln!(
                            "[gaps] {} {} {:.1} % b={}: {:.1} dB, updated {:.1} %",
                            c.variant,
                            c.rule.as_deref().unwrap_or("-"),
                            100.0 * c.share,
                            c.burst,
                            c.min_suppression_db,
                            100.0 * c.updated_share()
                        );
                    }
                    if let Ok(mut d) = done.lock() {
                        d.push((i, cell));
                    }
                }
            });
        }
    });
    let _ = std::fs::remove_dir_all(&tmp);
    let mut done = done.into_inner().map_err(|_| GapsError::Panicked)?;
    done.sort_by_key(|(i, _)| *i);
    let cells = done
        .into_iter()
        .map(|(_, c)| c)
        .collect::<Result<Vec<_>, _>>()?;
    Ok(GapCampaign {
        scenario: scenario.to_path_buf(),
        variants: variants.to_vec(),
        rules: rules.to_vec(),
        cells,
    })
}

/// The sub-table `name` of `t` (empty when absent).
fn table(t: &toml::Table, name: &str) -> toml::Table {
    t.get(name)
        .and_then(|v| v.as_table())
        .cloned()
        .unwrap_or_default()
}

/// Makes the relative file names of a controller table (`*-file` keys, `robust-gain`)
/// absolute from `dir`, so that the table can be written anywhere.
pub fn resolve_files(controller: &mut toml::Table, dir: &Path) {
    for (key, value) in controller.iter_mut() {
        if !(key.ends_with("-file") || key == "robust-gain") {
            continue;
        }
        if let Some(s) = value.as_str()
            && Path::new(s).is_relative()
        {
            let abs = std::path::absolute(dir.join(s)).unwrap_or_else(|_| dir.join(s));
            *value = abs.display().to_string().into();
        }
    }
}

/// Everything one run needs.
struct RunSpec<'a> {
    base: &'a toml::Table,
    dir: &'a Path,
    controller: Option<&'a (toml::Table, PathBuf)>,
    variant: &'a Variant,
    rule: Option<&'a Rule>,
    share: f64,
    burst: u64,
    lost: &'a [u64],
    runs: &'a Path,
    tmp: &'a Path,
    index: usize,
}

/// Puts the gap rule's keys into a controller table.
fn set_rule(controller: &mut toml::Table, rule: Option<&Rule>) {
    if let Some(r) = rule {
        controller.insert("gap-rule".into(), r.rule.clone().into());
        if let Some(p) = r.pause {
            controller.insert("gap-pause".into(), (p as i64).into());
        }
    }
}

/// One lockstep run with the lost samples `spec.lost`; reads its report.
fn one_run(spec: RunSpec<'_>) -> Result<Cell, GapsError> {
    let mut t = spec.base.clone();
    let mut rig = table(&t, "rig");
    let name = rig.get("name").and_then(|v| v.as_str()).unwrap_or("rig");
    let name = format!("{name}-gaps-{}-{}", std::process::id(), spec.index);
    rig.insert("name".into(), name.into());
    t.insert("rig".into(), rig.into());
    let mut controller = table(&t, "controller");
    resolve_files(&mut controller, spec.dir);
    if spec.controller.is_none() {
        set_rule(&mut controller, spec.rule);
    }
    t.insert("controller".into(), controller.into());
    let mut proxy = table(&t, "proxy");
    proxy.insert("mode".into(), "lockstep".into());
    let mut faults = table(&proxy, "faults");
    let list: Vec<toml::Value> = spec
        .lost
        .iter()
        .map(|at| {
            let mut s = toml::Table::new();
            s.insert("at".into(), (*at as i64).into());
            s.insert("periods".into(), (spec.burst as i64).into());
            s.into()
        })
        .collect();
    faults.insert("lost".into(), list.into());
    proxy.insert("faults".into(), faults.into());
    t.insert("proxy".into(), proxy.into());
    let rule_slug = spec.rule.map(|r| r.name().replace(':', "-"));
    let slug = format!(
        "{}-{}-{}pm-b{}",
        spec.variant.name,
        rule_slug.as_deref().unwrap_or("none"),
        (spec.share * 1000.0).round() as u64,
        spec.burst
    );
    let file = spec.tmp.join(format!("{slug}.toml"));
    let text = toml::to_string(&t).map_err(GapsError::Scenario)?;
    std::fs::write(&file, text)
        .map_err(|source| FileError::new(FileOp::Access, file.clone(), source))?;
    let controller_file = match spec.controller {
        None => None,
        Some((c, cdir)) => {
            let mut c = c.clone();
            let mut ct = table(&c, "controller");
            resolve_files(&mut ct, cdir);
            set_rule(&mut ct, spec.rule);
            c.insert("controller".into(), ct.into());
            let f = spec.tmp.join(format!("{slug}-controller.toml"));
            let text = toml::to_string(&c).map_err(GapsError::Controller)?;
            std::fs::write(&f, text)
                .map_err(|source| FileError::new(FileOp::Access, f.clone(), source))?;
            Some(f)
        }
    };
    let folder = spec.runs.join(&slug);
    let opts = LaunchOptions {
        config: file.clone(),
        run_folder: Some(folder.clone()),
        mode: "lockstep".into(),
        duration: Some(DURATION_S),
        controller: controller_file.clone(),
        skip_figure: true,
        ..Default::default()
    };
    // A failed verdict (lost samples, suspended adaptation) still leaves the report.
    let launched = launch(&opts, Arc::new(AtomicUsize::new(0)));
    let _ = std::fs::remove_file(&file);
    if let Some(f) = controller_file {
        let _ = std::fs::remove_file(f);
    }
    let report = match std::fs::read_to_string(folder.join("report.json")) {
        Ok(report) => report,
        Err(source) => {
            return Err(match launched {
                Err(source) => GapsError::Launch {
                    run: slug,
                    folder,
                    source,
                },
                Ok(_) => GapsError::NoReport {
                    run: slug,
                    folder,
                    source,
                },
            });
        }
    };
    let r: serde_json::Value = match serde_json::from_str(&report) {
        Ok(r) => r,
        Err(source) => return Err(GapsError::Report { run: slug, source }),
    };
    let tones = r["tones"]["tones"]
        .as_array()
        .ok_or_else(|| GapsError::NoTones { run: slug.clone() })?;
    let min_suppression_db = tones
        .iter()
        .filter_map(|t| t["suppression_db"].as_f64())
        .fold(f64::INFINITY, f64::min);
    let updated = r["adaptation"]["updated"].as_u64().unwrap_or(0);
    let suspended = r["adaptation"]["suspended"]
        .as_array()
        .map(|a| a.iter().filter_map(|c| c[1].as_u64()).sum())
        .unwrap_or(0);
    let stats = &r["stats"];
    let past = stats["samples_past_startup"].as_u64().unwrap_or(0);
    let lost = stats["lost_past_startup"].as_u64().unwrap_or(0);
    Ok(Cell {
        variant: spec.variant.name.clone(),
        rule: spec.rule.map(Rule::name),
        share: spec.share,
        burst: spec.burst,
        bursts: spec.lost.len(),
        lost_share: if past == 0 {
            0.0
        } else {
            lost as f64 / past as f64
        },
        min_suppression_db,
        updated,
        suspended,
        verdict_ok: r["verdict"]["ok"].as_bool().unwrap_or(false),
        folder,
    })
}

/// A share as a percentage for the tables.
fn pct(s: f64) -> String {
    let p = 100.0 * s;
    if p == 0.0 {
        "0".into()
    } else if p < 1.0 {
        format!("{p:.1}")
    } else {
        format!("{p:.0}")
    }
}

/// The campaign as Markdown: per controller, the smallest tone suppression (and the share
/// of closed-loop steps updated) against the lost share, one row per rule and burst.
pub fn render_markdown(c: &GapCampaign, command: &str) -> String {
    let mut out = String::new();
    out += &format!(
        "Command: `{command}` (lockstep, deterministic: every run of it gives these numbers).\n\n"
    );
    out += &format!(
        "Each cell: the smallest suppression of the seven tones in dB (end of the open loop \
         against the end of the {DURATION_S} s run), and in parentheses the share of \
         closed-loop steps on which RCAC updated θ. Losses: bursts of b samples at seeded \
         random positions after the open loop; the header gives the share of closed-loop \
         samples lost (the service's own count agrees to within a burst). The 0 % run meets \
         no gap and is the same for every rule.\n\n"
    );
    for v in &c.variants {
        let base = c
            .cells
            .iter()
            .find(|x| x.variant == v.name && x.rule.is_none());
        out += &format!("## {}", v.name);
        if let Some(f) = &v.controller {
            out += &format!(" (`--controller {}`)", f.display());
        }
        out += "\n\n| rule | burst |";
        for s in SHARES {
            out += &format!(" {} % |", pct(s));
        }
        out += "\n| --- | --- |";
        for _ in SHARES {
            out += " --- |";
        }
        out += "\n";
        for r in &c.rules {
            for b in BURSTS {
                out += &format!("| {} | {b} |", r.name());
                for s in SHARES {
                    let cell = if s == 0.0 {
                        base
                    } else {
                        c.cells.iter().find(|x| {
                            x.variant == v.name
                                && x.rule.as_deref() == Some(&r.name())
                                && x.burst == b
                                && x.share == s
                        })
                    };
                    match cell {
                        Some(x) => {
                            out += &format!(
                                " {:.1} ({:.0} %) |",
                                x.min_suppression_db,
                                100.0 * x.updated_share()
                            )
                        }
                        None => out += " – |",
                    }
                }
                out += "\n";
            }
        }
        out += "\n";
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bursts_are_sorted_apart_and_make_up_the_share() {
        for (i, &s) in SHARES.iter().enumerate().skip(1) {
            for b in BURSTS {
                let p = positions(8001, 80000, s, b, i as u64);
                assert_eq!(p, positions(8001, 80000, s, b, i as u64));
                let want = (s * 71999.0 / b as f64).round().max(1.0) as usize;
                assert_eq!(p.len(), want, "share {s} burst {b}");
                assert!(p.windows(2).all(|w| w[1] > w[0] + b), "{s} {b}");
                assert!(p.iter().all(|&a| a >= 8001 && a + b < 80000));
            }
        }
        assert!(positions(8001, 80000, 0.0, 4, 0).is_empty());
    }

    #[test]
    fn rules_parse_with_and_without_a_pause() {
        assert_eq!(
            Rule::parse("resume-plan:0").unwrap(),
            Rule {
                rule: "resume-plan".into(),
                pause: Some(0)
            }
        );
        assert_eq!(Rule::parse("suspend").unwrap().name(), "suspend");
        assert!(Rule::parse("resume-hold:x").is_err());
    }
}
