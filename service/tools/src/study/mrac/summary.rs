//! The summary of `study mrac`: per example, command and method the median and worst
//! `log₁₀‖e‖` over the grid and the number of unstable points, then the chapter's claims
//! (§4.6–4.8) checked one by one against those numbers.
//!
//! # Statistics
//!
//! - **median**: the median of `log₁₀‖e‖` over all grid points, an unstable point
//!   counting as `+∞` (so the median is `+∞` when half the points or more are unstable);
//! - **worst**: the largest `log₁₀‖e‖` over the stable points;
//! - **unstable**: how many points diverged ([`crate::study::mrac::closed_loop`]);
//! - **θ̂ settles**: the median over all points of the step after which `θ̂_k` stays
//!   within 10 % of its largest excursion from `θ̂_200`
//!   ([`crate::study::mrac::theta_settling`]), an unstable point counting as `+∞`.
//!
//! # Claims
//!
//! 1. §4.8 "Unlike APPC, the performance of RC-MRAC is not as sensitive to the
//!    persistency of the desired command." Checked on Examples 1 and 2: the spread
//!    (largest minus smallest) of the median `log₁₀‖e‖` over the step, two- and
//!    four-harmonic commands is smaller for RC-MRAC than for APPC.
//! 2. §4.8 "For minimum-phase systems, RC-MRAC outperforms APPC without the need for
//!    persistency." Example 1: RC-MRAC's median is lower than APPC's for every command.
//! 3. §4.8 "For NMP systems, RC-MRAC performs better than APPC at lower persistency
//!    levels". Example 2: RC-MRAC's median is lower than APPC's for the step and the
//!    two-harmonic command (the four-harmonic command is not part of the claim).
//! 4. Figures 4.8a–4.10a (APPC on the NMP plant): "Empty squares represent regions where
//!    the system became unstable." Read on two readings of the figures' axes
//!    ([`crate::study::mrac::empty_squares`]): the grid inside the unit circle, and the
//!    outward grid with the patch around the zero ([`crate::study::mrac::outward`]). A
//!    reading reproduces the captions when, for each of the three commands, APPC
//!    diverges at one point at least and somewhere APPC diverges while RC-MRAC does not.
//!    PASS when a reading reproduces them (the numbers name which), FAIL when neither
//!    does (or only the inside reading was run and it does not).
//! 5. §4.8 "RC-MRAC was shown numerically to be stable over a wide range of systems"
//!    (the captions of Figures 4.5a–4.7a and 4.11a–4.14a mark no unstable region): no
//!    unstable point for RC-MRAC in any example and command run.
//! 6. §4.7 "the algorithm is able to perform the model-following task while rejecting the
//!    disturbance for all tested poles". Example 3: RC-MRAC with `n = 4`, `n_s = 3` has no
//!    unstable point and a median `log₁₀‖e‖` at least one decade below RC-MRAC with
//!    Example 1b's `n = 2`, `n_s = 1` on the same disturbed plant, which cannot model the
//!    harmonic.
//! 7. §4.5.1 and §4.6.1 (APPC): with the two-harmonic command "The overall
//!    model-following error is improved compared to the step command", with the four
//!    "Due to the increased persistency of the command, the model-following error is
//!    improved over both the step command and the two-harmonic command". Examples 1 and
//!    2: APPC's median falls from step to two to four harmonics.
//! 8. §4.6.2 (RC-MRAC on the NMP plant, Figures 4.11–4.13): "the convergence is much
//!    slower than in the minimum-phase case" (step, Figure 4.11; four harmonics, Figure
//!    4.13: "much slower"; two harmonics, Figure 4.12: "still slower"). Read on the
//!    controller's estimate as the b panels show it: RC-MRAC's median θ̂ settling step
//!    over the grid in Example 2 is at least twice Example 1's with the step and the
//!    four-harmonic command, and above it with the two-harmonic command. The earlier
//!    reading on (4.85) (median `log₁₀‖e‖` of Example 2 above Example 1's) is reported
//!    beside it, not judged.
//!
//! A claim whose runs were not all made (a narrower `--example` or `--command`) is
//! reported as not checked.

use std::fmt::Write as _;

use crate::study::mrac::empty_squares::Reading;
use crate::study::mrac::grid::Sweep;
use crate::study::mrac::setup::{CommandKind, Example, Method};

