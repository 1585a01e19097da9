//! The claims of chapter 7 (§7.3) in the reproduction's record, checked on the results of
//! `study sampling-arm` ([`crate::study::arm`]): each with the dissertation's words,
//! where it says them, and a criterion that can fail.
//!
//! "Reaches 25 N" is read as: the median contact force over the contact phase within
//! `F_d (1 ± 5 %)` = [23.75, 26.25] N ([`BAND`]); a failed run never reaches it.

use crate::study::arm::closed_loop::{BAND, ContactStats, F_D, Law, Model};
use crate::study::arm::grid::GridPoint;
use crate::study::reproduction::{Claim, Statement};

/// The chapter.
const CH: u8 = 7;

/// Claim 7.5's region of "low stiffness combined with a high coefficient of restitution".
pub const HC_EXCLUDED: (f64, f64) = (3.0e3, 0.5);

/// Claim 7.8: the samples after the second contact's onset within which `λ_k` must drop
/// below 1 ("immediately": 50 ms at 2 kHz).
pub const LAMBDA_WINDOW: usize = 100;

/// Claim 7.8: the samples after the second onset over which `tr P_k` must rise (0.5 s).
pub const TRACE_WINDOW: usize = 1000;

/// The statements of the claims, in order.
pub const STATEMENTS: [Statement; 8] = [
    Statement {
        chapter: CH,
        id: "7.1",
        source: "§7.3.1, Figure 7.3",
        claim: "\"the augmented controller consistently reaches the desired contact force for all tested surface properties\" (linear model)",
        criterion: "linear grid, augmented: every run completes and its median contact force is within 25 N ± 5 %",
    },
    Statement {
        chapter: CH,
        id: "7.2",
        source: "§7.3.1, Figure 7.3",
        claim: "\"the nominal robust controller has difficulty reaching the desired contact force for low surface stiffness coefficients\"",
        criterion: "linear grid at the lowest stiffness k_s = 300 N/m: for every c_s the robust median is outside 25 N ± 5 % and below the augmented median",
    },
    Statement {
        chapter: CH,
        id: "7.3",
        source: "§7.3.1, Figure 7.4 (k_s = 2e5 N/m, c_s = 5 N s/m)",
        claim: "\"the PCAC augmented controller quickly reaches the desired contact force while the nominal robust controller on its own takes most of the 2 second contact period\"",
        criterion: "settling time into 25 N ± 5 % (to the end of the phase): augmented ≤ 0.5 s and robust ≥ 1.0 s",
    },
    Statement {
        chapter: CH,
        id: "7.4",
        source: "§7.3.2, Figure 7.5",
        claim: "\"the nominal robust controller's median contact force has difficulty reaching even half of the desired 25 N\" (Hunt–Crossley)",
        criterion: "Hunt–Crossley grid, robust: every median contact force below 12.5 N",
    },
    Statement {
        chapter: CH,
        id: "7.5",
        source: "§7.3.2, Figure 7.5",
        claim: "\"the augmented controller consistently reaches the desired contact force for all tested surface properties except for situations where there is low stiffness combined with a high coefficient of restitution\"",
        criterion: "Hunt–Crossley grid, augmented: median within 25 N ± 5 % at every point outside the region k_s < 3e3 and c_r > 0.5",
    },
    Statement {
        chapter: CH,
        id: "7.6",
        source: "§7.3.2, Figure 7.6 (k_s = 2e5, c_r = 0.9)",
        claim: "\"the PCAC augmented controller quickly reaches the desired contact force while the nominal robust controller never does\"",
        criterion: "augmented median within 25 N ± 5 % and settled within 0.5 s; robust never settles into 25 N ± 5 % before the phase ends",
    },
    Statement {
        chapter: CH,
        id: "7.7",
        source: "§7.3.3–7.3.4, Figures 7.7–7.8",
        claim: "\"the desired contact force is reached for both maneuvers\" (augmented controller, linear and Hunt–Crossley double maneuvers)",
        criterion: "both double maneuvers, augmented: two contact phases, each with its median contact force within 25 N ± 5 %",
    },
    Statement {
        chapter: CH,
        id: "7.8",
        source: "§7.3.3–7.3.4, Figures 7.7–7.8",
        claim: "\"on contact with the new surface at 8 s the RLS VRF factor λ_k automatically decreases … causing an increase in the trace of the RLS covariance tr(P_k)\"",
        criterion: "both double maneuvers: λ_k < 1 within 100 samples (50 ms) of the second contact phase's first sample, and the largest tr P_k over its first 0.5 s above 1.1 × tr P_k at its first sample",
    },
];

