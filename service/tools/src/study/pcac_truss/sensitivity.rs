//! The settings §6.2 leaves open, and the convergence claims under each alternative
//! (claims 6.4 and 6.11: "converges within 10 s").
//!
//! The chapter prints the controller (n̂, θ_0, P_0, η, τ_n, τ_d, α, ℓ, C_t, Q, R, the force
//! limit) and the disturbances' kinds, but not everything a simulation needs; the study
//! had to choose the rest, and a reader of "within 10 s" reads it off a figure without a
//! stated rule. Each [`Change`] moves one choice from the study's value (`*` in the table)
//! to an alternative, all else as printed ([`super::Setting::Printed`]):
//!
//! | choice | study | alternatives | why open |
//! | --- | --- | --- | --- |
//! | convergence window (trailing RMS) | 3 s | 1.5 s, 6 s | "converges" is read off Figures 6.2/6.8 |
//! | convergence bound (× the late RMS) | 2 | 1.5, 3 | the same |
//! | noise and disturbance realization (seed) | 61 / 63 | 4 more seeds | not given |
//! | tone amplitudes (harmonic) | 1 N | 0.5 N, 2 N | not given (the force limit is 10 N) |
//! | tone phases (harmonic) | 0°, 120°, 240° | all 0° | not given |
//! | broadband RMS (aliasing) | 1 N | 0.5 N, 2 N | not given |
//! | sensor SNR at node 8 | 40 dB | 30 dB, 50 dB | given for a 0.1 Hz, 1 N tone, whose amplitude convention is ours |
//! | `P_0` | `I` | `0.1 I`, `10 I` | printed, but its scale depends on the unit of `y` (see [`super::Setting`]) |
//! | settled fraction of ‖θ_k‖ and tr P_k (claim 6.5) | 10 % | 5 %, 20 % | "converge" is read off Figures 6.4, 6.7, 6.10 |
//!
//! For each, node 8's time to converge ([`super::convergence_time`], with the changed
//! window or bound), its reduction over the late window, and when ‖θ_k‖ and tr P_k settle
//! ([`super::settling::settling_time`]); the convergence claim's criterion (within 10 s,
//! 5 s for the 25 Hz broadband case, and reduced by at least 6 dB) and claim 6.5's (node 8
//! before both, in this experiment, the others as the study ran them) are evaluated under
//! each alternative ([`record`]). The criterion
//! changes are read on one run of the study's choices; the others run a new open and
//! closed loop (the open loop too, since the disturbance may change). Each of these runs
//! is a [`Probe`], a run of the study's sharded stage `sensitivity`.

use super::settling::{SETTLED_FRACTION, settling_time};
use super::{
    Experiment, Outcome, RMS_WINDOW_S, Setting, TrussError, convergence_time, rms,
    run_experiment_with,
};
use crate::study::reproduction::sensitivity::{Alternative, Reading};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// One alternative choice.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Change {
    /// The study's choices.
    Study,
    /// The trailing window of the convergence rule, s.
    Window(f64),
    /// The bound of the convergence rule, times the late RMS.
    Bound(f64),
    /// The seed of the noise and the disturbance.
    Seed(u64),
    /// Every tone's amplitude, N (harmonic).
    ToneAmplitude(f64),
    /// Every tone's phase set to 0 (harmonic).
    TonePhasesZero,
    /// The band-limited disturbance's RMS, N (broadband).
    BandRms(f64),
    /// The sensor noise rescaled to this SNR at node 8, dB (the study's is 40 dB).
    SnrDb(f64),
    /// `P_0 = p0 · I`.
    P0(f64),
    /// The fraction of their largest excursion within which ‖θ_k‖ and tr P_k count as
    /// settled (claim 6.5).
    Settled(f64),
}

