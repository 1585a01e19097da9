//! Response time by timing: the service's response time (sample → publication of the
//! answer) with `timing = "compute-first"` against `timing = "answer-first"`, per
//! controller.
//!
//! ## Method
//!
//! Each controller of [`configs::timing_cases`] runs in the paced two-process set-up of
//! the wake-up phase ([`crate::paced`]): the parent is a real-time plant on the plant core
//! that publishes a measurement every period `T` (absolute `clock_nanosleep`; 125 µs, but
//! 500 µs for the PCAC arm, whose step does not fit 8 kHz: see
//! [`configs::timing_cases`]) with a deadline of half a period (`deadline_ns = T/2`),
//! and the child is the real service
//! (`service::runtime::run`, with the service's default wait `sleep-poll`, the one every
//! shipped scenario uses) on the RT core. The service runs the controller
//! once per timing:
//!
//! ```text
//!  compute-first  at sample k: u_k = step(y_k, …), then publish Actuation{seq k}
//!  answer-first   at sample k: publish Actuation{seq k} = u_k prepared from data up to
//!                 k − 1, then take y_k in and prepare u_{k+1}
//! ```
//!
//! Both answer sample `k` with `Actuation{seq k}` (`reply_to == seq`), which the plant
//! must hold at `t_k + T/2`: the plant is the same for both, and its count of answers in
//! time is what the response time means for a deadline inside the period. The plant
//! closes the case's loop ([`PacedPlant`]): the adaptive controllers adapt on the data of
//! a real loop, as in the step-cost phase, and the input it applies for sample `k` is the
//! answer to `k` (held when it is missing).
//!
//! The two timings alternate in rounds of fresh service children in ABBA order
//! (compute-first, answer-first, answer-first, compute-first, …; `--rounds`), each round
//! `--seconds / --rounds` long, so each timing runs `--seconds` in all and a slow change
//! of the machine's load weighs on both alike. Each round runs on a rig name of its own
//! (`<rig base>-t<case><c|a><round>`).
//!
//! ## Figures
//!
//! The rows are the service's own: its `latency.response` (sample time → publication of
//! the answer to that sample) and `latency.compute` (the controller's work of the cycle:
//! `step` with compute-first; with answer-first the work after the publication that
//! prepares `u_{k+1}`). Per timing, the service's interval logs of its rounds
//! (`response.hlog`, `compute.hlog`, which hold the histograms its `report.json`
//! summarises) are summed; a round whose log does not hold as many values as its
//! report's `latency.response.count`, or whose report names another timing, fails. The
//! answer-first row's note gives answer-first ÷ compute-first of the response p50 and p99.

use crate::child;
use crate::cli::Settings;
use crate::configs::{self, PacedPlant, TimingCase};
use crate::hist::{self, Summary, new_histogram};
use crate::paced::{self, PacedModel};
use crate::progress;
use crate::report::{Collected, Measured};
use crate::step_cost::Loop;
use crate::synthetic_arm::ArmPlant;
use crate::table::fmt_ratio;
use crate::{PERIOD_NS, RT_PRIORITY};
use hdrhistogram::Histogram;
use ipc_types::{ChannelCounts, Timing};
use serde::Serialize;
use serde_json::{Map, Value, json};
use std::path::{Path, PathBuf};
use std::time::{Instant, SystemTime};

/// The two timings compared, in the order of the first round.
pub const TIMINGS: [Timing; 2] = [Timing::ComputeFirst, Timing::AnswerFirst];

/// What one round of one timing gave.
#[derive(Debug, Clone, Serialize)]
pub struct RoundFigures {
    /// The round (0-based).
    pub round: u64,
    /// The service's `latency.response` of this round, from its `report.json`.
    pub response: Summary,
    /// The service's `latency.compute` of this round.
    pub compute: Summary,
    /// Samples the plant published.
    pub samples: u64,
    /// Answers the plant had at the deadline of their sample.
    pub in_time: u64,
    /// Answers it found only at a later sample's check.
    pub late: u64,
    /// Samples the service never saw (`stats.skipped`).
    pub skipped: u64,
    /// Samples the service took in without answering them (`stats.caught_up`).
    pub caught_up: u64,
}

