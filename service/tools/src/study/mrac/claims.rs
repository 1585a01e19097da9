//! The claims of chapter 4 (§4.5–4.8) in the reproduction's record: the eight claims
//! [`crate::study::mrac::summary`] checks on the grid statistics of `study mrac`, each with
//! the dissertation's words, where it says them, and the criterion.

use crate::study::mrac::summary::{self, Verdict as MracVerdict};
use crate::study::reproduction::{Claim, Statement};

/// The chapter.
const CH: u8 = 4;

/// The statements of claims 1 … 8 of [`summary`], in order.
const STATEMENTS: [Statement; 8] = [
    Statement {
        chapter: CH,
        id: "4.1",
        source: "§4.8",
        claim: "\"Unlike APPC, the performance of RC-MRAC is not as sensitive to the persistency of the desired command.\"",
        criterion: "Examples 1 and 2: the spread (largest − smallest) over the step, two- and four-harmonic commands of \
                    the median log10‖e‖ (4.85) over the pole grid is smaller for RC-MRAC than for APPC",
    },
    Statement {
        chapter: CH,
        id: "4.2",
        source: "§4.8",
        claim: "\"For minimum-phase systems, RC-MRAC outperforms APPC without the need for persistency.\"",
        criterion: "Example 1: RC-MRAC's median log10‖e‖ over the grid is below APPC's for every command",
    },
    Statement {
        chapter: CH,
        id: "4.3",
        source: "§4.8",
        claim: "\"For NMP systems, RC-MRAC performs better than APPC at lower persistency levels\"",
        criterion: "Example 2: RC-MRAC's median log10‖e‖ is below APPC's for the step and the two-harmonic command",
    },
    Statement {
        chapter: CH,
        id: "4.4",
        source: "Figures 4.8a–4.10a (APPC, NMP plant)",
        claim: "\"Empty squares represent regions where the system became unstable.\"",
        criterion: "Example 2, on one of two readings of the figures' axes (the grid inside the unit circle; the \
                    outward grid to rho = 2 with a fine patch around the zero 1.5): with each of the step, two- and \
                    four-harmonic commands APPC diverges (y or u not finite, |y| > 1e6, or a controller fault) at one \
                    point at least, and at one point at least APPC diverges while RC-MRAC does not; the numbers say \
                    which reading the verdict was read on",
    },
    Statement {
        chapter: CH,
        id: "4.5",
        source: "§4.8; Figures 4.5a–4.7a, 4.11a–4.14a",
        claim: "\"RC-MRAC was shown numerically to be stable over a wide range of systems.\"",
        criterion: "no RC-MRAC grid point diverges in any example and command run",
    },
    Statement {
        chapter: CH,
        id: "4.6",
        source: "§4.7, Figure 4.14",
        claim: "\"the algorithm is able to perform the model-following task while rejecting the disturbance for all \
                tested poles\"",
        criterion: "Example 3: RC-MRAC with n = 4, n_s = 3 has no unstable point and a median log10‖e‖ at least one \
                    decade below RC-MRAC with n = 2, n_s = 1 (which cannot model the harmonic)",
    },
    Statement {
        chapter: CH,
        id: "4.7",
        source: "§4.5.1, §4.6.1 (APPC; Figures 4.2a–4.4a, 4.8a–4.10a)",
        claim: "two harmonics: \"The overall model-following error is improved compared to the step command\"; four: \
                \"the model-following error is improved over both the step command and the two-harmonic command\"",
        criterion: "Examples 1 and 2: APPC's median log10‖e‖ falls from the step to two to four harmonics",
    },
    Statement {
        chapter: CH,
        id: "4.8",
        source: "§4.6.2 (RC-MRAC, NMP plant; Figures 4.11–4.13)",
        claim: "\"the convergence is much slower than in the minimum-phase case\"",
        criterion: "read on the controller's estimate as the theta panels show it: per grid point the settling step \
                    is the first step k after which ‖θ̂_j − θ̂_200‖ stays within 10 % of its largest value over \
                    j = 0…200; RC-MRAC's median settling step over the grid (an unstable point counting as never) in \
                    Example 2 is at least twice Example 1's with the step and the four-harmonic command (\"much \
                    slower\") and above it with the two-harmonic command (\"still slower\"); the earlier reading on \
                    (4.85), median log10‖e‖ over steps 101–200, is reported beside it, not judged",
    },
];