impl Change {
    /// The choice it moves, as the table names it.
    pub fn choice(self) -> &'static str {
        match self {
            Change::Study => "the study's choices",
            Change::Window(_) => "convergence window",
            Change::Bound(_) => "convergence bound",
            Change::Seed(_) => "seed",
            Change::ToneAmplitude(_) => "tone amplitudes",
            Change::TonePhasesZero => "tone phases",
            Change::BandRms(_) => "broadband RMS",
            Change::SnrDb(_) => "sensor SNR",
            Change::P0(_) => "P_0",
            Change::Settled(_) => "settled fraction of ‖θ_k‖, tr P_k",
        }
    }

    /// Why §6.2 leaves it open.
    pub fn why_open(self) -> &'static str {
        match self {
            Change::Study => "",
            Change::Window(_) | Change::Bound(_) => {
                "\"converges\" is read off Figures 6.2, 6.5, 6.8; no rule is stated"
            }
            Change::Seed(_) => "not given",
            Change::ToneAmplitude(_) => "not given (the force limit is 10 N)",
            Change::TonePhasesZero => "not given",
            Change::BandRms(_) => "not given",
            Change::SnrDb(_) => "given for a 0.1 Hz, 1 N tone, whose amplitude convention is ours",
            Change::P0(_) => "printed, but its scale depends on the unit of y",
            Change::Settled(_) => {
                "\"converge\" is read off Figures 6.4, 6.7, 6.10; no rule is stated"
            }
        }
    }

    /// The study's value of the choice it moves, in `exp`.
    pub fn ours(self, exp: Experiment) -> String {
        match self {
            Change::Study => "–".into(),
            Change::Window(_) => format!("{RMS_WINDOW_S} s"),
            Change::Bound(_) => "2×".into(),
            Change::Seed(_) => match exp {
                Experiment::Harmonic => "61",
                Experiment::Broadband => "62",
                Experiment::Aliasing => "63",
            }
            .into(),
            Change::ToneAmplitude(_) | Change::BandRms(_) => "1 N".into(),
            Change::TonePhasesZero => "0°, 120°, 240°".into(),
            Change::SnrDb(_) => "40 dB".into(),
            Change::P0(_) => "1 I".into(),
            Change::Settled(_) => format!("{} %", SETTLED_FRACTION * 100.0),
        }
    }

    /// Its value, as text.
    pub fn value(self) -> String {
        match self {
            Change::Study => "–".into(),
            Change::Window(s) => format!("{s} s"),
            Change::Bound(b) => format!("{b}×"),
            Change::Seed(s) => format!("{s}"),
            Change::ToneAmplitude(a) => format!("{a} N"),
            Change::TonePhasesZero => "all 0°".into(),
            Change::BandRms(a) => format!("{a} N"),
            Change::SnrDb(d) => format!("{d} dB"),
            Change::P0(p) => format!("{p} I"),
            Change::Settled(f) => format!("{} %", f * 100.0),
        }
    }

    /// Whether it needs a new simulation (else it is read on the study's).
    fn simulates(self) -> bool {
        !matches!(
            self,
            Change::Study | Change::Window(_) | Change::Bound(_) | Change::Settled(_)
        )
    }
}

/// The alternatives of `exp` (module docs).
pub fn alternatives(exp: Experiment) -> Vec<Change> {
    let mut v = vec![
        Change::Study,
        Change::Window(1.5),
        Change::Window(6.0),
        Change::Bound(1.5),
        Change::Bound(3.0),
    ];
    v.extend((1..=4).map(|i| Change::Seed(1000 + i)));
    match exp {
        Experiment::Harmonic => v.extend([
            Change::ToneAmplitude(0.5),
            Change::ToneAmplitude(2.0),
            Change::TonePhasesZero,
        ]),
        Experiment::Broadband | Experiment::Aliasing => {
            v.extend([Change::BandRms(0.5), Change::BandRms(2.0)]);
        }
    }
    v.extend([
        Change::SnrDb(30.0),
        Change::SnrDb(50.0),
        Change::P0(0.1),
        Change::P0(10.0),
        Change::Settled(0.05),
        Change::Settled(0.2),
    ]);
    v
}

