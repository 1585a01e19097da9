//! The claims of chapter 6 (§6.2, Figures 6.2–6.10) that `study pcac-truss` checks on its
//! outcomes ([`crate::study::pcac_truss::Outcome`]), with the controller as printed
//! ([`Setting::Printed`]; the `metres` setting is the product's illustration of scaling,
//! not the chapter's).
//!
//! The measures are the study's: the reduction of the noise-free `z` of each node,
//! `20 log10(RMS z_OL / RMS z_CL)` over the late window (the second half of the run); the
//! per-tone reduction at node 8 (harmonic case); the time to converge at node 8 (the end of
//! the first trailing 3 s window from which on the RMS stays within twice its late level,
//! [`crate::study::pcac_truss::convergence_time`]). "Suppressed" is read as a reduction of
//! at least [`SUPPRESSED_DB`] (half the RMS). The initial transient is the peak `|z|` of
//! node 8 in the closed loop over the first [`TRANSIENT_S`] seconds over the open loop's
//! peak over the same seconds (the same disturbance realization). When ‖θ_k‖ and tr P_k
//! converge is [`super::settling`]'s reading; the reductions peak by peak and mode by mode
//! are [`super::spectral`]'s. "Most of the peaks" is more than half of them.

use crate::study::pcac_truss::settling::{SETTLED_FRACTION, settling_time};
use crate::study::pcac_truss::spectral::{self, late_psd, peak_reductions, reduction_at};
use crate::study::pcac_truss::{Closed, Experiment, NODES, Outcome, Setting};
use crate::study::reproduction::{Claim, Statement};

/// The chapter.
const CH: u8 = 6;

/// A reduction of at least this counts as suppressed, dB.
pub const SUPPRESSED_DB: f64 = 6.0;

/// The initial transient is measured over the first this many seconds.
pub const TRANSIENT_S: f64 = 10.0;

/// Node 8's index in `z`.
const NODE_8: usize = 3;

const ALL_NODES: [Statement; 3] = [
    Statement {
        chapter: CH,
        id: "6.1",
        source: "§6.2.1, Figures 6.2–6.3",
        claim: "harmonic disturbance (0.354, 1, 1.55 Hz), 50 Hz: \"the disturbance is suppressed in all measurements\"",
        criterion: "the RMS of z at each of nodes 5–8 over the second half of the run reduced by at least 6 dB",
    },
    Statement {
        chapter: CH,
        id: "6.6",
        source: "§6.2.2, Figures 6.5–6.6",
        claim: "25 Hz band-limited broadband disturbance, 50 Hz: \"the disturbance is suppressed in all measurements\"",
        criterion: "the RMS of z at each of nodes 5–8 over the second half of the run reduced by at least 6 dB",
    },
    Statement {
        chapter: CH,
        id: "6.10",
        source: "§6.2.3, Figures 6.8–6.9",
        claim: "50 Hz band-limited broadband disturbance at 10 Hz: \"the broadband disturbance is suppressed in all \
                measurements despite aliased disturbances and spillover\"",
        criterion: "the RMS of the sampled z at each of nodes 5–8 over the second half of the run reduced by at least \
                    6 dB",
    },
];

const MOST_AT_7_8: [Statement; 2] = [
    Statement {
        chapter: CH,
        id: "6.2",
        source: "§6.2.1, Figures 6.2–6.3",
        claim: "harmonic: \"with the most suppression occurring on nodes 7 and 8\"",
        criterion: "the smaller reduction of nodes 7 and 8 exceeds the larger of nodes 5 and 6",
    },
    Statement {
        chapter: CH,
        id: "6.7",
        source: "§6.2.2, Figures 6.5–6.6",
        claim: "broadband: \"with the most suppression occurring on nodes 7 and 8\"",
        criterion: "the smaller reduction of nodes 7 and 8 exceeds the larger of nodes 5 and 6",
    },
];