/// The statistics of one sweep.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepStats {
    /// The example.
    pub example: Example,
    /// The command.
    pub command: CommandKind,
    /// The method.
    pub method: Method,
    /// Median `log₁₀‖e‖`, unstable points counting as `+∞`.
    pub median: f64,
    /// Largest `log₁₀‖e‖` over the stable points (`-∞` when none is stable).
    pub worst: f64,
    /// Unstable points.
    pub unstable: usize,
    /// Grid points.
    pub points: usize,
    /// Median θ̂ settling step, unstable points counting as `+∞`.
    pub theta_settle: f64,
}

impl SweepStats {
    /// The statistics of `sweep`.
    pub fn of(sweep: &Sweep) -> Self {
        let mut logs: Vec<f64> = sweep
            .points
            .iter()
            .map(|p| {
                if p.unstable() {
                    f64::INFINITY
                } else {
                    p.e_norm.log10()
                }
            })
            .collect();
        logs.sort_by(f64::total_cmp);
        let median = crate::stats::median(&logs);
        let worst = logs
            .iter()
            .copied()
            .filter(|v| v.is_finite())
            .fold(f64::NEG_INFINITY, f64::max);
        let mut settle: Vec<f64> = sweep
            .points
            .iter()
            .map(|p| p.theta_settle.map_or(f64::INFINITY, |k| k as f64))
            .collect();
        settle.sort_by(f64::total_cmp);
        Self {
            example: sweep.example,
            command: sweep.command,
            method: sweep.method,
            median,
            worst,
            unstable: sweep.unstable(),
            points: sweep.points.len(),
            theta_settle: crate::stats::median(&settle),
        }
    }
}

/// The verdict on a claim.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// The numbers support it.
    Pass,
    /// They do not.
    Fail,
    /// Its runs were not made.
    NotChecked,
}

impl Verdict {
    fn word(self) -> &'static str {
        match self {
            Verdict::Pass => "PASS",
            Verdict::Fail => "FAIL",
            Verdict::NotChecked => "NOT CHECKED",
        }
    }

    fn from(ok: bool) -> Self {
        if ok { Verdict::Pass } else { Verdict::Fail }
    }
}

/// One claim of the chapter and its check.
#[derive(Debug, Clone, PartialEq)]
pub struct Claim {
    /// 1 … 8 (the module documentation).
    pub number: u8,
    /// The claim, short.
    pub statement: &'static str,
    /// The verdict.
    pub verdict: Verdict,
    /// The numbers behind it.
    pub numbers: String,
}

/// Finds the statistics of one sweep.
pub fn find(stats: &[SweepStats], e: Example, c: CommandKind, m: Method) -> Option<&SweepStats> {
    stats
        .iter()
        .find(|s| s.example == e && s.command == c && s.method == m)
}

/// `log₁₀` value for text: `inf` for `+∞`.
fn lg(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.2}")
    } else if v > 0.0 {
        "inf".into()
    } else {
        "-".into()
    }
}

/// The spread (largest minus smallest) of the medians of `method` over the three
/// commands on `example`, or `None` when a command is missing.
fn spread(stats: &[SweepStats], example: Example, method: Method) -> Option<(f64, String)> {
    let medians: Option<Vec<f64>> = CommandKind::ALL
        .iter()
        .map(|&c| find(stats, example, c, method).map(|s| s.median))
        .collect();
    let m = medians?;
    let hi = m.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let lo = m.iter().copied().fold(f64::INFINITY, f64::min);
    let spread = if hi.is_infinite() {
        f64::INFINITY
    } else {
        hi - lo
    };
    let text = format!(
        "{} medians {} (spread {})",
        method.label(example),
        m.iter().map(|v| lg(*v)).collect::<Vec<_>>().join("/"),
        lg(spread)
    );
    Some((spread, text))
}