/// One timing of one controller, over its rounds.
#[derive(Debug, Clone)]
pub struct TimingRuns {
    /// The timing.
    pub timing: Timing,
    /// The service's response times of every round, summed (ns).
    pub response: Histogram<u64>,
    /// The service's compute times of every round, summed (ns).
    pub compute: Histogram<u64>,
    /// Each round's figures, in the order they ran.
    pub rounds: Vec<RoundFigures>,
    /// Each round's `report.json`.
    pub reports: Vec<Value>,
    /// The controller's counters (`controller_counters`), summed over the rounds.
    pub counters: Vec<(String, u64)>,
    /// What the OS granted the plant thread (first round).
    pub plant_setup: Option<String>,
    /// The service's RT set-up as its report states it (first round).
    pub service_setup: Option<String>,
    /// Why a round failed; the timing's later rounds are then not run.
    pub error: Option<String>,
}

impl TimingRuns {
    fn new(timing: Timing) -> Self {
        Self {
            timing,
            response: new_histogram(),
            compute: new_histogram(),
            rounds: Vec::new(),
            reports: Vec::new(),
            counters: Vec::new(),
            plant_setup: None,
            service_setup: None,
            error: None,
        }
    }

    /// Adds a round's outcome.
    fn add(&mut self, r: Round) {
        let _ = self.response.add(&r.response);
        let _ = self.compute.add(&r.compute);
        if let Some(counters) = r
            .report
            .get("controller_counters")
            .and_then(Value::as_array)
        {
            for pair in counters {
                let (Some(name), Some(n)) = (
                    pair.get(0).and_then(Value::as_str),
                    pair.get(1).and_then(Value::as_u64),
                ) else {
                    continue;
                };
                match self.counters.iter_mut().find(|(k, _)| k == name) {
                    Some((_, total)) => *total += n,
                    None => self.counters.push((name.to_string(), n)),
                }
            }
        }
        self.plant_setup.get_or_insert(r.plant_setup);
        self.service_setup
            .get_or_insert_with(|| child::service_rt_line(&r.report));
        self.rounds.push(r.figures);
        self.reports.push(r.report);
    }

    /// The plant's answers in time over every round, and its samples.
    pub fn in_time(&self) -> (u64, u64) {
        self.rounds
            .iter()
            .fold((0, 0), |(a, b), r| (a + r.in_time, b + r.samples))
    }
}

/// One controller, both timings.
#[derive(Debug, Clone)]
pub struct CaseRuns {
    /// The controller.
    pub case: TimingCase,
    /// Compute-first, then answer-first ([`TIMINGS`]).
    pub runs: [TimingRuns; 2],
    /// Wall-clock start of the case, for the interval logs.
    pub start: SystemTime,
    /// How long the case took.
    pub elapsed: std::time::Duration,
}

/// One round's outcome.
struct Round {
    figures: RoundFigures,
    response: Histogram<u64>,
    compute: Histogram<u64>,
    report: Value,
    plant_setup: String,
}

/// The channel counts of `case` (no command).
pub fn counts(case: &TimingCase) -> ChannelCounts {
    let c = case.channels;
    ChannelCounts::new(c.y, c.z, 0, c.u).expect("the bench's counts fit")
}

/// The paced plant's model of `plant` for a rig of `counts`.
pub fn model(plant: &PacedPlant, counts: ChannelCounts) -> Box<dyn PacedModel> {
    match plant {
        PacedPlant::Signal => Box::new(paced::TestSignal),
        PacedPlant::Fir(lp) => Box::new(FirModel(Loop::new(
            lp,
            counts.n_z as usize,
            counts.n_u as usize,
        ))),
        PacedPlant::Arm(seed) => Box::new(ArmModel(ArmPlant::new(*seed))),
    }
}

