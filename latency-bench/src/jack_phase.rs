//! The acoustic rig through a sound card under JACK, against its direct loop
//! (`latency-bench jack`).
//!
//! For each period `P` (frames) the phase runs the design path of the JACK scenario
//! (`scenarios/jack/acoustic-rig.toml`) through a JACK server with the dummy backend at the
//! rig's 8 kHz and the simulated room (`rig launch … --plant jack-room`): an identification
//! run in lockstep (the server freewheeling), `rig-design frf` for the delays it finds, and
//! the FIR target of `200 + P` Markov parameters (`rig-design dtf --method fir`), which
//! covers the stretch of the impulse response past the delays that the direct rig's 200 do.
//! Then RCAC with that target, in lockstep and in real time, the latter idle and with a busy
//! loop on each core (normal priority: the box a user has is never idle). The direct loop
//! (`scenarios/acoustic-rig.toml`, plant-proxy, its committed target) runs the same
//! controller in lockstep and in real time under the same loads, as the reference.
//!
//! Each run gives a row: the seven tones' suppression (the service's run report: the tone
//! amplitudes at the end of the open-loop second against the end of the run, §3.5) and its
//! verdict; the plant side's misses; and through JACK the xruns per minute of wall time,
//! the callbacks that ran out of their budget, the callback's duration, the round trip of
//! a sample through the service, and the delay the loop through the server adds, as the
//! plant report states it and as the identification found it (the room's delays are 9 and
//! 16 samples).
//!
//! The phase runs the real binaries next to this one (`rig`, `rig-design`), which start
//! `jackd`, `plant-jack` and the service; it needs Debian's `jackd2`.

use rig_tools::soak::hog::Hog;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// The server the phase's runs use (one at a time; `rig launch --plant jack-room` starts
/// and stops it around each run).
pub const SERVER: &str = "latency-bench-jack";

/// What the phase runs.
#[derive(Debug, Clone)]
pub struct JackPlan {
    /// JACK periods, frames.
    pub periods: Vec<u32>,
    /// Seconds of each RCAC run.
    pub seconds: f64,
    /// Seconds of each identification run.
    pub ident_seconds: f64,
    /// The loads of the real-time runs.
    pub loads: Vec<Load>,
    /// The repository (its `scenarios/`).
    pub repo: PathBuf,
    /// The folder of the binaries (`rig`, `rig-design`).
    pub bin_dir: PathBuf,
}

/// What else runs on the box during a real-time run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Load {
    /// Nothing of the bench's.
    Idle,
    /// A busy loop on each core at normal priority.
    Busy,
}

impl Load {
    /// Its name in the table and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Load::Idle => "idle",
            Load::Busy => "busy",
        }
    }

    /// `idle` or `busy`.
    pub fn parse(s: &str) -> Result<Self, String> {
        match s {
            "idle" => Ok(Load::Idle),
            "busy" => Ok(Load::Busy),
            _ => Err(format!("'{s}' is not a load (idle or busy)")),
        }
    }
}

/// A busy loop on each core at normal priority (rig soak's load,
/// [`rig_tools::soak::hog::Hog`]), stopped when the guards are dropped.
fn hogs() -> Result<Vec<Hog>, String> {
    let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
    (0..cores)
        .map(|c| Hog::start(c).map_err(|e| format!("a busy loop on core {c}: {e}")))
        .collect()
}

/// One run of the table.
#[derive(Debug, Clone)]
pub struct LoopRun {
    /// `direct` or `jack`.
    pub path: &'static str,
    /// The JACK period, frames.
    pub period: Option<u32>,
    /// `lockstep` or `real-time`.
    pub mode: &'static str,
    /// The load of a real-time run.
    pub load: Option<Load>,
    /// The service's run report.
    pub report: Value,
    /// The plant's report.
    pub plant: Value,
    /// The delays the identification found (JACK runs).
    pub delays_found: Option<String>,
}