/// One row of the sensitivity table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Row {
    /// The change from the study's choices.
    pub change: Change,
    /// Node 8's time to converge, s (`None`: not by the end).
    pub converge: Option<f64>,
    /// Node 8's reduction over the late window, dB.
    pub reduction_db: f64,
    /// When ‖θ_k‖ settles, s (`None`: not logged or not finite).
    pub theta_settles: Option<f64>,
    /// When tr P_k settles, s (`None`: not logged or not finite).
    pub p_settles: Option<f64>,
}

impl Row {
    /// The convergence claim's criterion under this change: within `within` s and reduced
    /// by at least `min_db`.
    pub fn meets(&self, within: f64, min_db: f64) -> bool {
        self.reduction_db >= min_db && self.converge.is_some_and(|t| t <= within)
    }

    /// Claim 6.5's criterion in this run: node 8 converges before ‖θ_k‖ and tr P_k
    /// settle.
    pub fn suppressed_first(&self) -> bool {
        match (self.converge, self.theta_settles, self.p_settles) {
            (Some(t), Some(theta), Some(p)) => t < theta.min(p),
            _ => false,
        }
    }

    /// Claim 6.5's numbers in this run.
    fn identification_text(&self) -> String {
        let t = |x: Option<f64>| x.map_or("–".into(), |t| format!("{t:.1} s"));
        format!(
            "node 8 {}, ‖θ‖ {}, tr P {}",
            self.converge
                .map_or("never".into(), |t| format!("{t:.1} s")),
            t(self.theta_settles),
            t(self.p_settles)
        )
    }
}

/// The claim on node 8's time to converge in `exp`.
pub fn convergence_claim(exp: Experiment) -> &'static str {
    match exp {
        Experiment::Harmonic => "6.4",
        Experiment::Broadband => "6.8",
        Experiment::Aliasing => "6.11",
    }
}

/// The sensitivity rows of the study ([`crate::study::reproduction::sensitivity`]): each
/// experiment's alternatives with the verdicts, under each, of its convergence claim
/// ([`convergence_claim`], within [`super::claims::within_s`]) and of claim 6.5 (this
/// experiment under the alternative, the others under the study's choices; read only
/// when every experiment ran).
pub fn record(outcomes: &[Outcome], min_db: f64) -> Vec<Alternative> {
    let study_first = |exp: Experiment| {
        outcomes
            .iter()
            .find(|o| o.experiment == exp)
            .and_then(|o| o.sensitivity.iter().find(|r| r.change == Change::Study))
            .map(Row::suppressed_first)
    };
    let all_ran = Experiment::ALL.iter().all(|e| study_first(*e).is_some());
    let mut rows = Vec::new();
    for o in outcomes {
        let exp = o.experiment;
        let others_first = Experiment::ALL
            .iter()
            .filter(|e| **e != exp)
            .all(|e| study_first(*e) == Some(true));
        let within = super::claims::within_s(exp);
        for r in &o.sensitivity {
            let mut readings = Vec::new();
            if !matches!(r.change, Change::Settled(_)) {
                readings.push(Reading::of(
                    convergence_claim(exp),
                    r.meets(within, min_db),
                    format!(
                        "{} ({:.1} dB)",
                        r.converge.map_or("never".into(), |t| format!("{t:.1} s")),
                        r.reduction_db
                    ),
                ));
            }
            if all_ran {
                readings.push(Reading::of(
                    "6.5",
                    r.suppressed_first() && others_first,
                    format!(
                        "{}: {} (node 8 {}first here)",
                        exp.name(),
                        r.identification_text(),
                        if r.suppressed_first() { "" } else { "not " }
                    ),
                ));
            }
            rows.push(Alternative::new(
                format!("{} ({})", r.change.choice(), exp.name()),
                r.change.why_open(),
                r.change.ours(exp),
                r.change.value(),
                readings,
            ));
        }
    }
    rows
}

/// Node 8's index in `z`.
const NODE_8: usize = 3;