/// Checks the eight claims against `stats`; claim 4 on the empty squares of the reading
/// inside the unit circle `inside` and, when it was run, the outward reading `outward`.
pub fn claims(
    stats: &[SweepStats],
    inside: Option<&Reading>,
    outward: Option<&Reading>,
) -> Vec<Claim> {
    let mut out = Vec::new();
    // 1: persistency sensitivity.
    {
        let mut ok = true;
        let mut parts = Vec::new();
        let mut checked = true;
        for ex in [Example::One, Example::Two] {
            match (
                spread(stats, ex, Method::Appc),
                spread(stats, ex, Method::RcMrac),
            ) {
                (Some((a, ta)), Some((r, tr))) => {
                    ok &= r < a;
                    parts.push(format!("Example {}: {tr} vs {ta}", ex.number()));
                }
                _ => checked = false,
            }
        }
        out.push(Claim {
            number: 1,
            statement: "RC-MRAC is less sensitive than APPC to the persistency of the command \
                        (spread of the median log10‖e‖ over step/two/four smaller, Examples 1 and 2)",
            verdict: if checked {
                Verdict::from(ok)
            } else {
                Verdict::NotChecked
            },
            numbers: parts.join("; "),
        });
    }
    // 2 and 3: RC-MRAC better than APPC on a set of commands.
    let better = |number, statement, example: Example, commands: &[CommandKind]| {
        let mut ok = true;
        let mut checked = true;
        let mut parts = Vec::new();
        for &c in commands {
            match (
                find(stats, example, c, Method::RcMrac),
                find(stats, example, c, Method::Appc),
            ) {
                (Some(r), Some(a)) => {
                    ok &= r.median < a.median;
                    parts.push(format!(
                        "{}: RC-MRAC {} vs APPC {}",
                        c.name(),
                        lg(r.median),
                        lg(a.median)
                    ));
                }
                _ => checked = false,
            }
        }
        Claim {
            number,
            statement,
            verdict: if checked {
                Verdict::from(ok)
            } else {
                Verdict::NotChecked
            },
            numbers: format!("median log10‖e‖, {}", parts.join(", ")),
        }
    };
    out.push(better(
        2,
        "minimum-phase plant (Example 1): RC-MRAC outperforms APPC for every command",
        Example::One,
        &CommandKind::ALL,
    ));
    out.push(better(
        3,
        "NMP plant (Example 2): RC-MRAC better than APPC at lower persistency (step, two harmonics)",
        Example::Two,
        &[CommandKind::Step, CommandKind::Two],
    ));
    // 4: APPC's empty squares on the NMP plant, on the readings run.
    out.push(empty_squares_claim(inside, outward));
    // 5: RC-MRAC stable everywhere.
    {
        let rc: Vec<&SweepStats> = stats
            .iter()
            .filter(|s| s.method == Method::RcMrac)
            .collect();
        let total: usize = rc.iter().map(|s| s.unstable).sum();
        let points: usize = rc.iter().map(|s| s.points).sum();
        out.push(Claim {
            number: 5,
            statement: "RC-MRAC is stable over the whole grid (every example and command run)",
            verdict: if rc.is_empty() {
                Verdict::NotChecked
            } else {
                Verdict::from(total == 0)
            },
            numbers: format!("RC-MRAC unstable points: {total} of {points}"),
        });
    }
    // 6: harmonic rejection.
    out.push(
        match (
            find(stats, Example::Three, CommandKind::Step, Method::RcMrac),
            find(stats, Example::Three, CommandKind::Step, Method::RcMracPlain),
        ) {
            (Some(r), Some(p)) => Claim {
                number: 6,
                statement: "Example 3: RC-MRAC (n=4, n_s=3) follows the step while rejecting the \
                            input harmonic (median ≥ 1 decade below n=2, n_s=1; no unstable point)",
                verdict: Verdict::from(r.unstable == 0 && r.median <= p.median - 1.0),
                numbers: format!(
                    "median log10‖e‖ n=4: {} (worst {}, unstable {}/{}) vs n=2: {} (worst {}, unstable {}/{})",
                    lg(r.median),
                    lg(r.worst),
                    r.unstable,
                    r.points,
                    lg(p.median),
                    lg(p.worst),
                    p.unstable,
                    p.points
                ),
            },
            _ => Claim {
                number: 6,
                statement: "Example 3: RC-MRAC (n=4, n_s=3) rejects the input harmonic",
                verdict: Verdict::NotChecked,
                numbers: String::new(),
            },
        },
    );
    // 7: APPC improves with persistency.
    {
        let mut ok = true;
        let mut checked = true;
        let mut parts = Vec::new();
        for ex in [Example::One, Example::Two] {
            let m: Option<Vec<f64>> = CommandKind::ALL
                .iter()
                .map(|&c| find(stats, ex, c, Method::Appc).map(|s| s.median))
                .collect();
            match m {
                Some(m) => {
                    ok &= m[0] > m[1] && m[1] > m[2];
                    parts.push(format!(
                        "Example {}: {}",
                        ex.number(),
                        m.iter().map(|v| lg(*v)).collect::<Vec<_>>().join(" > ")
                    ));
                }
                None => checked = false,
            }
        }
        out.push(Claim {
            number: 7,
            statement: "APPC's error falls as the command's persistency rises (median step > two > four, Examples 1 and 2)",
            verdict: if checked {
                Verdict::from(ok)
            } else {
                Verdict::NotChecked
            },
            numbers: format!("APPC median log10‖e‖, {}", parts.join("; ")),
        });
    }
    // 8: RC-MRAC's θ̂ settles more slowly on the NMP plant.
    out.push(slower_convergence_claim(stats));
    out
}