impl LoopRun {
    /// The tones' suppression, dB, in the report's order.
    fn tones_db(&self) -> Vec<f64> {
        self.report["tones"]["tones"]
            .as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|t| t["suppression_db"].as_f64())
                    .collect()
            })
            .unwrap_or_default()
    }

    /// The row's cells.
    fn cells(&self) -> Vec<String> {
        let mut db = self.tones_db();
        db.sort_by(f64::total_cmp);
        let tones = if db.is_empty() {
            "-".to_string()
        } else {
            format!(
                "{:.1} / {:.1} / {:.1}",
                db[0],
                db[db.len() / 2],
                db[db.len() - 1]
            )
        };
        let below = db.iter().filter(|d| **d < 60.0).count();
        let p = &self.plant;
        let samples = p["samples"].as_f64().unwrap_or(0.0).max(1.0);
        let misses = p["misses"].as_f64().unwrap_or(0.0);
        let j = &p["jack"];
        let jack = |v: String| if j.is_null() { "-".to_string() } else { v };
        let minutes = p["wall_time_s"].as_f64().unwrap_or(0.0) / 60.0;
        let sampled = j["callback_time"]["callbacks"]
            .as_f64()
            .unwrap_or(0.0)
            .max(1.0);
        vec![
            self.path.to_string(),
            self.period.map_or("-".into(), |p| p.to_string()),
            self.mode.to_string(),
            self.load.map_or("-", Load::name).to_string(),
            tones,
            below.to_string(),
            if self.report["verdict"]["ok"] == true {
                "OK"
            } else {
                "FAILED"
            }
            .to_string(),
            format!("{:.2}", 100.0 * misses / samples),
            jack(format!(
                "{:.1}",
                100.0 * j["callbacks_budget_exhausted"].as_f64().unwrap_or(0.0) / sampled
            )),
            jack(if self.mode == "lockstep" || minutes <= 0.0 {
                "-".to_string()
            } else {
                format!("{:.0}", j["xruns"].as_f64().unwrap_or(0.0) / minutes)
            }),
            jack(format!(
                "{:.0} / {:.0}",
                j["callback_time"]["p50_us"].as_f64().unwrap_or(0.0),
                j["callback_time"]["p99_us"].as_f64().unwrap_or(0.0)
            )),
            if p["round_trip"].is_null() {
                "-".to_string()
            } else {
                format!(
                    "{:.0} / {:.0}",
                    p["round_trip"]["p50_us"].as_f64().unwrap_or(0.0),
                    p["round_trip"]["p99_us"].as_f64().unwrap_or(0.0)
                )
            },
            jack(format!(
                "{} / {}",
                j["added_delay_frames"],
                self.delays_found.as_deref().unwrap_or("-")
            )),
        ]
    }
}

/// The table's header.
const HEADER: [&str; 13] = [
    "loop",
    "P",
    "mode",
    "load",
    "tones dB min/med/max",
    "<60",
    "verdict",
    "miss %",
    "budget out %",
    "xruns/min",
    "callback p50/p99 µs",
    "round trip p50/p99 µs",
    "added delay / delays found",
];

/// The table of `runs`, aligned, with its header.
pub fn render(runs: &[LoopRun]) -> String {
    let rows: Vec<Vec<String>> = std::iter::once(HEADER.iter().map(|s| s.to_string()).collect())
        .chain(runs.iter().map(LoopRun::cells))
        .collect();
    let widths: Vec<usize> = (0..HEADER.len())
        .map(|c| rows.iter().map(|r| r[c].chars().count()).max().unwrap_or(0))
        .collect();
    let mut out = String::new();
    for r in &rows {
        let line: Vec<String> = r
            .iter()
            .zip(&widths)
            .map(|(cell, w)| format!("{cell:<w$}"))
            .collect();
        out.push_str(line.join("  ").trim_end());
        out.push('\n');
    }
    out
}

/// Runs `program args…`, its output into `log`; the exit code, or why it did not run.
fn run_logged(program: &Path, args: &[String], log: &Path) -> Result<i32, String> {
    let file = std::fs::File::create(log).map_err(|e| format!("{}: {e}", log.display()))?;
    let err = file.try_clone().map_err(|e| e.to_string())?;
    let status = Command::new(program)
        .args(args)
        .stdin(std::process::Stdio::null())
        .stdout(file)
        .stderr(err)
        .status()
        .map_err(|e| format!("starting {}: {e}", program.display()))?;
    Ok(status.code().unwrap_or(-1))
}