/// One double maneuver's evidence: its name, the augmented run's contact phases, its
/// `λ_k` and `tr P_k` per sample.
#[derive(Debug, Clone)]
pub struct DoubleEvidence<'a> {
    /// The figure's name.
    pub name: &'a str,
    /// The augmented run's contact phases.
    pub contacts: Vec<ContactStats>,
    /// `λ_k`.
    pub lambda: &'a [f64],
    /// `tr P_k`.
    pub trace_p: &'a [f64],
}

/// What the claims are checked on.
#[derive(Debug, Clone)]
pub struct Evidence<'a> {
    /// Every grid point (both models, both laws).
    pub grid: &'a [GridPoint],
    /// Figure 7.4's settling times `(robust, augmented)`, s.
    pub fig_7_4: (ContactStats, ContactStats),
    /// Figure 7.6's contact statistics `(robust, augmented)`.
    pub fig_7_6: (ContactStats, ContactStats),
    /// Per double maneuver.
    pub doubles: Vec<DoubleEvidence<'a>>,
}

/// True when `m` is within `F_d (1 ± BAND)`.
pub fn reaches(m: f64) -> bool {
    reaches_within(m, BAND)
}

/// True when `m` is within `F_d (1 ± band)`.
pub fn reaches_within(m: f64, band: f64) -> bool {
    (m - F_D).abs() <= band * F_D
}

fn pts(g: &[GridPoint], model: Model, law: Law) -> Vec<&GridPoint> {
    g.iter()
        .filter(|p| p.model == model && p.law == law)
        .collect()
}

fn fmt_pt(p: &GridPoint) -> String {
    format!(
        "(k_s {:.3e}, {} {:.3e}): {}",
        p.k_s,
        p.model.second(),
        p.c,
        if p.failed() {
            "failed".to_string()
        } else {
            format!("{:.2} N", p.median)
        }
    )
}

fn range(v: &[&GridPoint]) -> String {
    let m: Vec<f64> = v.iter().filter(|p| !p.failed()).map(|p| p.median).collect();
    let lo = m.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = m.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    format!(
        "medians {lo:.2}–{hi:.2} N over {} runs, {} failed",
        v.len(),
        v.len() - m.len()
    )
}

/// The figures of each claim (Figures 7.3–7.8).
pub const FIGURES: crate::study::reproduction::Figures = &[
    ("7.1", &["fig7_3_robust.png", "fig7_3_augmented.png"]),
    ("7.2", &["fig7_3_robust.png", "fig7_3_augmented.png"]),
    ("7.3", &["fig7_4.png"]),
    ("7.4", &["fig7_5_robust.png"]),
    ("7.5", &["fig7_5_augmented.png"]),
    ("7.6", &["fig7_6.png"]),
    ("7.7", &["fig7_7.png", "fig7_8.png"]),
    ("7.8", &["fig7_7.png", "fig7_8.png"]),
];

/// The claims checked on `e`.
pub fn claims(e: &Evidence<'_>) -> Vec<Claim> {
    claims_in_band(e, BAND)
}