/// The loop of a [`configs::LoopPlant`] as the paced plant's model: `z_k` from the FIR,
/// `y = z`.
struct FirModel(Loop);

impl PacedModel for FirModel {
    fn sample(&mut self, k: u64, y: &mut [f64], z: &mut [f64]) {
        self.0.output(k, z);
        let m = y.len().min(z.len());
        y[..m].copy_from_slice(&z[..m]);
    }

    fn apply(&mut self, u: &[f64]) {
        self.0.apply(u);
    }

    fn reports_applied(&self) -> bool {
        true
    }
}

/// [`ArmPlant`] as the paced plant's model: `y = z = x + v`.
struct ArmModel(ArmPlant);

impl PacedModel for ArmModel {
    fn sample(&mut self, _k: u64, y: &mut [f64], z: &mut [f64]) {
        self.0.sample(y);
        let m = y.len().min(z.len());
        z[..m].copy_from_slice(&y[..m]);
    }

    fn apply(&mut self, u: &[f64]) {
        self.0.advance(u);
    }

    fn reports_applied(&self) -> bool {
        true
    }
}

/// One round: the service child on `case` with `timing`, rig `rig`, run folder `dir`,
/// paced for `seconds`.
fn round(
    s: &Settings,
    dir: &Path,
    rig: &str,
    case: &TimingCase,
    timing: Timing,
    seconds: f64,
    r: u64,
) -> Result<Round, String> {
    let text = case.service_toml(rig, timing, s.service_log);
    let counts = counts(case);
    let child = child::spawn_service_with(s, dir, &text, "sleep-poll")?;
    let mut model = model(&case.plant, counts);
    let plant = paced::PacedSpec {
        counts,
        period_ns: case.period_ns,
        seconds,
    };
    let (p, setup, report) = paced::paced_service_run(s, child, dir, rig, &plant, model.as_mut())?;
    let ran = report.get("timing").and_then(Value::as_str).unwrap_or("?");
    if ran != timing.name() {
        return Err(format!(
            "the service ran timing '{ran}', not '{}'",
            timing.name()
        ));
    }
    let latency = |k: &str| {
        report
            .pointer(&format!("/latency/{k}"))
            .ok_or(format!("report.json has no latency.{k}"))
            .and_then(Summary::from_service_json)
    };
    let (response_sum, compute_sum) = (latency("response")?, latency("compute")?);
    let response = hist::read_interval_log(&dir.join("response.hlog"))?;
    let compute = hist::read_interval_log(&dir.join("compute.hlog"))?;
    if response.len() != response_sum.count || compute.len() != compute_sum.count {
        return Err(format!(
            "the service's interval logs hold {} response and {} compute values, its report \
             {} and {}",
            response.len(),
            compute.len(),
            response_sum.count,
            compute_sum.count
        ));
    }
    let stat = |k: &str| {
        report
            .pointer(&format!("/stats/{k}"))
            .and_then(Value::as_u64)
            .unwrap_or(0)
    };
    Ok(Round {
        figures: RoundFigures {
            round: r,
            response: response_sum,
            compute: compute_sum,
            samples: p.samples,
            in_time: p.in_time,
            late: p.late,
            skipped: stat("skipped"),
            caught_up: stat("caught_up"),
        },
        response,
        compute,
        report,
        plant_setup: setup.describe(),
    })
}

