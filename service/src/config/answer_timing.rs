//! `service.timing` and `service.plan-length`: when the service answers a sample, and how
//! many inputs ahead each answer carries as a plan.
//!
//! ```toml
//! [service]
//! timing = "send-ahead"  # "compute-first" (the default), "answer-first", "send-ahead",
//!                        # or "auto": send ahead when the controller can, else compute first
//! plan-length = 32       # plan entries per actuation (0 … 64; 0: no plan)
//! ```
//!
//! The default is compute-first because the timing is part of the control law: RCAC's
//! ahead form is (2.16) as written, `u_k = Φ_k θ_k`, whose update reaches the input one
//! sample later than the compute-first `u_k = Φ_k θ_{k+1}`, and a large gradient step that
//! is stable one way need not be the other. A deployment chooses the ahead timings on
//! purpose, with the plant's deadline (a plant that latches its inputs at the sample
//! instant needs send-ahead), as the main job's scenario does.
//!
//! A controller whose input for sample `k` needs `y_k` (an LTI controller with `D ≠ 0`,
//! PCAC's same-step timing) has no ahead form ([`control::ahead`]) and can only answer
//! compute-first; asking it for another timing, or for a plan, is refused naming the
//! field. Plans come with the ahead timings: compute-first sends none. The rules are
//! [`timing_rules::resolve_timing`] and [`timing_rules::plan_length`]; this module reads the
//! fields and words the refusals.

use super::{ConfigError, ControllerConfig, ErrFn};
use ipc_types::timing_rules::{self, PlanLengthRefusal, TimingChoice};
use ipc_types::{MAX_PLAN, Timing};

/// When the service answers and how long its plans are, validated against the controller.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AnswerTiming {
    /// The timing the loop runs.
    pub timing: Timing,
    /// Plan entries per actuation (`≤ MAX_PLAN`; 0 with [`Timing::ComputeFirst`]).
    pub plan_length: usize,
}

/// Resolves `service.timing` (`None`: `"compute-first"`) and `service.plan-length`
/// (`None`: 0) for `controller`.
pub(super) fn parse(
    timing: Option<&str>,
    plan_length: Option<u64>,
    controller: &ControllerConfig,
    err: &ErrFn<'_>,
) -> Result<AnswerTiming, ConfigError> {
    let ahead = controller.answers_ahead();
    let choice = match timing.unwrap_or("compute-first") {
        "auto" => TimingChoice::Auto,
        name => match Timing::from_name(name) {
            Some(t) => TimingChoice::Fixed(t),
            None => {
                return Err(err(
                    "service.timing",
                    format!(
                        "\"{name}\" is not a timing; use \"auto\", \"compute-first\", \
                         \"answer-first\" or \"send-ahead\""
                    ),
                ));
            }
        },
    };
    let timing = timing_rules::resolve_timing(choice, ahead).map_err(|t| {
        err(
            "service.timing",
            format!(
                "\"{}\" needs a controller whose input for sample k is ready before \
                 sample k arrives; this {} controller needs y_k for u_k ({}), so it \
                 answers \"compute-first\" (or use \"auto\")",
                t.name(),
                controller.kind_name(),
                controller.why_not_ahead()
            ),
        )
    })?;
    let requested = plan_length.unwrap_or(0);
    let plan_length = timing_rules::plan_length(requested, timing).map_err(|r| match r {
        PlanLengthRefusal::PastCapacity => err(
            "service.plan-length",
            format!("{requested} entries: an actuation carries at most {MAX_PLAN}"),
        ),
        PlanLengthRefusal::ComputeFirst => err(
            "service.plan-length",
            "plans come with the timings \"answer-first\" and \"send-ahead\"; this service \
             answers \"compute-first\", so it sends none (set plan-length = 0)"
                .into(),
        ),
    })?;
    Ok(AnswerTiming {
        timing,
        plan_length,
    })
}

#[cfg(test)]
mod tests {
    use super::super::ServiceConfig;
    use super::super::refusal_cases::assert_refused_naming_fields;
    use super::*;

    /// A static gain `u = −2y`: it needs `y_k` for `u_k`.
    const FEEDTHROUGH: &str = include_str!("../../../tests/fixtures/config/lti-static-gain.toml");
    /// PCAC in the dissertation's next-step timing: it answers ahead.
    const NEXT_STEP: &str = include_str!("../../../tests/fixtures/config/pcac-chapter-6.toml");

    fn parsed(text: &str) -> AnswerTiming {
        ServiceConfig::parse(text, "t.toml").expect("valid").answer
    }

    fn with(text: &str, lines: &str) -> String {
        text.replacen("[service]", &format!("[service]\n{lines}"), 1)
    }

    #[test]
    fn the_default_computes_first_and_auto_sends_ahead_when_the_controller_can() {
        for text in [NEXT_STEP, FEEDTHROUGH] {
            let d = parsed(text);
            assert_eq!((d.timing, d.plan_length), (Timing::ComputeFirst, 0));
        }
        let auto = |text: &str| parsed(&with(text, "timing = \"auto\"")).timing;
        assert_eq!(auto(NEXT_STEP), Timing::SendAhead);
        assert_eq!(auto(FEEDTHROUGH), Timing::ComputeFirst);
        let same_step = NEXT_STEP.replace("timing = \"next-step\"", "timing = \"same-step\"");
        assert_eq!(auto(&same_step), Timing::ComputeFirst);
        let no_d = FEEDTHROUGH.replace("d = [[-2.0]]", "d = [[0.0]]");
        assert_eq!(auto(&no_d), Timing::SendAhead);
    }

    #[test]
    fn a_timing_and_a_plan_length_are_taken_as_written() {
        for t in Timing::ALL {
            let text = with(NEXT_STEP, &format!("timing = \"{}\"", t.name()));
            assert_eq!(parsed(&text).timing, t);
        }
        let text = with(NEXT_STEP, "timing = \"answer-first\"\nplan-length = 64");
        assert_eq!(parsed(&text).plan_length, MAX_PLAN);
    }

    #[test]
    fn timings_and_plans_the_controller_cannot_give_are_refused_naming_the_field() {
        let cases = include_str!("../../../tests/fixtures/refusals/service-timing.toml");
        assert_refused_naming_fields(FEEDTHROUGH, "t.toml", cases);
        let cases = include_str!("../../../tests/fixtures/refusals/service-timing-next-step.toml");
        assert_refused_naming_fields(NEXT_STEP, "t.toml", cases);
        let m = ServiceConfig::parse(&with(FEEDTHROUGH, "timing = \"answer-first\""), "t.toml")
            .expect_err("refused")
            .to_string();
        assert!(m.contains("feedthrough D is not zero"), "{m}");
        let same_step = NEXT_STEP.replace("timing = \"next-step\"", "timing = \"same-step\"");
        let m = ServiceConfig::parse(&with(&same_step, "timing = \"send-ahead\""), "t.toml")
            .expect_err("refused")
            .to_string();
        assert!(m.contains("next-step"), "{m}");
        let m = ServiceConfig::parse(&with(FEEDTHROUGH, "plan-length = 3"), "t.toml")
            .expect_err("refused")
            .to_string();
        assert!(m.contains("compute-first"), "{m}");
    }
}