/// Claim 4 (module documentation): PASS when one reading reproduces the empty squares.
fn empty_squares_claim(inside: Option<&Reading>, outward: Option<&Reading>) -> Claim {
    let statement = "NMP plant (Example 2), APPC: empty squares (unstable points where RC-MRAC is \
                     stable) with every command (Figures 4.8a–4.10a), inside the unit circle or \
                     on the outward grid";
    let Some(inside) = inside.filter(|r| r.complete()) else {
        return Claim {
            number: 4,
            statement,
            verdict: Verdict::NotChecked,
            numbers: String::new(),
        };
    };
    let mut parts = vec![format!(
        "{} ({})",
        inside.text(),
        if inside.reproduces() {
            "reproduces"
        } else {
            "does not reproduce"
        }
    )];
    match outward {
        Some(o) => parts.push(format!(
            "{} ({})",
            o.text(),
            if o.reproduces() {
                "reproduces"
            } else {
                "does not reproduce"
            }
        )),
        None => parts.push("outward reading not run".into()),
    }
    let used = [Some(inside), outward]
        .into_iter()
        .flatten()
        .find(|r| r.reproduces());
    parts.push(match used {
        Some(r) => format!("verdict read on: {}", r.name),
        None => "neither reading reproduces the empty squares".into(),
    });
    Claim {
        number: 4,
        statement,
        verdict: Verdict::from(used.is_some()),
        numbers: parts.join("; "),
    }
}

/// How much slower claim 8 wants Example 2's θ̂ to settle than Example 1's: twice with
/// the step and four harmonics ("much slower"), at all with two ("still slower").
pub fn slower_by(command: CommandKind) -> f64 {
    match command {
        CommandKind::Two => 1.0,
        CommandKind::Step | CommandKind::Four => 2.0,
    }
}

/// Claim 8's test of one command: Example 2's measure `nmp` is at least [`slower_by`]
/// times Example 1's `mp` (above it when the factor is 1), `mp` finite.
pub fn is_slower(nmp: f64, mp: f64, command: CommandKind) -> bool {
    let factor = slower_by(command);
    mp.is_finite()
        && if factor > 1.0 {
            nmp >= factor * mp
        } else {
            nmp > mp
        }
}

/// Claim 8 (module documentation), on the θ̂ settling step; the (4.85) reading beside it.
fn slower_convergence_claim(stats: &[SweepStats]) -> Claim {
    let mut ok = true;
    let mut checked = true;
    let mut settle = Vec::new();
    let mut error = Vec::new();
    for c in CommandKind::ALL {
        match (
            find(stats, Example::Two, c, Method::RcMrac),
            find(stats, Example::One, c, Method::RcMrac),
        ) {
            (Some(n), Some(m)) => {
                let factor = slower_by(c);
                ok &= is_slower(n.theta_settle, m.theta_settle, c);
                let ratio = if m.theta_settle > 0.0 {
                    format!("{:.2}", n.theta_settle / m.theta_settle)
                } else {
                    "-".into()
                };
                settle.push(format!(
                    "{}: Example 2 {} vs Example 1 {} (ratio {ratio}, wanted {} {factor})",
                    c.name(),
                    n.theta_settle,
                    m.theta_settle,
                    if factor > 1.0 { "≥" } else { ">" }
                ));
                error.push(format!(
                    "{}: Example 2 {} vs Example 1 {}",
                    c.name(),
                    lg(n.median),
                    lg(m.median)
                ));
            }
            _ => checked = false,
        }
    }
    Claim {
        number: 8,
        statement: "RC-MRAC's estimate θ̂ converges more slowly on the NMP plant than on the \
                    minimum-phase one (median θ̂ settling step of Example 2 at least twice \
                    Example 1's with step and four harmonics, above it with two)",
        verdict: if checked {
            Verdict::from(ok)
        } else {
            Verdict::NotChecked
        },
        numbers: format!(
            "RC-MRAC median θ̂ settling step (within 10 % of its largest excursion from θ̂_200), {}; \
             not judged, median log10‖e‖ (4.85), {}",
            settle.join(", "),
            error.join(", ")
        ),
    }
}