/// Reads a JSON file, naming it when it cannot.
fn json_file(path: &Path) -> Result<Value, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
}

impl JackPlan {
    fn bin(&self, name: &str) -> PathBuf {
        self.bin_dir.join(name)
    }

    /// `rig launch <scenario> <args…> --run-folder <folder>`; the run's two reports. A run
    /// whose verdict failed still gives them; a run that left none is an error naming its
    /// log.
    fn launch(
        &self,
        scenario: &Path,
        args: &[&str],
        folder: &Path,
    ) -> Result<(Value, Value), String> {
        let _ = std::fs::remove_dir_all(folder);
        std::fs::create_dir_all(folder).map_err(|e| format!("{}: {e}", folder.display()))?;
        let mut all: Vec<String> = vec!["launch".into(), scenario.display().to_string()];
        all.extend(args.iter().map(|s| s.to_string()));
        all.extend(["--run-folder".into(), folder.display().to_string()]);
        let log = folder.with_extension("log");
        let code = run_logged(&self.bin("rig"), &all, &log)?;
        let report = json_file(&folder.join("report.json")).map_err(|e| {
            format!(
                "rig launch exited {code} without a run report ({e}); see {}",
                log.display()
            )
        })?;
        let plant = json_file(&folder.join("plant-report.json")).map_err(|e| {
            format!(
                "rig launch exited {code} without a plant report ({e}); see {}",
                log.display()
            )
        })?;
        Ok((report, plant))
    }

    /// The JACK scenario for period `p`: the server [`SERVER`], the period, its own rig
    /// name and the target model `target`.
    fn jack_scenario(&self, p: u32, target: &Path, dir: &Path) -> Result<PathBuf, String> {
        let src = self.repo.join("scenarios/jack/acoustic-rig.toml");
        let text = std::fs::read_to_string(&src).map_err(|e| format!("{}: {e}", src.display()))?;
        let mut out = String::new();
        let mut section = String::new();
        for line in text.lines() {
            let t = line.trim();
            if t.starts_with('[') {
                section = t.to_string();
            }
            let key = t.split('=').next().unwrap_or("").trim();
            let line = match (section.as_str(), key) {
                ("[rig]", "name") => "name = \"latency-bench-jack\"".to_string(),
                ("[jack]", "server") => format!("server = \"{SERVER}\""),
                ("[jack]", "period-frames") => format!("period-frames = {p}"),
                ("[controller]", "target-model-file") => {
                    format!("target-model-file = \"{}\"", target.display())
                }
                _ => line.to_string(),
            };
            out.push_str(&line);
            out.push('\n');
        }
        let path = dir.join("scenario.toml");
        std::fs::write(&path, out).map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(path)
    }