const TONES: Statement = Statement {
    chapter: CH,
    id: "6.3",
    source: "Figure 6.3",
    claim: "\"Notice that the 3 peaks corresponding to the 3 sinusoidal disturbances are suppressed in closed-loop for \
            nodes 7 and 8.\"",
    criterion: "each tone's amplitude in z of node 8 (fitted over the second half of the run; the study fits node 8 \
                only) reduced by at least 6 dB",
};

/// The criterion of a convergence claim: node 8 converges within `$s` seconds (and, with
/// `node_8_only`, that the study times node 8 alone).
macro_rules! converges_within {
    ($s:literal) => {
        concat!(
            "node 8 converges (trailing 3 s RMS within twice its late level from then on) within ",
            $s,
            " s"
        )
    };
    ($s:literal, node_8_only) => {
        concat!(converges_within!($s), " (the study times node 8 only)")
    };
}

/// A convergence claim of the chapter: its `id`, `source`, `claim` and `criterion`.
const fn converges(
    id: &'static str,
    source: &'static str,
    claim: &'static str,
    criterion: &'static str,
) -> Statement {
    Statement {
        chapter: CH,
        id,
        source,
        claim,
        criterion,
    }
}

/// What Figure 6.2's caption says of the harmonic disturbance.
const HARMONIC_CONVERGES: &str = "harmonic: \"The closed-loop response converges within 10 s.\"";

/// What Figure 6.5's caption says of the 25 Hz broadband disturbance.
const BROADBAND_SUPPRESSED: &str = "broadband: \"the broadband disturbance is suppressed within 10 s \
                                    for nodes 5 and 6, and within 5 s for nodes 7 and 8\"";

/// What Figure 6.8's caption says of the aliased broadband disturbance.
const ALIASED_SUPPRESSED: &str = "aliasing: \"the broadband disturbance is suppressed within 15 s for \
                                  nodes 5 and 6, and within 10 s for nodes 7 and 8\"";

// A table: one claim a line.
#[rustfmt::skip]
const CONVERGES: [Statement; 3] = [
    converges("6.4", "Figure 6.2", HARMONIC_CONVERGES, converges_within!(10)),
    converges("6.8", "Figure 6.5", BROADBAND_SUPPRESSED, converges_within!(5, node_8_only)),
    converges("6.11", "Figure 6.8", ALIASED_SUPPRESSED, converges_within!(10, node_8_only)),
];

const IDENTIFICATION: Statement = Statement {
    chapter: CH,
    id: "6.5",
    source: "§6.2.1–6.2.3, Figures 6.4, 6.7, 6.10",
    claim: "\"the disturbance is suppressed before either ‖θ_k‖ or tr(P_k) converge\"; \"the identification \
            coefficients do not need to be converged for the disturbance to be suppressed\"",
    criterion: "in each of the three experiments node 8 converges (trailing 3 s RMS within twice its late level) \
                before both ‖θ_k‖ and tr(P_k) settle (stay within 10 % of their largest excursion from their \
                final value)",
};

const BROADBAND_PEAKS: Statement = Statement {
    chapter: CH,
    id: "6.9",
    source: "Figure 6.6",
    claim: "\"Notice that most of the peaks in the open-loop response of nodes 7 and 8 are suppressed in closed-loop.\"",
    criterion: "at each of nodes 7 and 8, more than half of the open-loop PSD peaks (Welch, late window; \
                topographic prominence at least 10 dB) reduced by at least 6 dB",
};

const TRANSIENT: Statement = Statement {
    chapter: CH,
    id: "6.12",
    source: "§6.2.3, Figure 6.8",
    claim: "\"Note also that the initial transient is larger than in the nonaliased case.\"",
    criterion: "peak |z| of node 8 in the closed loop over the first 10 s, over the open loop's peak over the same \
                seconds, larger in the aliased case than in the 25 Hz broadband case",
};

const IN_BAND_MODES: Statement = Statement {
    chapter: CH,
    id: "6.13",
    source: "Figure 6.9",
    claim: "\"Notice that the modes inside the control bandwidth are suppressed.\"",
    criterion: "each truss mode below the 5 Hz Nyquist frequency reduced by at least 6 dB in the PSD of z summed \
                over nodes 5–8 (late window)",
};

