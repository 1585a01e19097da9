//! The settings §3.3 leaves open, and chapter 3's claims (3.1–3.7) under each alternative:
//! the sensitivity tables of `study rcac-siso` and `study rcac-miso`.
//!
//! §3.3.1 and §3.3.2 print the structures' parameters (the MISO structure only by its
//! figure), the DTM designs (`n̂`, `Δ`, `β`) and RCAC's (`n_c`, `θ_0`, `k_w`, `α`, `R`),
//! but not how long a run is, over what the "asymptotic" error is measured, the
//! disturbance's phase or whether the sensors are noisy; and §3.3.2.1 gives the windowed
//! average's `β` twice, differently. Each [`Change`] moves one of the study's choices to
//! an alternative, all else as the study runs it:
//!
//! | choice | study | alternatives | why open | claims |
//! | --- | --- | --- | --- | --- |
//! | run length | 120 s | 60 s, 240 s | not given (RCAC starts at 1 s, the figures' time axes are not printed) | all |
//! | window of the asymptotic error | last 10 s | last 5 s, last 20 s | "asymptotic error at the sample times": no window given | all |
//! | phase of every disturbance tone | 0° (`sin`) | 90° (`cos`) | not given | all |
//! | sensor noise on `y` and `z` | none | white, σ = 0.01 and 0.1 (seed 1) | not given; the text's runs read as noiseless | all |
//! | windowed average's `β` (MISO) | 1 | 0.8 | §3.3.2.1 says `β = γ = 1`, the caption of Figure 3.13 says 0.8 | 3.5, 3.7 |
//!
//! The gradient update (the dissertation's, `μ_Exp` with the printed `α`, `R = 0`) is run
//! under each. The single-run claims (3.1, 3.2, 3.5, 3.6) are read on the single run of
//! Figures 3.7/3.10 or 3.14/3.17 under the alternative; the sweep claims (3.3, 3.4, 3.7)
//! on a coarse subset of the sweep ([`super::driver::RcacStudy::sensitivity_points`]: six
//! `ω_d` per case, six damping ratios), each by its own criterion
//! ([`super::claims`]). The study's own row (value `–`) is that subset and those single
//! runs under the study's choices, so a sweep claim's row can be compared with it rather
//! than with the full sweep of the claim itself.
//!
//! What is not moved: the printed settings, and the RLS variant (not the dissertation's
//! update: no claim rests on its `P_0`); the MISO structure (the chapter gives only its
//! figure; why this one, `miso`).

use std::borrow::Cow;

use plant_proxy::scenario::Scenario;

use crate::study::rcac::common::{Dtm, Method, RUN_SECONDS, TS, WINDOW_SECONDS};
use crate::study::reproduction::Claim;
use crate::study::reproduction::sensitivity::{Alternative, Reading};

/// The noise of [`Change::Noise`]: its seed.
pub const NOISE_SEED: u64 = 1;

/// One alternative choice.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Change {
    /// The study's choices.
    Study,
    /// Runs of this many seconds.
    RunLength(f64),
    /// The asymptotic error on the last this many seconds (and the window before).
    Window(f64),
    /// Every disturbance tone's phase, degrees.
    TonePhase(f64),
    /// White noise of this standard deviation on every `y` and `z`.
    Noise(f64),
    /// The windowed-average DTM's `β`.
    AverageBeta(f64),
}

impl Change {
    /// The choice it moves, as the table names it.
    pub fn choice(self) -> &'static str {
        match self {
            Change::Study => "the study's choices",
            Change::RunLength(_) => "run length",
            Change::Window(_) => "window of the asymptotic error",
            Change::TonePhase(_) => "phase of the disturbance tones",
            Change::Noise(_) => "sensor noise on y and z",
            Change::AverageBeta(_) => "β of the windowed-average DTM",
        }
    }

    /// Why §3.3 leaves it open.
    pub fn why_open(self) -> &'static str {
        match self {
            Change::Study => "",
            Change::RunLength(_) => "not given (the figures' time axes are not printed)",
            Change::Window(_) => "\"asymptotic error at the sample times\": no window given",
            Change::TonePhase(_) => "not given",
            Change::Noise(_) => "not given; the runs read as noiseless",
            Change::AverageBeta(_) => {
                "ambiguous: §3.3.2.1 says β = γ = 1, the caption of Figure 3.13 says 0.8"
            }
        }
    }

    /// The study's value of the choice it moves.
    pub fn ours(self) -> String {
        match self {
            Change::Study => "–".into(),
            Change::RunLength(_) => format!("{RUN_SECONDS} s"),
            Change::Window(_) => format!("last {WINDOW_SECONDS} s"),
            Change::TonePhase(_) => "0°".into(),
            Change::Noise(_) => "none".into(),
            Change::AverageBeta(_) => format!("{}", super::common::beta(Method::Average)),
        }
    }

    /// Its value, as text.
    pub fn value(self) -> String {
        match self {
            Change::Study => "–".into(),
            Change::RunLength(s) => format!("{s} s"),
            Change::Window(s) => format!("last {s} s"),
            Change::TonePhase(d) => format!("{d}°"),
            Change::Noise(s) => format!("σ = {s}"),
            Change::AverageBeta(b) => format!("{b}"),
        }
    }

    /// Whether it bears on claim `id` (a claim on the optimization DTM alone is not moved
    /// by the windowed average's `β`).
    pub fn bears_on(self, id: &str) -> bool {
        match self {
            Change::AverageBeta(_) => matches!(id, "3.1" | "3.3" | "3.5" | "3.7"),
            _ => true,
        }
    }

    /// Samples per run and per measurement window under it.
    pub fn steps_and_window(self) -> (usize, usize) {
        let run = match self {
            Change::RunLength(s) => s,
            _ => RUN_SECONDS,
        };
        let window = match self {
            Change::Window(s) => s,
            _ => WINDOW_SECONDS,
        };
        ((run / TS).round() as usize, (window / TS).round() as usize)
    }

    /// Applies it to a sweep point's scenario (the disturbance's phase, the noise).
    pub fn apply(self, sc: &mut Scenario) {
        match self {
            Change::TonePhase(d) => sc
                .plant
                .disturbance
                .tones
                .iter_mut()
                .for_each(|t| t.phase = d.to_radians()),
            Change::Noise(s) => {
                let n = &mut sc.plant.noise;
                n.y_std.iter_mut().for_each(|v| *v = s);
                n.z_std.iter_mut().for_each(|v| *v = s);
                n.seed = NOISE_SEED;
            }
            Change::Study | Change::RunLength(_) | Change::Window(_) | Change::AverageBeta(_) => {}
        }
    }

    /// The target model of `method` under it.
    pub fn dtm(self, method: Method, dtm: &Dtm) -> Cow<'_, Dtm> {
        match self {
            Change::AverageBeta(b) if method == Method::Average => {
                let mut d = dtm.clone();
                d.target.beta = b;
                Cow::Owned(d)
            }
            _ => Cow::Borrowed(dtm),
        }
    }
}