    /// The design path through the server for period `p`: the target model's path and the
    /// delays `rig-design frf` found.
    fn design(&self, p: u32, dir: &Path) -> Result<(PathBuf, String), String> {
        let target = dir.join("target-model.toml");
        let scenario = self.jack_scenario(p, &target, dir)?;
        let excitation = self.repo.join("scenarios/identify/excitation.toml");
        let ident = dir.join("ident");
        let (_, plant) = self.launch(
            &scenario,
            &[
                "--plant",
                "jack-room",
                "--controller",
                &excitation.display().to_string(),
                "--mode",
                "lockstep",
                "--duration",
                &self.ident_seconds.to_string(),
            ],
            &ident,
        )?;
        if plant["misses"].as_u64() != Some(0) {
            return Err(format!(
                "the identification run through JACK missed samples: {plant}"
            ));
        }
        let frf = dir.join("frf");
        let frf_args: Vec<String> = [
            "frf",
            &ident.join("signals.csv").display().to_string(),
            "--inputs",
            "u0,u1",
            "--outputs",
            "y0",
            "--scenario",
            &scenario.display().to_string(),
            "--out",
            &frf.display().to_string(),
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        let log = dir.join("frf.log");
        if run_logged(&self.bin("rig-design"), &frf_args, &log)? != 0 {
            return Err(format!("rig-design frf failed; see {}", log.display()));
        }
        let printed = std::fs::read_to_string(&log).unwrap_or_default();
        let delays = printed
            .split("delays found ")
            .nth(1)
            .and_then(|s| s.split(" samples").next())
            .unwrap_or("?")
            .to_string();
        let fir = dir.join("fir");
        let fir_args: Vec<String> = [
            "dtf",
            &frf.join("frf.csv").display().to_string(),
            "--method",
            "fir",
            "--count",
            &(200 + p).to_string(),
            "--out",
            &fir.display().to_string(),
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        let log = dir.join("dtf.log");
        if run_logged(&self.bin("rig-design"), &fir_args, &log)? != 0 {
            return Err(format!("rig-design dtf failed; see {}", log.display()));
        }
        std::fs::copy(fir.join("target-model.toml"), &target)
            .map_err(|e| format!("copying the target model to {}: {e}", target.display()))?;
        Ok((scenario, delays))
    }

    /// The lockstep run and the real-time runs (one per load) of `scenario` with `args`.
    fn runs(
        &self,
        scenario: &Path,
        args: &[&str],
        dir: &Path,
        mut row: impl FnMut(&'static str, Option<Load>, Value, Value),
    ) -> Result<(), String> {
        let mut lockstep = args.to_vec();
        lockstep.extend(["--mode", "lockstep"]);
        let seconds = self.seconds.to_string();
        lockstep.extend(["--duration", &seconds]);
        let (r, p) = self.launch(scenario, &lockstep, &dir.join("lockstep"))?;
        row("lockstep", None, r, p);
        for &load in &self.loads {
            let mut rt = args.to_vec();
            rt.extend(["--duration", &seconds]);
            let load_guard = if load == Load::Busy {
                hogs()?
            } else {
                Vec::new()
            };
            let result = self.launch(
                scenario,
                &rt,
                &dir.join(format!("real-time-{}", load.name())),
            );
            drop(load_guard);
            let (r, p) = result?;
            row("real-time", Some(load), r, p);
        }
        Ok(())
    }
}

/// Runs the phase into `out`: the rows, the lines under the table, and the summary's
/// block; a run that could not be made is a line of `failures`.
pub fn jack_phase(plan: &JackPlan, out: &Path) -> (Vec<LoopRun>, Vec<String>, Value) {
    let mut runs = Vec::new();
    let mut failures = Vec::new();
    let started = Instant::now();
    let direct = plan.repo.join("scenarios/acoustic-rig.toml");
    crate::progress("the direct loop (plant-proxy): lockstep, then real time");
    let dir = out.join("direct");
    let _ = std::fs::create_dir_all(&dir);
    if let Err(e) = plan.runs(&direct, &[], &dir, |mode, load, report, plant| {
        runs.push(LoopRun {
            path: "direct",
            period: None,
            mode,
            load,
            report,
            plant,
            delays_found: None,
        })
    }) {
        failures.push(format!("direct loop: {e}"));
    }
    for &p in &plan.periods {
        crate::progress(&format!(
            "through JACK at {p} frames per period: identification, target model, lockstep, real time"
        ));
        let dir = out.join(format!("jack-{p}"));
        let _ = std::fs::create_dir_all(&dir);
        let (scenario, delays) = match plan.design(p, &dir) {
            Ok(d) => d,
            Err(e) => {
                failures.push(format!("JACK, {p} frames: {e}"));
                continue;
            }
        };
        if let Err(e) = plan.runs(
            &scenario,
            &["--plant", "jack-room"],
            &dir,
            |mode, load, report, plant| {
                runs.push(LoopRun {
                    path: "jack",
                    period: Some(p),
                    mode,
                    load,
                    report,
                    plant,
                    delays_found: Some(delays.clone()),
                })
            },
        ) {
            failures.push(format!("JACK, {p} frames: {e}"));
        }
    }
    let mut lines = vec![
        "tones: the seven tones' suppression (service report: end of the 1 s open loop against the end of the run); <60: tones below the scenario's 60 dB".to_string(),
        "miss %: samples whose input was not the service's answer (plant report); budget out %: callbacks whose budget (jack.budget of the period) ran out with a sample unanswered".to_string(),
        "xruns/min: server xruns per minute of the run's wall time; round trip: publishing M_k to holding the answer that carries u_(k+1)".to_string(),
        "added delay: frames the loop through the server adds (plant report, the room's stated latency); delays found: rig-design frf on the identification run (the room's own are 9 and 16)".to_string(),
        format!("busy: a busy loop on each core at normal priority during the real-time run; the phase took {:.0} s", started.elapsed().as_secs_f64()),
    ];
    lines.extend(failures.iter().map(|f| format!("FAILED: {f}")));
    let summary = json!({
        "periods": plan.periods,
        "seconds": plan.seconds,
        "ident_seconds": plan.ident_seconds,
        "loads": plan.loads.iter().map(|l| l.name()).collect::<Vec<_>>(),
        "runs": runs.iter().map(|r| json!({
            "loop": r.path, "period": r.period, "mode": r.mode, "load": r.load.map(Load::name),
            "tones_db": r.tones_db(), "verdict": r.report["verdict"], "plant": r.plant,
            "delays_found": r.delays_found,
        })).collect::<Vec<_>>(),
        "failures": failures,
    });
    (runs, lines, summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(path: &'static str, period: Option<u32>, mode: &'static str) -> LoopRun {
        let tones: Vec<Value> = [62.0, 70.0, 58.5, 80.0, 66.0, 75.0, 61.0]
            .iter()
            .map(|db| json!({ "suppression_db": db }))
            .collect();
        LoopRun {
            path,
            period,
            mode,
            load: (mode == "real-time").then_some(Load::Busy),
            report: json!({ "tones": { "tones": tones }, "verdict": { "ok": false } }),
            plant: json!({
                "samples": 80000, "misses": 800, "wall_time_s": 30.0,
                "round_trip": { "p50_us": 44.4, "p99_us": 240.2 },
                "jack": if path == "jack" { json!({
                    "callbacks_budget_exhausted": 50, "xruns": 6, "added_delay_frames": 16,
                    "callback_time": { "callbacks": 5000, "p50_us": 700.0, "p99_us": 1000.0 },
                }) } else { Value::Null },
            }),
            delays_found: (path == "jack").then(|| "[25, 32]".to_string()),
        }
    }

    #[test]
    fn a_row_gives_the_tones_the_misses_and_the_jack_figures() {
        let cells = run("jack", Some(16), "real-time").cells();
        assert_eq!(cells[0..4], ["jack", "16", "real-time", "busy"]);
        assert_eq!(cells[4], "58.5 / 66.0 / 80.0");
        assert_eq!(cells[5], "1");
        assert_eq!(cells[6], "FAILED");
        assert_eq!(cells[7], "1.00");
        assert_eq!(cells[8], "1.0");
        assert_eq!(cells[9], "12", "6 xruns in half a minute");
        assert_eq!(cells[10], "700 / 1000");
        assert_eq!(cells[11], "44 / 240");
        assert_eq!(cells[12], "16 / [25, 32]");
        let direct = run("direct", None, "lockstep").cells();
        assert_eq!(direct[8..11], ["-", "-", "-"]);
        let table = render(&[
            run("direct", None, "lockstep"),
            run("jack", Some(16), "real-time"),
        ]);
        assert_eq!(table.lines().count(), 3);
        assert!(table.starts_with("loop"), "{table}");
    }

    #[test]
    fn the_scenario_of_a_period_names_the_server_the_period_and_the_target() {
        let dir = std::env::temp_dir().join(format!("jack-phase-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let plan = JackPlan {
            periods: vec![64],
            seconds: 1.0,
            ident_seconds: 1.0,
            loads: vec![Load::Idle],
            repo: PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(".."),
            bin_dir: dir.clone(),
        };
        let target = dir.join("t.toml");
        let text = std::fs::read_to_string(plan.jack_scenario(64, &target, &dir).unwrap()).unwrap();
        for line in [
            "name = \"latency-bench-jack\"",
            "server = \"latency-bench-jack\"",
            "period-frames = 64",
            &format!("target-model-file = \"{}\"", target.display()),
        ] {
            assert!(text.lines().any(|l| l == line), "{line}");
        }
        assert!(Load::parse("busy").is_ok() && Load::parse("heavy").is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