/// The summary as Markdown: the table, then the claims.
pub fn render_markdown(stats: &[SweepStats], claims: &[Claim], preamble: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "{preamble}");
    let _ = writeln!(
        s,
        "| example | command | method | median log10‖e‖ | worst log10‖e‖ (stable) | unstable | median θ̂ settling step |"
    );
    let _ = writeln!(s, "| --- | --- | --- | --- | --- | --- | --- |");
    for st in stats {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {}/{} | {} |",
            st.example.number(),
            st.command.label(),
            st.method.label(st.example),
            lg(st.median),
            lg(st.worst),
            st.unstable,
            st.points,
            st.theta_settle
        );
    }
    let _ = writeln!(s, "\nThe chapter's claims:\n");
    for c in claims {
        let _ = writeln!(
            s,
            "{}. **{}** {}: {}.",
            c.number,
            c.verdict.word(),
            c.statement,
            c.numbers
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::mrac::closed_loop::Divergence;
    use crate::study::mrac::grid::GridPoint;

    fn sweep(example: Example, command: CommandKind, method: Method, norms: &[f64]) -> Sweep {
        settled(example, command, method, norms, 10)
    }

    /// As `sweep`, every stable point's θ̂ settling at `settle`.
    fn settled(
        example: Example,
        command: CommandKind,
        method: Method,
        norms: &[f64],
        settle: usize,
    ) -> Sweep {
        Sweep {
            example,
            command,
            method,
            points: norms
                .iter()
                .map(|&e| GridPoint {
                    rho: 0.5,
                    nu: 1.0,
                    e_norm: e,
                    diverged: e.is_infinite().then_some((Divergence::Large, 50)),
                    peak_y: 1.0,
                    theta_settle: (!e.is_infinite()).then_some(settle),
                })
                .collect(),
        }
    }

    #[test]
    fn the_median_counts_unstable_points_as_infinite_and_the_worst_ignores_them() {
        let s = SweepStats::of(&sweep(
            Example::Two,
            CommandKind::Step,
            Method::Appc,
            &[1e-3, 1e-1, f64::INFINITY, 10.0, f64::INFINITY],
        ));
        assert_eq!(s.unstable, 2);
        assert!((s.median - 1.0).abs() < 1e-12, "{}", s.median);
        assert!((s.worst - 1.0).abs() < 1e-12);
        let s = SweepStats::of(&sweep(
            Example::Two,
            CommandKind::Step,
            Method::Appc,
            &[f64::INFINITY, f64::INFINITY],
        ));
        assert_eq!(s.median, f64::INFINITY);
        assert_eq!(s.worst, f64::NEG_INFINITY);
        assert_eq!(s.theta_settle, f64::INFINITY);
    }

    #[test]
    fn claim_8_reads_the_settling_of_theta_with_the_wanted_factor_per_command() {
        // Example 1 settles at 10; Example 2 at `slow` with the step and four harmonics,
        // at `two` with two harmonics. The error is the same in both (not judged).
        let verdict = |slow: usize, two: usize| {
            let mut sweeps = Vec::new();
            for c in CommandKind::ALL {
                let s2 = if c == CommandKind::Two { two } else { slow };
                sweeps.push(settled(Example::One, c, Method::RcMrac, &[1e-6], 10));
                sweeps.push(settled(Example::Two, c, Method::RcMrac, &[1e-6], s2));
            }
            let stats: Vec<SweepStats> = sweeps.iter().map(SweepStats::of).collect();
            claims(&stats, None, None).remove(7)
        };
        assert_eq!(verdict(20, 11).verdict, Verdict::Pass);
        assert_eq!(verdict(19, 11).verdict, Verdict::Fail); // not twice with the step
        assert_eq!(verdict(20, 10).verdict, Verdict::Fail); // not slower with two
        assert_eq!(verdict(5, 5).verdict, Verdict::Fail);
        let c = verdict(20, 11);
        assert!(
            c.numbers
                .contains("step: Example 2 20 vs Example 1 10 (ratio 2.00, wanted ≥ 2)")
                && c.numbers
                    .contains("median log10‖e‖ (4.85), step: Example 2 -6.00"),
            "{}",
            c.numbers
        );
    }

    #[test]
    fn claim_4_passes_on_the_reading_that_shows_appc_alone_unstable_and_names_it() {
        // Example 2, every command, on the poles ρ = 0.5 (inside) and 1.5 (outward).
        let on = |rho: f64, appc_unstable: bool| -> Reading {
            let mut sw = Vec::new();
            for c in CommandKind::ALL {
                let mut a = sweep(Example::Two, c, Method::Appc, &[0.1]);
                let r = sweep(Example::Two, c, Method::RcMrac, &[0.1]);
                a.points[0].rho = rho;
                if appc_unstable {
                    a.points[0].diverged = Some((Divergence::Large, 30));
                }
                let mut r = r;
                r.points[0].rho = rho;
                sw.push((a, r));
            }
            let pairs: Vec<(&Sweep, &Sweep)> = sw.iter().map(|(a, r)| (a, r)).collect();
            Reading::of(if rho < 1.0 { "inside" } else { "outward" }, &pairs).expect("pairs")
        };
        let inside = on(0.5, false);
        let c = empty_squares_claim(Some(&inside), Some(&on(1.5, true)));
        assert_eq!(c.verdict, Verdict::Pass);
        assert!(
            c.numbers.ends_with("verdict read on: outward"),
            "{}",
            c.numbers
        );
        let c = empty_squares_claim(Some(&inside), Some(&on(1.5, false)));
        assert_eq!(c.verdict, Verdict::Fail);
        assert!(
            c.numbers.contains("inside: APPC unstable step 0/1"),
            "{}",
            c.numbers
        );
        assert!(
            c.numbers
                .contains("outward: APPC unstable step 0/1 (0 of 1 with ρ ≥ 1)")
        );
        assert!(
            c.numbers
                .ends_with("neither reading reproduces the empty squares")
        );
        let c = empty_squares_claim(Some(&inside), None);
        assert_eq!(c.verdict, Verdict::Fail);
        assert!(c.numbers.contains("outward reading not run"));
        assert_eq!(empty_squares_claim(None, None).verdict, Verdict::NotChecked);
    }

    #[test]
    fn the_claims_follow_the_numbers_and_missing_runs_are_not_checked() {
        let mut sweeps = Vec::new();
        for ex in [Example::One, Example::Two] {
            for (i, c) in CommandKind::ALL.into_iter().enumerate() {
                // APPC improves with persistency, RC-MRAC does not change.
                sweeps.push(sweep(ex, c, Method::Appc, &[10f64.powi(-(i as i32))]));
                sweeps.push(sweep(ex, c, Method::RcMrac, &[1e-4]));
            }
        }
        let stats: Vec<SweepStats> = sweeps.iter().map(SweepStats::of).collect();
        let c = claims(&stats, None, None);
        let v: Vec<Verdict> = c.iter().map(|c| c.verdict).collect();
        assert_eq!(
            v,
            [
                Verdict::Pass,
                Verdict::Pass,
                Verdict::Pass,
                Verdict::NotChecked, // no reading of the empty squares
                Verdict::Pass,
                Verdict::NotChecked, // no Example 3
                Verdict::Pass,
                Verdict::Fail, // θ̂ settles at the same step in both examples
            ]
        );
        assert!(c[0].numbers.contains("spread 2.00"), "{}", c[0].numbers);
        let text = render_markdown(&stats, &c, "");
        assert!(
            text.contains("| 1 | unit step | APPC | 0.00 | 0.00 | 0/1 | 10 |"),
            "{text}"
        );
        assert!(text.contains("6. **NOT CHECKED**"));
    }
}