/// The figures of each claim, printed setting.
pub const FIGURES: crate::study::reproduction::Figures = &[
    ("6.1", &["figure-6.2-harmonic-printed-response.png"]),
    ("6.2", &["figure-6.2-harmonic-printed-response.png"]),
    ("6.3", &["figure-6.3-harmonic-printed-psd.png"]),
    ("6.4", &["figure-6.2-harmonic-printed-response.png"]),
    (
        "6.5",
        &[
            "figure-6.4-harmonic-printed-identification.png",
            "figure-6.7-broadband-25hz-printed-identification.png",
            "figure-6.10-broadband-50hz-aliasing-printed-identification.png",
        ],
    ),
    ("6.6", &["figure-6.5-broadband-25hz-printed-response.png"]),
    ("6.7", &["figure-6.5-broadband-25hz-printed-response.png"]),
    ("6.8", &["figure-6.5-broadband-25hz-printed-response.png"]),
    ("6.9", &["figure-6.6-broadband-25hz-printed-psd.png"]),
    (
        "6.10",
        &["figure-6.8-broadband-50hz-aliasing-printed-response.png"],
    ),
    (
        "6.11",
        &["figure-6.8-broadband-50hz-aliasing-printed-response.png"],
    ),
    (
        "6.12",
        &[
            "figure-6.8-broadband-50hz-aliasing-printed-response.png",
            "figure-6.5-broadband-25hz-printed-response.png",
        ],
    ),
    (
        "6.13",
        &["figure-6.9-broadband-50hz-aliasing-printed-psd.png"],
    ),
];

/// Node 7's index in `z`.
const NODE_7: usize = 2;

/// Claim 6.5 on the experiments run: when node 8 converges, and when ‖θ_k‖ and tr P_k
/// settle.
fn identification(outcomes: &[Outcome]) -> Claim {
    let mut parts = Vec::new();
    let mut all = true;
    for exp in Experiment::ALL {
        let Some((o, c)) = printed(outcomes, exp) else {
            return IDENTIFICATION.not_checked(not_run(exp));
        };
        let settles = |name: &str| {
            c.trace
                .internal_names
                .iter()
                .position(|n| n == name)
                .and_then(|i| settling_time(&c.trace.internals[i], o.ts, SETTLED_FRACTION))
        };
        let (Some(theta), Some(p)) = (settles("theta_norm"), settles("trace_p")) else {
            return IDENTIFICATION.not_checked(format!(
                "{}: ‖θ_k‖ or tr P_k not logged, or not finite",
                exp.name()
            ));
        };
        let first = c.converge.is_some_and(|t| t < theta.min(p));
        all &= first;
        parts.push(format!(
            "{}: node 8 {}, ‖θ‖ {theta:.1} s, tr P {p:.1} s",
            exp.name(),
            c.converge.map_or("never".into(), |t| format!("{t:.1} s"))
        ));
    }
    IDENTIFICATION.check(all, parts.join("; "))
}