/// Runs `case` (the `index`-th of the phase) with both timings in `s.rounds` rounds of
/// fresh service children in ABBA order, each `s.seconds / s.rounds` long, on rigs
/// `<rig_base>-t<index><c|a><round>`, with the run folders under `out`
/// (`<timing>/round-<r>/`).
pub fn run_case(
    s: &Settings,
    out: &Path,
    rig_base: &str,
    index: usize,
    case: &TimingCase,
) -> CaseRuns {
    let mut runs = TIMINGS.map(TimingRuns::new);
    let seconds = s.seconds / s.rounds.max(1) as f64;
    let start = SystemTime::now();
    let t = Instant::now();
    for r in 0..s.rounds {
        let order = if r % 2 == 0 { [0, 1] } else { [1, 0] };
        for v in order {
            if runs[v].error.is_some() {
                continue;
            }
            let timing = TIMINGS[v];
            progress(&format!(
                "response time by timing: {}, {}, round {}/{}, {seconds:.2} s at {}",
                case.name,
                timing.name(),
                r + 1,
                s.rounds,
                rate(case.period_ns)
            ));
            let dir = out.join(timing.name()).join(format!("round-{r}"));
            let letter = if v == 0 { 'c' } else { 'a' };
            let rig = format!("{rig_base}-t{index}{letter}{r}");
            match round(s, &dir, &rig, case, timing, seconds, r) {
                Ok(outcome) => runs[v].add(outcome),
                Err(e) => runs[v].error = Some(format!("round {}: {e}", r + 1)),
            }
        }
    }
    CaseRuns {
        case: case.clone(),
        runs,
        start,
        elapsed: t.elapsed(),
    }
}

/// A sample rate as the bench prints it (`8 kHz`, `2 kHz`, `1.5 kHz`, `50 Hz`).
pub fn rate(period_ns: u64) -> String {
    let hz = 1e9 / period_ns.max(1) as f64;
    if hz >= 1e3 {
        format!("{} kHz", hz / 1e3)
    } else {
        format!("{hz} Hz")
    }
}

/// The table label of `case` with `timing`.
pub fn label(case: &TimingCase, timing: Timing) -> String {
    format!("response: {} — {}", case.name, timing.name())
}

/// Min and max of some values in µs, as "a–b µs" (or one value when equal).
fn range_us(values: impl Iterator<Item = u64>) -> String {
    let v: Vec<f64> = values.map(|ns| ns as f64 / 1e3).collect();
    if v.is_empty() {
        return "-".into();
    }
    let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if hi - lo < 0.005 {
        format!("{lo:.2} µs")
    } else {
        format!("{lo:.2}–{hi:.2} µs")
    }
}