/// The claims checked on `e`, "reaches 25 N" read as a median within `F_d (1 ± band)`
/// (the settling times of `e` are the caller's, in the same band).
pub fn claims_in_band(e: &Evidence<'_>, band: f64) -> Vec<Claim> {
    let reaches = |m: f64| reaches_within(m, band);
    let s = &STATEMENTS;
    let mut out = Vec::new();
    // 7.1
    let aug = pts(e.grid, Model::Linear, Law::Augmented);
    let miss: Vec<&&GridPoint> = aug
        .iter()
        .filter(|p| p.failed() || !reaches(p.median))
        .collect();
    out.push(s[0].check(
        miss.is_empty() && !aug.is_empty(),
        format!(
            "{}; {} of {} outside 25 N ± 5 %{}",
            range(&aug),
            miss.len(),
            aug.len(),
            miss.iter().take(4).map(|p| format!("; {}", fmt_pt(p))).collect::<String>()
        ),
    ));
    // 7.2
    let rob = pts(e.grid, Model::Linear, Law::Robust);
    let k0 = rob.iter().map(|p| p.k_s).fold(f64::INFINITY, f64::min);
    let low: Vec<(&&GridPoint, Option<&&GridPoint>)> = rob
        .iter()
        .filter(|p| p.k_s == k0)
        .map(|p| (p, aug.iter().find(|a| a.k_s == p.k_s && a.c == p.c)))
        .collect();
    let ok = !low.is_empty()
        && low.iter().all(|(r, a)| {
            (r.failed() || !reaches(r.median))
                && a.is_some_and(|a| !a.failed() && (r.failed() || r.median < a.median))
        });
    out.push(s[1].check(
        ok,
        format!(
            "at k_s = {k0:.3e}: robust {}",
            low.iter()
                .map(|(r, a)| format!(
                    "{} (augmented {})",
                    fmt_pt(r),
                    a.map_or("-".into(), |a| format!("{:.2} N", a.median))
                ))
                .collect::<Vec<_>>()
                .join("; ")
        ),
    ));
    // 7.3
    let (r, a) = e.fig_7_4;
    out.push(s[2].check(
        a.settling <= 0.5 && r.settling >= 1.0,
        format!(
            "settling: augmented {:.3} s (median {:.2} N), robust {:.3} s (median {:.2} N)",
            a.settling, a.median, r.settling, r.median
        ),
    ));
    // 7.4
    let hc_rob = pts(e.grid, Model::HuntCrossley, Law::Robust);
    let above: Vec<&&GridPoint> = hc_rob
        .iter()
        .filter(|p| p.failed() || p.median >= 12.5)
        .collect();
    out.push(s[3].check(
        above.is_empty() && !hc_rob.is_empty(),
        format!(
            "{}; {} of {} at or above 12.5 N (or failed){}",
            range(&hc_rob),
            above.len(),
            hc_rob.len(),
            above.iter().take(4).map(|p| format!("; {}", fmt_pt(p))).collect::<String>()
        ),
    ));
    // 7.5
    let hc_aug = pts(e.grid, Model::HuntCrossley, Law::Augmented);
    let excluded = |p: &GridPoint| p.k_s < HC_EXCLUDED.0 && p.c > HC_EXCLUDED.1;
    let outside: Vec<&&GridPoint> = hc_aug.iter().filter(|p| !excluded(p)).collect();
    let miss: Vec<&&&GridPoint> = outside
        .iter()
        .filter(|p| p.failed() || !reaches(p.median))
        .collect();
    let inside: Vec<&&GridPoint> = hc_aug.iter().filter(|p| excluded(p)).collect();
    let inside_miss = inside
        .iter()
        .filter(|p| p.failed() || !reaches(p.median))
        .count();
    out.push(s[4].check(
        miss.is_empty() && !outside.is_empty(),
        format!(
            "outside the region: {} of {} miss{}; inside it: {} of {} miss",
            miss.len(),
            outside.len(),
            miss.iter().take(4).map(|p| format!("; {}", fmt_pt(p))).collect::<String>(),
            inside_miss,
            inside.len()
        ),
    ));
    // 7.6
    let (r, a) = e.fig_7_6;
    out.push(s[5].check(
        reaches(a.median) && a.settling <= 0.5 && r.settling.is_infinite(),
        format!(
            "augmented median {:.2} N, settling {:.3} s; robust median {:.2} N, settling {}",
            a.median,
            a.settling,
            r.median,
            if r.settling.is_finite() {
                format!("{:.3} s", r.settling)
            } else {
                "never".into()
            }
        ),
    ));
    // 7.7 and 7.8
    let mut ok7 = !e.doubles.is_empty();
    let mut ok8 = !e.doubles.is_empty();
    let mut ours7 = Vec::new();
    let mut ours8 = Vec::new();
    for d in &e.doubles {
        let (name, contacts, lambda, trace_p) = (d.name, &d.contacts, d.lambda, d.trace_p);
        let both = contacts.len() >= 2 && contacts.iter().take(2).all(|c| reaches(c.median));
        ok7 &= both;
        ours7.push(format!(
            "{name}: {} contact phase(s), medians {}",
            contacts.len(),
            contacts
                .iter()
                .map(|c| format!("{:.2} N", c.median))
                .collect::<Vec<_>>()
                .join(", ")
        ));
        match contacts.get(1) {
            Some(c) if c.first < lambda.len() => {
                let end = (c.first + LAMBDA_WINDOW).min(lambda.len());
                let drop = lambda[c.first..end].iter().position(|&l| l < 1.0);
                let lmin = lambda[c.first..end]
                    .iter()
                    .copied()
                    .fold(f64::INFINITY, f64::min);
                let p0 = trace_p[c.first];
                let tend = (c.first + TRACE_WINDOW).min(trace_p.len());
                let pmax = trace_p[c.first..tend]
                    .iter()
                    .copied()
                    .fold(f64::NEG_INFINITY, f64::max);
                let good = drop.is_some() && pmax > 1.1 * p0;
                ok8 &= good;
                ours8.push(format!(
                    "{name}: λ_k {} (min {lmin:.4} in the window), tr P_k {p0:.4e} at onset → max {pmax:.4e}",
                    drop.map_or("not below 1".to_string(), |k| format!("below 1 after {k} samples")),
                ));
            }
            _ => {
                ok8 = false;
                ours8.push(format!("{name}: no second contact phase"));
            }
        }
    }
    out.push(s[6].check(ok7, ours7.join("; ")));
    out.push(s[7].check(ok8, ours8.join("; ")));
    out
}