/// Claim 6.9: the peaks of nodes 7 and 8 in the broadband case.
fn broadband_peaks(outcomes: &[Outcome]) -> Claim {
    let Some((o, c)) = printed(outcomes, Experiment::Broadband) else {
        return BROADBAND_PEAKS.not_checked(not_run(Experiment::Broadband));
    };
    let fs = 1.0 / o.ts;
    let mut parts = Vec::new();
    let mut most = true;
    for i in [NODE_7, NODE_8] {
        let (Ok(a), Ok(b)) = (
            late_psd(&o.open.z[i], o.late_start, fs),
            late_psd(&c.trace.z[i], o.late_start, fs),
        ) else {
            return BROADBAND_PEAKS.not_checked("the late window is too short for a PSD");
        };
        let peaks = peak_reductions(&a, &b);
        let reduced = peaks.iter().filter(|(_, db)| *db >= SUPPRESSED_DB).count();
        most &= 2 * reduced > peaks.len();
        parts.push(format!(
            "node {}: {reduced} of {} peaks reduced ({})",
            NODES[i],
            peaks.len(),
            peaks
                .iter()
                .map(|(f, db)| format!("{f:.2} Hz {db:.1} dB"))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    BROADBAND_PEAKS.check(most, parts.join("; "))
}

/// Claim 6.13: the in-band modes in the aliased case.
fn in_band_modes(outcomes: &[Outcome]) -> Claim {
    let Some((o, c)) = printed(outcomes, Experiment::Aliasing) else {
        return IN_BAND_MODES.not_checked(not_run(Experiment::Aliasing));
    };
    let fs = 1.0 / o.ts;
    let sum = |t: &[Vec<f64>]| {
        let psds: Result<Vec<_>, _> = t.iter().map(|z| late_psd(z, o.late_start, fs)).collect();
        psds.ok().and_then(|p| spectral::summed(&p))
    };
    let (Some(a), Some(b)) = (sum(&o.open.z), sum(&c.trace.z)) else {
        return IN_BAND_MODES.not_checked("the late window is too short for a PSD");
    };
    if o.in_band_modes.is_empty() {
        return IN_BAND_MODES
            .not_checked("the scenario has no truss mode below the Nyquist frequency");
    }
    let per_mode: Vec<(f64, f64)> = o
        .in_band_modes
        .iter()
        .map(|&f| (f, reduction_at(&a, &b, f)))
        .collect();
    IN_BAND_MODES.check(
        per_mode.iter().all(|(_, db)| *db >= SUPPRESSED_DB),
        per_mode
            .iter()
            .map(|(f, db)| format!("{f:.2} Hz mode {db:.1} dB"))
            .collect::<Vec<_>>()
            .join(", "),
    )
}

/// The time within which node 8 converges in `exp` by its caption: 10 s (harmonic,
/// Figure 6.2), 5 s (broadband, nodes 7 and 8, Figure 6.5), 10 s (aliasing, nodes 7 and 8,
/// Figure 6.8).
pub fn within_s(exp: Experiment) -> f64 {
    match exp {
        Experiment::Harmonic | Experiment::Aliasing => 10.0,
        Experiment::Broadband => 5.0,
    }
}

/// The printed setting's closed loop of `exp`, if run.
fn printed(outcomes: &[Outcome], exp: Experiment) -> Option<(&Outcome, &Closed)> {
    let o = outcomes.iter().find(|o| o.experiment == exp)?;
    let c = o.closed.iter().find(|c| c.setting == Setting::Printed)?;
    Some((o, c))
}

/// The reason a claim on `exp` is not checked.
fn not_run(exp: Experiment) -> String {
    format!(
        "{} with the printed setting was not run (--experiments/--settings)",
        exp.name()
    )
}

/// The reductions of nodes 5–8 as text.
fn reductions(o: &Outcome, c: &Closed) -> String {
    NODES
        .iter()
        .enumerate()
        .map(|(i, n)| format!("node {n} {:.1} dB", o.reduction(c, i)))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Peak `|x|` over the first `n` samples.
fn peak(x: &[f64], n: usize) -> f64 {
    x.iter().take(n).fold(0.0_f64, |a, v| {
        if v.is_finite() {
            a.max(v.abs())
        } else {
            f64::INFINITY
        }
    })
}

/// The initial transient of the module docs: closed-loop over open-loop peak of node 8.
pub fn transient_ratio(o: &Outcome, c: &Closed) -> f64 {
    let n = (TRANSIENT_S / o.ts).round() as usize;
    peak(&c.trace.z[NODE_8], n) / peak(&o.open.z[NODE_8], n)
}

/// The chapter's claims checked on `outcomes` (one per experiment run).
pub fn claims(outcomes: &[Outcome]) -> Vec<Claim> {
    use Experiment::{Aliasing, Broadband, Harmonic};
    let all_nodes = |st: &Statement, exp| match printed(outcomes, exp) {
        Some((o, c)) => st.check(
            (0..NODES.len()).all(|i| o.reduction(c, i) >= SUPPRESSED_DB),
            reductions(o, c),
        ),
        None => st.not_checked(not_run(exp)),
    };
    let most = |st: &Statement, exp| match printed(outcomes, exp) {
        Some((o, c)) => {
            let r = |i| o.reduction(c, i);
            st.check(r(2).min(r(3)) > r(0).max(r(1)), reductions(o, c))
        }
        None => st.not_checked(not_run(exp)),
    };
    let converges = |st: &Statement, exp: Experiment| match printed(outcomes, exp) {
        Some((o, c)) => {
            let within = within_s(exp);
            let reduced = o.reduction(c, NODE_8) >= SUPPRESSED_DB;
            let sens = super::sensitivity::earliest(&o.sensitivity, SUPPRESSED_DB)
                .map_or(String::new(), |e| {
                    format!("; the earliest under the choices §6.2 leaves open: {e}")
                });
            st.check(
                reduced && c.converge.is_some_and(|t| t <= within),
                format!(
                    "node 8 converges {} (reduced by {:.1} dB){sens}",
                    c.converge
                        .map_or("never".into(), |t| format!("at {t:.1} s")),
                    o.reduction(c, NODE_8)
                ),
            )
        }
        None => st.not_checked(not_run(exp)),
    };
    let mut out = vec![
        all_nodes(&ALL_NODES[0], Harmonic),
        most(&MOST_AT_7_8[0], Harmonic),
        match printed(outcomes, Harmonic) {
            Some((o, c)) => {
                let per_tone: Vec<(f64, f64)> = o
                    .tones
                    .iter()
                    .zip(&c.tone_amps)
                    .map(|((f, a), b)| (*f, control::tones::suppression_db(*a, *b)))
                    .collect();
                TONES.check(
                    !per_tone.is_empty() && per_tone.iter().all(|(_, db)| *db >= SUPPRESSED_DB),
                    per_tone
                        .iter()
                        .map(|(f, db)| format!("{f} Hz {db:.1} dB"))
                        .collect::<Vec<_>>()
                        .join(", "),
                )
            }
            None => TONES.not_checked(not_run(Harmonic)),
        },
        converges(&CONVERGES[0], Harmonic),
    ];
    out.push(identification(outcomes));
    out.push(all_nodes(&ALL_NODES[1], Broadband));
    out.push(most(&MOST_AT_7_8[1], Broadband));
    out.push(converges(&CONVERGES[1], Broadband));
    out.push(broadband_peaks(outcomes));
    out.push(all_nodes(&ALL_NODES[2], Aliasing));
    out.push(converges(&CONVERGES[2], Aliasing));
    out.push(
        match (printed(outcomes, Aliasing), printed(outcomes, Broadband)) {
            (Some((oa, ca)), Some((ob, cb))) => {
                let (a, b) = (transient_ratio(oa, ca), transient_ratio(ob, cb));
                TRANSIENT.check(
                    a > b,
                    format!("closed-over-open peak ratio: aliased {a:.2}, 25 Hz broadband {b:.2}"),
                )
            }
            _ => TRANSIENT.not_checked(
                "needs both broadband experiments with the printed setting (--experiments/--settings)",
            ),
        },
    );
    out.push(in_band_modes(outcomes));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::Trace;
    use crate::study::reproduction::Verdict;

    /// A trace of `n` samples at 0.1 s whose `z` (every node) is `first` for the first 10
    /// s, then two tones (1 and 3 Hz) of amplitude `late`; its ‖θ_k‖ and tr P_k ramp down
    /// to 1 and settle at 13.5 s.
    fn trace(first: f64, late: f64, n: usize) -> Trace {
        let z = (0..n)
            .map(|k| {
                let t = k as f64 * 0.1;
                let w = 2.0 * std::f64::consts::PI * t;
                if k < 100 {
                    first
                } else {
                    late * ((w * 1.0).sin() + 0.5 * (w * 3.0).sin())
                }
            })
            .collect();
        let ramp: Vec<f64> = (0..n)
            .map(|k| if k < 150 { 2.0 - k as f64 / 150.0 } else { 1.0 })
            .collect();
        Trace {
            sample_period: 0.1,
            z: vec![z; 4],
            internal_names: vec!["theta_norm".into(), "trace_p".into()],
            internals: vec![ramp.clone(), ramp],
            ..Trace::default()
        }
    }

    /// An outcome of `exp` whose printed closed loop has the late RMS `rms` per node
    /// (open loop 1), converges at `converge` and peaks at `first` in the first 10 s.
    fn outcome(exp: Experiment, rms: [f64; 4], converge: Option<f64>, first: f64) -> Outcome {
        Outcome {
            experiment: exp,
            ts: 0.1,
            open: trace(1.0, 1.0, 200),
            late_start: 100,
            rms_open: [1.0; 4],
            rms_y_open: 1.0,
            in_band_modes: vec![1.0],
            sensitivity: Vec::new(),
            tones: if exp == Experiment::Harmonic {
                vec![(1.0, 1.0), (2.0, 1.0)]
            } else {
                Vec::new()
            },
            closed: vec![Closed {
                setting: Setting::Printed,
                trace: trace(first, rms[3], 200),
                rms,
                tone_amps: vec![rms[3]; 2],
                converge,
                max_input: 10.0,
                counters: Default::default(),
                final_trace_p: 1.0,
                final_theta_norm: 1.0,
            }],
        }
    }

    fn verdicts(outcomes: &[Outcome]) -> Vec<(String, Verdict)> {
        claims(outcomes)
            .into_iter()
            .map(|c| (c.id, c.verdict))
            .collect()
    }

    #[test]
    fn the_verdicts_follow_the_reductions_the_times_and_the_transients() {
        use Verdict::{Fail, NotChecked, Pass};
        // -20 dB at nodes 5 and 6, -40 dB at 7 and 8, converged early; the aliased
        // transient larger.
        let good = [0.1, 0.1, 0.01, 0.01];
        let outcomes = [
            outcome(Experiment::Harmonic, good, Some(8.0), 2.0),
            outcome(Experiment::Broadband, good, Some(4.0), 2.0),
            outcome(Experiment::Aliasing, good, Some(9.0), 3.0),
        ];
        let v = verdicts(&outcomes);
        let expected = [
            ("6.1", Pass),
            ("6.2", Pass),
            ("6.3", Pass),
            ("6.4", Pass),
            ("6.5", Pass),
            ("6.6", Pass),
            ("6.7", Pass),
            ("6.8", Pass),
            ("6.9", Pass),
            ("6.10", Pass),
            ("6.11", Pass),
            ("6.12", Pass),
            ("6.13", Pass),
        ];
        assert_eq!(
            v,
            expected
                .iter()
                .map(|(i, v)| (i.to_string(), *v))
                .collect::<Vec<_>>()
        );
        // Node 5 barely reduced, node 6 most, late convergence (after ‖θ‖ and tr P settle),
        // smaller aliased transient; node 8's late z (the spectra) only 3 dB down.
        let bad = [0.8, 0.001, 0.01, 0.7];
        let outcomes = [
            outcome(Experiment::Harmonic, bad, Some(20.0), 2.0),
            outcome(Experiment::Broadband, bad, None, 2.0),
            outcome(Experiment::Aliasing, bad, Some(11.0), 1.5),
        ];
        let failed: Vec<String> = verdicts(&outcomes)
            .into_iter()
            .filter(|(_, v)| *v == Fail)
            .map(|(id, _)| id)
            .collect();
        assert_eq!(
            failed,
            [
                "6.1", "6.2", "6.3", "6.4", "6.5", "6.6", "6.7", "6.8", "6.9", "6.10", "6.11",
                "6.12", "6.13"
            ]
        );
        // Only the harmonic experiment: the others' claims are not checked.
        let v = verdicts(&[outcome(Experiment::Harmonic, good, Some(8.0), 2.0)]);
        assert!(v[5..].iter().all(|(_, v)| *v == NotChecked), "{v:?}");
    }
}