/// One simulation of the sensitivity of `experiment`, `duration_s` long, the printed
/// setting: the open and closed loop under `simulated`, on which the rows of the
/// alternatives `read` are read (the criterion changes share the run of the study's
/// choices; every other alternative is its own run).
#[derive(Debug, Clone, PartialEq)]
pub struct Probe {
    /// The experiment.
    pub experiment: Experiment,
    /// The simulated duration, s.
    pub duration_s: f64,
    /// The change simulated ([`Change::Study`] for the criterion changes).
    pub simulated: Change,
    /// The alternatives read on this run.
    pub read: Vec<Change>,
}

/// The simulations of the alternatives of `exp` for `duration` s: one for the study's
/// choices and the criterion changes, then one per alternative that simulates, in the
/// order of [`alternatives`].
pub fn probes(exp: Experiment, duration: f64) -> Vec<Probe> {
    let probe = |simulated, read| Probe {
        experiment: exp,
        duration_s: duration,
        simulated,
        read,
    };
    let (simulates, read): (Vec<Change>, Vec<Change>) =
        alternatives(exp).into_iter().partition(|c| c.simulates());
    std::iter::once(probe(Change::Study, read))
        .chain(simulates.into_iter().map(|c| probe(c, vec![c])))
        .collect()
}

/// Runs `probe`: its rows, in the order of its `read`.
pub fn run_probe(probe: &Probe) -> Result<Vec<Row>, TrussError> {
    let (exp, change) = (probe.experiment, probe.simulated);
    let o = if change.simulates() {
        run_experiment_with(exp, &[Setting::Printed], probe.duration_s, &|sc, params| {
            apply(change, sc, params)
        })?
    } else {
        run_experiment_with(exp, &[Setting::Printed], probe.duration_s, &|_, _| {})?
    };
    Ok(probe.read.iter().map(|&c| row(&o, c)).collect())
}

/// The rows of `exp`'s probes in the order of [`alternatives`].
pub fn in_order(exp: Experiment, mut rows: Vec<Row>) -> Vec<Row> {
    let alternatives = alternatives(exp);
    rows.sort_by_key(|r| alternatives.iter().position(|c| *c == r.change));
    rows
}

/// Runs the alternatives of `exp` for `duration` s (in parallel), the printed setting.
pub fn run(exp: Experiment, duration: f64) -> Result<Vec<Row>, TrussError> {
    let rows = probes(exp, duration)
        .par_iter()
        .map(run_probe)
        .collect::<Result<Vec<_>, _>>()?;
    Ok(in_order(exp, rows.into_iter().flatten().collect()))
}

/// The row of `change` read on `o`, the run of its [`Probe`].
fn row(o: &Outcome, change: Change) -> Row {
    let c = &o.closed[0];
    let (window_s, bound) = match change {
        Change::Window(w) => (w, 2.0),
        Change::Bound(b) => (RMS_WINDOW_S, b),
        _ => (RMS_WINDOW_S, 2.0),
    };
    let fraction = match change {
        Change::Settled(f) => f,
        _ => SETTLED_FRACTION,
    };
    let settles = |name: &str| {
        c.trace
            .internal_names
            .iter()
            .position(|n| n == name)
            .and_then(|i| settling_time(&c.trace.internals[i], o.ts, fraction))
    };
    let z = &c.trace.z[NODE_8];
    let late = rms(&z[o.late_start..]);
    let window = (window_s / o.ts).round() as usize;
    Row {
        change,
        // convergence_time's bound is twice its target.
        converge: convergence_time(z, o.ts, window, late * bound / 2.0),
        reduction_db: o.reduction(c, NODE_8),
        theta_settles: settles("theta_norm"),
        p_settles: settles("trace_p"),
    }
}