/// The figures of each claim (the maps of `log10‖e‖` over the pole grid; the step
/// command where one command stands for all).
pub const FIGURES: crate::study::reproduction::Figures = &[
    (
        "4.1",
        &[
            "map-ex1-step-appc.png",
            "map-ex1-step-rc-mrac.png",
            "map-ex1-four-appc.png",
            "map-ex1-four-rc-mrac.png",
        ],
    ),
    (
        "4.2",
        &["map-ex1-step-appc.png", "map-ex1-step-rc-mrac.png"],
    ),
    (
        "4.3",
        &["map-ex2-step-appc.png", "map-ex2-step-rc-mrac.png"],
    ),
    (
        "4.4",
        &[
            "map-ex2-step-appc.png",
            "map-ex2-two-appc.png",
            "map-ex2-four-appc.png",
            "map-outward-ex2-step-appc.png",
            "map-outward-ex2-step-rc-mrac.png",
        ],
    ),
    (
        "4.5",
        &[
            "map-ex1-step-rc-mrac.png",
            "map-ex2-step-rc-mrac.png",
            "map-ex3-step-rc-mrac.png",
        ],
    ),
    (
        "4.6",
        &["map-ex3-step-rc-mrac.png", "map-ex3-step-rc-mrac-n2.png"],
    ),
    (
        "4.7",
        &[
            "map-ex1-step-appc.png",
            "map-ex1-two-appc.png",
            "map-ex1-four-appc.png",
        ],
    ),
    (
        "4.8",
        &["single-ex1-step-rc-mrac.png", "single-ex2-step-rc-mrac.png"],
    ),
];

/// The claims of [`summary::claims`] in the reproduction's record.
pub fn claims(checked: &[summary::Claim]) -> Vec<Claim> {
    checked
        .iter()
        .filter_map(|c| {
            let s = STATEMENTS.get(usize::from(c.number).checked_sub(1)?)?;
            Some(match c.verdict {
                MracVerdict::Pass => s.check(true, c.numbers.clone()),
                MracVerdict::Fail => s.check(false, c.numbers.clone()),
                MracVerdict::NotChecked => s.not_checked_with(
                    "its runs were not all made (a narrower --example or --command)",
                    c.numbers.clone(),
                ),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::reproduction::Verdict;

    #[test]
    fn each_checked_claim_keeps_its_verdict_and_numbers_under_the_chapters_words() {
        let checked: Vec<summary::Claim> = [
            (1, MracVerdict::Pass),
            (4, MracVerdict::Fail),
            (6, MracVerdict::NotChecked),
        ]
        .into_iter()
        .map(|(number, verdict)| summary::Claim {
            number,
            statement: "short",
            verdict,
            numbers: format!("numbers of {number}"),
        })
        .collect();
        let c = claims(&checked);
        let got: Vec<(&str, Verdict, &str)> = c
            .iter()
            .map(|c| (c.id.as_str(), c.verdict, c.ours.as_str()))
            .collect();
        assert_eq!(
            got,
            [
                ("4.1", Verdict::Pass, "numbers of 1"),
                ("4.4", Verdict::Fail, "numbers of 4"),
                ("4.6", Verdict::NotChecked, "numbers of 6"),
            ]
        );
        assert!(c[1].claim.contains("Empty squares"));
        assert!(c[2].reason.is_some() && c[0].reason.is_none());
    }
}