/// The alternatives both studies move (module documentation); the study's own first.
pub fn shared() -> Vec<Change> {
    vec![
        Change::Study,
        Change::RunLength(60.0),
        Change::RunLength(240.0),
        Change::Window(5.0),
        Change::Window(20.0),
        Change::TonePhase(90.0),
        Change::Noise(0.01),
        Change::Noise(0.1),
    ]
}

/// The row of `change`: the verdicts of the claims it bears on among `claims` (checked
/// under it by their own criteria; a claim not checked gives no reading).
pub fn row(change: Change, claims: &[Claim]) -> Alternative {
    let readings = claims
        .iter()
        .filter(|c| change.bears_on(&c.id))
        .filter(|c| c.verdict != crate::study::reproduction::Verdict::NotChecked)
        .map(|c| {
            Reading::of(
                &c.id,
                c.verdict == crate::study::reproduction::Verdict::Pass,
                c.ours.clone(),
            )
        })
        .collect();
    Alternative::new(
        change.choice(),
        change.why_open(),
        change.ours(),
        change.value(),
        readings,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::reproduction::Statement;

    #[test]
    fn each_change_moves_its_own_setting_only() {
        let study = Change::Study.steps_and_window();
        assert_eq!(study, (12_000, 1_000));
        assert_eq!(Change::RunLength(60.0).steps_and_window(), (6_000, 1_000));
        assert_eq!(Change::Window(20.0).steps_and_window(), (12_000, 2_000));
        let mut sc = super::super::siso::scenario(0.01, 22.0 * std::f64::consts::PI, 21.0)
            .expect("scenario");
        let before = sc.clone();
        Change::RunLength(60.0).apply(&mut sc);
        Change::AverageBeta(0.8).apply(&mut sc);
        assert_eq!(sc, before);
        Change::TonePhase(90.0).apply(&mut sc);
        assert!(
            sc.plant
                .disturbance
                .tones
                .iter()
                .all(|t| (t.phase - std::f64::consts::FRAC_PI_2).abs() < 1e-15)
        );
        Change::Noise(0.01).apply(&mut sc);
        assert_eq!(sc.plant.noise.y_std, vec![0.01]);
        assert_eq!(sc.plant.noise.z_std, vec![0.01]);
        for c in shared().into_iter().skip(1) {
            assert_ne!(c.value(), c.ours(), "{c:?}");
        }
        assert_eq!(Change::Study.value(), Change::Study.ours());
    }

    #[test]
    fn the_row_keeps_the_verdicts_of_the_claims_it_bears_on() {
        let st = |id| Statement {
            chapter: 3,
            id,
            source: "",
            claim: "",
            criterion: "",
        };
        let claims = vec![
            st("3.5").check(true, "60 dB"),
            st("3.6").check(false, "50 dB"),
            st("3.7").not_checked("not run"),
        ];
        let r = row(Change::Window(5.0), &claims);
        assert_eq!(r.readings.len(), 2);
        assert_eq!(r.readings[1].measured, "50 dB");
        assert_eq!(
            r.readings[1].verdict,
            crate::study::reproduction::Verdict::Fail
        );
        // β of the windowed average does not bear on 3.6 (optimization DTM).
        let r = row(Change::AverageBeta(0.8), &claims);
        assert_eq!(r.readings.len(), 1);
        assert_eq!(r.readings[0].claim, "3.5");
    }
}