/// Applies `change` to a loaded scenario and controller.
fn apply(
    change: Change,
    sc: &mut plant_proxy::scenario::Scenario,
    params: &mut control::pcac::PcacParams,
) {
    let plant = &mut sc.plant;
    match change {
        Change::Study | Change::Window(_) | Change::Bound(_) | Change::Settled(_) => {}
        Change::Seed(s) => plant.noise.seed = s,
        Change::ToneAmplitude(a) => plant
            .disturbance
            .tones
            .iter_mut()
            .for_each(|t| t.amplitude = a),
        Change::TonePhasesZero => plant
            .disturbance
            .tones
            .iter_mut()
            .for_each(|t| t.phase = 0.0),
        Change::BandRms(a) => plant
            .disturbance
            .band_limited
            .iter_mut()
            .for_each(|b| b.rms = a),
        Change::SnrDb(db) => {
            // The study's noise is set for 40 dB; σ scales as 10^(−ΔSNR/20).
            let k = 10f64.powf((40.0 - db) / 20.0);
            plant.noise.y_std.iter_mut().for_each(|s| *s *= k);
        }
        Change::P0(p) => params.model.p0 = p,
    }
}

/// The alternative of node 8's convergence (the study's own row and the settled
/// fractions, which do not change it, not counted) that converges first while reduced by
/// at least `min_db`, as text (`None`: none converges).
pub fn earliest(rows: &[Row], min_db: f64) -> Option<String> {
    rows.iter()
        .filter(|r| !matches!(r.change, Change::Study | Change::Settled(_)))
        .filter(|r| r.reduction_db >= min_db)
        .filter_map(|r| r.converge.map(|t| (t, r)))
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(t, r)| format!("{} {} at {t:.1} s", r.change.choice(), r.change.value()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_experiment_varies_each_open_choice_once_and_starts_from_the_studys() {
        for exp in Experiment::ALL {
            let v = alternatives(exp);
            assert_eq!(v[0], Change::Study);
            assert!(v.iter().filter(|c| **c == Change::Study).count() == 1);
            let tones = v.iter().any(|c| matches!(c, Change::ToneAmplitude(_)));
            assert_eq!(tones, exp == Experiment::Harmonic, "{exp:?}");
            let band = v.iter().any(|c| matches!(c, Change::BandRms(_)));
            assert_eq!(band, exp != Experiment::Harmonic, "{exp:?}");
        }
    }

    #[test]
    fn a_row_meets_the_claim_only_when_converged_in_time_and_reduced() {
        let r = |converge, reduction_db| Row {
            change: Change::Study,
            converge,
            reduction_db,
            theta_settles: Some(20.0),
            p_settles: Some(30.0),
        };
        assert!(r(Some(9.0), 20.0).meets(10.0, 6.0));
        assert!(!r(Some(11.0), 20.0).meets(10.0, 6.0));
        assert!(!r(None, 20.0).meets(10.0, 6.0));
        assert!(!r(Some(5.0), 3.0).meets(10.0, 6.0));
        let mut rows = vec![r(Some(3.0), 20.0), r(Some(9.0), 20.0), r(None, 20.0)];
        rows[1].change = Change::Seed(2);
        rows[2].change = Change::P0(10.0);
        // The study's own row (3 s) is not an alternative.
        assert_eq!(earliest(&rows, 6.0).as_deref(), Some("seed 2 at 9.0 s"));
        assert_eq!(earliest(&rows, 30.0), None);
        assert!(r(Some(9.0), 20.0).suppressed_first());
        assert!(!r(Some(25.0), 20.0).suppressed_first());
        assert!(!r(None, 20.0).suppressed_first());
    }

    #[test]
    fn the_changes_reach_the_scenario_and_the_controller() {
        let (mut sc, mut params) =
            super::super::load(Experiment::Harmonic, Setting::Printed).unwrap();
        let sigma = sc.plant.noise.y_std[3];
        apply(Change::SnrDb(20.0), &mut sc, &mut params);
        assert!((sc.plant.noise.y_std[3] / sigma - 10.0).abs() < 1e-9);
        apply(Change::ToneAmplitude(2.0), &mut sc, &mut params);
        assert!(
            sc.plant
                .disturbance
                .tones
                .iter()
                .all(|t| t.amplitude == 2.0)
        );
        apply(Change::P0(10.0), &mut sc, &mut params);
        assert_eq!(params.model.p0, 10.0);
        apply(Change::Seed(7), &mut sc, &mut params);
        assert_eq!(sc.plant.noise.seed, 7);
    }
}