/// The rows (compute-first, answer-first), the detail lines and the `summary.json` block
/// of `c`, writing the summed distributions (`response.{hgrm,hlog}`,
/// `compute.{hgrm,hlog}`) into `out/<timing>/`.
pub fn case_rows(c: &CaseRuns, out: &Path) -> (Vec<Measured>, Vec<String>, Value) {
    let id = |t: Timing| format!("response-{}-{}", c.case.slug, t.name());
    let mut rows = Vec::new();
    let mut block = Map::new();
    let compute_p50 = |r: &TimingRuns| hist::quantile(&r.compute, 0.5) as f64 / 1e3;
    for r in &c.runs {
        let label = label(&c.case, r.timing);
        if let Some(e) = &r.error {
            rows.push(Measured::failed(&id(r.timing), &label, e.clone()));
            block.insert(r.timing.name().into(), json!({ "error": e }));
            continue;
        }
        let dir = out.join(r.timing.name());
        let mut files: Vec<PathBuf> =
            hist::write_files(&dir, "response", &r.response, c.start, c.elapsed)
                .unwrap_or_default();
        files.extend(
            hist::write_files(&dir, "compute", &r.compute, c.start, c.elapsed).unwrap_or_default(),
        );
        let mut m = Measured::from_summary(&id(r.timing), &label, Summary::of(&r.response), files);
        let (in_time, samples) = r.in_time();
        m.note = format!(
            "compute p50 {:.2} µs; plant: {in_time} of {samples} in time",
            compute_p50(r)
        );
        rows.push(m);
        block.insert(
            r.timing.name().into(),
            json!({
                "response": Summary::of(&r.response),
                "compute": Summary::of(&r.compute),
                "rounds": r.rounds,
                "controller_counters": r.counters,
            }),
        );
    }
    let [cf, af] = &c.runs;
    let ratios = match (rows[0].summary, rows[1].summary) {
        (Some(a), Some(b)) if cf.error.is_none() && af.error.is_none() => {
            let p50 = hist::ratio(b.p50_ns, a.p50_ns);
            let p99 = hist::ratio(b.p99_ns, a.p99_ns);
            rows[1].note = format!(
                "÷ compute-first: p50 {}, p99 {}; {}",
                fmt_ratio(p50),
                fmt_ratio(p99),
                rows[1].note
            );
            json!({ "p50": p50, "p99": p99 })
        }
        _ => Value::Null,
    };
    block.insert("answer_first_over_compute_first".into(), ratios);
    let mut details = Vec::new();
    let ok: Vec<&TimingRuns> = c.runs.iter().filter(|r| r.error.is_none()).collect();
    if !ok.is_empty() {
        let per_timing = |f: &dyn Fn(&TimingRuns) -> String| {
            ok.iter()
                .map(|r| format!("{} {}", r.timing.name(), f(r)))
                .collect::<Vec<_>>()
                .join(", ")
        };
        details.push(format!(
            "response by timing, {}: response p50 per round: {}; plant (deadline {:.1} µs): {}; \
             service: {}; controller counters: {}",
            c.case.name,
            per_timing(&|r| range_us(r.rounds.iter().map(|f| f.response.p50_ns))),
            c.case.period_ns as f64 / 2_000.0,
            per_timing(&|r| {
                let (in_time, samples) = r.in_time();
                let late: u64 = r.rounds.iter().map(|f| f.late).sum();
                format!(
                    "{in_time} in time, {late} late, {} missing of {samples}",
                    samples.saturating_sub(in_time + late)
                )
            }),
            per_timing(&|r| {
                let skipped: u64 = r.rounds.iter().map(|f| f.skipped).sum();
                let caught_up: u64 = r.rounds.iter().map(|f| f.caught_up).sum();
                format!("{skipped} skipped, {caught_up} caught up")
            }),
            per_timing(&|r| {
                if r.counters.is_empty() {
                    "none".to_string()
                } else {
                    r.counters
                        .iter()
                        .map(|(k, n)| format!("{k} {n}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                }
            }),
        ));
    }
    (rows, details, Value::Object(block))
}

/// The phase of the full run: every case of [`configs::timing_cases`], both timings each
/// ([`run_case`]), with its folders under `out/<slug>/`. The rows, the detail lines, the
/// `extra.timing` block of `summary.json` and the service's run reports go into `col`.
pub fn timing_phase(s: &Settings, out: &Path, rig_base: &str, col: &mut Collected) {
    let cases = configs::timing_cases();
    let mut extra = Map::new();
    let (mut plant_setup, mut service_setup) = (None, None);
    for (i, case) in cases.iter().enumerate() {
        let dir = out.join(&case.slug);
        let c = run_case(s, &dir, rig_base, i, case);
        let (rows, details, block) = case_rows(&c, &dir);
        col.measured.extend(rows);
        col.details.extend(details);
        extra.insert(case.slug.clone(), block);
        for r in &c.runs {
            plant_setup = plant_setup.or(r.plant_setup.clone());
            service_setup = service_setup.or(r.service_setup.clone());
            for (f, report) in r.rounds.iter().zip(&r.reports) {
                col.reports.insert(
                    format!("timing-{}-{}-round-{}", case.slug, r.timing.name(), f.round),
                    report.clone(),
                );
            }
        }
    }
    col.details.push(format!(
        "response by timing: {} rounds per timing of {:.2} s each, fresh service children in ABBA \
         order (compute-first first); service sleep-polling on core {}, SCHED_FIFO {RT_PRIORITY}, \
         service RT set-up: {}; paced plant on core {} at {} unless the row names its rate, \
         deadline T/2, closing each controller's loop; plant thread: {}; rows: the service's \
         own response.hlog and compute.hlog summed over the rounds",
        s.rounds,
        s.seconds / s.rounds.max(1) as f64,
        s.rt_core,
        service_setup.as_deref().unwrap_or("?"),
        s.plant_core,
        rate(PERIOD_NS),
        plant_setup.as_deref().unwrap_or("?"),
    ));
    col.extra.insert("timing".into(), Value::Object(extra));
}
